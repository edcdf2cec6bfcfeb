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

// Identity of a feature pair (kind and its vertex ids) for keeping a set of active constraints.
struct FeatureKey {
  int kind = 0;
  int v[4] = {-1, -1, -1, -1};
  bool operator<(const FeatureKey& o) const;
  bool operator==(const FeatureKey& o) const;
};
FeatureKey key_of(const collision::Contact& c);

// The constraint row of a contact: the separation along the contact normal between the vertex and the face
// point (vf) or between the two edge points (ee), with fixed barycentric weights, must reach `gap`.
// x0 / x1: positions at the start / trial end of the frame, n x 3; rest: rest positions.
physics::ContactRow contact_row(const collision::Contact& c, const Points& rest, const Points& x0, const Points& x1,
                                double gap);

// Resolve the inner wall's self-contacts for the motion state.x -> rest + u (u is updated in place).
// Rounds (at most scene.collision.max_iterations): the contacts found so far become rows (constraint: an LCP
// by physics::solve_contacts, warm-started from last frame's pushing contacts in state.active; paper: hold
// their nodes and the probe points by physics::solve_equality); the corrected motion of the inner wall is
// re-checked by one CCD pass at half the gap, whose contacts join the next round. Unresolved: the safe
// fallback (stop at 0.9 of the earliest true contact). Fills rec's collision statistics, response iterations
// and fallback flag; CCD time goes to rec.ms[kCollision], the rest to rec.ms[kResponse].
void collide_and_respond(const Model& model, State& state, Eigen::VectorXd& u, FrameRecord& rec);

}  // namespace lumen::engine
