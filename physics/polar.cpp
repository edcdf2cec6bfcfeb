// Proper rotations: Newton's polar iteration (one matrix, and several in lockstep), the SVD for the rest.
#include "physics/polar.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "physics/detail/target_clones.hpp"

namespace lumen::physics {

namespace {

// Below this det F the polar rotation comes from the SVD instead of the Newton iteration.
constexpr double kNewtonMinDet = 1e-2;
constexpr int kNewtonMaxIterations = 20;
// A Newton step (largest entry of the change of X) this small ends the iteration: convergence is quadratic, so X is
// then within about step^2 / 2 of the rotation.
constexpr double kNewtonStepTolerance = 1e-8;
// While steps are larger than this, X is far from orthogonal and the iteration scales by det^(-1/3).
constexpr double kNewtonScaledStep = 1e-2;
// |det - 1| below which the Newton scaling is its series (newton_scaling).
constexpr double kNewtonSeriesRange = 0.25;

// Cofactor matrix of X (X^-T det X): its columns are cross products of the columns of X.
[[gnu::always_inline]] inline Eigen::Matrix3d cofactor(const Eigen::Matrix3d& X) {
  Eigen::Matrix3d C;
  C.col(0) = X.col(1).cross(X.col(2));
  C.col(1) = X.col(2).cross(X.col(0));
  C.col(2) = X.col(0).cross(X.col(1));
  return C;
}

// Higham's scaling det^(-1/3) of the Newton polar iteration. It only sets the speed of convergence, not the limit,
// so near det = 1 its Taylor series to second order (relative error at most about 3e-3 for |det - 1| < 0.25) replaces
// std::cbrt, which cost more than the rest of an iteration.
[[gnu::always_inline]] inline double newton_series(double det) {
  const double e = det - 1.0;
  return 1.0 - e / 3.0 + e * e * (2.0 / 9.0);
}
double newton_scaling(double det) {
  if (std::abs(det - 1.0) < kNewtonSeriesRange) return newton_series(det);
  return std::cbrt(1.0 / det);
}

using Lanes = double[detail::kPolarLanes];

// The cofactor matrix c of every lane's x (entries column-major, as cofactor()'s), and det x from its first column.
[[gnu::always_inline]] inline void cofactor_lanes(const double (&x)[9][detail::kPolarLanes],
                                                  double (&c)[9][detail::kPolarLanes], Lanes& det) {
#pragma omp simd
  for (int l = 0; l < detail::kPolarLanes; ++l) {
    c[0][l] = x[4][l] * x[8][l] - x[5][l] * x[7][l];
    c[1][l] = x[5][l] * x[6][l] - x[3][l] * x[8][l];
    c[2][l] = x[3][l] * x[7][l] - x[4][l] * x[6][l];
    c[3][l] = x[7][l] * x[2][l] - x[8][l] * x[1][l];
    c[4][l] = x[8][l] * x[0][l] - x[6][l] * x[2][l];
    c[5][l] = x[6][l] * x[1][l] - x[7][l] * x[0][l];
    c[6][l] = x[1][l] * x[5][l] - x[2][l] * x[4][l];
    c[7][l] = x[2][l] * x[3][l] - x[0][l] * x[5][l];
    c[8][l] = x[0][l] * x[4][l] - x[1][l] * x[3][l];
    det[l] = x[0][l] * c[0][l] + x[1][l] * c[1][l] + x[2][l] * c[2][l];
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------------
// One matrix

Eigen::Matrix3d proper_rotation(const Eigen::Matrix3d& F, bool* inverted) {
  if (!F.allFinite()) {
    std::ostringstream msg;
    msg << "proper_rotation: F must be finite, got\n" << F;
    throw std::invalid_argument(msg.str());
  }
  Eigen::Matrix3d C = cofactor(F);
  double det = F.col(0).dot(C.col(0));
  if (inverted) *inverted = !(det > 0.0);
  // Well-conditioned, not inverted: Newton's polar iteration X <- (g X + X^-T / g) / 2 with determinant scaling
  // g = |det X|^(-1/3) while far from orthogonal (Higham 1986); converges quadratically to the polar rotation.
  // (X^-T det X is the cofactor matrix, whose first column also gives det X.)
  if (det > kNewtonMinDet) {
    Eigen::Matrix3d X = F;
    bool scale = true;
    for (int k = 0; k < kNewtonMaxIterations; ++k) {
      const double g = scale ? newton_scaling(det) : 1.0;
      const Eigen::Matrix3d next = (0.5 * g) * X + (0.5 / (g * det)) * C;
      const double step = (next - X).lpNorm<Eigen::Infinity>();
      X = next;
      if (step <= kNewtonStepTolerance) return X;
      scale = step > kNewtonScaledStep;
      C = cofactor(X);
      det = X.col(0).dot(C.col(0));
    }
  }
  // Inverted, nearly degenerate or not converged: SVD, the smallest singular value's sign flipped when
  // U V^T would be a reflection (Irving et al. 2004), so R is always a proper rotation.
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU();
  const Eigen::Matrix3d& V = svd.matrixV();
  if ((U * V.transpose()).determinant() < 0.0) U.col(2) = -U.col(2);
  return U * V.transpose();
}

// ---------------------------------------------------------------------------------------------------------------
// Several matrices in lockstep

namespace detail {

LUMEN_TARGET_CLONES unsigned polar_newton_lanes(double (&x)[9][kPolarLanes]) {
  // Per lane: live (1 while iterating, else 0), scaled (1 while the steps are large), settled (1 once converged).
  alignas(32) double c[9][kPolarLanes];
  alignas(32) Lanes det, live, scaled, settled, g;
  cofactor_lanes(x, c, det);
#pragma omp simd
  for (int l = 0; l < kPolarLanes; ++l) {
    live[l] = det[l] > kNewtonMinDet ? 1.0 : 0.0;  // (false for NaN)
    scaled[l] = 1.0;
    settled[l] = 0.0;
  }
  for (int k = 0; k < kNewtonMaxIterations; ++k) {
    // The scaling: its series, or std::cbrt lane by lane where det is far from 1 (rare: large stretches).
#pragma omp simd
    for (int l = 0; l < kPolarLanes; ++l) g[l] = scaled[l] > 0.0 ? newton_series(det[l]) : 1.0;
    for (int l = 0; l < kPolarLanes; ++l)
      if (scaled[l] > 0.0 && live[l] > 0.0 && !(std::abs(det[l] - 1.0) < kNewtonSeriesRange))
        g[l] = std::cbrt(1.0 / det[l]);
    // X <- (g X + C / (g det)) / 2 on the live lanes, and each lane's step.
    double any_live = 0.0;
#pragma omp simd reduction(max : any_live)
    for (int l = 0; l < kPolarLanes; ++l) {
      const double a = 0.5 * g[l], b = 0.5 / (g[l] * det[l]);
      double step = 0.0;
      for (int e = 0; e < 9; ++e) {
        const double next = a * x[e][l] + b * c[e][l];
        step = std::max(step, std::abs(next - x[e][l]));
        x[e][l] = live[l] > 0.0 ? next : x[e][l];
      }
      const double converged = live[l] > 0.0 && step <= kNewtonStepTolerance ? 1.0 : 0.0;
      settled[l] = converged > 0.0 ? 1.0 : settled[l];
      live[l] = converged > 0.0 ? 0.0 : live[l];
      scaled[l] = step > kNewtonScaledStep ? 1.0 : 0.0;
      any_live = std::max(any_live, live[l]);
    }
    if (any_live == 0.0) break;
    cofactor_lanes(x, c, det);
  }
  unsigned mask = 0;
  for (int l = 0; l < kPolarLanes; ++l)
    if (settled[l] > 0.0) mask |= 1u << l;
  return mask;
}

}  // namespace detail

}  // namespace lumen::physics
