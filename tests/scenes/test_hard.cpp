// The hard-case suite (scenes/hard/): scenes built to break the simulator, each run frame by frame through
// step(). On every frame of every case: the state and the frame's report are finite and no numerical failure
// is reported, the inner wall has no intersecting triangle pair by the exact check (independent of the CCD
// code), the reported inverted-element count equals a recount from the positions (signed volumes computed
// here), and every frame of the scene is done. Then each case's own truth: closing force and 5x over it, a
// force step met within one frame (quasi-static, and dynamic settling to it), a 180-degree twist (corotational
// keeps the volume, linear distorts the tets' volumes), nearly incompressible tissue, exact scaling of linear
// elasticity with Young's modulus, inverted elements under a point force, a 10,000-frame soak (return to rest,
// no drift, no memory growth), a bent tube whose walls touch in the bend. HardCasesCorotational runs the same
// cases and assertions on the corotational model (all but the dynamic force step and the soak, whose runs on it
// take minutes; tools/hard_cases.py --model corotational measures every case).
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "collision/self_collision.hpp"
#include "engine/simulation.hpp"

using namespace lumen;
using namespace lumen::engine;

namespace {

std::string hard_scene(const std::string& file) { return std::string(LUMEN_SOURCE_DIR) + "/scenes/hard/" + file; }

// Signed volume of tet e at positions x, cubic metres: (x1 - x0) . ((x2 - x0) x (x3 - x0)) / 6, written out here
// rather than taken from the physics module.
double signed_volume(const Points& x, const Tets& tets, int e) {
  const Eigen::Vector3d a = x.row(tets(e, 0)), b = x.row(tets(e, 1)), c = x.row(tets(e, 2)), d = x.row(tets(e, 3));
  return (b - a).dot((c - a).cross(d - a)) / 6.0;
}

int count_inverted(const Points& x, const Tets& tets) {
  int n = 0;
  for (int e = 0; e < tets.rows(); ++e) n += signed_volume(x, tets, e) <= 0.0;
  return n;
}

double total_volume(const Points& x, const Tets& tets) {
  double v = 0.0;
  for (int e = 0; e < tets.rows(); ++e) v += signed_volume(x, tets, e);
  return v;
}

// Largest |V_e / V_e,rest - 1| over the tets.
double max_tet_volume_error(const Points& x, const Points& rest, const Tets& tets) {
  double worst = 0.0;
  for (int e = 0; e < tets.rows(); ++e)
    worst = std::max(worst, std::abs(signed_volume(x, tets, e) / signed_volume(rest, tets, e) - 1.0));
  return worst;
}

// Resident set size of this process, bytes (/proc/self/statm, second field in pages).
long resident_bytes() {
  long size = 0, resident = 0;
  FILE* f = std::fopen("/proc/self/statm", "r");
  if (!f) return -1;
  const int got = std::fscanf(f, "%ld %ld", &size, &resident);
  std::fclose(f);
  return got == 2 ? resident * sysconf(_SC_PAGESIZE) : -1;
}

// The per-frame invariants of a hard case, tallied over a run (first offending frame kept for the message).
struct Invariants {
  int frames = 0;
  int nonfinite = 0, first_nonfinite = 0;          // state or record not finite
  int failures = 0, first_failure = 0;             // FrameRecord::numerical_failure
  int intersecting = 0, first_intersecting = 0;    // frames with intersecting inner-wall pairs (exact check)
  long worst_pairs = 0;
  int miscounted = 0, first_miscounted = 0;        // reported inverted elements != recount
  int max_inverted = 0;                            // largest recount
  long max_contacts = 0;
  int frames_with_contacts = 0;

  // Check one committed frame.
  void check(const Model& model, const State& state, const FrameRecord& rec) {
    ++frames;
    bool finite = state.x.allFinite() && state.sim.u.allFinite() && std::isfinite(rec.max_displacement);
    for (const auto& f : rec.reactions) finite = finite && f.allFinite();
    for (double ms : rec.ms) finite = finite && std::isfinite(ms);
    if (!finite && nonfinite++ == 0) first_nonfinite = rec.frame;
    if (rec.numerical_failure && failures++ == 0) first_failure = rec.frame;
    // Exact intersection count of the inner wall (orientation predicates, not the CCD).
    const long pairs = state.x.allFinite() ? collision::count_intersecting_pairs(state.x, model.mesh.surface(lumen::physics::kInnerWall)) : -1;
    if (pairs != 0 && intersecting++ == 0) first_intersecting = rec.frame;
    worst_pairs = std::max(worst_pairs, pairs);
    const int inverted = count_inverted(state.x, model.mesh.tets);
    if (inverted != rec.inverted_elements && miscounted++ == 0) first_miscounted = rec.frame;
    max_inverted = std::max(max_inverted, inverted);
    max_contacts = std::max(max_contacts, rec.contacts);
    frames_with_contacts += rec.contacts > 0;
  }

  // Assert them for a run that should have had `expected_frames` frames.
  void expect_clean(const std::string& what, int expected_frames) const {
    EXPECT_EQ(frames, expected_frames) << what << ": not every frame was run";
    EXPECT_EQ(nonfinite, 0) << what << ": non-finite state or report, first at frame " << first_nonfinite;
    EXPECT_EQ(failures, 0) << what << ": numerical failure reported, first at frame " << first_failure;
    EXPECT_EQ(intersecting, 0) << what << ": " << intersecting << " frames with intersecting inner-wall pairs (worst "
                               << worst_pairs << "), first at frame " << first_intersecting;
    EXPECT_EQ(miscounted, 0) << what << ": reported inverted elements differ from the recount, first at frame "
                             << first_miscounted;
  }
};

// A hard case run frame by frame; `each` sees every committed frame.
struct HardRun {
  Scene scene;
  std::unique_ptr<Model> model;
  std::vector<FrameRecord> frames;
  Invariants inv;
  Points final_x;  // positions after the last frame, n x 3, metres
};

using FrameHook = std::function<void(const Model&, const State&, const FrameRecord&)>;
using SceneEdit = std::function<void(Scene&)>;

// The case on the corotational model (the hard cases are written for the linear one, but for the twists).
void corotational(Scene& s) { s.material.model = MaterialModel::kCorotational; }
// The same with the lagged factorisation refreshed in the solving thread: runs reproducible bit for bit (the
// background refresh lands at a time that depends on the machine's load, and changes the iterates).
void corotational_reproducible(Scene& s) {
  corotational(s);
  s.solver.background_factorisation = false;
}

HardRun run_hard(const std::string& file, const FrameHook& each = {}, const SceneEdit& edit = {}) {
  HardRun run;
  run.scene = load_scene(hard_scene(file));
  if (edit) edit(run.scene);
  run.model = compile_model(run.scene);
  Inputs inputs = make_inputs(run.scene);
  State state = make_state(*run.model);
  const int frames = run.scene.frames;
  run.frames.reserve(frames);
  for (int i = 0; i < frames; ++i) {
    FrameRecord rec;
    step(*run.model, inputs, state, rec);
    run.inv.check(*run.model, state, rec);
    if (each) each(*run.model, state, rec);
    run.frames.push_back(std::move(rec));
  }
  run.final_x = state.x;
  run.inv.expect_clean(file + (run.scene.material.model == MaterialModel::kCorotational ? " (corotational)" : ""), frames);
  return run;
}

double max_reaction(const FrameRecord& f) {
  double m = 0.0;
  for (const auto& r : f.reactions) m = std::max(m, r.norm());
  return m;
}

}  // namespace

// 1. Two probes close the lumen and keep pushing to 5x the closing force. The closing force is found from the
// run itself: the probe force of the first frame with a contact (an upper bound of the force at first touch).
void expect_closure_then_five_times(const SceneEdit& edit) {
  HardRun run = run_hard("closure-5x-force.json", {}, edit);
  int first = -1;
  for (size_t i = 0; i < run.frames.size() && first < 0; ++i)
    if (run.frames[i].contacts > 0) first = static_cast<int>(i);
  ASSERT_GT(first, 0) << "the walls never touched (or touched at rest)";
  const double closing = max_reaction(run.frames[first]);
  EXPECT_EQ(run.frames[first - 1].contacts, 0);
  double pushed = 0.0;
  for (const auto& f : run.frames) pushed = std::max(pushed, max_reaction(f));
  EXPECT_GE(pushed, 5.0 * closing) << "closing force " << closing << " N";
  // The lumen stays closed while the force rises and is held: every frame from the first touch has contacts.
  int open_frames = 0;
  for (size_t i = first; i < run.frames.size(); ++i) open_frames += run.frames[i].contacts == 0;
  EXPECT_EQ(open_frames, 0) << "walls apart again after closing at frame " << first + 1;
}
TEST(HardCases, ClosureThenFiveTimesTheClosingForce) { expect_closure_then_five_times({}); }
TEST(HardCasesCorotational, ClosureThenFiveTimesTheClosingForce) { expect_closure_then_five_times(corotational); }

// 2. The force goes from zero to its maximum in one frame: the walls meet within that first frame.
void expect_force_step_met_in_one_frame(const SceneEdit& edit) {
  HardRun run = run_hard("force-step.json", {}, edit);
  ASSERT_FALSE(run.frames.empty());
  EXPECT_GT(run.frames[0].contacts, 0) << "the walls did not meet within the step";
  EXPECT_GT(max_reaction(run.frames[0]), 0.0);
  EXPECT_EQ(run.inv.frames_with_contacts, static_cast<int>(run.frames.size()));
}
TEST(HardCases, ForceStepInOneFrame) { expect_force_step_met_in_one_frame({}); }
TEST(HardCasesCorotational, ForceStepInOneFrame) { expect_force_step_met_in_one_frame(corotational); }

// 4. Nearly incompressible tissue: the lumen is squeezed shut at poisson_ratio 0.49 and 0.499.
TEST(HardCases, NearlyIncompressible049) { EXPECT_GT(run_hard("incompressible-nu0p49.json").inv.max_contacts, 0); }
TEST(HardCases, NearlyIncompressible0499) { EXPECT_GT(run_hard("incompressible-nu0p499.json").inv.max_contacts, 0); }
TEST(HardCasesCorotational, NearlyIncompressible049) {
  EXPECT_GT(run_hard("incompressible-nu0p49.json", {}, corotational).inv.max_contacts, 0);
}
TEST(HardCasesCorotational, NearlyIncompressible0499) {
  EXPECT_GT(run_hard("incompressible-nu0p499.json", {}, corotational).inv.max_contacts, 0);
}

// 5. Young's modulus from 100 Pa to 1 MPa with forces proportional to E: linear elasticity (contacts included,
// whose constraints are in metres) gives the same displacements, frame by frame, up to round-off. So does the
// corotational model (its forces are E times a function of the positions; its tolerances are relative), which
// checks that no absolute force scale hides in its solve.
void expect_modulus_sweep_scales_exactly(const SceneEdit& edit) {
  HardRun soft = run_hard("modulus-100pa.json", {}, edit);
  HardRun mid = run_hard("modulus-5kpa.json", {}, edit);
  HardRun stiff = run_hard("modulus-1mpa.json", {}, edit);
  EXPECT_GT(mid.inv.max_contacts, 0) << "the sweep's walls should meet";
  double umax = 0.0;
  for (const auto& f : mid.frames) umax = std::max(umax, f.max_displacement);
  ASSERT_GT(umax, 0.0);
  for (const HardRun* other : {&soft, &stiff}) {
    ASSERT_EQ(other->frames.size(), mid.frames.size());
    for (size_t i = 0; i < mid.frames.size(); ++i)
      EXPECT_NEAR(other->frames[i].max_displacement, mid.frames[i].max_displacement, 1e-9 * umax)
          << other->scene.name << " frame " << i + 1;
    const double diff = (other->final_x - mid.final_x).cwiseAbs().maxCoeff();
    EXPECT_LE(diff, 1e-9 * umax) << other->scene.name << ": final positions differ";
    std::printf("[hard] %s vs modulus-5kpa: final positions differ by %.3g m (max displacement %.4g m)\n",
                other->scene.name.c_str(), diff, umax);
    // The same contact work: the linear system is the same up to a factor.
    EXPECT_EQ(other->inv.frames_with_contacts, mid.inv.frames_with_contacts) << other->scene.name;
  }
}
TEST(HardCases, ModulusSweepScalesExactly) { expect_modulus_sweep_scales_exactly({}); }
TEST(HardCasesCorotational, ModulusSweepScalesExactly) { expect_modulus_sweep_scales_exactly(corotational_reproducible); }

// 6. A point force large enough to invert elements: inverted elements are reported (and counted right), the
// state stays finite and the inner wall intersection-free.
void expect_inverted_elements_reported(const SceneEdit& edit) {
  HardRun run = run_hard("inverting-point-force.json", {}, edit);
  EXPECT_GT(run.inv.max_inverted, 0) << "the force should invert elements";
  int reported = 0;
  for (const auto& f : run.frames) reported = std::max(reported, f.inverted_elements);
  EXPECT_EQ(reported, run.inv.max_inverted);
}
TEST(HardCases, InvertingPointForce) { expect_inverted_elements_reported({}); }
TEST(HardCasesCorotational, InvertingPointForce) { expect_inverted_elements_reported(corotational); }

// 8. A bent tube whose walls touch in the bend: contacts, and every node in contact lies in the middle third
// of the arc (where the probe pushes), never intersecting.
void expect_bent_tube_touches_in_the_bend(const SceneEdit& edit) {
  std::vector<int> contact_rings;
  const Scene bent = load_scene(hard_scene("bent-tube-contact.json"));
  HardRun run = run_hard("bent-tube-contact.json", [&](const Model& model, const State& state, const FrameRecord&) {
    const int per_ring = (bent.mesh.layers + 1) * bent.mesh.segments_around;
    for (int v = 0; v < model.mesh.n_nodes(); ++v)
      if (state.in_contact[v]) contact_rings.push_back(v / per_ring);
  }, edit);
  ASSERT_GT(run.scene.mesh.bend_radius, 0.0);
  EXPECT_GT(run.inv.max_contacts, 0);
  ASSERT_FALSE(contact_rings.empty());
  const int along = run.scene.mesh.segments_along;
  const auto [lo, hi] = std::minmax_element(contact_rings.begin(), contact_rings.end());
  EXPECT_GE(*lo, along / 3);
  EXPECT_LE(*hi, along - along / 3);
}
TEST(HardCases, BentTubeWallsTouchInTheBend) { expect_bent_tube_touches_in_the_bend({}); }
TEST(HardCasesCorotational, BentTubeWallsTouchInTheBend) { expect_bent_tube_touches_in_the_bend(corotational); }

// 7. Soak: 10,000 frames of a probe that pushes the lumen shut and pulls it open (triangle wave, zero force every
// 80 frames). When the force is back to zero the tube is back at rest (linear quasi-static: to 1e-9 of the
// soak's largest displacement); equal phases of an early and a late cycle give equal positions (no drift); the
// resident memory after frame 10,000 is not above that after frame 1,000 plus 1 MiB.
TEST(HardCases, SoakTenThousandFrames) {
  const Scene scene = load_scene(hard_scene("soak-oscillating.json"));
  auto model = compile_model(scene);
  Inputs inputs = make_inputs(scene);
  ASSERT_EQ(scene.frames, 10000);
  const int period = static_cast<int>(std::lround(4.0 * scene.fps));  // frames per push-pull cycle
  const int zero_every = period / 2;                                          // frames between zero-force keys
  State state = make_state(*model);
  Invariants inv;
  double umax = 0.0;             // largest displacement of the soak, metres
  double worst_at_zero = 0.0;    // largest displacement at a zero-force frame, metres
  int zero_frames = 0;
  // Positions at four phases of cycle 2 (early) and cycle 60 (late).
  const int early = 2 * period, late = 60 * period;
  const int phases[4] = {period / 8, period / 4, 5 * period / 8, 3 * period / 4};
  std::vector<Points> early_x(4);
  double drift = 0.0;
  long rss_1000 = -1, rss_end = -1;
  for (int i = 0; i < scene.frames; ++i) {
    FrameRecord rec;
    step(*model, inputs, state, rec);
    inv.check(*model, state, rec);
    // Largest node displacement from rest, from the positions.
    const double u = (state.x - model->mesh.rest).rowwise().norm().maxCoeff();
    umax = std::max(umax, u);
    // Zero-force frames: the probe track's force is exactly zero there.
    if (rec.frame % zero_every == 0) {
      ++zero_frames;
      EXPECT_EQ(state.samples[0].force.norm(), 0.0) << "frame " << rec.frame;
      worst_at_zero = std::max(worst_at_zero, u);
    }
    for (int p = 0; p < 4; ++p) {
      if (rec.frame == early + phases[p]) early_x[p] = state.x;
      if (rec.frame == late + phases[p]) drift = std::max(drift, (state.x - early_x[p]).cwiseAbs().maxCoeff());
    }
    if (rec.frame == 1000) rss_1000 = resident_bytes();
    if (rec.frame == scene.frames) rss_end = resident_bytes();
  }
  inv.expect_clean("soak-oscillating.json", 10000);
  std::printf("[hard] soak: max displacement %.6g m, at zero force %.3g m, drift %.3g m, contacts max %ld, "
              "frames with contacts %d, inverted max %d, resident %ld -> %ld bytes\n",
              umax, worst_at_zero, drift, inv.max_contacts, inv.frames_with_contacts, inv.max_inverted, rss_1000, rss_end);
  EXPECT_GT(inv.max_contacts, 0) << "the soak should close the lumen";
  EXPECT_EQ(zero_frames, scene.frames / zero_every);
  ASSERT_GT(umax, 0.0);
  EXPECT_LE(worst_at_zero, 1e-9 * umax) << "not back at rest when the force is zero";
  EXPECT_LE(drift, 1e-9 * umax) << "positions at equal phases drift between cycles 2 and 60";
  ASSERT_GT(rss_1000, 0);
  EXPECT_LE(rss_end, rss_1000 + (1L << 20)) << "resident memory grew from " << rss_1000 << " to " << rss_end << " bytes";
}

// 3. One end twisted by 180 degrees (scene keys "solver" and "twist"; collision on). Corotational: the tube's
// volume stays within 5% of rest. Linear: the small-rotation model is visibly wrong (it shrinks the rings toward
// the axis instead of rotating them), so some tets lose or gain more than half their volume; the collapsing
// lumen must stay intersection-free.
TEST(HardCases, TwistCorotationalKeepsTheVolume) {
  HardRun run = run_hard("twist-180-corotational.json");
  const Points& rest = run.model->mesh.rest;
  const double v0 = total_volume(rest, run.model->mesh.tets);
  const double v1 = total_volume(run.final_x, run.model->mesh.tets);
  EXPECT_LE(std::abs(v1 / v0 - 1.0), 0.05) << "rest " << v0 << " m^3, twisted " << v1 << " m^3";
  std::printf("[hard] twist corotational: volume change %.4f, largest per-tet volume error %.3f, contacts max %ld\n",
              v1 / v0 - 1.0, max_tet_volume_error(run.final_x, rest, run.model->mesh.tets), run.inv.max_contacts);
  // The end really turned: the stop end's first node is at the opposite side of the axis.
  const int v = run.model->mesh.node_set(lumen::physics::kStopEnd).front();
  EXPECT_NEAR(run.final_x(v, 0), -rest(v, 0), 1e-6);
  EXPECT_NEAR(run.final_x(v, 1), -rest(v, 1), 1e-6);
}

TEST(HardCases, TwistLinearIsVisiblyWrongButIntersectionFree) {
  HardRun run = run_hard("twist-180-linear.json");
  const double err = max_tet_volume_error(run.final_x, run.model->mesh.rest, run.model->mesh.tets);
  EXPECT_GT(err, 0.5) << "largest per-tet volume error " << err;
  const double v0 = total_volume(run.model->mesh.rest, run.model->mesh.tets);
  std::printf("[hard] twist linear: volume change %.4f, largest per-tet volume error %.3f, contacts max %ld\n",
              total_volume(run.final_x, run.model->mesh.tets) / v0 - 1.0, err, run.inv.max_contacts);
  EXPECT_GT(run.inv.max_contacts, 0) << "the linear twist should collapse the lumen onto itself";
}

// 2b. The force step under implicit dynamics (backward Euler, Rayleigh damping): every frame clean, the walls
// meet, and once the motion has died out the tube rests where the quasi-static solve puts it.
TEST(HardCases, ForceStepDynamicSettlesToTheQuasiStaticState) {
  HardRun dyn = run_hard("force-step-dynamic.json");
  HardRun stat = run_hard("force-step.json");
  EXPECT_GT(dyn.inv.max_contacts, 0);
  double umax = 0.0;
  for (const auto& f : stat.frames) umax = std::max(umax, f.max_displacement);
  ASSERT_GT(umax, 0.0);
  const double diff = (dyn.final_x - stat.final_x).cwiseAbs().maxCoeff();
  EXPECT_LE(diff, 1e-6 * umax) << "dynamic end state differs from the quasi-static one by " << diff << " m";
  std::printf("[hard] force step dynamic: end state differs from the quasi-static one by %.3g m (max displacement "
              "%.4g m), frames with contacts %d\n", diff, umax, dyn.inv.frames_with_contacts);
}
