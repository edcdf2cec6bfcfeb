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

void collide_and_respond(const Model& model, State& state, Eigen::VectorXd& u, FrameRecord& rec) {
  const int n = model.mesh.n_nodes();
  const CollisionSpec& cs = model.scene.collision;
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
  state.detector->detect(x0, x1, cs.gap, state.contacts, &stats);
  rec.bv_overlaps = stats.bv_overlaps;
  rec.feature_tests = stats.feature_tests;
  rec.contacts = stats.contacts;
  rec.ms[kCollision] += ms_since(clock);

  // Active constraints: last frame's held contacts (warm start, constraint response) plus every new one. The
  // contacts that pushed last time are the active-set solver's first guess.
  clock = Clock::now();
  std::map<FeatureKey, collision::Contact> active;
  std::set<FeatureKey> pushing;
  if (cs.response == "constraint")
    for (const auto& c : state.active) {
      active.emplace(key_of(c), c);
      pushing.insert(key_of(c));
    }
  std::vector<collision::Contact> found = state.contacts;
  bool resolved = found.empty() && active.empty();
  int iterations = 0;
  std::vector<physics::ContactRow> rows;
  std::vector<int> warm;
  physics::ContactResult solved;
  while (!resolved && iterations < cs.max_iterations) {
    ++iterations;
    // Add the contacts found on the current trial motion.
    for (const auto& c : found) active[key_of(c)] = c;
    rows.clear();
    if (cs.response == "paper") {
      // The paper (Sec. 3.4): hold every colliding vertex, and the probe points, at their time-of-contact positions.
      double toi_min = 1.0;
      std::map<int, Eigen::Vector3d> held;
      for (const auto& [key, c] : active) {
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
          rows.push_back(r);
        }
      solved = physics::solve_equality(*state.compliance, rows, u_free, 1e-9, false);
    } else {
      // Non-penetration with the gap, as an LCP on the inner wall's compliance: active-set method on columns of
      // the coupling matrix computed on demand, warm-started from the rows that pushed last time.
      warm.clear();
      for (const auto& [key, c] : active) {
        if (pushing.count(key)) warm.push_back(static_cast<int>(rows.size()));
        rows.push_back(contact_row(c, model.mesh.rest, x0, x1, cs.gap));
      }
      solved = physics::solve_contacts(*state.compliance, rows, u_free, warm, {}, false,
                                       model.held.points.empty() ? nullptr : &model.held);
      pushing.clear();
      int r = 0;
      for (const auto& entry : active)
        if (solved.lambda[r++] > 0.0) pushing.insert(entry.first);
    }
    // The correction is exact on the inner wall (all the check reads); the rest of the mesh follows at the end.
    u = u_free + solved.correction;
    x1 = positions(u);
    rec.ms[kResponse] += ms_since(clock);

    // Re-check the corrected motion with one CCD pass at half the gap (the rows ask for the full gap, so a held
    // contact is done when this is clear); what it finds joins the active set for the next round.
    clock = Clock::now();
    state.detector->detect(x0, x1, 0.5 * cs.gap, found, nullptr);
    resolved = found.empty();
    rec.ms[kCollision] += ms_since(clock);
    clock = Clock::now();
  }
  rec.response_iterations = iterations;
  // Total normal force the walls carry (the constraint response's multipliers are contact forces).
  if (iterations > 0 && cs.response == "constraint") rec.contact_force = solved.lambda.sum();

  // The probes' forces with the contacts' effect (what a device displays): displacement-driven probes change
  // their force so that contacts do not move them; in the paper's response every probe is held, and the holding
  // forces at its nodes add to its force.
  if (iterations > 0 && cs.response == "constraint" && solved.held_force.size() > 0) {
    for (size_t a = 0; a < model.held_probes.size(); ++a)
      state.samples[model.held_probes[a]].force += solved.held_force.segment<3>(3 * a);
  } else if (iterations > 0 && cs.response == "paper") {
    for (size_t p = 0; p < model.probe_points.size(); ++p)
      for (int k = 0; k < 3; ++k) {
        const int node = model.probe_points[p].node[k];
        for (size_t r = 0; r < rows.size(); ++r)
          if (rows[r].node[0] == node) state.samples[p].force += solved.lambda[static_cast<long>(r)] * rows[r].n;
      }
  }

  // Whole-mesh correction for the last multipliers (a sum of precomputed columns or one back-substitution); the
  // inner wall keeps the values the check saw (equal to round-off).
  if (iterations > 0) {
    clock = Clock::now();
    Eigen::VectorXd du;
    state.compliance->displacement(solved.force, du);
    for (int v : state.compliance->nodes()) du.segment<3>(3 * v) = solved.correction.segment<3>(3 * v);
    u = u_free + du;
    x1 = positions(u);
    rec.ms[kResponse] += ms_since(clock);
  }

  // Fallback: stop the motion at a safe fraction of the earliest true contact (intersection-free by construction).
  if (!resolved) {
    clock = Clock::now();
    std::vector<collision::Contact> hits;
    state.detector->detect(x0, x1, 0.0, hits, nullptr);
    double toi_min = 1.0;
    for (const auto& c : hits) toi_min = std::min(toi_min, c.toi);
    const double tau = hits.empty() ? 1.0 : 0.9 * toi_min;
    x1 = x0 + tau * (x1 - x0);
    const Points du = x1 - model.mesh.rest;
    u = Eigen::Map<const Eigen::VectorXd>(du.data(), 3 * n);
    rec.fallback = !hits.empty();
    rec.ms[kCollision] += ms_since(clock);
  }

  // Keep the correction and the contacts that carry force for the next frame; flag their nodes for rendering.
  state.last_correction = u - u_free;
  state.active.clear();
  int r = 0;
  for (const auto& [key, c] : active) {
    const bool carries = cs.response == "paper" || (r < solved.lambda.size() && solved.lambda[r] > 0.0);
    if (carries) state.active.push_back(c);
    ++r;
  }
  for (const auto& c : active)
    for (int k = 0; k < 4; ++k) state.in_contact[c.second.v[k]] = 1;
  rec.contacts = static_cast<long>(std::max<size_t>(active.size(), static_cast<size_t>(stats.contacts)));
}

}  // namespace lumen::engine
