#pragma once
// Grasping: a grasper's jaws that close on tissue hold the organ nodes they touch, rigidly in the instrument's
// frame, until the jaws open again (scene key instruments[i].grasp).
//
// A hold is a set of prescribed displacements on the linear quasi-static model, as a displacement-driven probe
// is: when the jaws close, S = (E^T K^-1 E)^-1 (3d x 3d) is taken from the contact compliance's 3 x 3 blocks of
// the held (wall) nodes, with no solve; each frame the free solution is moved by K^-1 E S (d - E^T u), one
// displacement of the holding forces, so that the held nodes sit at their targets d, and the contact solve keeps
// them there (physics::HeldPoints without columns: its G = H K^-1 E comes from the same blocks). The force the
// hold puts on the organ, minus, is the grasp's part of the force on the instrument.
#include <vector>

#include <Eigen/Core>

#include "engine/pose_track.hpp"
#include "physics/contact_solve.hpp"
#include "physics/types.hpp"

namespace lumen::engine {

struct Model;
struct State;
struct HeldContact;
struct OpeningKey;

// One instrument's grasp.
struct GraspHold {
  std::vector<int> nodes;  // organ node ids held (sorted; empty: not holding)
  Points local;            // nodes x 3: their positions in the instrument frame when it closed, metres
  double opening = 0.0;    // the jaws' opening when they closed on the tissue, radians (kept while holding)
  bool holding() const { return !nodes.empty(); }
};

// Every instrument's held nodes as one hold of the contact solve: points in instrument order (weight 1 on one
// node each), S over all of them (no U: see physics::held_points_on).
struct GraspHolds {
  physics::HeldPoints held;
  std::vector<int> instrument;  // per point, the instrument holding it
  bool empty() const { return held.points.empty(); }
};

// The commanded jaw opening at time t (seconds): linear between the keys, held outside them; `rest` without keys.
double commanded_opening(const std::vector<OpeningKey>& keys, double rest, double t);

// At the start of a frame ending at t1, each grasper's opening for the frame's end (state.tool_opening_target):
// a holding grasper lets go when the command exceeds its held opening by the release margin, else keeps it; a
// free one that is closing with each jaw pressing the tissue with at least the grip force (last frame's held tool
// contacts) grasps the organ nodes of those contacts and stops at its current opening. Rebuilds state.grasp_holds when a
// hold begins or ends.
void update_grasps(const Model& model, State& state, double t1);

// Move the free displacement u (3n, metres) so that every held node sits at its target (the instrument's pose at
// the frame's end applied to its instrument-frame position); keeps the holding forces on the organ
// (state.grasp_force, 3d, newtons, point order of state.grasp_holds). No-op without holds.
void hold_grasped_nodes(const Model& model, State& state, Eigen::VectorXd& u);

// Whether a tool contact's organ-side nodes are all held by the contact's own instrument (their distance to its
// parts is frozen while it holds them: such a contact is not a constraint).
bool held_by_own_instrument(const Model& model, const State& state, const HeldContact& h);

}  // namespace lumen::engine
