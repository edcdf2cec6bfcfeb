#pragma once
// Exact discrete intersection check: orientation predicates and triangle-triangle tests built on them.
// Independent of the CCD code. Points are 3 doubles (metres); all inputs must be finite.
#include <array>
#include <vector>

#include "collision/self_collision.hpp"

namespace lumen::collision {

// Sign of det[a - d; b - d; c - d] (Shewchuk's convention: +1 when d lies below the plane of a, b, c seen
// counter-clockwise from above, 0 when coplanar). Exact for all finite doubles: a floating-point filter,
// then exact big-integer arithmetic on the coordinates scaled to integers. Throws on non-finite input
// reaching the exact stage.
int orient3d(const double* a, const double* b, const double* c, const double* d);
// Sign of the 2D orientation of a, b, c projected by dropping coordinate `drop` (0, 1, 2) and keeping
// ((drop + 1) % 3, (drop + 2) % 3): the `drop` component of (a - c) x (b - c). Exact, as orient3d.
int orient2d(const double* a, const double* b, const double* c, int drop);
// The exact stages alone (no filter); the same signs, slower. For tests and benchmarks.
int orient3d_exact(const double* a, const double* b, const double* c, const double* d);
int orient2d_exact(const double* a, const double* b, const double* c, int drop);

// Closed segment pq against closed triangle abc (degenerate triangles count as their edges).
bool segment_triangle_intersect(const double* p, const double* q, const double* a, const double* b,
                                const double* c);
// Closed segments pq and ab in 3D.
bool segments_intersect(const double* p, const double* q, const double* a, const double* b);
// Closed triangles (a0 a1 a2) and (b0 b1 b2): true when they share at least one point.
bool triangles_intersect(const double* a0, const double* a1, const double* a2, const double* b0, const double* b1,
                         const double* b2);

// Two mesh triangles (vertex ids into x) intersect, taking shared vertices into account:
// - no shared vertex: closed intersection (touching counts);
// - one shared vertex v: intersection beyond v, i.e. the edge opposite v in either triangle meets the
//   other triangle (this also catches collinear overlapping edges at v);
// - one shared edge: intersection beyond the edge, i.e. coplanar with both opposite vertices strictly on
//   the same side of the edge (non-coplanar edge neighbours meet only on the edge);
// - same three vertices: true (the triangles coincide).
bool mesh_triangles_intersect(const PointsRef& x, const int* ta, const int* tb);

// Every pair of triangles of the mesh that intersect by mesh_triangles_intersect at positions x, as (i, j) with
// i < j, sorted; count_intersecting_pairs is its size.
std::vector<std::array<int, 2>> intersecting_pairs(const PointsRef& x, const TrisRef& tris);

}  // namespace lumen::collision
