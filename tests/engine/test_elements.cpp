// Scene-selectable element and collision walls: mesh.element "tet10" (quadratic tets, walls split over the edge
// nodes) and collision.surfaces; the loader's refusals name the key and value.
#include <gtest/gtest.h>

#include <algorithm>

#include <nlohmann/json.hpp>

#include "engine/scene.hpp"
#include "engine/simulation.hpp"
#include "physics/quadratic.hpp"
#include "support/scene_files.hpp"

using namespace lumen;
using nlohmann::json;

namespace {

json small_scene() {
  return json::parse(R"({
    "name": "t",
    "mesh": {"type": "hollow_cylinder", "inner_radius": 0.01, "outer_radius": 0.013, "length": 0.04,
             "segments_around": 8, "segments_along": 6, "layers": 1, "element": "tet10"},
    "material": {"model": "linear", "young_modulus": 5000.0, "poisson_ratio": 0.45},
    "fixed": ["ends"],
    "probes": [{"point": [0.0, 0.013, 0.02], "track": [{"t": 0.0, "force": [0, 0, 0]}, {"t": 0.1, "force": [0, -0.01, 0]}]}],
    "frames": 4, "fps": 40
  })");
}

using lumen::test::scene_parse_error;

}  // namespace

TEST(Elements, LoaderNamesBadElementAndCombinations) {
  json s = small_scene();
  s["mesh"]["element"] = "tet8";
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: mesh.element: must be one of tet4, tet10 (value \"tet8\")");
  s = small_scene();
  s["material"]["model"] = "corotational";
  EXPECT_EQ(scene_parse_error(s), "");
  s["solver"] = {{"tangent", "exact"}};
  EXPECT_EQ(scene_parse_error(s),
            "dir/s.json: solver.tangent: \"exact\" needs mesh.element \"tet4\" (got \"tet10\") (value \"exact\")");
  s = small_scene();
  s["solver"] = {{"type", "dynamic"}};
  EXPECT_EQ(scene_parse_error(s),
            "dir/s.json: mesh.element: \"tet10\" needs solver.type \"quasi_static\" (got \"dynamic\") (value \"tet10\")");
}

TEST(Elements, LoaderNamesBadCollisionSurfaces) {
  json s = small_scene();
  s["collision"] = {{"self", true}, {"surfaces", {"outer"}}};
  EXPECT_EQ(scene_parse_error(s),
            "dir/s.json: collision.surfaces: must include \"inner\" (the lumen's walls always collide) (value [\"outer\"])");
  s["collision"]["surfaces"] = {"inner", "ends"};
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: collision.surfaces[1]: must be one of inner, outer (value \"ends\")");
  s["collision"]["surfaces"] = json::array();
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: collision.surfaces: must be a non-empty array of wall names (value [])");
}

// The engine's tet10 model (precomputed probe responses, walls split over the edge nodes) against a direct solve
// of the quadratic stiffness with the same load: same displacement; the end nodes, corners and edge nodes, stay
// at rest.
TEST(Elements, Tet10ModelMatchesADirectQuadraticSolve) {
  const engine::Scene scene = engine::parse_scene(small_scene().dump(), "s.json");
  auto model = engine::compile_model(scene);
  const physics::TetMesh linear = physics::make_hollow_cylinder(scene.mesh);
  const physics::QuadraticMesh q = physics::make_quadratic_cylinder(linear, scene.mesh);
  ASSERT_EQ(model->mesh.n_nodes(), q.n_nodes());
  ASSERT_EQ(model->mesh.surface(lumen::physics::kInnerWall).rows(), 4 * linear.surface(lumen::physics::kInnerWall).rows());

  // Run the frames; the last has the full force.
  engine::Inputs inputs = engine::make_inputs(scene);
  engine::State state = engine::make_state(*model);
  engine::FrameRecord rec;
  for (int i = 0; i < scene.frames; ++i) engine::step(*model, inputs, state, rec);
  ASSERT_DOUBLE_EQ(state.samples[0].force.y(), -0.01);

  // Direct solve: K of the 10-node tets, both ends' corner and edge nodes fixed, the probe's nodal load.
  std::vector<int> fixed = q.node_set(lumen::physics::kStartEnd);
  fixed.insert(fixed.end(), q.node_set(lumen::physics::kStopEnd).begin(), q.node_set(lumen::physics::kStopEnd).end());
  const physics::StaticSolver solver(physics::assemble_stiffness(q, physics::LinearMaterial{5000.0, 0.45}), fixed);
  Eigen::VectorXd u;
  solver.solve(engine::nodal_loads(*model, state), u);
  ASSERT_EQ(u.size(), state.sim.u.size());
  EXPECT_LT((u - state.sim.u).norm(), 1e-9 * u.norm());
  EXPECT_GT(u.norm(), 0.0);
  for (int v : fixed) EXPECT_EQ(state.sim.u.segment<3>(3 * v).norm(), 0.0) << "end node " << v;
}

// The engine's corotational tet10 model against a direct corotational solve on the same quadratic mesh with the
// same nodal load (the wiring: mesh, fixed ends, probe loads); at this point load (0.01 N) it is not the linear
// tet10 answer.
TEST(Elements, CorotationalTet10ModelMatchesADirectCorotationalSolve) {
  json s = small_scene();
  s["material"]["model"] = "corotational";
  s["solver"] = {{"tolerance", 1e-8}, {"max_iterations", 100}};
  const engine::Scene scene = engine::parse_scene(s.dump(), "s.json");
  auto model = engine::compile_model(scene);
  engine::Inputs inputs = engine::make_inputs(scene);
  engine::State state = engine::make_state(*model);
  engine::FrameRecord rec;
  for (int i = 0; i < scene.frames; ++i) engine::step(*model, inputs, state, rec);
  EXPECT_TRUE(rec.physics_converged);

  // Direct solve from rest on the quadratic mesh, both ends' corner and edge nodes fixed.
  const physics::QuadraticMesh q =
      physics::make_quadratic_cylinder(physics::make_hollow_cylinder(scene.mesh), scene.mesh);
  std::vector<int> fixed = q.node_set(lumen::physics::kStartEnd);
  fixed.insert(fixed.end(), q.node_set(lumen::physics::kStopEnd).begin(), q.node_set(lumen::physics::kStopEnd).end());
  const physics::CorotationalModel direct(q, physics::LinearMaterial{5000.0, 0.45}, fixed);
  physics::CorotationalOptions options;
  options.tolerance = 1e-10;
  options.max_iterations = 200;
  options.cg_tolerance = 1e-3;
  options.max_cg_iterations = 500;
  physics::CorotationalState direct_state;
  const Eigen::VectorXd f = engine::nodal_loads(*model, state);
  EXPECT_TRUE(physics::solve_corotational(direct, f, direct_state, options).converged);
  EXPECT_LT((direct_state.u - state.sim.u).norm(), 1e-6 * direct_state.u.norm());
  // The linear tet10 answer to the same load.
  Eigen::VectorXd u_linear;
  direct.solver().solve(f, u_linear);
  const double difference = (u_linear - state.sim.u).norm() / u_linear.norm();
  EXPECT_GT(difference, 1e-2);
}

// collision.surfaces with "outer": the colliding walls are the inner then the outer triangles, and their nodes.
TEST(Elements, OuterWallJoinsTheCollisionSurfaceWhenAsked) {
  json s = small_scene();
  s["mesh"]["element"] = "tet4";
  s["collision"] = {{"self", true}};
  auto inner_only = engine::compile_model(engine::parse_scene(s.dump(), "s.json"));
  s["collision"]["surfaces"] = {"inner", "outer"};
  auto both = engine::compile_model(engine::parse_scene(s.dump(), "s.json"));
  EXPECT_EQ(inner_only->collision_tris.rows(), inner_only->mesh.surface(lumen::physics::kInnerWall).rows());
  ASSERT_EQ(both->collision_tris.rows(), both->mesh.surface(lumen::physics::kInnerWall).rows() + both->mesh.surface(lumen::physics::kOuterWall).rows());
  EXPECT_TRUE(both->collision_tris.bottomRows(both->mesh.surface(lumen::physics::kOuterWall).rows()) == both->mesh.surface(lumen::physics::kOuterWall));
  // Every inner- and outer-wall node (the whole 1-layer mesh but none else) is a collision node.
  EXPECT_EQ(static_cast<int>(both->collision_nodes.size()), both->mesh.n_nodes());
  EXPECT_EQ(inner_only->collision_nodes, inner_only->inner_nodes);
}
