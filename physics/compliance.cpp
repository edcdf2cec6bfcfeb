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
    const std::string at = "ContactRow[" + std::to_string(r) + "]";
    int used = 0;
    for (int k = 0; k < 4; ++k) {
      check_slot(rows[r].node[k], n_nodes, at + ".node[" + std::to_string(k) + "]");
      if (!std::isfinite(rows[r].weight[k]))
        fail(at + ".weight[" + std::to_string(k) + "] must be finite, got " + num(rows[r].weight[k]));
      used += rows[r].node[k] >= 0;
    }
    if (used == 0) fail(at + ".node must name at least one node, got none");
    if (!rows[r].n.allFinite()) fail(at + ".n must be finite");
    if (!std::isfinite(rows[r].g)) fail(at + ".g must be finite, got " + num(rows[r].g));
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

SurfaceCompliance::SurfaceCompliance(const StaticSolver& solver, const std::vector<int>& nodes, int block_columns)
    : solver_(&solver), nodes_(nodes) {
  const int n = solver.n_dofs(), n_mesh = n / 3, s = static_cast<int>(nodes_.size());
  if (block_columns < 1) fail("SurfaceCompliance: block_columns must be >= 1, got " + std::to_string(block_columns));
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
  // C by blocks of unit columns: solve, keep the rows of the set.
  C_.resize(3 * s, 3 * s);
  for (int c0 = 0; c0 < 3 * s; c0 += block_columns) {
    const int nc = std::min(block_columns, 3 * s - c0);
    Eigen::MatrixXd F = Eigen::MatrixXd::Zero(n, nc);
    for (int c = 0; c < nc; ++c) F(3 * nodes_[(c0 + c) / 3] + (c0 + c) % 3, c) = 1.0;
    const Eigen::MatrixXd X = solver.solve_many(F);
    for (int a = 0; a < s; ++a) C_.block(3 * a, c0, 3, nc) = X.middleRows(3 * nodes_[a], 3);
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

Eigen::MatrixXd coupling_matrix(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows) {
  check_rows(rows, compliance.n_nodes_mesh());
  const int m = static_cast<int>(rows.size());
  // Columns of every touched node outside the set, in one solve.
  std::vector<int> touched;
  std::vector<char> outside(m, 0);  // row touches a node outside the set
  for (int r = 0; r < m; ++r)
    for (int k = 0; k < 4; ++k)
      if (rows[r].node[k] >= 0) {
        touched.push_back(rows[r].node[k]);
        outside[r] = outside[r] || compliance.index_of(rows[r].node[k]) < 0;
      }
  compliance.ensure_columns(touched);
  // Set-set part: Y = C h_s over the whole set (columns of C are contiguous, C is symmetric), then
  // A_rs = h_r . Y_s on the set nodes of row r.
  const Eigen::MatrixXd& C = compliance.matrix();
  Eigen::MatrixXd Y = Eigen::MatrixXd::Zero(C.rows(), m);
  for (int s = 0; s < m; ++s)
    for (int l = 0; l < 4; ++l) {
      const int ib = rows[s].node[l] >= 0 ? compliance.index_of(rows[s].node[l]) : -1;
      if (ib >= 0) Y.col(s).noalias() += rows[s].weight[l] * (C.middleCols<3>(3 * ib) * rows[s].n);
    }
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(m, m);
  for (int r = 0; r < m; ++r)
    for (int k = 0; k < 4; ++k) {
      const int ia = rows[r].node[k] >= 0 ? compliance.index_of(rows[r].node[k]) : -1;
      if (ia < 0) continue;
      const Eigen::RowVector3d hn = rows[r].weight[k] * rows[r].n.transpose();
      A.row(r).noalias() += hn * Y.middleRows<3>(3 * ia);
    }
  // Terms with a node outside the set: from the cached columns, pair by pair.
  for (int r = 0; r < m; ++r)
    for (int s = 0; s < m; ++s) {
      if (!outside[r] && !outside[s]) continue;
      for (int k = 0; k < 4; ++k) {
        const int a = rows[r].node[k];
        if (a < 0) continue;
        for (int l = 0; l < 4; ++l) {
          const int b = rows[s].node[l];
          if (b < 0 || (compliance.index_of(a) >= 0 && compliance.index_of(b) >= 0)) continue;
          A(r, s) += rows[r].weight[k] * rows[s].weight[l] * rows[r].n.dot(compliance.block(a, b) * rows[s].n);
        }
      }
    }
  // Symmetrise (C is symmetric up to round-off).
  const Eigen::MatrixXd At = A.transpose();
  A = 0.5 * (A + At);
  return A;
}

namespace {

// Force, correction (one back-substitution) and the row values after correction.
Eigen::VectorXd finish(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows,
                       const Eigen::VectorXd& u_free, ContactResult& out) {
  const int n = compliance.solver().n_dofs();
  out.force = contact_force(rows, out.lambda, n);
  compliance.solver().solve(out.force, out.correction);
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
                             const Eigen::VectorXd& u_free, double tolerance) {
  check_u_free(compliance, u_free, "solve_equality");
  const int m = static_cast<int>(rows.size());
  ContactResult out;
  out.iterations = 1;
  Eigen::VectorXd g(m);
  for (int r = 0; r < m; ++r) g[r] = rows[r].g;
  // A lambda = g - H u_free: Cholesky when A is positive definite, else minimum-norm least squares.
  const Eigen::MatrixXd A = coupling_matrix(compliance, rows);
  const Eigen::VectorXd b = g - row_values(rows, u_free);
  Eigen::LLT<Eigen::MatrixXd> llt(A);
  if (llt.info() == Eigen::Success && m > 0) {
    out.lambda = llt.solve(b);
  } else {
    out.lambda = m > 0 ? Eigen::VectorXd(A.completeOrthogonalDecomposition().solve(b)) : Eigen::VectorXd(0);
  }
  const Eigen::VectorXd h = finish(compliance, rows, u_free, out);
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
  // Violation of H u >= g, and of equality where the row pushes.
  double res = 0.0;
  for (int r = 0; r < m; ++r) {
    res = std::max(res, g[r] - h[r]);
    if (out.lambda[r] > 0.0) res = std::max(res, std::abs(h[r] - g[r]));
  }
  out.residual = res;
  out.converged = lcp.converged && res <= options.tolerance;
  return out;
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
  if (!(options.tolerance >= 0.0)) fail("LcpOptions.tolerance must be >= 0, got " + num(options.tolerance));
  if (options.max_iterations < 0)
    fail("LcpOptions.max_iterations must be >= 0, got " + std::to_string(options.max_iterations));
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
