#pragma once
// Per-frame records, stage statistics against the frame budget, and the session report (report.json).
#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "physics/types.hpp"

namespace lumen::engine {

// Stages of one frame, in order; Total is the simulation thread's work for the frame.
enum Stage : int { kInput = 0, kPhysics, kCollision, kResponse, kRender, kTotal, kStageCount };
const char* stage_name(int stage);

// What one instrument did in a frame (report.json per_frame[i].instruments).
struct InstrumentRecord {
  std::string name;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();            // its origin (the tip) at the frame's end, metres
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  // instrument frame -> organ frame
  Eigen::Vector3d force = Eigen::Vector3d::Zero();   // newtons: the contact force on the instrument
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();  // newton metres: the contacts' torque about its origin
  int contacts = 0;                                  // its contact rows in the frame's last solve
  double opening = 0.0;                              // radians: a grasper's jaw opening at the frame's end (else 0)
  std::vector<int> held_nodes;                       // organ node ids its jaws hold (a grasping grasper), sorted
  // Local stiffness of its tip against translation, N/m: d(-force)/d(position) with the frame's pushing contacts
  // held (symmetric positive semi-definite; zero without contact). What the haptic loop renders between frames.
  Eigen::Matrix3d stiffness = Eigen::Matrix3d::Zero();
};

// What one frame did and cost.
struct FrameRecord {
  int frame = 0;                      // 1-based
  double t = 0.0;                     // simulated time at the end of the frame, seconds
  std::array<double, kStageCount> ms{};  // milliseconds per stage
  bool over_budget = false;
  // Collision statistics (zero when self-collision is off).
  long bv_overlaps = 0, feature_tests = 0, contacts = 0;
  // The frame's first detection tested every wall feature pair (collision.detection "full", or a new proximity
  // reference); false when it was restricted by the last one.
  bool full_detection = true;
  long first_contacts = 0;  // the walls' self-contacts the frame's first detection found
  int response_iterations = 0;
  bool fallback = false;              // the safe fallback ended this frame's motion early
  bool contact_rows_capped = false;   // ... because its contacts exceeded collision.max_contact_rows
  // Part of its last trial motion the fallback kept: sum over nodes of |x_end - x_start| over the same sum for the
  // motion it ended (the stop's time fraction); 1 when no fallback ran.
  double fallback_kept = 1.0;
  // The whole-mesh correction's interior (the nodes neither colliding nor drawn) was solved on a second thread while
  // the frame rendered (pipelined: and while the next frame ran up to its response). interior_wait_ms: this frame's
  // wait for such a solve, its own after the render or the last frame's after its response, milliseconds (also
  // counted in the response stage).
  bool interior_deferred = false;
  double interior_wait_ms = 0.0;
  long intersecting_pairs = -1;       // exact check (--check), -1 when not run
  long instrument_intersecting_pairs = -1;  // exact check (--check) of instrument-organ pairs, -1 when not run
  int inverted_elements = 0;          // tets with non-positive volume after the frame
  bool numerical_failure = false;     // NaN/Inf or solver failure: the last good frame was kept
  bool bad_input = false;             // a source gave a non-finite sample; its last good sample was used
  int physics_iterations = 0;         // corotational or dynamic: outer iterations of the solve (0 for static linear)
  bool physics_converged = true;      // corotational or dynamic: the solve reached its tolerance
  bool physics_diverged = false;      // corotational: the solve diverged and went back to its start (a numerical
                                      // failure: the last good frame was kept)
  int refactorisations = 0;           // corotational: lagged warped factorisations started this frame
  int tangent_fallbacks = 0;          // corotational, solver.tangent exact: steps redone with K_w this frame
  int cg_iterations = 0;              // corotational quasi-static: PCG iterations this frame
  int truncated_steps = 0;            // corotational, solver.tangent exact: CG stopped at negative curvature
  int preconditioner_failures = 0;    // corotational: lagged factorisations that failed (previous one kept)
  double twist_degrees = 0.0;         // angle of the twisted end ring at the end of the frame (0 without twist)
  double kinetic_energy = 0.0;        // dynamic: 1/2 v^T M v at the end of the frame, joules (0 quasi-static)
  double contact_force = 0.0;         // constraint response: total normal force the walls carry (sum of the
                                      // contact multipliers), newtons; 0 without contact or with "paper"
  double contact_residual = 0.0;      // the last contact solve's residual (largest row violation or
                                      // complementarity gap), metres; 0 without contact
  int lcp_iterations = 0;             // the contact solves' pivots / active-set rounds / NNCG sweeps, summed
  bool lcp_converged = true;          // every contact solve's LCP reached its tolerance (NNCG may stop at its
                                      // sweep budget short of it); true without contact
  // collision.coupling "solved": QP steps and line-search halvings over the frame's response rounds, and the
  // equilibrium's KKT residual at the end (|f - f_int + H^T lambda| / force scale; 0 without contact).
  int equilibrium_steps = 0;
  int equilibrium_backtracks = 0;
  double equilibrium_residual = 0.0;
  double max_displacement = 0.0;      // metres, max node displacement from rest
  std::vector<Eigen::Vector3d> reactions;  // per probe, newtons
  // Per probe, the displacement from rest of its attachment point at the end of the frame (its nodes'
  // displacements by the barycentric weights), metres. A tip made of several probes is measured by their mean.
  std::vector<Eigen::Vector3d> probe_displacement;
  std::vector<InstrumentRecord> instruments;  // per instrument, in the scene's order
};

struct StageSummary {
  double median_ms = 0, p95_ms = 0, p99_ms = 0, max_ms = 0;
};
// Percentiles by linear interpolation between order statistics.
StageSummary summarize(std::vector<double> values_ms);

// Writes JSON to `path` atomically (temporary name, then rename). Throws std::runtime_error naming the path.
void write_json_file(const std::string& path, const nlohmann::json& j);
// Writes text to `path` atomically (temporary name, then rename). Throws std::runtime_error naming the path.
void write_text_file(const std::string& path, const std::string& text);
// Node positions as CSV, one "x,y,z" line per node with 17 significant digits (round-trips exactly), metres.
std::string positions_csv(const Points& x);

// Stage table as text (for `lumen bench` and the end of `lumen run`).
std::string format_stage_table(const std::vector<FrameRecord>& frames, double budget_ms);
nlohmann::json stages_json(const std::vector<FrameRecord>& frames);
nlohmann::json frame_json(const FrameRecord& r);

}  // namespace lumen::engine
