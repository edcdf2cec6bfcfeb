// Exact discrete intersection check: filtered orientation predicates with an exact big-integer fallback,
// segment/triangle tests from them, and a pruned all-pairs count over a mesh.
#include "collision/intersect.hpp"

#include <algorithm>
#include <array>
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
// Exact arithmetic: signed integers of at most N base-2^32 limbs (sign and magnitude, little-endian),
// stored inline (no allocation). Callers size N from the inputs' bit span so nothing can overflow.
template <int N>
class BigInt {
 public:
  int sign() const { return sign_; }

  // x * 2^-emin as an integer; x must be finite and a multiple of 2^emin.
  static BigInt from_scaled(double x, int emin) {
    BigInt r;
    if (x == 0.0) return r;
    int e = 0;
    const double f = std::frexp(std::abs(x), &e);                  // |x| = f 2^e, f in [0.5, 1)
    const auto m = static_cast<std::uint64_t>(std::ldexp(f, 53));  // |x| = m 2^(e - 53), exact
    const int shift = e - 53 - emin;
    const int word = shift / 32, bit = shift % 32;
    const unsigned __int128 v = static_cast<unsigned __int128>(m) << bit;
    for (int i = 0; i < word; ++i) r.mag_[i] = 0u;
    for (int i = 0; i < 3; ++i) r.mag_[word + i] = static_cast<std::uint32_t>(v >> (32 * i));
    r.n_ = word + 3;
    r.sign_ = x < 0 ? -1 : 1;
    r.trim();
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
      add_mag(a, b, r);
      r.sign_ = a.sign_;
      return r;
    }
    const int c = cmp_mag(a, b);
    if (c == 0) return r;
    if (c > 0) {
      sub_mag(a, b, r);
      r.sign_ = a.sign_;
    } else {
      sub_mag(b, a, r);
      r.sign_ = b.sign_;
    }
    r.trim();
    return r;
  }
  friend BigInt operator-(const BigInt& a, const BigInt& b) { return a + (-b); }
  friend BigInt operator*(const BigInt& a, const BigInt& b) {
    BigInt r;
    if (a.sign_ == 0 || b.sign_ == 0) return r;
    r.n_ = a.n_ + b.n_;
    for (int i = 0; i < r.n_; ++i) r.mag_[i] = 0u;
    for (int i = 0; i < a.n_; ++i) {
      std::uint64_t carry = 0;
      for (int j = 0; j < b.n_; ++j) {
        const std::uint64_t t = static_cast<std::uint64_t>(a.mag_[i]) * b.mag_[j] + r.mag_[i + j] + carry;
        r.mag_[i + j] = static_cast<std::uint32_t>(t);
        carry = t >> 32;
      }
      r.mag_[i + b.n_] = static_cast<std::uint32_t>(carry);
    }
    r.sign_ = a.sign_ * b.sign_;
    r.trim();
    return r;
  }

 private:
  void trim() {
    while (n_ > 0 && mag_[n_ - 1] == 0u) --n_;
    if (n_ == 0) sign_ = 0;
  }
  static int cmp_mag(const BigInt& a, const BigInt& b) {
    if (a.n_ != b.n_) return a.n_ < b.n_ ? -1 : 1;
    for (int i = a.n_ - 1; i >= 0; --i) {
      if (a.mag_[i] != b.mag_[i]) return a.mag_[i] < b.mag_[i] ? -1 : 1;
    }
    return 0;
  }
  static void add_mag(const BigInt& a, const BigInt& b, BigInt& r) {
    const BigInt& l = a.n_ >= b.n_ ? a : b;
    const BigInt& s = a.n_ >= b.n_ ? b : a;
    std::uint64_t carry = 0;
    for (int i = 0; i < l.n_; ++i) {
      const std::uint64_t t = static_cast<std::uint64_t>(l.mag_[i]) + (i < s.n_ ? s.mag_[i] : 0u) + carry;
      r.mag_[i] = static_cast<std::uint32_t>(t);
      carry = t >> 32;
    }
    r.n_ = l.n_;
    if (carry != 0u) r.mag_[r.n_++] = static_cast<std::uint32_t>(carry);
  }
  // r = |a| - |b| with |a| > |b|.
  static void sub_mag(const BigInt& a, const BigInt& b, BigInt& r) {
    std::int64_t borrow = 0;
    for (int i = 0; i < a.n_; ++i) {
      std::int64_t t = static_cast<std::int64_t>(a.mag_[i]) - (i < b.n_ ? b.mag_[i] : 0u) - borrow;
      borrow = t < 0 ? 1 : 0;
      if (t < 0) t += (std::int64_t{1} << 32);
      r.mag_[i] = static_cast<std::uint32_t>(t);
    }
    r.n_ = a.n_;
  }

  int sign_ = 0;
  int n_ = 0;
  std::uint32_t mag_[N] = {};
};

// Bit span of the values as integers times 2^emin: the smallest last-bit exponent (emin) and the largest
// magnitude exponent (every |v| < 2^emax). Throws on a non-finite value.
struct BitSpan {
  int emin = 0, emax = 0;
};
BitSpan bit_span(const double* v, int n) {
  BitSpan s;
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
    if (!any || e - 53 < s.emin) s.emin = e - 53;
    if (!any || e > s.emax) s.emax = e;
    any = true;
  }
  if (!any) s.emax = s.emin;
  return s;
}

// Limbs for a degree-3 polynomial of differences of integers below 2^bits (3 bits + 6, plus slack for
// the product buffers); the largest double span is 1024 + 1126 bits.
constexpr int kSmallLimbs = 24;   // spans up to 160 bits (ordinary geometry)
constexpr int kLargeLimbs = 212;  // any finite doubles (needs 203)
constexpr int kSmallSpanBits = 160;

// Sign of det[a - d; b - d; c - d] on integers (12 values: a, b, c, d), expanded on the z column.
template <int N>
int orient3d_int(const double* v, int emin) {
  using B = BigInt<N>;
  B w[12];
  for (int i = 0; i < 12; ++i) w[i] = B::from_scaled(v[i], emin);
  const B adx = w[0] - w[9], ady = w[1] - w[10], adz = w[2] - w[11];
  const B bdx = w[3] - w[9], bdy = w[4] - w[10], bdz = w[5] - w[11];
  const B cdx = w[6] - w[9], cdy = w[7] - w[10], cdz = w[8] - w[11];
  const B det = adz * (bdx * cdy - cdx * bdy) + bdz * (cdx * ady - adx * cdy) + cdz * (adx * bdy - bdx * ady);
  return det.sign();
}

// Sign of (a - c) x (b - c) on integers (6 values: au, aw, bu, bw, cu, cw).
template <int N>
int orient2d_int(const double* v, int emin) {
  using B = BigInt<N>;
  B z[6];
  for (int i = 0; i < 6; ++i) z[i] = B::from_scaled(v[i], emin);
  const B det = (z[0] - z[4]) * (z[3] - z[5]) - (z[1] - z[5]) * (z[2] - z[4]);
  return det.sign();
}

// ---------------------------------------------------------------------------------------------------
// Exact arithmetic, fast stage: floating-point expansions (Shewchuk 1997), nonoverlapping components in
// increasing magnitude with zeros eliminated. Exact when no product underflows or overflows, which holds
// when every nonzero input magnitude lies in [2^-247, 2^300] (see expansion_range_ok).

// x + y = a + b exactly.
inline void two_sum(double a, double b, double& x, double& y) {
  x = a + b;
  const double bv = x - a, av = x - bv;
  y = (a - av) + (b - bv);
}
// x + y = a + b exactly, given |a| >= |b| (or a == 0).
inline void fast_two_sum(double a, double b, double& x, double& y) {
  x = a + b;
  y = b - (x - a);
}
// x + y = a - b exactly.
inline void two_diff(double a, double b, double& x, double& y) {
  x = a - b;
  const double bv = a - x, av = x + bv;
  y = (a - av) + (bv - b);
}
// x + y = a * b exactly (hardware FMA when the target has it, else Dekker's split).
inline void two_product(double a, double b, double& x, double& y) {
  x = a * b;
#if defined(__FMA__)
  y = std::fma(a, b, -x);
#else
  constexpr double kSplitter = 134217729.0;  // 2^27 + 1
  const double ca = kSplitter * a, ahi = ca - (ca - a), alo = a - ahi;
  const double cb = kSplitter * b, bhi = cb - (cb - b), blo = b - bhi;
  const double err1 = x - ahi * bhi, err2 = err1 - alo * bhi, err3 = err2 - ahi * blo;
  y = alo * blo - err3;
#endif
}
// h = e + b; h may be e (in place); returns the length (>= 1), at most elen + 1.
inline int grow_expansion(int elen, const double* e, double b, double* h) {
  double q = b;
  int hn = 0;
  for (int i = 0; i < elen; ++i) {
    double qn, hh;
    two_sum(q, e[i], qn, hh);
    q = qn;
    if (hh != 0.0) h[hn++] = hh;
  }
  if (q != 0.0 || hn == 0) h[hn++] = q;
  return hn;
}
// h = e * b (h distinct from e); returns the length, at most 2 elen.
inline int scale_expansion(int elen, const double* e, double b, double* h) {
  double q, hh;
  two_product(e[0], b, q, hh);
  int hn = 0;
  if (hh != 0.0) h[hn++] = hh;
  for (int i = 1; i < elen; ++i) {
    double p1, p0, sum;
    two_product(e[i], b, p1, p0);
    two_sum(q, p0, sum, hh);
    if (hh != 0.0) h[hn++] = hh;
    fast_two_sum(p1, sum, q, hh);
    if (hh != 0.0) h[hn++] = hh;
  }
  if (q != 0.0 || hn == 0) h[hn++] = q;
  return hn;
}
// h = e + s f (s = +1 or -1), h distinct from f; h has room for elen + flen; returns the length.
inline int add_expansion(int elen, const double* e, int flen, const double* f, double s, double* h) {
  for (int i = 0; i < elen; ++i) h[i] = e[i];
  int hn = elen;
  for (int j = 0; j < flen; ++j) hn = grow_expansion(hn, h, s * f[j], h);
  return hn;
}
// h = e * f (h distinct from both); h has room for 2 elen flen; returns the length.
inline int mul_expansion(int elen, const double* e, int flen, const double* f, double* h) {
  int hn = scale_expansion(elen, e, f[0], h);
  double t[64];
  for (int j = 1; j < flen; ++j) {
    const int tn = scale_expansion(elen, e, f[j], t);
    for (int i = 0; i < tn; ++i) hn = grow_expansion(hn, h, t[i], h);
  }
  return hn;
}
// The exact difference a - b as an expansion of 1 or 2 components; returns the length.
inline int diff_expansion(double a, double b, double* h) {
  double x, y;
  two_diff(a, b, x, y);
  if (y == 0.0) {
    h[0] = x;
    return 1;
  }
  h[0] = y;
  h[1] = x;
  return 2;
}
inline int expansion_sign(int n, const double* e) { return e[n - 1] > 0.0 ? 1 : (e[n - 1] < 0.0 ? -1 : 0); }

// True when every value is finite and zero or of magnitude in [2^-247, 2^300]: then all components of
// the degree-3 expansions are multiples of 2^-900 below 2^910, so no product underflows or overflows.
inline bool expansion_range_ok(const double* v, int n) {
  constexpr double kLo = 0x1p-247, kHi = 0x1p300;
  for (int i = 0; i < n; ++i) {
    const double m = std::abs(v[i]);
    if (!(m <= kHi) || (m != 0.0 && m < kLo)) return false;
  }
  return true;
}

// Sign of det[a - d; b - d; c - d] from expansions (values: a, b, c, d).
int orient3d_expansion(const double* v) {
  double ad[3][2], bd[3][2], cd[3][2];
  int nad[3], nbd[3], ncd[3];
  for (int k = 0; k < 3; ++k) {
    nad[k] = diff_expansion(v[k], v[9 + k], ad[k]);
    nbd[k] = diff_expansion(v[3 + k], v[9 + k], bd[k]);
    ncd[k] = diff_expansion(v[6 + k], v[9 + k], cd[k]);
  }
  // z-column cofactors: m = p * q - r * s, each term then times a z difference.
  const auto minor_times = [](const double* p, int np, const double* q, int nq, const double* r, int nr,
                              const double* s, int ns, const double* z, int nz, double* out) {
    double pq[8], rs[8], m[16];
    const int npq = mul_expansion(np, p, nq, q, pq);
    const int nrs = mul_expansion(nr, r, ns, s, rs);
    const int nm = add_expansion(npq, pq, nrs, rs, -1.0, m);
    return mul_expansion(nm, m, nz, z, out);
  };
  double t1[64], t2[64], t3[64], acc[192];
  const int n1 = minor_times(bd[0], nbd[0], cd[1], ncd[1], cd[0], ncd[0], bd[1], nbd[1], ad[2], nad[2], t1);
  const int n2 = minor_times(cd[0], ncd[0], ad[1], nad[1], ad[0], nad[0], cd[1], ncd[1], bd[2], nbd[2], t2);
  const int n3 = minor_times(ad[0], nad[0], bd[1], nbd[1], bd[0], nbd[0], ad[1], nad[1], cd[2], ncd[2], t3);
  double acc2[128];
  const int n12 = add_expansion(n1, t1, n2, t2, 1.0, acc2);
  const int n = add_expansion(n12, acc2, n3, t3, 1.0, acc);
  return expansion_sign(n, acc);
}

// Sign of (a - c) x (b - c) from expansions (values: au, aw, bu, bw, cu, cw).
int orient2d_expansion(const double* v) {
  double acu[2], acw[2], bcu[2], bcw[2], l[8], r[8], det[16];
  const int nacu = diff_expansion(v[0], v[4], acu), nacw = diff_expansion(v[1], v[5], acw);
  const int nbcu = diff_expansion(v[2], v[4], bcu), nbcw = diff_expansion(v[3], v[5], bcw);
  const int nl = mul_expansion(nacu, acu, nbcw, bcw, l);
  const int nr = mul_expansion(nacw, acw, nbcu, bcu, r);
  const int n = add_expansion(nl, l, nr, r, -1.0, det);
  return expansion_sign(n, det);
}

// Filter constants (Shewchuk 1997): epsilon = 2^-53. The absolute term covers products that underflow
// (each off by at most 2^-1075, then scaled by at most the largest difference); it is a normal number so
// the filter never computes with subnormals (slow on x86), and it only sends values below ~1e-270 to
// the exact stage.
constexpr double kEps = DBL_EPSILON / 2.0;
constexpr double kO3dErrBoundA = (7.0 + 56.0 * kEps) * kEps;
constexpr double kCcwErrBoundA = (3.0 + 16.0 * kEps) * kEps;
constexpr double kUnderflowPad = 0x1p-900;
constexpr double kPlaneErrBound = 12.0 * kEps;

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

// True when det of the 3x3 rows is zero by its zero entries alone (computed differences are zero only
// when exactly zero): some column expansion has every term with a zero factor. Exact, and cheap for the
// axis-aligned structure of generated meshes.
bool structurally_zero_det(const double* r0, const double* r1, const double* r2) {
  const double* rows[3] = {r0, r1, r2};
  for (int k = 0; k < 3; ++k) {
    const int i = (k + 1) % 3, j = (k + 2) % 3;
    bool zero = true;
    for (int r = 0; r < 3 && zero; ++r) {
      const double* a = rows[r];
      const double* b = rows[(r + 1) % 3];
      const double* c = rows[(r + 2) % 3];
      zero = a[k] == 0.0 || ((b[i] == 0.0 || c[j] == 0.0) && (c[i] == 0.0 || b[j] == 0.0));
    }
    if (zero) return true;
  }
  return false;
}

// A triangle's plane with its normal precomputed, for the orientation of many points against it: the
// same exact sign as orient3d(p0, p1, p2, q) with a cheaper filter. With rounded differences e1, e2, r
// and n = e1 x e2, the computed r . n is off by at most gamma_8 sum_k |r_k| (|P_k| + |Q_k|) (P_k, Q_k the
// two products of n_k); we use 12 u of the computed sum, plus the normal-range underflow term.
struct TriPlane {
  const double *p0 = nullptr, *p1 = nullptr, *p2 = nullptr;
  double e1[3] = {0, 0, 0}, e2[3] = {0, 0, 0};  // p1 - p0, p2 - p0, rounded
  double n[3] = {0, 0, 0};                      // e1 x e2, rounded
  double m[3] = {0, 0, 0};                      // |P_k| + |Q_k| per component
  mutable int drop_ = -2;                       // projection axis, -2 until known

  void set(const double* a, const double* b, const double* c) {
    p0 = a;
    p1 = b;
    p2 = c;
    for (int k = 0; k < 3; ++k) {
      e1[k] = b[k] - a[k];
      e2[k] = c[k] - a[k];
    }
    for (int k = 0; k < 3; ++k) {
      const int i = (k + 1) % 3, j = (k + 2) % 3;
      const double pk = e1[i] * e2[j], qk = e1[j] * e2[i];
      n[k] = pk - qk;
      m[k] = std::abs(pk) + std::abs(qk);
    }
    // Projection axis: the largest normal component when it is certainly nonzero (its rounding error is
    // below gamma_4 m_k), else found exactly on demand.
    int k = 0;
    if (std::abs(n[1]) > std::abs(n[k])) k = 1;
    if (std::abs(n[2]) > std::abs(n[k])) k = 2;
    drop_ = std::abs(n[k]) > 8.0 * kEps * m[k] + kUnderflowPad ? k : -2;
  }
  // A coordinate to drop so that the plane projects one-to-one (the triangle stays non-degenerate), or -1
  // when the triangle is degenerate.
  int drop() const {
    if (drop_ == -2) drop_ = faithful_drop(p0, p1, p2);
    return drop_;
  }
  // orient3d(p0, p1, p2, q) = -(q - p0) . n.
  int orient(const double* q) const {
    const double r0 = q[0] - p0[0], r1 = q[1] - p0[1], r2 = q[2] - p0[2];
    const double det = r0 * n[0] + r1 * n[1] + r2 * n[2];
    const double a0 = std::abs(r0), a1 = std::abs(r1), a2 = std::abs(r2);
    const double bound = kPlaneErrBound * (a0 * m[0] + a1 * m[1] + a2 * m[2]) + kUnderflowPad * (a0 + a1 + a2 + 1.0);
    if (bound <= DBL_MAX) {
      if (det > bound) return -1;
      if (-det > bound) return 1;
      const double r[3] = {r0, r1, r2};
      if (structurally_zero_det(r, e1, e2)) return 0;
    }
    return orient3d(p0, p1, p2, q);
  }
};

// Closed triangles a and b in a common plane, b non-degenerate in projection `drop`.
bool triangles_intersect_coplanar(const double* a0, const double* a1, const double* a2, const double* b0,
                                  const double* b1, const double* b2, int drop) {
  const int sa = orient2d(a0, a1, a2, drop);
  if (sa == 0) {
    // a is a segment or a point: the union of its edges.
    return segment_triangle_coplanar(a0, a1, b0, b1, b2, drop) || segment_triangle_coplanar(a1, a2, b0, b1, b2, drop) ||
           segment_triangle_coplanar(a2, a0, b0, b1, b2, drop);
  }
  const int sb = orient2d(b0, b1, b2, drop);
  // Separating axes: disjoint convex polygons are separated by the line of an edge of one of them, with
  // the other strictly outside.
  const double* ta[3] = {a0, a1, a2};
  const double* tb[3] = {b0, b1, b2};
  for (int i = 0; i < 3; ++i) {
    const double* p = ta[i];
    const double* q = ta[(i + 1) % 3];
    if (orient2d(p, q, b0, drop) * sa < 0 && orient2d(p, q, b1, drop) * sa < 0 && orient2d(p, q, b2, drop) * sa < 0) {
      return false;
    }
    const double* r = tb[i];
    const double* t = tb[(i + 1) % 3];
    if (orient2d(r, t, a0, drop) * sb < 0 && orient2d(r, t, a1, drop) * sb < 0 && orient2d(r, t, a2, drop) * sb < 0) {
      return false;
    }
  }
  return true;
}

// Segment pq against triangle abc given op = orient3d(a, b, c, p) and oq = orient3d(a, b, c, q); `plane`
// (optional) is the triangle's plane, for its projection axis.
bool segment_triangle_signed(const double* p, const double* q, const double* a, const double* b, const double* c,
                             int op, int oq, const TriPlane* plane) {
  if (op * oq > 0) return false;
  if (op == 0 && oq == 0) {
    // In the plane of a non-degenerate triangle, or a degenerate triangle (a segment or a point).
    const int drop = plane ? plane->drop() : faithful_drop(a, b, c);
    if (drop >= 0) return segment_triangle_coplanar(p, q, a, b, c, drop);
    return segments_intersect(p, q, a, b) || segments_intersect(p, q, b, c) || segments_intersect(p, q, c, a);
  }
  if (op == 0 || oq == 0) {
    // Only one endpoint is on the plane (so the triangle is not degenerate): that point in the triangle,
    // in 2D.
    const double* s = op == 0 ? p : q;
    const int drop = plane ? plane->drop() : faithful_drop(a, b, c);
    return !mixed_signs(orient2d(a, b, s, drop), orient2d(b, c, s, drop), orient2d(c, a, s, drop));
  }
  // The segment crosses the plane at one interior point; it is in the triangle iff line pq passes no edge
  // strictly on opposite sides.
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
  if (expansion_range_ok(v, 12)) return orient3d_expansion(v);
  const BitSpan s = bit_span(v, 12);
  if (s.emax - s.emin <= kSmallSpanBits) return orient3d_int<kSmallLimbs>(v, s.emin);
  return orient3d_int<kLargeLimbs>(v, s.emin);
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
    const double ad[3] = {adx, ady, adz}, bd[3] = {bdx, bdy, bdz}, cd[3] = {cdx, cdy, cdz};
    if (structurally_zero_det(ad, bd, cd)) return 0;
  }
  return orient3d_exact(a, b, c, d);
}

int orient2d_exact(const double* a, const double* b, const double* c, int drop) {
  const int u = (drop + 1) % 3, w = (drop + 2) % 3;
  const double v[6] = {a[u], a[w], b[u], b[w], c[u], c[w]};
  if (expansion_range_ok(v, 6)) return orient2d_expansion(v);
  const BitSpan s = bit_span(v, 6);
  if (s.emax - s.emin <= kSmallSpanBits) return orient2d_int<kSmallLimbs>(v, s.emin);
  return orient2d_int<kLargeLimbs>(v, s.emin);
}

int orient2d(const double* a, const double* b, const double* c, int drop) {
  const int u = (drop + 1) % 3, w = (drop + 2) % 3;
  const double acu = a[u] - c[u], bcw = b[w] - c[w], acw = a[w] - c[w], bcu = b[u] - c[u];
  // A zero factor (a computed difference is zero only when exact): the sign of the other product, whose
  // factors' signs are exact.
  const auto sgn = [](double v) { return (v > 0.0) - (v < 0.0); };
  if (acu == 0.0 || bcw == 0.0) return -sgn(acw) * sgn(bcu);
  if (acw == 0.0 || bcu == 0.0) return sgn(acu) * sgn(bcw);
  const double detleft = acu * bcw;
  const double detright = acw * bcu;
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
  return segment_triangle_signed(p, q, a, b, c, orient3d(a, b, c, p), orient3d(a, b, c, q), nullptr);
}

namespace {

// Closed triangles a and b with their planes pa, pb (built from the same vertex order).
bool triangles_intersect_planes(const double* a0, const double* a1, const double* a2, const double* b0,
                                const double* b1, const double* b2, const TriPlane& pa, const TriPlane& pb) {
  // Each triangle's vertices against the other's plane: strictly one side means disjoint.
  const int oa0 = pb.orient(a0), oa1 = pb.orient(a1), oa2 = pb.orient(a2);
  if ((oa0 > 0 && oa1 > 0 && oa2 > 0) || (oa0 < 0 && oa1 < 0 && oa2 < 0)) return false;
  if (oa0 == 0 && oa1 == 0 && oa2 == 0) {
    // In the plane of a non-degenerate b: a 2D test in a faithful projection.
    const int drop = pb.drop();
    if (drop >= 0) return triangles_intersect_coplanar(a0, a1, a2, b0, b1, b2, drop);
  }
  const int ob0 = pa.orient(b0), ob1 = pa.orient(b1), ob2 = pa.orient(b2);
  if ((ob0 > 0 && ob1 > 0 && ob2 > 0) || (ob0 < 0 && ob1 < 0 && ob2 < 0)) return false;
  // Closed triangles meet iff an edge of one meets the other (the intersection's extreme points lie on edges).
  return segment_triangle_signed(a0, a1, b0, b1, b2, oa0, oa1, &pb) ||
         segment_triangle_signed(a1, a2, b0, b1, b2, oa1, oa2, &pb) ||
         segment_triangle_signed(a2, a0, b0, b1, b2, oa2, oa0, &pb) ||
         segment_triangle_signed(b0, b1, a0, a1, a2, ob0, ob1, &pa) ||
         segment_triangle_signed(b1, b2, a0, a1, a2, ob1, ob2, &pa) ||
         segment_triangle_signed(b2, b0, a0, a1, a2, ob2, ob0, &pa);
}

// Mesh triangles ta, tb (ids into x) with their planes: see mesh_triangles_intersect.
bool mesh_pair_intersects(const PointsRef& x, const int* ta, const int* tb, const TriPlane& pa, const TriPlane& pb) {
  const auto pt = [&x](int i) { return x.data() + i * x.outerStride(); };
  // Which vertices of ta are shared with tb.
  int shared = 0;
  bool in_b[3];
  for (int i = 0; i < 3; ++i) {
    in_b[i] = ta[i] == tb[0] || ta[i] == tb[1] || ta[i] == tb[2];
    shared += in_b[i];
  }
  if (shared == 0) {
    return triangles_intersect_planes(pt(ta[0]), pt(ta[1]), pt(ta[2]), pt(tb[0]), pt(tb[1]), pt(tb[2]), pa, pb);
  }
  if (shared == 3) return true;
  if (shared == 1) {
    // Shared vertex v: the edge opposite v in each triangle against the other triangle.
    int ia = 0, ib = 0;
    while (!in_b[ia]) ++ia;
    while (tb[ib] != ta[ia]) ++ib;
    const double *a1 = pt(ta[(ia + 1) % 3]), *a2 = pt(ta[(ia + 2) % 3]);
    const double *b1 = pt(tb[(ib + 1) % 3]), *b2 = pt(tb[(ib + 2) % 3]);
    const double *A0 = pt(ta[0]), *A1 = pt(ta[1]), *A2 = pt(ta[2]);
    const double *B0 = pt(tb[0]), *B1 = pt(tb[1]), *B2 = pt(tb[2]);
    const int o1 = pb.orient(a1), o2 = pb.orient(a2);
    if (o1 == 0 && o2 == 0) {
      // Both triangles in one plane (tb non-degenerate): 2D tests, ta as its edges if degenerate.
      const int drop = pb.drop();
      if (drop >= 0) {
        if (segment_triangle_coplanar(a1, a2, B0, B1, B2, drop)) return true;
        if (orient2d(A0, A1, A2, drop) != 0) return segment_triangle_coplanar(b1, b2, A0, A1, A2, drop);
        return segments_intersect_2d(b1, b2, A0, A1, drop) || segments_intersect_2d(b1, b2, A1, A2, drop) ||
               segments_intersect_2d(b1, b2, A2, A0, drop);
      }
    }
    return segment_triangle_signed(a1, a2, B0, B1, B2, o1, o2, &pb) ||
           segment_triangle_signed(b1, b2, A0, A1, A2, pa.orient(b1), pa.orient(b2), &pa);
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
  if (pa.orient(pt(d)) != 0) return false;
  const int drop = pa.drop();
  if (drop < 0) return false;  // ta degenerate: it lies on the shared edge's line
  return orient2d(pt(u), pt(w), pt(c), drop) * orient2d(pt(u), pt(w), pt(d), drop) > 0;
}

}  // namespace

bool triangles_intersect(const double* a0, const double* a1, const double* a2, const double* b0, const double* b1,
                         const double* b2) {
  TriPlane pa, pb;
  pa.set(a0, a1, a2);
  pb.set(b0, b1, b2);
  return triangles_intersect_planes(a0, a1, a2, b0, b1, b2, pa, pb);
}

bool mesh_triangles_intersect(const PointsRef& x, const int* ta, const int* tb) {
  const auto pt = [&x](int i) { return x.data() + i * x.outerStride(); };
  TriPlane pa, pb;
  pa.set(pt(ta[0]), pt(ta[1]), pt(ta[2]));
  pb.set(pt(tb[0]), pt(tb[1]), pt(tb[2]));
  return mesh_pair_intersects(x, ta, tb, pa, pb);
}

std::vector<std::array<int, 2>> intersecting_pairs(const PointsRef& x, const TrisRef& tris) {
  check_mesh(x, tris);
  const int n = static_cast<int>(tris.rows());
  std::vector<std::array<int, 2>> pairs;
  if (n < 2) return pairs;
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
  // Planes of the triangles, then the exact test on each overlapping pair.
  std::vector<TriPlane> planes(static_cast<std::size_t>(n));
  for (int t = 0; t < n; ++t) {
    const auto pt = [&x](int i) { return x.data() + i * x.outerStride(); };
    planes[static_cast<std::size_t>(t)].set(pt(tris(t, 0)), pt(tris(t, 1)), pt(tris(t, 2)));
  }
  bvh.self_pairs([&](int i, int j) {
    const int ta[3] = {tris(i, 0), tris(i, 1), tris(i, 2)};
    const int tb[3] = {tris(j, 0), tris(j, 1), tris(j, 2)};
    if (mesh_pair_intersects(x, ta, tb, planes[static_cast<std::size_t>(i)], planes[static_cast<std::size_t>(j)]))
      pairs.push_back({std::min(i, j), std::max(i, j)});
  });
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

long count_intersecting_pairs(const PointsRef& x, const TrisRef& tris) {
  return static_cast<long>(intersecting_pairs(x, tris).size());
}

}  // namespace lumen::collision
