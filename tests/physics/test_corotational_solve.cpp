// Contacts carried into the corotational equilibrium by an augmented Lagrangian (AugmentedContacts), and
// Anderson mixing of its fixed-point iterations. The augmented Lagrangian: the
// method of multipliers on one contact row against the exact answer of the linear model at a load small enough
// that the two models agree (the LCP of one row: lambda = (g - h_free) / C), and its input checks.
#include <gtest/gtest.h>

#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "physics/corotational.hpp"
#include "physics/fem.hpp"
#include "physics/mesh.hpp"
#include "support/fem.hpp"

namespace lumen::physics {
namespace {

using lumen::test::kTissue;

struct Pressed {
  TetMesh mesh;
  std::vector<int> fixed;
  int node = -1;                // the pressed outer-wall node (the highest one at mid-length)
  Eigen::VectorXd f;            // its load, 3n, newtons
};

// An 8 x 4 x 1 tube held at both ends, pressed down at the top of its middle ring by `force` newtons.
Pressed pressed_tube(double force) {
  Pressed p;
  p.mesh = lumen::test::small_tube();
  p.fixed = lumen::test::both_ends(p.mesh);
  double best = -1.0;
  for (int v = 0; v < p.mesh.n_nodes(); ++v)
    if (std::abs(p.mesh.rest(v, 2) - 0.02) < 1e-9 && p.mesh.rest(v, 1) > best) best = p.mesh.rest(v, 1), p.node = v;
  p.f = Eigen::VectorXd::Zero(3 * p.mesh.n_nodes());
  p.f[3 * p.node + 1] = -force;
  return p;
}

// Options that solve a frame of the press ramps below to a tight tolerance, Anderson-mixed: the reference every
// variant of the ramp is compared with.
CorotationalOptions tight_mixed_options() {
  CorotationalOptions o;
  o.tolerance = 1e-8;
  o.max_iterations = 400;
  o.anderson_depth = 5;
  return o;
}

// The lagged preconditioners are factorised on the rest factorisation's symbolic analysis
// (StaticSolver::refactorised): the warped stiffness and the projected tangent at a pressed state store the rest
// stiffness' entries, and their refactorised solvers solve as fresh factorisations of them.
TEST(LaggedPreconditioner, WarpedAndTangentMatricesRefactoriseOnTheRestAnalysis) {
  const Pressed p = pressed_tube(0.05);
  const CorotationalModel model(p.mesh, kTissue, p.fixed);
  CorotationalState state;
  CorotationalOptions options;
  options.max_iterations = 200;
  ASSERT_TRUE(solve_corotational(model, p.f, state, options).converged);
  const CorotationalElements& el = model.elements();
  std::vector<Eigen::Matrix3d> R;
  el.rotations(state.u, R);
  std::vector<TwistModes> twist;
  el.twist_modes(state.u, R, /*project=*/true, twist);
  for (const Eigen::SparseMatrix<double>& K : {el.warped_stiffness(R), el.tangent_stiffness(R, twist)}) {
    ASSERT_TRUE(model.solver().has_pattern(K));
    const StaticSolver refactorised = model.solver().refactorised(K);
    const StaticSolver fresh(K, p.fixed);
    Eigen::VectorXd u, u_fresh;
    refactorised.solve(p.f, u);
    fresh.solve(p.f, u_fresh);
    EXPECT_GT(u_fresh.norm(), 0.0);
    EXPECT_LE((u - u_fresh).norm(), 1e-10 * u_fresh.norm());
  }
}

TEST(AugmentedContacts, MultipliersConvergeToTheExactContactForceOfOneRow) {
  const Pressed p = pressed_tube(1e-7);  // displacements ~1e-6 of the wall: corotational = linear to ~1e-6
  const CorotationalModel model(p.mesh, kTissue, p.fixed);
  const int dof = 3 * p.node + 1;
  // Linear truth: the free displacement, the node's compliance C, the row u_y >= g = -d at half the free motion.
  Eigen::VectorXd u_free, unit = Eigen::VectorXd::Zero(model.n_dofs()), c_col;
  model.solver().solve(p.f, u_free);
  unit[dof] = 1.0;
  model.solver().solve(unit, c_col);
  const double g = 0.5 * u_free[dof];
  const double lambda_exact = (g - u_free[dof]) / c_col[dof];
  ASSERT_GT(lambda_exact, 0.0);
  // The method of multipliers: each solve carries lambda_k and returns lambda_eff = lambda_{k+1}.
  AugmentedContacts contacts;
  ContactRow row;
  row.node[0] = p.node;
  row.weight[0] = 1.0;
  row.n = Eigen::Vector3d::UnitY();
  row.g = g;
  contacts.rows = {row};
  contacts.lambda = Eigen::VectorXd::Zero(1);
  contacts.stiffness = model.stiffness().coeff(dof, dof);
  CorotationalOptions options;
  options.tolerance = 1e-8;
  options.max_iterations = 50;
  CorotationalState state;
  for (int k = 0; k < 40; ++k) {
    const CorotationalResult r = solve_corotational(model, p.f, state, options, Eigen::VectorXd(), &contacts);
    ASSERT_TRUE(r.converged) << "multiplier iteration " << k << " residual " << r.residual << " iterations " << r.iterations;
    contacts.lambda = r.contact_lambda;
  }
  EXPECT_NEAR(contacts.lambda[0], lambda_exact, 1e-4 * lambda_exact);
  EXPECT_NEAR(state.u[dof], g, 1e-4 * std::abs(g));
  // Without the row the same solve moves the node by the free displacement (the row did the holding).
  CorotationalState free_state;
  ASSERT_TRUE(solve_corotational(model, p.f, free_state, options).converged);
  EXPECT_NEAR(free_state.u[dof], u_free[dof], 1e-4 * std::abs(u_free[dof]));
}

TEST(AugmentedContacts, ARowThatDoesNotPushCarriesNoForce) {
  const Pressed p = pressed_tube(1e-7);
  const CorotationalModel model(p.mesh, kTissue, p.fixed);
  Eigen::VectorXd u_free;
  model.solver().solve(p.f, u_free);
  AugmentedContacts contacts;
  ContactRow row;
  row.node[0] = p.node;
  row.weight[0] = 1.0;
  row.n = Eigen::Vector3d::UnitY();
  row.g = 2.0 * u_free[3 * p.node + 1];  // the free motion stays above the bound
  contacts.rows = {row};
  contacts.lambda = Eigen::VectorXd::Zero(1);
  contacts.stiffness = 1.0;
  CorotationalState state;
  const CorotationalResult r = solve_corotational(model, p.f, state, {}, Eigen::VectorXd(), &contacts);
  EXPECT_TRUE(r.converged);
  EXPECT_EQ(r.contact_lambda[0], 0.0);
}

TEST(AugmentedContacts, BadContactsAreRefusedNamingTheField) {
  const Pressed p = pressed_tube(1e-7);
  const CorotationalModel model(p.mesh, kTissue, p.fixed);
  AugmentedContacts contacts;
  ContactRow row;
  row.node[0] = p.node;
  row.weight[0] = 1.0;
  row.n = Eigen::Vector3d::UnitY();
  contacts.rows = {row};
  contacts.lambda = Eigen::VectorXd::Zero(1);
  auto message = [&]() -> std::string {
    CorotationalState state;
    try {
      solve_corotational(model, p.f, state, {}, Eigen::VectorXd(), &contacts);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  contacts.stiffness = 0.0;
  EXPECT_NE(message().find("contacts.stiffness"), std::string::npos) << message();
  contacts.stiffness = 1.0;
  contacts.lambda[0] = -1.0;
  EXPECT_NE(message().find("contacts.lambda[0]"), std::string::npos) << message();
  contacts.lambda[0] = 0.0;
  contacts.rows[0].node[0] = p.mesh.n_nodes();
  EXPECT_NE(message().find("contacts.rows[0].node[0]"), std::string::npos) << message();
}

}  // namespace
}  // namespace lumen::physics

namespace lumen::physics {
namespace {

// u is the equilibrium under f that PCG on K_w finds at tolerance 1e-10 (within 1e-5 relative).
void expect_at_tight_pcg_equilibrium(const CorotationalModel& model, const Eigen::VectorXd& f,
                                     const Eigen::VectorXd& u) {
  CorotationalOptions pcg;
  pcg.tolerance = 1e-10;
  pcg.max_iterations = 4000;
  pcg.max_cg_iterations = 400;
  CorotationalState reference;
  ASSERT_TRUE(solve_corotational(model, f, reference, pcg).converged);
  EXPECT_LT((u - reference.u).norm(), 1e-5 * reference.u.norm());
}

// Anderson mixing changes the path of the fixed-point iterations, not where they end: a large pinch (the wall
// deflects by about its thickness) solved to a tight tolerance with and without it.
TEST(AndersonMixing, ReachesTheSameEquilibriumAsThePlainIteration) {
  const Pressed p = pressed_tube(3e-2);
  const CorotationalModel model(p.mesh, kTissue, p.fixed);
  CorotationalOptions plain;
  plain.tolerance = 1e-9;
  plain.max_iterations = 400;
  CorotationalOptions mixed = plain;
  mixed.anderson_depth = 5;
  CorotationalState a, b;
  const CorotationalResult ra = solve_corotational(model, p.f, a, plain);
  const CorotationalResult rb = solve_corotational(model, p.f, b, mixed);
  std::printf("plain: %d iterations, mixed: %d iterations, deflection %.3e m\n", ra.iterations, rb.iterations,
              a.u[3 * p.node + 1]);
  ASSERT_TRUE(ra.converged);
  ASSERT_TRUE(rb.converged);
  EXPECT_GT(-a.u[3 * p.node + 1], 1e-3);  // a large deflection: the rotations matter
  EXPECT_LT((a.u - b.u).norm(), 1e-6 * a.u.norm());
}

// The secant start is tried while it is kept and, once refused, not again for the next four solves: a press
// ramped up (the secant prediction lowers the residual: kept, no skips), then reversed (the prediction overshoots
// the other way: refused, four skips counted down). Every frame reaches the equilibrium of the same ramp solved
// without secant starts, at a tight tolerance.
TEST(CorotationalSolve, ARefusedSecantStartIsNotTriedForTheNextFourSolves) {
  const Pressed p = pressed_tube(3e-2);
  const CorotationalModel model(p.mesh, kTissue, p.fixed);
  const CorotationalOptions plain = tight_mixed_options();
  CorotationalOptions secant = plain;
  secant.extrapolate = true;
  CorotationalState a, b;
  // Up over four frames, then back down over four.
  const double scale[] = {0.25, 0.5, 0.75, 1.0, 0.75, 0.5, 0.25, 0.0};
  std::vector<int> skips;
  for (double s : scale) {
    const CorotationalResult ra = solve_corotational(model, s * p.f, a, plain);
    const CorotationalResult rb = solve_corotational(model, s * p.f, b, secant);
    ASSERT_TRUE(ra.converged && rb.converged) << "load " << s;
    EXPECT_LE((a.u - b.u).norm(), 1e-6 * std::max(a.u.norm(), 1e-9)) << "load " << s;
    skips.push_back(b.secant_skips);
    EXPECT_EQ(a.secant_skips, 0);
  }
  // Ramping up, the secant start is kept (the first frame has no prediction yet); the first frame down refuses
  // it, and each later solve counts the skips down (the last, unloaded, goes back to rest without a step).
  EXPECT_EQ(skips, (std::vector<int>{0, 0, 0, 0, 4, 3, 2, 1})) << ::testing::PrintToString(skips);
}

// The Anderson history carried from solve to solve (a frame sequence: the press ramped over 12 frames, secant
// starts, the lagged factorisation at once so that the runs are deterministic) changes the path, not the
// equilibria: every frame against the same ramp solved with each solve's history afresh, at a tight tolerance.
// (Whether it saves iterations depends on the scene: none on this small tube, 60 against 61; the sessions'
// numbers are in docs/bench_anderson_carry.csv.) A history of another length (a state from another model) is
// dropped, not mixed.
TEST(AndersonMixing, HistoryCarriedAcrossSolvesReachesTheSameEquilibria) {
  const Pressed p = pressed_tube(3e-2);
  const CorotationalModel model(p.mesh, kTissue, p.fixed);
  CorotationalOptions fresh = tight_mixed_options();
  fresh.extrapolate = true;
  fresh.refactor_cg_iterations = 5;
  CorotationalOptions carried = fresh;
  carried.carry_anderson_history = true;
  CorotationalState a, b;
  int iterations_fresh = 0, iterations_carried = 0;
  constexpr int kFrames = 12;
  for (int k = 1; k <= kFrames; ++k) {
    const Eigen::VectorXd f = p.f * (static_cast<double>(k) / kFrames);
    const CorotationalResult ra = solve_corotational(model, f, a, fresh);
    const CorotationalResult rb = solve_corotational(model, f, b, carried);
    ASSERT_TRUE(ra.converged) << "frame " << k;
    ASSERT_TRUE(rb.converged) << "frame " << k;
    EXPECT_LT((a.u - b.u).norm(), 1e-6 * a.u.norm()) << "frame " << k;
    EXPECT_TRUE(a.anderson_dX.empty());
    iterations_fresh += ra.iterations;
    iterations_carried += rb.iterations;
  }
  std::printf("over %d frames: %d nonlinear iterations with each solve's history afresh, %d carried\n", kFrames,
              iterations_fresh, iterations_carried);
  EXPECT_GT(-a.u[3 * p.node + 1], 1e-3);  // a large deflection: the rotations matter
  EXPECT_FALSE(b.anderson_dX.empty());
  // A history of another length is dropped: the solve is the fresh one's.
  CorotationalState c, d;
  for (CorotationalState* s : {&c, &d}) s->u = a.u, s->u_previous = a.u_previous, s->preconditioner = a.preconditioner;
  d.anderson_dX.assign(2, Eigen::VectorXd::Ones(5));
  d.anderson_dF.assign(2, Eigen::VectorXd::Ones(5));
  const Eigen::VectorXd f = 1.1 * p.f;
  const CorotationalResult rc = solve_corotational(model, f, c, carried);
  const CorotationalResult rd = solve_corotational(model, f, d, carried);
  EXPECT_EQ(rc.iterations, rd.iterations);
  EXPECT_EQ((c.u - d.u).norm(), 0.0);
}

// Newton's method on the exact tangent: the same equilibrium as the warped (quasi-Newton) iteration, in
// fewer linear steps (its convergence is superlinear where K_w's is linear).
TEST(ExactTangent, ReachesTheSameEquilibriumInFewerIterations) {
  const Pressed p = pressed_tube(3e-2);
  const CorotationalModel model(p.mesh, kTissue, p.fixed);
  CorotationalOptions warped;
  warped.tolerance = 1e-9;
  warped.max_iterations = 400;
  warped.max_cg_iterations = 400;
  warped.cg_tolerance = 1e-8;  // exact linear steps: the iteration counts are the methods' own
  CorotationalOptions newton = warped;
  newton.tangent = CorotationalTangent::exact;
  CorotationalState a, b;
  const CorotationalResult ra = solve_corotational(model, p.f, a, warped);
  const CorotationalResult rb = solve_corotational(model, p.f, b, newton);
  std::printf("warped: %d iterations (%d CG), exact tangent: %d iterations (%d CG)\n", ra.iterations,
              ra.cg_iterations, rb.iterations, rb.cg_iterations);
  ASSERT_TRUE(ra.converged);
  ASSERT_TRUE(rb.converged);
  EXPECT_LT((a.u - b.u).norm(), 1e-6 * a.u.norm());
  EXPECT_LT(rb.iterations, ra.iterations);
}

// A tube crushed end to end (its stop end pushed 40% of the length towards the start, a small side push to break
// the symmetry): it buckles, tets compress across their axes and the exact tangent turns indefinite. Newton's
// linear steps stop at directions of negative curvature (truncated CG, still descent directions), and the solve
// reaches the warped iteration's equilibrium in far fewer iterations.
TEST(ExactTangent, TruncatesItsStepsWhereTheTangentIsIndefiniteAndReachesTheSameEquilibrium) {
  const Pressed p = pressed_tube(1e-3);
  const CorotationalModel model(p.mesh, kTissue, p.fixed);
  Eigen::VectorXd u_fixed = Eigen::VectorXd::Zero(3 * p.mesh.n_nodes());
  for (int v : p.mesh.node_set(kStopEnd)) u_fixed[3 * v + 2] = -0.4 * 0.04;
  CorotationalOptions warped;
  warped.tolerance = 1e-8;  // (the warped iteration crawls near the buckling point: 1966 iterations)
  warped.max_iterations = 2000;
  warped.max_cg_iterations = 400;
  warped.anderson_depth = 5;
  CorotationalOptions newton = warped;
  newton.tangent = CorotationalTangent::exact;
  CorotationalState a, b;
  const CorotationalResult ra = solve_corotational(model, p.f, a, warped, u_fixed);
  const CorotationalResult rb = solve_corotational(model, p.f, b, newton, u_fixed);
  std::printf("warped: %d iterations, exact tangent: %d iterations (%d truncated at negative curvature, %d warped "
              "fallbacks), side deflection %.3e m\n", ra.iterations, rb.iterations, rb.truncated_steps,
              rb.tangent_fallbacks, a.u[3 * p.node + 1]);
  ASSERT_TRUE(ra.converged);
  ASSERT_TRUE(rb.converged);
  EXPECT_GT(rb.truncated_steps, 0);
  EXPECT_LT(rb.iterations, ra.iterations);
  EXPECT_LT((a.u - b.u).norm(), 1e-5 * a.u.norm());
}

TEST(AndersonMixing, ANegativeDepthIsRefused) {
  CorotationalOptions o;
  o.anderson_depth = -1;
  try {
    validate_options(o);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("anderson_depth"), std::string::npos) << e.what();
  }
}

// Chord steps (one back-substitution on the lagged factorisation each, Anderson-mixed) reach the equilibrium of
// the PCG iteration on K_w on a large press, and on the buckling end-to-end crush that of Newton's method on the
// exact tangent (the same equilibrium as PCG's there, ExactTangent.TruncatesItsSteps..., in 31 steps instead of
// PCG's 1966, which took most of this test's time under the sanitizers), both at tight tolerance.
TEST(ChordMethod, ReachesThePcgEquilibriumOnAPressAndABucklingCrush) {
  const Pressed p = pressed_tube(3e-2);
  const CorotationalModel model(p.mesh, kTissue, p.fixed);
  Eigen::VectorXd crush = Eigen::VectorXd::Zero(3 * p.mesh.n_nodes());
  for (int v : p.mesh.node_set(kStopEnd)) crush[3 * v + 2] = -0.4 * 0.04;
  const Pressed nudge = pressed_tube(1e-3);
  for (const auto& [f, u_fixed] : {std::pair{p.f, Eigen::VectorXd()}, std::pair{nudge.f, crush}}) {
    CorotationalOptions reference;
    reference.tolerance = 1e-8;
    reference.max_iterations = 4000;
    reference.max_cg_iterations = 400;
    reference.anderson_depth = 5;
    CorotationalOptions chord = reference;
    chord.method = CorotationalMethod::chord;
    chord.refactor_cg_iterations = 5;  // refresh the factorisation (inside the solve) when a solve takes longer
    if (u_fixed.size() > 0) reference.tangent = CorotationalTangent::exact;
    CorotationalState a, b;
    const CorotationalResult ra = solve_corotational(model, f, a, reference, u_fixed);
    const CorotationalResult rb = solve_corotational(model, f, b, chord, u_fixed);
    std::printf("%s: %d iterations (%d CG); chord: %d iterations (%d refactorisations)\n",
                u_fixed.size() > 0 ? "exact tangent" : "pcg", ra.iterations, ra.cg_iterations, rb.iterations,
                rb.refactorisations);
    ASSERT_TRUE(ra.converged);
    ASSERT_TRUE(rb.converged);
    EXPECT_FALSE(ra.diverged);
    EXPECT_FALSE(rb.diverged);
    EXPECT_EQ(rb.cg_iterations, rb.iterations);  // one back-substitution a step
    EXPECT_LT((a.u - b.u).norm(), 1e-5 * a.u.norm());
  }
}

// A lagged factorisation far softer than the tangent (here the rest one scaled to 1/100 of K, steps 100 times
// too long) makes the chord iteration diverge: the solve must go back exactly to its start, say so, and factorise
// at the start's rotations, after which the same solve converges to the equilibrium a tight PCG solve finds.
TEST(ChordMethod, ADivergingSolveGoesBackToItsStartAndConvergesAfterItsRefactorisation) {
  constexpr double kSoftening = 1e-2;
  const Pressed half = pressed_tube(1.5e-2), full = pressed_tube(3e-2);
  const CorotationalModel model(full.mesh, kTissue, full.fixed);
  CorotationalOptions chord;
  chord.method = CorotationalMethod::chord;
  chord.tolerance = 1e-8;
  chord.max_iterations = 4000;
  chord.refactor_cg_iterations = 0;  // no periodic refresh: only the guard refactorises
  CorotationalState state;
  ASSERT_TRUE(solve_corotational(model, half.f, state, chord).converged);
  const Eigen::VectorXd start = state.u;
  auto soft = std::make_shared<const StaticSolver>(model.solver().scaled(kSoftening));
  state.preconditioner = soft;

  const CorotationalResult bad = solve_corotational(model, full.f, state, chord);
  EXPECT_TRUE(bad.diverged);
  EXPECT_FALSE(bad.converged);
  EXPECT_LT(bad.iterations, 10);  // caught within a few steps, not at the iteration cap
  EXPECT_EQ(bad.refactorisations, 1);
  EXPECT_TRUE(state.u.allFinite());
  EXPECT_EQ(state.u, start);  // exactly the start, not an iterate on the way out
  EXPECT_NE(state.preconditioner, soft);

  const CorotationalResult good = solve_corotational(model, full.f, state, chord);
  ASSERT_TRUE(good.converged);
  EXPECT_FALSE(good.diverged);
  expect_at_tight_pcg_equilibrium(model, full.f, state.u);
}

// A frame budget of one chord step a solve (solver.max_iterations 1): the refresh of the lagged factorisation is
// counted over solves, so a sequence of one-step solves still gets its operator refreshed every
// refactor_cg_iterations steps (counted per solve, it never would be), and the sequence reaches the equilibrium of
// a tight PCG solve.
TEST(ChordMethod, OneStepSolvesRefreshTheirFactorisationAcrossSolves) {
  const Pressed p = pressed_tube(3e-2);
  const CorotationalModel model(p.mesh, kTissue, p.fixed);
  CorotationalOptions chord;
  chord.method = CorotationalMethod::chord;
  chord.tolerance = 1e-8;
  chord.max_iterations = 1;
  chord.anderson_depth = 0;  // (mixing restarts every solve; one step has nothing to mix)
  chord.refactor_cg_iterations = 4;
  CorotationalState state;
  int solves = 0, refactorisations = 0;
  bool converged = false;
  for (; solves < 400 && !converged; ++solves) {
    const CorotationalResult r = solve_corotational(model, p.f, state, chord);
    ASSERT_FALSE(r.diverged) << "solve " << solves;
    refactorisations += r.refactorisations;
    converged = r.converged;
  }
  std::printf("one-step chord solves: %d solves, %d refactorisations\n", solves, refactorisations);
  ASSERT_TRUE(converged);
  EXPECT_GE(refactorisations, solves / 4 - 1);  // one every 4 steps (the last may not have been due)
  expect_at_tight_pcg_equilibrium(model, p.f, state.u);
}

TEST(ChordMethod, NeedsTheWarpedTangent) {
  CorotationalOptions o;
  o.method = CorotationalMethod::chord;
  o.tangent = CorotationalTangent::exact;
  try {
    validate_options(o);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("method chord needs tangent warped"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace lumen::physics
