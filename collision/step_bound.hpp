#pragma once
// Conservative per-vertex step bound, in the manner of Offset Geometric Contact (Chen et al. 2025; the per-vertex
// trust region of IPC Toolkit's ipc::ogc): a motion that moves every vertex by at most its bound keeps every
// non-adjacent vertex-face and edge-edge pair of an intersection-free surface apart, so a frame that cannot
// finish its contact solve can keep most of its motion instead of stopping every vertex at the first contact.
//
// Rule. For a pair (vertex p, triangle t not incident to p) or (edge e, edge f sharing no vertex with e) at
// distance d (exact closest points, collision/distance.hpp) every vertex of the pair is limited by d:
//   b_v = gamma / 2 * min(r, min over the pairs that contain v of d),
// with r the query radius (pairs farther than r apart limit nothing beyond r) and gamma in (0, 1). For a vertex
// v this covers the triangles not incident to v, the edges not adjacent to v's edges and the vertices not on v's
// triangles (a triangle vertex is limited by the points near its triangle, else the triangle could move onto a
// point that stays still).
//
// Guarantee. If every vertex moves linearly from x0 by at most b_v, every point of a primitive moves by at most
// gamma / 2 * min(r, d) (a convex combination of its vertices' motions), so each such pair stays at least
// (1 - gamma) * min(r, d0) apart over the whole motion: no contact closer than that, no intersection. Pairs that
// touch at x0 (d0 = 0) freeze their vertices.
#include <Eigen/Core>

#include "collision/surface.hpp"

namespace lumen::collision {

// gamma: the part of the distance that the two sides of a pair may close together (each side half of it).
constexpr double kStepFraction = 0.9;

// Options of the step bound.
struct StepBoundOptions {
  double radius = 0.0;               // query radius r, metres (> 0): e.g. a little over the largest |dx|
  double fraction = kStepFraction;   // gamma, in (0, 1)
};

// A displacement truncated to the bounds.
struct TruncatedStep {
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> dx;  // n_points x 3, metres, |dx_v| <= b_v
  double kept = 1.0;  // sum_v |truncated dx_v| / sum_v |dx_v| (1 when dx = 0)
  int truncated = 0;  // vertices whose motion was shortened
};

// Bound b_v (n_points, metres) of every point at positions x0 (n_points x 3, intersection-free), by a uniform
// spatial hash of cell size max(r, mean edge length): each vertex queries the cells its r-box overlaps for
// triangles, each edge its r-inflated box for edges; sub-quadratic for a surface of bounded density. Points
// that no triangle references get +infinity (they are not on the surface). Throws std::invalid_argument for x0
// of the wrong shape or not finite, radius <= 0 or not finite, fraction outside (0, 1), or a radius so small
// that the grid over x0 would exceed 2^20 cells along an axis.
Eigen::VectorXd vertex_step_bounds(const CollisionSurface& surface, const PointsRef& x0,
                                   const StepBoundOptions& options);
// The same over all vertex-triangle and edge-edge pairs (O(n^2), the twin in tests): bit-identical bounds.
Eigen::VectorXd vertex_step_bounds_brute_force(const CollisionSurface& surface, const PointsRef& x0,
                                               const StepBoundOptions& options);

// dx_v shortened to |dx_v| = b_v where longer, direction kept (bounds: n_points; dx: n_points x 3, finite).
TruncatedStep truncate_step(const Eigen::VectorXd& bounds, const PointsRef& dx);

// vertex_step_bounds then truncate_step.
TruncatedStep bound_step(const CollisionSurface& surface, const PointsRef& x0, const PointsRef& dx,
                         const StepBoundOptions& options);

}  // namespace lumen::collision
