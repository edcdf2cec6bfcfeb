// Elastic supports (scene key "support"): springs to rest on the outer wall, k times each node's lumped area.
// Checked against the polygon prism's area, and against the stiff-support limit where a node's own spring carries
// the load (u = F / (k A)); the keys' errors name the key and the value.
#include <gtest/gtest.h>

#include <cmath>

#include <nlohmann/json.hpp>

#include "engine/scene.hpp"
#include "engine/session.hpp"
#include "engine/simulation.hpp"
#include "physics/support.hpp"
#include "support/files.hpp"
#include "support/instruments.hpp"
#include "support/tube.hpp"

using namespace lumen;
using nlohmann::json;

namespace {

// The small tube's outer wall: 12 sides of radius 13 mm, 0.1 m long, 10 cells along.
constexpr int kAround = 12, kAlong = 10;
using lumen::test::kPaperOuterRadius;
constexpr double kLength = 0.1;
double chord() { return 2.0 * kPaperOuterRadius * std::sin(EIGEN_PI / kAround); }

}  // namespace

TEST(Support, LumpedAreasSumToThePolygonPrismAndStiffnessIsKTimesThem) {
  json scene = test::small_tube_scene("areas");
  scene["frames"] = 1;
  const auto model = engine::compile_model(engine::parse_scene(scene.dump(), "areas.json"));
  const Eigen::VectorXd area = physics::lumped_areas(model->mesh.rest, model->outer_wall());
  EXPECT_NEAR(area.sum(), kAround * chord() * kLength, 1e-15);
  constexpr double k = 2500.0;
  const Eigen::SparseMatrix<double> S = physics::support_stiffness(model->mesh.rest, model->outer_wall(), k);
  EXPECT_EQ(S.nonZeros(), 3 * (area.array() > 0).count());
  for (Eigen::Index v = 0; v < area.size(); ++v)
    for (int d = 0; d < 3; ++d) EXPECT_DOUBLE_EQ(S.coeff(3 * v + d, 3 * v + d), k * area[v]);
}

// Springs much stiffer than the wall: the loaded node moves F / (k A) with A its lumped area, the area of one
// quad of the outer wall (chord x cell length) for a node inside the wall; unsupported it moves far more.
TEST(Support, StiffSupportsCarryTheLoadOnTheNodesOwnSpring) {
  auto displacement = [](double k) {
    json s = test::small_tube_scene("supported");
    s["frames"] = 1;
    // At an outer-wall node: angle 0, mid-length (ring 5 of 10).
    s["probes"] = json::parse(R"([{"name": "p", "point": [0.013, 0.0, 0.05],
                                   "track": [{"t": 0.0, "force": [-0.01, 0, 0]}]}])");
    if (k > 0) s["support"] = {{"stiffness_n_per_m3", k}};
    const auto model = engine::compile_model(engine::parse_scene(s.dump(), "supported.json"));
    engine::SessionOptions opt;
    opt.render = false;
    const engine::SessionResult r = engine::run_session(*model, engine::make_inputs(engine::parse_scene(s.dump(), "supported.json")), opt);
    return r.frames.back().probe_displacement[0];
  };
  constexpr double kStiff = 1e10, kForce = 0.01;
  const double node_area = chord() * kLength / kAlong;
  const Eigen::Vector3d stiff = displacement(kStiff);
  EXPECT_NEAR(stiff.x(), -kForce / (kStiff * node_area), 1e-3 * kForce / (kStiff * node_area));
  EXPECT_NEAR(stiff.y(), 0.0, 1e-12);
  // Softer supports: the wall shares the load, so the node moves less than its spring alone would allow ...
  constexpr double kSoft = 1e5;
  const Eigen::Vector3d soft = displacement(kSoft);
  EXPECT_GT(soft.x(), -kForce / (kSoft * node_area));
  // ... and more than with stiffer springs; without supports most of all.
  EXPECT_LT(soft.x(), stiff.x());
  EXPECT_LT(displacement(0.0).x(), soft.x());
}

TEST(Support, KeysAreValidatedAndNeedA4NodeModel) {
  auto error_of = [](const json& s) { return test::message_of<engine::InputError>([&] { engine::parse_scene(s.dump(), "s.json"); }); };
  json s = test::small_tube_scene("keys");
  s["frames"] = 1;
  s["support"] = {{"stiffness_n_per_m3", -1.0}};
  EXPECT_NE(error_of(s).find("support.stiffness_n_per_m3"), std::string::npos) << error_of(s);
  s["support"] = {{"stiffness", 1.0}};
  EXPECT_NE(error_of(s).find("stiffness"), std::string::npos) << error_of(s);
  s["support"] = json::object();
  EXPECT_NE(error_of(s).find("stiffness_n_per_m3"), std::string::npos) << error_of(s);
  s["support"] = {{"stiffness_n_per_m3", 1000.0}};
  s["mesh"]["element"] = "tet10";
  EXPECT_EQ(error_of(s), "s.json: support: needs mesh.element \"tet4\" (value {\"stiffness_n_per_m3\":1000.0})");
  s["mesh"].erase("element");
  s["material"]["model"] = "corotational";
  EXPECT_EQ(error_of(s), "") << "the corotational model takes supports";
  s["solver"] = {{"type", "dynamic"}};
  EXPECT_EQ(error_of(s), "") << "the dynamic model takes supports";
}

// The corotational quasi-static model on supports: its probe displacement approaches the linear model's on the same
// supports (the springs added to K by the linear path, an independent assembly) to second order as the load
// shrinks (10x less load: about 10x less relative difference), and the springs carry load in both (less motion
// than without them).
TEST(Support, TheCorotationalModelOnSupportsApproachesTheLinearOneToSecondOrder) {
  auto displacement = [](const char* model, double force, bool supported) {
    json s = test::small_tube_scene("supported");
    s["frames"] = 4;
    s["material"]["model"] = model;
    s["probes"] = json::parse(R"([{"name": "p", "point": [0.013, 0.0, 0.05], "track": [{"t": 0.0, "force": [0, 0, 0]}]}])");
    s["probes"][0]["track"].push_back({{"t", 0.05}, {"force", {-force, 0.0, 0.0}}});
    if (supported) s["support"] = {{"stiffness_n_per_m3", 2e5}};
    const engine::Scene scene = engine::parse_scene(s.dump(), "supported.json");
    const auto m = engine::compile_model(scene);
    engine::SessionOptions opt;
    opt.render = false;
    const engine::SessionResult r = engine::run_session(*m, engine::make_inputs(scene), opt);
    for (const auto& f : r.frames) EXPECT_FALSE(f.numerical_failure) << model << " frame " << f.frame;
    return r.frames.back().probe_displacement[0];
  };
  const double big = 0.01, small = 0.001;
  const Eigen::Vector3d linear_big = displacement("linear", big, true), corot_big = displacement("corotational", big, true);
  const Eigen::Vector3d linear_small = displacement("linear", small, true);
  const Eigen::Vector3d corot_small = displacement("corotational", small, true);
  ASSERT_GT(linear_big.norm(), 1e-4);
  const double diff_big = (corot_big - linear_big).norm() / linear_big.norm();
  const double diff_small = (corot_small - linear_small).norm() / linear_small.norm();
  EXPECT_GT(diff_big, 0.0);
  EXPECT_LT(diff_big, 0.1);
  EXPECT_NEAR(diff_small / diff_big, 0.1, 0.05) << diff_small << " vs " << diff_big;
  // The springs hold: the supported corotational tube moves less than the unsupported one.
  EXPECT_LT(corot_big.norm(), 0.8 * displacement("corotational", big, false).norm());
  std::printf("supported tube at %.0f mN: linear %.4f mm, corotational %.4f mm (%.2f %%; at a tenth %.3f %%)\n",
              big * 1e3, linear_big.norm() * 1e3, corot_big.norm() * 1e3, 100.0 * diff_big, 100.0 * diff_small);
}

// The dynamic model on supports (backward Euler, Rayleigh mass damping, the load held): linear and corotational
// settle on their quasi-static answers on the same supports (the quasi-static runs are the twins).
TEST(Support, DynamicRunsOnSupportsSettleOnTheQuasiStaticAnswer) {
  auto displacement = [](const char* model, const char* solver, int frames) {
    json s = test::small_tube_scene("supported");
    s["frames"] = frames;
    s["material"]["model"] = model;
    s["material"]["density"] = 1050.0;
    s["solver"] = {{"type", solver}};
    if (std::string(solver) == "dynamic") s["solver"]["rayleigh_mass"] = 2.0;
    s["probes"] = json::parse(R"([{"name": "p", "point": [0.013, 0.0, 0.05], "track": [{"t": 0.0, "force": [0, 0, 0]},
                                   {"t": 0.05, "force": [-0.01, 0, 0]}]}])");
    s["support"] = {{"stiffness_n_per_m3", 2e5}};
    const engine::Scene scene = engine::parse_scene(s.dump(), "supported.json");
    const auto m = engine::compile_model(scene);
    engine::SessionOptions opt;
    opt.render = false;
    const engine::SessionResult r = engine::run_session(*m, engine::make_inputs(scene), opt);
    for (const auto& f : r.frames) EXPECT_FALSE(f.numerical_failure) << model << " " << solver << " frame " << f.frame;
    return r.frames.back().probe_displacement[0];
  };
  for (const char* model : {"linear", "corotational"}) {
    const Eigen::Vector3d still = displacement(model, "quasi_static", 4);
    const Eigen::Vector3d settled = displacement(model, "dynamic", 240);
    ASSERT_GT(still.norm(), 1e-4) << model;
    EXPECT_LT((settled - still).norm(), 1e-3 * still.norm()) << model << ": " << settled.transpose() << " vs "
                                                              << still.transpose();
  }
}
