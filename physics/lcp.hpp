#pragma once
// Dense LCP solvers w = A z + q, w >= 0, z >= 0, w . z = 0 for a symmetric positive semidefinite A: Lemke's
// complementary pivoting, and an active-set method that needs only the columns of its active indices.
#include <Eigen/Core>
#include <functional>
#include <vector>

namespace lumen::physics {

// Options of the dense LCP solver.
struct LcpOptions {
  double tolerance = 1e-9;  // residual accepted as converged, metres
  int max_iterations = 0;   // pivot bound; 0 = 10 * rows + 100
};

// Result of a dense LCP w = A z + q, w >= 0, z >= 0, w . z = 0.
struct LcpResult {
  Eigen::VectorXd z;    // multipliers, >= 0
  Eigen::VectorXd w;    // A z + q
  int iterations = 0;   // pivots
  double residual = 0;  // max_i |min(w_i, A_ii z_i)| and max(-w_i, 0), units of q
  bool converged = false;
};

// Lemke's complementary pivoting (lexicographic tie-break, covering vector 1) on a dense symmetric positive
// semidefinite A (m x m), with a final polish on the active set. Fails (converged = false) on ray termination
// (infeasible problem) or at the pivot bound.
LcpResult solve_lcp_dense(const Eigen::MatrixXd& A, const Eigen::VectorXd& q, const LcpOptions& options = {});

// Active-set solve of the same LCP for a symmetric positive semidefinite A given column by column
// (column(j) = A e_j, called only for indices that enter the active set), in the manner of Lawson and Hanson's
// NNLS on the equivalent convex QP min 1/2 z^T A z + q^T z, z >= 0: solve A_PP z_P = -q_P on the passive set P
// (incrementally updated Cholesky), step back and drop indices whose z would turn negative, add the index of
// the most negative w, until w >= -tolerance off P. A row that is linearly dependent on P is exchanged with a
// member of P along the null direction; an unbounded such direction (infeasible problem) ends the solve.
// warm: indices guessed to be active (e.g. the last solve's), tried first. iterations counts the rounds (adds,
// drops, exchanges); max_iterations 0 = 10 * rows + 100. converged = false (never a throw) on an infeasible
// problem or at the round bound: callers fall back to solve_lcp_dense.
LcpResult solve_lcp_active_set(const std::function<const Eigen::VectorXd&(int)>& column, const Eigen::VectorXd& q,
                               const std::vector<int>& warm = {}, const LcpOptions& options = {});
// The same on a dense A (m x m).
LcpResult solve_lcp_active_set(const Eigen::MatrixXd& A, const Eigen::VectorXd& q, const std::vector<int>& warm = {},
                               const LcpOptions& options = {});
// Residual of a candidate solution z >= 0 with w = A z + q (units of w): the largest violation of w >= 0 (-w_i)
// and, over the indices with z_i > 0, the complementarity gap |min(w_i, d_i z_i)|, d_i z_i being z_i in units
// of w (d = the diagonal of A, negative entries counted as 0). The LCP solvers report it with d = diag(A); the
// contact solves with d empty, which makes the gap |w_i| wherever z_i > 0 (equality on every pushing row).

double lcp_residual(const Eigen::VectorXd& w, const Eigen::VectorXd& z, const Eigen::VectorXd& diagonal = {});

}  // namespace lumen::physics
