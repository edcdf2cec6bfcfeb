// Elementary continuous collision tests: inclusion-based, earliest-t-first bisection of the parameter box,
// with a coplanarity filter and a certified fast path for transversal contacts.
#include "collision/ccd.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "collision/detail/checks.hpp"
#include "collision/distance.hpp"

namespace lumen::collision {
namespace {

constexpr double kUnitRoundoff = 0x1p-53;
// Every box bound is a multiple of 2^-kGridBits: then 1 - t, u + v and the bounds are exact in double.
constexpr int kGridBits = 45;
// Smallest parameter width a box is split to.
constexpr double kMinWidth = 0x1p-40;
// Absolute allowance for underflow in the error bounds (far below any physical length or volume).
constexpr double kTiny = 1e-300;

constexpr double kGridScale = 0x1p45, kGridStep = 0x1p-45;  // 2^kGridBits and its inverse (exact)
static_assert(kGridScale == static_cast<double>(1ULL << kGridBits) && kGridScale * kGridStep == 1.0,
              "the grid scale is 2^kGridBits and its step the exact inverse");
double grid_down(double x) { return std::floor(x * kGridScale) * kGridStep; }
double grid_up(double x) { return std::ceil(x * kGridScale) * kGridStep; }
double grid_mid(double a, double b) { return grid_down(0.5 * (a + b)); }

// The contact function F(t, u, v) = d(t) + u e(t) + v f(t), each term linear in t:
// x(t) = (1 - t) x0 + t x1. vf: d = p - a, e = a - b, f = a - c (so F = p - (a + u (b-a) + v (c-a)));
// ee: d = a - c, e = b - a, f = c - d (so F = (a + u (b-a)) - (c + v (d-c))).
// F = 0 for some (u, v) in the domain needs the coplanarity cubic g(t) = det(e(t), f(t), d(t)) = 0.
struct Problem {
  double d0[3], d1[3], e0[3], e1[3], f0[3], f1[3];  // per axis, metres
  double eps[3];          // bound of the rounding error of each computed coordinate of F, metres
  double eps_det = 0.0;   // bound of the rounding error of one computed determinant of the cubic, m^3
  double eps_cross = 0.0; // bound of the rounding error of one computed coordinate of e x f, m^2
  bool simplex = false;   // vf: (u, v) restricted to the triangle u, v >= 0, u + v <= 1
  double gap = 0.0;       // contact distance, metres
  double tolerance = 0.0; // acceptance width, metres
};

// A parameter box [t0,t1] x [u0,u1] x [v0,v1] with the bounds of F over it.
struct Box {
  double t0, t1, u0, u1, v0, v1;
  double lo[3], hi[3];  // computed range of F (not yet inflated by eps)
  double ct, cu, cv;    // how much t, u, v each widen the range (max over the coordinates)
  int depth;            // number of splits from the whole domain
};

// Values of F at the evaluation points of a box (the domain vertices at t0 and t1) and the box centre.
struct Corners {
  int n = 0;           // number of points
  double x[10][3];     // computed F at each point, metres
  double tc, uc, vc;   // centre of the box (inside the domain)
};

// Earliest lower t first; among equal t, the narrower in t, then the deeper box first (depth-first
// towards a contact, also when a whole curve of contacts shares the earliest t).
struct Later {
  bool operator()(const Box& a, const Box& b) const {
    if (a.t0 != b.t0) return a.t0 > b.t0;
    if (a.t1 != b.t1) return a.t1 > b.t1;
    return a.depth < b.depth;
  }
};

double det3(const double* x, const double* y, const double* z) {
  return x[0] * (y[1] * z[2] - y[2] * z[1]) + x[1] * (y[2] * z[0] - y[0] * z[2]) +
         x[2] * (y[0] * z[1] - y[1] * z[0]);
}

// Fills the differences of the four points and the error bounds. Returns false if a difference
// overflowed (then the caller reports a conservative contact).
//
// Error bound of F: with u the unit roundoff and D the largest |computed difference| on an axis, the
// difference itself is off by <= u |exact|; x(t) = (1-t) x0 + t x1 (t, 1-t exact) adds <= 2uD (so
// x(t) is off by <= 3uD); u e(t) and v f(t) add <= uD each (<= 4uD each); the two sums add <= 2uD and
// <= 3uD. Hence |computed F - F| <= 16 u D (+ O(u^2) D); we use 32 u D plus an underflow allowance.
// Error bound of a determinant det(x, y, z) of vectors at some t (each coordinate off by <= 3uD_axis,
// |coordinate| <= D_axis): each of the 6 products of one coordinate per axis is <= P = Dx Dy Dz, is off
// by <= 9uP from the inputs and 2uP from its roundings, and the sums add <= 5 * 6uP: <= 96uP in all;
// we use 128 u P (and three times that for the sum of three determinants). A coordinate of e x f (two
// products of coordinates off by <= 3u each, one difference) is off by <= 16 u E F: we use 32 u E F.
bool setup(const Vec3& d0, const Vec3& d1, const Vec3& e0, const Vec3& e1, const Vec3& f0,
           const Vec3& f1, Problem& pb) {
  double prod = 1.0, emax = 0.0, fmax = 0.0;
  for (int j = 0; j < 3; ++j) {
    emax = std::max({emax, std::abs(e0[j]), std::abs(e1[j])});
    fmax = std::max({fmax, std::abs(f0[j]), std::abs(f1[j])});
    pb.d0[j] = d0[j];
    pb.d1[j] = d1[j];
    pb.e0[j] = e0[j];
    pb.e1[j] = e1[j];
    pb.f0[j] = f0[j];
    pb.f1[j] = f1[j];
    const double m = std::max({std::abs(d0[j]), std::abs(d1[j]), std::abs(e0[j]), std::abs(e1[j]),
                               std::abs(f0[j]), std::abs(f1[j])});
    if (!std::isfinite(m)) return false;
    pb.eps[j] = 32.0 * kUnitRoundoff * m + kTiny;
    prod *= m;
  }
  pb.eps_det = 128.0 * kUnitRoundoff * prod + kTiny;
  pb.eps_cross = 32.0 * kUnitRoundoff * emax * fmax + kTiny;
  return std::isfinite(pb.eps_det);
}

// d, e, f at time t (t on the grid, so 1 - t is exact).
void at_time(const Problem& pb, double t, double* D, double* E, double* F) {
  const double s = 1.0 - t;
  for (int j = 0; j < 3; ++j) {
    D[j] = s * pb.d0[j] + t * pb.d1[j];
    E[j] = s * pb.e0[j] + t * pb.e1[j];
    F[j] = s * pb.f0[j] + t * pb.f1[j];
  }
}

// Bernstein coefficients of the coplanarity cubic over [t0, t1] from d, e, f at both ends (blossoming);
// the middle two are multiplied by 3.
void cubic_bernstein(const double D[2][3], const double E[2][3], const double F[2][3], double b[4]) {
  b[0] = det3(E[0], F[0], D[0]);
  b[1] = det3(E[1], F[0], D[0]) + det3(E[0], F[1], D[0]) + det3(E[0], F[0], D[1]);
  b[2] = det3(E[0], F[1], D[1]) + det3(E[1], F[0], D[1]) + det3(E[1], F[1], D[0]);
  b[3] = det3(E[1], F[1], D[1]);
}

// True when the coplanarity cubic proves |F| > gap over [t0, t1] (d, e, f given at both ends): g / |e x f|
// is the signed distance of the point from the face plane (vf) or between the two lines (ee), a lower
// bound of |F|. With N >= |e x f| over the interval (from the Bernstein coefficients of the quadratic
// e x f), all Bernstein coefficients of g beyond gap N + their error bound on one side of zero mean
// |g| > gap |e x f| throughout. For gap = 0: no coplanarity, so no contact.
bool cubic_excludes(const Problem& pb, const double D[2][3], const double E[2][3], const double F[2][3]) {
  double b[4];
  cubic_bernstein(D, E, F, b);
  double shift = 0.0;
  if (pb.gap > 0.0) {
    // Bernstein coefficients of e x f: E0 x F0, (E0 x F1 + E1 x F0) / 2, E1 x F1; largest per axis.
    double n2 = 0.0;
    for (int j = 0; j < 3; ++j) {
      const int p = (j + 1) % 3, q = (j + 2) % 3;
      const double c0 = E[0][p] * F[0][q] - E[0][q] * F[0][p];
      const double c2 = E[1][p] * F[1][q] - E[1][q] * F[1][p];
      const double c1 = 0.5 * ((E[0][p] * F[1][q] - E[0][q] * F[1][p]) + (E[1][p] * F[0][q] - E[1][q] * F[0][p]));
      const double m = std::max({std::abs(c0), std::abs(c1), std::abs(c2)}) + pb.eps_cross;
      n2 += m * m;
    }
    shift = pb.gap * std::sqrt(n2) * (1.0 + 1e-12);
  }
  const double e = pb.eps_det + shift, e3 = 3.0 * e;
  if (b[0] > e && b[1] > e3 && b[2] > e3 && b[3] > e) return true;
  if (b[0] < -e && b[1] < -e3 && b[2] < -e3 && b[3] < -e) return true;
  return false;
}

// Range of F over the box (vf: box clipped to the triangle), and the widening due to each parameter;
// the values it is made of go to `cs`. With `cubic`, also tests the coplanarity cubic over [t0, t1].
// Returns false when the box is empty or provably free of contact by the cubic.
bool evaluate(const Problem& pb, Box& b, bool cubic, Corners& cs) {
  // F's coefficient vectors at the two bounding times.
  double D[2][3], E[2][3], F[2][3];
  at_time(pb, b.t0, D[0], E[0], F[0]);
  at_time(pb, b.t1, D[1], E[1], F[1]);
  if (cubic && cubic_excludes(pb, D, E, F)) return false;
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
        // Edges are axis-aligned: the crossing of u + v = 1 is exact (grid bounds).
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
  double us = 0.0, vs = 0.0;
  for (int i = 0; i < n; ++i) {
    const double u = uv[i][0], v = uv[i][1];
    us += u;
    vs += v;
    for (int j = 0; j < 3; ++j) {
      const double x0 = D[0][j] + u * E[0][j] + v * F[0][j];
      const double x1 = D[1][j] + u * E[1][j] + v * F[1][j];
      cs.x[2 * i][j] = x0;
      cs.x[2 * i + 1][j] = x1;
      lo[j] = std::min(lo[j], std::min(x0, x1));
      hi[j] = std::max(hi[j], std::max(x0, x1));
      ct = std::max(ct, std::abs(x1 - x0));
    }
  }
  cs.n = 2 * n;
  cs.tc = 0.5 * (b.t0 + b.t1);
  cs.uc = us / n;
  cs.vc = vs / n;
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
bool axis_excludes(const Problem& pb, const Box& b) {
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

// True when the inflated range is narrower than the tolerance in every coordinate, or (gap > 0) lies
// entirely within the gap: the box is accepted as a contact.
bool accepted(const Problem& pb, const Box& b) {
  bool narrow = true;
  for (int j = 0; j < 3; ++j)
    if (b.hi[j] - b.lo[j] + 2.0 * pb.eps[j] > pb.tolerance) narrow = false;
  if (narrow || pb.gap == 0.0) return narrow;
  double r2 = 0.0;
  for (int j = 0; j < 3; ++j) {
    const double s = (std::max(std::abs(b.lo[j]), std::abs(b.hi[j])) + pb.eps[j]) / pb.gap;
    r2 += s * s;
  }
  return r2 < 1.0 - 1e-12;
}

// Jacobian of F at (t, u, v): columns dF/dt = d' + u e' + v f', e(t), f(t).
void jacobian(const Problem& pb, double t, double u, double v, double J[3][3]) {
  const double s = 1.0 - t;
  for (int j = 0; j < 3; ++j) {
    J[j][0] = (pb.d1[j] - pb.d0[j]) + u * (pb.e1[j] - pb.e0[j]) + v * (pb.f1[j] - pb.f0[j]);
    J[j][1] = s * pb.e0[j] + t * pb.e1[j];
    J[j][2] = s * pb.f0[j] + t * pb.f1[j];
  }
}

// Adjugate of a 3 x 3 matrix (inverse times determinant).
void adjugate(const double J[3][3], double A[3][3]) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const int r0 = (j + 1) % 3, r1 = (j + 2) % 3, c0 = (i + 1) % 3, c1 = (i + 2) % 3;
      A[i][j] = J[r0][c0] * J[r1][c1] - J[r0][c1] * J[r1][c0];
    }
}

// True when G = A F, A = the adjugate of the Jacobian at the box centre, provably stays farther than
// gap from the origin over the box: then F does too (G = 0 for F = 0, |G_i| <= |A_i| |F|). G is
// multilinear like F, so its range is the hull of A times the computed corner values of F; each G_i is
// off by <= sum_j |A_ij| (eps_j + 4u |F_j|) (the product by A adds <= 3u sum_j |A_ij F_j|).
bool precond_excludes(const Problem& pb, const Corners& cs) {
  double J[3][3], A[3][3];
  jacobian(pb, cs.tc, cs.uc, cs.vc, J);
  adjugate(J, A);
  double fmax[3] = {0.0, 0.0, 0.0};
  for (int c = 0; c < cs.n; ++c)
    for (int j = 0; j < 3; ++j) fmax[j] = std::max(fmax[j], std::abs(cs.x[c][j]));
  for (int i = 0; i < 3; ++i) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (int c = 0; c < cs.n; ++c) {
      const double g = A[i][0] * cs.x[c][0] + A[i][1] * cs.x[c][1] + A[i][2] * cs.x[c][2];
      lo = std::min(lo, g);
      hi = std::max(hi, g);
    }
    double err = 0.0;
    for (int j = 0; j < 3; ++j) err += std::abs(A[i][j]) * (pb.eps[j] + 4.0 * kUnitRoundoff * fmax[j]);
    err = err * (1.0 + 1e-12) + kTiny;
    if (pb.gap > 0.0) {
      const double row = std::sqrt(A[i][0] * A[i][0] + A[i][1] * A[i][1] + A[i][2] * A[i][2]);
      err += row * pb.gap * (1.0 + 1e-12);
    }
    if (lo > err || hi < -err) return true;
  }
  return false;
}

// Rigorous proof that F has a zero in the box (inside the domain), by the Poincare-Miranda theorem
// applied to G = A F for a preconditioner A ~ the inverse Jacobian (any nonsingular A works; G is
// multilinear, so the sign of each G_k on a face is decided by the face's 4 corners).
bool miranda(const Problem& pb, const Box& b, const double A[3][3]) {
  // A must be provably nonsingular: |det A| beyond its rounding error bound.
  {
    const double det = det3(A[0], A[1], A[2]);
    double mag = 0.0;
    for (int i = 0; i < 3; ++i)
      mag += std::abs(A[0][i]) * (std::abs(A[1][(i + 1) % 3] * A[2][(i + 2) % 3]) +
                                  std::abs(A[1][(i + 2) % 3] * A[2][(i + 1) % 3]));
    if (!(std::abs(det) > 16.0 * kUnitRoundoff * mag + kTiny)) return false;
  }
  // F at the 8 corners (computed), and its largest magnitude per coordinate.
  double Fc[8][3], fmax[3] = {0.0, 0.0, 0.0};
  double D[2][3], E[2][3], F[2][3];
  at_time(pb, b.t0, D[0], E[0], F[0]);
  at_time(pb, b.t1, D[1], E[1], F[1]);
  for (int c = 0; c < 8; ++c) {
    const int k = c & 1;
    const double u = (c & 2) ? b.u1 : b.u0, v = (c & 4) ? b.v1 : b.v0;
    for (int j = 0; j < 3; ++j) {
      Fc[c][j] = D[k][j] + u * E[k][j] + v * F[k][j];
      fmax[j] = std::max(fmax[j], std::abs(Fc[c][j]));
    }
  }
  // G = A F at the corners, with the bound of its error: sum_j |A_ij| (eps_j + 4u |F_j|).
  double G[8][3], gerr[3];
  for (int i = 0; i < 3; ++i) {
    gerr[i] = 0.0;
    for (int j = 0; j < 3; ++j)
      gerr[i] += std::abs(A[i][j]) * (pb.eps[j] + 4.0 * kUnitRoundoff * fmax[j]);
    gerr[i] = gerr[i] * (1.0 + 1e-12) + kTiny;
  }
  for (int c = 0; c < 8; ++c)
    for (int i = 0; i < 3; ++i) G[c][i] = A[i][0] * Fc[c][0] + A[i][1] * Fc[c][1] + A[i][2] * Fc[c][2];
  // Component k must have one strict sign on the face param_k = lo and the other on param_k = hi.
  for (int k = 0; k < 3; ++k) {
    const int bit = 1 << k;
    bool lo_neg = true, lo_pos = true, hi_neg = true, hi_pos = true;
    for (int c = 0; c < 8; ++c) {
      const double g = G[c][k];
      const bool neg = g < -gerr[k], pos = g > gerr[k];
      if (c & bit) { hi_neg &= neg; hi_pos &= pos; }
      else { lo_neg &= neg; lo_pos &= pos; }
    }
    if (!((lo_neg && hi_pos) || (lo_pos && hi_neg))) return false;
  }
  return true;
}

// Real roots in [0, 1] of the cubic with Bernstein coefficients b (middle ones times 3), ascending.
// Floating-point estimates only (used to place the box that `miranda` then certifies).
int cubic_roots(const double b[4], double roots[3]) {
  // Power form c0 + c1 t + c2 t^2 + c3 t^3.
  const double b0 = b[0], b1 = b[1] / 3.0, b2 = b[2] / 3.0, b3 = b[3];
  const double c0 = b0, c1 = 3.0 * (b1 - b0), c2 = 3.0 * (b0 - 2.0 * b1 + b2),
               c3 = b3 - b0 + 3.0 * (b1 - b2);
  auto g = [&](double t) { return ((c3 * t + c2) * t + c1) * t + c0; };
  auto dg = [&](double t) { return (3.0 * c3 * t + 2.0 * c2) * t + c1; };
  // Monotone pieces split at the critical points in (0, 1).
  double cuts[4] = {0.0, 0.0, 0.0, 0.0};
  int nc = 1;
  const double qa = 3.0 * c3, qb = 2.0 * c2, qc = c1;
  if (qa != 0.0) {
    const double disc = qb * qb - 4.0 * qa * qc;
    if (disc > 0.0) {
      const double sq = std::sqrt(disc);
      const double q = -0.5 * (qb + std::copysign(sq, qb));
      double r[2] = {q / qa, q != 0.0 ? qc / q : 0.0};
      if (r[0] > r[1]) std::swap(r[0], r[1]);
      for (double x : r)
        if (x > 0.0 && x < 1.0 && x > cuts[nc - 1]) cuts[nc++] = x;
    }
  } else if (qb != 0.0) {
    const double x = -qc / qb;
    if (x > 0.0 && x < 1.0) cuts[nc++] = x;
  }
  cuts[nc++] = 1.0;
  int n = 0;
  for (int i = 0; i + 1 < nc; ++i) {
    double lo = cuts[i], hi = cuts[i + 1];
    double glo = g(lo), ghi = g(hi);
    if (glo == 0.0) {
      if (n == 0 || roots[n - 1] != lo) roots[n++] = lo;
      continue;
    }
    if (ghi == 0.0) {
      roots[n++] = hi;
      continue;
    }
    if ((glo < 0.0) == (ghi < 0.0)) continue;
    // Safeguarded Newton inside the bracket.
    double x = 0.5 * (lo + hi);
    for (int it = 0; it < 60; ++it) {
      const double gx = g(x);
      if (gx == 0.0) break;
      if ((gx < 0.0) == (glo < 0.0)) lo = x;
      else hi = x;
      const double d = dg(x);
      double xn = d != 0.0 ? x - gx / d : 0.5 * (lo + hi);
      if (!(xn > lo && xn < hi)) xn = 0.5 * (lo + hi);
      if (std::abs(xn - x) <= 1e-14 || hi - lo <= 1e-14) {
        x = xn;
        break;
      }
      x = xn;
    }
    if (n == 0 || roots[n - 1] != x) roots[n++] = x;
  }
  return n;
}

// Dot products of d, e, f at time t: the normal equations of min |d + u e + v f|.
void normal_sums(const Problem& pb, double t, double& ee, double& ef, double& ff, double& ed, double& fd) {
  double D[3], E[3], F[3];
  at_time(pb, t, D, E, F);
  ee = ef = ff = ed = fd = 0.0;
  for (int j = 0; j < 3; ++j) {
    ee += E[j] * E[j];
    ef += E[j] * F[j];
    ff += F[j] * F[j];
    ed += E[j] * D[j];
    fd += F[j] * D[j];
  }
}

// (u, v) minimising |d + u e + v f| at time t (floating-point estimate).
bool closest_uv(const Problem& pb, double t, double& u, double& v) {
  double ee, ef, ff, ed, fd;
  normal_sums(pb, t, ee, ef, ff, ed, fd);
  const double det = ee * ff - ef * ef;
  if (!(det > 1e-12 * ee * ff) || !std::isfinite(det)) return false;
  u = (-ed * ff + fd * ef) / det;
  v = (-fd * ee + ed * ef) / det;
  return std::isfinite(u) && std::isfinite(v);
}

// Tries to certify a contact near the cubic root t: a small box around (t, u, v) proven by Miranda to
// hold a zero of F. The box may reach outside the domain by `out` per parameter (so that each coordinate
// of F changes by at most 3/8 tolerance to the nearest domain point): a zero there is a contact within
// tolerance. On success sets the box (its t0 then bounds the time of contact from below once [0, t0] is
// searched) and the contact (u, v).
//
// Box size: F = F(x) + J (y - x) + (t' - t)(u' - u) e' + (t' - t)(v' - v) f' exactly (F is multilinear),
// so with A = J^-1, G_t = A F varies on a t face by about rt (ru |(A e')_t| + rv |(A f')_t|) against its
// offset rt: ru, rv are kept below 1 / (4 |(A e')_t|), 1 / (4 |(A f')_t|); likewise rt for the u and v
// components. rt also keeps the motion of each coordinate of F over the box within tolerance / 4.
bool certify_near(const Problem& pb, double t, Box& cert, double& uc, double& vc) {
  double u, v;
  if (!closest_uv(pb, t, u, v)) return false;
  // Preconditioner: the inverse Jacobian (adjugate / determinant) at the estimated root.
  double J[3][3], A[3][3];
  jacobian(pb, t, u, v, J);
  adjugate(J, A);
  const double detj = J[0][0] * A[0][0] + J[0][1] * A[1][0] + J[0][2] * A[2][0];
  if (!(std::abs(detj) > 0.0) || !std::isfinite(detj)) return false;
  // Allowed reach outside the domain, in parameter units.
  double emax = 0.0;
  for (int j = 0; j < 3; ++j) emax = std::max({emax, std::abs(J[j][1]), std::abs(J[j][2])});
  const double out = std::min(1.0 / 64.0, 0.125 * pb.tolerance / std::max(emax, 1e-300));
  // Room around (u, v) inside the extended domain.
  double ru, rv;
  if (pb.simplex) {
    const double w = 1.0 + out - u - v;
    if (!(u > -out && v > -out && w > 0.0)) return false;
    ru = 0.5 * std::min(u + out, w);
    rv = 0.5 * std::min(v + out, w);
  } else {
    if (!(u > -out && u < 1.0 + out && v > -out && v < 1.0 + out)) return false;
    ru = 0.5 * std::min(u + out, 1.0 + out - u);
    rv = 0.5 * std::min(v + out, 1.0 + out - v);
  }
  double w[3], z[3];  // A e', A f' with A = J^-1
  for (int i = 0; i < 3; ++i) {
    w[i] = z[i] = 0.0;
    for (int j = 0; j < 3; ++j) {
      w[i] += A[i][j] * (pb.e1[j] - pb.e0[j]);
      z[i] += A[i][j] * (pb.f1[j] - pb.f0[j]);
    }
    w[i] /= detj;
    z[i] /= detj;
  }
  ru = std::min(ru, 0.25 / std::max(std::abs(w[0]), 1e-300));
  rv = std::min(rv, 0.25 / std::max(std::abs(z[0]), 1e-300));
  // Time half-width: F moves by at most tolerance / 4 over the box, and the cross terms stay small.
  double speed = 0.0;
  for (int j = 0; j < 3; ++j) speed = std::max(speed, std::abs(J[j][0]));
  double rt = std::min(0.0625, 0.125 * pb.tolerance / std::max(speed, 1e-300));
  rt = std::min(rt, 0.25 * ru / std::max(ru * std::abs(w[1]) + rv * std::abs(z[1]), 1e-300));
  rt = std::min(rt, 0.25 * rv / std::max(ru * std::abs(w[2]) + rv * std::abs(z[2]), 1e-300));
  rt = std::max(rt, kMinWidth);
  cert.t0 = std::max(0.0, grid_down(t - rt));
  cert.t1 = std::min(1.0, grid_up(t + rt));
  cert.u0 = grid_up(u - ru);
  cert.u1 = grid_down(u + ru);
  cert.v0 = grid_up(v - rv);
  cert.v1 = grid_down(v + rv);
  if (!(cert.t0 < t && t < cert.t1 && cert.u0 < u && u < cert.u1 && cert.v0 < v && v < cert.v1))
    return false;
  if (!miranda(pb, cert, A)) return false;
  // Contact parameters: the estimate, moved into the domain.
  uc = std::min(1.0, std::max(0.0, u));
  vc = std::min(1.0, std::max(0.0, v));
  if (pb.simplex && uc + vc > 1.0) {
    const double sum = uc + vc;
    uc /= sum;
    vc /= sum;
  }
  return true;
}

// (u, v) in the domain closest to contact at time t: minimiser of |d + u e + v f| over the triangle
// (vf) or the unit square (ee), floating-point estimate: the interior stationary point if inside, else
// the best of the clamped minimisers along each side.
void closest_in_domain(const Problem& pb, double t, double& u, double& v) {
  double ee, ef, ff, ed, fd;
  normal_sums(pb, t, ee, ef, ff, ed, fd);
  auto inside = [&](double x, double y) {
    return x >= 0.0 && y >= 0.0 && (pb.simplex ? x + y <= 1.0 : (x <= 1.0 && y <= 1.0));
  };
  const double det = ee * ff - ef * ef;
  if (det > 1e-14 * ee * ff && std::isfinite(det)) {
    const double x = (-ed * ff + fd * ef) / det, y = (-fd * ee + ed * ef) / det;
    if (inside(x, y)) {
      u = x;
      v = y;
      return;
    }
  }
  // Squared distance (up to the constant |d|^2) at (x, y).
  auto q = [&](double x, double y) {
    return x * x * ee + y * y * ff + 2.0 * (x * y * ef + x * ed + y * fd);
  };
  auto clamp01 = [](double x) { return std::min(1.0, std::max(0.0, x)); };
  // Sides as segments (x0, y0) + s (dx, dy), s in [0, 1].
  double sides[4][4];
  int ns = 0;
  if (pb.simplex) {
    const double s3[3][4] = {{0, 0, 1, 0}, {0, 0, 0, 1}, {1, 0, -1, 1}};
    for (auto& s : s3) std::copy(s, s + 4, sides[ns++]);
  } else {
    const double s4[4][4] = {{0, 0, 1, 0}, {0, 0, 0, 1}, {1, 0, 0, 1}, {0, 1, 1, 0}};
    for (auto& s : s4) std::copy(s, s + 4, sides[ns++]);
  }
  double best = std::numeric_limits<double>::infinity();
  u = v = 0.0;
  for (int i = 0; i < ns; ++i) {
    const double x0 = sides[i][0], y0 = sides[i][1], dx = sides[i][2], dy = sides[i][3];
    // d/ds of q along the side: a s + b = 0.
    const double a = dx * dx * ee + dy * dy * ff + 2.0 * dx * dy * ef;
    const double b = x0 * dx * ee + y0 * dy * ff + (x0 * dy + y0 * dx) * ef + dx * ed + dy * fd;
    const double s = a > 0.0 ? clamp01(-b / a) : 0.0;
    const double x = x0 + s * dx, y = y0 + s * dy, val = q(x, y);
    if (val < best) {
      best = val;
      u = x;
      v = y;
    }
  }
  if (pb.simplex && u + v > 1.0) {
    const double sum = u + v;
    u /= sum;
    v /= sum;
  }
}

// True when F(t, u, v) ((u, v) in the domain, t on the grid) provably has |F| <= gap + allowance: the
// primitives are in contact (within the allowance) at time t.
bool witness(const Problem& pb, double t, double u, double v, double allowance) {
  double D[3], E[3], F[3];
  at_time(pb, t, D, E, F);
  double r2 = 0.0;
  for (int j = 0; j < 3; ++j) {
    const double x = std::abs(D[j] + u * E[j] + v * F[j]) + pb.eps[j];
    r2 += x * x;
  }
  const double limit = pb.gap + allowance;
  return r2 * (1.0 + 1e-12) <= limit * limit;
}

// Contact parameters reported for an accepted box: its (u, v) centre, inside the triangle for vf.
void report(const Problem& pb, double toi, double u, double v, bool bounded, int boxes, CcdHit* hit) {
  if (hit == nullptr) return;
  if (pb.simplex && u + v > 1.0) {
    const double sum = u + v;
    u /= sum;
    v /= sum;
  }
  hit->toi = toi;
  hit->s = u;
  hit->t = v;
  hit->boxes = boxes;
  hit->bounded = bounded;
}

// A fixed direction n for narrowing a box in t: |n.F| > band at a computed value x of F proves |F| > gap
// there, for all x with |x_j| <= fmax_j (|n| <= 1 + 4u; n.x is off by <= sum_j |n_j| (eps_j + 4u |x_j|)).
struct Direction {
  double n[3];
  int axis;     // 0, 1, 2 for a coordinate axis (then n.x = x_axis exactly), -1 otherwise
  double band;  // for the values of the box the direction was made for
};

double project(const Direction& d, const double* x) {
  return d.axis >= 0 ? x[d.axis] : d.n[0] * x[0] + d.n[1] * x[1] + d.n[2] * x[2];
}

double band_for(const Problem& pb, const Direction& d, const double* fmax) {
  if (d.axis >= 0) return pb.gap + pb.eps[d.axis];
  double err = 0.0;
  for (int j = 0; j < 3; ++j) err += std::abs(d.n[j]) * (pb.eps[j] + 4.0 * kUnitRoundoff * fmax[j]);
  return (pb.gap + err) * (1.0 + 1e-12) + kTiny;
}

// Largest |computed F_j| over the points of cs, raised to at least fmax_j.
void largest(const Corners& cs, double* fmax) {
  for (int c = 0; c < cs.n; ++c)
    for (int j = 0; j < 3; ++j) fmax[j] = std::max(fmax[j], std::abs(cs.x[c][j]));
}

// Directions to narrow along: the axes, F at the box centre and its parts orthogonal to e and to f
// (normalised), with their bands for the values of cs. Returns their number.
int narrowing_directions(const Problem& pb, const Corners& cs, Direction* dirs) {
  int nd = 0;
  for (int j = 0; j < 3; ++j)
    dirs[nd++] = Direction{{j == 0 ? 1.0 : 0.0, j == 1 ? 1.0 : 0.0, j == 2 ? 1.0 : 0.0}, j, pb.gap + pb.eps[j]};
  double D[3], E[3], F[3], fc[3], fmax[3] = {0.0, 0.0, 0.0};
  largest(cs, fmax);
  at_time(pb, cs.tc, D, E, F);
  for (int j = 0; j < 3; ++j) fc[j] = D[j] + cs.uc * E[j] + cs.vc * F[j];
  auto add = [&](const double* w) {
    const double len2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
    if (!(len2 > 0.0) || !std::isfinite(len2)) return;
    const double inv = 1.0 / std::sqrt(len2);
    Direction& d = dirs[nd++];
    d = Direction{{w[0] * inv, w[1] * inv, w[2] * inv}, -1, 0.0};
    d.band = band_for(pb, d, fmax);
  };
  add(fc);
  for (const double* w : {E, F}) {
    const double ww = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
    if (!(ww > 0.0)) continue;
    const double k = (fc[0] * w[0] + fc[1] * w[1] + fc[2] * w[2]) / ww;
    const double n[3] = {fc[0] - k * w[0], fc[1] - k * w[1], fc[2] - k * w[2]};
    add(n);
  }
  return nd;
}

// True when n.F keeps one strict sign beyond `band` at the given points of a and of b (the values at
// t0 when parity is 0, at t1 when it is 1).
bool one_sign(const Direction& d, double band, const Corners& a, int parity_a, const Corners& b,
              int parity_b) {
  bool pos = true, neg = true;
  for (int c = parity_a; c < a.n; c += 2) {
    const double x = project(d, a.x[c]);
    pos &= x > band;
    neg &= x < -band;
  }
  for (int c = parity_b; c < b.n; c += 2) {
    const double x = project(d, b.x[c]);
    pos &= x > band;
    neg &= x < -band;
  }
  return pos || neg;
}

// Narrows the box in t: along a fixed direction n, n.F is linear in t at every domain vertex, so the
// times where it provably stays beyond gap with one sign at all vertices can be cut off at both ends.
// The cut [t0, t0'] is verified from the values at t0 and t0' (the range over it is their hull),
// likewise [t1', t1]. Replaces b and cs by the narrowed box when that removes at least 1/16 of it.
void narrow_t(const Problem& pb, Box& b, Corners& cs, const Direction* dirs, int nd, bool cubic,
              int& boxes) {
  // Predicted cut times (floating point), as fractions of the t width.
  double lo_cut = 0.0, hi_cut = 1.0;
  for (int k = 0; k < nd; ++k) {
    double first = 1.0, last = 0.0;  // first time a vertex enters the band, last time one leaves it
    bool pos0 = true, neg0 = true, pos1 = true, neg1 = true;
    const double e = dirs[k].band;
    for (int c = 0; c < cs.n; c += 2) {
      const double x0 = project(dirs[k], cs.x[c]), x1 = project(dirs[k], cs.x[c + 1]);
      pos0 &= x0 > e; neg0 &= x0 < -e; pos1 &= x1 > e; neg1 &= x1 < -e;
      // Fraction s in [0, 1] where x0 + s (x1 - x0) reaches the band [-e, e].
      if (x0 > e && x1 <= e) first = std::min(first, (x0 - e) / (x0 - x1));
      else if (x0 < -e && x1 >= -e) first = std::min(first, (x0 + e) / (x0 - x1));
      if (x1 > e && x0 <= e) last = std::max(last, (e - x0) / (x1 - x0));
      else if (x1 < -e && x0 >= -e) last = std::max(last, (-e - x0) / (x1 - x0));
    }
    if (pos0 || neg0) lo_cut = std::max(lo_cut, first);
    if (pos1 || neg1) hi_cut = std::min(hi_cut, last);
  }
  const double w = b.t1 - b.t0;
  const double ta = std::max(b.t0, grid_down(b.t0 + 0.999 * lo_cut * w));
  const double tb = std::min(b.t1, grid_up(b.t0 + (hi_cut + 0.001 * (1.0 - hi_cut)) * w));
  if (!(ta - b.t0 >= 0.0625 * w || b.t1 - tb >= 0.0625 * w)) return;
  if (!(ta < tb)) return;  // a full cut is left to the regular splitting
  // Evaluate the narrowed box and verify both cut-off parts.
  Box nb = b;
  nb.t0 = ta;
  nb.t1 = tb;
  Corners ncs;
  ++boxes;
  if (!evaluate(pb, nb, cubic, ncs)) return;
  // Bands for the values of both boxes.
  double fmax[3] = {0.0, 0.0, 0.0};
  largest(cs, fmax);
  largest(ncs, fmax);
  if (ta > b.t0) {
    bool ok = false;
    for (int k = 0; k < nd && !ok; ++k) ok = one_sign(dirs[k], band_for(pb, dirs[k], fmax), cs, 0, ncs, 0);
    if (!ok) return;
  }
  if (tb < b.t1) {
    bool ok = false;
    for (int k = 0; k < nd && !ok; ++k) ok = one_sign(dirs[k], band_for(pb, dirs[k], fmax), ncs, 1, cs, 1);
    if (!ok) return;
  }
  b = nb;
  cs = ncs;
}

// True when F, projected on one of the non-axis narrowing directions n, provably stays beyond gap with
// one sign over the box: then |F| >= |n.F| / |n| > gap (a separating direction). n along F at the box
// centre is tight near the closest point, where the axis-aligned range is not; its parts orthogonal to
// e and f are tight for parallel edges and for motion along an edge (F then varies along e or f only).
bool direction_excludes(const Corners& cs, const Direction* dirs, int nd) {
  for (int k = 3; k < nd; ++k) {
    bool pos = true, neg = true;
    const double e = dirs[k].band;
    for (int c = 0; c < cs.n && (pos || neg); ++c) {
      const double x = project(dirs[k], cs.x[c]);
      pos &= x > e;
      neg &= x < -e;
    }
    if (pos || neg) return true;
  }
  return false;
}

// True when the box is provably free of contact: its range, its preconditioned range or a separating
// direction; the directions tried are left in dirs (for narrow_t).
bool box_excluded(const Problem& pb, const Box& b, const Corners& cs, Direction* dirs, int& nd) {
  nd = 0;
  if (axis_excludes(pb, b) || precond_excludes(pb, cs)) return true;
  nd = narrowing_directions(pb, cs, dirs);
  return direction_excludes(cs, dirs, nd);
}

// The running state of one solve: the work spent, the whole-domain box and the upper bound of the time
// of contact found by the fast path (t_hi > 1: none yet), with the contact parameters there and the time
// t_stop before which the search still has to look.
struct SolveState {
  Corners cs;
  int boxes = 1;
  Box root{0.0, 1.0, 0.0, 1.0, 0.0, 1.0, {}, {}, 0.0, 0.0, 0.0, 0};
  double D[2][3], E[2][3], F[2][3];  // d, e, f at t = 0 and t = 1
  double t_hi = 2.0, hit_u = 0.0, hit_v = 0.0, t_stop = 1.0;
  double rt = 0.0;  // time step over which each coordinate of F moves by at most tolerance / 2
};

// Phase 1, set-up and bounds: true when the whole domain is excluded by the swept bounding box of F,
// the coplanarity cubic over [0, 1] or the preconditioned range; otherwise leaves rt set.
bool whole_domain_excluded(const Problem& pb, SolveState& st) {
  evaluate(pb, st.root, false, st.cs);
  if (axis_excludes(pb, st.root)) return true;
  at_time(pb, 0.0, st.D[0], st.E[0], st.F[0]);
  at_time(pb, 1.0, st.D[1], st.E[1], st.F[1]);
  if (cubic_excludes(pb, st.D, st.E, st.F) || precond_excludes(pb, st.cs)) return true;
  st.rt = std::max(kMinWidth, std::min(1.0, 0.5 * pb.tolerance / std::max(st.root.ct, 1e-300)));
  return false;
}

// Phase 2a, fast path at the roots of the cubic: an upper bound t_hi of the time of contact (a contact
// within tolerance at or before it) from a transversal crossing certified by Miranda at a root of the
// cubic; then only [0, t_stop] is left to search, t_stop = t_hi - rt (each coordinate of F moves by at
// most tolerance / 2 in rt), and t_stop is the toi if that is clean. Roots where the contact lies on the
// boundary of the domain or is tangential cannot be certified by Miranda: there a witness point within
// gap (up to rounding: 8 max eps) at the root time bounds the toi instead.
void bound_from_cubic_roots(const Problem& pb, SolveState& st) {
  const double exact_allowance = 8.0 * std::max({pb.eps[0], pb.eps[1], pb.eps[2]});
  double bern[4], roots[3];
  cubic_bernstein(st.D, st.E, st.F, bern);
  const int nr = cubic_roots(bern, roots);
  Box cert{};
  for (int i = 0; i < nr && st.t_hi > 1.0; ++i) {
    st.boxes += 2;
    if (certify_near(pb, roots[i], cert, st.hit_u, st.hit_v)) {
      st.t_hi = cert.t1;
      st.t_stop = cert.t0;
      break;
    }
    const double t = std::min(1.0, grid_up(roots[i]));
    double u, v;
    closest_in_domain(pb, t, u, v);
    if (witness(pb, t, u, v, exact_allowance)) {
      st.t_hi = t;
      st.t_stop = std::max(0.0, grid_down(t - st.rt));
      st.hit_u = u;
      st.hit_v = v;
    }
  }
}

// Phase 2b, fast path within the gap (gap > 0): the earliest sample time with a witness point within
// gap + tolerance / 2, then regula falsi (Illinois) on the distance towards the first one: t_lo never
// has a witness, t_hi always bounds a contact. True when the contact is at t = 0 (nothing to search).
bool bound_from_gap_witness(const Problem& pb, SolveState& st) {
  const double allowance = 0.5 * pb.tolerance;
  auto excess = [&](double t, double& u, double& v) {  // distance estimate - gap - allowance
    closest_in_domain(pb, t, u, v);
    double D3[3], E3[3], F3[3], r2 = 0.0;
    at_time(pb, t, D3, E3, F3);
    for (int j = 0; j < 3; ++j) {
      const double x = D3[j] + u * E3[j] + v * F3[j];
      r2 += x * x;
    }
    return std::sqrt(r2) - pb.gap - allowance;
  };
  constexpr int kSamples = 8;
  double t_lo = -1.0, f_lo = 0.0, f_hi = 0.0;
  for (int k = 0; k <= kSamples; ++k) {
    const double t = static_cast<double>(k) / kSamples;
    if (t >= st.t_hi) break;
    double u, v;
    ++st.boxes;
    const double f = excess(t, u, v);
    if (witness(pb, t, u, v, allowance)) {
      st.t_hi = t;
      f_hi = f;
      st.hit_u = u;
      st.hit_v = v;
      break;
    }
    t_lo = t;
    f_lo = f;
  }
  if (st.t_hi == 0.0) return true;
  if (st.t_hi > 1.0) return false;
  if (t_lo >= 0.0 && f_hi == 0.0) {
    double u, v;
    f_hi = std::min(0.0, excess(st.t_hi, u, v));
  }
  int kept = 0;  // +1 / -1: how many times in a row t_lo / t_hi was kept
  for (int it = 0; it < 64 && st.t_hi - t_lo > st.rt; ++it) {
    const double w = st.t_hi - std::max(t_lo, 0.0);
    double m = t_lo >= 0.0 && f_lo > f_hi ? t_lo + w * f_lo / (f_lo - f_hi) : st.t_hi - 0.5 * w;
    m = std::min(st.t_hi - 0.0625 * st.rt, std::max(std::max(t_lo, 0.0) + 0.0625 * st.rt, m));
    m = grid_down(m);
    if (!(std::max(t_lo, 0.0) < m && m < st.t_hi)) m = grid_mid(std::max(t_lo, 0.0), st.t_hi);
    if (!(std::max(t_lo, 0.0) < m && m < st.t_hi)) break;
    double u, v;
    ++st.boxes;
    const double f = excess(m, u, v);
    if (witness(pb, m, u, v, allowance)) {
      st.t_hi = m;
      f_hi = std::min(f, 0.0);
      st.hit_u = u;
      st.hit_v = v;
      kept = kept > 0 ? kept + 1 : 1;
      if (kept >= 2) f_lo *= 0.5;
    } else {
      t_lo = m;
      f_lo = std::max(f, 0.0);
      kept = kept < 0 ? kept - 1 : -1;
      if (kept <= -2) f_hi *= 0.5;
    }
  }
  st.t_stop = std::max(0.0, grid_down(st.t_hi - st.rt));
  return false;
}

// Phase 3, the exclusion test of what is left (with an upper bound t_hi and t_stop > 0): true when
// [0, t_stop] x domain is provably free of contact, so that t_stop is the toi; otherwise the root box is
// narrowed to it for the subdivision.
bool nothing_before_stop(const Problem& pb, SolveState& st) {
  st.root.t1 = st.t_stop;
  ++st.boxes;
  Direction dirs[6];
  int nd = 0;
  return !evaluate(pb, st.root, true, st.cs) || box_excluded(pb, st.root, st.cs, dirs, nd);
}

// Phase 4, root finding by subdivision: earliest-t-first bisection of the root box, each child dropped
// when excluded and narrowed in t otherwise. True (and the contact reported) when a box is accepted, a
// witness within the gap is found or the work bound is reached; false when every box was excluded.
bool bisect(const Problem& pb, int max_boxes, SolveState& st, CcdHit* hit) {
  thread_local std::vector<Box> heap;
  heap.clear();
  heap.push_back(st.root);
  double witness_t = -1.0;  // end time of the last witness tried
  while (!heap.empty()) {
    std::pop_heap(heap.begin(), heap.end(), Later{});
    const Box b = heap.back();
    heap.pop_back();
    // Accept: the range is within tolerance, or the box cannot be split further.
    const bool t_min = b.t1 - b.t0 <= kMinWidth, u_min = b.u1 - b.u0 <= kMinWidth,
               v_min = b.v1 - b.v0 <= kMinWidth;
    if (accepted(pb, b) || (t_min && u_min && v_min)) {
      report(pb, b.t0, 0.5 * (b.u0 + b.u1), 0.5 * (b.v0 + b.v1), false, st.boxes, hit);
      return true;
    }
    // gap > 0: when each coordinate of F moves by at most tolerance / 2 over the box's times, a domain
    // point within gap + tolerance / 2 at its end time (found by a closest-point estimate, checked
    // rigorously) makes it a contact; tried once per end time.
    if (pb.gap > 0.0 && b.ct <= 0.5 * pb.tolerance && b.t1 != witness_t) {
      witness_t = b.t1;
      double u, v;
      ++st.boxes;
      closest_in_domain(pb, b.t1, u, v);
      if (witness(pb, b.t1, u, v, 0.5 * pb.tolerance)) {
        report(pb, b.t0, u, v, false, st.boxes, hit);
        return true;
      }
    }
    if (st.boxes >= max_boxes) {
      report(pb, b.t0, 0.5 * (b.u0 + b.u1), 0.5 * (b.v0 + b.v1), true, st.boxes, hit);
      return true;
    }
    // Split the parameter that widens the range most.
    const double ct = t_min ? -1.0 : b.ct, cu = u_min ? -1.0 : b.cu, cv = v_min ? -1.0 : b.cv;
    Box c[2] = {b, b};
    c[0].depth = c[1].depth = b.depth + 1;
    const bool split_t = ct >= cu && ct >= cv;
    if (split_t) {
      const double m = grid_mid(b.t0, b.t1);
      c[0].t1 = m;
      c[1].t0 = m;
    } else if (cu >= cv) {
      const double m = grid_mid(b.u0, b.u1);
      c[0].u1 = m;
      c[1].u0 = m;
    } else {
      const double m = grid_mid(b.v0, b.v1);
      c[0].v1 = m;
      c[1].v0 = m;
    }
    for (Box& child : c) {
      ++st.boxes;
      Direction dirs[6];
      int nd = 0;
      if (!evaluate(pb, child, split_t, st.cs) || box_excluded(pb, child, st.cs, dirs, nd)) continue;
      narrow_t(pb, child, st.cs, dirs, nd, true, st.boxes);
      heap.push_back(child);
      std::push_heap(heap.begin(), heap.end(), Later{});
    }
  }
  return false;
}

// Phase 5, the result when no box was accepted: the contact bounded by the fast path (at t_stop, nothing
// being before it), or no contact.
bool final_result(const Problem& pb, const SolveState& st, CcdHit* hit) {
  if (st.t_hi <= 1.0) {
    report(pb, st.t_stop, st.hit_u, st.hit_v, false, st.boxes, hit);
    return true;
  }
  if (hit != nullptr) {
    *hit = CcdHit{};
    hit->boxes = st.boxes;
  }
  return false;
}

// The elementary test of one problem: set-up and whole-domain bounds, the fast-path upper bound of the
// time of contact, the exclusion of what is before it, the root-finding subdivision, the result.
bool solve(const Problem& pb, int max_boxes, CcdHit* hit) {
  SolveState st;
  if (whole_domain_excluded(pb, st)) return final_result(pb, st, hit);
  bound_from_cubic_roots(pb, st);
  if (pb.gap > 0.0 && bound_from_gap_witness(pb, st)) {
    report(pb, 0.0, st.hit_u, st.hit_v, false, st.boxes, hit);
    return true;
  }
  if (st.t_hi <= 1.0) {
    if (st.t_stop <= 0.0) {
      report(pb, 0.0, st.hit_u, st.hit_v, false, st.boxes, hit);
      return true;
    }
    if (nothing_before_stop(pb, st)) return final_result(pb, st, hit);
  }
  if (bisect(pb, max_boxes, st, hit)) return true;
  return final_result(pb, st, hit);
}

void check_point(const Vec3& x, const char* name) {
  if (!x.allFinite()) {
    std::ostringstream msg;
    msg << "ccd: point " << name << " must be finite, got (" << x[0] << ", " << x[1] << ", " << x[2]
        << ")";
    throw std::invalid_argument(msg.str());
  }
}

// Overflowed differences: report a conservative contact at t = 0.
bool overflow_contact(CcdHit* hit) {
  if (hit != nullptr) *hit = CcdHit{0.0, 0.0, 0.0, 0, true};
  return true;
}

// Separation filter, rigorous for any direction n: the features' projections on n are separated by sep0 at
// t = 0 and can approach by at most `closing` over the frame, so their distance stays >= sep0 - closing.
// first: the points of the first feature (n points away from the second), second: those of the second.
// Directions come from the closest points at t = 0 (any direction is valid; a good one makes it tight).
bool separated(const Vec3* first0, const Vec3* first1, int n_first, const Vec3* second0, const Vec3* second1,
               int n_second, const Vec3& direction, double gap) {
  const double len = direction.norm();
  if (!(len > 0.0) || !std::isfinite(len)) return false;
  const Vec3 n = direction / len;
  double lo_first = std::numeric_limits<double>::infinity(), hi_second = -lo_first;
  double closing_first = 0.0, closing_second = 0.0, scale = 0.0;
  for (int i = 0; i < n_first; ++i) {
    lo_first = std::min(lo_first, n.dot(first0[i]));
    closing_first = std::max(closing_first, -n.dot(first1[i] - first0[i]));
    scale = std::max({scale, first0[i].cwiseAbs().maxCoeff(), first1[i].cwiseAbs().maxCoeff()});
  }
  for (int i = 0; i < n_second; ++i) {
    hi_second = std::max(hi_second, n.dot(second0[i]));
    closing_second = std::max(closing_second, n.dot(second1[i] - second0[i]));
    scale = std::max({scale, second0[i].cwiseAbs().maxCoeff(), second1[i].cwiseAbs().maxCoeff()});
  }
  // Rounding of the projections and of |n| (a few ulps of the coordinates' magnitude), generously bounded.
  const double rounding = 64.0 * std::numeric_limits<double>::epsilon() * scale;
  const double sep_end = (lo_first - hi_second) - closing_first - closing_second;
  return sep_end * (1.0 - 1e-12) - rounding > gap;
}

bool no_contact_hit(CcdHit* hit) {
  if (hit != nullptr) *hit = CcdHit{};
  return false;
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
  // (one branch in the common case; the named check only runs to build the message)
  if (!(p0.allFinite() && a0.allFinite() && b0.allFinite() && c0.allFinite() && p1.allFinite() && a1.allFinite() &&
        b1.allFinite() && c1.allFinite())) {
    check_point(p0, "p0"); check_point(a0, "a0"); check_point(b0, "b0"); check_point(c0, "c0");
    check_point(p1, "p1"); check_point(a1, "a1"); check_point(b1, "b1"); check_point(c1, "c1");
  }
  detail::check_gap(gap, "ccd: gap must be finite and >= 0");
  validate_ccd_options(options);
  // Cheap exit: the vertex stays farther than gap from the face's plane-side along the closest direction.
  {
    const Eigen::Vector3d w = closest_on_triangle(p0, a0, b0, c0);
    const Vec3 face0[3] = {a0, b0, c0}, face1[3] = {a1, b1, c1};
    if (separated(&p0, &p1, 1, face0, face1, 3, p0 - (w[0] * a0 + w[1] * b0 + w[2] * c0), gap))
      return no_contact_hit(hit);
  }
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
  // (one branch in the common case; the named check only runs to build the message)
  if (!(a0.allFinite() && b0.allFinite() && c0.allFinite() && d0.allFinite() && a1.allFinite() && b1.allFinite() &&
        c1.allFinite() && d1.allFinite())) {
    check_point(a0, "a0"); check_point(b0, "b0"); check_point(c0, "c0"); check_point(d0, "d0");
    check_point(a1, "a1"); check_point(b1, "b1"); check_point(c1, "c1"); check_point(d1, "d1");
  }
  detail::check_gap(gap, "ccd: gap must be finite and >= 0");
  validate_ccd_options(options);
  // Cheap exit: the two edges stay farther than gap apart along the direction between their closest points.
  {
    double s = 0.0, t = 0.0;
    segment_segment_closest(a0, b0, c0, d0, s, t);
    const Vec3 e0[2] = {a0, b0}, e1[2] = {a1, b1}, f0[2] = {c0, d0}, f1[2] = {c1, d1};
    if (separated(e0, e1, 2, f0, f1, 2, (a0 + s * (b0 - a0)) - (c0 + t * (d0 - c0)), gap)) return no_contact_hit(hit);
  }
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
