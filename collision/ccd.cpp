// Elementary continuous collision tests: inclusion-based, earliest-t-first bisection of the parameter box.
#include "collision/ccd.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace lumen::collision {
namespace {

constexpr double kUnitRoundoff = 0x1p-53;
// Smallest parameter width a box is split to: keeps every box bound a dyadic number with few bits, so
// 1 - t, u0 + v0 and midpoints are exact in double.
constexpr double kMinWidth = 0x1p-40;

// The contact function F(t, u, v) = d(t) + u e(t) + v f(t), each term linear in t:
// x(t) = (1 - t) x0 + t x1. vf: d = p - a, e = a - b, f = a - c (so F = p - (a + u (b-a) + v (c-a)));
// ee: d = a - c, e = b - a, f = c - d (so F = (a + u (b-a)) - (c + v (d-c))).
struct Problem {
  double d0[3], d1[3], e0[3], e1[3], f0[3], f1[3];  // per axis, metres
  double eps[3];        // rigorous bound of the rounding error of each computed coordinate of F, metres
  bool simplex = false; // vf: (u, v) restricted to the triangle u, v >= 0, u + v <= 1
  double gap = 0.0;     // contact distance, metres
  double tolerance = 0.0;
};

// A parameter box [t0,t1] x [u0,u1] x [v0,v1] with the bounds of F over it.
struct Box {
  double t0, t1, u0, u1, v0, v1;
  double lo[3], hi[3];  // computed range of F (not yet inflated by eps)
  double ct, cu, cv;    // how much t, u, v each widen the range (max over the coordinates)
};

// Earliest lower t first; among equal t, the narrower box first (depth-first towards a contact).
struct Later {
  bool operator()(const Box& a, const Box& b) const {
    if (a.t0 != b.t0) return a.t0 > b.t0;
    return (a.t1 - a.t0) > (b.t1 - b.t0);
  }
};

// Fills the differences of the four points and the error bound eps. Returns false if a difference
// overflowed (then the caller reports a conservative contact).
//
// Error bound: with u the unit roundoff and D the largest |computed difference| on an axis, the
// difference itself is off by <= u |exact|; x(t) = (1-t) x0 + t x1 (t, 1-t exact dyadics) adds <= 2uD
// (total <= 3uD); u e(t) and v f(t) add <= uD each (total <= 4uD); the two sums add <= 2uD and <= 3uD.
// Hence |computed F - F| <= 16 u D (+ O(u^2) D); we use 32 u D plus an underflow allowance.
bool setup(const Vec3& d0, const Vec3& d1, const Vec3& e0, const Vec3& e1, const Vec3& f0,
           const Vec3& f1, Problem& pb) {
  for (int j = 0; j < 3; ++j) {
    pb.d0[j] = d0[j];
    pb.d1[j] = d1[j];
    pb.e0[j] = e0[j];
    pb.e1[j] = e1[j];
    pb.f0[j] = f0[j];
    pb.f1[j] = f1[j];
    const double m = std::max({std::abs(d0[j]), std::abs(d1[j]), std::abs(e0[j]), std::abs(e1[j]),
                               std::abs(f0[j]), std::abs(f1[j])});
    if (!std::isfinite(m)) return false;
    pb.eps[j] = 32.0 * kUnitRoundoff * m + 1e-300;
  }
  return true;
}

// Range of F over the box (vf: box clipped to the triangle), and the widening due to each parameter.
// Returns false when the clipped box is empty.
bool evaluate(const Problem& pb, Box& b) {
  // F's coefficient vectors at the two bounding times.
  double D[2][3], E[2][3], F[2][3];
  const double ts[2] = {b.t0, b.t1};
  for (int k = 0; k < 2; ++k) {
    const double t = ts[k], s = 1.0 - t;
    for (int j = 0; j < 3; ++j) {
      D[k][j] = s * pb.d0[j] + t * pb.d1[j];
      E[k][j] = s * pb.e0[j] + t * pb.e1[j];
      F[k][j] = s * pb.f0[j] + t * pb.f1[j];
    }
  }
  // Vertices of the (u, v) domain: the rectangle, clipped by u + v <= 1 for a triangle.
  double uv[5][2];
  int n = 0;
  if (!pb.simplex || b.u1 + b.v1 <= 1.0) {
    uv[0][0] = b.u0; uv[0][1] = b.v0;
    uv[1][0] = b.u1; uv[1][1] = b.v0;
    uv[2][0] = b.u1; uv[2][1] = b.v1;
    uv[3][0] = b.u0; uv[3][1] = b.v1;
    n = 4;
  } else {
    if (b.u0 + b.v0 > 1.0) return false;
    const double corner[4][2] = {{b.u0, b.v0}, {b.u1, b.v0}, {b.u1, b.v1}, {b.u0, b.v1}};
    for (int i = 0; i < 4; ++i) {
      const double* c = corner[i];
      const double* nx = corner[(i + 1) % 4];
      const bool in_c = c[0] + c[1] <= 1.0, in_n = nx[0] + nx[1] <= 1.0;
      if (in_c) { uv[n][0] = c[0]; uv[n][1] = c[1]; ++n; }
      if (in_c != in_n) {
        // Edges are axis-aligned: the crossing of u + v = 1 is exact (dyadic bounds).
        if (c[1] == nx[1]) { uv[n][0] = 1.0 - c[1]; uv[n][1] = c[1]; }
        else { uv[n][0] = c[0]; uv[n][1] = 1.0 - c[0]; }
        ++n;
      }
    }
  }
  // Values at the vertices x {t0, t1}: their hull bounds F over the box (F is multilinear).
  double lo[3], hi[3], ct = 0.0;
  for (int j = 0; j < 3; ++j) {
    lo[j] = std::numeric_limits<double>::infinity();
    hi[j] = -lo[j];
  }
  for (int i = 0; i < n; ++i) {
    const double u = uv[i][0], v = uv[i][1];
    for (int j = 0; j < 3; ++j) {
      const double x0 = D[0][j] + u * E[0][j] + v * F[0][j];
      const double x1 = D[1][j] + u * E[1][j] + v * F[1][j];
      lo[j] = std::min(lo[j], std::min(x0, x1));
      hi[j] = std::max(hi[j], std::max(x0, x1));
      ct = std::max(ct, std::abs(x1 - x0));
    }
  }
  double cu = 0.0, cv = 0.0;
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 3; ++j) {
      cu = std::max(cu, std::abs(E[k][j]));
      cv = std::max(cv, std::abs(F[k][j]));
    }
  for (int j = 0; j < 3; ++j) {
    b.lo[j] = lo[j];
    b.hi[j] = hi[j];
  }
  b.ct = ct;
  b.cu = cu * (b.u1 - b.u0);
  b.cv = cv * (b.v1 - b.v0);
  return true;
}

// True when the inflated range of F over the box is farther than gap from the origin (no contact).
bool excluded(const Problem& pb, const Box& b) {
  if (pb.gap == 0.0) {
    for (int j = 0; j < 3; ++j)
      if (b.lo[j] > pb.eps[j] || b.hi[j] < -pb.eps[j]) return true;
    return false;
  }
  // Euclidean distance from the origin to the range box, compared with a relative margin for rounding.
  double r2 = 0.0;
  for (int j = 0; j < 3; ++j) {
    const double s = std::max({0.0, b.lo[j] - pb.eps[j], -b.hi[j] - pb.eps[j]}) / pb.gap;
    r2 += s * s;
  }
  return r2 > 1.0 + 1e-12;
}

// True when the inflated range is narrower than the tolerance in every coordinate.
bool within_tolerance(const Problem& pb, const Box& b) {
  for (int j = 0; j < 3; ++j)
    if (b.hi[j] - b.lo[j] + 2.0 * pb.eps[j] > pb.tolerance) return false;
  return true;
}

// Contact parameters reported for an accepted box: its (u, v) centre, inside the triangle for vf.
void report(const Problem& pb, const Box& b, bool bounded, int boxes, CcdHit* hit) {
  if (hit == nullptr) return;
  double u = 0.5 * (b.u0 + b.u1), v = 0.5 * (b.v0 + b.v1);
  if (pb.simplex && u + v > 1.0) {
    const double sum = u + v;
    u /= sum;
    v /= sum;
  }
  hit->toi = b.t0;
  hit->s = u;
  hit->t = v;
  hit->boxes = boxes;
  hit->bounded = bounded;
}

// Earliest-t-first bisection of [0,1] x domain.
bool solve(const Problem& pb, int max_boxes, CcdHit* hit) {
  thread_local std::vector<Box> heap;
  heap.clear();
  Box root{0.0, 1.0, 0.0, 1.0, 0.0, 1.0, {}, {}, 0.0, 0.0, 0.0};
  evaluate(pb, root);
  int boxes = 1;
  if (excluded(pb, root)) {
    if (hit != nullptr) hit->boxes = boxes;
    return false;
  }
  heap.push_back(root);
  while (!heap.empty()) {
    std::pop_heap(heap.begin(), heap.end(), Later{});
    const Box b = heap.back();
    heap.pop_back();
    // Accept: the range is within tolerance, or the box cannot be split further.
    const bool t_min = b.t1 - b.t0 <= kMinWidth, u_min = b.u1 - b.u0 <= kMinWidth,
               v_min = b.v1 - b.v0 <= kMinWidth;
    if (within_tolerance(pb, b) || (t_min && u_min && v_min)) {
      report(pb, b, false, boxes, hit);
      return true;
    }
    if (boxes >= max_boxes) {
      report(pb, b, true, boxes, hit);
      return true;
    }
    // Split the parameter that widens the range most.
    const double ct = t_min ? -1.0 : b.ct, cu = u_min ? -1.0 : b.cu, cv = v_min ? -1.0 : b.cv;
    Box c[2] = {b, b};
    if (ct >= cu && ct >= cv) {
      const double m = 0.5 * (b.t0 + b.t1);
      c[0].t1 = m;
      c[1].t0 = m;
    } else if (cu >= cv) {
      const double m = 0.5 * (b.u0 + b.u1);
      c[0].u1 = m;
      c[1].u0 = m;
    } else {
      const double m = 0.5 * (b.v0 + b.v1);
      c[0].v1 = m;
      c[1].v0 = m;
    }
    for (Box& child : c) {
      if (!evaluate(pb, child)) continue;
      ++boxes;
      if (excluded(pb, child)) continue;
      heap.push_back(child);
      std::push_heap(heap.begin(), heap.end(), Later{});
    }
  }
  if (hit != nullptr) hit->boxes = boxes;
  return false;
}

void check_point(const Vec3& x, const char* name) {
  if (!x.allFinite()) {
    std::ostringstream msg;
    msg << "ccd: point " << name << " must be finite, got (" << x[0] << ", " << x[1] << ", " << x[2]
        << ")";
    throw std::invalid_argument(msg.str());
  }
}

void check_gap(double gap) {
  if (!(gap >= 0.0) || !std::isfinite(gap))
    throw std::invalid_argument("ccd: gap must be finite and >= 0, got " + std::to_string(gap));
}

// Overflowed differences: report a conservative contact at t = 0.
bool overflow_contact(CcdHit* hit) {
  if (hit != nullptr) *hit = CcdHit{0.0, 0.0, 0.0, 0, true};
  return true;
}

}  // namespace

void validate_ccd_options(const CcdOptions& options) {
  if (!(options.tolerance > 0.0) || !std::isfinite(options.tolerance)) {
    std::ostringstream msg;
    msg << "ccd: tolerance must be finite and > 0, got " << options.tolerance;
    throw std::invalid_argument(msg.str());
  }
  if (options.max_boxes < 1)
    throw std::invalid_argument("ccd: max_boxes must be >= 1, got " + std::to_string(options.max_boxes));
}

bool vertex_face_ccd(const Vec3& p0, const Vec3& a0, const Vec3& b0, const Vec3& c0,
                     const Vec3& p1, const Vec3& a1, const Vec3& b1, const Vec3& c1,
                     double gap, const CcdOptions& options, CcdHit* hit) {
  // Validate the inputs.
  check_point(p0, "p0"); check_point(a0, "a0"); check_point(b0, "b0"); check_point(c0, "c0");
  check_point(p1, "p1"); check_point(a1, "a1"); check_point(b1, "b1"); check_point(c1, "c1");
  check_gap(gap);
  validate_ccd_options(options);
  // F = (p - a) + u (a - b) + v (a - c) over t in [0,1], (u, v) in the triangle.
  Problem pb;
  pb.simplex = true;
  pb.gap = gap;
  pb.tolerance = options.tolerance;
  if (!setup(p0 - a0, p1 - a1, a0 - b0, a1 - b1, a0 - c0, a1 - c1, pb)) return overflow_contact(hit);
  return solve(pb, options.max_boxes, hit);
}

bool edge_edge_ccd(const Vec3& a0, const Vec3& b0, const Vec3& c0, const Vec3& d0,
                   const Vec3& a1, const Vec3& b1, const Vec3& c1, const Vec3& d1,
                   double gap, const CcdOptions& options, CcdHit* hit) {
  // Validate the inputs.
  check_point(a0, "a0"); check_point(b0, "b0"); check_point(c0, "c0"); check_point(d0, "d0");
  check_point(a1, "a1"); check_point(b1, "b1"); check_point(c1, "c1"); check_point(d1, "d1");
  check_gap(gap);
  validate_ccd_options(options);
  // F = (a - c) + u (b - a) + v (c - d) over t, u, v in [0,1].
  Problem pb;
  pb.simplex = false;
  pb.gap = gap;
  pb.tolerance = options.tolerance;
  if (!setup(a0 - c0, a1 - c1, b0 - a0, b1 - a1, c0 - d0, c1 - d1, pb)) return overflow_contact(hit);
  return solve(pb, options.max_boxes, hit);
}

bool vertex_face_ccd(const Vec3& p0, const Vec3& a0, const Vec3& b0, const Vec3& c0,
                     const Vec3& p1, const Vec3& a1, const Vec3& b1, const Vec3& c1,
                     double gap, CcdHit* hit) {
  return vertex_face_ccd(p0, a0, b0, c0, p1, a1, b1, c1, gap, CcdOptions{}, hit);
}

bool edge_edge_ccd(const Vec3& a0, const Vec3& b0, const Vec3& c0, const Vec3& d0,
                   const Vec3& a1, const Vec3& b1, const Vec3& c1, const Vec3& d1,
                   double gap, CcdHit* hit) {
  return edge_edge_ccd(a0, b0, c0, d0, a1, b1, c1, d1, gap, CcdOptions{}, hit);
}

}  // namespace lumen::collision
