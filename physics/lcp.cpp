// Dense LCP solvers: active set (Lawson-Hanson type) and Lemke's complementary pivoting.
#include "physics/lcp.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <string>

#include "physics/detail/messages.hpp"

namespace lumen::physics {

using detail::fail;
using detail::num;

// ---------------------------------------------------------------------------------------------------------------
// Residual

double lcp_residual(const Eigen::VectorXd& w, const Eigen::VectorXd& z, const Eigen::VectorXd& diagonal) {
  const bool scaled = diagonal.size() > 0;
  double res = 0.0;
  for (Eigen::Index i = 0; i < w.size(); ++i) {
    res = std::max(res, -w[i]);
    if (z[i] > 0.0) res = std::max(res, std::abs(scaled ? std::min(w[i], std::max(diagonal[i], 0.0) * z[i]) : w[i]));
  }
  return res;
}

// ---------------------------------------------------------------------------------------------------------------
// Active set (Lawson-Hanson type) on the convex QP min 1/2 z^T A z + q^T z, z >= 0

namespace {

void check_lcp_options(const LcpOptions& options) {
  if (!(options.tolerance >= 0.0)) fail("LcpOptions.tolerance must be >= 0, got " + num(options.tolerance));
  if (options.max_iterations < 0)
    fail("LcpOptions.max_iterations must be >= 0, got " + std::to_string(options.max_iterations));
}

// Cholesky factor L L^T = A_PP of the passive set P, grown one index at a time, rebuilt after removals.
class PassiveFactor {
 public:
  explicit PassiveFactor(const std::function<const Eigen::VectorXd&(int)>& column) : column_(column) {}
  const std::vector<int>& set() const { return P_; }
  int size() const { return static_cast<int>(P_.size()); }

  // Symmetric entry A_ij from the two columns (both are needed anyway).
  double entry(int i, int j) const { return 0.5 * (column_(j)[i] + column_(i)[j]); }

  // Appends j when A_{P+j} stays positive definite; otherwise leaves P as it is and returns false with
  // coefficients c (A e_j = A_{., P} c up to the dependence tolerance).
  bool append(int j, Eigen::VectorXd& c) {
    const int p = size();
    reserve(p + 1);
    Eigen::VectorXd l(p);
    for (int a = 0; a < p; ++a) l[a] = entry(P_[a], j);
    if (p > 0) L_.topLeftCorner(p, p).triangularView<Eigen::Lower>().solveInPlace(l);
    const double ajj = column_(j)[j];
    const double d2 = ajj - l.squaredNorm();
    if (!(ajj > 0.0) || !(d2 > kDependence * ajj)) {
      c = l;
      if (p > 0) L_.topLeftCorner(p, p).triangularView<Eigen::Lower>().transpose().solveInPlace(c);
      return false;
    }
    L_.row(p).head(p) = l.transpose();
    L_(p, p) = std::sqrt(d2);
    P_.push_back(j);
    return true;
  }

  // Keeps the members of P for which keep(index) is true and refactors; false when A_PP is not positive definite.
  template <class Keep>
  bool retain(Keep keep) {
    std::vector<int> kept;
    for (int i : P_)
      if (keep(i)) kept.push_back(i);
    P_ = kept;
    const int p = size();
    if (p == 0) return true;
    Eigen::MatrixXd M(p, p);
    for (int a = 0; a < p; ++a)
      for (int b = 0; b <= a; ++b) M(a, b) = M(b, a) = entry(P_[a], P_[b]);
    const Eigen::LLT<Eigen::MatrixXd> llt(M);
    if (llt.info() != Eigen::Success) return false;
    const Eigen::MatrixXd Lp = llt.matrixL();
    for (int a = 0; a < p; ++a)
      if (!(Lp(a, a) * Lp(a, a) > kDependence * M(a, a))) return false;
    L_.topLeftCorner(p, p) = Lp;
    return true;
  }

  // zeta_P = -A_PP^-1 q_P.
  Eigen::VectorXd solve(const Eigen::VectorXd& q) const {
    const int p = size();
    Eigen::VectorXd x(p);
    for (int a = 0; a < p; ++a) x[a] = -q[P_[a]];
    const auto L = L_.topLeftCorner(p, p).triangularView<Eigen::Lower>();
    L.solveInPlace(x);
    L.transpose().solveInPlace(x);
    return x;
  }

 private:
  static constexpr double kDependence = 1e-10;  // relative pivot below which a row counts as dependent
  void reserve(int p) {
    if (L_.rows() >= p) return;
    const int cap = std::max(16, 2 * p);
    Eigen::MatrixXd grown = Eigen::MatrixXd::Zero(cap, cap);
    const int old = size();
    grown.topLeftCorner(old, old) = L_.topLeftCorner(old, old);
    L_.swap(grown);
  }
  const std::function<const Eigen::VectorXd&(int)>& column_;
  std::vector<int> P_;
  Eigen::MatrixXd L_;
};

// The active-set iteration on w = A z + q: its state (z, w, the passive set P and its factor, the round count)
// and its phases. Every phase keeps z feasible (z >= 0, z = 0 off P).
class ActiveSet {
 public:
  ActiveSet(const std::function<const Eigen::VectorXd&(int)>& column, const Eigen::VectorXd& q, int max_rounds,
            double tolerance)
      : column_(column), q_(q), m_(static_cast<int>(q.size())), max_rounds_(max_rounds), tol_(tolerance),
        z_(Eigen::VectorXd::Zero(m_)), w_(q), in_P_(m_, 0), F_(column) {}

  // Warm start: the guessed set (independent members), pruned of negative multipliers until the subproblem's
  // solution is positive; it is then a feasible starting point.
  void warm_start(const std::vector<int>& warm) {
    for (int j : warm)
      if (!in_P_[j] && F_.append(j, c_)) in_P_[j] = 1;
    while (F_.size() > 0 && !failed_) {
      const Eigen::VectorXd zeta = F_.solve(q_);
      bool positive = true;
      for (int a = 0; a < F_.size(); ++a) positive = positive && zeta[a] > 0.0;
      if (positive) {
        for (int a = 0; a < F_.size(); ++a) z_[F_.set()[a]] = zeta[a];
        break;
      }
      std::vector<char> keep(m_, 0);
      for (int a = 0; a < F_.size(); ++a) keep[F_.set()[a]] = zeta[a] > 0.0;
      drop([&](int i) { return keep[i] != 0; });
      ++rounds_;
    }
    update_w();
  }

  // Main loop: the most violated row off P enters and the subproblem on P is solved, until no row is below
  // -tolerance (true: solved) or the solve fails or reaches the round bound (false).
  bool run() {
    while (!failed_ && rounds_ < max_rounds_) {
      const int j = most_violated();
      if (j < 0) return true;
      ++rounds_;
      if (!F_.append(j, c_) && !exchange(j)) {
        failed_ = true;
        return false;
      }
      in_P_[j] = 1;
      descend();
      update_w();
    }
    return false;
  }

  // Result: z clipped at 0, w = A z + q, the residual on the diagonal entries of the columns at hand (those of
  // z_i > 0; no others are computed).
  LcpResult result(bool done) {
    LcpResult out;
    out.iterations = rounds_;
    out.z = z_.cwiseMax(0.0);
    update_w();
    out.w = w_;
    Eigen::VectorXd diagonal = Eigen::VectorXd::Zero(m_);
    for (int i = 0; i < m_; ++i)
      if (out.z[i] > 0.0) diagonal[i] = column_(i)[i];
    out.residual = lcp_residual(w_, out.z, diagonal);
    out.converged = done && !failed_ && out.residual <= tol_;
    return out;
  }

 private:
  // w = A z + q from the columns of P.
  void update_w() {
    w_ = q_;
    for (int j : F_.set()) w_.noalias() += z_[j] * column_(j);
  }

  // Removes the members of P that keep() rejects (their z becomes exactly 0) and refactors.
  template <class Keep>
  void drop(Keep keep) {
    failed_ = failed_ || !F_.retain(keep);
    std::vector<char> kept(m_, 0);
    for (int j : F_.set()) kept[j] = 1;
    for (int i = 0; i < m_; ++i)
      if (in_P_[i] && !kept[i]) z_[i] = 0.0;
    in_P_.swap(kept);
  }

  // The most violated row off P (w_j < -tolerance), or -1.
  int most_violated() const {
    int j = -1;
    for (int i = 0; i < m_; ++i)
      if (!in_P_[i] && w_[i] < -tol_ && (j < 0 || w_[i] < w_[j])) j = i;
    return j;
  }

  // Row j depends on P (append() left its coefficients in c_): along d = e_j - sum c_a e_{P_a} (A d = 0,
  // q . d = w_j < 0) the objective falls linearly; go until a member of P reaches zero and exchange it for j.
  // False when there is no such member (unbounded: the constraints are inconsistent) or the exchange fails.
  bool exchange(int j) {
    int block = -1;
    double t = 0.0;
    for (int a = 0; a < F_.size(); ++a)
      if (c_[a] > 0.0 && (block < 0 || z_[F_.set()[a]] / c_[a] < t)) block = a, t = z_[F_.set()[a]] / c_[a];
    if (block < 0) return false;
    for (int a = 0; a < F_.size(); ++a) z_[F_.set()[a]] -= t * c_[a];
    const int leaving = F_.set()[block];
    z_[leaving] = 0.0;
    z_[j] = t;
    drop([&](int i) { return i != leaving && z_[i] > 0.0; });
    return !failed_ && F_.append(j, c_);
  }

  // Subproblem on P from the feasible z: step towards its solution, dropping members that reach zero first.
  void descend() {
    while (!failed_) {
      const Eigen::VectorXd zeta = F_.solve(q_);
      double alpha = 1.0;
      for (int a = 0; a < F_.size(); ++a) {
        const int i = F_.set()[a];
        const double den = z_[i] - zeta[a];
        if (zeta[a] <= 0.0) alpha = std::min(alpha, den > 0.0 ? z_[i] / den : 0.0);
      }
      if (alpha >= 1.0) {
        for (int a = 0; a < F_.size(); ++a) z_[F_.set()[a]] = zeta[a];
        break;
      }
      std::vector<char> keep(m_, 0);
      for (int a = 0; a < F_.size(); ++a) {
        const int i = F_.set()[a];
        const double zi = z_[i] + alpha * (zeta[a] - z_[i]);
        const bool blocking = zeta[a] <= 0.0 && z_[i] <= alpha * (z_[i] - zeta[a]) * (1.0 + 1e-12);
        z_[i] = blocking || zi <= 0.0 ? 0.0 : zi;
        keep[i] = z_[i] > 0.0;
      }
      drop([&](int i) { return keep[i] != 0; });
      if (++rounds_ >= max_rounds_) failed_ = true;
    }
  }

  const std::function<const Eigen::VectorXd&(int)>& column_;
  const Eigen::VectorXd& q_;
  const int m_, max_rounds_;
  const double tol_;
  Eigen::VectorXd z_, w_;
  std::vector<char> in_P_;
  PassiveFactor F_;
  Eigen::VectorXd c_;  // coefficients of a dependent row (PassiveFactor::append)
  int rounds_ = 0;
  bool failed_ = false;
};

}  // namespace

LcpResult solve_lcp_active_set(const std::function<const Eigen::VectorXd&(int)>& column, const Eigen::VectorXd& q,
                               const std::vector<int>& warm, const LcpOptions& options) {
  const int m = static_cast<int>(q.size());
  if (!q.allFinite()) fail("solve_lcp_active_set: q must be finite");
  check_lcp_options(options);
  for (size_t i = 0; i < warm.size(); ++i)
    if (warm[i] < 0 || warm[i] >= m)
      fail("solve_lcp_active_set: warm[" + std::to_string(i) + "] must be in [0, " + std::to_string(m) + "), got " +
           std::to_string(warm[i]));
  const int max_rounds = options.max_iterations > 0 ? options.max_iterations : 10 * m + 100;
  ActiveSet solver(column, q, max_rounds, options.tolerance);
  solver.warm_start(warm);
  const bool done = solver.run();
  return solver.result(done);
}

LcpResult solve_lcp_active_set(const Eigen::MatrixXd& A, const Eigen::VectorXd& q, const std::vector<int>& warm,
                               const LcpOptions& options) {
  const int m = static_cast<int>(q.size());
  if (A.rows() != m || A.cols() != m)
    fail("solve_lcp_active_set: A must be " + std::to_string(m) + " x " + std::to_string(m) + ", got " +
         std::to_string(A.rows()) + " x " + std::to_string(A.cols()));
  if (!A.allFinite()) fail("solve_lcp_active_set: A must be finite");
  std::vector<Eigen::VectorXd> columns(m);
  return solve_lcp_active_set(
      [&](int j) -> const Eigen::VectorXd& {
        if (columns[j].size() != m) columns[j] = A.col(j);
        return columns[j];
      },
      q, warm, options);
}

// ---------------------------------------------------------------------------------------------------------------
// Lemke

namespace {

// Lemke's tableau for w - A z - e z0 = q. Variables: w_i -> i, z_i -> m + i, artificial z0 -> 2m; the basis
// starts at w. Binv is the inverse of the basis matrix, x the basic values (kept >= 0).
class LemkeTableau {
 public:
  LemkeTableau(const Eigen::MatrixXd& A, const Eigen::VectorXd& q)
      : A_(A), m_(static_cast<int>(q.size())), z0_(2 * m_), basis_(m_), Binv_(Eigen::MatrixXd::Identity(m_, m_)),
        x_(q), d_(m_), dd_(m_), br_(m_) {
    for (int i = 0; i < m_; ++i) basis_[i] = i;
  }

  // Pivots until z0 leaves the basis (true) or on ray termination or at max_it pivots (false); it counts them.
  bool run(const Eigen::VectorXd& q, int max_it, int& it) {
    // First pivot: z0 enters at the most negative q.
    int r0 = 0;
    q.minCoeff(&r0);
    direction(z0_);
    int leaving = pivot(r0, z0_);
    it = 1;
    while (it < max_it) {
      // The complement of the variable that just left enters.
      const int enter = leaving < m_ ? leaving + m_ : leaving - m_;
      direction(enter);
      const int r = ratio_row();
      if (r < 0) break;  // ray termination: infeasible (or not copositive-plus)
      leaving = pivot(r, enter);
      ++it;
      if (leaving == z0_) return true;
    }
    return false;
  }

  // z from the basis (negative basic values clipped at 0).
  Eigen::VectorXd z() const {
    Eigen::VectorXd z = Eigen::VectorXd::Zero(m_);
    for (int i = 0; i < m_; ++i)
      if (basis_[i] >= m_ && basis_[i] < 2 * m_) z[basis_[i] - m_] = std::max(x_[i], 0.0);
    return z;
  }
  // The indices i whose z_i is basic (the active set).
  std::vector<int> active() const {
    std::vector<int> S;
    for (int i = 0; i < m_; ++i)
      if (basis_[i] >= m_ && basis_[i] < 2 * m_) S.push_back(basis_[i] - m_);
    return S;
  }

 private:
  // d = Binv * (column of variable var); columns: w_i -> e_i, z_i -> -A e_i, z0 -> -1.
  void direction(int var) {
    if (var < m_) {
      d_ = Binv_.col(var);
    } else if (var < 2 * m_) {
      d_.noalias() = -(Binv_ * A_.col(var - m_));
    } else {
      d_ = -Binv_.rowwise().sum();
    }
  }

  // Pivot: variable `enter` with direction d replaces the basic variable of row r (rank-one update of Binv).
  int pivot(int r, int enter) {
    const double dr = d_[r];
    Binv_.row(r) /= dr;
    x_[r] /= dr;
    dd_ = d_;
    dd_[r] = 0.0;
    br_ = Binv_.row(r);
    Binv_.noalias() -= dd_ * br_;
    x_ -= dd_ * x_[r];
    const int leave = basis_[r];
    basis_[r] = enter;
    return leave;
  }

  // Minimum ratio x_i / d_i over d_i > 0; ties go to z0 (finishes at once), then lexicographically smaller rows
  // of Binv / d_i (the rule that rules out cycling under degeneracy). -1: no d_i > 0 (ray termination).
  int ratio_row() const {
    const double piv_tol = 1e-12 * d_.cwiseAbs().maxCoeff();
    auto prefer = [&](int i, int r) {
      if (basis_[r] == z0_) return false;
      if (basis_[i] == z0_) return true;
      for (int j = 0; j < m_; ++j) {
        const double a = Binv_(i, j) / d_[i], b = Binv_(r, j) / d_[r];
        if (a != b) return a < b;
      }
      return false;
    };
    const double dmax = d_.maxCoeff();
    if (!(dmax > piv_tol)) return -1;
    const double tie = 1e-12 * x_.cwiseAbs().maxCoeff() / dmax;
    int r = -1;
    double best = 0.0;
    for (int i = 0; i < m_; ++i) {
      if (d_[i] <= piv_tol) continue;
      const double ratio = std::max(x_[i], 0.0) / d_[i];
      if (r < 0 || ratio < best - tie) {
        r = i, best = ratio;
      } else if (ratio <= best + tie && prefer(i, r)) {
        r = i, best = std::min(best, ratio);
      }
    }
    return r;
  }

  const Eigen::MatrixXd& A_;
  const int m_, z0_;
  std::vector<int> basis_;
  Eigen::MatrixXd Binv_;
  Eigen::VectorXd x_, d_, dd_;
  Eigen::RowVectorXd br_;
};

// Polish on the active set S: z_S from A_SS z_S = -q_S (complete orthogonal decomposition, clipped at 0),
// taken when its residual is at least as good as out's.
void polish(const Eigen::MatrixXd& A, const Eigen::VectorXd& q, const std::vector<int>& S, LcpResult& out) {
  if (S.empty()) return;
  const int m = static_cast<int>(q.size()), s = static_cast<int>(S.size());
  Eigen::MatrixXd Ass(s, s);
  Eigen::VectorXd qs(s);
  for (int a = 0; a < s; ++a) {
    qs[a] = -q[S[a]];
    for (int b = 0; b < s; ++b) Ass(a, b) = A(S[a], S[b]);
  }
  const Eigen::VectorXd zs = Ass.completeOrthogonalDecomposition().solve(qs);
  Eigen::VectorXd z = Eigen::VectorXd::Zero(m);
  for (int a = 0; a < s; ++a) z[S[a]] = std::max(zs[a], 0.0);
  const Eigen::VectorXd w = A * z + q;
  const double res = lcp_residual(w, z, A.diagonal());
  if (res <= out.residual) out.z = z, out.w = w, out.residual = res;
}

}  // namespace

LcpResult solve_lcp_dense(const Eigen::MatrixXd& A, const Eigen::VectorXd& q, const LcpOptions& options) {
  const int m = static_cast<int>(q.size());
  if (A.rows() != m || A.cols() != m)
    fail("solve_lcp_dense: A must be " + std::to_string(m) + " x " + std::to_string(m) + ", got " +
         std::to_string(A.rows()) + " x " + std::to_string(A.cols()));
  if (!A.allFinite() || !q.allFinite()) fail("solve_lcp_dense: A and q must be finite");
  check_lcp_options(options);
  const int max_it = options.max_iterations > 0 ? options.max_iterations : 10 * m + 100;

  LcpResult out;
  out.z = Eigen::VectorXd::Zero(m);
  // q >= 0: z = 0 is the solution.
  if (m == 0 || q.minCoeff() >= 0.0) {
    out.w = q;
    out.converged = true;
    return out;
  }

  LemkeTableau tableau(A, q);
  const bool done = tableau.run(q, max_it, out.iterations);
  // Read z from the basis and polish it on the active set (A_SS z_S = -q_S) when that is at least as good.
  out.z = tableau.z();
  out.w = A * out.z + q;
  out.residual = lcp_residual(out.w, out.z, A.diagonal());
  if (done) polish(A, q, tableau.active(), out);
  out.converged = done && out.residual <= options.tolerance;
  return out;
}

}  // namespace lumen::physics
