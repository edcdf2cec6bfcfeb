#include "engine/pose_track.hpp"

#include <cassert>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <stdexcept>

#include "engine/input.hpp"

namespace lumen::engine {
namespace {

// The columns of a pose CSV file.
const std::vector<std::string> kPoseColumns = {"t", "x", "y", "z", "qw", "qx", "qy", "qz"};
// A quaternion whose norm is this close to 1 is kept as it is (normalising it again could move its last bits, and
// a written track would not read back bit for bit).
constexpr double kUnitToRounding = 4.0 * std::numeric_limits<double>::epsilon();
// Significant digits that make a double read back bit for bit.
constexpr int kRoundTripDigits = 17;

// A quaternion's coefficients in the order the inputs give them, [w, x, y, z].
std::string wxyz_text(const Eigen::Quaterniond& q) {
  const double v[4] = {q.w(), q.x(), q.y(), q.z()};
  return values_text(v, 4);
}

// Refuse a vector with a non-finite entry, naming where[i].
void require_finite(const Eigen::Vector3d& v, const std::string& where) {
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(v[i]))
      throw InputError(where + "[" + std::to_string(i) + "]: must be finite (value " + value_text(v[i]) + ")");
}

}  // namespace

Eigen::Isometry3d Pose::transform() const {
  Eigen::Isometry3d x = Eigen::Isometry3d::Identity();
  x.linear() = rotation.toRotationMatrix();
  x.translation() = position;
  return x;
}

Eigen::Quaterniond unit_rotation(const Eigen::Quaterniond& q, const std::string& where) {
  // Finite, then of unit norm within the tolerance.
  if (!q.coeffs().allFinite()) throw InputError(where + ": must be finite (value " + wxyz_text(q) + ")");
  const double norm = q.norm();
  if (!(std::abs(norm - 1.0) <= kQuaternionNormTolerance))
    throw InputError(where + ": not a unit quaternion: norm " + value_text(norm) +
                     " is off 1 by more than kQuaternionNormTolerance " + value_text(kQuaternionNormTolerance) +
                     " (value " + wxyz_text(q) + ")");
  return std::abs(norm - 1.0) <= kUnitToRounding ? q : q.normalized();
}

Eigen::Quaterniond axis_angle_rotation(const Eigen::Vector3d& axis, double angle, const std::string& where) {
  // A finite, non-zero axis and a finite angle.
  require_finite(axis, where + ".axis");
  if (!(axis.norm() > 0.0)) throw InputError(where + ".axis: must not be zero (value " + values_text(axis.data(), 3) + ")");
  if (!std::isfinite(angle)) throw InputError(where + ".angle: must be finite (value " + value_text(angle) + ")");
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis.normalized()));
}

Pose interpolate(const Pose& a, const Pose& b, double w) {
  assert(w >= 0.0 && w <= 1.0);
  // Eigen's slerp negates the far end when the dot product is negative: the shortest arc.
  Pose p;
  p.position = (1.0 - w) * a.position + w * b.position;
  p.rotation = a.rotation.slerp(w, b.rotation);
  return p;
}

PoseTrack::PoseTrack(std::vector<PoseKey> keys, const std::string& where) : keys_(std::move(keys)) {
  if (keys_.empty()) throw InputError(where + ": must not be empty");
  // Each key: a finite, strictly increasing time, a finite position, a unit rotation.
  for (size_t i = 0; i < keys_.size(); ++i) {
    const std::string key = where + "[" + std::to_string(i) + "]";
    const double t = keys_[i].t;
    if (!std::isfinite(t)) throw InputError(key + ".t: must be finite (value " + value_text(t) + ")");
    if (i > 0 && !(t > keys_[i - 1].t))
      throw InputError(key + ".t: times must be strictly increasing (value " + value_text(t) + ", after " +
                       value_text(keys_[i - 1].t) + ")");
    require_finite(keys_[i].pose.position, key + ".position");
    keys_[i].pose.rotation = unit_rotation(keys_[i].pose.rotation, key + ".rotation");
  }
}

Pose PoseTrack::at(double t) const {
  size_t i;
  double w;
  bracket_keys(keys_, t, i, w);
  return w == 0.0 ? keys_[i].pose : interpolate(keys_[i].pose, keys_[i + 1].pose, w);
}

PoseTrack read_pose_csv(const std::string& path) {
  // Rows of finite numbers with increasing times (read_csv_table), then each row's quaternion.
  const CsvTable table = read_csv_table(path, kPoseColumns, "pose file");
  std::vector<PoseKey> keys(static_cast<size_t>(table.rows()));
  for (int i = 0; i < table.rows(); ++i) {
    const double* v = table.row(i);
    PoseKey& k = keys[static_cast<size_t>(i)];
    k.t = v[0];
    k.pose.position = Eigen::Vector3d(v[1], v[2], v[3]);
    k.pose.rotation = unit_rotation(Eigen::Quaterniond(v[4], v[5], v[6], v[7]),
                                    path + ": line " + std::to_string(table.lines[static_cast<size_t>(i)]) +
                                        ": fields qw, qx, qy, qz");
  }
  return PoseTrack(std::move(keys), path);
}

void write_pose_csv(const std::string& path, const std::vector<PoseKey>& keys) {
  // Header and one line per key, under a temporary name.
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp);
    out.precision(kRoundTripDigits);
    for (size_t c = 0; c < kPoseColumns.size(); ++c) out << (c ? "," : "") << kPoseColumns[c];
    out << "\n";
    for (const PoseKey& k : keys) {
      const Eigen::Vector3d& p = k.pose.position;
      const Eigen::Quaterniond& q = k.pose.rotation;
      out << k.t << "," << p.x() << "," << p.y() << "," << p.z() << "," << q.w() << "," << q.x() << "," << q.y()
          << "," << q.z() << "\n";
    }
    if (!out) {
      std::error_code ec;
      std::filesystem::remove(tmp, ec);
      throw std::runtime_error(path + ": cannot write pose file");
    }
  }
  std::filesystem::rename(tmp, path);
}

Eigen::Isometry3d rigid_to_organ(const std::array<double, 16>& row_major, const std::string& where) {
  // Finite entries and the last row 0 0 0 1.
  const std::string value = " (value " + values_text(row_major.data(), 16) + ")";
  for (size_t i = 0; i < row_major.size(); ++i)
    if (!std::isfinite(row_major[i]))
      throw InputError(where + "[" + std::to_string(i) + "]: must be finite (value " + value_text(row_major[i]) + ")");
  const Eigen::Matrix<double, 4, 4, Eigen::RowMajor> m(row_major.data());
  if ((m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > kOrthonormalTolerance)
    throw InputError(where + ": not rigid: last row must be 0 0 0 1" + value);
  // Its rotation orthonormal and proper.
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  const double off = (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (off > kOrthonormalTolerance)
    throw InputError(where + ": not rigid: rotation not orthonormal (largest entry of |R^T R - I| " + value_text(off) +
                     " > kOrthonormalTolerance " + value_text(kOrthonormalTolerance) + ")" + value);
  const double det = r.determinant();
  if (std::abs(det - 1.0) > kOrthonormalTolerance)
    throw InputError(where + ": not rigid: det R = " + value_text(det) + ", must be +1 (a reflection)" + value);
  Eigen::Isometry3d x = Eigen::Isometry3d::Identity();
  x.linear() = Eigen::Quaterniond(r).normalized().toRotationMatrix();
  x.translation() = m.topRightCorner<3, 1>();
  return x;
}

Pose device_to_organ(const Eigen::Isometry3d& to_organ, const Eigen::Vector3d& position_mm,
                     const Eigen::Quaterniond& rotation) {
  // Millimetres to metres, then the rigid map; the rotations compose.
  Pose p;
  p.position = to_organ * (kMetresPerMillimetre * position_mm);
  p.rotation = (Eigen::Quaterniond(to_organ.linear()) * rotation).normalized();
  return p;
}

PoseVelocity velocity_between(const Pose& a, const Pose& b, double dt) {
  assert(dt > 0.0);
  // The relative rotation in the organ frame, taken along its shortest arc (w >= 0).
  Eigen::Quaterniond rel = b.rotation * a.rotation.conjugate();
  if (rel.w() < 0.0) rel.coeffs() = -rel.coeffs();
  const Eigen::AngleAxisd aa(rel.normalized());
  PoseVelocity v;
  v.linear = (b.position - a.position) / dt;
  v.angular = aa.axis() * (aa.angle() / dt);
  return v;
}

}  // namespace lumen::engine
