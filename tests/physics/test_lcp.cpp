// The active-set LCP solver against brute-force enumeration and Lemke's pivoting: random semidefinite problems
// with duplicate and dependent rows, warm starts, infeasible and trivial problems. (Moved as-is from
// tests/engine/test_response.cpp; brute_force_w is this file's brute-force LCP twin.)
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "physics/lcp.hpp"
#include "support/lcp.hpp"

namespace lumen::physics {
namespace {

// Brute-force twin (tests/support/lcp.hpp, every active set), tolerances relative to 1 + max |q|: w of the first
// solution found. For a positive semidefinite A, w is the same for every solution.
bool brute_force_w(const Eigen::MatrixXd& A, const Eigen::VectorXd& q, Eigen::VectorXd& w_out) {
  Eigen::VectorXd z;
  return test::brute_force_lcp(A, q, 1.0 + q.cwiseAbs().maxCoeff(), z, w_out);
}

// The conditions of a solution: z >= 0, w = A z + q >= 0, complementary.
void expect_lcp_solution(const Eigen::MatrixXd& A, const Eigen::VectorXd& q, const LcpResult& r, double tol,
                         const std::string& what) {
  ASSERT_EQ(r.z.size(), q.size()) << what;
  EXPECT_GE(r.z.minCoeff(), 0.0) << what;
  EXPECT_LE((r.w - (A * r.z + q)).norm(), 1e-10 * (1.0 + q.norm())) << what;
  EXPECT_GE(r.w.minCoeff(), -tol) << what;
  for (int i = 0; i < q.size(); ++i)
    if (r.z[i] > 0.0) {
      EXPECT_LE(std::abs(r.w[i]), tol) << what << " row " << i;
    }
}

// Random positive semidefinite problems (full rank, rank deficient, duplicated rows with different q) that are
// solvable by construction: q = w* - A z* from a complementary pair. The active set's w equals brute force's and
// Lemke's (w is unique for a semidefinite LCP).
TEST(ActiveSetLcp, MatchesBruteForceAndLemkeOnSemidefiniteProblems) {
  std::mt19937 rng(21);
  std::normal_distribution<double> nd;
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  int exchanges_possible = 0;
  for (int trial = 0; trial < 90; ++trial) {
    const int m = 2 + trial % 8;
    const int rank = trial % 3 == 0 ? m + 2 : 1 + (trial / 3) % m;  // full rank, or rank deficient
    Eigen::MatrixXd B(m, rank);
    for (int i = 0; i < B.size(); ++i) B.data()[i] = nd(rng);
    if (trial % 4 == 1) B.row(m - 1) = B.row(0);  // a duplicated row (its q differs)
    const Eigen::MatrixXd A = B * B.transpose();
    Eigen::VectorXd zs = Eigen::VectorXd::Zero(m), ws = Eigen::VectorXd::Zero(m);
    for (int i = 0; i < m; ++i) (u01(rng) < 0.6 ? zs[i] : ws[i]) = u01(rng);
    const Eigen::VectorXd q = ws - A * zs;
    exchanges_possible += rank < m;
    const std::string what = "trial " + std::to_string(trial);

    const LcpResult r = physics::solve_lcp_active_set(A, q);
    ASSERT_TRUE(r.converged) << what << " residual " << r.residual;
    expect_lcp_solution(A, q, r, 1e-9, what);
    Eigen::VectorXd wb;
    ASSERT_TRUE(brute_force_w(A, q, wb)) << what;
    EXPECT_LE((r.w - wb).norm(), 1e-8 * (1.0 + q.norm())) << what;
    const LcpResult lemke = physics::solve_lcp_dense(A, q);
    ASSERT_TRUE(lemke.converged) << what;
    EXPECT_LE((r.w - lemke.w).norm(), 1e-8 * (1.0 + q.norm())) << what;
  }
  EXPECT_GT(exchanges_possible, 30);
}

// Rows that are combinations of others (a dependent row enters while its parts are active: the exchange step)
// and exact duplicates with equal q (the copy must stay out). H rows act on u in R^3, A = H H^T, q = H u_free - g.
TEST(ActiveSetLcp, DependentAndDuplicateRows) {
  Eigen::MatrixXd H(4, 3), Hs(3, 3);
  H << 1, 0, 0,  // h0
      0, 1, 0,   // h1
      1, 1, 0,   // h2 = h0 + h1
      1, 0, 0;   // h3 = h0
  Hs << 1, 0, 0,  //
      0, 1, 0,    //
      0.1, 0.1, 0;  // a small multiple of h0 + h1: h0 and h1 enter first, then it must replace them
  struct Case {
    Eigen::MatrixXd H;
    Eigen::VectorXd g;
  };
  std::vector<Case> cases;
  for (const Eigen::Vector4d& g : {Eigen::Vector4d(0.0, 0.0, 0.5, 0.0), Eigen::Vector4d(-0.5, 0.0, 1.0, -0.5),
                                   Eigen::Vector4d(0.0, -3.0, 0.5, 0.0), Eigen::Vector4d(0.2, 0.1, 0.0, 0.2)})
    cases.push_back({H, g});
  cases.push_back({Hs, Eigen::Vector3d(0.0, 0.0, 0.05)});
  cases.push_back({Hs, Eigen::Vector3d(-0.5, 0.0, 0.05)});
  const Eigen::Vector3d u_free(-1.0, -1.0, 0.0);
  for (const Case& c : cases) {
    const Eigen::MatrixXd A = c.H * c.H.transpose();
    const Eigen::VectorXd q = c.H * u_free - c.g;
    const LcpResult r = physics::solve_lcp_active_set(A, q);
    ASSERT_TRUE(r.converged) << c.g.transpose();
    expect_lcp_solution(A, q, r, 1e-9, "dependent");
    Eigen::VectorXd wb;
    ASSERT_TRUE(brute_force_w(A, q, wb));
    EXPECT_LE((r.w - wb).norm(), 1e-10) << c.g.transpose();
    // The displacement u_free + H^T z is unique and satisfies every row.
    const Eigen::Vector3d u = u_free + c.H.transpose() * r.z;
    const LcpResult lemke = physics::solve_lcp_dense(A, q);
    EXPECT_LE((u - (u_free + c.H.transpose() * lemke.z)).norm(), 1e-10) << c.g.transpose();
    for (int i = 0; i < c.H.rows(); ++i) EXPECT_GE(c.H.row(i).dot(u), c.g[i] - 1e-9);
  }
  // The scaled case's solution pushes with the dependent row alone: u = (0.25, 0.25, 0).
  const Eigen::MatrixXd As = Hs * Hs.transpose();
  const LcpResult rs = physics::solve_lcp_active_set(As, Hs * u_free - Eigen::Vector3d(0.0, 0.0, 0.05));
  EXPECT_LE((u_free + Hs.transpose() * rs.z - Eigen::Vector3d(0.25, 0.25, 0.0)).norm(), 1e-12);
}

// Any warm-start guess (right, wrong, repeated, empty) gives the same solution; the right guess needs no round.
TEST(ActiveSetLcp, WarmStartGivesTheSameSolution) {
  std::mt19937 rng(22);
  std::normal_distribution<double> nd;
  std::uniform_int_distribution<int> coin(0, 1);
  for (int trial = 0; trial < 30; ++trial) {
    const int m = 3 + trial % 12;
    Eigen::MatrixXd B(m, m + 3);
    for (int i = 0; i < B.size(); ++i) B.data()[i] = nd(rng);
    const Eigen::MatrixXd A = B * B.transpose();  // positive definite: z unique
    Eigen::VectorXd q(m);
    for (int i = 0; i < m; ++i) q[i] = nd(rng);
    const LcpResult cold = physics::solve_lcp_active_set(A, q);
    ASSERT_TRUE(cold.converged);
    std::vector<int> right, guess;
    for (int i = 0; i < m; ++i) {
      if (cold.z[i] > 0.0) right.push_back(i);
      if (coin(rng)) guess.push_back(i);
    }
    guess.push_back(guess.empty() ? 0 : guess.front());  // a repeated index
    for (const auto& warm : {right, guess}) {
      const LcpResult r = physics::solve_lcp_active_set(A, q, warm);
      ASSERT_TRUE(r.converged) << "trial " << trial;
      EXPECT_LE((r.z - cold.z).norm(), 1e-10 * (1.0 + cold.z.norm())) << "trial " << trial;
    }
    EXPECT_EQ(physics::solve_lcp_active_set(A, q, right).iterations, 0) << "trial " << trial;
  }
}

TEST(ActiveSetLcp, InfeasibleAndTrivialProblems) {
  // x >= 1 and -x >= 1: the dependent row's null direction is unbounded.
  Eigen::MatrixXd A(2, 2);
  A << 1, -1, -1, 1;
  EXPECT_FALSE(physics::solve_lcp_active_set(A, Eigen::Vector2d(-1.0, -1.0)).converged);
  // A row no force can move (zero column) that is violated.
  Eigen::MatrixXd Z = Eigen::MatrixXd::Zero(2, 2);
  Z(0, 0) = 1.0;
  EXPECT_FALSE(physics::solve_lcp_active_set(Z, Eigen::Vector2d(-1.0, -1.0)).converged);
  // q >= 0: z = 0 without a round.
  const LcpResult r0 = physics::solve_lcp_active_set(Eigen::MatrixXd::Identity(3, 3), Eigen::Vector3d(1, 0, 2));
  EXPECT_TRUE(r0.converged);
  EXPECT_EQ(r0.z.norm(), 0.0);
  EXPECT_EQ(r0.iterations, 0);
  // Empty problem.
  EXPECT_TRUE(physics::solve_lcp_active_set(Eigen::MatrixXd(0, 0), Eigen::VectorXd(0)).converged);
  // Validation at the boundary.
  EXPECT_THROW(physics::solve_lcp_active_set(Eigen::MatrixXd::Identity(2, 2), Eigen::Vector3d::Ones()),
               std::invalid_argument);
  EXPECT_THROW(physics::solve_lcp_active_set(Eigen::MatrixXd::Identity(2, 2), -Eigen::Vector2d::Ones(), {2}),
               std::invalid_argument);
  physics::LcpOptions bad;
  bad.tolerance = -1.0;
  EXPECT_THROW(physics::solve_lcp_active_set(Eigen::MatrixXd::Identity(2, 2), -Eigen::Vector2d::Ones(), {}, bad),
               std::invalid_argument);
}

}  // namespace
}  // namespace lumen::physics
