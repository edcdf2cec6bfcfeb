#include "engine/input.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

namespace lumen::engine {
TrackSource::TrackSource(const Eigen::Vector3d& point, std::vector<TrackKey> keys, ProbeDrive drive)
    : point_(point), keys_(std::move(keys)), drive_(drive) {
  if (keys_.empty()) throw InputError("track: must not be empty");
}

ProbeSample TrackSource::sample(double t) {
  // Interpolate the force linearly between the surrounding keys.
  size_t i;
  double w;
  bracket_keys(keys_, t, i, w);
  ProbeSample s;
  s.point = point_;
  const Eigen::Vector3d value = (w == 0.0) ? keys_[i].value : ((1.0 - w) * keys_[i].value + w * keys_[i + 1].value);
  s.displacement_driven = drive_ == ProbeDrive::Displacement;
  (s.displacement_driven ? s.displacement : s.force) = value;
  return s;
}

ReplaySource::ReplaySource(const std::string& csv_path) {
  std::ifstream in(csv_path);
  if (!in) throw InputError(csv_path + ": cannot read replay file");
  static const char* names[7] = {"t", "x", "y", "z", "fx", "fy", "fz"};
  std::string line;
  int lineno = 0;
  // Parse each data line: 7 finite numbers, t strictly increasing.
  while (std::getline(in, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    if (t_.empty() && (line[0] == 't' || line[0] == 'T')) continue;  // header
    std::stringstream ss(line);
    std::string field;
    double v[7];
    int n = 0;
    while (std::getline(ss, field, ',')) {
      const std::string where = csv_path + ": line " + std::to_string(lineno) + ": field ";
      if (n >= 7) throw InputError(where + std::to_string(n + 1) + ": expected 7 fields (t, x, y, z, fx, fy, fz)");
      size_t used = 0;
      const auto b = field.find_first_not_of(" \t"), e = field.find_last_not_of(" \t");
      std::string trimmed = b == std::string::npos ? "" : field.substr(b, e - b + 1);
      try {
        v[n] = std::stod(trimmed, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used == 0 || used != trimmed.size())
        throw InputError(where + names[n] + ": not a number (value \"" + trimmed + "\")");
      if (!std::isfinite(v[n])) throw InputError(where + names[n] + ": must be finite (value " + trimmed + ")");
      ++n;
    }
    if (n != 7)
      throw InputError(csv_path + ": line " + std::to_string(lineno) + ": expected 7 fields (t, x, y, z, fx, fy, fz), got " +
                       std::to_string(n));
    if (!t_.empty() && !(v[0] > t_.back()))
      throw InputError(csv_path + ": line " + std::to_string(lineno) + ": field t: times must be strictly increasing (value " +
                       std::to_string(v[0]) + ")");
    t_.push_back(v[0]);
    x_.emplace_back(v[1], v[2], v[3]);
    f_.emplace_back(v[4], v[5], v[6]);
  }
  if (t_.empty()) throw InputError(csv_path + ": no samples (expected lines t, x, y, z, fx, fy, fz)");
  for (const auto& x : x_) fixed_point_ = fixed_point_ && (x - x_.front()).norm() == 0.0;
}

ProbeSample ReplaySource::sample(double t) {
  size_t i;
  double w;
  bracket_times(t_, t, i, w);
  ProbeSample s;
  s.point = (w == 0.0) ? x_[i] : ((1 - w) * x_[i] + w * x_[i + 1]);
  s.force = (w == 0.0) ? f_[i] : ((1 - w) * f_[i] + w * f_[i + 1]);
  return s;
}

void ReplaySource::feedback(double, const Eigen::Vector3d& reaction) { reactions_.push_back(reaction); }

std::unique_ptr<InputSource> make_source(const ProbeSpec& probe) {
  if (!probe.replay.empty()) return std::make_unique<ReplaySource>(probe.replay);
  return std::make_unique<TrackSource>(probe.point, probe.track, probe.drive);
}

}  // namespace lumen::engine
