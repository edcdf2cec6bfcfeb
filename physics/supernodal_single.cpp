// Single-precision copy of a supernodal Cholesky factor and its triangular solves
// (physics/detail/supernodal_single.hpp).
#include "physics/detail/supernodal_single.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "physics/detail/messages.hpp"
#include "physics/detail/target_clones.hpp"

namespace lumen::physics::detail {

namespace {

// Validates one supernode of the view: its rows start with its own columns, every row is in range, and its
// diagonal is positive and finite. Returns its largest diagonal entry.
double check_supernode(const SupernodalView& L, int k) {
  const std::string where = "SupernodalSingle: supernode " + std::to_string(k);
  const int c0 = L.super[k], ncol = L.super[k + 1] - c0, nrow = L.pi[k + 1] - L.pi[k];
  if (ncol < 1 || nrow < ncol || c0 < 0 || c0 + ncol > L.n)
    fail(where + " must hold columns in [0, n) and at least as many rows as columns, got " + std::to_string(ncol) +
         " columns from " + std::to_string(c0) + " and " + std::to_string(nrow) + " rows");
  const int* rows = L.s + L.pi[k];
  for (int i = 0; i < nrow; ++i) {
    if (i < ncol && rows[i] != c0 + i)
      fail(where + ": row " + std::to_string(i) + " must be its own column " + std::to_string(c0 + i) + ", got " +
           std::to_string(rows[i]));
    if (rows[i] < 0 || rows[i] >= L.n)
      fail(where + ": row " + std::to_string(i) + " must be in [0, " + std::to_string(L.n) + "), got " +
           std::to_string(rows[i]));
  }
  double largest = 0.0;
  for (int j = 0; j < ncol; ++j) {
    const double d = L.x[L.px[k] + j + static_cast<long>(j) * nrow];
    if (!(d > 0.0) || !std::isfinite(d)) fail_value(where + ": diagonal " + std::to_string(j), "must be > 0", d);
    largest = std::max(largest, d);
  }
  return largest;
}

// The sweeps are compiled for AVX2 and FMA as well as for the build's baseline (LUMEN_TARGET_CLONES: the float
// values are widened to double four at a time).

// The factor's arrays as the sweeps read them (see SupernodalView).
struct Supernodes {
  int nsuper;
  const int *super, *pi, *px, *s;
  const float* x;
};

// sum_i a[i] b[i] over m entries, the float values widened to double (vectorised: the pragma lets the compiler
// reorder the sum; -fopenmp-simd, no OpenMP runtime).
inline double dot(const float* a, const double* b, int m) {
  double sum = 0.0;
#pragma omp simd reduction(+ : sum)
  for (int i = 0; i < m; ++i) sum += a[i] * b[i];
  return sum;
}

// The sweeps read each supernode's rows below its diagonal block (m rows, columns of stride nrow) four columns at
// a time, so that t is loaded (and in the forward sweep stored) once per four columns.
constexpr int kColumnBlock = 4;

// L z = y in place, supernode by supernode: the diagonal block, then its rows below into t, scattered.
LUMEN_TARGET_CLONES void forward(const Supernodes& f, double* y, double* t) {
  for (int k = 0; k < f.nsuper; ++k) {
    const int c0 = f.super[k], ncol = f.super[k + 1] - c0, nrow = f.pi[k + 1] - f.pi[k], m = nrow - ncol;
    const float* v = f.x + f.px[k];
    double* ys = y + c0;
    for (int j = 0; j < ncol; ++j) {
      const float* col = v + static_cast<long>(j) * nrow;
      const double yj = ys[j] / col[j];
      ys[j] = yj;
      for (int i = j + 1; i < ncol; ++i) ys[i] -= col[i] * yj;
    }
    if (m == 0) continue;
    std::fill(t, t + m, 0.0);
    const float* below = v + ncol;
    int j = 0;
    for (; j + kColumnBlock <= ncol; j += kColumnBlock) {
      const float *a0 = below + static_cast<long>(j) * nrow, *a1 = a0 + nrow, *a2 = a1 + nrow, *a3 = a2 + nrow;
      const double y0 = ys[j], y1 = ys[j + 1], y2 = ys[j + 2], y3 = ys[j + 3];
      for (int i = 0; i < m; ++i) t[i] += (a0[i] * y0 + a1[i] * y1) + (a2[i] * y2 + a3[i] * y3);
    }
    for (; j < ncol; ++j) {
      const float* a0 = below + static_cast<long>(j) * nrow;
      const double y0 = ys[j];
      for (int i = 0; i < m; ++i) t[i] += a0[i] * y0;
    }
    const int* rows = f.s + f.pi[k] + ncol;
    for (int i = 0; i < m; ++i) y[rows[i]] -= t[i];
  }
}

// L^T w = z in place, supernodes in reverse: the rows below gathered into t, then the diagonal block.
LUMEN_TARGET_CLONES void backward(const Supernodes& f, double* y, double* t) {
  for (int k = f.nsuper - 1; k >= 0; --k) {
    const int c0 = f.super[k], ncol = f.super[k + 1] - c0, nrow = f.pi[k + 1] - f.pi[k], m = nrow - ncol;
    const float* v = f.x + f.px[k];
    double* ys = y + c0;
    const int* rows = f.s + f.pi[k] + ncol;
    for (int i = 0; i < m; ++i) t[i] = y[rows[i]];
    const float* below = v + ncol;
    int j = 0;
    for (; j + kColumnBlock <= ncol; j += kColumnBlock) {
      const float *a0 = below + static_cast<long>(j) * nrow, *a1 = a0 + nrow, *a2 = a1 + nrow, *a3 = a2 + nrow;
      double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
#pragma omp simd reduction(+ : s0, s1, s2, s3)
      for (int i = 0; i < m; ++i) {
        const double ti = t[i];
        s0 += a0[i] * ti;
        s1 += a1[i] * ti;
        s2 += a2[i] * ti;
        s3 += a3[i] * ti;
      }
      ys[j] -= s0;
      ys[j + 1] -= s1;
      ys[j + 2] -= s2;
      ys[j + 3] -= s3;
    }
    for (; j < ncol; ++j) ys[j] -= dot(below + static_cast<long>(j) * nrow, t, m);
    for (j = ncol - 1; j >= 0; --j) {
      const float* col = v + static_cast<long>(j) * nrow;
      ys[j] = (ys[j] - dot(col + j + 1, ys + j + 1, ncol - j - 1)) / col[j];
    }
  }
}

}  // namespace

SupernodalSingle::SupernodalSingle(const SupernodalView& L) : n_(L.n) {
  if (L.n < 1 || L.nsuper < 1 || !L.super || !L.pi || !L.px || !L.s || !L.x)
    fail("SupernodalSingle: the view must be a supernodal factor with n >= 1 and at least one supernode, got n = " +
         std::to_string(L.n) + " and " + std::to_string(L.nsuper) + " supernodes");
  if (L.super[0] != 0 || L.super[L.nsuper] != L.n)
    fail("SupernodalSingle: the supernodes must cover columns 0 to n = " + std::to_string(L.n) + ", got " +
         std::to_string(L.super[0]) + " to " + std::to_string(L.super[L.nsuper]));
  size_t max_rows = 0;
  double largest = 0.0;  // the largest diagonal entry
  for (int k = 0; k < L.nsuper; ++k) {
    largest = std::max(largest, check_supernode(L, k));
    max_rows = std::max(max_rows, static_cast<size_t>(L.pi[k + 1] - L.pi[k]));
  }
  super_.assign(L.super, L.super + L.nsuper + 1);
  pi_.assign(L.pi, L.pi + L.nsuper + 1);
  px_.assign(L.px, L.px + L.nsuper + 1);
  s_.assign(L.s, L.s + L.pi[L.nsuper]);
  if (L.perm) {
    // A permutation of 0 .. n - 1.
    std::vector<char> seen(L.n, 0);
    for (int k = 0; k < L.n; ++k) {
      if (L.perm[k] < 0 || L.perm[k] >= L.n || seen[L.perm[k]])
        fail("SupernodalSingle: perm[" + std::to_string(k) + "] must be a row of [0, " + std::to_string(L.n) +
             ") not taken before, got " + std::to_string(L.perm[k]));
      seen[L.perm[k]] = 1;
    }
    perm_.assign(L.perm, L.perm + L.n);
  }
  // The values over the largest diagonal entry, rounded: rounded as they are, scaling K by c (L by sqrt c) would
  // round differently unless c were a power of 4, and the preconditioner would not commute with scaling K (the
  // corotational modulus sweep checks that it does). Only what the sweeps read, each supernode's lower
  // trapezoid, is read and checked; the rest of x_ (the diagonal blocks' upper triangles, any gaps) is 0.
  inverse_square_scale_ = 1.0 / (largest * largest);
  x_.assign(static_cast<size_t>(L.px[L.nsuper]), 0.0f);
  constexpr double kFloatMax = std::numeric_limits<float>::max();
  for (int k = 0; k < L.nsuper; ++k) {
    const int nrow = L.pi[k + 1] - L.pi[k];
    for (int j = 0; j < L.super[k + 1] - L.super[k]; ++j)
      for (int i = j; i < nrow; ++i) {
        const long at = L.px[k] + i + static_cast<long>(j) * nrow;
        const double scaled = L.x[at] / largest;
        if (!(std::abs(scaled) <= kFloatMax))
          fail_value("SupernodalSingle: value " + std::to_string(at),
                     "must be finite and within float's range of the largest diagonal entry", L.x[at]);
        x_[at] = static_cast<float>(scaled);
      }
  }
  y_.resize(n_);
  t_.resize(max_rows);
}

void SupernodalSingle::solve(const double* b, double* x) const {
  double* y = y_.data();
  const Supernodes f{static_cast<int>(super_.size()) - 1, super_.data(), pi_.data(), px_.data(), s_.data(),
                     x_.data()};
  // y = P b; L' z = y; L'^T w = z; x = P^T w / scale^2 (L' = L / scale, as stored).
  if (perm_.empty()) std::copy(b, b + n_, y);
  else for (int k = 0; k < n_; ++k) y[k] = b[perm_[k]];
  forward(f, y, t_.data());
  backward(f, y, t_.data());
  if (perm_.empty()) for (int k = 0; k < n_; ++k) x[k] = inverse_square_scale_ * y[k];
  else for (int k = 0; k < n_; ++k) x[perm_[k]] = inverse_square_scale_ * y[k];
}

}  // namespace lumen::physics::detail
