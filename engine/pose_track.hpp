#pragma once
// Instrument poses: a position and a unit quaternion, key-frame tracks (positions linear, rotations by slerp),
// recorded pose CSV files, the rigid device-to-organ transform, and the velocity between two poses.
//
// The scene key `instruments` reads its tracks and replays with these (engine/scene.cpp). Every input is validated
// here, at the boundary, with InputError messages naming where (file and line, or key path), the field and the
// value; past it a pose is finite and its quaternion unit.
#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace lumen::engine {

// How far from 1 a given quaternion's norm may be before it is refused (inputs rounded to a few digits, a
// device's float32 wire values); within it the quaternion is normalised.
inline constexpr double kQuaternionNormTolerance = 1e-3;
// How far a rigid transform's rotation may be from orthonormal: the largest entry of |R^T R - I| and |det R - 1|.
inline constexpr double kOrthonormalTolerance = 1e-3;
// Metres in a millimetre (device and OpenIGTLink positions are in millimetres).
inline constexpr double kMetresPerMillimetre = 1e-3;

// Where an instrument is: its frame's origin (the tip) and its orientation, in the organ frame.
struct Pose {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();               // metres
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();     // unit: instrument frame -> organ frame
  // x_organ = rotation * x_instrument + position.
  Eigen::Isometry3d transform() const;
};

// One key of a pose track: the pose reached at time t (seconds).
struct PoseKey {
  double t = 0.0;
  Pose pose;
};

// A rotation given as a unit quaternion [w, x, y, z]: refused unless finite with its norm within
// kQuaternionNormTolerance of 1; returned normalised (as it is when already unit to rounding). `where` names it
// in messages ("FILE: line 3: fields qw, qx, qy, qz" or "instruments[0].track[2].rotation").
Eigen::Quaterniond unit_rotation(const Eigen::Quaterniond& q, const std::string& where);
// A rotation given as an axis (any non-zero length, normalised here) and an angle in radians about it.
Eigen::Quaterniond axis_angle_rotation(const Eigen::Vector3d& axis, double angle, const std::string& where);

// The pose a fraction w in [0, 1] of the way from a to b: position linear, rotation by slerp along the shortest
// arc (q and -q are the same rotation; the one nearer a is taken).
Pose interpolate(const Pose& a, const Pose& b, double w);

// Key frames with times strictly increasing, interpolated between keys and held before the first and after the
// last.
class PoseTrack {
 public:
  // Refuses an empty track, a non-finite or non-increasing time, a non-finite position and a rotation that
  // unit_rotation refuses, naming where[i] and the field; the keys' rotations are stored normalised.
  PoseTrack(std::vector<PoseKey> keys, const std::string& where);
  Pose at(double t) const;
  const std::vector<PoseKey>& keys() const { return keys_; }

 private:
  std::vector<PoseKey> keys_;
};

// A recorded track: CSV lines `t, x, y, z, qw, qx, qy, qz` (seconds, metres in the organ frame, unit quaternion),
// optional header line starting with 't', '#' comments. Throws InputError naming the file, line, field and value.
PoseTrack read_pose_csv(const std::string& path);
// Write one in that format (17 significant digits: it reads back bit for bit), under a temporary name then
// renamed. Throws std::runtime_error naming the file when it cannot be written.
void write_pose_csv(const std::string& path, const std::vector<PoseKey>& keys);

// The rigid transform from device coordinates (after millimetres are converted to metres) to the organ frame,
// from a row-major 4 x 4: refused unless finite, its rotation orthonormal and proper (det +1) within
// kOrthonormalTolerance and its last row 0 0 0 1, naming where and the value; the rotation is re-orthonormalised.
Eigen::Isometry3d rigid_to_organ(const std::array<double, 16>& row_major, const std::string& where);
// A device pose (position in millimetres, rotation device frame -> tool) in the organ frame, metres.
Pose device_to_organ(const Eigen::Isometry3d& to_organ, const Eigen::Vector3d& position_mm,
                     const Eigen::Quaterniond& rotation);

// The instrument's velocity from pose a to pose b over dt > 0 seconds, in the organ frame: linear (m/s, of the
// tip) and angular (rad/s, the rotation b a^-1 along its shortest arc, as axis times angle over dt).
struct PoseVelocity {
  Eigen::Vector3d linear = Eigen::Vector3d::Zero();
  Eigen::Vector3d angular = Eigen::Vector3d::Zero();
};
PoseVelocity velocity_between(const Pose& a, const Pose& b, double dt);

}  // namespace lumen::engine
