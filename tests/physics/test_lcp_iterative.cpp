// The iterative LCP solvers (PGS, NNCG) against independent truths: brute-force enumeration on small
// semidefinite problems, Lemke's pivoting on contact-like problems A = H K^-1 H^T; warm starts, the sweep budget
// and its reported residual, NNCG against PGS on an ill-conditioned stack, degenerate and invalid inputs.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "physics/lcp.hpp"
#include "physics/lcp_iterative.hpp"
#include "support/lcp.hpp"

namespace lumen::physics {
namespace {

using Solver = std::function<LcpResult(const Eigen::MatrixXd&, const Eigen::VectorXd&, const IterativeLcpOptions&)>;

// The solvers under test, with a name for messages (PGS also over-relaxed).
struct Named {
  std::string name;
  Solver solve;
};
std::vector<Named> solvers() {
  const Solver sor = [](const Eigen::MatrixXd& A, const Eigen::VectorXd& q, const IterativeLcpOptions& o) {
    IterativeLcpOptions over = o;
    over.relaxation = 1.3;
    return solve_lcp_pgs(A, q, over);
  };
  return {{"pgs", solve_lcp_pgs}, {"pgs omega 1.3", sor}, {"nncg", solve_lcp_nncg}};
}

// A solvable semidefinite problem by construction: q = w* - A z* from a complementary pair (z*, w*).
Eigen::VectorXd solvable_q(const Eigen::MatrixXd& A, std::mt19937& rng) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const Eigen::Index m = A.rows();
  Eigen::VectorXd zs = Eigen::VectorXd::Zero(m), ws = Eigen::VectorXd::Zero(m);
  for (Eigen::Index i = 0; i < m; ++i) (u01(rng) < 0.6 ? zs[i] : ws[i]) = u01(rng);
  return ws - A * zs;
}

// A contact-like problem: K (3n x 3n, SPD, sparse: springs along a random graph of n nodes, each node tied to
// the ground by a weaker spring, N/m), rows of H (m x 3n) a unit normal on one node against the same normal on
// another (vertex-face-like), A = H K^-1 H^T (m/N), q = H u_free - gap (metres, mixed signs).
struct ContactProblem {
  Eigen::MatrixXd A;
  Eigen::VectorXd q;
};
ContactProblem contact_problem(int n_nodes, int m, double ground, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> nd;
  std::uniform_int_distribution<int> node(0, n_nodes - 1);
  const int dofs = 3 * n_nodes;
  constexpr double kSpring = 1e3;      // N/m, node-to-node
  constexpr double kGapScale = 1e-3;   // metres
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(dofs, dofs);
  const auto spring = [&](int a, int b) {
    for (int k = 0; k < 3; ++k) {
      K(3 * a + k, 3 * a + k) += kSpring;
      K(3 * b + k, 3 * b + k) += kSpring;
      K(3 * a + k, 3 * b + k) -= kSpring;
      K(3 * b + k, 3 * a + k) -= kSpring;
    }
  };
  for (int a = 1; a < n_nodes; ++a) spring(a - 1, a);                // a chain keeps the graph connected
  for (int e = 0; e < 2 * n_nodes; ++e) {
    const int a = node(rng), b = node(rng);
    if (a != b) spring(a, b);
  }
  K.diagonal().array() += ground * kSpring;
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(m, dofs);
  for (int i = 0; i < m; ++i) {
    const Eigen::Vector3d nrm = Eigen::Vector3d(nd(rng), nd(rng), nd(rng)).normalized();
    const int a = node(rng);
    int b = node(rng);
    if (b == a) b = (a + 1) % n_nodes;
    H.block<1, 3>(i, 3 * a) += nrm.transpose();
    H.block<1, 3>(i, 3 * b) -= nrm.transpose();
  }
  ContactProblem p;
  const Eigen::MatrixXd KinvHt = K.llt().solve(H.transpose());
  p.A = H * KinvHt;
  p.A = 0.5 * (p.A + p.A.transpose());
  p.q.resize(m);
  for (int i = 0; i < m; ++i) p.q[i] = kGapScale * nd(rng);
  return p;
}

// A pinch-like problem: a soft square membrane of side x side nodes (springs to the 4 neighbours, N/m, and a
// weak ground spring), its central c x c patch pressed onto a plane (rows on the nodes' heights), every contact
// pushing: strongly coupled rows, A = H K^-1 H^T (m/N), q the penetration (metres, deepest at the centre).
ContactProblem patch_problem(int c) {
  const int side = 2 * c + 4, n = side * side, dofs = 3 * n;
  constexpr double kSpring = 1e3;   // N/m
  constexpr double kGround = 0.01;  // ground spring, relative to kSpring
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(dofs, dofs);
  for (int i = 0; i < side; ++i)
    for (int j = 0; j < side; ++j)
      for (const int b : {i + 1 < side ? (i + 1) * side + j : -1, j + 1 < side ? i * side + j + 1 : -1}) {
        if (b < 0) continue;
        const int a = i * side + j;
        for (int k = 0; k < 3; ++k) {
          K(3 * a + k, 3 * a + k) += kSpring;
          K(3 * b + k, 3 * b + k) += kSpring;
          K(3 * a + k, 3 * b + k) -= kSpring;
          K(3 * b + k, 3 * a + k) -= kSpring;
        }
      }
  K.diagonal().array() += kGround * kSpring;
  const int m = c * c, o = (side - c) / 2;
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(m, dofs);
  ContactProblem p;
  p.q.resize(m);
  for (int r = 0; r < m; ++r) {
    const int i = o + r / c, j = o + r % c;
    H(r, 3 * (i * side + j) + 2) = 1.0;
    const double x = (i - 0.5 * side) / c, y = (j - 0.5 * side) / c;
    p.q[r] = -1e-3 * (1.0 - 0.5 * (x * x + y * y));
  }
  p.A = H * K.llt().solve(H.transpose());
  p.A = 0.5 * (p.A + p.A.transpose());
  return p;
}

// The conditions of a solution to tolerance tol: z >= 0, w = A z + q >= -tol, |w_i| <= tol where z_i > 0.
void expect_solution(const Eigen::MatrixXd& A, const Eigen::VectorXd& q, const LcpResult& r, double tol,
                     const std::string& what) {
  ASSERT_EQ(r.z.size(), q.size()) << what;
  if (q.size() == 0) return;
  EXPECT_GE(r.z.minCoeff(), 0.0) << what;
  EXPECT_LE((r.w - (A * r.z + q)).cwiseAbs().maxCoeff(), 1e-12 * (1.0 + q.cwiseAbs().maxCoeff())) << what;
  EXPECT_DOUBLE_EQ(r.residual, lcp_residual(r.w, r.z, A.diagonal())) << what;
  EXPECT_LE(r.residual, tol) << what;
}

// Random positive definite and rank-deficient semidefinite problems (m <= 10, duplicated rows), against the
// brute-force enumeration of every active set: the same w (unique for a semidefinite LCP), and the same z where
// A is positive definite (z unique).
TEST(IterativeLcp, MatchesBruteForceOnDefiniteAndSemidefiniteProblems) {
  std::mt19937 rng(91);
  std::normal_distribution<double> nd;
  int deficient = 0;
  for (int trial = 0; trial < 120; ++trial) {
    const int m = 1 + trial % 10;
    const bool full = trial % 3 == 0;
    const int rank = full ? m + 2 : 1 + (trial / 3) % m;
    Eigen::MatrixXd B(m, rank);
    for (int i = 0; i < B.size(); ++i) B.data()[i] = nd(rng);
    if (trial % 4 == 1 && m > 1) B.row(m - 1) = B.row(0);  // a duplicated row (its q differs)
    const Eigen::MatrixXd A = B * B.transpose();
    const Eigen::VectorXd q = solvable_q(A, rng);
    const double scale = 1.0 + q.cwiseAbs().maxCoeff();
    const bool definite = Eigen::LLT<Eigen::MatrixXd>(A).info() == Eigen::Success &&
                          A.ldlt().vectorD().minCoeff() > 1e-6 * A.diagonal().maxCoeff();
    deficient += !definite;
    Eigen::VectorXd zb, wb;
    ASSERT_TRUE(test::brute_force_lcp(A, q, scale, zb, wb)) << "trial " << trial;
    IterativeLcpOptions opt;
    opt.tolerance = 1e-9 * scale;
    opt.max_sweeps = 2000000;  // nearly singular active sets take PGS a few 1e5 sweeps (m <= 10: milliseconds)
    for (const Named& s : solvers()) {
      const std::string what = s.name + " trial " + std::to_string(trial) + " m " + std::to_string(m);
      const LcpResult r = s.solve(A, q, opt);
      ASSERT_TRUE(r.converged) << what << " residual " << r.residual;
      expect_solution(A, q, r, opt.tolerance, what);
      EXPECT_LE((r.w - wb).cwiseAbs().maxCoeff(), 1e-5 * scale) << what;
      if (definite) {
        EXPECT_LE((r.z - zb).cwiseAbs().maxCoeff(), 1e-5 * (1.0 + zb.cwiseAbs().maxCoeff())) << what;
      }
    }
  }
  EXPECT_GT(deficient, 40);
}

// Contact-like problems (m = 50..300, A positive definite: fewer rows than DOFs, generic normals) against
// Lemke's pivoting: the same z and w.
TEST(IterativeLcp, MatchesLemkeOnContactLikeProblems) {
  int pushing = 0;
  for (const int m : {50, 120, 200, 300}) {
    const ContactProblem p = contact_problem(m / 2 + 20, m, 0.05, 100u + static_cast<unsigned>(m));
    const LcpResult lemke = solve_lcp_dense(p.A, p.q);
    ASSERT_TRUE(lemke.converged) << "m " << m;
    const double qmax = p.q.cwiseAbs().maxCoeff();
    IterativeLcpOptions opt;
    opt.tolerance = 1e-10 * qmax;
    opt.max_sweeps = 100000;
    for (const Named& s : solvers()) {
      const std::string what = s.name + " m " + std::to_string(m);
      const LcpResult r = s.solve(p.A, p.q, opt);
      ASSERT_TRUE(r.converged) << what << " residual " << r.residual << " after " << r.iterations;
      expect_solution(p.A, p.q, r, opt.tolerance, what);
      EXPECT_LE((r.w - lemke.w).cwiseAbs().maxCoeff(), 1e-7 * qmax) << what;
      const double zmax = lemke.z.cwiseAbs().maxCoeff();
      EXPECT_LE((r.z - lemke.z).cwiseAbs().maxCoeff(), 1e-5 * zmax) << what;
    }
    for (Eigen::Index i = 0; i < lemke.z.size(); ++i) pushing += lemke.z[i] > 0.0;
  }
  EXPECT_GT(pushing, 100);  // many active contacts, not a trivial z = 0
}

// Warm started from the exact (Lemke) solution, the solvers stop within one sweep; from a perturbed solution
// they need fewer sweeps than from cold.
TEST(IterativeLcp, WarmStartFromTheSolutionConvergesInOneSweep) {
  const ContactProblem p = contact_problem(80, 120, 0.05, 7u);
  const LcpResult lemke = solve_lcp_dense(p.A, p.q);
  ASSERT_TRUE(lemke.converged);
  IterativeLcpOptions opt;
  opt.tolerance = 1e-9 * p.q.cwiseAbs().maxCoeff();
  opt.max_sweeps = 100000;
  for (const Named& s : solvers()) {
    IterativeLcpOptions warm = opt;
    warm.warm = lemke.z;
    const LcpResult r = s.solve(p.A, p.q, warm);
    EXPECT_TRUE(r.converged) << s.name;
    EXPECT_LE(r.iterations, 1) << s.name;
    warm.warm = lemke.z * 1.01;
    const LcpResult near = s.solve(p.A, p.q, warm);
    const LcpResult cold = s.solve(p.A, p.q, opt);
    ASSERT_TRUE(near.converged && cold.converged) << s.name;
    EXPECT_LT(near.iterations, cold.iterations) << s.name;
  }
}

// An ill-conditioned stack: kNodes unit masses in a column on the ground, a contact row under each (ground and
// neighbours): A = J M^-1 J^T is the tridiagonal (-1, 2, -1) (condition ~ kNodes^2), every row violated and
// every contact pushing at the solution (A^-1 > 0). A larger budget never gives a larger residual (beyond
// rounding), and NNCG reaches the tolerance in fewer than half of PGS's sweeps; on a pinch-like patch, in fewer.
TEST(IterativeLcp, NncgNeedsFewerSweepsThanPgsOnAnIllConditionedStack) {
  constexpr int kNodes = 60;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(kNodes, kNodes);
  for (int a = 0; a < kNodes; ++a) {
    A(a, a) = 2.0;
    if (a + 1 < kNodes) A(a, a + 1) = A(a + 1, a) = -1.0;
  }
  Eigen::VectorXd q(kNodes);
  for (int a = 0; a < kNodes; ++a) q[a] = -1e-3 * (1.0 + 0.5 * std::sin(0.3 * a));  // metres, every row violated
  IterativeLcpOptions opt;
  opt.tolerance = 1e-9 * q.cwiseAbs().maxCoeff();
  opt.max_sweeps = 200000;
  const LcpResult pgs = solve_lcp_pgs(A, q, opt);
  const LcpResult nncg = solve_lcp_nncg(A, q, opt);
  ASSERT_TRUE(pgs.converged) << pgs.residual;
  ASSERT_TRUE(nncg.converged) << nncg.residual;
  EXPECT_LT(2 * nncg.iterations, pgs.iterations) << "nncg " << nncg.iterations << " pgs " << pgs.iterations;
  EXPECT_EQ((nncg.z.array() > 0.0).count(), kNodes);
  std::printf("stack of %d: sweeps to %.1e: pgs %d, nncg %d\n", kNodes, opt.tolerance, pgs.iterations, nncg.iterations);
  // The same on the pinch-like patch (every contact pushing), where plain PGS does comparatively well.
  const ContactProblem patch = patch_problem(6);
  IterativeLcpOptions popt = opt;
  popt.tolerance = 1e-9 * patch.q.cwiseAbs().maxCoeff();
  const LcpResult ppgs = solve_lcp_pgs(patch.A, patch.q, popt);
  const LcpResult pnncg = solve_lcp_nncg(patch.A, patch.q, popt);
  ASSERT_TRUE(ppgs.converged && pnncg.converged);
  EXPECT_LT(pnncg.iterations, ppgs.iterations);
  EXPECT_GT((pnncg.z.array() > 0.0).count(), 24);  // most contacts pushing
  std::printf("patch of 36: sweeps to %.1e: pgs %d, nncg %d\n", popt.tolerance, ppgs.iterations, pnncg.iterations);
  const LcpResult lemke = solve_lcp_dense(A, q);
  ASSERT_TRUE(lemke.converged);
  EXPECT_LE((nncg.w - lemke.w).cwiseAbs().maxCoeff(), 1e-8 * q.cwiseAbs().maxCoeff());
  // Residual against the budget.
  for (const Named& s : solvers()) {
    double last = HUGE_VAL;
    for (int budget = 1; budget <= 4096; budget *= 4) {
      IterativeLcpOptions b = opt;
      b.max_sweeps = budget;
      const LcpResult r = s.solve(A, q, b);
      EXPECT_EQ(r.iterations, r.converged ? r.iterations : budget) << s.name;
      EXPECT_LE(r.residual, last * (1.0 + 1e-9)) << s.name << " budget " << budget;
      last = r.residual;
    }
  }
}

// A budget of one sweep on a problem that needs more: converged = false, a finite residual above the tolerance,
// and still z >= 0 with w = A z + q.
TEST(IterativeLcp, OneSweepBudgetReportsNonConvergence) {
  const ContactProblem p = contact_problem(60, 100, 0.05, 11u);
  IterativeLcpOptions opt;
  opt.tolerance = 1e-10 * p.q.cwiseAbs().maxCoeff();
  opt.max_sweeps = 1;
  for (const Named& s : solvers()) {
    const LcpResult r = s.solve(p.A, p.q, opt);
    EXPECT_FALSE(r.converged) << s.name;
    EXPECT_EQ(r.iterations, 1) << s.name;
    EXPECT_TRUE(std::isfinite(r.residual)) << s.name;
    EXPECT_GT(r.residual, opt.tolerance) << s.name;
    EXPECT_GE(r.z.minCoeff(), 0.0) << s.name;
    EXPECT_LE((r.w - (p.A * r.z + p.q)).cwiseAbs().maxCoeff(), 1e-12) << s.name;
  }
}

// No rows; nothing violated (z = 0 without a sweep); rows no force can move (A_ii = 0) keep z = 0.
TEST(IterativeLcp, DegenerateInputs) {
  for (const Named& s : solvers()) {
    const LcpResult empty = s.solve(Eigen::MatrixXd(0, 0), Eigen::VectorXd(0), {});
    EXPECT_TRUE(empty.converged) << s.name;
    EXPECT_EQ(empty.z.size(), 0) << s.name;
    EXPECT_EQ(empty.iterations, 0) << s.name;

    const ContactProblem p = contact_problem(20, 30, 0.05, 3u);
    const Eigen::VectorXd q = p.q.cwiseAbs();
    const LcpResult free = s.solve(p.A, q, {});
    EXPECT_TRUE(free.converged) << s.name;
    EXPECT_EQ(free.iterations, 0) << s.name;
    EXPECT_EQ(free.z, Eigen::VectorXd::Zero(30)) << s.name;

    // Rows 0 and 3 no force can move (zero row and column), row 3 violated: z = 0 there, the rest solved.
    Eigen::MatrixXd A = p.A;
    Eigen::VectorXd qv = p.q;
    for (const int i : {0, 3}) {
      A.row(i).setZero();
      A.col(i).setZero();
    }
    qv[3] = -1.0;
    IterativeLcpOptions opt;
    opt.tolerance = 1e-10;
    opt.max_sweeps = 2000;
    opt.warm = Eigen::VectorXd::Ones(30);
    const LcpResult fixed = s.solve(A, qv, opt);
    EXPECT_EQ(fixed.z[0], 0.0) << s.name;
    EXPECT_EQ(fixed.z[3], 0.0) << s.name;
    EXPECT_FALSE(fixed.converged) << s.name;  // row 3 stays violated
    EXPECT_DOUBLE_EQ(fixed.residual, 1.0) << s.name;
  }
}

TEST(IterativeLcp, ValidatesInputs) {
  const Eigen::Matrix2d A = Eigen::Matrix2d::Identity();
  const Eigen::Vector2d q(-1.0, 1.0);
  IterativeLcpOptions ok;
  for (const Named& s : solvers()) {
    EXPECT_THROW(s.solve(Eigen::MatrixXd::Identity(3, 3), q, ok), std::invalid_argument) << s.name;
    Eigen::MatrixXd asym = A;
    asym(0, 1) = 0.5;
    EXPECT_THROW(s.solve(asym, q, ok), std::invalid_argument) << s.name;
    EXPECT_THROW(s.solve(A, Eigen::Vector2d(NAN, 0.0), ok), std::invalid_argument) << s.name;
    IterativeLcpOptions bad = ok;
    bad.max_sweeps = 0;
    EXPECT_THROW(s.solve(A, q, bad), std::invalid_argument) << s.name;
    bad = ok;
    bad.tolerance = -1.0;
    EXPECT_THROW(s.solve(A, q, bad), std::invalid_argument) << s.name;
    bad = ok;
    bad.warm = Eigen::VectorXd::Ones(3);
    EXPECT_THROW(s.solve(A, q, bad), std::invalid_argument) << s.name;
    EXPECT_TRUE(s.solve(A, q, ok).converged) << s.name;
  }
  IterativeLcpOptions bad = ok;
  bad.relaxation = 2.0;
  EXPECT_THROW(solve_lcp_pgs(A, q, bad), std::invalid_argument);
}

}  // namespace
}  // namespace lumen::physics
