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
                       const Eigen::VectorXd& u_free, ContactResult& out, bool whole_mesh = true,
                       const Eigen::VectorXd* extra_force = nullptr) {
  const int n = compliance.solver().n_dofs();
  out.force = contact_force(rows, out.lambda, n);
  if (extra_force) out.force += *extra_force;
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
  const Eigen::VectorXd g = row_targets(rows);
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
  const Eigen::VectorXd g = row_targets(rows);
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
// rows x 3d, m/N) and G S (rows x 3d); empty without held points.
struct HeldCoupling {
  Eigen::MatrixXd G, GS;
};

// Checks the held points' shapes: U 3n x 3d (or empty), S 3d x 3d, d points.
void check_held(const HeldPoints& held, int n, const char* who) {
  const int d3 = 3 * static_cast<int>(held.points.size());
  const bool u_ok = !held.has_columns() || (held.U.rows() == n && held.U.cols() == d3);
  if (!u_ok || held.S.rows() != d3 || held.S.cols() != d3)
    fail(std::string(who) + ": held points must have U 3n x 3d (or empty), S 3d x 3d and d points, got U " +
         std::to_string(held.U.rows()) + " x " + std::to_string(held.U.cols()) + ", S " +
         std::to_string(held.S.rows()) + " x " + std::to_string(held.S.cols()) + ", " +
         std::to_string(held.points.size()) + " points");
}

// Row r of G from the columns U: sum over the row's nodes of w n^T U(node rows).
Eigen::RowVectorXd coupling_row_from_columns(const ContactRow& row, const HeldPoints& held) {
  Eigen::RowVectorXd g = Eigen::RowVectorXd::Zero(held.S.cols());
  for (int k = 0; k < 4; ++k)
    if (row.node[k] >= 0) g += row.weight[k] * row.n.transpose() * held.U.middleRows(3 * row.node[k], 3);
  return g;
}

// Row r of G from the compliance's blocks: per held point, sum over the row's and the point's nodes of
// w_row w_point n^T K^-1(row node, point node).
Eigen::RowVectorXd coupling_row_from_blocks(SurfaceCompliance& compliance, const ContactRow& row,
                                            const HeldPoints& held) {
  Eigen::RowVectorXd g = Eigen::RowVectorXd::Zero(held.S.cols());
  for (size_t p = 0; p < held.points.size(); ++p) {
    const LoadPoint& lp = held.points[p];
    for (int k = 0; k < 4; ++k) {
      if (row.node[k] < 0) continue;
      for (int j = 0; j < 3; ++j)
        if (lp.node[j] >= 0)
          g.segment<3>(3 * static_cast<Eigen::Index>(p)) +=
              row.weight[k] * lp.weight[j] * row.n.transpose() * compliance.block(row.node[k], lp.node[j]);
    }
  }
  return g;
}

HeldCoupling held_coupling(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows,
                           const HeldPoints* held, const char* who) {
  HeldCoupling hc;
  if (!held) return hc;
  check_held(*held, compliance.solver().n_dofs(), who);
  const int m = static_cast<int>(rows.size()), d3 = static_cast<int>(held->S.rows());
  hc.G.resize(m, d3);
  for (int r = 0; r < m; ++r)
    hc.G.row(r) = held->has_columns() ? coupling_row_from_columns(rows[r], *held)
                                      : coupling_row_from_blocks(compliance, rows[r], *held);
  hc.GS = hc.G * held->S;
  return hc;
}

// The result of the LCP's multipliers: force and correction (finish), the held points' force change -S G^T lambda
// joining both, and the residual of the rows at u_free + correction. Without columns the held forces join the
// contact force before its one displacement; with them, their columns are added to the contacts' correction.
void finish_contacts(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows, const Eigen::VectorXd& u_free,
                     const HeldPoints* held, const HeldCoupling& hc, const Eigen::VectorXd& g, bool whole_mesh,
                     ContactResult& out) {
  if (held && !held->has_columns()) {
    out.held_force = -(hc.GS.transpose() * out.lambda);
    const Eigen::VectorXd extra = point_forces(held->points, out.held_force, compliance.solver().n_dofs());
    const Eigen::VectorXd h = finish(compliance, rows, u_free, out, whole_mesh, &extra);
    out.residual = lcp_residual(h - g, out.lambda);
    return;
  }
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
  const HeldCoupling hc = held_coupling(compliance, rows, held, "solve_contacts");
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
  const HeldCoupling hc = held_coupling(compliance, rows, held, "solve_contacts_iterative");
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

Eigen::MatrixXd point_compliance(SurfaceCompliance& compliance, const std::vector<LoadPoint>& points) {
  const Eigen::Index d = static_cast<Eigen::Index>(points.size());
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(3 * d, 3 * d);
  // Block (a, b): sum over both points' nodes of w_a w_b K^-1(node_a, node_b).
  for (Eigen::Index a = 0; a < d; ++a)
    for (Eigen::Index b = 0; b < d; ++b) {
      const LoadPoint &pa = points[static_cast<size_t>(a)], &pb = points[static_cast<size_t>(b)];
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          if (pa.node[i] >= 0 && pb.node[j] >= 0)
            P.block<3, 3>(3 * a, 3 * b) += pa.weight[i] * pb.weight[j] * compliance.block(pa.node[i], pb.node[j]);
    }
  return P;
}

HeldPoints held_points_on(SurfaceCompliance& compliance, std::vector<LoadPoint> points) {
  HeldPoints held;
  held.points = std::move(points);
  const Eigen::Index d3 = 3 * static_cast<Eigen::Index>(held.points.size());
  // S = (E^T K^-1 E)^-1 by LDL^T (symmetric positive definite without fixed DOFs at the points).
  held.S = point_compliance(compliance, held.points).ldlt().solve(Eigen::MatrixXd::Identity(d3, d3));
  return held;
}

Eigen::VectorXd point_forces(const std::vector<LoadPoint>& points, const Eigen::VectorXd& f, int n_dofs) {
  if (f.size() != 3 * static_cast<Eigen::Index>(points.size()))
    fail("point_forces: f must have " + std::to_string(3 * points.size()) + " entries, got " + std::to_string(f.size()));
  Eigen::VectorXd nodal = Eigen::VectorXd::Zero(n_dofs);
  for (size_t p = 0; p < points.size(); ++p) add_point_force(points[p], f.segment<3>(3 * static_cast<Eigen::Index>(p)), nodal);
  return nodal;
}

void held_displacement(SurfaceCompliance& compliance, const HeldPoints& held, const Eigen::VectorXd& f,
                       Eigen::VectorXd& du) {
  check_held(held, compliance.solver().n_dofs(), "held_displacement");
  if (held.has_columns()) {
    du = held.U * f;
    return;
  }
  compliance.displacement(point_forces(held.points, f, compliance.solver().n_dofs()), du);
}

}  // namespace lumen::physics
