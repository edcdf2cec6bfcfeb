// Rays against a triangle surface: an AABB tree over the triangles, slab tests, Möller-Trumbore.
#include "collision/raycast.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Geometry>

namespace lumen::collision {

namespace {

// A ray hit this close to the plane of the triangle's edges (barycentric tolerance) still counts, so that a ray
// through a shared edge or vertex meets one of the triangles there.
constexpr double kBarycentricTolerance = 1e-12;

// Does the ray origin + t dir, 0 < t < t_max, cross the axis-aligned box (Kdop<6>: axes x, y, z)?
bool crosses_box(const Kdop<6>& box, const double* origin, const double* dir, double t_max) {
  double t0 = 0.0, t1 = t_max;
  for (int a = 0; a < 3; ++a) {
    if (dir[a] == 0.0) {
      if (origin[a] < box.lo[a] || origin[a] > box.hi[a]) return false;
      continue;
    }
    double ta = (box.lo[a] - origin[a]) / dir[a], tb = (box.hi[a] - origin[a]) / dir[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  return true;
}

}  // namespace

RayCaster::RayCaster(const PointsRef& points, const TrisRef& tris) : points_(points), tris_(tris) {
  const int n = static_cast<int>(tris_.rows());
  std::vector<double> centres(static_cast<size_t>(3 * n));
  for (int t = 0; t < n; ++t)
    for (int d = 0; d < 3; ++d)
      centres[static_cast<size_t>(3 * t + d)] =
          (points_(tris_(t, 0), d) + points_(tris_(t, 1), d) + points_(tris_(t, 2), d)) / 3.0;
  bvh_.build(centres.data(), n);
  for (int t = 0; t < n; ++t) {
    Kdop<6>& box = bvh_.leaf_box(t);
    box.clear();
    for (int j = 0; j < 3; ++j) box.add_point(points_.data() + 3 * tris_(t, j));
  }
  bvh_.refit();
}

void RayCaster::test_triangle(int t, const double* origin, const double* dir, int skip_vertex, RayHit& best) const {
  if (tris_(t, 0) == skip_vertex || tris_(t, 1) == skip_vertex || tris_(t, 2) == skip_vertex) return;
  const Eigen::Vector3d o(origin[0], origin[1], origin[2]), d(dir[0], dir[1], dir[2]);
  const Eigen::Vector3d a = points_.row(tris_(t, 0)), b = points_.row(tris_(t, 1)), c = points_.row(tris_(t, 2));
  const Eigen::Vector3d e1 = b - a, e2 = c - a, p = d.cross(e2);
  const double det = e1.dot(p);
  if (det == 0.0) return;  // the ray runs parallel to the triangle's plane
  const Eigen::Vector3d s = o - a;
  const double u = s.dot(p) / det;
  if (u < -kBarycentricTolerance || u > 1.0 + kBarycentricTolerance) return;
  const Eigen::Vector3d q = s.cross(e1);
  const double v = d.dot(q) / det;
  if (v < -kBarycentricTolerance || u + v > 1.0 + kBarycentricTolerance) return;
  const double dist = e2.dot(q) / det;
  if (dist > 0.0 && (!best.hit() || dist < best.t)) best = {t, dist};
}

RayHit RayCaster::first_hit(const double* origin, const double* dir, int skip_vertex) const {
  RayHit best;
  if (bvh_.num_prims() == 0) return best;
  const BvhTopology& topo = bvh_.topology();
  std::vector<int> stack = {0};
  while (!stack.empty()) {
    const int node = stack.back();
    stack.pop_back();
    const double t_max = best.hit() ? best.t : std::numeric_limits<double>::infinity();
    if (!crosses_box(bvh_.node_box(node), origin, dir, t_max)) continue;
    const BvhTopology::Node& nd = topo.node(node);
    if (nd.prim >= 0) {
      test_triangle(nd.prim, origin, dir, skip_vertex, best);
    } else {
      stack.push_back(nd.left);
      stack.push_back(nd.right);
    }
  }
  return best;
}

RayHit RayCaster::first_hit_brute_force(const double* origin, const double* dir, int skip_vertex) const {
  RayHit best;
  for (int t = 0; t < tris_.rows(); ++t) test_triangle(t, origin, dir, skip_vertex, best);
  return best;
}

}  // namespace lumen::collision
