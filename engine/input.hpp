#pragma once
// Probe input sources: scripted key-frame tracks, recorded CSV replay, and (later) haptic devices.
//
// Every source sits behind `InputSource`. Once per frame the engine calls `sample(t)` for the probe's load
// (a force at a point on the organ's surface) and, after the frame is solved, `feedback(t, reaction)` with the
// reaction force at that point (what a haptic device displays). A device source runs its own polling thread at
// the device's rate (e.g. 1 kHz): `sample` returns its latest reading without waiting, and `feedback` stores the
// force for the device thread to send. The engine never blocks on a source.
#include <algorithm>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "engine/pose_track.hpp"
#include "engine/report.hpp"
#include "engine/scene.hpp"

namespace lumen::engine {

// What a source gives at one instant.
struct ProbeSample {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  // metres, on (or near) the organ's outer wall
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  // newtons, applied at `point` (force-driven)
  bool displacement_driven = false;                 // true: `displacement` is prescribed, the force is solved for
  Eigen::Vector3d displacement = Eigen::Vector3d::Zero();  // metres, of the point from rest (displacement-driven)
};

class InputSource {
 public:
  virtual ~InputSource() = default;
  virtual std::string kind() const = 0;  // "track", "replay", "device", ...
  // The load at simulation time t (seconds). Must not block.
  virtual ProbeSample sample(double t) = 0;
  // The reaction force at the probe point after the frame at time t, newtons.
  virtual void feedback(double /*t*/, const Eigen::Vector3d& /*reaction*/) {}
  // Whether the point can move during the session (false: precompute its load response once).
  virtual bool point_is_fixed() const { return true; }
};

// Key frames with times strictly increasing (time_of(key), seconds): the key i and blend weight w of time t,
// value(t) = (1 - w) value_i + w value_{i+1}; held (w = 0) at the first key before it and at the last after it.
// The one key-frame interpolator of tracks, twists and replays.
template <class Key, class TimeOf>
void bracket_by(const std::vector<Key>& keys, double t, TimeOf time_of, size_t& i, double& w) {
  if (t <= time_of(keys.front())) {
    i = 0;
    w = 0.0;
    return;
  }
  if (t >= time_of(keys.back())) {
    i = keys.size() - 1;
    w = 0.0;
    return;
  }
  i = static_cast<size_t>(std::upper_bound(keys.begin(), keys.end(), t,
                                           [&](double v, const Key& k) { return v < time_of(k); }) - keys.begin()) - 1;
  w = (t - time_of(keys[i])) / (time_of(keys[i + 1]) - time_of(keys[i]));
}
// Keys with a member t (TrackKey, TwistKey).
template <class Key>
void bracket_keys(const std::vector<Key>& keys, double t, size_t& i, double& w) {
  bracket_by(keys, t, [](const Key& k) { return k.t; }, i, w);
}
// Plain times.
inline void bracket_times(const std::vector<double>& times, double t, size_t& i, double& w) {
  bracket_by(times, t, [](double v) { return v; }, i, w);
}

// Numbers as input messages quote them: "0.003", and a list "[1, 0, 0, 0]" (6 significant digits).
std::string value_text(double v);
std::string values_text(const double* v, int n);

// A numeric CSV file as read at the boundary: every data line has one finite number per named column, the first
// column (a time) strictly increasing; lines starting with '#' and a first header line starting with 't' are
// skipped.
struct CsvTable {
  int columns = 0;
  std::vector<double> values;  // rows x columns, row-major
  std::vector<int> lines;      // rows: the file's line number of each row (1-based, for messages)
  int rows() const { return static_cast<int>(lines.size()); }
  const double* row(int i) const { return &values[static_cast<size_t>(i) * static_cast<size_t>(columns)]; }
};
// Read one; `what` names the kind of file ("replay file"). Throws InputError naming the file, line, field
// (the column's name) and value.
CsvTable read_csv_table(const std::string& path, const std::vector<std::string>& names, const std::string& what);

// Scripted key frames at a fixed point; linear interpolation between keys, held before the first / after the last.
class TrackSource final : public InputSource {
 public:
  TrackSource(const Eigen::Vector3d& point, std::vector<TrackKey> keys, ProbeDrive drive = ProbeDrive::Force);
  std::string kind() const override { return "track"; }
  ProbeSample sample(double t) override;

 private:
  Eigen::Vector3d point_;
  std::vector<TrackKey> keys_;
  ProbeDrive drive_;
};

// Replay of a recorded session: CSV lines `t, x, y, z, fx, fy, fz` (seconds, metres, newtons), t increasing.
// Lines starting with '#' and a first header line starting with 't' are skipped. Linear interpolation.
class ReplaySource final : public InputSource {
 public:
  // Throws InputError naming the file, line, field and value.
  explicit ReplaySource(const std::string& csv_path);
  std::string kind() const override { return "replay"; }
  ProbeSample sample(double t) override;
  bool point_is_fixed() const override { return fixed_point_; }
  const std::vector<double>& times() const { return t_; }
  // Reaction forces handed back, one per frame (for reports and tests).
  const std::vector<Eigen::Vector3d>& reactions() const { return reactions_; }
  void feedback(double t, const Eigen::Vector3d& reaction) override;

 private:
  std::vector<double> t_;                    // n_samples, seconds
  std::vector<Eigen::Vector3d> x_, f_;       // n_samples each, metres / newtons
  std::vector<Eigen::Vector3d> reactions_;   // n_frames, newtons
  bool fixed_point_ = true;
};

// Build the source a probe asks for.
std::unique_ptr<InputSource> make_source(const ProbeSpec& probe);

// An instrument's pose source: where the instrument is at time t (organ frame), and after each frame the contact
// record (its end pose, the contacts' force and torque on it, and its local stiffness: what a haptic device
// displays). A device's source (engine/device.hpp) returns its latest pose without waiting; the engine never
// blocks on it.
class PoseSource {
 public:
  virtual ~PoseSource() = default;
  virtual std::string kind() const = 0;
  virtual Pose pose(double t) = 0;
  virtual void feedback(double t, const InstrumentRecord& record) = 0;
};

// Poses played back from key frames or a recorded pose file ("track" | "replay"); keeps what it is handed back.
class PoseTrackSource final : public PoseSource {
 public:
  PoseTrackSource(PoseTrack track, std::string kind) : track_(std::move(track)), kind_(std::move(kind)) {}
  std::string kind() const override { return kind_; }
  Pose pose(double t) override { return track_.at(t); }
  void feedback(double t, const InstrumentRecord& record) override;
  // Force and torque handed back, one per frame (for reports and tests).
  const std::vector<Eigen::Vector3d>& forces() const { return forces_; }
  const std::vector<Eigen::Vector3d>& torques() const { return torques_; }

 private:
  PoseTrack track_;
  std::string kind_;
  std::vector<Eigen::Vector3d> forces_, torques_;
};

}  // namespace lumen::engine
