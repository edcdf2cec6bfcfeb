// Pose tracks: slerp against rotation matrices written out by hand (a fixed axis, angle linear in t), the
// shortest arc, linear positions, clamping, the pose CSV round trip and its refusals, the to_organ transform
// against a hand-computed map, and the velocity between two poses.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <random>

#include "engine/pose_track.hpp"
#include "engine/scene.hpp"
#include "support/files.hpp"
#include "support/build.hpp"

using namespace lumen::engine;

namespace {

using lumen::test::kPi;
// Rotations and positions computed two ways agree to rounding.
constexpr double kTrackTight = 1e-12;
// Random rotations written and read back (about 2 % of them move by an ulp when normalised again).
constexpr size_t kRandomRotations = 1000;

using lumen::test::write_temp;

// The message of the InputError that f throws ("" when it throws none).
std::string track_error_of(const std::function<void()>& f) { return lumen::test::message_of<InputError>(f); }

// The rotation by angle a about z, written out.
Eigen::Matrix3d rot_z(double a) {
  Eigen::Matrix3d r;
  r << std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a), 0, 0, 0, 1;
  return r;
}

Pose pose_of(const Eigen::Vector3d& p, const Eigen::Quaterniond& q) {
  Pose x;
  x.position = p;
  x.rotation = q;
  return x;
}

Eigen::Quaterniond about_z(double a) { return Eigen::Quaterniond(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ())); }

}  // namespace

TEST(PoseTrack, SlerpTurnsAboutAFixedAxisWithTheAngleLinearInTime) {
  // Keys at 0.3 rad (t = 1) and 1.7 rad (t = 3) about z: the angle at t is 0.3 + 0.7 (t - 1).
  const PoseTrack track({{1.0, pose_of({0, 0, 0}, about_z(0.3))}, {3.0, pose_of({0, 0, 0}, about_z(1.7))}}, "track");
  for (double t : {1.0, 1.25, 1.9, 2.5, 3.0}) {
    const Eigen::Matrix3d r = track.at(t).rotation.toRotationMatrix();
    EXPECT_LT((r - rot_z(0.3 + 0.7 * (t - 1.0))).cwiseAbs().maxCoeff(), kTrackTight) << "t " << t;
  }
  // The same about an oblique axis: the relative rotation to the first key is about that axis, angle linear.
  const Eigen::Vector3d axis = Eigen::Vector3d(1, -2, 0.5).normalized();
  const Eigen::Quaterniond q0(Eigen::AngleAxisd(0.2, axis)), q1(Eigen::AngleAxisd(2.2, axis));
  const PoseTrack oblique({{0.0, pose_of({0, 0, 0}, q0)}, {2.0, pose_of({0, 0, 0}, q1)}}, "track");
  const Eigen::AngleAxisd rel(oblique.at(0.5).rotation * q0.conjugate());
  EXPECT_NEAR(rel.angle(), 0.5, kTrackTight);
  EXPECT_LT((rel.axis() - axis).norm(), kTrackTight);
}

TEST(PoseTrack, SlerpTakesTheShortestArcForEitherSignOfTheQuaternion) {
  // -q is q: from the identity to -(0.4 rad about z) the midpoint is 0.2 rad about z, not the long way round.
  Eigen::Quaterniond far = about_z(0.4);
  far.coeffs() = -far.coeffs();
  const PoseTrack track({{0.0, pose_of({0, 0, 0}, Eigen::Quaterniond::Identity())}, {1.0, pose_of({0, 0, 0}, far)}},
                        "track");
  EXPECT_LT((track.at(0.5).rotation.toRotationMatrix() - rot_z(0.2)).cwiseAbs().maxCoeff(), kTrackTight);
  EXPECT_LT((track.at(0.25).rotation.toRotationMatrix() - rot_z(0.1)).cwiseAbs().maxCoeff(), kTrackTight);
}

TEST(PoseTrack, PositionsAreLinearAndClampedOutsideTheKeys) {
  const Eigen::Quaterniond q = about_z(0.5);
  const PoseTrack track({{0.5, pose_of({0, 0.03, 0.05}, q)},
                         {1.5, pose_of({0.01, 0.01, 0.05}, q)},
                         {2.0, pose_of({0.01, 0.0, 0.07}, q)}},
                        "track");
  EXPECT_LT((track.at(1.0).position - Eigen::Vector3d(0.005, 0.02, 0.05)).norm(), kTrackTight);
  EXPECT_LT((track.at(1.75).position - Eigen::Vector3d(0.01, 0.005, 0.06)).norm(), kTrackTight);
  // Held at the first key before it and at the last after it.
  EXPECT_EQ(track.at(-3.0).position, Eigen::Vector3d(0, 0.03, 0.05));
  EXPECT_EQ(track.at(0.5).position, Eigen::Vector3d(0, 0.03, 0.05));
  EXPECT_EQ(track.at(9.0).position, Eigen::Vector3d(0.01, 0.0, 0.07));
  EXPECT_LT(track.at(9.0).rotation.angularDistance(q), kTrackTight);
}

TEST(PoseTrack, AxisAngleKeysAreRotationsAboutTheNormalisedAxis) {
  const Eigen::Quaterniond q = axis_angle_rotation({0, 0, 2}, 0.7, "k.rotation");
  EXPECT_LT((q.toRotationMatrix() - rot_z(0.7)).cwiseAbs().maxCoeff(), kTrackTight);
  EXPECT_EQ(track_error_of([] { axis_angle_rotation({0, 0, 0}, 0.7, "k.rotation"); }),
            "k.rotation.axis: must not be zero (value [0, 0, 0])");
  EXPECT_EQ(track_error_of([] { axis_angle_rotation({0, NAN, 1}, 0.7, "k.rotation"); }),
            "k.rotation.axis[1]: must be finite (value nan)");
  EXPECT_EQ(track_error_of([] { axis_angle_rotation({0, 0, 1}, INFINITY, "k.rotation"); }),
            "k.rotation.angle: must be finite (value inf)");
}

TEST(PoseTrack, RefusesBadKeysNamingTheKeyAndField) {
  const Pose ok;
  EXPECT_EQ(track_error_of([] { PoseTrack({}, "tr"); }), "tr: must not be empty");
  EXPECT_EQ(track_error_of([&] { PoseTrack({{0.0, ok}, {0.0, ok}}, "tr"); }),
            "tr[1].t: times must be strictly increasing (value 0, after 0)");
  EXPECT_EQ(track_error_of([&] { PoseTrack({{NAN, ok}}, "tr"); }), "tr[0].t: must be finite (value nan)");
  EXPECT_EQ(track_error_of([] { PoseTrack({{0.0, pose_of({0, 0, INFINITY}, Eigen::Quaterniond::Identity())}}, "tr"); }),
            "tr[0].position[2]: must be finite (value inf)");
  EXPECT_EQ(track_error_of([] { PoseTrack({{0.0, pose_of({0, 0, 0}, Eigen::Quaterniond(1, 1, 0, 0))}}, "tr"); }),
            "tr[0].rotation: not a unit quaternion: norm 1.41421 is off 1 by more than kQuaternionNormTolerance "
            "0.001 (value [1, 1, 0, 0])");
  EXPECT_EQ(track_error_of([] { PoseTrack({{0.0, pose_of({0, 0, 0}, Eigen::Quaterniond(NAN, 0, 0, 0))}}, "tr"); }),
            "tr[0].rotation: must be finite (value [nan, 0, 0, 0])");
  // Within the tolerance: accepted and normalised.
  const PoseTrack near({{0.0, pose_of({0, 0, 0}, Eigen::Quaterniond(1.0005, 0, 0, 0))}}, "tr");
  EXPECT_NEAR(near.keys()[0].pose.rotation.norm(), 1.0, kTrackTight);
}

TEST(PoseCsv, RoundTripsAndReadsAHeaderAndComments) {
  // Awkward values: thirds, tiny and large magnitudes, a rotation about an oblique axis.
  const Eigen::Quaterniond q(Eigen::AngleAxisd(1.0 / 3.0, Eigen::Vector3d(1, 2, 3).normalized()));
  const PoseTrack track({{0.0, pose_of({1.0 / 3.0, -2e-7, 0.05}, q)},
                         {0.025, pose_of({0.1, 123.456, -1.0 / 7.0}, Eigen::Quaterniond::Identity())},
                         {1.0 / 3.0, pose_of({0, 0, 0}, q.conjugate())}},
                        "keys");
  const std::vector<PoseKey>& keys = track.keys();  // as stored: rotations normalised
  const std::string path = (std::filesystem::temp_directory_path() / "lumen_test_poses.csv").string();
  write_pose_csv(path, keys);
  const PoseTrack back = read_pose_csv(path);
  ASSERT_EQ(back.keys().size(), keys.size());
  for (size_t i = 0; i < keys.size(); ++i) {
    EXPECT_EQ(back.keys()[i].t, keys[i].t);
    EXPECT_EQ(back.keys()[i].pose.position, keys[i].pose.position);
    EXPECT_EQ(back.keys()[i].pose.rotation.coeffs(), keys[i].pose.rotation.coeffs());
  }
  // Bit for bit also for many random rotations (normalising a unit quaternion again can move its last bits).
  std::mt19937 gen(1);
  std::normal_distribution<double> normal;
  std::vector<PoseKey> many(kRandomRotations);
  for (size_t i = 0; i < many.size(); ++i) {
    many[i].t = static_cast<double>(i);
    const Eigen::Vector4d wxyz(normal(gen), normal(gen), normal(gen), normal(gen));
    many[i].pose.rotation = unit_rotation(Eigen::Quaterniond(wxyz[0], wxyz[1], wxyz[2], wxyz[3]).normalized(), "q");
  }
  write_pose_csv(path, many);
  const PoseTrack many_back = read_pose_csv(path);
  for (size_t i = 0; i < many.size(); ++i)
    EXPECT_EQ(many_back.keys()[i].pose.rotation.coeffs(), many[i].pose.rotation.coeffs()) << "key " << i;
  const PoseTrack hand = read_pose_csv(write_temp("poses_hand.csv", "# recorded\nt,x,y,z,qw,qx,qy,qz\n"
                                                                    "0, 0,0.03,0.05, 1,0,0,0\n"
                                                                    "2, 0,0.012,0.05, 0,0,0,1\n"));
  EXPECT_LT((hand.at(1.0).position - Eigen::Vector3d(0, 0.021, 0.05)).norm(), kTrackTight);
  EXPECT_LT((hand.at(1.0).rotation.toRotationMatrix() - rot_z(kPi / 2)).cwiseAbs().maxCoeff(), kTrackTight);
}

TEST(PoseCsv, RefusalsNameTheFileLineAndField) {
  auto error_of_file = [](const std::string& path) { return track_error_of([&] { read_pose_csv(path); }); };
  const std::string p1 = write_temp("poses_bad1.csv", "0,0,0,0,1,0,0,0\n1,0,0,0,1,x0,0,0\n");
  EXPECT_EQ(error_of_file(p1), p1 + ": line 2: field qx: not a number (value \"x0\")");
  const std::string p2 = write_temp("poses_bad2.csv", "0,0,0,0,1,0,0\n");
  EXPECT_EQ(error_of_file(p2), p2 + ": line 1: expected 8 fields (t, x, y, z, qw, qx, qy, qz), got 7");
  const std::string p3 = write_temp("poses_bad3.csv", "0,0,0,0,1,0,0,0,9\n");
  EXPECT_EQ(error_of_file(p3), p3 + ": line 1: field 9: expected 8 fields (t, x, y, z, qw, qx, qy, qz)");
  const std::string p4 = write_temp("poses_bad4.csv", "t,x,y,z,qw,qx,qy,qz\n1,0,0,0,1,0,0,0\n0.5,0,0,0,1,0,0,0\n");
  EXPECT_EQ(error_of_file(p4), p4 + ": line 3: field t: times must be strictly increasing (value 0.500000)");
  const std::string p5 = write_temp("poses_bad5.csv", "0,0,inf,0,1,0,0,0\n");
  EXPECT_EQ(error_of_file(p5), p5 + ": line 1: field y: must be finite (value inf)");
  const std::string p6 = write_temp("poses_bad6.csv", "0,0,0,0,1,0,0,0\n\n1,0,0,0,0.9,0,0,0\n");
  EXPECT_EQ(error_of_file(p6), p6 + ": line 3: fields qw, qx, qy, qz: not a unit quaternion: norm 0.9 is off 1 by "
                                    "more than kQuaternionNormTolerance 0.001 (value [0.9, 0, 0, 0])");
  const std::string p7 = write_temp("poses_empty.csv", "t,x,y,z,qw,qx,qy,qz\n");
  EXPECT_EQ(error_of_file(p7), p7 + ": no samples (expected lines t, x, y, z, qw, qx, qy, qz)");
  EXPECT_EQ(error_of_file("/nonexistent/p.csv"), "/nonexistent/p.csv: cannot read pose file");
}

TEST(ToOrgan, MapsADevicePoseInMillimetresAsComputedByHand) {
  // A quarter turn about z, then a shift of (10, 20, 30) mm written in metres.
  const Eigen::Isometry3d to_organ =
      rigid_to_organ({0, -1, 0, 0.01, 1, 0, 0, 0.02, 0, 0, 1, 0.03, 0, 0, 0, 1}, "to_organ");
  // The device tool turned a quarter about x (y -> z), at (10, 20, 30) mm.
  const Pose p = device_to_organ(to_organ, {10, 20, 30},
                                 Eigen::Quaterniond(Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitX())));
  // (0.01, 0.02, 0.03) m turned about z is (-0.02, 0.01, 0.03), shifted: (-0.01, 0.03, 0.06).
  EXPECT_LT((p.position - Eigen::Vector3d(-0.01, 0.03, 0.06)).norm(), kTrackTight);
  // Tool axes: y -> z (device) -> z (organ); x -> x -> y.
  EXPECT_LT((p.rotation * Eigen::Vector3d::UnitY() - Eigen::Vector3d::UnitZ()).norm(), kTrackTight);
  EXPECT_LT((p.rotation * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), kTrackTight);
}

TEST(ToOrgan, RefusesATransformThatIsNotRigid) {
  auto error_of_rows = [](const std::array<double, 16>& m) { return track_error_of([&] { rigid_to_organ(m, "to_organ"); }); };
  EXPECT_EQ(error_of_rows({1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, NAN, 0, 0, 0, 1}), "to_organ[11]: must be finite (value nan)");
  EXPECT_EQ(error_of_rows({1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 1}),
            "to_organ: not rigid: last row must be 0 0 0 1 (value [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 1])");
  EXPECT_EQ(error_of_rows({2, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}),
            "to_organ: not rigid: rotation not orthonormal (largest entry of |R^T R - I| 3 > kOrthonormalTolerance "
            "0.001) (value [2, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1])");
  EXPECT_EQ(error_of_rows({-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}),
            "to_organ: not rigid: det R = -1, must be +1 (a reflection) (value [-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, "
            "0, 0, 0, 1])");
  // Rounded to 4 digits: accepted, and made exactly orthonormal.
  const Eigen::Isometry3d r =
      rigid_to_organ({0.7071, -0.7071, 0, 0, 0.7071, 0.7071, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}, "to_organ");
  EXPECT_LT((r.linear().transpose() * r.linear() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), kTrackTight);
  EXPECT_LT((r.linear() - rot_z(kPi / 4)).cwiseAbs().maxCoeff(), 1e-4);
}

TEST(PoseVelocity, LinearAndAngularBetweenTwoPoses) {
  // From 0.5 rad about x to 0.3 rad about z after it, 4 mm along y, in 0.1 s.
  const Eigen::Quaterniond a_rot(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitX()));
  const Pose a = pose_of({0, 0.01, 0}, a_rot);
  Pose b = pose_of({0, 0.014, 0}, about_z(0.3) * a_rot);
  const PoseVelocity v = velocity_between(a, b, 0.1);
  EXPECT_LT((v.linear - Eigen::Vector3d(0, 0.04, 0)).norm(), kTrackTight);
  EXPECT_LT((v.angular - Eigen::Vector3d(0, 0, 3.0)).norm(), kTrackTight);
  // -q is the same rotation: the same (short-arc) angular velocity.
  b.rotation.coeffs() = -b.rotation.coeffs();
  EXPECT_LT((velocity_between(a, b, 0.1).angular - Eigen::Vector3d(0, 0, 3.0)).norm(), kTrackTight);
  // At rest.
  EXPECT_LT(velocity_between(a, a, 0.1).angular.norm(), kTrackTight);
}
