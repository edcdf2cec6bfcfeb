#include "engine/response.hpp"

#include <algorithm>
#include <cstdint>
#include <map>
#include <set>

#include "collision/ccd.hpp"
#include "engine/clock.hpp"
#include "engine/grasp.hpp"
#include "engine/instrument_contact.hpp"
#include "engine/simulation.hpp"
#include "physics/lcp.hpp"

namespace lumen::engine {
namespace {


// Position of node i at time tau along the linear motion x0 -> x1.
Eigen::Vector3d at(const Points& x0, const Points& x1, int i, double tau) {
  return (1.0 - tau) * x0.row(i).transpose() + tau * x1.row(i).transpose();
}

}  // namespace

void weights_of(const collision::Contact& c, double w[4]) {
  if (c.kind == collision::FeatureKind::VertexFace) {
    w[0] = 1.0;
    w[1] = -(1.0 - c.s - c.t);
    w[2] = -c.s;
    w[3] = -c.t;
  } else {
    w[0] = 1.0 - c.s;
    w[1] = c.s;
    w[2] = -(1.0 - c.t);
    w[3] = -c.t;
  }
}

bool FeatureKey::operator<(const FeatureKey& o) const {
  if (part != o.part) return part < o.part;
  if (tool != o.tool) return tool < o.tool;
  if (kind != o.kind) return kind < o.kind;
  return std::lexicographical_compare(v, v + 4, o.v, o.v + 4);
}
bool FeatureKey::operator==(const FeatureKey& o) const {
  return part == o.part && tool == o.tool && kind == o.kind && std::equal(v, v + 4, o.v);
}

FeatureKey key_of(const collision::Contact& c) {
  FeatureKey k;
  k.kind = static_cast<int>(c.kind);
  std::copy(c.v, c.v + 4, k.v);
  return k;
}

FeatureKey key_of(const HeldContact& h) {
  FeatureKey k = key_of(h.c);
  k.part = h.part;
  k.tool = h.tool;
  return k;
}

physics::ContactRow row_of(const collision::Contact& c, const RowVertices& rv, double gap) {
  physics::ContactRow row;
  double w[4];
  weights_of(c, w);
  // Separation vector at the time of contact, at the start of the frame, and its part that u does not move.
  Eigen::Vector3d d_toi = Eigen::Vector3d::Zero(), d0 = Eigen::Vector3d::Zero(), d_fixed = Eigen::Vector3d::Zero();
  Eigen::Vector3d p[4];
  for (int k = 0; k < 4; ++k) {
    p[k] = (1.0 - c.toi) * rv.x0[k] + c.toi * rv.x1[k];
    d_toi += w[k] * p[k];
    d0 += w[k] * rv.x0[k];
    d_fixed += w[k] * rv.fixed[k];
  }
  // Contact normal: the separation direction at contact; when the features touch, the face normal (vf) or the
  // edges' common normal (ee), oriented to the side the first feature came from.
  Eigen::Vector3d n;
  const double scale = std::max(gap, 1e-12);
  if (d_toi.norm() > 1e-3 * scale) {
    n = d_toi.normalized();
  } else {
    n = (c.kind == collision::FeatureKind::VertexFace) ? (p[2] - p[1]).cross(p[3] - p[1]) : (p[1] - p[0]).cross(p[3] - p[2]);
    if (n.norm() == 0.0) n = d0.norm() > 0 ? d0 : Eigen::Vector3d::UnitZ();
    n.normalize();
    if (n.dot(d0) < 0) n = -n;
  }
  // Row: n . sum_k w_k (fixed_k + u_k) >= gap over the organ nodes (u_k = 0 for a kinematic vertex)
  // <=>  H u >= gap - n . sum_k w_k fixed_k.
  for (int k = 0; k < 4; ++k) {
    row.node[k] = rv.node[k];
    row.weight[k] = rv.node[k] >= 0 ? w[k] : 0.0;
  }
  row.n = n;
  row.g = gap - n.dot(d_fixed);
  return row;
}

physics::ContactRow contact_row(const collision::Contact& c, const Points& rest, const Points& x0, const Points& x1,
                                double gap) {
  // Every vertex an organ node: its end position is its rest position plus u.
  RowVertices rv;
  for (int k = 0; k < 4; ++k) {
    rv.node[k] = c.v[k];
    rv.x0[k] = x0.row(c.v[k]).transpose();
    rv.x1[k] = x1.row(c.v[k]).transpose();
    rv.fixed[k] = rest.row(c.v[k]).transpose();
  }
  return row_of(c, rv, gap);
}

namespace {

// Behavioural constants of the response.
constexpr double kIterativeToleranceGapFraction = 1e-3;  // NNCG: residual accepted, as a fraction of the gap
constexpr double kRecheckGapFraction = 0.5;   // re-check the corrected motion at this fraction of the gap
constexpr double kFallbackTimeFraction = 0.9; // the fallback stops the motion at this fraction of the first contact
constexpr double kEqualityTolerance = 1e-9;   // paper response: metres
// Restricted re-check: a wall feature pair is tested again when its vertices moved relative to each other, since
// the first detection, by this share of the difference between that detection's gap and the re-check's (the
// other half is the spare that keeps a skipped pair clear of the re-check's gap).
constexpr double kRecheckMarginShare = 0.5;
// Restricted first detections: the full one that makes their reference runs at this many gaps (the pairs it proves
// clear stay clear while their relative moves stay below the difference), and is run again once a restricted one
// meets more than this share of its leaf-box overlaps (its vertices have moved too far for the proof to prune). Chosen
// by the first detections' leaf-box overlaps summed over three scenes (factor 2, 3, 5; share 0.3, 0.5, 0.7).
constexpr double kNearGapFactor = 3.0;
constexpr double kReferenceOverlapShare = 0.3;
// What the restricted first detection's margin (the two gaps' difference) keeps spare, metres: the elementary tests
// may report a pair up to two tolerances beyond the gap (false positives, collision::CcdOptions), so a skipped pair
// is kept clear of that too, with as much again for rounding; the full twin then finds nothing it skips, short of a
// test that reaches its work bound (reported whatever the distance; none in the twin tests).
constexpr double kMarginSpare = 4.0 * collision::CcdOptions{}.tolerance;
// Contacts solved in the equilibrium (coupling "solved"): the frame's first detection holds every pair within this
// many gaps of the trial motion as a row (each still asks for the gap only). A round moves the whole tube to its
// equilibrium, pushing pairs near the contact area together: found only by the re-checks, they cost a round each.
constexpr double kSolvedDetectionGapFactor = 3.0;

// One frame's response rounds: the active constraints and the last solve.
struct ResponseRounds {
  std::map<FeatureKey, HeldContact> active;         // contacts held as constraints (self and tool)
  std::set<FeatureKey> pushing;                     // those whose multiplier was positive in the last solve
  std::vector<physics::ContactRow> rows;            // the last solve's rows (active order)
  physics::ContactResult solved;                    // the last solve
  int iterations = 0;
  int lcp_iterations = 0;                           // pivots / rounds / sweeps over the solves
  bool lcp_converged = true;                        // every LCP of the rounds reached its tolerance
  std::map<FeatureKey, double> carried;             // last frame's multipliers (NNCG's warm start)
  std::map<FeatureKey, double> in_solve;            // coupling "carried": each carried row's force in the solve
  int equilibrium_steps = 0;                        // coupling "solved": QP steps over the rounds
  int equilibrium_backtracks = 0;                   // coupling "solved": line-search halvings over the rounds
  double equilibrium_residual = 0.0;                // coupling "solved": the last round's KKT residual
  int refactor_failures = 0;                        // coupling "solved": its Hessian's failed factorisations
};

// The paper's response (Sec. 3.4): hold every colliding vertex, and the probe points, at their time-of-contact
// positions along the free motion.
void solve_paper(const Model& model, State& state, const Points& x_free, const Eigen::VectorXd& u_free,
                 ResponseRounds& rr) {
  const Points& x0 = state.x;
  double toi_min = 1.0;
  std::map<int, Eigen::Vector3d> held;
  for (const auto& [key, h] : rr.active) {
    const collision::Contact& c = h.c;
    toi_min = std::min(toi_min, c.toi);
    for (int k = 0; k < 4; ++k)
      if (!held.count(c.v[k])) held[c.v[k]] = at(x0, x_free, c.v[k], c.toi);
  }
  for (const auto& sp : model.probe_points)
    for (int k = 0; k < 3; ++k)
      if (!held.count(sp.node[k])) held[sp.node[k]] = at(x0, x_free, sp.node[k], toi_min);
  for (const auto& [node, pos] : held)
    for (int axis = 0; axis < 3; ++axis) {
      physics::ContactRow r;
      r.node[0] = node;
      r.weight[0] = 1.0;
      r.n = Eigen::Vector3d::Unit(axis);
      r.g = pos[axis] - model.mesh.rest(node, axis);
      rr.rows.push_back(r);
    }
  rr.solved = physics::solve_equality(*state.compliance, rr.rows, u_free, kEqualityTolerance, false);
}

// Contacts inside the corotational equilibrium (collision.coupling "solved"): the round's rows constrain the
// integrator's own equilibrium (Integrator::solve_with_contacts: the potential minimised on the rows), from the last
// round's end (the free motion in the first), each row warm-started with its contact's last multiplier. The
// correction is whole-mesh; the residual is the rows' (the largest violation, or a pushing row's distance from its
// value), metres, as the other contact solves report it.
void solve_in_equilibrium(const Model& model, State& state, const Points& x1, const Eigen::VectorXd& u_free,
                          ResponseRounds& rr) {
  const CollisionSpec& cs = model.collision;
  Eigen::VectorXd warm = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(rr.active.size()));
  for (const auto& [key, h] : rr.active) {
    const auto carried = rr.carried.find(key);
    if (carried != rr.carried.end()) warm[static_cast<Eigen::Index>(rr.rows.size())] = carried->second;
    rr.rows.push_back(contact_row(h.c, model.mesh.rest, state.x, x1, cs.gap));
  }
  // The start: the last round's end, or in the first round the last frame's end (on last frame's rows, and near
  // this frame's, where the free motion may have passed far through the walls) with the frame's prescribed values.
  Eigen::VectorXd u = u_free;
  if (rr.solved.correction.size() == u_free.size()) {
    u += rr.solved.correction;
  } else if (state.sim.u.size() == u.size()) {
    for (Eigen::Index d = 0; d < u.size(); ++d)
      if (!model.integrator->is_fixed_dof(static_cast<int>(d))) u[d] = state.sim.u[d];
  }
  physics::ContactEquilibriumOptions o;
  o.tolerance = model.equilibrium_tolerance;
  o.max_steps = cs.equilibrium_steps;
  o.feasibility_tolerance = kIterativeToleranceGapFraction * cs.gap;
  o.lcp_sweeps = cs.lcp == LcpSolver::kNncg ? cs.lcp_sweeps : 0;
  o.hessian = cs.equilibrium_hessian == EquilibriumHessian::kWarpedRest ? physics::ContactHessian::node_rotations
                                                                       : physics::ContactHessian::as_given;
  const physics::ContactEquilibriumResult r =
      model.integrator->solve_with_contacts(rr.rows, *state.compliance, o, state.work, u, warm);
  rr.equilibrium_steps += r.steps;
  rr.equilibrium_backtracks += r.backtracks;
  rr.equilibrium_residual = r.residual;
  rr.lcp_iterations += r.lcp_iterations;
  rr.lcp_converged = rr.lcp_converged && r.lcp_converged;
  rr.refactor_failures += r.refactor_failures;
  physics::ContactResult& solved = rr.solved;
  solved.lambda = r.lambda;
  solved.force = physics::contact_force(rr.rows, r.lambda, static_cast<int>(u.size()));
  solved.correction = u - u_free;
  solved.iterations = r.steps;
  solved.converged = r.converged;
  solved.residual =
      physics::lcp_residual(physics::row_values(rr.rows, u) - physics::row_targets(rr.rows), r.lambda);
  rr.pushing.clear();
  Eigen::Index i = 0;
  for (const auto& entry : rr.active) {
    rr.carried[entry.first] = r.lambda[i];
    if (r.lambda[i++] > 0.0) rr.pushing.insert(entry.first);
  }
}

// Non-penetration with the gap, as an LCP on the walls' compliance: active-set method on columns of the coupling
// matrix computed on demand, warm-started from the rows that pushed last time.
void solve_constraint(const Model& model, State& state, const Points& x1, const Eigen::VectorXd& u_free,
                      ResponseRounds& rr) {
  // The points the solve keeps where u_free put them: the graspers' held nodes, or the held probes.
  const physics::HeldPoints* held = state.grasp_holds.empty() ? model.integrator->held_points() : &state.grasp_holds.held;
  std::vector<int> warm;
  for (const auto& [key, h] : rr.active) {
    if (rr.pushing.count(key)) warm.push_back(static_cast<int>(rr.rows.size()));
    rr.rows.push_back(h.is_tool() ? tool_contact_row(h, model, state, state.x, x1, model.collision.gap)
                                  : contact_row(h.c, model.mesh.rest, state.x, x1, model.collision.gap));
  }
  if (model.collision.lcp == LcpSolver::kNncg) {
    // Warm start: last frame's multiplier of each contact still held (0 for a new one).
    physics::IterativeLcpOptions o;
    o.max_sweeps = model.collision.lcp_sweeps;
    o.tolerance = kIterativeToleranceGapFraction * model.collision.gap;
    o.warm = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(rr.active.size()));
    Eigen::Index r = 0;
    for (const auto& entry : rr.active) {
      const auto carried = rr.carried.find(entry.first);
      if (carried != rr.carried.end()) o.warm[r] = carried->second;
      ++r;
    }
    rr.solved = physics::solve_contacts_iterative(*state.compliance, rr.rows, u_free, o, false, held);
  } else {
    rr.solved = physics::solve_contacts(*state.compliance, rr.rows, u_free, warm, {}, false, held);
  }
  rr.lcp_iterations += rr.solved.iterations;
  rr.lcp_converged = rr.lcp_converged && rr.solved.converged;
  rr.pushing.clear();
  int r = 0;
  for (const auto& entry : rr.active)
    if (rr.solved.lambda[r++] > 0.0) rr.pushing.insert(entry.first);
}

// The probes' forces with the contacts' effect (what a device displays): displacement-driven probes change their
// force so that contacts do not move them; in the paper's response every probe is held, and the holding forces at
// its nodes add to its force.
void add_contact_to_probe_forces(const Model& model, State& state, const ResponseRounds& rr) {
  const bool constraint = model.collision.response == ResponseKind::kConstraint;
  if (constraint && rr.solved.held_force.size() > 0) {
    for (size_t a = 0; a < model.held_probes.size(); ++a)
      state.samples[model.held_probes[a]].force += rr.solved.held_force.segment<3>(3 * a);
  } else if (!constraint) {
    for (size_t p = 0; p < model.probe_points.size(); ++p)
      for (int k = 0; k < 3; ++k) {
        const int node = model.probe_points[p].node[k];
        for (size_t r = 0; r < rr.rows.size(); ++r)
          if (rr.rows[r].node[0] == node) state.samples[p].force += rr.solved.lambda[static_cast<long>(r)] * rr.rows[r].n;
      }
  }
}

// The frame's first detection, which a restricted re-check starts from: its end positions, its gap, and the
// nodes of the self-contacts it found.
struct RecheckReference {
  Points x1;
  double gap = 0.0;
  std::vector<int> contact_nodes;
};

// The wall features a re-check at `gap` must test again: those of the reference's contacts (flagged), and those
// whose vertices moved relative to each other, since the reference, by at least half the gaps' difference. Any
// other pair was farther apart than ref.gap all along the reference sweep (no contact: the tests are
// conservative) and, with the same start and its separation off by at most its relative move at every time, is
// farther than gap + (ref.gap - gap) / 2 on the new one: clear, with half the difference to spare.
void flag_reference_contacts(const Model& model, const RecheckReference& ref, std::vector<std::uint8_t>& flagged) {
  flagged.assign(static_cast<size_t>(model.mesh.n_nodes()), 0);
  for (const int v : ref.contact_nodes) flagged[static_cast<size_t>(v)] = 1;
}

// A new proximity reference: the walls' full detection of state.x -> x1 at the near gap, its contacts at `gap` into
// `contacts`.
void take_proximity_reference(const Model& model, State& state, const Points& x1, double gap,
                              std::vector<collision::Contact>& contacts, collision::CollisionStats& stats) {
  ProximityReference& ref = state.proximity;
  ref.near_gap = kNearGapFactor * gap;
  collision::detect_self_near(*model.collision_surface, *state.detector, state.x, x1, gap, ref.near_gap, contacts,
                              ref.near, &stats);
  ref.x0 = state.x;
  ref.x1 = x1;
  ref.overlaps = stats.bv_overlaps;
}

// The walls' contacts of a frame's first detection (state.x -> x1 within gap) into state.contacts: restricted by the
// proximity reference when there is one (and the scene asks for it), otherwise in full at the near gap, which makes
// the next reference. Returns whether it was full.
bool detect_walls_first(const Model& model, State& state, const Points& x1, double gap,
                        collision::CollisionStats& stats) {
  const collision::CollisionSurface& surface = *model.collision_surface;
  ProximityReference& ref = state.proximity;
  if (model.collision.detection == Detection::kFull) {
    collision::detect_self(surface, *state.detector, state.x, x1, gap, state.contacts, &stats);
    return true;
  }
  const double margin = ref.near_gap - gap - kMarginSpare;
  if (ref.valid() && margin > 0.0) {
    const collision::PointsRef x0_ref(ref.x0), x1_ref(ref.x1);
    const collision::MoveFilter filter{&x1_ref, margin, nullptr, &x0_ref, &ref.near};
    collision::detect_self_moved(surface, *state.detector, state.x, x1, gap, filter, state.contacts, &stats);
    // Too much left to test: the next first detection makes a new reference.
    if (static_cast<double>(stats.bv_overlaps) > kReferenceOverlapShare * static_cast<double>(ref.overlaps))
      ref = ProximityReference{};
    return false;
  }
  take_proximity_reference(model, state, x1, gap, state.contacts, stats);
  return true;
}

// Every contact of the organ motion state.x -> x1 within gap: the walls' self-contacts (when they collide) and the
// instruments' contacts along their sweeps; `out` is cleared first. With a reference (a re-check at a smaller
// gap), the walls' features that provably stay clear since it are not tested again (the instruments' sweeps are).
// A frame's first detection (`first`) goes through the proximity reference (detect_walls_first); its return says
// whether the walls were tested in full (always, for the other detections).
bool detect_all(const Model& model, State& state, const Points& x1, double gap, std::vector<HeldContact>& out,
                collision::CollisionStats* stats, const RecheckReference* ref = nullptr, bool first = false) {
  out.clear();
  bool full = true;
  if (model.collision_surface && ref && ref->gap > gap) {
    flag_reference_contacts(model, *ref, state.recheck_flags);
    const collision::PointsRef x1_ref(ref->x1);
    const collision::MoveFilter filter{&x1_ref, kRecheckMarginShare * (ref->gap - gap), &state.recheck_flags};
    collision::detect_self_moved(*model.collision_surface, *state.detector, state.x, x1, gap, filter, state.contacts,
                                 stats);
  } else if (model.collision_surface && first) {
    collision::CollisionStats walls;
    full = detect_walls_first(model, state, x1, gap, walls);
    if (stats) *stats = walls;
  } else if (model.collision_surface) {
    collision::detect_self(*model.collision_surface, *state.detector, state.x, x1, gap, state.contacts, stats);
  }
  if (model.collision_surface)
    for (const collision::Contact& c : state.contacts) out.push_back(HeldContact{c, -1, 0});
  if (!model.tool_parts.empty()) detect_tool_contacts(model, state, state.x, x1, gap, out, stats);
  return full;
}

// The first detection as a re-check's reference (none when the scene asks for full re-checks).
RecheckReference reference_of(const Model& model, const Points& x1, double gap, const std::vector<HeldContact>& found) {
  RecheckReference ref;
  if (model.collision.recheck != Recheck::kRestricted || !model.collision_surface) return ref;
  ref.x1 = x1;
  ref.gap = gap;
  for (const HeldContact& h : found)
    if (!h.is_tool()) ref.contact_nodes.insert(ref.contact_nodes.end(), h.c.v, h.c.v + 4);
  return ref;
}

// Fallback: stop the motion x0 -> x1, and the instruments' sweeps, at a safe fraction of the earliest true contact
// (intersection-free by construction: every vertex moves linearly and nothing touched before); u follows, and the
// instruments end the frame there (state.tool_target, state.tool_pose_target). Returns whether a contact was found.
bool stop_before_contact(const Model& model, State& state, Points& x1, Eigen::VectorXd& u) {
  std::vector<HeldContact> hits;
  detect_all(model, state, x1, 0.0, hits, nullptr);
  double toi_min = 1.0;
  for (const HeldContact& h : hits) toi_min = std::min(toi_min, h.c.toi);
  const double tau = hits.empty() ? 1.0 : kFallbackTimeFraction * toi_min;
  x1 = state.x + tau * (x1 - state.x);
  const Points du = x1 - model.mesh.rest;
  u = Eigen::Map<const Eigen::VectorXd>(du.data(), du.size());
  for (size_t p = 0; p < state.tool_target.size(); ++p)
    state.tool_target[p] = state.tool_points[p] + tau * (state.tool_target[p] - state.tool_points[p]);
  for (size_t i = 0; i < state.tool_pose_target.size(); ++i) {
    state.tool_pose_target[i] = interpolate(state.tool_pose[i], state.tool_pose_target[i], tau);
    state.tool_opening_target[i] = state.tool_opening[i] + tau * (state.tool_opening_target[i] - state.tool_opening[i]);
  }
  return !hits.empty();
}

// Sum over nodes of |x - x0|, metres.
double path_length(const Points& x, const Points& x0) { return (x - x0).rowwise().norm().sum(); }

// Keep the correction and the contacts that carry force for the next frame; flag their nodes for rendering.
void keep_for_next_frame(const Model& model, State& state, const ResponseRounds& rr, const Eigen::VectorXd& u,
                         const Eigen::VectorXd& u_free) {
  state.last_correction = u - u_free;
  state.active.clear();
  state.active_lambda.clear();
  state.active_total.clear();
  state.tool_active.clear();
  state.tool_active_lambda.clear();
  int r = 0;
  for (const auto& [key, h] : rr.active) {
    const double lambda = r < rr.solved.lambda.size() ? rr.solved.lambda[r] : 0.0;
    const auto solve = rr.in_solve.find(key);
    const double total = lambda + (solve == rr.in_solve.end() ? 0.0 : solve->second);
    if (h.is_tool() && total > 0.0) {
      state.tool_active.push_back(h);
      state.tool_active_lambda.push_back(lambda);
    } else if (!h.is_tool() && (model.collision.response == ResponseKind::kPaper || total > 0.0)) {
      state.active.push_back(h.c);
      state.active_lambda.push_back(lambda);
      state.active_total.push_back(total);
    }
    ++r;
  }
  // The organ's nodes of every contact (a tool contact's part vertices are not mesh nodes).
  for (const auto& entry : rr.active)
    for (int k = 0; k < 4; ++k)
      if (!entry.second.on_tool(k)) state.in_contact[entry.second.c.v[k]] = 1;
}

// The instruments end the frame where their sweep ended (the target, or short of it after the fallback); their
// records carry the last solve's contact forces on them.
void end_tool_sweeps(const Model& model, State& state, const ResponseRounds& rr) {
  if (model.instruments.empty()) return;
  state.tool_points = state.tool_target;
  state.tool_pose = state.tool_pose_target;
  state.tool_opening = state.tool_opening_target;
  // The holds' forces: what held the nodes on the free motion, and what kept them there through the contacts.
  if (!state.grasp_holds.empty() && rr.solved.held_force.size() == state.grasp_force.size())
    state.grasp_force += rr.solved.held_force;
  std::vector<HeldContact> contacts;
  for (const auto& entry : rr.active) contacts.push_back(entry.second);
  state.tool_records = instrument_records(model, state, contacts, rr.rows, rr.solved.lambda);
  if (model.collision.response == ResponseKind::kConstraint)
    add_tool_stiffness(model, state, contacts, rr.rows, rr.solved.lambda, state.tool_records);
}

// The constraint response's warm start: last frame's held self-contacts and tool contacts, re-measured at the
// frame's start, all guessed to push, with their multipliers.
void warm_start(const Model& model, const State& state, ResponseRounds& rr) {
  for (size_t i = 0; i < state.active.size(); ++i) {
    const FeatureKey key = key_of(state.active[i]);
    rr.active.emplace(key, remeasured(HeldContact{state.active[i], -1, 0}, state));
    rr.pushing.insert(key);
    if (i < state.active_lambda.size()) rr.carried[key] = state.active_lambda[i];
    if (static_cast<Eigen::Index>(i) < state.carried_lambda.size()) rr.in_solve[key] = state.carried_lambda[i];
  }
  for (size_t i = 0; i < state.tool_active.size(); ++i) {
    if (held_by_own_instrument(model, state, state.tool_active[i])) continue;  // grasped since: frozen
    const FeatureKey key = key_of(state.tool_active[i]);
    rr.active.emplace(key, remeasured(state.tool_active[i], state));
    rr.pushing.insert(key);
    rr.carried[key] = state.tool_active_lambda[i];
  }
}

}  // namespace

void prime_proximity(const Model& model, State& state) {
  if (!model.collision_surface || model.collision.detection != Detection::kRestricted) return;
  std::vector<collision::Contact> at_rest;
  collision::CollisionStats stats;
  take_proximity_reference(model, state, state.x, model.collision.gap, at_rest, stats);
}

void collide_and_respond(const Model& model, State& state, Eigen::VectorXd& u, FrameRecord& rec) {
  const int n = model.mesh.n_nodes();
  const CollisionSpec& cs = model.collision;
  const bool paper = cs.response == ResponseKind::kPaper;
  const Eigen::VectorXd u_free = u;
  auto positions = [&](const Eigen::VectorXd& uu) { return Points(model.mesh.rest + Eigen::Map<const Points>(uu.data(), n, 3)); };
  const Points x_free = positions(u);
  // Predicted motion: the free solution plus last frame's contact correction (contacts persist from frame to
  // frame), so where the walls already touch the sweep stays short instead of passing deep through each other.
  const bool predict = state.last_correction.size() == u.size() && !state.last_correction.isZero(0.0);
  Points x1 = predict ? positions(u_free + state.last_correction) : x_free;
  bool x1_predicted = predict;  // x1 is still that prediction

  // Active constraints: last frame's held contacts (warm start, constraint response) plus every new one. The
  // contacts that pushed last time are the active-set solver's first guess.
  auto clock = Clock::now();
  ResponseRounds rr;
  if (!paper) warm_start(model, state, rr);
  rec.ms[kResponse] += ms_since(clock);

  // First detection on the predicted motion (the instruments sweep to their targets). When it finds nothing to
  // hold, the frame ends on the free motion, so that is the motion checked: a prediction carrying a correction
  // whose contacts were not kept (a capped frame, or contacts that let go) differs from it.
  clock = Clock::now();
  collision::CollisionStats stats;
  std::vector<HeldContact> found;
  const double first_gap = model.contacts_in_solve ? kSolvedDetectionGapFactor * cs.gap : cs.gap;
  rec.full_detection = detect_all(model, state, x1, first_gap, found, &stats, nullptr, true);
  if (predict && found.empty() && rr.active.empty()) {
    x1 = x_free;
    x1_predicted = false;
    collision::CollisionStats again;
    rec.full_detection = detect_all(model, state, x1, first_gap, found, &again, nullptr, true) || rec.full_detection;
    stats.bv_overlaps += again.bv_overlaps;  // the frame's counters cover both detections, as its time does
    stats.feature_tests += again.feature_tests;
    stats.contacts = again.contacts;
  }
  rec.first_contacts = std::count_if(found.begin(), found.end(), [](const HeldContact& h) { return !h.is_tool(); });
  const RecheckReference reference = reference_of(model, x1, first_gap, found);
  const RecheckReference* restrict_to = reference.gap > 0.0 ? &reference : nullptr;
  rec.bv_overlaps = stats.bv_overlaps;
  rec.feature_tests = stats.feature_tests;
  rec.contacts = stats.contacts;
  rec.ms[kCollision] += ms_since(clock);

  clock = Clock::now();
  bool resolved = found.empty() && rr.active.empty();
  while (!resolved && rr.iterations < cs.max_iterations) {
    ++rr.iterations;
    // Add the contacts found on the current trial motion, solve for the correction; too many: the safe fallback
    // (nothing of this frame's solves is kept).
    for (const HeldContact& h : found) rr.active[key_of(h)] = h;
    if (rr.active.size() > static_cast<size_t>(cs.max_contact_rows)) {
      rec.contact_rows_capped = true;
      rr = ResponseRounds{};
      break;
    }
    rr.rows.clear();
    if (paper)
      solve_paper(model, state, x_free, u_free, rr);
    else if (model.contacts_in_solve)
      solve_in_equilibrium(model, state, x1, u_free, rr);
    else
      solve_constraint(model, state, x1, u_free, rr);
    // The correction is exact on the colliding walls (all the check reads); the rest of the mesh follows at the end.
    u = u_free + rr.solved.correction;
    x1 = positions(u);
    x1_predicted = false;
    rec.ms[kResponse] += ms_since(clock);

    // Re-check the corrected motion with one CCD pass at a fraction of the gap (the rows ask for the full gap, so
    // a held contact is done when this is clear), restricted to the wall features that moved since the first
    // detection; what it finds joins the active set for the next round.
    clock = Clock::now();
    detect_all(model, state, x1, kRecheckGapFraction * cs.gap, found, nullptr, restrict_to);
    resolved = found.empty();
    rec.ms[kCollision] += ms_since(clock);
    clock = Clock::now();
  }
  rec.response_iterations = rr.iterations;  // 0 after the cap (its rounds were discarded)
  if (rr.iterations > 0) {
    // Total normal force the walls carry (the constraint response's multipliers are contact forces).
    if (!paper) rec.contact_force = rr.solved.lambda.sum();
    for (const auto& [key, lambda] : rr.in_solve) rec.contact_force += lambda;
    rec.contact_residual = rr.solved.residual;
    rec.lcp_iterations = rr.lcp_iterations;
    rec.lcp_converged = rr.lcp_converged;
    rec.equilibrium_steps = rr.equilibrium_steps;
    rec.equilibrium_backtracks = rr.equilibrium_backtracks;
    rec.equilibrium_residual = rr.equilibrium_residual;
    rec.preconditioner_failures += rr.refactor_failures;
    add_contact_to_probe_forces(model, state, rr);
    // Whole-mesh correction for the last multipliers (a sum of precomputed columns or one back-substitution); the
    // colliding walls keep the values the check saw (equal to round-off).
    // Deferred (a resolved frame that would back-substitute, in a session that renders): exact on the colliding
    // and drawn nodes now from the kept rows; step_begin() starts the interior's solve, step_end() joins it.
    clock = Clock::now();
    Eigen::VectorXd du;
    physics::SurfaceCompliance& sc = *state.compliance;
    bool by_view = false;
    if (model.contacts_in_solve) {
      du = rr.solved.correction;  // (contacts solved in the equilibrium: whole-mesh already)
    } else {
      by_view = sc.needs_solve(rr.solved.force) && sc.loads_only_view(rr.solved.force);
      if (by_view)
        sc.displacement_on_view(rr.solved.force, du);
      else
        sc.displacement(rr.solved.force, du);
      for (int v : sc.nodes()) du.segment<3>(3 * v) = rr.solved.correction.segment<3>(3 * v);
    }
    rec.interior_deferred = by_view && state.defer_interior && resolved;
    if (rec.interior_deferred) {
      state.pending.du = du;
      state.pending.u_free = u_free;
    } else if (by_view) {
      sc.complete_interior(du);
    }
    u = u_free + du;
    x1 = positions(u);
    rec.ms[kResponse] += ms_since(clock);
  }

  // A pipelined last frame commits now that the rounds are done: before the fallback, which reads the whole state,
  // and before this frame's correction replaces the last one. A trial motion still on the prediction takes the last
  // correction's interior, whole only now.
  const bool settling = state.pending.in_flight.interior.valid();
  wait_for_last_frame(model, state, rec);
  if (settling && x1_predicted) x1 = positions(u_free + state.last_correction);

  // Unresolved after the last round: the safe fallback.
  if (!resolved) {
    clock = Clock::now();
    const double wanted = path_length(x1, state.x);
    rec.fallback = stop_before_contact(model, state, x1, u);
    rec.fallback_kept = wanted > 0.0 ? path_length(x1, state.x) / wanted : 1.0;
    rec.ms[kCollision] += ms_since(clock);
  }
  keep_for_next_frame(model, state, rr, u, u_free);
  end_tool_sweeps(model, state, rr);
  rec.contacts = static_cast<long>(std::max<size_t>(rr.active.size(), static_cast<size_t>(stats.contacts)));
}

}  // namespace lumen::engine
