// Load response, surface compliance and contact solves on a prefactorised FEM model.
#include "physics/compliance.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

namespace lumen::physics {

namespace {

[[noreturn]] void fail(const std::string& what) { throw std::invalid_argument(what); }

std::string num(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

// Validates a node id of a slot that may be unused (-1).
void check_slot(int node, int n_nodes, const std::string& name) {
  if (node < -1 || node >= n_nodes)
    fail(name + " must be -1 (unused) or a node id in [0, " + std::to_string(n_nodes) + "), got " +
         std::to_string(node));
}

void check_rows(const std::vector<ContactRow>& rows, int n_nodes) {
  for (size_t r = 0; r < rows.size(); ++r) {
    // Cheap test first; the message is built only for a bad row.
    const ContactRow& row = rows[r];
    int used = 0;
    bool ok = row.n.allFinite() && std::isfinite(row.g);
    for (int k = 0; k < 4; ++k) {
      ok = ok && row.node[k] >= -1 && row.node[k] < n_nodes && std::isfinite(row.weight[k]);
      used += row.node[k] >= 0;
    }
    if (ok && used > 0) continue;
    const std::string at = "ContactRow[" + std::to_string(r) + "]";
    for (int k = 0; k < 4; ++k) {
      check_slot(row.node[k], n_nodes, at + ".node[" + std::to_string(k) + "]");
      if (!std::isfinite(row.weight[k]))
        fail(at + ".weight[" + std::to_string(k) + "] must be finite, got " + num(row.weight[k]));
    }
    if (used == 0) fail(at + ".node must name at least one node, got none");
    if (!row.n.allFinite()) fail(at + ".n must be finite");
    fail(at + ".g must be finite, got " + num(row.g));
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------------
// LoadResponse

LoadResponse::LoadResponse(const StaticSolver& solver, const std::vector<LoadPoint>& points) : points_(points) {
  const int n = solver.n_dofs(), m = n_points();
  // Validate the points: node ids, finite weights, at least one node each.
  for (int p = 0; p < m; ++p) {
    int used = 0;
    for (int k = 0; k < 3; ++k) {
      const std::string at = "LoadPoint[" + std::to_string(p) + "]";
      check_slot(points_[p].node[k], n / 3, at + ".node[" + std::to_string(k) + "]");
      if (!std::isfinite(points_[p].weight[k]))
        fail(at + ".weight[" + std::to_string(k) + "] must be finite, got " + num(points_[p].weight[k]));
      used += points_[p].node[k] >= 0;
    }
    if (used == 0) fail("LoadPoint[" + std::to_string(p) + "].node must name at least one node, got none");
  }
  // Unit forces: column 3p + c spreads a unit force along c over the nodes of point p by the weights.
  Eigen::MatrixXd F = Eigen::MatrixXd::Zero(n, 3 * m);
  for (int p = 0; p < m; ++p)
    for (int k = 0; k < 3; ++k)
      if (points_[p].node[k] >= 0)
        for (int c = 0; c < 3; ++c) F(3 * points_[p].node[k] + c, 3 * p + c) += points_[p].weight[k];
  U_ = solver.solve_many(F);
  // Point compliance P = F^T U (the same weights gather the displacement of each point).
  P_ = F.transpose() * U_;
}

void LoadResponse::displacement(const Points& forces, Eigen::VectorXd& u) const {
  if (forces.rows() != n_points())
    fail("LoadResponse::displacement: forces must have " + std::to_string(n_points()) + " rows, got " +
         std::to_string(forces.rows()));
  // Row-major m x 3 forces are the flat vector (f0x, f0y, f0z, f1x, ...) that U multiplies.
  const Eigen::Map<const Eigen::VectorXd> f(forces.data(), 3 * n_points());
  u.resize(U_.rows());
  u.noalias() = U_ * f;
}

Eigen::VectorXd LoadResponse::displacement(const Points& forces) const {
  Eigen::VectorXd u;
  displacement(forces, u);
  return u;
}

// ---------------------------------------------------------------------------------------------------------------
// SurfaceCompliance

SurfaceCompliance::SurfaceCompliance(const StaticSolver& solver, const std::vector<int>& nodes, int block_columns,
                                     long max_mesh_column_bytes)
    : solver_(&solver), nodes_(nodes) {
  const int n = solver.n_dofs(), n_mesh = n / 3, s = static_cast<int>(nodes_.size());
  if (block_columns < 1) fail("SurfaceCompliance: block_columns must be >= 1, got " + std::to_string(block_columns));
  if (max_mesh_column_bytes < 0)
    fail("SurfaceCompliance: max_mesh_column_bytes must be >= 0, got " + std::to_string(max_mesh_column_bytes));
  // Node ids: in range and distinct.
  index_.assign(n_mesh, -1);
  extra_index_.assign(n_mesh, -1);
  for (int a = 0; a < s; ++a) {
    const int v = nodes_[a];
    if (v < 0 || v >= n_mesh)
      fail("SurfaceCompliance: nodes[" + std::to_string(a) + "] must be in [0, " + std::to_string(n_mesh) + "), got " +
           std::to_string(v));
    if (index_[v] >= 0) fail("SurfaceCompliance: nodes[" + std::to_string(a) + "] repeats node " + std::to_string(v));
    index_[v] = a;
  }
  // C by blocks of unit columns: solve, keep the rows of the set (and all rows when they fit the budget).
  const bool keep = static_cast<double>(n) * 3.0 * s * sizeof(double) <= static_cast<double>(max_mesh_column_bytes);
  C_.resize(3 * s, 3 * s);
  if (keep && s > 0) Kc_.resize(n, 3 * s);
  for (int c0 = 0; c0 < 3 * s; c0 += block_columns) {
    const int nc = std::min(block_columns, 3 * s - c0);
    Eigen::MatrixXd F = Eigen::MatrixXd::Zero(n, nc);
    for (int c = 0; c < nc; ++c) F(3 * nodes_[(c0 + c) / 3] + (c0 + c) % 3, c) = 1.0;
    const Eigen::MatrixXd X = solver.solve_many(F);
    for (int a = 0; a < s; ++a) C_.block(3 * a, c0, 3, nc) = X.middleRows(3 * nodes_[a], 3);
    if (Kc_.size() > 0) Kc_.middleCols(c0, nc) = X;
  }
}

void SurfaceCompliance::displacement(const Eigen::VectorXd& f, Eigen::VectorXd& du) {
  const int n = solver_->n_dofs();
  if (f.size() != n) fail("SurfaceCompliance::displacement: f must have " + std::to_string(n) + " entries, got " +
                          std::to_string(f.size()));
  // Loaded nodes, and whether each has whole-mesh columns at hand.
  std::vector<int> loaded;
  bool all_at_hand = true;
  for (int v = 0; v < n / 3; ++v) {
    if (f[3 * v] == 0.0 && f[3 * v + 1] == 0.0 && f[3 * v + 2] == 0.0) continue;
    loaded.push_back(v);
    all_at_hand = all_at_hand && ((index_[v] >= 0 && Kc_.size() > 0) || extra_index_[v] >= 0);
  }
  // Summing 3 columns of 3n per loaded node against two sweeps over the factor (forward and back).
  const double sum_cost = 3.0 * n * static_cast<double>(loaded.size());
  const double solve_cost = 2.0 * static_cast<double>(solver_->factor_nonzeros());
  if (!all_at_hand || sum_cost > solve_cost) {
    solver_->solve(f, du);
    return;
  }
  du.setZero(n);
  for (int v : loaded) {
    const Eigen::Vector3d fv = f.segment<3>(3 * v);
    if (index_[v] >= 0)
      du.noalias() += Kc_.middleCols<3>(3 * index_[v]) * fv;
    else
      du.noalias() += extra_cols_[extra_index_[v]] * fv;
  }
}

void SurfaceCompliance::check_node(int node, const char* what) const {
  if (node < 0 || node >= n_nodes_mesh())
    fail(std::string("SurfaceCompliance: ") + what + " must be in [0, " + std::to_string(n_nodes_mesh()) + "), got " +
         std::to_string(node));
}

int SurfaceCompliance::index_of(int node) const {
  check_node(node, "node");
  return index_[node];
}

void SurfaceCompliance::ensure_columns(const std::vector<int>& nodes) {
  // Nodes outside the set and not cached, each once.
  std::vector<int> missing;
  for (int v : nodes) {
    check_node(v, "node");
    if (index_[v] < 0 && extra_index_[v] < 0 && std::find(missing.begin(), missing.end(), v) == missing.end())
      missing.push_back(v);
  }
  if (missing.empty()) return;
  // One multi-column solve for all of them, cached per node.
  const int n = solver_->n_dofs(), nm = static_cast<int>(missing.size());
  Eigen::MatrixXd F = Eigen::MatrixXd::Zero(n, 3 * nm);
  for (int k = 0; k < nm; ++k)
    for (int c = 0; c < 3; ++c) F(3 * missing[k] + c, 3 * k + c) = 1.0;
  const Eigen::MatrixXd X = solver_->solve_many(F);
  for (int k = 0; k < nm; ++k) {
    extra_index_[missing[k]] = static_cast<int>(extra_nodes_.size());
    extra_nodes_.push_back(missing[k]);
    extra_cols_.push_back(X.middleCols(3 * k, 3));
  }
}

Eigen::Matrix3d SurfaceCompliance::block(int node_a, int node_b) {
  check_node(node_a, "node_a");
  check_node(node_b, "node_b");
  const int ia = index_[node_a], ib = index_[node_b];
  // Both in the set: the precomputed matrix.
  if (ia >= 0 && ib >= 0) return C_.block<3, 3>(3 * ia, 3 * ib);
  // Otherwise a cached column of b (rows of a), or of a transposed (C is symmetric).
  if (ib < 0) {
    ensure_columns({node_b});
    return extra_cols_[extra_index_[node_b]].middleRows<3>(3 * node_a);
  }
  ensure_columns({node_a});
  return extra_cols_[extra_index_[node_a]].middleRows<3>(3 * node_b).transpose();
}

void SurfaceCompliance::displacement_on_set(const Eigen::VectorXd& f, Eigen::VectorXd& du, const std::vector<int>& also) {
  const int n = solver_->n_dofs(), s = static_cast<int>(nodes_.size());
  if (f.size() != n) fail("SurfaceCompliance::displacement_on_set: f must have " + std::to_string(n) +
                          " entries, got " + std::to_string(f.size()));
  // Loaded nodes; columns of the ones outside the set, and of the listed outside nodes, at hand.
  std::vector<int> loaded, outside;
  for (int v = 0; v < n / 3; ++v) {
    if (f[3 * v] == 0.0 && f[3 * v + 1] == 0.0 && f[3 * v + 2] == 0.0) continue;
    loaded.push_back(v);
    if (index_[v] < 0) outside.push_back(v);
  }
  for (int v : also) {
    check_node(v, "also");
    if (index_[v] < 0) outside.push_back(v);
  }
  ensure_columns(outside);
  // Set nodes: C times the set loads plus the cached columns of outside loads, gathered on the set rows.
  Eigen::VectorXd v_set = Eigen::VectorXd::Zero(3 * s);
  for (int b : loaded) {
    const Eigen::Vector3d fb = f.segment<3>(3 * b);
    if (index_[b] >= 0) {
      v_set.noalias() += C_.middleCols<3>(3 * index_[b]) * fb;
    } else {
      const Eigen::MatrixXd& X = extra_cols_[extra_index_[b]];
      for (int a = 0; a < s; ++a) v_set.segment<3>(3 * a).noalias() += X.middleRows<3>(3 * nodes_[a]) * fb;
    }
  }
  du.setZero(n);
  for (int a = 0; a < s; ++a) du.segment<3>(3 * nodes_[a]) = v_set.segment<3>(3 * a);
  // Listed nodes outside the set: K^-1_ab f_b from the cached columns of a (C symmetric) or of b.
  for (int a : also) {
    if (index_[a] >= 0) continue;
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    for (int b : loaded) {
      const Eigen::Vector3d fb = f.segment<3>(3 * b);
      if (index_[b] >= 0)
        d.noalias() += extra_cols_[extra_index_[a]].middleRows<3>(3 * b).transpose() * fb;
      else
        d.noalias() += extra_cols_[extra_index_[b]].middleRows<3>(3 * a) * fb;
    }
    du.segment<3>(3 * a) = d;
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Rows of H

Eigen::VectorXd row_values(const std::vector<ContactRow>& rows, const Eigen::VectorXd& u) {
  if (u.size() % 3 != 0) fail("row_values: u must have 3n entries, got " + std::to_string(u.size()));
  check_rows(rows, static_cast<int>(u.size() / 3));
  Eigen::VectorXd h(rows.size());
  for (size_t r = 0; r < rows.size(); ++r) {
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    for (int k = 0; k < 4; ++k)
      if (rows[r].node[k] >= 0) d += rows[r].weight[k] * u.segment<3>(3 * rows[r].node[k]);
    h[r] = rows[r].n.dot(d);
  }
  return h;
}

Eigen::VectorXd contact_force(const std::vector<ContactRow>& rows, const Eigen::VectorXd& lambda, int n_dofs) {
  if (n_dofs < 0 || n_dofs % 3 != 0) fail("contact_force: n_dofs must be 3n, got " + std::to_string(n_dofs));
  if (lambda.size() != static_cast<Eigen::Index>(rows.size()))
    fail("contact_force: lambda must have " + std::to_string(rows.size()) + " entries, got " +
         std::to_string(lambda.size()));
  check_rows(rows, n_dofs / 3);
  Eigen::VectorXd f = Eigen::VectorXd::Zero(n_dofs);
  for (size_t r = 0; r < rows.size(); ++r)
    for (int k = 0; k < 4; ++k)
      if (rows[r].node[k] >= 0) f.segment<3>(3 * rows[r].node[k]) += lambda[r] * rows[r].weight[k] * rows[r].n;
  return f;
}

// ---------------------------------------------------------------------------------------------------------------
// Coupling matrix A = H C H^T, column by column

CouplingMatrix::CouplingMatrix(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows)
    : compliance_(&compliance), rows_(&rows) {
  check_rows(rows, compliance.n_nodes_mesh());
  const int m = static_cast<int>(rows.size());
  // Distinct touched nodes; each row's used entries as (slot among them, weight * n).
  std::vector<int> slot_of(compliance.n_nodes_mesh(), -1);
  entry_begin_.assign(m + 1, 0);
  for (int r = 0; r < m; ++r) {
    for (int k = 0; k < 4; ++k) {
      const int v = rows[r].node[k];
      if (v < 0) continue;
      if (slot_of[v] < 0) {
        slot_of[v] = static_cast<int>(touched_.size());
        touched_.push_back(v);
        touched_set_index_.push_back(compliance.index_[v]);
      }
      entry_slot_.push_back(slot_of[v]);
      entry_wn_.push_back(rows[r].weight[k] * rows[r].n);
    }
    entry_begin_[r + 1] = static_cast<int>(entry_slot_.size());
  }
  // Columns of every touched node outside the set, in one solve.
  std::vector<int> outside;
  for (size_t t = 0; t < touched_.size(); ++t)
    if (touched_set_index_[t] < 0) outside.push_back(touched_[t]);
  compliance.ensure_columns(outside);
  columns_.resize(m);
  y_.resize(static_cast<Eigen::Index>(touched_.size()), 3);
}

const Eigen::VectorXd& CouplingMatrix::column(int s) {
  const int m = size();
  if (s < 0 || s >= m) fail("CouplingMatrix::column: s must be in [0, " + std::to_string(m) + "), got " + std::to_string(s));
  Eigen::VectorXd& col = columns_[s];
  if (col.size() == m) return col;
  const SurfaceCompliance& sc = *compliance_;
  const Eigen::MatrixXd& C = sc.C_;
  // y_a = C_{a, .} h_s for every touched node a: sum over the row's entries (node b, w_b n_s) of C_ab w_b n_s.
  y_.setZero();
  const int nt = static_cast<int>(touched_.size());
  for (int e = entry_begin_[s]; e < entry_begin_[s + 1]; ++e) {
    const int b = touched_[entry_slot_[e]], ib = touched_set_index_[entry_slot_[e]];
    const Eigen::Vector3d& wn = entry_wn_[e];
    if (ib >= 0) {
      // b in the set: rows of its column block for touched nodes in the set; for the others, the cached
      // columns of a (C symmetric: C_ab = (C_ba)^T).
      const double* c0 = C.col(3 * ib).data();
      const double* c1 = C.col(3 * ib + 1).data();
      const double* c2 = C.col(3 * ib + 2).data();
      for (int t = 0; t < nt; ++t) {
        const int ia = touched_set_index_[t];
        if (ia >= 0) {
          const int i0 = 3 * ia;
          y_(t, 0) += c0[i0] * wn[0] + c1[i0] * wn[1] + c2[i0] * wn[2];
          y_(t, 1) += c0[i0 + 1] * wn[0] + c1[i0 + 1] * wn[1] + c2[i0 + 1] * wn[2];
          y_(t, 2) += c0[i0 + 2] * wn[0] + c1[i0 + 2] * wn[1] + c2[i0 + 2] * wn[2];
        } else {
          const Eigen::MatrixXd& X = sc.extra_cols_[sc.extra_index_[touched_[t]]];  // 3n x 3, columns of a
          y_.row(t) += (X.middleRows<3>(3 * b).transpose() * wn).transpose();
        }
      }
    } else {
      // b outside the set: its cached whole-mesh columns hold C_ab for every a.
      const Eigen::MatrixXd& X = sc.extra_cols_[sc.extra_index_[b]];  // 3n x 3
      for (int t = 0; t < nt; ++t) y_.row(t) += (X.middleRows<3>(3 * touched_[t]) * wn).transpose();
    }
  }
  // A_rs = sum over row r's entries of (w n_r) . y_slot.
  col.resize(m);
  for (int r = 0; r < m; ++r) {
    double acc = 0.0;
    for (int e = entry_begin_[r]; e < entry_begin_[r + 1]; ++e) {
      const int t = entry_slot_[e];
      acc += entry_wn_[e][0] * y_(t, 0) + entry_wn_[e][1] * y_(t, 1) + entry_wn_[e][2] * y_(t, 2);
    }
    col[r] = acc;
  }
  ++n_computed_;
  return col;
}

Eigen::MatrixXd CouplingMatrix::dense() {
  const int m = size();
  Eigen::MatrixXd A(m, m);
  for (int s = 0; s < m; ++s) A.col(s) = column(s);
  // Symmetrise (C is symmetric up to round-off).
  const Eigen::MatrixXd At = A.transpose();
  A = 0.5 * (A + At);
  return A;
}

Eigen::MatrixXd coupling_matrix(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows) {
  return CouplingMatrix(compliance, rows).dense();
}

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

// Violation of H u >= g (h = H u), and of equality where the row pushes (lambda > 0), metres.
double lcp_residual(const Eigen::VectorXd& g, const Eigen::VectorXd& h, const Eigen::VectorXd& lambda) {
  double res = 0.0;
  for (Eigen::Index r = 0; r < g.size(); ++r) {
    res = std::max(res, g[r] - h[r]);
    if (lambda[r] > 0.0) res = std::max(res, std::abs(h[r] - g[r]));
  }
  return res;
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
  out.residual = lcp_residual(g, h, out.lambda);
  out.converged = lcp.converged && out.residual <= options.tolerance;
  return out;
}

ContactResult solve_contacts(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows,
                             const Eigen::VectorXd& u_free, const std::vector<int>& warm, const LcpOptions& options,
                             bool whole_mesh, const HeldPoints* held) {
  check_u_free(compliance, u_free, "solve_contacts");
  const int m = static_cast<int>(rows.size());
  for (size_t i = 0; i < warm.size(); ++i)
    if (warm[i] < 0 || warm[i] >= m)
      fail("solve_contacts: warm[" + std::to_string(i) + "] must be a row index in [0, " + std::to_string(m) +
           "), got " + std::to_string(warm[i]));
  const int n = compliance.solver().n_dofs();
  const int d3 = held ? static_cast<int>(held->U.cols()) : 0;
  if (held && (held->U.rows() != n || held->S.rows() != d3 || held->S.cols() != d3 ||
               static_cast<int>(held->points.size()) * 3 != d3))
    fail("solve_contacts: held points must have U 3n x 3d, S 3d x 3d and d points, got U " +
         std::to_string(held->U.rows()) + " x " + std::to_string(d3) + ", S " + std::to_string(held->S.rows()) + " x " +
         std::to_string(held->S.cols()) + ", " + std::to_string(held->points.size()) + " points");
  Eigen::VectorXd g(m);
  for (int r = 0; r < m; ++r) g[r] = rows[r].g;
  // G = H U: how each row's value moves per unit force at the held points (rows x 3d, m/N).
  Eigen::MatrixXd G(m, d3), GS(m, d3);
  if (held) {
    for (int r = 0; r < m; ++r) {
      G.row(r).setZero();
      for (int k = 0; k < 4; ++k)
        if (rows[r].node[k] >= 0)
          G.row(r) += rows[r].weight[k] * rows[r].n.transpose() * held->U.middleRows(3 * rows[r].node[k], 3);
    }
    GS = G * held->S;
  }
  // w = A' lambda + (H u_free - g), A' = A - G S G^T: active set on columns computed on demand, Lemke if that fails.
  CouplingMatrix A(compliance, rows);
  std::vector<Eigen::VectorXd> held_columns(held ? m : 0);
  auto column = [&](int j) -> const Eigen::VectorXd& {
    if (!held) return A.column(j);
    if (held_columns[j].size() == 0) held_columns[j] = A.column(j) - G * GS.row(j).transpose();
    return held_columns[j];
  };
  const Eigen::VectorXd q = row_values(rows, u_free) - g;
  LcpResult lcp = solve_lcp_active_set(column, q, warm, options);
  ContactResult out;
  if (!lcp.converged) {
    const int rounds = lcp.iterations;
    Eigen::MatrixXd dense = A.dense();
    if (held) dense -= G * GS.transpose();
    lcp = solve_lcp_dense(0.5 * (dense + dense.transpose()), q, options);
    lcp.iterations += rounds;
    out.used_lemke = true;
  }
  out.lambda = lcp.z;
  out.iterations = lcp.iterations;
  Eigen::VectorXd h = finish(compliance, rows, u_free, out, whole_mesh);
  // Held points: their force change -S G^T lambda joins the force and its displacement U df the correction.
  if (held) {
    out.held_force = -(GS.transpose() * out.lambda);
    out.correction += held->U * out.held_force;
    for (int p = 0; p < static_cast<int>(held->points.size()); ++p)
      for (int k = 0; k < 3; ++k)
        if (held->points[p].node[k] >= 0)
          out.force.segment<3>(3 * held->points[p].node[k]) += held->points[p].weight[k] * out.held_force.segment<3>(3 * p);
    h = row_values(rows, u_free + out.correction);
  }
  out.residual = lcp_residual(g, h, out.lambda);
  out.converged = lcp.converged && out.residual <= options.tolerance;
  return out;
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
  const double tol = options.tolerance;

  LcpResult out;
  Eigen::VectorXd z = Eigen::VectorXd::Zero(m), w = q;
  std::vector<char> in_P(m, 0);
  PassiveFactor F(column);
  Eigen::VectorXd c;
  int rounds = 0;
  bool failed = false;
  // w = A z + q from the columns of P.
  auto update_w = [&]() {
    w = q;
    for (int j : F.set()) w.noalias() += z[j] * column(j);
  };
  // Removes the members of P that keep() rejects (their z becomes exactly 0) and refactors.
  auto drop = [&](auto keep) {
    failed = failed || !F.retain(keep);
    std::vector<char> kept(m, 0);
    for (int j : F.set()) kept[j] = 1;
    for (int i = 0; i < m; ++i)
      if (in_P[i] && !kept[i]) z[i] = 0.0;
    in_P.swap(kept);
  };

  // Warm start: the guessed set (independent members), pruned of negative multipliers until the subproblem's
  // solution is positive; it is then a feasible starting point.
  for (int j : warm)
    if (!in_P[j] && F.append(j, c)) in_P[j] = 1;
  while (F.size() > 0 && !failed) {
    const Eigen::VectorXd zeta = F.solve(q);
    bool positive = true;
    for (int a = 0; a < F.size(); ++a) positive = positive && zeta[a] > 0.0;
    if (positive) {
      for (int a = 0; a < F.size(); ++a) z[F.set()[a]] = zeta[a];
      break;
    }
    std::vector<char> keep(m, 0);
    for (int a = 0; a < F.size(); ++a) keep[F.set()[a]] = zeta[a] > 0.0;
    drop([&](int i) { return keep[i] != 0; });
    ++rounds;
  }
  update_w();

  bool done = false;
  while (!failed && rounds < max_rounds) {
    // The most violated row off P enters; none below -tolerance: solved.
    int j = -1;
    for (int i = 0; i < m; ++i)
      if (!in_P[i] && w[i] < -tol && (j < 0 || w[i] < w[j])) j = i;
    if (j < 0) {
      done = true;
      break;
    }
    ++rounds;
    if (!F.append(j, c)) {
      // Row j depends on P: along d = e_j - sum c_a e_{P_a} (A d = 0, q . d = w_j < 0) the objective falls
      // linearly; go until a member of P reaches zero and exchange it for j. No such member: unbounded
      // (the constraints are inconsistent).
      int block = -1;
      double t = 0.0;
      for (int a = 0; a < F.size(); ++a)
        if (c[a] > 0.0 && (block < 0 || z[F.set()[a]] / c[a] < t)) block = a, t = z[F.set()[a]] / c[a];
      if (block < 0) {
        failed = true;
        break;
      }
      for (int a = 0; a < F.size(); ++a) z[F.set()[a]] -= t * c[a];
      const int leaving = F.set()[block];
      z[leaving] = 0.0;
      z[j] = t;
      drop([&](int i) { return i != leaving && z[i] > 0.0; });
      if (failed || !F.append(j, c)) {
        failed = true;
        break;
      }
    }
    in_P[j] = 1;
    // Subproblem on P from the feasible z: step towards its solution, dropping members that reach zero first.
    while (!failed) {
      const Eigen::VectorXd zeta = F.solve(q);
      double alpha = 1.0;
      for (int a = 0; a < F.size(); ++a) {
        const int i = F.set()[a];
        const double den = z[i] - zeta[a];
        if (zeta[a] <= 0.0) alpha = std::min(alpha, den > 0.0 ? z[i] / den : 0.0);
      }
      if (alpha >= 1.0) {
        for (int a = 0; a < F.size(); ++a) z[F.set()[a]] = zeta[a];
        break;
      }
      std::vector<char> keep(m, 0);
      for (int a = 0; a < F.size(); ++a) {
        const int i = F.set()[a];
        const double zi = z[i] + alpha * (zeta[a] - z[i]);
        const bool blocking = zeta[a] <= 0.0 && z[i] <= alpha * (z[i] - zeta[a]) * (1.0 + 1e-12);
        z[i] = blocking || zi <= 0.0 ? 0.0 : zi;
        keep[i] = z[i] > 0.0;
      }
      drop([&](int i) { return keep[i] != 0; });
      if (++rounds >= max_rounds) failed = true;
    }
    update_w();
  }
  out.iterations = rounds;
  out.z = z.cwiseMax(0.0);
  update_w();
  out.w = w;
  // Residual: max_i |min(w_i, A_ii z_i)| over z_i > 0, and the violations of w >= 0.
  double res = 0.0;
  for (int i = 0; i < m; ++i) {
    res = std::max(res, -w[i]);
    if (out.z[i] > 0.0) res = std::max(res, std::abs(std::min(w[i], std::max(column(i)[i], 0.0) * out.z[i])));
  }
  out.residual = res;
  out.converged = done && !failed && res <= tol;
  return out;
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

// Residual of a candidate LCP solution: max_i |min(w_i, A_ii z_i)| and the violations of w, z >= 0.
double lcp_residual(const Eigen::MatrixXd& A, const Eigen::VectorXd& z, const Eigen::VectorXd& w) {
  double r = 0.0;
  for (int i = 0; i < z.size(); ++i) {
    const double zi = std::max(A(i, i), 0.0) * z[i];
    r = std::max({r, std::abs(std::min(w[i], zi)), -w[i], -zi});
  }
  return r;
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

  // Variables: w_i -> i, z_i -> m + i, artificial z0 -> 2m. System: w - A z - e z0 = q, basis starts at w.
  // Binv is the inverse of the basis matrix, x the basic values (kept >= 0).
  const int z0 = 2 * m;
  std::vector<int> basis(m);
  for (int i = 0; i < m; ++i) basis[i] = i;
  Eigen::MatrixXd Binv = Eigen::MatrixXd::Identity(m, m);
  Eigen::VectorXd x = q;
  Eigen::VectorXd d(m), dd(m);
  Eigen::RowVectorXd br(m);

  // d = Binv * (column of variable var); columns: w_i -> e_i, z_i -> -A e_i, z0 -> -1.
  auto direction = [&](int var) {
    if (var < m) {
      d = Binv.col(var);
    } else if (var < 2 * m) {
      d.noalias() = -(Binv * A.col(var - m));
    } else {
      d = -Binv.rowwise().sum();
    }
  };
  // Pivot: variable `enter` with direction d replaces the basic variable of row r (rank-one update of Binv).
  auto pivot = [&](int r, int enter) {
    const double dr = d[r];
    Binv.row(r) /= dr;
    x[r] /= dr;
    dd = d;
    dd[r] = 0.0;
    br = Binv.row(r);
    Binv.noalias() -= dd * br;
    x -= dd * x[r];
    const int leave = basis[r];
    basis[r] = enter;
    return leave;
  };

  // First pivot: z0 enters at the most negative q.
  int r0 = 0;
  q.minCoeff(&r0);
  direction(z0);
  int leaving = pivot(r0, z0);
  int it = 1;
  bool done = false;
  while (it < max_it) {
    // The complement of the variable that just left enters.
    const int enter = leaving < m ? leaving + m : leaving - m;
    direction(enter);
    const double piv_tol = 1e-12 * d.cwiseAbs().maxCoeff();
    // Minimum ratio x_i / d_i over d_i > 0; ties go to z0 (finishes at once), then lexicographically smaller
    // rows of Binv / d_i (the rule that rules out cycling under degeneracy).
    auto prefer = [&](int i, int r) {
      if (basis[r] == z0) return false;
      if (basis[i] == z0) return true;
      for (int j = 0; j < m; ++j) {
        const double a = Binv(i, j) / d[i], b = Binv(r, j) / d[r];
        if (a != b) return a < b;
      }
      return false;
    };
    const double dmax = d.maxCoeff();
    if (!(dmax > piv_tol)) break;  // ray termination: infeasible (or not copositive-plus)
    const double tie = 1e-12 * x.cwiseAbs().maxCoeff() / dmax;
    int r = -1;
    double best = 0.0;
    for (int i = 0; i < m; ++i) {
      if (d[i] <= piv_tol) continue;
      const double ratio = std::max(x[i], 0.0) / d[i];
      if (r < 0 || ratio < best - tie) {
        r = i, best = ratio;
      } else if (ratio <= best + tie && prefer(i, r)) {
        r = i, best = std::min(best, ratio);
      }
    }
    leaving = pivot(r, enter);
    ++it;
    if (leaving == z0) {
      done = true;
      break;
    }
  }
  out.iterations = it;

  // Read z from the basis and polish it on the active set (A_SS z_S = -q_S) when that is at least as good.
  for (int i = 0; i < m; ++i)
    if (basis[i] >= m && basis[i] < 2 * m) out.z[basis[i] - m] = std::max(x[i], 0.0);
  out.w = A * out.z + q;
  out.residual = lcp_residual(A, out.z, out.w);
  if (done) {
    std::vector<int> S;
    for (int i = 0; i < m; ++i)
      if (basis[i] >= m && basis[i] < 2 * m) S.push_back(basis[i] - m);
    if (!S.empty()) {
      const int s = static_cast<int>(S.size());
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
      const double res = lcp_residual(A, z, w);
      if (res <= out.residual) out.z = z, out.w = w, out.residual = res;
    }
  }
  out.converged = done && out.residual <= options.tolerance;
  return out;
}

}  // namespace lumen::physics
