#pragma once
// Rays against a fixed triangle surface: the first triangle a ray from a point meets, through an AABB tree.
#include <vector>

#include "collision/kdop.hpp"
#include "collision/surface.hpp"

namespace lumen::collision {

// The first triangle along a ray: its index and the distance to it (t along the unit direction), or none.
struct RayHit {
  int triangle = -1;  // -1: the ray meets no triangle
  double t = 0.0;     // metres along the (unit) direction
  bool hit() const { return triangle >= 0; }
};

// A triangle surface (points and triangles copied in) with an AABB tree over its triangles, for ray queries.
class RayCaster {
 public:
  RayCaster(const PointsRef& points, const TrisRef& tris);
  // The nearest triangle the ray origin + t dir (dir unit, t > 0) meets, ignoring the triangles that have vertex
  // `skip_vertex` (-1: none; a ray cast from a surface vertex leaves its own triangles at t = 0). Möller-Trumbore
  // on each triangle whose box the ray crosses (slab test); a ray grazing an edge meets either neighbour.
  RayHit first_hit(const double* origin, const double* dir, int skip_vertex = -1) const;
  // The same by testing every triangle (the twin the tree is tested against).
  RayHit first_hit_brute_force(const double* origin, const double* dir, int skip_vertex = -1) const;

 private:
  // The ray's hit on triangle t (closer than best, not touching skip_vertex) replaces best.
  void test_triangle(int t, const double* origin, const double* dir, int skip_vertex, RayHit& best) const;
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> points_;
  Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor> tris_;
  KdopBvh<6> bvh_;
};

}  // namespace lumen::collision
