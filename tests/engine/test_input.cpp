// Input sources: track interpolation against hand-computed values; replay CSV parsing and its errors.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "engine/input.hpp"
#include "support/files.hpp"

using namespace lumen::engine;

namespace {
using lumen::test::write_temp;
std::string replay_error_of(const std::string& path) {
  try {
    ReplaySource s(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(TrackSource, InterpolatesLinearlyAndHoldsOutside) {
  TrackSource src({0, 0.013, 0.05}, {{0.5, {0, 0, 0}}, {1.5, {0, -1, 2}}, {2.0, {1, -1, 2}}});
  EXPECT_EQ(src.sample(0.0).force, Eigen::Vector3d(0, 0, 0));
  EXPECT_TRUE(src.sample(1.0).force.isApprox(Eigen::Vector3d(0, -0.5, 1.0)));
  EXPECT_TRUE(src.sample(1.75).force.isApprox(Eigen::Vector3d(0.5, -1, 2)));
  EXPECT_EQ(src.sample(10.0).force, Eigen::Vector3d(1, -1, 2));
  EXPECT_EQ(src.sample(1.0).point, Eigen::Vector3d(0, 0.013, 0.05));
}

TEST(TrackSource, DisplacementDrivenGivesTheDisplacement) {
  TrackSource src({0, 0.013, 0.05}, {{0.0, {0, 0, 0}}, {1.0, {0, -0.004, 0}}}, ProbeDrive::Displacement);
  const ProbeSample s = src.sample(0.5);
  EXPECT_TRUE(s.displacement_driven);
  EXPECT_TRUE(s.displacement.isApprox(Eigen::Vector3d(0, -0.002, 0)));
  EXPECT_EQ(s.force, Eigen::Vector3d::Zero());
}

TEST(ReplaySource, ReadsAndInterpolates) {
  auto path = write_temp("replay_ok.csv", "t,x,y,z,fx,fy,fz\n0,0,0.013,0.05,0,0,0\n1.0, 0,0.013,0.05, 0,-0.2,0\n");
  ReplaySource src(path);
  EXPECT_TRUE(src.point_is_fixed());
  EXPECT_TRUE(src.sample(0.25).force.isApprox(Eigen::Vector3d(0, -0.05, 0)));
  src.feedback(0.25, {0, 0.05, 0});
  EXPECT_EQ(src.reactions().size(), 1u);
}

TEST(ReplaySource, MovingPointIsNotFixed) {
  auto path = write_temp("replay_move.csv", "0,0,0.013,0.05,0,0,0\n1,0,0.013,0.06,0,-0.2,0\n");
  ReplaySource src(path);
  EXPECT_FALSE(src.point_is_fixed());
  EXPECT_TRUE(src.sample(0.5).point.isApprox(Eigen::Vector3d(0, 0.013, 0.055)));
}

TEST(ReplaySource, ErrorsNameFileLineFieldAndValue) {
  auto p1 = write_temp("replay_bad1.csv", "0,0,0.013,0.05,0,0,0\n1,0,0.013,abc,0,0,0\n");
  EXPECT_EQ(replay_error_of(p1), p1 + ": line 2: field z: not a number (value \"abc\")");
  auto p2 = write_temp("replay_bad2.csv", "0,0,0.013,0.05,0,0\n");
  EXPECT_EQ(replay_error_of(p2), p2 + ": line 1: expected 7 fields (t, x, y, z, fx, fy, fz), got 6");
  auto p3 = write_temp("replay_bad3.csv", "0,0,0.013,0.05,0,0,0\n0,0,0.013,0.05,0,0,0\n");
  EXPECT_EQ(replay_error_of(p3), p3 + ": line 2: field t: times must be strictly increasing (value 0.000000)");
  auto p4 = write_temp("replay_bad4.csv", "0,0,0.013,0.05,0,nan,0\n");
  EXPECT_EQ(replay_error_of(p4), p4 + ": line 1: field fy: must be finite (value nan)");
  auto p5 = write_temp("replay_empty.csv", "# nothing\n");
  EXPECT_EQ(replay_error_of(p5), p5 + ": no samples (expected lines t, x, y, z, fx, fy, fz)");
  EXPECT_EQ(replay_error_of("/nonexistent/r.csv"), "/nonexistent/r.csv: cannot read replay file");
}
