// Scene-selected material models: corotational agrees with linear as the load goes to zero (relative difference
// shrinking linearly with the load) and is reported per frame; unsupported combinations are refused.
#include <gtest/gtest.h>

#include <limits>
#include <memory>
#include <vector>

#include "engine/simulation.hpp"

using namespace lumen;

namespace {
std::string scene_text(const std::string& model, double force, const std::string& drive = "force") {
  return R"({"name": "m", "mesh": {"type": "hollow_cylinder", "inner_radius": 0.01, "outer_radius": 0.013,
    "length": 0.08, "segments_around": 12, "segments_along": 8, "layers": 2},
    "material": {"model": ")" + model + R"(", "young_modulus": 5000.0, "poisson_ratio": 0.45},
    "fixed": ["ends"],
    "probes": [{"point": [0.0, 0.013, 0.04], "track": [{"t": 0, ")" + drive + R"(": [0, 0, 0]},
               {"t": 0.25, ")" + drive + R"(": [0, )" + std::to_string(-force) + R"(, 0]}]}],
    "frames": 10, "fps": 40})";
}
Eigen::VectorXd final_u(const std::string& model, double force) {
  const engine::Scene scene = engine::parse_scene(scene_text(model, force), "m.json");
  auto m = engine::compile_model(scene);
  engine::Inputs in = engine::make_inputs(scene);
  engine::State s = engine::make_state(*m);
  engine::FrameRecord rec;
  for (int i = 0; i < 10; ++i) {
    engine::step(*m, in, s, rec);
    if (model == "corotational") {
      EXPECT_TRUE(rec.physics_converged);
      EXPECT_FALSE(rec.numerical_failure);
    }
  }
  return s.sim.u;
}
}  // namespace

TEST(Models, CorotationalMatchesLinearInTheSmallLoadLimit) {
  double previous = 1.0;
  for (double force : {1e-2, 1e-3, 1e-4}) {
    const Eigen::VectorXd lin = final_u("linear", force), cor = final_u("corotational", force);
    const double rel = (cor - lin).norm() / lin.norm();
    EXPECT_LT(rel, 0.3 * previous) << "force " << force;  // shrinks about 10x per 10x less load
    previous = rel;
  }
  EXPECT_LT(previous, 1e-3);
}

TEST(Models, CorotationalRefusesDisplacementDrivenProbes) {
  try {
    engine::compile_model(engine::parse_scene(scene_text("corotational", 0.001, "displacement"), "m.json"));
    FAIL();
  } catch (const engine::InputError& e) {
    EXPECT_STREQ(e.what(), "m.json: probes[0].track: displacement-driven probes need material.model \"linear\" (value \"corotational\")");
  }
}

namespace {
// A faulty device: NaN on some frames, a real force otherwise.
class FlakySource final : public engine::InputSource {
 public:
  std::string kind() const override { return "device"; }
  engine::ProbeSample sample(double t) override {
    engine::ProbeSample s;
    s.point = Eigen::Vector3d(0.0, 0.013, 0.04);
    s.force = Eigen::Vector3d(0, -0.004 * t, 0);
    if (++calls_ % 3 == 0) s.force.y() = std::numeric_limits<double>::quiet_NaN();
    return s;
  }
  void feedback(double, const Eigen::Vector3d& reaction) override { reactions.push_back(reaction); }
  std::vector<Eigen::Vector3d> reactions;

 private:
  int calls_ = 0;
};
}  // namespace

TEST(Models, FaultyDeviceIsDetectedReportedAndSurvived) {
  const engine::Scene scene = engine::parse_scene(scene_text("linear", 0.004), "m.json");
  auto m = engine::compile_model(scene);
  engine::Inputs in = engine::make_inputs(scene);
  engine::State s = engine::make_state(*m);
  auto device = std::make_unique<FlakySource>();
  FlakySource* dev = device.get();
  in.sources[0] = std::move(device);
  engine::FrameRecord rec;
  int failures = 0;
  for (int i = 0; i < 12; ++i) {
    engine::step(*m, in, s, rec);
    failures += rec.bad_input;
    EXPECT_EQ(rec.bad_input, (i + 1) % 3 == 0) << "frame " << rec.frame;
    EXPECT_TRUE(s.sim.u.allFinite());
    EXPECT_TRUE(rec.reactions[0].allFinite());
  }
  EXPECT_EQ(failures, 4);
  EXPECT_EQ(s.failures, 4);
  EXPECT_EQ(dev->reactions.size(), 12u);
  // Frame 12 was a bad one: it used frame 11's sample, the last good one.
  EXPECT_NEAR(rec.reactions[0].y(), 0.004 * 11 / 40.0, 1e-15);
}

// The scene's solver keys bound the corotational solve: one outer iteration cannot converge on a nonlinear
// load, and a tighter tolerance costs more iterations and lands closer to the tight solution.
TEST(Models, SolverKeysBoundTheCorotationalSolve) {
  auto first_frame = [](const std::string& solver, engine::FrameRecord& rec) {
    std::string text = scene_text("corotational", 0.1);
    const std::string key = "\"fps\": 40}", first_key = R"({"t": 0, "force": [0, 0, 0]},)";
    text.replace(text.find(key), key.size(), "\"fps\": 40, \"solver\": " + solver + "}");
    text.erase(text.find(first_key), first_key.size());  // the full load from the first frame on
    const std::string mesh = R"("segments_around": 12, "segments_along": 8, "layers": 2)";
    text.replace(text.find(mesh), mesh.size(), R"("segments_around": 8, "segments_along": 4, "layers": 1)");
    const engine::Scene scene = engine::parse_scene(text, "m.json");
    auto m = engine::compile_model(scene);
    engine::Inputs in = engine::make_inputs(scene);
    engine::State s = engine::make_state(*m);
    engine::step(*m, in, s, rec);
    return s.sim.u;
  };
  engine::FrameRecord one, loose, tight, tighter;
  first_frame(R"({"max_iterations": 1})", one);
  EXPECT_EQ(one.physics_iterations, 1);
  EXPECT_FALSE(one.physics_converged);
  const Eigen::VectorXd u_loose = first_frame(R"({"tolerance": 0.01})", loose);
  const Eigen::VectorXd u_tight = first_frame(R"({"tolerance": 1e-6, "max_iterations": 100})", tight);
  const Eigen::VectorXd u_ref = first_frame(R"({"tolerance": 1e-9, "max_iterations": 100})", tighter);
  EXPECT_TRUE(loose.physics_converged);
  EXPECT_TRUE(tight.physics_converged);
  EXPECT_TRUE(tighter.physics_converged);
  EXPECT_GT(tight.physics_iterations, loose.physics_iterations);
  EXPECT_LT((u_tight - u_ref).norm(), (u_loose - u_ref).norm());
}

// A corotational frame whose solve diverges (its lagged factorisation injected far softer than the tangent) is a
// numerical failure: reported, the last good frame kept exactly, nothing non-finite committed; once the
// factorisation the guard asked for is in, the frames converge again.
TEST(Models, ADivergingCorotationalFrameIsReportedAndTheLastGoodFrameKept) {
  constexpr double kSoftening = 1e-6;
  std::string text = scene_text("corotational", 0.02);
  const std::string key = "\"fps\": 40}";
  text.replace(text.find(key), key.size(), R"("fps": 40, "solver": {"method": "chord", "background_factorisation": true}})");
  const engine::Scene scene = engine::parse_scene(text, "m.json");
  auto m = engine::compile_model(scene);
  engine::Inputs in = engine::make_inputs(scene);
  engine::State s = engine::make_state(*m);
  engine::FrameRecord rec;
  for (int i = 0; i < 4; ++i) {
    engine::step(*m, in, s, rec);
    ASSERT_FALSE(rec.numerical_failure);
  }
  const Eigen::VectorXd last_good = s.sim.u;
  physics::CorotationalState& solve = s.work.corotational;
  if (solve.pending.valid()) solve.pending.wait();
  solve.pending = {};
  solve.preconditioner = std::make_shared<const physics::StaticSolver>(m->integrator->contact_solver().scaled(kSoftening));

  engine::step(*m, in, s, rec);
  EXPECT_TRUE(rec.physics_diverged);
  EXPECT_TRUE(rec.numerical_failure);
  EXPECT_FALSE(rec.physics_converged);
  EXPECT_EQ(s.sim.u, last_good);
  EXPECT_EQ(s.failures, 1);
  ASSERT_TRUE(solve.pending.valid());  // the guard's factorisation, on the second core
  solve.pending.wait();
  for (int i = 0; i < 5; ++i) {
    engine::step(*m, in, s, rec);
    EXPECT_FALSE(rec.physics_diverged) << "frame " << rec.frame;
    EXPECT_FALSE(rec.numerical_failure) << "frame " << rec.frame;
    EXPECT_TRUE(rec.physics_converged) << "frame " << rec.frame;
    EXPECT_TRUE(s.sim.u.allFinite());
  }
  EXPECT_GT(s.sim.u.norm(), last_good.norm());  // the load kept growing and the wall followed it
}

// A frame whose solve returns a finite displacement far beyond anything an organ does (here the linear model under
// a force ramped past the point where the tube would move 10 times its own size) is a numerical failure too: the
// frames below that point commit, the ones above keep the last good frame.
TEST(Models, AnImplausiblyLargeDisplacementIsANumericalFailure) {
  constexpr double kProbeForce = 0.004, kBeyond = 2.2;  // the ramp's end: 2.2 x the force at the bound
  struct Run {
    double bound = 0.0;  // the model's max_displacement, metres
    int failures = 0;
    Eigen::VectorXd u_end, u_at_4;  // committed displacements at the end and after frame 4
    std::vector<engine::FrameRecord> records;
  };
  auto run = [](double force) {
    const engine::Scene scene = engine::parse_scene(scene_text("linear", force), "m.json");
    auto m = engine::compile_model(scene);
    engine::Inputs in = engine::make_inputs(scene);
    engine::State s = engine::make_state(*m);
    Run r;
    r.bound = m->max_displacement;
    r.records.resize(10);
    for (int i = 0; i < 10; ++i) {
      engine::step(*m, in, s, r.records[i]);
      EXPECT_TRUE(s.sim.u.allFinite());
      if (i == 3) r.u_at_4 = s.sim.u;
    }
    r.failures = s.failures;
    r.u_end = s.sim.u;
    return r;
  };
  const Run small = run(kProbeForce);
  const double at_full = small.records.back().max_displacement;  // metres at kProbeForce (linear: proportional)
  ASSERT_EQ(small.failures, 0);
  ASSERT_GT(at_full, 0.0);
  ASSERT_LT(at_full, small.bound);
  const Run large = run(kBeyond * kProbeForce * small.bound / at_full);
  for (int i = 0; i < 10; ++i) {
    const bool beyond = (i + 1) / 10.0 * kBeyond > 1.0;  // frame i+1 carries (i+1)/10 of the ramp's end
    EXPECT_EQ(large.records[i].numerical_failure, beyond) << "frame " << i + 1;
    EXPECT_FALSE(large.records[i].physics_diverged);
    EXPECT_LE(large.records[i].max_displacement, large.bound) << "frame " << i + 1;
  }
  EXPECT_EQ(large.failures, 6);
  EXPECT_EQ(large.u_end, large.u_at_4);  // frames 5-10 kept frame 4
}
