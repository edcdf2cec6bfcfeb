// Contact solves: equality rows, non-penetration LCP (Lemke, or active set with a Lemke fallback), held points.
#include "physics/contact_solve.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <string>

#include "physics/detail/messages.hpp"

namespace lumen::physics {

using detail::fail;

namespace {

// Force, correction (whole mesh: a sum of precomputed columns or one back-substitution; else on the set and the
// rows' nodes) and the row values after correction.
Eigen::VectorXd finish(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows,
                       const Eigen::VectorXd& u_free, ContactResult& out, bool whole_mesh = true) {
  const int n = compliance.solver().n_dofs();
  out.force = contact_force(rows, out.lambda, n);
  if (whole_mesh) {
    compliance.displacement(out.force, out.correction);
  } else {
    std::vector<int> also;
    for (const ContactRow& r : rows)
      for (int k = 0; k < 4; ++k)
        if (r.node[k] >= 0 && compliance.index_of(r.node[k]) < 0) also.push_back(r.node[k]);
    std::sort(also.begin(), also.end());
    also.erase(std::unique(also.begin(), also.end()), also.end());
    compliance.displacement_on_set(out.force, out.correction, also);
  }
  return row_values(rows, u_free + out.correction);
}

void check_u_free(const SurfaceCompliance& compliance, const Eigen::VectorXd& u_free, const char* who) {
  if (u_free.size() != compliance.solver().n_dofs())
    fail(std::string(who) + ": u_free must have " + std::to_string(compliance.solver().n_dofs()) + " entries, got " +
         std::to_string(u_free.size()));
  if (!u_free.allFinite()) fail(std::string(who) + ": u_free must be finite");
}

}  // namespace

ContactResult solve_equality(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows,
                             const Eigen::VectorXd& u_free, double tolerance, bool whole_mesh) {
  check_u_free(compliance, u_free, "solve_equality");
  const int m = static_cast<int>(rows.size());
  ContactResult out;
  out.iterations = 1;
  Eigen::VectorXd g(m);
  for (int r = 0; r < m; ++r) g[r] = rows[r].g;
  // A lambda = g - H u_free: Cholesky on the rows with a non-zero diagonal (the others touch only fixed DOFs:
  // no force moves them, lambda = 0 is their minimum-norm value), else minimum-norm least squares on all.
  const Eigen::MatrixXd A = coupling_matrix(compliance, rows);
  const Eigen::VectorXd b = g - row_values(rows, u_free);
  std::vector<int> live;
  const double dmax = m > 0 ? A.diagonal().cwiseAbs().maxCoeff() : 0.0;
  for (int r = 0; r < m; ++r)
    if (A(r, r) > 1e-14 * dmax) live.push_back(r);
  const int ml = static_cast<int>(live.size());
  Eigen::MatrixXd All(ml, ml);
  Eigen::VectorXd bl(ml);
  for (int i = 0; i < ml; ++i) {
    bl[i] = b[live[i]];
    for (int j = 0; j < ml; ++j) All(i, j) = A(live[i], live[j]);
  }
  Eigen::LLT<Eigen::MatrixXd> llt(All);
  out.lambda = Eigen::VectorXd::Zero(m);
  if (ml > 0 && llt.info() == Eigen::Success) {
    const Eigen::VectorXd zl = llt.solve(bl);
    for (int i = 0; i < ml; ++i) out.lambda[live[i]] = zl[i];
  } else if (m > 0) {
    out.lambda = A.completeOrthogonalDecomposition().solve(b);
  }
  const Eigen::VectorXd h = finish(compliance, rows, u_free, out, whole_mesh);
  out.residual = m > 0 ? (h - g).cwiseAbs().maxCoeff() : 0.0;
  out.converged = out.residual <= tolerance;
  return out;
}

ContactResult solve_lcp(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows,
                        const Eigen::VectorXd& u_free, const LcpOptions& options) {
  check_u_free(compliance, u_free, "solve_lcp");
  const int m = static_cast<int>(rows.size());
  Eigen::VectorXd g(m);
  for (int r = 0; r < m; ++r) g[r] = rows[r].g;
  // w = A lambda + (H u_free - g) >= 0, lambda >= 0, complementary.
  const Eigen::MatrixXd A = coupling_matrix(compliance, rows);
  const LcpResult lcp = solve_lcp_dense(A, row_values(rows, u_free) - g, options);
  ContactResult out;
  out.lambda = lcp.z;
  out.iterations = lcp.iterations;
  const Eigen::VectorXd h = finish(compliance, rows, u_free, out);
  out.residual = lcp_residual(h - g, out.lambda);  // (g - H u)^+, |H u - g| where lambda > 0
  out.converged = lcp.converged && out.residual <= options.tolerance;
  return out;
}

namespace {

// The held points' coupling to the rows: G = H U (how each row's value moves per unit force at the held points,
// rows x 3d, m/N) and G S (rows x 3d); empty without held points. Validates their shapes.
struct HeldCoupling {
  Eigen::MatrixXd G, GS;
};
HeldCoupling held_coupling(const std::vector<ContactRow>& rows, const HeldPoints* held, int n, const char* who) {
  HeldCoupling hc;
  if (!held) return hc;
  const int m = static_cast<int>(rows.size()), d3 = static_cast<int>(held->U.cols());
  if (held->U.rows() != n || held->S.rows() != d3 || held->S.cols() != d3 ||
      static_cast<int>(held->points.size()) * 3 != d3)
    fail(std::string(who) + ": held points must have U 3n x 3d, S 3d x 3d and d points, got U " +
         std::to_string(held->U.rows()) + " x " + std::to_string(d3) + ", S " + std::to_string(held->S.rows()) + " x " +
         std::to_string(held->S.cols()) + ", " + std::to_string(held->points.size()) + " points");
  hc.G.resize(m, d3);
  for (int r = 0; r < m; ++r) {
    hc.G.row(r).setZero();
    for (int k = 0; k < 4; ++k)
      if (rows[r].node[k] >= 0)
        hc.G.row(r) += rows[r].weight[k] * rows[r].n.transpose() * held->U.middleRows(3 * rows[r].node[k], 3);
  }
  hc.GS = hc.G * held->S;
  return hc;
}

// The result of the LCP's multipliers: force and correction (finish), the held points' force change -S G^T lambda
// joining both, and the residual of the rows at u_free + correction.
void finish_contacts(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows, const Eigen::VectorXd& u_free,
                     const HeldPoints* held, const HeldCoupling& hc, const Eigen::VectorXd& g, bool whole_mesh,
                     ContactResult& out) {
  Eigen::VectorXd h = finish(compliance, rows, u_free, out, whole_mesh);
  if (held) {
    out.held_force = -(hc.GS.transpose() * out.lambda);
    out.correction += held->U * out.held_force;
    for (int p = 0; p < static_cast<int>(held->points.size()); ++p)
      for (int k = 0; k < 3; ++k)
        if (held->points[p].node[k] >= 0)
          out.force.segment<3>(3 * held->points[p].node[k]) += held->points[p].weight[k] * out.held_force.segment<3>(3 * p);
    h = row_values(rows, u_free + out.correction);
  }
  out.residual = lcp_residual(h - g, out.lambda);  // (g - H u)^+, |H u - g| where lambda > 0
}

Eigen::VectorXd row_targets(const std::vector<ContactRow>& rows) {
  Eigen::VectorXd g(static_cast<Eigen::Index>(rows.size()));
  for (size_t r = 0; r < rows.size(); ++r) g[static_cast<Eigen::Index>(r)] = rows[r].g;
  return g;
}

}  // namespace

ContactResult solve_contacts(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows,
                             const Eigen::VectorXd& u_free, const std::vector<int>& warm, const LcpOptions& options,
                             bool whole_mesh, const HeldPoints* held) {
  check_u_free(compliance, u_free, "solve_contacts");
  const int m = static_cast<int>(rows.size());
  for (size_t i = 0; i < warm.size(); ++i)
    if (warm[i] < 0 || warm[i] >= m)
      fail("solve_contacts: warm[" + std::to_string(i) + "] must be a row index in [0, " + std::to_string(m) +
           "), got " + std::to_string(warm[i]));
  const HeldCoupling hc = held_coupling(rows, held, compliance.solver().n_dofs(), "solve_contacts");
  const Eigen::VectorXd g = row_targets(rows);
  // w = A' lambda + (H u_free - g), A' = A - G S G^T: active set on columns computed on demand, Lemke if that fails.
  CouplingMatrix A(compliance, rows);
  std::vector<Eigen::VectorXd> held_columns(held ? m : 0);
  auto column = [&](int j) -> const Eigen::VectorXd& {
    if (!held) return A.column(j);
    if (held_columns[j].size() == 0) held_columns[j] = A.column(j) - hc.G * hc.GS.row(j).transpose();
    return held_columns[j];
  };
  const Eigen::VectorXd q = row_values(rows, u_free) - g;
  LcpResult lcp = solve_lcp_active_set(column, q, warm, options);
  ContactResult out;
  if (!lcp.converged) {
    const int rounds = lcp.iterations;
    Eigen::MatrixXd dense = A.dense();
    if (held) dense -= hc.G * hc.GS.transpose();
    lcp = solve_lcp_dense(0.5 * (dense + dense.transpose()), q, options);
    lcp.iterations += rounds;
    out.used_lemke = true;
  }
  out.lambda = lcp.z;
  out.iterations = lcp.iterations;
  finish_contacts(compliance, rows, u_free, held, hc, g, whole_mesh, out);
  out.converged = lcp.converged && out.residual <= options.tolerance;
  return out;
}

ContactResult solve_contacts_iterative(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows,
                                       const Eigen::VectorXd& u_free, const IterativeLcpOptions& options,
                                       bool whole_mesh, const HeldPoints* held) {
  check_u_free(compliance, u_free, "solve_contacts_iterative");
  const HeldCoupling hc = held_coupling(rows, held, compliance.solver().n_dofs(), "solve_contacts_iterative");
  const Eigen::VectorXd g = row_targets(rows);
  // All of A' = A - G S G^T (symmetric), then NNCG within the sweep budget from the warm start.
  Eigen::MatrixXd A = CouplingMatrix(compliance, rows).dense();
  if (held) A -= hc.G * hc.GS.transpose();
  A = 0.5 * (A + A.transpose());
  const LcpResult lcp = solve_lcp_nncg(A, row_values(rows, u_free) - g, options);
  ContactResult out;
  out.lambda = lcp.z;
  out.iterations = lcp.iterations;
  finish_contacts(compliance, rows, u_free, held, hc, g, whole_mesh, out);
  out.converged = out.residual <= options.tolerance;
  return out;
}

}  // namespace lumen::physics
