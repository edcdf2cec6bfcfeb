#include "engine/response.hpp"

#include <algorithm>
#include <chrono>
#include <map>
#include <set>

#include "engine/simulation.hpp"

namespace lumen::engine {
namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

// Position of node i at time tau along the linear motion x0 -> x1.
Eigen::Vector3d at(const Points& x0, const Points& x1, int i, double tau) {
  return (1.0 - tau) * x0.row(i).transpose() + tau * x1.row(i).transpose();
}

// Barycentric-style weights of a contact's four vertices: sum_k w_k x_k is the separation vector.
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

}  // namespace

bool FeatureKey::operator<(const FeatureKey& o) const {
  if (kind != o.kind) return kind < o.kind;
  return std::lexicographical_compare(v, v + 4, o.v, o.v + 4);
}
bool FeatureKey::operator==(const FeatureKey& o) const { return kind == o.kind && std::equal(v, v + 4, o.v); }

FeatureKey key_of(const collision::Contact& c) {
  FeatureKey k;
  k.kind = static_cast<int>(c.kind);
  std::copy(c.v, c.v + 4, k.v);
  return k;
}

physics::ContactRow contact_row(const collision::Contact& c, const Points& rest, const Points& x0, const Points& x1,
                                double gap) {
  physics::ContactRow row;
  double w[4];
  weights_of(c, w);
  // Separation vector at the time of contact and at the start of the frame.
  Eigen::Vector3d d_toi = Eigen::Vector3d::Zero(), d0 = Eigen::Vector3d::Zero(), d_rest = Eigen::Vector3d::Zero();
  for (int k = 0; k < 4; ++k) {
    d_toi += w[k] * at(x0, x1, c.v[k], c.toi);
    d0 += w[k] * x0.row(c.v[k]).transpose();
    d_rest += w[k] * rest.row(c.v[k]).transpose();
  }
  // Contact normal: the separation direction at contact; when the features touch, the face normal (vf) or the
  // edges' common normal (ee), oriented to the side the first feature came from.
  Eigen::Vector3d n;
  const double scale = std::max(gap, 1e-12);
  if (d_toi.norm() > 1e-3 * scale) {
    n = d_toi.normalized();
  } else {
    const Eigen::Vector3d p0 = at(x0, x1, c.v[0], c.toi), p1 = at(x0, x1, c.v[1], c.toi);
    const Eigen::Vector3d p2 = at(x0, x1, c.v[2], c.toi), p3 = at(x0, x1, c.v[3], c.toi);
    n = (c.kind == collision::FeatureKind::VertexFace) ? (p2 - p1).cross(p3 - p1) : (p1 - p0).cross(p3 - p2);
    if (n.norm() == 0.0) n = d0.norm() > 0 ? d0 : Eigen::Vector3d::UnitZ();
    n.normalize();
    if (n.dot(d0) < 0) n = -n;
  }
  // Row: n . sum_k w_k (X_k + u_k) >= gap  <=>  H u >= gap - n . sum_k w_k X_k.
  for (int k = 0; k < 4; ++k) {
    row.node[k] = c.v[k];
    row.weight[k] = w[k];
  }
  row.n = n;
  row.g = gap - n.dot(d_rest);
  return row;
}

namespace {

// Behavioural constants of the response.
constexpr double kIterativeToleranceGapFraction = 1e-3;  // NNCG: residual accepted, as a fraction of the gap
constexpr double kRecheckGapFraction = 0.5;   // re-check the corrected motion at this fraction of the gap
constexpr double kFallbackTimeFraction = 0.9; // the fallback stops the motion at this fraction of the first contact
constexpr double kEqualityTolerance = 1e-9;   // paper response: metres

// One frame's response rounds: the active constraints and the last solve.
struct ResponseRounds {
  std::map<FeatureKey, collision::Contact> active;  // contacts held as constraints
  std::set<FeatureKey> pushing;                     // those whose multiplier was positive in the last solve
  std::vector<physics::ContactRow> rows;            // the last solve's rows (active order)
  physics::ContactResult solved;                    // the last solve
  int iterations = 0;
  int lcp_iterations = 0;                           // pivots / rounds / sweeps over the solves
  std::map<FeatureKey, double> carried;             // last frame's multipliers (NNCG's warm start)
  std::map<FeatureKey, double> in_solve;            // coupling "carried": each carried row's force in the solve
};

// The paper's response (Sec. 3.4): hold every colliding vertex, and the probe points, at their time-of-contact
// positions along the free motion.
void solve_paper(const Model& model, State& state, const Points& x_free, const Eigen::VectorXd& u_free,
                 ResponseRounds& rr) {
  const Points& x0 = state.x;
  double toi_min = 1.0;
  std::map<int, Eigen::Vector3d> held;
  for (const auto& [key, c] : rr.active) {
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

// Non-penetration with the gap, as an LCP on the walls' compliance: active-set method on columns of the coupling
// matrix computed on demand, warm-started from the rows that pushed last time.
void solve_constraint(const Model& model, State& state, const Points& x1, const Eigen::VectorXd& u_free,
                      ResponseRounds& rr) {
  std::vector<int> warm;
  for (const auto& [key, c] : rr.active) {
    if (rr.pushing.count(key)) warm.push_back(static_cast<int>(rr.rows.size()));
    rr.rows.push_back(contact_row(c, model.mesh.rest, state.x, x1, model.collision.gap));
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
    rr.solved = physics::solve_contacts_iterative(*state.compliance, rr.rows, u_free, o, false,
                                                  model.integrator->held_points());
  } else {
    rr.solved = physics::solve_contacts(*state.compliance, rr.rows, u_free, warm, {}, false,
                                        model.integrator->held_points());
  }
  rr.lcp_iterations += rr.solved.iterations;
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

// Fallback: stop the motion x0 -> x1 at a safe fraction of its earliest true contact (intersection-free by
// construction); u follows. Returns whether a contact was found.
bool stop_before_contact(const Model& model, State& state, Points& x1, Eigen::VectorXd& u) {
  std::vector<collision::Contact> hits;
  collision::detect_self(*model.collision_surface, *state.detector, state.x, x1, 0.0, hits, nullptr);
  double toi_min = 1.0;
  for (const auto& c : hits) toi_min = std::min(toi_min, c.toi);
  const double tau = hits.empty() ? 1.0 : kFallbackTimeFraction * toi_min;
  x1 = state.x + tau * (x1 - state.x);
  const Points du = x1 - model.mesh.rest;
  u = Eigen::Map<const Eigen::VectorXd>(du.data(), du.size());
  return !hits.empty();
}

// Keep the correction and the contacts that carry force for the next frame; flag their nodes for rendering.
void keep_for_next_frame(const Model& model, State& state, const ResponseRounds& rr, const Eigen::VectorXd& u,
                         const Eigen::VectorXd& u_free) {
  state.last_correction = u - u_free;
  state.active.clear();
  state.active_lambda.clear();
  state.active_total.clear();
  int r = 0;
  for (const auto& [key, c] : rr.active) {
    const double lambda = r < rr.solved.lambda.size() ? rr.solved.lambda[r] : 0.0;
    const auto solve = rr.in_solve.find(key);
    const double total = lambda + (solve == rr.in_solve.end() ? 0.0 : solve->second);
    if (model.collision.response == ResponseKind::kPaper || total > 0.0) {
      state.active.push_back(c);
      state.active_lambda.push_back(lambda);
      state.active_total.push_back(total);
    }
    ++r;
  }
  for (const auto& c : rr.active)
    for (int k = 0; k < 4; ++k) state.in_contact[c.second.v[k]] = 1;
}

}  // namespace

void collide_and_respond(const Model& model, State& state, Eigen::VectorXd& u, FrameRecord& rec) {
  const int n = model.mesh.n_nodes();
  const CollisionSpec& cs = model.collision;
  const bool paper = cs.response == ResponseKind::kPaper;
  const Points& x0 = state.x;
  const Eigen::VectorXd u_free = u;
  auto positions = [&](const Eigen::VectorXd& uu) { return Points(model.mesh.rest + Eigen::Map<const Points>(uu.data(), n, 3)); };
  const Points x_free = positions(u);
  // Predicted motion: the free solution plus last frame's contact correction (contacts persist from frame to
  // frame), so where the walls already touch the sweep stays short instead of passing deep through each other.
  const bool predict = state.last_correction.size() == u.size() && !state.last_correction.isZero(0.0);
  Points x1 = predict ? positions(u_free + state.last_correction) : x_free;

  // First detection on the predicted motion.
  auto clock = Clock::now();
  collision::CollisionStats stats;
  collision::detect_self(*model.collision_surface, *state.detector, x0, x1, cs.gap, state.contacts, &stats);
  rec.bv_overlaps = stats.bv_overlaps;
  rec.feature_tests = stats.feature_tests;
  rec.contacts = stats.contacts;
  rec.ms[kCollision] += ms_since(clock);

  // Active constraints: last frame's held contacts (warm start, constraint response) plus every new one. The
  // contacts that pushed last time are the active-set solver's first guess.
  clock = Clock::now();
  ResponseRounds rr;
  if (!paper)
    for (size_t i = 0; i < state.active.size(); ++i) {
      const FeatureKey key = key_of(state.active[i]);
      rr.active.emplace(key, state.active[i]);
      rr.pushing.insert(key);
      if (i < state.active_lambda.size()) rr.carried[key] = state.active_lambda[i];
      if (static_cast<Eigen::Index>(i) < state.carried_lambda.size()) rr.in_solve[key] = state.carried_lambda[i];
    }
  std::vector<collision::Contact> found = state.contacts;
  bool resolved = found.empty() && rr.active.empty();
  while (!resolved && rr.iterations < cs.max_iterations) {
    ++rr.iterations;
    // Add the contacts found on the current trial motion, solve for the correction.
    for (const auto& c : found) rr.active[key_of(c)] = c;
    rr.rows.clear();
    if (paper)
      solve_paper(model, state, x_free, u_free, rr);
    else
      solve_constraint(model, state, x1, u_free, rr);
    // The correction is exact on the colliding walls (all the check reads); the rest of the mesh follows at the end.
    u = u_free + rr.solved.correction;
    x1 = positions(u);
    rec.ms[kResponse] += ms_since(clock);

    // Re-check the corrected motion with one CCD pass at a fraction of the gap (the rows ask for the full gap, so
    // a held contact is done when this is clear); what it finds joins the active set for the next round.
    clock = Clock::now();
    collision::detect_self(*model.collision_surface, *state.detector, x0, x1, kRecheckGapFraction * cs.gap, found,
                           nullptr);
    resolved = found.empty();
    rec.ms[kCollision] += ms_since(clock);
    clock = Clock::now();
  }
  rec.response_iterations = rr.iterations;
  if (rr.iterations > 0) {
    // Total normal force the walls carry (the constraint response's multipliers are contact forces).
    if (!paper) rec.contact_force = rr.solved.lambda.sum();
    for (const auto& [key, lambda] : rr.in_solve) rec.contact_force += lambda;
    rec.contact_residual = rr.solved.residual;
    rec.lcp_iterations = rr.lcp_iterations;
    add_contact_to_probe_forces(model, state, rr);
    // Whole-mesh correction for the last multipliers (a sum of precomputed columns or one back-substitution); the
    // colliding walls keep the values the check saw (equal to round-off).
    clock = Clock::now();
    Eigen::VectorXd du;
    state.compliance->displacement(rr.solved.force, du);
    for (int v : state.compliance->nodes()) du.segment<3>(3 * v) = rr.solved.correction.segment<3>(3 * v);
    u = u_free + du;
    x1 = positions(u);
    rec.ms[kResponse] += ms_since(clock);
  }

  // Unresolved after the last round: the safe fallback.
  if (!resolved) {
    clock = Clock::now();
    rec.fallback = stop_before_contact(model, state, x1, u);
    rec.ms[kCollision] += ms_since(clock);
  }
  keep_for_next_frame(model, state, rr, u, u_free);
  rec.contacts = static_cast<long>(std::max<size_t>(rr.active.size(), static_cast<size_t>(stats.contacts)));
}

}  // namespace lumen::engine
