// Test support: a brute-force twin for linear complementarity problems (find z >= 0 with w = A z + q >= 0 and
// z_i w_i = 0) by enumeration of every active set; for the few rows (m <= ~12) the tests use.
#pragma once

#include <vector>

#include <Eigen/Dense>

namespace lumen::test {

// Every active set S in increasing bit-mask order: A_SS z_S = -q_S solvable (least squares, residual at most
// 1e-9 * scale: consistent), z >= 0 (to 1e-12 relative) and w = A z + q >= -1e-9 * scale. Returns whether one
// was found, with the first such z and its w. For a positive semidefinite A, w is the same for every solution.
inline bool brute_force_lcp(const Eigen::MatrixXd& A, const Eigen::VectorXd& q, double scale, Eigen::VectorXd& z_out,
                            Eigen::VectorXd& w_out) {
  const int m = static_cast<int>(q.size());
  for (int mask = 0; mask < (1 << m); ++mask) {
    std::vector<int> S;
    for (int i = 0; i < m; ++i)
      if (mask & (1 << i)) S.push_back(i);
    Eigen::VectorXd z = Eigen::VectorXd::Zero(m);
    if (!S.empty()) {
      const int s = static_cast<int>(S.size());
      Eigen::MatrixXd Ass(s, s);
      Eigen::VectorXd qs(s);
      for (int a = 0; a < s; ++a) {
        qs[a] = -q[S[a]];
        for (int b = 0; b < s; ++b) Ass(a, b) = A(S[a], S[b]);
      }
      const Eigen::VectorXd zs = Ass.completeOrthogonalDecomposition().solve(qs);
      if ((Ass * zs - qs).norm() > 1e-9 * scale) continue;  // inconsistent
      for (int a = 0; a < s; ++a) z[S[a]] = zs[a];
    }
    const Eigen::VectorXd w = A * z + q;
    if (z.minCoeff() >= -1e-12 * (1.0 + z.cwiseAbs().maxCoeff()) && w.minCoeff() >= -1e-9 * scale) {
      z_out = z;
      w_out = w;
      return true;
    }
  }
  return false;
}

}  // namespace lumen::test
