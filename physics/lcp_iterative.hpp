#pragma once
// Iterative dense LCP solvers w = A z + q, w >= 0, z >= 0, w . z = 0 for a symmetric positive semidefinite A,
// with a sweep budget and a warm start, for many contacts where the pivoting solvers of physics/lcp.hpp grow
// too costly: projected Gauss-Seidel (optionally over-relaxed) and the nonsmooth nonlinear conjugate gradient
// (NNCG: Silcowitz, Niebe and Erleben 2010, "A nonsmooth nonlinear conjugate gradient method for interactive
// contact force problems"), which accelerates the same sweeps by Fletcher-Reeves conjugation.
//
// Both return the LcpResult of physics/lcp.hpp: iterations = sweeps spent, residual = lcp_residual(w, z,
// diag(A)) of the returned z (units of q), converged = residual <= tolerance. Running out of the sweep budget is
// not an error (converged = false with the residual reached): the budget is the point, callers report the
// residual. Rows with A_ii <= 0 (fixed DOFs, rows no force can move) keep z_i = 0.
#include <Eigen/Core>

#include "physics/lcp.hpp"

namespace lumen::physics {

// Options of the iterative LCP solvers.
struct IterativeLcpOptions {
  int max_sweeps = 100;      // sweep budget (>= 1); one sweep visits every row once
  double tolerance = 1e-9;   // residual accepted as converged, units of q (metres for contact gaps)
  double relaxation = 1.0;   // over-relaxation factor omega of the PGS row update, in (0, 2); 1 = plain PGS
  Eigen::VectorXd warm;      // warm start z0 (m, clamped to >= 0); empty = 0
};

// Projected Gauss-Seidel: z_i <- max(0, z_i - omega w_i / A_ii) row after row, w kept equal to A z + q.
// Throws std::invalid_argument for A not m x m, not finite or not symmetric, q not finite, a warm start of the
// wrong size or not finite, or bad options.
LcpResult solve_lcp_pgs(const Eigen::MatrixXd& A, const Eigen::VectorXd& q, const IterativeLcpOptions& options = {});

// NNCG: each round is one symmetric PGS sweep (forward then backward, 2 sweeps of the budget; the "gradient"
// g = z_k - SPGS(z_k)) followed by the conjugation z += beta p, p <- beta p - g with beta = |g_k+1|^2 / |g_k|^2
// (Fletcher-Reeves), restarted (p = 0) when beta > 1, i.e. when the merit |g| grows. The returned z is always a
// post-sweep iterate (z >= 0). Silcowitz et al. use the forward sweep alone; with it, on a pinch-like patch of
// coupled contacts, a third of the rounds restarted and NNCG needed 5x PGS's sweeps, while the symmetric sweep
// (a symmetric preconditioner, as in CG) needs about 0.6x PGS's sweeps there and 0.07x on a stack. Same
// validation as PGS.
LcpResult solve_lcp_nncg(const Eigen::MatrixXd& A, const Eigen::VectorXd& q, const IterativeLcpOptions& options = {});

}  // namespace lumen::physics
