// Scene-selected implicit dynamics (solver.type "dynamic"): a damped step load settles on the static solution
// (linear: a direct CHOLMOD solve; corotational: the quasi-static corotational solve), the undamped step obeys
// backward Euler's exact energy balance, contacts are solved on the compliance of one implicit step with the
// velocity following the committed motion, and the loader refuses what it cannot do.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "collision/self_collision.hpp"
#include "engine/simulation.hpp"
#include "physics/fem.hpp"
#include "support/build.hpp"

using namespace lumen;

namespace {

// Optimised builds run the paper's mesh where a test names it; the Debug + sanitizer build runs a coarse one
// (the same checks, quickly; tests/support/build.hpp).
using test::kOptimised;

// The scenes' material (pascals, dimensionless).
constexpr double kYoungModulus = 5000.0, kPoissonRatio = 0.45;

// A tube pressed by one probe with a constant force from t = 0 (a step load). Mesh: around x along x layers.
std::string step_scene(const std::string& model, const std::string& solver, int around, int along, int layers,
                       double force, int fps = 40) {
  return R"({"name": "d", "mesh": {"type": "hollow_cylinder", "inner_radius": 0.01, "outer_radius": 0.013,
    "length": 0.1, "segments_around": )" + std::to_string(around) + R"(, "segments_along": )" + std::to_string(along) +
         R"(, "layers": )" + std::to_string(layers) + R"(},
    "material": {"model": ")" + model + R"(", "young_modulus": )" + std::to_string(kYoungModulus) +
         R"(, "poisson_ratio": )" + std::to_string(kPoissonRatio) + R"(, "density": 1050.0},
    "fixed": ["ends"],
    "probes": [{"point": [0.0, 0.013, 0.05], "track": [{"t": 0, "force": [0, )" + std::to_string(-force) + R"(, 0]}]}],
    "frames": 10, "fps": )" + std::to_string(fps) + R"(, "solver": )" + solver + "}";
}

std::unique_ptr<engine::Model> compile(const std::string& text) {
  return engine::compile_model(engine::parse_scene(text, "d.json"));
}
// The input sources of a scene text (its probes' tracks).
engine::Inputs inputs_of(const std::string& text) { return engine::make_inputs(engine::parse_scene(text, "d.json")); }

// Lumped mass as a diagonal matrix.
Eigen::SparseMatrix<double> diagonal(const Eigen::VectorXd& m) {
  Eigen::SparseMatrix<double> M(m.size(), m.size());
  for (Eigen::Index i = 0; i < m.size(); ++i) M.insert(i, i) = m[i];
  return M;
}

// The dynamic model behind a scene's integrator (backward Euler), or null.
const physics::DynamicModel* dynamic_model(const engine::Model& m) {
  const auto* be = dynamic_cast<const physics::BackwardEuler*>(m.integrator.get());
  return be ? &be->model() : nullptr;
}
bool is_corotational_quasi_static(const engine::Model& m) {
  return dynamic_cast<const physics::CorotationalQuasiStatic*>(m.integrator.get()) != nullptr;
}
// The scene's linear material.
physics::LinearMaterial material_of(const engine::Model&) {
  physics::LinearMaterial mat;
  mat.young_modulus = kYoungModulus;
  mat.poisson_ratio = kPoissonRatio;
  return mat;
}

}  // namespace

// The paper's mesh (20 x 26 x 3) under a step load with mass damping: the motion rings down onto the static
// solution u = K^-1 f of an independent CHOLMOD solve, and early on it is far from it (inertia is modelled).
TEST(DynamicScene, DampedStepLoadSettlesOnTheLinearStaticSolution) {
  const std::string text = step_scene("linear", R"({"type": "dynamic", "rayleigh_mass": 10.0})", kOptimised ? 20 : 12,
                                      kOptimised ? 26 : 8, kOptimised ? 3 : 2, 0.02);
  const auto m = compile(text);
  ASSERT_TRUE(dynamic_model(*m));
  engine::Inputs in = inputs_of(text);
  engine::State s = engine::make_state(*m);
  engine::FrameRecord rec;
  // Truth: K u = f with the ends fixed.
  const Eigen::SparseMatrix<double> K = physics::assemble_stiffness(m->mesh, material_of(*m));
  const physics::StaticSolver statics(K, m->fixed_nodes);
  engine::step(*m, in, s, rec);
  Eigen::VectorXd u_static;
  statics.solve(engine::nodal_loads(*m, s), u_static);
  EXPECT_GT((s.sim.u - u_static).norm(), 0.3 * u_static.norm());  // one step of 25 ms: still moving
  EXPECT_EQ(rec.physics_iterations, 1);
  EXPECT_TRUE(rec.physics_converged);
  EXPECT_GT(rec.kinetic_energy, 0.0);
  double error = 1.0;
  for (int i = 1; i < 160; ++i) {
    engine::step(*m, in, s, rec);
    ASSERT_FALSE(rec.numerical_failure);
    error = (s.sim.u - u_static).norm() / u_static.norm();
  }
  EXPECT_LT(error, 1e-6);
  EXPECT_LT(rec.kinetic_energy, 1e-12 * 0.5 * u_static.dot(K * u_static));
}

// Undamped backward Euler under a constant load: with E = 1/2 v'Mv + 1/2 u'Ku - f'u, every step loses exactly
// 1/2 |v1 - v0|_M^2 + 1/2 |u1 - u0|_K^2 (its numerical dissipation), so E never increases.
TEST(DynamicScene, UndampedStepDissipatesExactlyWhatBackwardEulerPredicts) {
  const std::string text = step_scene("linear", R"({"type": "dynamic"})", 12, 10, 2, 0.02);
  const auto m = compile(text);
  engine::Inputs in = inputs_of(text);
  engine::State s = engine::make_state(*m);
  engine::FrameRecord rec;
  const Eigen::SparseMatrix<double> K = physics::assemble_stiffness(m->mesh, material_of(*m));
  const Eigen::VectorXd& mass = dynamic_model(*m)->mass();
  // The lumped mass carries the mesh's mass, density x rest volume, on each axis.
  double volume = 0.0;
  for (int t = 0; t < m->mesh.tets.rows(); ++t) volume += physics::tet_volume(m->mesh.rest, m->mesh.tets, t);
  EXPECT_NEAR(mass.sum() / 3.0, 1050.0 * volume, 1e-12 * 1050.0 * volume);
  Eigen::VectorXd f;
  auto energy = [&](const Eigen::VectorXd& u, const Eigen::VectorXd& v) {
    return 0.5 * v.dot(mass.cwiseProduct(v)) + 0.5 * u.dot(K * u) - f.dot(u);
  };
  engine::step(*m, in, s, rec);
  f = engine::nodal_loads(*m, s);
  double e0 = energy(s.sim.u, s.sim.v), scale = std::abs(e0);
  Eigen::VectorXd u0 = s.sim.u, v0 = s.sim.v;
  int decreasing = 0;
  for (int i = 0; i < 40; ++i) {
    engine::step(*m, in, s, rec);
    const double e1 = energy(s.sim.u, s.sim.v);
    const Eigen::VectorXd du = s.sim.u - u0, dv = s.sim.v - v0;
    const double dissipated = 0.5 * dv.dot(mass.cwiseProduct(dv)) + 0.5 * du.dot(K * du);
    EXPECT_NEAR(e1 - e0, -dissipated, 1e-9 * scale) << "frame " << rec.frame;
    EXPECT_LE(e1, e0 + 1e-12 * scale) << "frame " << rec.frame;
    decreasing += e1 < e0 - 1e-6 * scale;
    e0 = e1;
    u0 = s.sim.u;
    v0 = s.sim.v;
  }
  EXPECT_GT(decreasing, 10);  // the dissipation is real, not round-off
  EXPECT_GT(rec.kinetic_energy, 0.0);
}

// Corotational dynamics with mass and stiffness damping settle on the quasi-static corotational equilibrium
// (long steps, h = 0.2 s, so that a few frames suffice).
TEST(DynamicScene, DampedCorotationalStepLoadSettlesOnTheCorotationalEquilibrium) {
  const std::string tight = R"("tolerance": 1e-8, "max_iterations": 60)";
  const std::string dyn_text = step_scene("corotational", R"({"type": "dynamic", "rayleigh_mass": 10.0,
    "rayleigh_stiffness": 0.002, )" + tight + "}", 8, 4, 1, 0.05, 5);
  const std::string qs_text = step_scene("corotational", "{" + tight + "}", 8, 4, 1, 0.05, 5);
  const auto dyn = compile(dyn_text);
  const auto qs = compile(qs_text);
  engine::Inputs in_dyn = inputs_of(dyn_text), in_qs = inputs_of(qs_text);
  ASSERT_TRUE(dynamic_model(*dyn));
  ASSERT_FALSE(is_corotational_quasi_static(*dyn));
  ASSERT_TRUE(is_corotational_quasi_static(*qs));
  engine::State sd = engine::make_state(*dyn), sq = engine::make_state(*qs);
  engine::FrameRecord rec;
  engine::step(*qs, in_qs, sq, rec);
  ASSERT_TRUE(rec.physics_converged);
  int iterating = 0;
  for (int i = 0; i < 15; ++i) {
    engine::step(*dyn, in_dyn, sd, rec);
    ASSERT_TRUE(rec.physics_converged) << "frame " << rec.frame;
    iterating += rec.physics_iterations >= 1;
  }
  EXPECT_GT(iterating, 3);  // the nonlinear step really iterates while the tube moves
  // Large enough to be nonlinear: the corotational equilibrium differs from the linear one.
  Eigen::VectorXd u_linear;
  qs->contact_solver().solve(engine::nodal_loads(*qs, sq), u_linear);
  EXPECT_GT((sq.sim.u - u_linear).norm(), 1e-3 * sq.sim.u.norm());
  EXPECT_LT((sd.sim.u - sq.sim.u).norm(), 1e-6 * sq.sim.u.norm());
}

// The contact compliance of a dynamic scene is that of one implicit step: an extra nodal force g changes the
// backward Euler step's u1 by exactly A_u^-1 g, A_u = (1 + beta/h) K + (1 + h alpha) M / h^2.
TEST(DynamicScene, ContactComplianceIsTheImplicitStepsResponse) {
  const std::string text = step_scene("linear", R"({"type": "dynamic", "rayleigh_mass": 3.0, "rayleigh_stiffness": 0.01})",
                                      12, 8, 2, 0.02);
  const auto m = compile(text);
  engine::Inputs in = inputs_of(text);
  ASSERT_TRUE(m->integrator);
  // A state in motion.
  engine::State s = engine::make_state(*m);
  engine::FrameRecord rec;
  for (int i = 0; i < 3; ++i) engine::step(*m, in, s, rec);
  const Eigen::VectorXd f = engine::nodal_loads(*m, s);
  Eigen::VectorXd g = Eigen::VectorXd::Zero(f.size());
  const int node = m->inner_nodes[m->inner_nodes.size() / 2];
  g.segment<3>(3 * node) = Eigen::Vector3d(0.003, -0.01, 0.002);
  physics::DynamicState a{s.sim.u, s.sim.v}, b{s.sim.u, s.sim.v};
  physics::step(*dynamic_model(*m), a, f, m->time_step);
  physics::step(*dynamic_model(*m), b, f + g, m->time_step);
  Eigen::VectorXd du;
  m->contact_solver().solve(g, du);
  EXPECT_LT((b.u - a.u - du).norm(), 1e-9 * du.norm());
  // And it is the formula's matrix (assembled here from K and the lumped mass).
  const double h = 1.0 / 40.0;
  const Eigen::SparseMatrix<double> A_u = (1.0 + 0.01 / h) * physics::assemble_stiffness(m->mesh, material_of(*m)) +
                                          ((1.0 + 3.0 * h) / (h * h)) * diagonal(dynamic_model(*m)->mass());
  Eigen::VectorXd r = A_u * du - g;
  for (int d = 0; d < r.size(); ++d)
    if (dynamic_model(*m)->is_fixed_dof(d)) r[d] = 0.0;
  EXPECT_LT(r.norm(), 1e-9 * g.norm());
  // The session's contact compliance is built on that solver.
  engine::Scene with_contacts = engine::parse_scene(text, "d.json");
  with_contacts.collision.self = true;
  const auto mc = engine::compile_model(with_contacts);
  const engine::State sc = engine::make_state(*mc);
  EXPECT_EQ(&sc.compliance->solver(), &mc->contact_solver());
}

// A coarse tube squeezed shut in a dynamic scene with self-collision: every frame is intersection-free (exact
// check), contacts happen, and the committed velocity is the committed motion over the step.
TEST(DynamicScene, SqueezeWithContactsStaysIntersectionFreeWithConsistentVelocity) {
  engine::Scene s = engine::load_scene(std::string(LUMEN_SOURCE_DIR) + "/scenes/full-closure.json");
  s.mesh.segments_around = 12;
  s.mesh.segments_along = 8;
  s.mesh.layers = 2;
  s.mesh.length = 0.06;
  for (engine::ProbeSpec& p : s.probes) {
    p.point.z() = 0.03;
    p.track = {engine::TrackKey{0.0, Eigen::Vector3d::Zero()}, engine::TrackKey{0.5, 3.0 * p.track.back().value},
               engine::TrackKey{1.0, 3.0 * p.track.back().value}};
  }
  s.solver.type = engine::SolverType::kDynamic;
  s.solver.rayleigh_mass = 5.0;
  const auto m = engine::compile_model(s);
  engine::Inputs in = engine::make_inputs(s);
  engine::State st = engine::make_state(*m);
  engine::FrameRecord rec;
  long contacts = 0;
  int solved = 0;
  for (int i = 0; i < 36; ++i) {
    const Eigen::VectorXd u0 = st.sim.u;
    engine::step(*m, in, st, rec);
    ASSERT_FALSE(rec.numerical_failure) << "frame " << rec.frame;
    EXPECT_EQ(collision::count_intersecting_pairs(st.x, m->mesh.surface(lumen::physics::kInnerWall)), 0) << "frame " << rec.frame;
    contacts += rec.contacts;
    solved += rec.response_iterations > 0 && !rec.fallback;
    Eigen::VectorXd expected = (st.sim.u - u0) / m->time_step;
    for (int d = 0; d < expected.size(); ++d)
      if (dynamic_model(*m)->is_fixed_dof(d)) expected[d] = 0.0;
    EXPECT_LT((st.sim.v - expected).norm(), 1e-12 * (1.0 + expected.norm())) << "frame " << rec.frame;
  }
  EXPECT_GT(contacts, 0);
  EXPECT_GT(solved, 3);
}

TEST(DynamicScene, DisplacementDrivenProbesAreRefused) {
  std::string text = step_scene("linear", R"({"type": "dynamic"})", 12, 8, 2, 0.0);
  const std::string key = "\"force\"";
  text.replace(text.find(key), key.size(), "\"displacement\"");
  try {
    compile(text);
    FAIL();
  } catch (const engine::InputError& e) {
    EXPECT_STREQ(e.what(),
                 "d.json: probes[0].track: displacement-driven probes need solver.type \"quasi_static\" (value \"dynamic\")");
  }
}
