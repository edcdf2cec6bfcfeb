#pragma once
// Collision response: contacts of the inner wall become constraints on the FEM solve; CCD re-checks the
// corrected motion until none remains, and a safe fallback ends the frame when the bound is hit.
#include <vector>

#include <Eigen/Dense>

#include "collision/self_collision.hpp"
#include "physics/compliance.hpp"
#include "physics/types.hpp"

namespace lumen::engine {

struct Model;
struct State;
struct FrameRecord;

// A contact the response holds: between the organ's walls (part = -1), or between an instrument part and the
// organ (part >= 0, an index into Model::tool_parts): bit k of `tool` set when c.v[k] is a vertex of that part
// (an id into its points, kinematic), clear when it is an organ node.
struct HeldContact {
  collision::Contact c;
  int part = -1;
  unsigned tool = 0;
  bool is_tool() const { return part >= 0; }
  bool on_tool(int k) const { return (tool >> k) & 1u; }
};

// Identity of a feature pair (kind, its vertex ids, and for a tool contact the part and which ids are the
// part's) for keeping a set of active constraints.
struct FeatureKey {
  int kind = 0;
  int v[4] = {-1, -1, -1, -1};
  int part = -1;
  unsigned tool = 0;
  bool operator<(const FeatureKey& o) const;
  bool operator==(const FeatureKey& o) const;
};
FeatureKey key_of(const collision::Contact& c);
FeatureKey key_of(const HeldContact& c);

// The constraint row of a contact: the separation along the contact normal between the vertex and the face
// point (vf) or between the two edge points (ee), with fixed barycentric weights, must reach `gap`.
// x0 / x1: positions at the start / trial end of the frame, n x 3; rest: rest positions.
physics::ContactRow contact_row(const collision::Contact& c, const Points& rest, const Points& x0, const Points& x1,
                                double gap);

// The positions a contact's row is built from, per vertex: at the start and at the trial end of the frame, and the
// part of its end position the displacement u does not hold (an organ node's rest position; all of a kinematic
// instrument vertex's end position, whose motion is prescribed). node[k] = -1 for a kinematic vertex.
struct RowVertices {
  int node[4] = {-1, -1, -1, -1};
  Eigen::Vector3d x0[4], x1[4], fixed[4];
};
// The one row formula: n . sum_k w_k x_k >= gap at the end of the frame, i.e. H u >= gap - n . sum_k w_k fixed_k,
// with the weights and the normal of the contact (c.kind, s, t, toi); only the organ nodes enter H.
physics::ContactRow row_of(const collision::Contact& c, const RowVertices& rv, double gap);
// Barycentric-style weights of a contact's four vertices: sum_k w_k x_k is the separation vector.
void weights_of(const collision::Contact& c, double w[4]);

// Resolve the inner wall's self-contacts and the instruments' contacts with the organ for the motion
// state.x -> rest + u (u is updated in place) while each instrument part sweeps from state.tool_points to
// state.tool_target (kinematic: its motion enters the rows' right-hand side).
// Rounds (at most scene.collision.max_iterations): the contacts found so far become rows (constraint: an LCP
// by physics::solve_contacts, warm-started from last frame's pushing contacts in state.active; paper: hold
// their nodes and the probe points by physics::solve_equality); the corrected motion of the inner wall is
// re-checked by one CCD pass at half the gap, whose contacts join the next round. Unresolved: the safe
// fallback (stop the organ and the instruments at 0.9 of the earliest true contact: the instruments end the frame
// there, short of their target poses). Fills rec's collision statistics, response iterations
// and fallback flag; CCD time goes to rec.ms[kCollision], the rest to rec.ms[kResponse].
void collide_and_respond(const Model& model, State& state, Eigen::VectorXd& u, FrameRecord& rec);
// A pipelined last frame still in flight (State::pipeline_interior): settle() it; the wait is this frame's
// (rec.interior_wait_ms, and in the response stage).
void wait_for_last_frame(const Model& model, State& state, FrameRecord& rec);

// The walls' first proximity reference, taken on the state's positions at rest (a full detection of the resting
// walls at the near gap; State::proximity), so that the first frame's detection is already restricted and the
// workspace's buffers are allocated before the frames are timed. Nothing when the walls do not collide or the
// scene asks for full first detections.
void prime_proximity(const Model& model, State& state);

}  // namespace lumen::engine
