// Iterative dense LCP solvers: projected Gauss-Seidel and nonsmooth nonlinear conjugate gradient (NNCG).
#include "physics/lcp_iterative.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <string>

#include "physics/detail/messages.hpp"

namespace lumen::physics {

using detail::fail;
using detail::num;

namespace {

constexpr double kSymmetryTolerance = 1e-10;  // |A_ij - A_ji| accepted, relative to max |A|
constexpr double kMaxRelaxation = 2.0;        // PGS over-relaxation must stay below this (convergence)
constexpr int kRefreshSweeps = 32;            // sweeps between exact recomputations of w = A z + q (drift)

// Throws std::invalid_argument naming the solver, the input and the value.
void validate(const char* who, const Eigen::MatrixXd& A, const Eigen::VectorXd& q,
              const IterativeLcpOptions& options) {
  const std::string name(who);
  const Eigen::Index m = q.size();
  if (A.rows() != m || A.cols() != m)
    fail(name + ": A must be " + std::to_string(m) + " x " + std::to_string(m) + ", got " +
         std::to_string(A.rows()) + " x " + std::to_string(A.cols()));
  if (!A.allFinite() || !q.allFinite()) fail(name + ": A and q must be finite");
  const double scale = m > 0 ? A.cwiseAbs().maxCoeff() : 0.0;
  const double asym = m > 0 ? (A - A.transpose()).cwiseAbs().maxCoeff() : 0.0;
  if (asym > kSymmetryTolerance * scale) fail(name + ": A must be symmetric, max |A - A^T| = " + num(asym));
  if (options.max_sweeps < 1) fail(name + ": max_sweeps must be >= 1, got " + std::to_string(options.max_sweeps));
  if (!(options.tolerance >= 0.0)) fail(name + ": tolerance must be >= 0, got " + num(options.tolerance));
  if (!(options.relaxation > 0.0 && options.relaxation < kMaxRelaxation))
    fail(name + ": relaxation must be in (0, 2), got " + num(options.relaxation));
  if (options.warm.size() != 0 && options.warm.size() != m)
    fail(name + ": warm must be empty or of size " + std::to_string(m) + ", got " +
         std::to_string(options.warm.size()));
  if (!options.warm.allFinite()) fail(name + ": warm must be finite");
}

// The iterate z (m, >= 0 after every sweep) with w = A z + q (m, units of q) kept up to date, and the sweep.
class PgsState {
 public:
  PgsState(const Eigen::MatrixXd& A, const Eigen::VectorXd& q, const IterativeLcpOptions& options)
      : A_(A), q_(q), omega_(options.relaxation), diag_(A.diagonal()), inv_diag_(q.size()) {
    // Movable rows: 1 / A_ii; fixed rows (A_ii <= 0): 0, and z_i = 0 for ever.
    for (Eigen::Index i = 0; i < q.size(); ++i) inv_diag_[i] = diag_[i] > 0.0 ? 1.0 / diag_[i] : 0.0;
    z = options.warm.size() > 0 ? Eigen::VectorXd(options.warm.cwiseMax(0.0))
                                : Eigen::VectorXd(Eigen::VectorXd::Zero(q.size()));
    for (Eigen::Index i = 0; i < q.size(); ++i)
      if (inv_diag_[i] == 0.0) z[i] = 0.0;
    refresh();
  }

  // One Gauss-Seidel sweep over the rows (first to last, or last to first) with the projection on z >= 0; w
  // follows each change by a column update.
  void sweep(bool backward = false) {
    const Eigen::Index m = z.size();
    for (Eigen::Index k = 0; k < m; ++k) {
      const Eigen::Index i = backward ? m - 1 - k : k;
      if (inv_diag_[i] == 0.0) continue;
      const double zi = std::max(0.0, z[i] - omega_ * w[i] * inv_diag_[i]);
      const double dz = zi - z[i];
      if (dz == 0.0) continue;
      z[i] = zi;
      w.noalias() += dz * A_.col(i);
    }
    if (++sweeps % kRefreshSweeps == 0) refresh();
  }

  // w = A z + q recomputed (removes the drift of the column updates).
  void refresh() { w.noalias() = A_ * z + q_; }
  // z += dz with w following (dz: m).
  void step(const Eigen::VectorXd& dz) {
    z += dz;
    w.noalias() += A_ * dz;
  }
  double residual() const { return lcp_residual(w, z, diag_); }

  // True when the current iterate meets the tolerance with an exact w (recomputed before the verdict).
  bool done(double tolerance) {
    if (residual() > tolerance) return false;
    refresh();
    return residual() <= tolerance;
  }

  LcpResult result(double tolerance) {
    refresh();
    LcpResult out;
    out.z = z;
    out.w = w;
    out.iterations = sweeps;
    out.residual = residual();
    out.converged = out.residual <= tolerance;
    return out;
  }

  Eigen::VectorXd z;  // m, multipliers
  Eigen::VectorXd w;  // m, A z + q
  int sweeps = 0;

 private:
  const Eigen::MatrixXd& A_;
  const Eigen::VectorXd& q_;
  double omega_;
  Eigen::VectorXd diag_;      // m, A_ii
  Eigen::VectorXd inv_diag_;  // m, 1 / A_ii on movable rows, 0 on fixed ones
};

}  // namespace

LcpResult solve_lcp_pgs(const Eigen::MatrixXd& A, const Eigen::VectorXd& q, const IterativeLcpOptions& options) {
  validate("solve_lcp_pgs", A, q, options);
  PgsState s(A, q, options);
  // The warm start may already be the solution; otherwise sweep until the tolerance or the budget.
  if (s.done(options.tolerance)) return s.result(options.tolerance);
  while (s.sweeps < options.max_sweeps) {
    s.sweep();
    if (s.done(options.tolerance)) break;
  }
  return s.result(options.tolerance);
}

LcpResult solve_lcp_nncg(const Eigen::MatrixXd& A, const Eigen::VectorXd& q, const IterativeLcpOptions& options) {
  validate("solve_lcp_nncg", A, q, options);
  PgsState s(A, q, options);
  if (s.done(options.tolerance)) return s.result(options.tolerance);
  // Each round: a symmetric sweep (forward then backward; only forward when one sweep of the budget is left) and
  // its gradient g = z_before - SPGS(z_before) (m); the test, on the post-sweep iterate only (z >= 0); then the
  // first round sets the direction p = -g (m), later ones conjugate or restart.
  Eigen::VectorXd z_before, g, p = Eigen::VectorXd::Zero(q.size());
  double gg = 0.0;
  for (bool first = true;; first = false) {
    z_before = s.z;
    s.sweep();
    if (s.sweeps < options.max_sweeps) s.sweep(/*backward=*/true);
    g = z_before - s.z;
    const double gg_next = g.squaredNorm();
    if (s.done(options.tolerance) || s.sweeps >= options.max_sweeps) break;
    const double beta = first || !(gg > 0.0) ? 0.0 : gg_next / gg;
    gg = gg_next;
    if (beta > 1.0) {
      // The merit grew: restart from the plain PGS iterate.
      p.setZero();
      continue;
    }
    p *= beta;
    if (beta > 0.0) s.step(p);
    p -= g;
  }
  assert(s.z.minCoeff() >= 0.0 || s.z.size() == 0);
  return s.result(options.tolerance);
}

}  // namespace lumen::physics
