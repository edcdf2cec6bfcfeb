// A probe's force at a surface point: the point found is the nearest on the outer wall (against dense
// sampling), and the nodal forces sum to the probe force with zero moment about the point; probes snap to the
// nearer wall, and a point off both is refused.
#include <gtest/gtest.h>

#include <random>

#include "engine/simulation.hpp"
#include "physics/fem.hpp"

using namespace lumen;

TEST(ProbeLoad, SnapsToNearestOuterPointAndSpreadsWithoutMoment) {
  physics::HollowCylinderSpec spec;
  spec.segments_around = 12;
  spec.segments_along = 8;
  spec.layers = 2;
  const physics::TetMesh mesh = physics::make_hollow_cylinder(spec);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> angle(0, 6.283185307179586), z(0.0, spec.length), r(0.012, 0.016);
  for (int trial = 0; trial < 20; ++trial) {
    const double a = angle(rng), rr = r(rng);
    const Eigen::Vector3d p(rr * std::cos(a), rr * std::sin(a), z(rng));
    const engine::SurfacePoint sp = engine::snap_to_surface(mesh.rest, mesh.surface(lumen::physics::kOuterWall), p);
    ASSERT_GE(sp.triangle, 0);
    Eigen::Vector3d q = Eigen::Vector3d::Zero();
    double wsum = 0;
    for (int k = 0; k < 3; ++k) {
      EXPECT_GE(sp.weight[k], -1e-12);
      wsum += sp.weight[k];
      q += sp.weight[k] * mesh.rest.row(sp.node[k]).transpose();
    }
    EXPECT_NEAR(wsum, 1.0, 1e-12);
    // Brute-force twin: densely sampled points of every outer triangle are never closer.
    double best = 1e9;
    for (int t = 0; t < mesh.surface(lumen::physics::kOuterWall).rows(); ++t)
      for (int i = 0; i <= 20; ++i)
        for (int j = 0; i + j <= 20; ++j) {
          const Eigen::Vector3d s = (1 - (i + j) / 20.0) * mesh.rest.row(mesh.surface(lumen::physics::kOuterWall)(t, 0)).transpose() +
                                    (i / 20.0) * mesh.rest.row(mesh.surface(lumen::physics::kOuterWall)(t, 1)).transpose() +
                                    (j / 20.0) * mesh.rest.row(mesh.surface(lumen::physics::kOuterWall)(t, 2)).transpose();
          best = std::min(best, (s - p).norm());
        }
    EXPECT_LE((q - p).norm(), best + 1e-12);
    // Nodal forces: same resultant, zero moment about the attachment point.
    const Eigen::Vector3d F(0.3, -1.2, 0.5);
    Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * mesh.n_nodes());
    physics::add_point_force(sp, F, f);
    Eigen::Vector3d sum = Eigen::Vector3d::Zero(), moment = Eigen::Vector3d::Zero();
    for (int i = 0; i < mesh.n_nodes(); ++i) {
      sum += f.segment<3>(3 * i);
      moment += (mesh.rest.row(i).transpose() - q).cross(Eigen::Vector3d(f.segment<3>(3 * i)));
    }
    EXPECT_LT((sum - F).norm(), 1e-12);
    EXPECT_LT(moment.norm(), 1e-14);
  }
}

TEST(ProbeLoad, DisplacementDrivenProbeReachesItsTargetAndReportsTheForce) {
  // Two probes: one force-driven, one displacement-driven; the solved force, applied through a direct CHOLMOD
  // solve together with the other probe's force, must move the held point exactly to its target.
  engine::Scene scene = engine::parse_scene(R"({"name": "held",
    "mesh": {"type": "hollow_cylinder", "inner_radius": 0.01, "outer_radius": 0.013, "length": 0.1,
             "segments_around": 12, "segments_along": 10, "layers": 2},
    "material": {"model": "linear", "young_modulus": 5000.0, "poisson_ratio": 0.45},
    "fixed": ["ends"],
    "probes": [{"point": [0.0, 0.013, 0.05], "track": [{"t": 0, "displacement": [0, 0, 0]}, {"t": 1, "displacement": [0.0005, -0.003, 0]}]},
               {"point": [0.0, -0.013, 0.03], "track": [{"t": 0, "force": [0, 0, 0]}, {"t": 1, "force": [0, 0.02, 0.01]}]}],
    "frames": 40, "fps": 40})", "held.json");
  auto model = engine::compile_model(scene);
  engine::Inputs inputs = engine::make_inputs(scene);
  engine::State state = engine::make_state(*model);
  engine::FrameRecord rec;
  for (int i = 0; i < 30; ++i) engine::step(*model, inputs, state, rec);
  const double t = 30.0 / 40.0;
  const Eigen::Vector3d target = t * Eigen::Vector3d(0.0005, -0.003, 0);
  // Direct solve with both forces.
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * model->mesh.n_nodes()), u;
  physics::add_point_force(model->probe_points[0], -rec.reactions[0], f);
  physics::add_point_force(model->probe_points[1], t * Eigen::Vector3d(0, 0.02, 0.01), f);
  model->contact_solver().solve(f, u);
  Eigen::Vector3d moved = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) moved += model->probe_points[0].weight[k] * u.segment<3>(3 * model->probe_points[0].node[k]);
  EXPECT_LT((moved - target).norm(), 1e-9 * target.norm() + 1e-15);
  // The record's probe displacements are the direct solve's at both points (the held one: its target).
  ASSERT_EQ(rec.probe_displacement.size(), 2u);
  EXPECT_LT((rec.probe_displacement[0] - target).norm(), 1e-9 * target.norm());
  Eigen::Vector3d other = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) other += model->probe_points[1].weight[k] * u.segment<3>(3 * model->probe_points[1].node[k]);
  EXPECT_LT((rec.probe_displacement[1] - other).norm(), 1e-9 * other.norm());
  EXPECT_GT(other.norm(), 1e-4);  // a real displacement, not zero
  // The force-driven probe's reaction is its force, reversed.
  EXPECT_LT((rec.reactions[1] + t * Eigen::Vector3d(0, 0.02, 0.01)).norm(), 1e-15);
  // Pushing the point inwards takes an inward force.
  EXPECT_LT(-rec.reactions[0].y(), 0.0);
}

namespace {
// Two opposite displacement-driven probes squeeze a small tube shut; returns the last frame and the model.
struct Squeeze {
  std::unique_ptr<engine::Model> model;
  engine::FrameRecord last;
  engine::State state;
};
Squeeze squeeze(bool self_collision) {
  const std::string text = std::string(R"({"name": "squeeze",
    "mesh": {"type": "hollow_cylinder", "inner_radius": 0.01, "outer_radius": 0.013, "length": 0.08,
             "segments_around": 16, "segments_along": 10, "layers": 2},
    "material": {"model": "linear", "young_modulus": 5000.0, "poisson_ratio": 0.45},
    "fixed": ["ends"],
    "probes": [{"point": [0.0, 0.013, 0.04], "track": [{"t": 0, "displacement": [0, 0, 0]}, {"t": 1, "displacement": [0, -0.013, 0]}]},
               {"point": [0.0, -0.013, 0.04], "track": [{"t": 0, "displacement": [0, 0, 0]}, {"t": 1, "displacement": [0, 0.013, 0]}]}],
    "frames": 40, "fps": 40, "collision": {"self": )") + (self_collision ? "true" : "false") + R"(, "gap": 1e-4}})";
  Squeeze s;
  const engine::Scene scene = engine::parse_scene(text, "squeeze.json");
  s.model = engine::compile_model(scene);
  engine::Inputs inputs = engine::make_inputs(scene);
  s.state = engine::make_state(*s.model);
  for (int i = 0; i < 40; ++i) engine::step(*s.model, inputs, s.state, s.last);
  return s;
}
}  // namespace

TEST(ProbeLoad, HeldProbeReactionIncludesTheContact) {
  Squeeze free = squeeze(false), held = squeeze(true);
  ASSERT_GT(held.last.contacts, 0);  // the walls meet
  // The held points stay exactly at their targets although contacts push on the wall.
  for (int p = 0; p < 2; ++p) {
    const engine::SurfacePoint& sp = held.model->probe_points[p];
    Eigen::Vector3d moved = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) moved += sp.weight[k] * held.state.sim.u.segment<3>(3 * sp.node[k]);
    const Eigen::Vector3d target(0, p == 0 ? -0.013 : 0.013, 0);
    EXPECT_LT((moved - target).norm(), 1e-6 * target.norm()) << "probe " << p;
  }
  // Closing the lumen on itself takes more force than pushing through an empty one (linear superposition:
  // the same displacement with extra contact forces resisting it); the reaction points back outwards.
  for (int p = 0; p < 2; ++p) {
    const double without = std::abs(free.last.reactions[p].y()), with = std::abs(held.last.reactions[p].y());
    EXPECT_GT(with, 1.05 * without) << "probe " << p << ": " << with << " vs " << without;
  }
  EXPECT_GT(held.last.reactions[0].y(), 0.0);
  EXPECT_LT(held.last.reactions[1].y(), 0.0);
}

// A probe point must lie on a wall, within a quarter of the wall's local thickness (3 mm here: the distance from
// its outer-wall point to the inner wall, found on the mesh): 0.5 mm off the outer wall is snapped, 1 mm off is
// refused naming the probe, the distances to both walls and the value.
TEST(ProbeLoad, PointOffTheWallIsRefusedByTheLocalWallThickness) {
  auto scene_with = [](const std::string& point) {
    return engine::parse_scene(R"({"name": "off",
      "mesh": {"type": "hollow_cylinder", "inner_radius": 0.01, "outer_radius": 0.013, "length": 0.1,
               "segments_around": 12, "segments_along": 10, "layers": 2},
      "material": {"model": "linear", "young_modulus": 5000.0, "poisson_ratio": 0.45},
      "fixed": ["ends"],
      "probes": [{"point": )" + point + R"(, "track": [{"t": 0, "force": [0, 0, 0]}]}],
      "frames": 2, "fps": 40})", "off.json");
  };
  // (0, 0.013, 0.05) is a ring node of the outer wall: straight out from it is straight off the wall.
  EXPECT_NO_THROW(engine::compile_model(scene_with("[0.0, 0.0135, 0.05]")));
  try {
    engine::compile_model(scene_with("[0.0, 0.014, 0.05]"));
    FAIL() << "a point 1 mm off the wall was accepted";
  } catch (const engine::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("off.json: probes[0].point: not on the organ's walls (0.001000 m from the "
                                         "outer wall, 0.004000 m from the inner; value [0.000000, 0.014000, 0.050000])"),
              std::string::npos) << e.what();
  }
  // Inside the wall, 1.5 mm from both: refused too.
  EXPECT_THROW(engine::compile_model(scene_with("[0.0, 0.0115, 0.05]")), engine::InputError);
}

// A probe on the inner wall (a point in the lumen side, as an instrument tip pushing outwards from inside): it
// snaps to the inner wall's node there, and its force moves that node by K^-1 f of a direct solve on the same
// mesh (the independent twin), outwards.
TEST(ProbeLoad, APointOnTheInnerWallPushesItFromTheLumen) {
  const engine::Scene scene = engine::parse_scene(R"({"name": "inside",
    "mesh": {"type": "hollow_cylinder", "inner_radius": 0.01, "outer_radius": 0.013, "length": 0.1,
             "segments_around": 12, "segments_along": 10, "layers": 2},
    "material": {"model": "linear", "young_modulus": 5000.0, "poisson_ratio": 0.45},
    "fixed": ["ends"],
    "probes": [{"point": [0.0, 0.0102, 0.05], "track": [{"t": 0, "force": [0, 0, 0]}, {"t": 1, "force": [0, 0.004, 0]}]}],
    "frames": 40, "fps": 40})", "inside.json");
  auto model = engine::compile_model(scene);
  const engine::SurfacePoint& sp = model->probe_points[0];
  const Eigen::Vector3d q = engine::point_of(model->mesh.rest, sp);
  EXPECT_LT((q - Eigen::Vector3d(0.0, 0.01, 0.05)).norm(), 1e-12) << q.transpose();  // the inner ring node
  const auto& inner = model->inner_wall();
  for (int k = 0; k < 3; ++k) {
    if (sp.weight[k] == 0.0) continue;
    EXPECT_TRUE((inner.array() == sp.node[k]).any()) << "node " << sp.node[k] << " is not on the inner wall";
  }
  engine::Inputs inputs = engine::make_inputs(scene);
  engine::State state = engine::make_state(*model);
  engine::FrameRecord rec;
  for (int i = 0; i < 40; ++i) engine::step(*model, inputs, state, rec);
  // Twin: the linear solve of the nodal force on the same mesh and supports.
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * model->mesh.n_nodes()), u;
  physics::add_point_force(sp, Eigen::Vector3d(0, 0.004, 0), f);
  const physics::StaticSolver direct(physics::assemble_stiffness(model->mesh, physics::LinearMaterial{5000.0, 0.45}),
                                     model->fixed_nodes);
  direct.solve(f, u);
  Eigen::Vector3d moved = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) moved += sp.weight[k] * u.segment<3>(3 * sp.node[k]);
  ASSERT_EQ(rec.probe_displacement.size(), 1u);
  EXPECT_LT((rec.probe_displacement[0] - moved).norm(), 1e-9 * moved.norm());
  EXPECT_GT(moved.y(), 1e-4);  // outwards, a real displacement
}
