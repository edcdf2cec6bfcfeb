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
// quad of the outer wall (chord x cell length) for a node inside the wall; unsupported it moves far more. On 10-node
// tets (the outer wall split over its edge nodes into quads of half the size each way) a corner node's area is a
// quarter of that; the limit holds for the linear and the corotational model alike.
TEST(Support, StiffSupportsCarryTheLoadOnTheNodesOwnSpring) {
  // The probe's displacement; area (optional): the loaded node's lumped area, a third of each outer-wall
  // triangle around it summed here from the compiled mesh.
  auto displacement = [](double k, const char* element, const char* model, double* area = nullptr) {
    json s = test::small_tube_scene("supported");
    s["frames"] = 1;
    s["mesh"]["element"] = element;
    s["material"]["model"] = model;
    // At an outer-wall node: angle 0, mid-length (ring 5 of 10).
    s["probes"] = json::parse(R"([{"name": "p", "point": [0.013, 0.0, 0.05],
                                   "track": [{"t": 0.0, "force": [-0.01, 0, 0]}]}])");
    if (k > 0) s["support"] = {{"stiffness_n_per_m3", k}};
    const auto m = engine::compile_model(engine::parse_scene(s.dump(), "supported.json"));
    if (area) {
      Eigen::Index node = 0;
      (m->mesh.rest.rowwise() - Eigen::RowVector3d(0.013, 0.0, 0.05)).rowwise().squaredNorm().minCoeff(&node);
      *area = 0.0;
      const Tris& wall = m->outer_wall();
      for (Eigen::Index t = 0; t < wall.rows(); ++t) {
        if (wall(t, 0) != node && wall(t, 1) != node && wall(t, 2) != node) continue;
        const Eigen::Vector3d a = m->mesh.rest.row(wall(t, 0)), b = m->mesh.rest.row(wall(t, 1)),
                              c = m->mesh.rest.row(wall(t, 2));
        *area += (b - a).cross(c - a).norm() / 6.0;
      }
    }
    engine::SessionOptions opt;
    opt.render = false;
    const engine::SessionResult r = engine::run_session(*m, engine::make_inputs(engine::parse_scene(s.dump(), "supported.json")), opt);
    EXPECT_FALSE(r.frames.back().numerical_failure) << element << " " << model;
    return r.frames.back().probe_displacement[0];
  };
  constexpr double kStiff = 1e10, kForce = 0.01;
  const double node_area = chord() * kLength / kAlong;
  const Eigen::Vector3d stiff = displacement(kStiff, "tet4", "linear");
  EXPECT_NEAR(stiff.x(), -kForce / (kStiff * node_area), 1e-3 * kForce / (kStiff * node_area));
  EXPECT_NEAR(stiff.y(), 0.0, 1e-12);
  for (const char* model : {"linear", "corotational"}) {
    double area = 0.0;
    const Eigen::Vector3d quadratic = displacement(kStiff, "tet10", model, &area);
    EXPECT_NEAR(area, node_area / 4, 0.05 * node_area / 4);  // (the edge nodes on the curved wall: not exactly)
    EXPECT_NEAR(quadratic.x(), -kForce / (kStiff * area), 1e-3 * kForce / (kStiff * area)) << model;
    EXPECT_NEAR(quadratic.y(), 0.0, 1e-4 * kForce / (kStiff * area)) << model;  // (the split wall's diagonals)
  }
  // Softer supports: the wall shares the load, so the node moves less than its spring alone would allow ...
  constexpr double kSoft = 1e5;
  const Eigen::Vector3d soft = displacement(kSoft, "tet4", "linear");
  EXPECT_GT(soft.x(), -kForce / (kSoft * node_area));
  // ... and more than with stiffer springs; without supports most of all.
  EXPECT_LT(soft.x(), stiff.x());
  EXPECT_LT(displacement(0.0, "tet4", "linear").x(), soft.x());
}

TEST(Support, KeysAreValidatedAndEveryModelTakesThem) {
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
  EXPECT_EQ(error_of(s), "") << "10-node tets take supports";
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

// support.where limits the springs to the outer-wall nodes its entries select (entries as in "fixed"). With springs
// much stiffer than the wall, a load at a selected node moves F / (k A) (its own spring, as with the whole wall
// supported); a selection that leaves that node out (the other half of the tube, by a plane side) lets it move
// orders of magnitude more, yet less than without supports; a box around the whole organ is the same as no "where",
// bit for bit. Selections that select nothing, or nothing on the outer wall, are refused naming the entry.
TEST(Support, WhereLimitsTheSpringsToTheSelectedOuterWallNodes) {
  constexpr double kStiff = 1e10, kForce = 0.01;
  auto scene_with = [&](const json& where) {
    json s = test::small_tube_scene("supported");
    s["frames"] = 1;
    s["probes"] = json::parse(R"([{"name": "p", "point": [0.013, 0.0, 0.05],
                                   "track": [{"t": 0.0, "force": [-0.01, 0, 0]}]}])");
    s["support"] = {{"stiffness_n_per_m3", kStiff}};
    if (!where.is_null()) s["support"]["where"] = where;
    return s;
  };
  auto displacement = [](const json& s) {
    const engine::Scene scene = engine::parse_scene(s.dump(), "supported.json");
    const auto m = engine::compile_model(scene);
    engine::SessionOptions opt;
    opt.render = false;
    return engine::run_session(*m, engine::make_inputs(scene), opt).frames.back().probe_displacement[0];
  };
  const double own_spring = kForce / (kStiff * chord() * kLength / kAlong);
  const json x_positive = json::parse(R"([{"plane": {"point": [0, 0, 0], "normal": [1, 0, 0]}}])");
  const json x_negative = json::parse(R"([{"plane": {"point": [0, 0, 0], "normal": [-1, 0, 0]}}])");
  const json everything = json::parse(R"([{"box": [[-1, -1, -1], [1, 1, 1]]}])");
  EXPECT_NEAR(displacement(scene_with(x_positive)).x(), -own_spring, 1e-3 * own_spring);
  const Eigen::Vector3d other_half = displacement(scene_with(x_negative));
  json unsupported = scene_with(json());
  unsupported.erase("support");
  EXPECT_LT(other_half.x(), -100.0 * own_spring);
  EXPECT_GT(other_half.x(), displacement(unsupported).x());
  EXPECT_EQ(displacement(scene_with(everything)), displacement(scene_with(json())));

  auto error_of = [&](const json& where) {
    return test::message_of<engine::InputError>([&] {
      const json s = scene_with(where);
      engine::compile_model(engine::parse_scene(s.dump(), "s.json"));
    });
  };
  EXPECT_EQ(error_of(json::array()), "s.json: support.where: must be a non-empty list of node selections (as \"fixed\") "
                                     "(value [])");
  EXPECT_EQ(error_of(json::parse(R"([{"box": [[1, 1, 1], [2, 2, 2]]}])")),
            "s.json: support.where[0]: selects no node of the mesh (value {\"box\":[[1,1,1],[2,2,2]]})");
  // (The inner wall's nodes only: a box of radius 10.5 mm around the axis holds the 10 mm lumen wall.)
  EXPECT_EQ(error_of(json::parse(R"([{"box": [[-0.0105, -0.0105, -1], [0.0105, 0.0105, 1]]}])")),
            "s.json: support.where: selects no node of the outer wall (the springs would hold nothing) (value "
            "[{\"box\":[[-0.0105,-0.0105,-1],[0.0105,0.0105,1]]}])");
  EXPECT_NE(error_of(json::parse(R"(["middle"])")).find("support.where[0]"), std::string::npos)
      << error_of(json::parse(R"(["middle"])"));
}
