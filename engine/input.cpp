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

std::string value_text(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

std::string values_text(const double* v, int n) {
  std::string s = "[";
  for (int i = 0; i < n; ++i) s += (i ? ", " : "") + value_text(v[i]);
  return s + "]";
}

namespace {
// The columns' names joined as "t, x, y, z".
std::string joined(const std::vector<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
  return s;
}

// One field of a CSV line as a finite number; `where` is "FILE: line N: field ".
double csv_number(const std::string& field, const std::string& where, const std::string& name) {
  size_t used = 0;
  const auto b = field.find_first_not_of(" \t"), e = field.find_last_not_of(" \t");
  const std::string trimmed = b == std::string::npos ? "" : field.substr(b, e - b + 1);
  double v = 0.0;
  try {
    v = std::stod(trimmed, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != trimmed.size()) throw InputError(where + name + ": not a number (value \"" + trimmed + "\")");
  if (!std::isfinite(v)) throw InputError(where + name + ": must be finite (value " + trimmed + ")");
  return v;
}
}  // namespace

CsvTable read_csv_table(const std::string& path, const std::vector<std::string>& names, const std::string& what) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot read " + what);
  const size_t n_fields = names.size();
  const std::string expected = "expected " + std::to_string(n_fields) + " fields (" + joined(names) + ")";
  CsvTable table;
  table.columns = static_cast<int>(n_fields);
  std::string line;
  int lineno = 0;
  // Parse each data line: one finite number per column, the first strictly increasing.
  while (std::getline(in, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    if (table.lines.empty() && (line[0] == 't' || line[0] == 'T')) continue;  // header
    const std::string at_line = path + ": line " + std::to_string(lineno) + ": ";
    std::stringstream ss(line);
    std::string field;
    size_t n = 0;
    while (std::getline(ss, field, ',')) {
      if (n >= n_fields) throw InputError(at_line + "field " + std::to_string(n + 1) + ": " + expected);
      table.values.push_back(csv_number(field, at_line + "field ", names[n]));
      ++n;
    }
    if (n != n_fields) throw InputError(at_line + expected + ", got " + std::to_string(n));
    const double t = table.values[table.values.size() - n_fields];
    if (!table.lines.empty() && !(t > table.row(table.rows() - 1)[0]))
      throw InputError(at_line + "field " + names[0] + ": times must be strictly increasing (value " +
                       std::to_string(t) + ")");
    table.lines.push_back(lineno);
  }
  if (table.lines.empty()) throw InputError(path + ": no samples (expected lines " + joined(names) + ")");
  return table;
}

ReplaySource::ReplaySource(const std::string& csv_path) {
  // Columns t, x, y, z, fx, fy, fz: seconds, metres, newtons.
  const CsvTable table = read_csv_table(csv_path, {"t", "x", "y", "z", "fx", "fy", "fz"}, "replay file");
  for (int i = 0; i < table.rows(); ++i) {
    const double* v = table.row(i);
    t_.push_back(v[0]);
    x_.emplace_back(v[1], v[2], v[3]);
    f_.emplace_back(v[4], v[5], v[6]);
  }
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

void PoseTrackSource::feedback(double, const InstrumentRecord& record) {
  forces_.push_back(record.force);
  torques_.push_back(record.torque);
}

}  // namespace lumen::engine
