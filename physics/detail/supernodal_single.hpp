#pragma once
// A single-precision copy of a supernodal Cholesky factor and its two triangular solves, for preconditioning.
//
// CHOLMOD 3 (Debian's SuiteSparse 5.12) factorises and solves in double precision only. A preconditioner needs
// no more than a few digits, and a back-substitution reads the whole factor twice (L, then L^T): on the paper
// mesh 1.54 million stored values (1.23 million nonzeros and the supernodes' padding), 12 MB in double. This keeps the values in
// float (half the bytes) and solves in double arithmetic on them, supernode by supernode, in CHOLMOD's layout.
// The values are stored over the largest diagonal entry, so that the rounding, and the solves, commute with
// scaling the matrix (up to double round-off).
#include <vector>

namespace lumen::physics::detail {

// CHOLMOD's supernodal factor (cholmod_factor with is_super, int indices), as read by SupernodalSingle: P A P^T
// = L L^T with Perm[k] the row of A that is row k of L. Supernode s holds columns super[s] .. super[s+1] - 1 of L;
// its rows are s[pi[s]] .. s[pi[s+1] - 1] (the first ones are its own columns), and its values are column-major
// at x[px[s]], nrow = pi[s+1] - pi[s] per column.
struct SupernodalView {
  int n = 0;                      // rows of A (the free DOFs)
  int nsuper = 0;                 // supernodes
  const int* super = nullptr;     // nsuper + 1: first column of each supernode
  const int* pi = nullptr;        // nsuper + 1: start of each supernode's rows in s
  const int* px = nullptr;        // nsuper + 1: start of each supernode's values in x
  const int* s = nullptr;         // row indices
  const double* x = nullptr;      // values
  const int* perm = nullptr;      // n: the fill-reducing permutation (null: identity)
};

class SupernodalSingle {
 public:
  // Copies the structure and rounds the values, over the largest diagonal entry, to float. Throws
  // std::invalid_argument for a view that is not a supernodal factor (null arrays, a supernode whose rows do not
  // start with its own columns, a non-positive or non-finite diagonal, or a value that is not finite or is beyond
  // float's range once divided by the largest diagonal entry).
  explicit SupernodalSingle(const SupernodalView& L);

  int n() const { return n_; }
  // x = A^-1 b to about float's precision times the factor's condition (b, x: n entries each, distinct).
  // Uses the object's workspace: one solve at a time.
  void solve(const double* b, double* x) const;

 private:
  int n_ = 0;
  std::vector<int> super_, pi_, px_, s_, perm_;  // as in SupernodalView (perm_ empty: identity)
  std::vector<float> x_;                         // the values over the largest diagonal entry, rounded
  double inverse_square_scale_ = 1.0;            // 1 / (largest diagonal entry)^2
  mutable std::vector<double> y_;                // the permuted right-hand side and solution, n
  mutable std::vector<double> t_;                // one supernode's off-diagonal rows, max rows of a supernode
};

}  // namespace lumen::physics::detail
