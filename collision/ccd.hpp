#pragma once
// Elementary continuous collision tests (Provot): vertex-face and edge-edge, conservative.
//
// Method: the contact function F(t, u, v) (vf: p(t) - face(t, u, v); ee: point on ab - point on cd) is
// multilinear in (t, u, v), so its range over a parameter box is the hull of its values at the box's
// corners (vf: the corners of the box clipped to the triangle u, v >= 0, u + v <= 1). Every computed
// value carries a rigorous floating-point error bound derived from the input magnitudes, so nothing is
// ever excluded by rounding. Filters: the swept bounding box, the coplanarity cubic in Bernstein form
// (|signed plane / line distance| > gap over [0, 1]), a preconditioned range. Fast path: the earliest
// transversal crossing is certified (Poincare-Miranda on a small box around a root of the cubic), or,
// with gap > 0, a point within the gap is found; then only the times before it are searched. The search
// bisects boxes of [0, t] x domain earliest-t first, dropping a box when its range (or a rotated or
// preconditioned range, or the cubic) proves |F| > gap, narrowing boxes in t, and accepting a box whose
// range is narrower than `tolerance` in every coordinate. The reported toi is the lower t of the first
// accepted box (or of the certified one), so it is never later than the true time of contact; when the
// work bound is reached the earliest open box is reported as a contact (conservative).
#include <Eigen/Core>

namespace lumen::collision {

using Vec3 = Eigen::Vector3d;

// Result of one elementary test.
struct CcdHit {
  double toi = 1.0;  // earliest time of contact in [0, 1] (conservative: never later than the true one)
  // Contact parameters at toi: vf -> barycentric (u, v) of the face point a + u (b - a) + v (c - a);
  // ee -> (s, t) along edge ab and edge cd.
  double s = 0.0, t = 0.0;
  int boxes = 0;          // work units spent (box evaluations, certification and witness attempts)
  bool bounded = false;   // true when the work bound was reached and the contact is reported conservatively
};

// Accuracy and work bound of the elementary tests.
struct CcdOptions {
  // Width (metres) under which a box whose range contains the origin is accepted as a contact. Unless
  // the work bound is reached, a reported contact has the primitives within gap + 2 tolerance of each
  // other at toi (near misses closer than that may be reported: false positives, never negatives).
  double tolerance = 1e-6;
  // Work units (box evaluations, certification and witness attempts) per query before a conservative
  // contact is reported: bounds the worst-case time (about 60 us at the default on the dev machine).
  int max_boxes = 300;
};

// Throws std::invalid_argument naming the field when tolerance <= 0 (or not finite) or max_boxes < 1.
void validate_ccd_options(const CcdOptions& options);

// Vertex p against triangle (a, b, c), each moving linearly from *0 (t = 0) to *1 (t = 1).
// Returns true when they come within `gap` metres (gap >= 0) at some time in [0, 1]; never misses a
// true contact (zero false negatives), bounded work per query. `hit` may be null. Coordinates whose
// differences overflow (beyond ~1e100 m) give a conservative contact at t = 0.
// Throws std::invalid_argument for a non-finite coordinate or a negative / non-finite gap.
bool vertex_face_ccd(const Vec3& p0, const Vec3& a0, const Vec3& b0, const Vec3& c0,
                     const Vec3& p1, const Vec3& a1, const Vec3& b1, const Vec3& c1,
                     double gap, CcdHit* hit);

// Edge (a, b) against edge (c, d), same conventions.
bool edge_edge_ccd(const Vec3& a0, const Vec3& b0, const Vec3& c0, const Vec3& d0,
                   const Vec3& a1, const Vec3& b1, const Vec3& c1, const Vec3& d1,
                   double gap, CcdHit* hit);

// The same with explicit options (the overloads above use CcdOptions{}).
bool vertex_face_ccd(const Vec3& p0, const Vec3& a0, const Vec3& b0, const Vec3& c0,
                     const Vec3& p1, const Vec3& a1, const Vec3& b1, const Vec3& c1,
                     double gap, const CcdOptions& options, CcdHit* hit);
bool edge_edge_ccd(const Vec3& a0, const Vec3& b0, const Vec3& c0, const Vec3& d0,
                   const Vec3& a1, const Vec3& b1, const Vec3& c1, const Vec3& d1,
                   double gap, const CcdOptions& options, CcdHit* hit);

}  // namespace lumen::collision
