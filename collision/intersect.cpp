// Exact discrete intersection check: filtered orientation predicates with an exact big-integer fallback,
// segment/triangle tests from them, and a pruned all-pairs count over a mesh.
#include "collision/intersect.hpp"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "collision/kdop.hpp"

namespace lumen::collision {

namespace {

// ---------------------------------------------------------------------------------------------------
// Exact arithmetic: signed integers of any size (sign and magnitude, base 2^32 limbs, little-endian).
class BigInt {
 public:
  int sign() const { return sign_; }

  // x * 2^-emin as an integer; x must be finite and a multiple of 2^emin (emin <= exponent of x's last bit).
  static BigInt from_scaled(double x, int emin) {
    BigInt r;
    if (x == 0.0) return r;
    int e = 0;
    const double f = std::frexp(std::abs(x), &e);  // |x| = f 2^e, f in [0.5, 1)
    const auto m = static_cast<std::uint64_t>(std::ldexp(f, 53));  // |x| = m 2^(e - 53), exact
    const int shift = e - 53 - emin;
    const int word = shift / 32, bit = shift % 32;
    const unsigned __int128 v = static_cast<unsigned __int128>(m) << bit;
    r.mag_.assign(static_cast<std::size_t>(word), 0u);
    for (int i = 0; i < 3; ++i) r.mag_.push_back(static_cast<std::uint32_t>(v >> (32 * i)));
    r.trim();
    r.sign_ = x < 0 ? -1 : 1;
    return r;
  }

  friend BigInt operator-(BigInt a) {
    a.sign_ = -a.sign_;
    return a;
  }
  friend BigInt operator+(const BigInt& a, const BigInt& b) {
    if (a.sign_ == 0) return b;
    if (b.sign_ == 0) return a;
    BigInt r;
    if (a.sign_ == b.sign_) {
      add_mag(a.mag_, b.mag_, r.mag_);
      r.sign_ = a.sign_;
      return r;
    }
    const int c = cmp_mag(a.mag_, b.mag_);
    if (c == 0) return r;
    if (c > 0) {
      sub_mag(a.mag_, b.mag_, r.mag_);
      r.sign_ = a.sign_;
    } else {
      sub_mag(b.mag_, a.mag_, r.mag_);
      r.sign_ = b.sign_;
    }
    return r;
  }
  friend BigInt operator-(const BigInt& a, const BigInt& b) { return a + (-b); }
  friend BigInt operator*(const BigInt& a, const BigInt& b) {
    BigInt r;
    if (a.sign_ == 0 || b.sign_ == 0) return r;
    r.mag_.assign(a.mag_.size() + b.mag_.size(), 0u);
    for (std::size_t i = 0; i < a.mag_.size(); ++i) {
      std::uint64_t carry = 0;
      for (std::size_t j = 0; j < b.mag_.size(); ++j) {
        const std::uint64_t t = static_cast<std::uint64_t>(a.mag_[i]) * b.mag_[j] + r.mag_[i + j] + carry;
        r.mag_[i + j] = static_cast<std::uint32_t>(t);
        carry = t >> 32;
      }
      r.mag_[i + b.mag_.size()] = static_cast<std::uint32_t>(carry);
    }
    r.trim();
    r.sign_ = a.sign_ * b.sign_;
    return r;
  }

 private:
  using Mag = std::vector<std::uint32_t>;
  void trim() {
    while (!mag_.empty() && mag_.back() == 0u) mag_.pop_back();
    if (mag_.empty()) sign_ = 0;
  }
  static int cmp_mag(const Mag& a, const Mag& b) {
    if (a.size() != b.size()) return a.size() < b.size() ? -1 : 1;
    for (std::size_t i = a.size(); i-- > 0;) {
      if (a[i] != b[i]) return a[i] < b[i] ? -1 : 1;
    }
    return 0;
  }
  static void add_mag(const Mag& a, const Mag& b, Mag& r) {
    const Mag& l = a.size() >= b.size() ? a : b;
    const Mag& s = a.size() >= b.size() ? b : a;
    r.assign(l.size() + 1, 0u);
    std::uint64_t carry = 0;
    for (std::size_t i = 0; i < l.size(); ++i) {
      const std::uint64_t t = static_cast<std::uint64_t>(l[i]) + (i < s.size() ? s[i] : 0u) + carry;
      r[i] = static_cast<std::uint32_t>(t);
      carry = t >> 32;
    }
    r[l.size()] = static_cast<std::uint32_t>(carry);
    while (!r.empty() && r.back() == 0u) r.pop_back();
  }
  // r = a - b with |a| > |b|.
  static void sub_mag(const Mag& a, const Mag& b, Mag& r) {
    r.assign(a.size(), 0u);
    std::int64_t borrow = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      std::int64_t t = static_cast<std::int64_t>(a[i]) - (i < b.size() ? b[i] : 0u) - borrow;
      borrow = t < 0 ? 1 : 0;
      if (t < 0) t += (std::int64_t{1} << 32);
      r[i] = static_cast<std::uint32_t>(t);
    }
    while (!r.empty() && r.back() == 0u) r.pop_back();
  }

  int sign_ = 0;
  Mag mag_;
};

// Smallest exponent of the last significant bit over the nonzero values (so each is an integer times 2^emin).
int min_lsb_exponent(const double* v, int n) {
  int emin = 0;
  bool any = false;
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(v[i])) {
      std::ostringstream msg;
      msg << "orientation predicate: coordinate must be finite, got " << v[i];
      throw std::invalid_argument(msg.str());
    }
    if (v[i] == 0.0) continue;
    int e = 0;
    std::frexp(v[i], &e);
    if (!any || e - 53 < emin) emin = e - 53;
    any = true;
  }
  return emin;
}

// Filter constants (Shewchuk 1997): epsilon = 2^-53, plus an absolute term for products that underflow.
constexpr double kEps = DBL_EPSILON / 2.0;
constexpr double kO3dErrBoundA = (7.0 + 56.0 * kEps) * kEps;
constexpr double kCcwErrBoundA = (3.0 + 16.0 * kEps) * kEps;
const double kUnderflowPad = std::ldexp(1.0, -1068);

// ---------------------------------------------------------------------------------------------------
// Segment and triangle tests (closed sets) from the exact predicates.

// True when the three signs contain both a positive and a negative one.
bool mixed_signs(int s1, int s2, int s3) {
  return (s1 > 0 || s2 > 0 || s3 > 0) && (s1 < 0 || s2 < 0 || s3 < 0);
}

// Collinear p on closed segment ab, checked on the two kept coordinates of projection `drop`.
bool on_segment_2d(const double* a, const double* b, const double* p, int drop) {
  for (int k = 1; k <= 2; ++k) {
    const int i = (drop + k) % 3;
    if (p[i] < std::min(a[i], b[i]) || p[i] > std::max(a[i], b[i])) return false;
  }
  return true;
}

// Closed segments pq and ab in a faithful projection `drop` of their common plane.
bool segments_intersect_2d(const double* p, const double* q, const double* a, const double* b, int drop) {
  const int d1 = orient2d(a, b, p, drop), d2 = orient2d(a, b, q, drop);
  const int d3 = orient2d(p, q, a, drop), d4 = orient2d(p, q, b, drop);
  if (d1 * d2 < 0 && d3 * d4 < 0) return true;
  if (d1 == 0 && on_segment_2d(a, b, p, drop)) return true;
  if (d2 == 0 && on_segment_2d(a, b, q, drop)) return true;
  if (d3 == 0 && on_segment_2d(p, q, a, drop)) return true;
  if (d4 == 0 && on_segment_2d(p, q, b, drop)) return true;
  return false;
}

// A projection (dropped coordinate) in which a, b, c are not collinear, or -1 when they are collinear in 3D.
int faithful_drop(const double* a, const double* b, const double* c) {
  for (int drop = 2; drop >= 0; --drop) {
    if (orient2d(a, b, c, drop) != 0) return drop;
  }
  return -1;
}

// Closed segment pq against closed non-degenerate triangle abc, all coplanar, in projection `drop`.
bool segment_triangle_coplanar(const double* p, const double* q, const double* a, const double* b,
                               const double* c, int drop) {
  // An endpoint inside the triangle, or the segment crossing one of its edges.
  const auto inside = [&](const double* s) {
    return !mixed_signs(orient2d(a, b, s, drop), orient2d(b, c, s, drop), orient2d(c, a, s, drop));
  };
  if (inside(p) || inside(q)) return true;
  return segments_intersect_2d(p, q, a, b, drop) || segments_intersect_2d(p, q, b, c, drop) ||
         segments_intersect_2d(p, q, c, a, drop);
}

// Segment pq against triangle abc given op = orient3d(a, b, c, p) and oq = orient3d(a, b, c, q).
bool segment_triangle_signed(const double* p, const double* q, const double* a, const double* b, const double* c,
                             int op, int oq) {
  if (op * oq > 0) return false;
  if (op == 0 && oq == 0) {
    // In the plane of a non-degenerate triangle, or a degenerate triangle (a segment or a point).
    const int drop = faithful_drop(a, b, c);
    if (drop >= 0) return segment_triangle_coplanar(p, q, a, b, c, drop);
    return segments_intersect(p, q, a, b) || segments_intersect(p, q, b, c) || segments_intersect(p, q, c, a);
  }
  // The segment meets the plane at one point; it is in the triangle iff line pq passes no edge strictly
  // on opposite sides.
  return !mixed_signs(orient3d(p, q, a, b), orient3d(p, q, b, c), orient3d(p, q, c, a));
}

// Throw unless x is finite and tris index into it without repeats.
void check_mesh(const PointsRef& x, const TrisRef& tris) {
  for (Eigen::Index i = 0; i < x.rows(); ++i) {
    for (int d = 0; d < 3; ++d) {
      if (!std::isfinite(x(i, d))) {
        std::ostringstream msg;
        msg << "x(" << i << ", " << d << ") must be finite, got " << x(i, d);
        throw std::invalid_argument(msg.str());
      }
    }
  }
  for (Eigen::Index i = 0; i < tris.rows(); ++i) {
    for (int j = 0; j < 3; ++j) {
      if (tris(i, j) < 0 || tris(i, j) >= x.rows()) {
        throw std::invalid_argument("tris(" + std::to_string(i) + ", " + std::to_string(j) + ") must be in [0, " +
                                    std::to_string(x.rows()) + "), got " + std::to_string(tris(i, j)));
      }
    }
    if (tris(i, 0) == tris(i, 1) || tris(i, 1) == tris(i, 2) || tris(i, 0) == tris(i, 2)) {
      throw std::invalid_argument("tris row " + std::to_string(i) + " repeats a vertex: (" + std::to_string(tris(i, 0)) +
                                  ", " + std::to_string(tris(i, 1)) + ", " + std::to_string(tris(i, 2)) + ")");
    }
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------------
// Predicates.

int orient3d_exact(const double* a, const double* b, const double* c, const double* d) {
  const double v[12] = {a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2], d[0], d[1], d[2]};
  const int emin = min_lsb_exponent(v, 12);
  BigInt w[12];
  for (int i = 0; i < 12; ++i) w[i] = BigInt::from_scaled(v[i], emin);
  // Differences to d, then the 3x3 determinant expanded on the z column (as the filter).
  const BigInt adx = w[0] - w[9], ady = w[1] - w[10], adz = w[2] - w[11];
  const BigInt bdx = w[3] - w[9], bdy = w[4] - w[10], bdz = w[5] - w[11];
  const BigInt cdx = w[6] - w[9], cdy = w[7] - w[10], cdz = w[8] - w[11];
  const BigInt det = adz * (bdx * cdy - cdx * bdy) + bdz * (cdx * ady - adx * cdy) + cdz * (adx * bdy - bdx * ady);
  return det.sign();
}

int orient3d(const double* a, const double* b, const double* c, const double* d) {
  // Floating-point evaluation and its error bound; the exact stage when the sign is not certain.
  const double adx = a[0] - d[0], bdx = b[0] - d[0], cdx = c[0] - d[0];
  const double ady = a[1] - d[1], bdy = b[1] - d[1], cdy = c[1] - d[1];
  const double adz = a[2] - d[2], bdz = b[2] - d[2], cdz = c[2] - d[2];
  const double bdxcdy = bdx * cdy, cdxbdy = cdx * bdy;
  const double cdxady = cdx * ady, adxcdy = adx * cdy;
  const double adxbdy = adx * bdy, bdxady = bdx * ady;
  const double det = adz * (bdxcdy - cdxbdy) + bdz * (cdxady - adxcdy) + cdz * (adxbdy - bdxady);
  const double permanent = (std::abs(bdxcdy) + std::abs(cdxbdy)) * std::abs(adz) +
                           (std::abs(cdxady) + std::abs(adxcdy)) * std::abs(bdz) +
                           (std::abs(adxbdy) + std::abs(bdxady)) * std::abs(cdz);
  const double errbound =
      kO3dErrBoundA * permanent + kUnderflowPad * (std::abs(adz) + std::abs(bdz) + std::abs(cdz) + 1.0);
  if (errbound <= DBL_MAX) {
    if (det > errbound) return 1;
    if (-det > errbound) return -1;
  }
  return orient3d_exact(a, b, c, d);
}

int orient2d_exact(const double* a, const double* b, const double* c, int drop) {
  const int u = (drop + 1) % 3, w = (drop + 2) % 3;
  const double v[6] = {a[u], a[w], b[u], b[w], c[u], c[w]};
  const int emin = min_lsb_exponent(v, 6);
  BigInt z[6];
  for (int i = 0; i < 6; ++i) z[i] = BigInt::from_scaled(v[i], emin);
  const BigInt det = (z[0] - z[4]) * (z[3] - z[5]) - (z[1] - z[5]) * (z[2] - z[4]);
  return det.sign();
}

int orient2d(const double* a, const double* b, const double* c, int drop) {
  const int u = (drop + 1) % 3, w = (drop + 2) % 3;
  const double detleft = (a[u] - c[u]) * (b[w] - c[w]);
  const double detright = (a[w] - c[w]) * (b[u] - c[u]);
  const double det = detleft - detright;
  const double errbound = kCcwErrBoundA * (std::abs(detleft) + std::abs(detright)) + kUnderflowPad;
  if (errbound <= DBL_MAX) {
    if (det > errbound) return 1;
    if (-det > errbound) return -1;
  }
  return orient2d_exact(a, b, c, drop);
}

// ---------------------------------------------------------------------------------------------------
// Segments and triangles.

bool segments_intersect(const double* p, const double* q, const double* a, const double* b) {
  if (orient3d(p, q, a, b) != 0) return false;
  // Coplanar: a projection where some triple of the four points is not collinear is faithful.
  const double* triples[4][3] = {{p, q, a}, {p, q, b}, {a, b, p}, {a, b, q}};
  for (const auto& t : triples) {
    const int drop = faithful_drop(t[0], t[1], t[2]);
    if (drop >= 0) return segments_intersect_2d(p, q, a, b, drop);
  }
  // All four collinear: compare intervals on a coordinate along which they spread.
  for (int i = 0; i < 3; ++i) {
    if (p[i] == q[i] && q[i] == a[i] && a[i] == b[i]) continue;
    return std::max(std::min(p[i], q[i]), std::min(a[i], b[i])) <= std::min(std::max(p[i], q[i]), std::max(a[i], b[i]));
  }
  return true;  // all four points coincide
}

bool segment_triangle_intersect(const double* p, const double* q, const double* a, const double* b,
                                const double* c) {
  return segment_triangle_signed(p, q, a, b, c, orient3d(a, b, c, p), orient3d(a, b, c, q));
}

bool triangles_intersect(const double* a0, const double* a1, const double* a2, const double* b0, const double* b1,
                         const double* b2) {
  // Each triangle's vertices against the other's plane: strictly one side means disjoint.
  const int oa0 = orient3d(b0, b1, b2, a0), oa1 = orient3d(b0, b1, b2, a1), oa2 = orient3d(b0, b1, b2, a2);
  if ((oa0 > 0 && oa1 > 0 && oa2 > 0) || (oa0 < 0 && oa1 < 0 && oa2 < 0)) return false;
  const int ob0 = orient3d(a0, a1, a2, b0), ob1 = orient3d(a0, a1, a2, b1), ob2 = orient3d(a0, a1, a2, b2);
  if ((ob0 > 0 && ob1 > 0 && ob2 > 0) || (ob0 < 0 && ob1 < 0 && ob2 < 0)) return false;
  // Closed triangles meet iff an edge of one meets the other (the intersection's extreme points lie on edges).
  return segment_triangle_signed(a0, a1, b0, b1, b2, oa0, oa1) || segment_triangle_signed(a1, a2, b0, b1, b2, oa1, oa2) ||
         segment_triangle_signed(a2, a0, b0, b1, b2, oa2, oa0) || segment_triangle_signed(b0, b1, a0, a1, a2, ob0, ob1) ||
         segment_triangle_signed(b1, b2, a0, a1, a2, ob1, ob2) || segment_triangle_signed(b2, b0, a0, a1, a2, ob2, ob0);
}

bool mesh_triangles_intersect(const PointsRef& x, const int* ta, const int* tb) {
  const auto pt = [&x](int i) { return x.data() + i * x.outerStride(); };
  // Which vertices of ta are shared with tb.
  int shared = 0;
  bool in_b[3];
  for (int i = 0; i < 3; ++i) {
    in_b[i] = ta[i] == tb[0] || ta[i] == tb[1] || ta[i] == tb[2];
    shared += in_b[i];
  }
  if (shared == 0) {
    return triangles_intersect(pt(ta[0]), pt(ta[1]), pt(ta[2]), pt(tb[0]), pt(tb[1]), pt(tb[2]));
  }
  if (shared == 3) return true;
  if (shared == 1) {
    // Shared vertex v: the edge opposite v in each triangle against the other triangle.
    int ia = 0, ib = 0;
    while (!in_b[ia]) ++ia;
    while (tb[ib] != ta[ia]) ++ib;
    const int a1 = ta[(ia + 1) % 3], a2 = ta[(ia + 2) % 3];
    const int b1 = tb[(ib + 1) % 3], b2 = tb[(ib + 2) % 3];
    return segment_triangle_intersect(pt(a1), pt(a2), pt(tb[0]), pt(tb[1]), pt(tb[2])) ||
           segment_triangle_intersect(pt(b1), pt(b2), pt(ta[0]), pt(ta[1]), pt(ta[2]));
  }
  // Shared edge (u, w) with opposite vertices c (in ta) and d (in tb): beyond the edge only when coplanar
  // with c and d strictly on the same side.
  int ic = 0;
  while (in_b[ic]) ++ic;
  const int u = ta[(ic + 1) % 3], w = ta[(ic + 2) % 3], c = ta[ic];
  int d = tb[0];
  for (int j = 0; j < 3; ++j) {
    if (tb[j] != u && tb[j] != w) d = tb[j];
  }
  if (orient3d(pt(u), pt(w), pt(c), pt(d)) != 0) return false;
  const int drop = faithful_drop(pt(u), pt(w), pt(c));
  if (drop < 0) return false;  // ta degenerate: it lies on the shared edge's line
  return orient2d(pt(u), pt(w), pt(c), drop) * orient2d(pt(u), pt(w), pt(d), drop) > 0;
}

long count_intersecting_pairs(const PointsRef& x, const TrisRef& tris) {
  check_mesh(x, tris);
  const int n = static_cast<int>(tris.rows());
  if (n < 2) return 0;
  // AABB tree over the triangles (exact min/max, closed overlap: never prunes a touching pair).
  std::vector<double> centres(static_cast<std::size_t>(3 * n));
  for (int t = 0; t < n; ++t) {
    for (int d = 0; d < 3; ++d) {
      centres[static_cast<std::size_t>(3 * t + d)] = (x(tris(t, 0), d) + x(tris(t, 1), d) + x(tris(t, 2), d)) / 3.0;
    }
  }
  KdopBvh<6> bvh;
  bvh.build(centres.data(), n);
  for (int t = 0; t < n; ++t) {
    Kdop<6>& box = bvh.leaf_box(t);
    for (int j = 0; j < 3; ++j) box.add_point(x.data() + tris(t, j) * x.outerStride());
  }
  bvh.refit();
  // Exact test on each overlapping pair.
  long count = 0;
  bvh.self_pairs([&](int i, int j) {
    const int ta[3] = {tris(i, 0), tris(i, 1), tris(i, 2)};
    const int tb[3] = {tris(j, 0), tris(j, 1), tris(j, 2)};
    if (mesh_triangles_intersect(x, ta, tb)) ++count;
  });
  return count;
}

}  // namespace lumen::collision
