// How the contacts meet the corotational solve (collision.coupling): "correct" corrects the contact-free solution
// on the rest compliance; "carried" puts the last frame's contacts into the nonlinear equilibrium (augmented
// Lagrangian) and corrects what is left; "solved" minimises the corotational potential on each response round's
// rows (physics::solve_contact_equilibrium). Checked on a corotational squeeze past closure: every frame
// intersection-free (exact check), and the committed state against the nonlinear equilibrium with the contact
// forces, f_int(u) = f_probes + H^T lambda, evaluated independently here (element forces at u, rows rebuilt at the
// committed positions, lambda the contacts' whole multipliers).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <numeric>
#include <string>
#include <vector>

#include "collision/self_collision.hpp"
#include "engine/equilibrium.hpp"
#include "engine/simulation.hpp"
#include "support/build.hpp"

using namespace lumen;

namespace {

// Optimised builds run a finer tube; the Debug + sanitizer build a coarse one (tests/support/build.hpp).
using test::kOptimised;
// The shipped full closure's force times this: the walls meet over a large area, then hold.
constexpr double kForceFactor = 1.0;

engine::Scene squeeze(engine::ContactCoupling coupling) {
  engine::Scene s = engine::load_scene(std::string(LUMEN_SOURCE_DIR) + "/scenes/full-closure.json");
  s.mesh.segments_around = kOptimised ? 16 : 12;
  s.mesh.segments_along = kOptimised ? 10 : 8;
  s.mesh.layers = 2;
  s.mesh.length = 0.06;
  for (engine::ProbeSpec& p : s.probes) {
    p.point.z() = 0.03;
    const Eigen::Vector3d f = kForceFactor * p.track.back().value;
    p.track = {engine::TrackKey{0.0, Eigen::Vector3d::Zero()}, engine::TrackKey{0.5, f}, engine::TrackKey{1.0, f}};
  }
  s.material.model = engine::MaterialModel::kCorotational;
  s.solver.tolerance = 1e-6;
  s.solver.max_iterations = 40;
  s.solver.background_factorisation = false;
  s.collision.coupling = coupling;
  return s;
}

struct Outcome {
  double residual = 0.0;       // |f_int(u) - f_probes - H^T lambda| on the free DOFs / |f_probes|
  double fitted_residual = 0.0;  // the same with the best non-negative multipliers for the state
  double contact_force = 0.0;  // sum of the whole multipliers at the end, newtons
  int fallbacks = 0, intersecting_frames = 0, failures = 0;
  int contact_frames = 0, lcp_short_frames = 0;  // frames with contacts; of them, an LCP short of its tolerance
  double reported_kkt = 0.0;   // "solved": the last frame's KKT residual as the session reports it
};

// lcp_sweeps > 0: the contact LCPs by NNCG with that sweep budget (else the active-set method).
Outcome run(engine::ContactCoupling coupling, int frames, int lcp_sweeps = 0) {
  engine::Scene scene = squeeze(coupling);
  if (lcp_sweeps > 0) {
    scene.collision.lcp = engine::LcpSolver::kNncg;
    scene.collision.lcp_sweeps = lcp_sweeps;
  }
  const auto m = engine::compile_model(scene);
  engine::Inputs in = engine::make_inputs(scene);
  engine::State s = engine::make_state(*m);
  engine::FrameRecord rec;
  Outcome o;
  for (int i = 0; i < frames; ++i) {
    engine::step(*m, in, s, rec);
    o.fallbacks += rec.fallback;
    o.failures += rec.numerical_failure;
    o.contact_frames += rec.response_iterations > 0;
    o.lcp_short_frames += !rec.lcp_converged;
    o.intersecting_frames += collision::count_intersecting_pairs(s.x, m->inner_wall()) > 0;
  }
  o.reported_kkt = rec.equilibrium_residual;
  // The equilibrium with the contact forces at the committed state.
  const engine::ContactEquilibrium eq = engine::contact_equilibrium(*m, s);
  EXPECT_TRUE(eq.available);
  o.residual = eq.reported_residual;
  o.fitted_residual = eq.fitted_residual;
  o.contact_force = std::accumulate(s.active_total.begin(), s.active_total.end(), 0.0);
  return o;
}

}  // namespace

TEST(Coupling, CarriedContactsStayInTheNonlinearEquilibrium) {
  // Optimised: the ramp (20 frames) and a third of the hold; the sanitizer build: most of the ramp (the walls
  // meet at frame 7).
  const int frames = kOptimised ? 30 : 16;
  const Outcome correct = run(engine::ContactCoupling::kCorrect, frames);
  const Outcome carried = run(engine::ContactCoupling::kCarried, frames);
  for (const auto& [name, o] : {std::pair{"correct", &correct}, std::pair{"carried", &carried}})
    std::printf("%s: residual %.3e  contact force %.4f N  fallbacks %d  intersecting frames %d\n", name, o->residual,
                o->contact_force, o->fallbacks, o->intersecting_frames);
  for (const Outcome* o : {&correct, &carried}) {
    EXPECT_EQ(o->failures, 0);
    EXPECT_EQ(o->intersecting_frames, 0);
    EXPECT_GT(o->contact_force, 0.0);  // the walls do meet
  }
  // The contacts carried into the solve leave the committed state nearer its equilibrium than a correction of
  // the contact-free solution on the rest compliance (measured: 2.6 against 12 in Release; neither is converged:
  // the corotational solve itself stops at its iteration bound once the wall folds).
  EXPECT_LT(carried.residual, correct.residual);
  // The fit minimises the residual over non-negative multipliers, the committed ones among them.
  for (const Outcome* o : {&correct, &carried}) EXPECT_LE(o->fitted_residual, o->residual * (1.0 + 1e-9));
}

// Contacts solved inside the equilibrium: every frame intersection-free, no fallback, and the committed state
// nearly in the nonlinear equilibrium with its contacts as the independent measure rebuilds it (rows at the
// committed positions, element forces at u), where the correction of the contact-free solution is far from it
// (measured: Release, 30 frames, 0.025 against 12, the session's own KKT residual on the rows as linearised in the
// frame 1.3e-5, the rest is the rows' linearisation; the sanitizer build's coarse tube, 16 frames, the last on the
// ramp and stopped at the step bound, 0.32 against 9.1: at least ten times nearer in both).
TEST(Coupling, SolvedContactsEndInTheNonlinearEquilibrium) {
  const int frames = kOptimised ? 30 : 16;
  const Outcome correct = run(engine::ContactCoupling::kCorrect, frames);
  const Outcome solved = run(engine::ContactCoupling::kSolved, frames);
  for (const auto& [name, o] : {std::pair{"correct", &correct}, std::pair{"solved", &solved}})
    std::printf("%s: residual %.3e (fitted %.3e, reported %.3e)  contact force %.4f N  fallbacks %d  intersecting "
                "frames %d\n", name, o->residual, o->fitted_residual, o->reported_kkt, o->contact_force, o->fallbacks,
                o->intersecting_frames);
  for (const Outcome* o : {&correct, &solved}) {
    EXPECT_EQ(o->failures, 0);
    EXPECT_EQ(o->intersecting_frames, 0);
    EXPECT_GT(o->contact_force, 0.0);
  }
  EXPECT_EQ(solved.fallbacks, 0);
  EXPECT_LT(solved.residual, 0.1 * correct.residual);
  // The pivoting LCPs reach their tolerance, and the frames say so.
  for (const Outcome* o : {&correct, &solved}) {
    EXPECT_GT(o->contact_frames, 0);
    EXPECT_EQ(o->lcp_short_frames, 0);
  }
}

// With collision.prediction_back_substitutions 2 the free prediction of every frame after a contact frame takes at
// most 2 back-substitutions (the frames before the walls meet take more: the bound is what holds them), and the
// session stays intersection-free and ten times nearer the nonlinear equilibrium with its contacts than "correct"
// (measured independently as above). Not as near as with the whole prediction: on this squeeze, ramped in 20
// frames, the short trial motion misses pairs the rounds then meet (Release: frames of 4-8 rounds, 1 fallback,
// residual 0.35 against 0.026; on the 8x pinch, ramped in 80, no fallback and the same tip, README).
TEST(Coupling, APredictionBoundedAfterContactFramesKeepsItsBoundAndTheWallsApart) {
  const int frames = kOptimised ? 30 : 16;
  const Outcome correct = run(engine::ContactCoupling::kCorrect, frames);
  engine::Scene scene = squeeze(engine::ContactCoupling::kSolved);
  scene.collision.prediction_back_substitutions = 2;
  const auto m = engine::compile_model(scene);
  engine::Inputs in = engine::make_inputs(scene);
  engine::State s = engine::make_state(*m);
  engine::FrameRecord rec;
  bool last_in_contact = false;
  int bounded_frames = 0, most_before_contact = 0, intersecting = 0, fallbacks = 0;
  for (int i = 0; i < frames; ++i) {
    engine::step(*m, in, s, rec);
    if (last_in_contact) {
      EXPECT_LE(rec.cg_iterations, 2) << "frame " << rec.frame;
      ++bounded_frames;
    } else {
      most_before_contact = std::max(most_before_contact, rec.cg_iterations);
    }
    last_in_contact = rec.response_iterations > 0;
    intersecting += collision::count_intersecting_pairs(s.x, m->inner_wall()) > 0;
    fallbacks += rec.fallback;
  }
  const engine::ContactEquilibrium eq = engine::contact_equilibrium(*m, s);
  ASSERT_TRUE(eq.available);
  std::printf("bounded prediction: residual %.3e (correct %.3e), %d bounded frames, at most %d back-substitutions "
              "before contact, %d fallbacks\n", eq.reported_residual, correct.residual, bounded_frames,
              most_before_contact, fallbacks);
  EXPECT_GT(bounded_frames, 0);
  EXPECT_GT(most_before_contact, 2);
  EXPECT_EQ(intersecting, 0);
  EXPECT_LT(eq.reported_residual, 0.1 * correct.residual);
}

// NNCG held to its least sweep budget (2) stops short of its tolerance (1e-3 of the gap) on the squeeze's coupled
// contacts, and the frames report it (lcp_converged false); the default budget (200) leaves fewer frames short, not
// none (measured: Release 24 and 14 of 24 contact frames; the sanitizer build's coarse tube 7 and 3 of 8). The pivoting solves' frames report none short
// (Coupling.SolvedContactsEndInTheNonlinearEquilibrium).
TEST(Coupling, FramesReportAnLcpStoppedShortOfItsTolerance) {
  const int frames = kOptimised ? 30 : 16;
  const Outcome starved = run(engine::ContactCoupling::kCorrect, frames, 2);
  const Outcome budgeted = run(engine::ContactCoupling::kCorrect, frames, engine::CollisionSpec{}.lcp_sweeps);
  std::printf("NNCG 2 sweeps: %d of %d contact frames short; %d sweeps: %d of %d\n", starved.lcp_short_frames,
              starved.contact_frames, engine::CollisionSpec{}.lcp_sweeps, budgeted.lcp_short_frames,
              budgeted.contact_frames);
  EXPECT_GT(starved.contact_frames, 0);
  EXPECT_GT(starved.lcp_short_frames, 0);
  EXPECT_GT(budgeted.contact_frames, 0);
  EXPECT_LT(budgeted.lcp_short_frames, starved.lcp_short_frames);
  EXPECT_EQ(starved.intersecting_frames, 0);  // (short or not, the re-checks keep the walls apart)
}

// Before the walls meet (the squeeze's first 5 frames) the committed state is the corotational solve's converged
// solution: its measured equilibrium residual is the solve's own (tolerance 1e-6 of the force scale, which the
// support reactions may make larger than |f_probes|), and there are no rows. A linear model is not measured.
TEST(Coupling, TheEquilibriumOfAContactFreeStateIsTheSolvesOwnResidual) {
  const engine::Scene scene = squeeze(engine::ContactCoupling::kCorrect);
  const auto m = engine::compile_model(scene);
  engine::Inputs in = engine::make_inputs(scene);
  engine::State s = engine::make_state(*m);
  engine::FrameRecord rec;
  for (int i = 0; i < 5; ++i) engine::step(*m, in, s, rec);
  ASSERT_TRUE(s.active.empty());
  ASSERT_TRUE(rec.physics_converged);
  const engine::ContactEquilibrium eq = engine::contact_equilibrium(*m, s);
  ASSERT_TRUE(eq.available);
  EXPECT_EQ(eq.rows, 0);
  EXPECT_LT(eq.reported_residual, 1e-4);
  EXPECT_GT(eq.reported_residual, 0.0);  // measured, not assumed
  engine::Scene linear = scene;
  linear.material.model = engine::MaterialModel::kLinear;
  linear.collision.coupling = engine::ContactCoupling::kCorrect;
  const auto lm = engine::compile_model(linear);
  EXPECT_FALSE(engine::contact_equilibrium(*lm, engine::make_state(*lm)).available);
}
