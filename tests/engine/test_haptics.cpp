// The haptic loop: the coupling formula against hand computations, saturation, fading, non-finite models, the
// loop thread rendering what the simulation published, the `haptics` scene keys and their errors, and the local
// stiffness K of an instrument in contact against finite differences of the frame's solve.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <string>
#include <thread>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "engine/haptics.hpp"
#include "engine/session.hpp"
#include "support/build.hpp"
#include "support/files.hpp"
#include "support/instruments.hpp"

using namespace lumen::engine;
using lumen::test::message_of;
using nlohmann::json;

namespace {

// A model in contact: 0.5 N up, stiffness 200 N/m along y and 50 N/m along x, published at t = 1 s.
HapticModel contact_model() {
  HapticModel m;
  m.valid = true;
  m.time_s = 1.0;
  m.x_frame = Eigen::Vector3d(0.0, 0.012, 0.05);
  m.f_frame = Eigen::Vector3d(0.0, 0.5, 0.0);
  m.stiffness = Eigen::Vector3d(50.0, 200.0, 0.0).asDiagonal();
  return m;
}

HapticsSpec spec_with_damping(double c) {
  HapticsSpec s;
  s.damping_n_s_per_m = c;
  return s;
}

}  // namespace

TEST(Haptics, CouplingFormulaMatchesAHandComputation) {
  const HapticsSpec spec = spec_with_damping(2.0);
  const HapticModel m = contact_model();
  // The device 1 mm further down and 2 mm along x, moving down at 0.1 m/s, 10 ms after the model:
  // f = (0, 0.5, 0) - diag(50, 200, 0) (0.002, -0.001, 0) - 2 (0, -0.1, 0) = (-0.1, 0.5 + 0.2 + 0.2, 0).
  const HapticForce f =
      render_force(spec, m, m.x_frame + Eigen::Vector3d(0.002, -0.001, 0.0), Eigen::Vector3d(0.0, -0.1, 0.0), 1.01);
  EXPECT_NEAR(f.force.x(), -0.1, 1e-12);
  EXPECT_NEAR(f.force.y(), 0.9, 1e-12);
  EXPECT_EQ(f.force.z(), 0.0);
  EXPECT_EQ(f.weight, 1.0);
  EXPECT_FALSE(f.clamped);
}

TEST(Haptics, TheForceIsSaturatedAlongItsDirection) {
  HapticsSpec spec = spec_with_damping(0.0);
  spec.max_force_n = 0.6;
  const HapticModel m = contact_model();
  // Unclamped: (-0.1, 0.9, 0); clamped to 0.6 N along it.
  const HapticForce f = render_force(spec, m, m.x_frame + Eigen::Vector3d(0.002, -0.002, 0.0), Eigen::Vector3d::Zero(), 1.0);
  EXPECT_TRUE(f.clamped);
  EXPECT_NEAR(f.force.norm(), 0.6, 1e-12);
  EXPECT_NEAR(f.force.normalized().dot(Eigen::Vector3d(-0.1, 0.9, 0.0).normalized()), 1.0, 1e-12);
}

TEST(Haptics, FadeIsOneWhileFreshThenLinearToZero) {
  HapticsSpec spec;
  spec.stale_after_s = 0.1;
  spec.fade_s = 0.05;
  EXPECT_EQ(fade_weight(spec, 0.0), 1.0);
  EXPECT_EQ(fade_weight(spec, 0.1), 1.0);
  EXPECT_NEAR(fade_weight(spec, 0.125), 0.5, 1e-12);
  EXPECT_NEAR(fade_weight(spec, 0.15), 0.0, 1e-12);
  EXPECT_EQ(fade_weight(spec, 5.0), 0.0);
  // The rendered force follows: a model 125 ms old gives half of the fresh force.
  const HapticModel m = contact_model();
  const Eigen::Vector3d x = m.x_frame + Eigen::Vector3d(0.0, -0.001, 0.0);
  const HapticForce fresh = render_force(spec, m, x, Eigen::Vector3d::Zero(), 1.0);
  const HapticForce old = render_force(spec, m, x, Eigen::Vector3d::Zero(), 1.125);
  EXPECT_NEAR((old.force - 0.5 * fresh.force).norm(), 0.0, 1e-12);
}

TEST(Haptics, NonFiniteOrMissingModelsAndNoContactRenderNothing) {
  const HapticsSpec spec;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  HapticModel m = contact_model();
  m.stiffness(1, 1) = nan;
  EXPECT_EQ(render_force(spec, m, m.x_frame, Eigen::Vector3d::Zero(), 1.0).force, Eigen::Vector3d::Zero());
  m = contact_model();
  EXPECT_EQ(render_force(spec, m, Eigen::Vector3d(nan, 0, 0), Eigen::Vector3d::Zero(), 1.0).force, Eigen::Vector3d::Zero());
  m.valid = false;
  EXPECT_EQ(render_force(spec, m, m.x_frame, Eigen::Vector3d::Zero(), 1.0).force, Eigen::Vector3d::Zero());
  // No contact: nothing at all, damping included (no force towards the tissue).
  HapticModel free;
  free.valid = true;
  free.time_s = 1.0;
  const HapticForce f = render_force(spec_with_damping(5.0), free, Eigen::Vector3d(0, 0.02, 0), Eigen::Vector3d(0, 1, 0), 1.0);
  EXPECT_EQ(f.force, Eigen::Vector3d::Zero());
}

TEST(Haptics, TheSpringNeverPullsTheDeviceTowardsTheTissue) {
  const HapticsSpec spec = spec_with_damping(0.0);
  const HapticModel m = contact_model();
  // 5 mm above the frame's tip: the linear model would give 0.5 - 200 * 0.005 = -0.5 N (a pull); the normal
  // component is dropped, the tangential one (-50 * 0.001 along x) stays.
  const HapticForce f = render_force(spec, m, m.x_frame + Eigen::Vector3d(0.001, 0.005, 0.0), Eigen::Vector3d::Zero(), 1.0);
  EXPECT_EQ(f.force.y(), 0.0);
  EXPECT_NEAR(f.force.x(), -0.05, 1e-12);
}

TEST(Haptics, StiffnessIsSymmetrisedAndItsEigenvaluesClamped) {
  // K = R diag(5000, 100, -3) R^T plus an antisymmetric part: eigenvalues (3000, 100, 0) after clamping.
  const Eigen::Matrix3d r = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  Eigen::Matrix3d skew;
  skew << 0, 1, -2, -1, 0, 4, 2, -4, 0;
  const Eigen::Matrix3d k = r * Eigen::Vector3d(5000.0, 100.0, -3.0).asDiagonal() * r.transpose() + skew;
  bool clamped = false;
  const Eigen::Matrix3d c = clamp_stiffness(k, 3000.0, clamped);
  EXPECT_TRUE(clamped);
  const Eigen::Matrix3d expected = r * Eigen::Vector3d(3000.0, 100.0, 0.0).asDiagonal() * r.transpose();
  EXPECT_LE((c - expected).norm(), 1e-9 * expected.norm());
  clamp_stiffness(100.0 * Eigen::Matrix3d::Identity(), 3000.0, clamped);
  EXPECT_FALSE(clamped);
}

TEST(HapticLoop, RendersThePublishedModelAtTheDevicesPoseAndFadesWhenNoneComes) {
  HapticsSpec spec = spec_with_damping(0.0);
  spec.stale_after_s = 0.002;
  spec.fade_s = 0.002;
  auto device = std::make_shared<PoseChannel>();
  const auto epoch = std::chrono::steady_clock::now();
  auto clock = [epoch] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - epoch).count(); };
  // The sink sees the fresh model's force (weight 1), then, with no new model, the weight reach 0.
  std::atomic<long> ticks{0};
  std::atomic<bool> saw_force{false}, faded{false};
  HapticLoop loop(spec, {device}, clock, [&](const std::vector<HapticForce>& f, double) {
    ++ticks;
    if (f[0].weight == 1.0 && std::abs(f[0].force.y() - 0.7) < 1e-12) saw_force = true;
    if (saw_force && f[0].weight == 0.0) faded = true;
  });
  // The device 1 mm into the model's contact: 0.5 + 200 * 0.001 = 0.7 N up.
  const HapticModel m = contact_model();
  DeviceSample s;
  s.pose.position = m.x_frame + Eigen::Vector3d(0.0, -0.001, 0.0);
  s.seq = 1;
  s.time_s = clock();
  device->write(s);
  InstrumentRecord rec;
  rec.position = m.x_frame;
  rec.force = m.f_frame;
  rec.stiffness = m.stiffness;
  loop.start();
  // Publish (as the simulation does each frame) until the loop has rendered a fresh model, then stop and wait for
  // the fade; bounded (60 s of 100 us waits), not a timing requirement.
  constexpr int kMaxWaits = 600000;
  for (int i = 0; i < kMaxWaits && !saw_force; ++i) {
    loop.publish(0, rec);
    std::this_thread::sleep_for(std::chrono::microseconds(100));
  }
  for (int i = 0; i < kMaxWaits && !faded; ++i) std::this_thread::sleep_for(std::chrono::microseconds(100));
  loop.stop();
  EXPECT_TRUE(saw_force);
  EXPECT_TRUE(faded);
  const HapticStats st = loop.stats();
  EXPECT_EQ(st.ticks, ticks.load());
  EXPECT_GT(st.faded_ticks, 0);
  EXPECT_GT(st.rate_hz, 0.0);
  EXPECT_GE(st.period_p99_ms, st.period_p50_ms);
}

TEST(HapticsScene, KeysAreReadAndEveryBadValueIsRefusedByName) {
  json s = lumen::test::small_tube_scene("haptics");
  s["frames"] = 10;
  s["haptics"] = {{"rate_hz", 500}, {"max_force_n", 3.3}, {"max_stiffness_n_per_m", 1200},
                  {"damping_n_s_per_m", 0}, {"stale_after_s", 0.2}, {"fade_s", 0.02}};
  const HapticsSpec h = parse_scene(s.dump(), "dir/s.json").haptics;
  EXPECT_EQ(h.rate_hz, 500.0);
  EXPECT_EQ(h.max_force_n, 3.3);
  EXPECT_EQ(h.max_stiffness_n_per_m, 1200.0);
  EXPECT_EQ(h.damping_n_s_per_m, 0.0);
  EXPECT_EQ(h.stale_after_s, 0.2);
  EXPECT_EQ(h.fade_s, 0.02);
  json plain = s;
  plain.erase("haptics");
  const HapticsSpec defaults = parse_scene(plain.dump(), "dir/s.json").haptics;
  EXPECT_EQ(defaults.rate_hz, 1000.0);
  EXPECT_EQ(defaults.stale_after_s, 0.1);
  auto error_with = [&](const char* key, const json& value) {
    json bad = s;
    bad["haptics"][key] = value;
    return message_of<InputError>([&] { parse_scene(bad.dump(), "dir/s.json"); });
  };
  EXPECT_EQ(error_with("rate_hz", 0), "dir/s.json: haptics.rate_hz: out of range (0, 10000] (value 0)");
  EXPECT_EQ(error_with("rate_hz", 20000), "dir/s.json: haptics.rate_hz: out of range (0, 10000] (value 20000)");
  EXPECT_EQ(error_with("max_force_n", -1), "dir/s.json: haptics.max_force_n: must be > 0 (value -1)");
  EXPECT_EQ(error_with("max_stiffness_n_per_m", 0), "dir/s.json: haptics.max_stiffness_n_per_m: must be > 0 (value 0)");
  EXPECT_EQ(error_with("damping_n_s_per_m", -0.5), "dir/s.json: haptics.damping_n_s_per_m: must be >= 0 (value -0.5)");
  EXPECT_EQ(error_with("stale_after_s", "soon"), "dir/s.json: haptics.stale_after_s: must be a number (value \"soon\")");
  EXPECT_EQ(error_with("fade_s", 0), "dir/s.json: haptics.fade_s: must be > 0 (value 0)");
  EXPECT_EQ(error_with("rate", 1000), "dir/s.json: haptics.rate: unknown key");
}

namespace {

// A track whose pose at one time (the probed frame's end) is shifted by `offset`.
class ShiftedTrack final : public PoseSource {
 public:
  ShiftedTrack(PoseTrack track, double t_shift, const Eigen::Vector3d& offset)
      : track_(std::move(track)), t_shift_(t_shift), offset_(offset) {}
  std::string kind() const override { return "track"; }
  Pose pose(double t) override {
    Pose p = track_.at(t);
    if (t == t_shift_) p.position += offset_;
    return p;
  }
  void feedback(double, const InstrumentRecord&) override {}

 private:
  PoseTrack track_;
  double t_shift_;
  Eigen::Vector3d offset_;
};

// The force on the instrument and its stiffness at the last of `frames` frames, the tool shifted by `offset`
// at that frame's end.
InstrumentRecord last_record(const Model& model, const Scene& scene, int frames, const Eigen::Vector3d& offset) {
  Inputs in;
  in.instruments.push_back(std::make_unique<ShiftedTrack>(PoseTrack(scene.instruments[0].poses, scene.path),
                                                          frames / scene.fps, offset));
  SessionOptions opt;
  opt.frames = frames;
  opt.render = false;
  return run_session(model, std::move(in), opt).frames.back().instruments[0];
}

// Central differences of the force on the instrument over a 1 micrometre shift of the tool at the last of `frames`
// frames, column j for axis j: -dF/dx, the stiffness the frame's solve implies. Each shifted run must keep the
// base run's contacts and held nodes (the force is linear in the shift only while those stay).
void finite_difference_stiffness(const Model& model, const Scene& scene, int frames, const InstrumentRecord& base,
                                 Eigen::Matrix3d& fd) {
  constexpr double kStep = 1e-6;
  for (int j = 0; j < 3; ++j) {
    const Eigen::Vector3d e = kStep * Eigen::Vector3d::Unit(j);
    const InstrumentRecord plus = last_record(model, scene, frames, e);
    const InstrumentRecord minus = last_record(model, scene, frames, -e);
    ASSERT_EQ(plus.held_nodes, base.held_nodes);
    ASSERT_EQ(minus.held_nodes, base.held_nodes);
    ASSERT_EQ(plus.contacts, base.contacts);
    ASSERT_EQ(minus.contacts, base.contacts);
    fd.col(j) = -(plus.force - minus.force) / (2.0 * kStep);
  }
}

}  // namespace

TEST(HapticsStiffness, LocalStiffnessMatchesFiniteDifferencesOfTheFrameSolve) {
  // A 3 mm probe pressed 2 mm into the small tube from above, then held.
  json s = lumen::test::small_tube_scene("stiffness");
  constexpr double kOuterRadius = 0.013, kDepth = 0.002;
  s["instruments"] = {{{"name", "probe"},
                       {"shape", {{"type", "sphere_probe"}, {"tip_radius", 0.003}, {"shaft_radius", 0.002},
                                  {"shaft_length", 0.04}}},
                       {"track", {{{"t", 0.0}, {"position", {0.0, kOuterRadius + 0.0005, 0.05}}},
                                  {{"t", 0.4}, {"position", {0.0, kOuterRadius - kDepth, 0.05}}}}}}};
  s["collision"] = {{"self", true}, {"gap", 1e-4}};
  s["frames"] = 18;
  const Scene scene = parse_scene(s.dump(), "stiffness.json");
  const auto model = compile_model(scene);
  constexpr int kFrames = 18;
  const InstrumentRecord base = last_record(*model, scene, kFrames, Eigen::Vector3d::Zero());
  ASSERT_GT(base.contacts, 0);
  ASSERT_GT(base.stiffness.norm(), 0.0);
  // Central differences of the force on the tool over a 1 micrometre shift of the tip: -dF/dx = K.
  Eigen::Matrix3d fd;
  ASSERT_NO_FATAL_FAILURE(finite_difference_stiffness(*model, scene, kFrames, base, fd));
  // The frame's force is linear in the tool's position while the pushing set stays (measured: 4e-12 relative).
  EXPECT_LE((fd - base.stiffness).norm(), 1e-6 * base.stiffness.norm()) << "K\n" << base.stiffness << "\nFD\n" << fd;
  // The press is vertical: the stiffest direction is y.
  EXPECT_GT(base.stiffness(1, 1), base.stiffness(0, 0));
}

// The same for a grasper holding the wall: its held nodes move with it, so the hold is part of its stiffness. The
// shipped grasper scene on a coarser tube (each of the seven sessions builds its contact compliance; under the
// sanitizers coarser still: 97-146 s there on 20 x 24), half-way through the lift.
TEST(HapticsStiffness, LocalStiffnessOfAGraspIncludesTheHoldAndMatchesFiniteDifferences) {
  std::ifstream file(std::string(LUMEN_SOURCE_DIR) + "/scenes/instrument-grasper-lift.json");
  json s = json::parse(file);
  // The shipped scene: 32 x 40.
  constexpr bool kFine = lumen::test::kOptimised;
  constexpr int kGraspTestAround = kFine ? 20 : 14, kGraspTestAlong = kFine ? 24 : 16;
  s["mesh"]["segments_around"] = kGraspTestAround;
  s["mesh"]["segments_along"] = kGraspTestAlong;
  const Scene scene = parse_scene(s.dump(), "grasp-stiffness.json");
  const auto model = compile_model(scene);
  constexpr int kFrames = 80;  // 2.0 s: lifting, holding
  const InstrumentRecord base = last_record(*model, scene, kFrames, Eigen::Vector3d::Zero());
  ASSERT_FALSE(base.held_nodes.empty()) << "not holding at the probed frame";
  ASSERT_GT(base.stiffness.norm(), 0.0);
  // Central differences of the force on the grasper (contacts and hold) over a 1 micrometre shift.
  Eigen::Matrix3d fd;
  ASSERT_NO_FATAL_FAILURE(finite_difference_stiffness(*model, scene, kFrames, base, fd));
  EXPECT_LE((fd - base.stiffness).norm(), 1e-6 * base.stiffness.norm()) << "K\n" << base.stiffness << "\nFD\n" << fd;
  // Every direction resists: the held wall is pulled along whichever way the grasper moves.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(base.stiffness);
  EXPECT_GT(eig.eigenvalues().minCoeff(), 0.0) << base.stiffness;
}
