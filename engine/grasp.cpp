#include "engine/grasp.hpp"

#include <algorithm>
#include <cassert>

#include "engine/input.hpp"
#include "engine/response.hpp"
#include "engine/simulation.hpp"

namespace lumen::engine {
namespace {

// The organ nodes of a grasper's force-carrying jaw contacts (last frame's held tool contacts), if each jaw
// presses with at least the grip force; none otherwise. Nodes on fixed DOFs or held by another instrument are
// left out.
std::vector<int> nodes_between_jaws(const Model& model, const State& state, size_t instrument) {
  const CompiledInstrument& ci = model.instruments[instrument];
  const physics::StaticSolver& solver = model.contact_solver();
  double pressing[2] = {0.0, 0.0};  // normal force of jaw_positive, jaw_negative, newtons
  std::vector<int> nodes;
  for (size_t c = 0; c < state.tool_active.size(); ++c) {
    const HeldContact& h = state.tool_active[c];
    const ToolPart& tp = model.tool_parts[static_cast<size_t>(h.part)];
    if (tp.instrument != static_cast<int>(instrument)) continue;
    const PartJoint joint = ci.instrument.parts[static_cast<size_t>(tp.part)].joint;
    if (joint == PartJoint::kFixed) continue;
    pressing[joint == PartJoint::kJawPositive ? 0 : 1] += state.tool_active_lambda[c];
    for (int k = 0; k < 4; ++k)
      if (!h.on_tool(k) && !solver.is_fixed_dof(3 * h.c.v[k])) nodes.push_back(h.c.v[k]);
  }
  if (!(pressing[0] >= ci.grasp.grip_force_n) || !(pressing[1] >= ci.grasp.grip_force_n)) return {};
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  // A node another grasper already holds stays with it.
  for (size_t j = 0; j < state.grasps.size(); ++j) {
    if (j == instrument) continue;
    const std::vector<int>& other = state.grasps[j].nodes;
    nodes.erase(std::remove_if(nodes.begin(), nodes.end(),
                               [&](int n) { return std::binary_search(other.begin(), other.end(), n); }),
                nodes.end());
  }
  return nodes;
}

// state.grasp_holds from every instrument's hold: S = (E^T K^-1 E)^-1 from the contact compliance's blocks of the
// held nodes (wall nodes: no solve), no whole-mesh columns (the hold moves the mesh by one displacement a frame).
void rebuild_holds(State& state) {
  GraspHolds& g = state.grasp_holds;
  g = GraspHolds{};
  std::vector<physics::LoadPoint> points;
  for (size_t i = 0; i < state.grasps.size(); ++i)
    for (int node : state.grasps[i].nodes) {
      physics::LoadPoint p;
      p.node[0] = node;
      p.weight[0] = 1.0;
      points.push_back(p);
      g.instrument.push_back(static_cast<int>(i));
    }
  state.grasp_force = Eigen::VectorXd::Zero(3 * static_cast<Eigen::Index>(points.size()));
  if (points.empty()) return;
  assert(state.compliance && "grasping needs instruments, which build the contact compliance");
  g.held = physics::held_points_on(*state.compliance, std::move(points));
}

}  // namespace

double commanded_opening(const std::vector<OpeningKey>& keys, double rest, double t) {
  if (keys.empty()) return rest;
  size_t i;
  double w;
  bracket_keys(keys, t, i, w);
  return w == 0.0 ? keys[i].angle : (1.0 - w) * keys[i].angle + w * keys[i + 1].angle;
}

void update_grasps(const Model& model, State& state, double t1) {
  bool changed = false;
  for (size_t i = 0; i < model.instruments.size(); ++i) {
    const CompiledInstrument& ci = model.instruments[i];
    const double command = commanded_opening(ci.openings, ci.instrument.rest_opening, t1);
    GraspHold& hold = state.grasps[i];
    double& target = state.tool_opening_target[i];
    // Holding: keep the opening until the command opens past it by the margin, then let go and follow it.
    if (hold.holding()) {
      if (command > hold.opening + ci.grasp.release_margin) {
        hold = GraspHold{};
        target = command;
        changed = true;
      } else {
        target = hold.opening;
      }
      continue;
    }
    target = command;
    // Free: grasp when closing with tissue on both jaws.
    if (!ci.grasp.enabled || !(command < state.tool_opening[i])) continue;
    std::vector<int> nodes = nodes_between_jaws(model, state, i);
    if (nodes.empty()) continue;
    const Eigen::Isometry3d to_instrument = state.tool_pose[i].transform().inverse();
    hold.local.resize(static_cast<Eigen::Index>(nodes.size()), 3);
    for (size_t a = 0; a < nodes.size(); ++a)
      hold.local.row(static_cast<Eigen::Index>(a)) = (to_instrument * state.x.row(nodes[a]).transpose()).transpose();
    hold.nodes = std::move(nodes);
    hold.opening = state.tool_opening[i];
    target = hold.opening;
    changed = true;
  }
  if (changed) rebuild_holds(state);
}

void hold_grasped_nodes(const Model& model, State& state, Eigen::VectorXd& u) {
  const GraspHolds& g = state.grasp_holds;
  if (g.empty()) return;
  // Each held node's shortfall from its target, in the holds' point order (instrument, then node order).
  Eigen::VectorXd shortfall(3 * static_cast<Eigen::Index>(g.held.points.size()));
  Eigen::Index a = 0;
  for (size_t i = 0; i < state.grasps.size(); ++i) {
    const GraspHold& hold = state.grasps[i];
    const Eigen::Isometry3d to_organ = state.tool_pose_target[i].transform();
    for (size_t j = 0; j < hold.nodes.size(); ++j, ++a) {
      const int node = hold.nodes[j];
      assert(g.held.points[static_cast<size_t>(a)].node[0] == node);
      const Eigen::Vector3d target = to_organ * hold.local.row(static_cast<Eigen::Index>(j)).transpose();
      shortfall.segment<3>(3 * a) = target - model.mesh.rest.row(node).transpose() - u.segment<3>(3 * node);
    }
  }
  // The holding forces, and the whole mesh moved by them (one displacement: a back-substitution or kept columns).
  state.grasp_force = g.held.S * shortfall;
  Eigen::VectorXd du;
  physics::held_displacement(*state.compliance, g.held, state.grasp_force, du);
  u += du;
}

bool held_by_own_instrument(const Model& model, const State& state, const HeldContact& h) {
  if (!h.is_tool() || state.grasps.empty()) return false;
  const std::vector<int>& held = state.grasps[static_cast<size_t>(model.tool_parts[static_cast<size_t>(h.part)].instrument)].nodes;
  if (held.empty()) return false;
  for (int k = 0; k < 4; ++k)
    if (!h.on_tool(k) && !std::binary_search(held.begin(), held.end(), h.c.v[k])) return false;
  return true;
}

}  // namespace lumen::engine
