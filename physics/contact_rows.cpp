// Contact rows: H u, H^T lambda, and the coupling A = H C H^T column by column.
#include "physics/contact_rows.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "physics/detail/messages.hpp"

namespace lumen::physics {

using detail::check_slot;
using detail::fail;
using detail::num;

namespace {

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

std::vector<int> row_nodes(const std::vector<ContactRow>& rows) {
  std::vector<int> nodes;
  for (const ContactRow& r : rows)
    for (int k = 0; k < 4; ++k)
      if (r.node[k] >= 0) nodes.push_back(r.node[k]);
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  return nodes;
}

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

Eigen::VectorXd row_targets(const std::vector<ContactRow>& rows) {
  Eigen::VectorXd g(static_cast<Eigen::Index>(rows.size()));
  for (size_t r = 0; r < rows.size(); ++r) g[static_cast<Eigen::Index>(r)] = rows[r].g;
  return g;
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

CouplingMatrix::CouplingMatrix(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows,
                               const std::vector<Eigen::Matrix3d>* node_frames)
    : compliance_(&compliance), rows_(&rows) {
  check_rows(rows, compliance.n_nodes_mesh());
  if (node_frames && static_cast<int>(node_frames->size()) != compliance.n_nodes_mesh())
    fail("CouplingMatrix: node_frames must have " + std::to_string(compliance.n_nodes_mesh()) + " rotations, got " +
         std::to_string(node_frames->size()));
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
      entry_wn_.push_back(rows[r].weight[k] * (node_frames ? Eigen::Vector3d((*node_frames)[v].transpose() * rows[r].n)
                                                          : rows[r].n));
    }
    entry_begin_[r + 1] = static_cast<int>(entry_slot_.size());
  }
  // Columns of every touched node not at hand (outside the set, or in a lazy set), in one solve.
  compliance.ensure_columns(touched_);
  columns_.resize(m);
  y_.resize(static_cast<Eigen::Index>(touched_.size()), 3);
}

const Eigen::VectorXd& CouplingMatrix::column(int s) {
  const int m = size();
  if (s < 0 || s >= m) fail("CouplingMatrix::column: s must be in [0, " + std::to_string(m) + "), got " + std::to_string(s));
  Eigen::VectorXd& col = columns_[s];
  if (col.size() == m) return col;
  SurfaceCompliance& sc = *compliance_;
  // y_a = C_{a, .} h_s for every touched node a: sum over the row's entries (node b, w_b n_s) of C_ab w_b n_s.
  y_.setZero();
  const int nt = static_cast<int>(touched_.size());
  bool half = false;  // (a lazy set: its part through z = sum of Y_b w_b n_s, below)
  for (int e = entry_begin_[s]; e < entry_begin_[s + 1]; ++e) {
    const int b = touched_[entry_slot_[e]], ib = touched_set_index_[entry_slot_[e]];
    const Eigen::Vector3d& wn = entry_wn_[e];
    if (ib >= 0) {
      // b in the set: for touched nodes in the set, the rows of its column block, or (lazy) its half columns into
      // z, their part below; for the others, the cached columns of a (C symmetric: C_ab = (C_ba)^T).
      const double *c0 = nullptr, *c1 = nullptr, *c2 = nullptr;
      if (sc.lazy_) {
        sc.scatter_half(ib, wn, sc.half_z_);
        half = true;
      } else {
        const Eigen::Ref<const Eigen::MatrixXd> Cb = sc.set_block(ib);  // 3s x 3, columns of C itself
        c0 = Cb.col(0).data(), c1 = Cb.col(1).data(), c2 = Cb.col(2).data();
      }
      for (int t = 0; t < nt; ++t) {
        const int ia = touched_set_index_[t];
        if (ia >= 0 && c0) {
          const int i0 = 3 * ia;
          y_(t, 0) += c0[i0] * wn[0] + c1[i0] * wn[1] + c2[i0] * wn[2];
          y_(t, 1) += c0[i0 + 1] * wn[0] + c1[i0 + 1] * wn[1] + c2[i0 + 1] * wn[2];
          y_(t, 2) += c0[i0 + 2] * wn[0] + c1[i0 + 2] * wn[1] + c2[i0 + 2] * wn[2];
        } else if (ia < 0) {
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
  // The lazy set's part: y_a += Y_a^T z for the touched set nodes a (C_ab = Y_a^T Y_b), then z back to 0.
  if (half) {
    for (int t = 0; t < nt; ++t)
      if (touched_set_index_[t] >= 0) y_.row(t) += sc.gather_half(touched_set_index_[t], sc.half_z_).transpose();
    for (int e = entry_begin_[s]; e < entry_begin_[s + 1]; ++e)
      if (touched_set_index_[entry_slot_[e]] >= 0) sc.clear_half(touched_set_index_[entry_slot_[e]], sc.half_z_);
  }
  // A_rs = h_r . y.
  col.resize(m);
  for (int r = 0; r < m; ++r) col[r] = row_times(r, y_.data());
  ++n_computed_;
  return col;
}

double CouplingMatrix::row_times(int r, const double* y) const {
  double acc = 0.0;
  for (int e = entry_begin_[r]; e < entry_begin_[r + 1]; ++e)
    acc += entry_wn_[e].dot(Eigen::Map<const Eigen::Vector3d>(y + 3 * entry_slot_[e]));
  return acc;
}

Eigen::MatrixXd CouplingMatrix::dense() {
  const int m = size();
  Eigen::MatrixXd A(m, m);
  // Every touched node in a lazy set, no column yet: A = H_t C_t H_t^T with C_t the touched nodes' block of C from
  // one dense product of their half columns (the columns' sparse gathers cost about as many products, scattered).
  const SurfaceCompliance& sc = *compliance_;
  const bool all_half = sc.lazy_ && std::all_of(touched_set_index_.begin(), touched_set_index_.end(),
                                                [](int a) { return a >= 0; });
  if (all_half && n_computed_ == 0) {
    const Eigen::MatrixXd C = compliance_->half_gram(touched_set_index_);  // 3t x 3t
    // C H_t^T (3t x rows), column s the sum over row s's entries of C's columns of the entry's node times w n; then
    // A_rs = row r's entries against it (H_t has at most 12 nonzeros a row: both products sparse).
    Eigen::MatrixXd CHt = Eigen::MatrixXd::Zero(C.rows(), m);
    for (int s = 0; s < m; ++s)
      for (int e = entry_begin_[s]; e < entry_begin_[s + 1]; ++e)
        CHt.col(s).noalias() += C.middleCols<3>(3 * entry_slot_[e]) * entry_wn_[e];
    for (int s = 0; s < m; ++s) {
      for (int r = 0; r < m; ++r) A(r, s) = row_times(r, CHt.col(s).data());
      columns_[s] = A.col(s);
    }
    n_computed_ = m;
  } else {
    for (int s = 0; s < m; ++s) A.col(s) = column(s);
  }
  // Symmetrise (C is symmetric up to round-off).
  const Eigen::MatrixXd At = A.transpose();
  A = 0.5 * (A + At);
  return A;
}

Eigen::MatrixXd coupling_matrix(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows,
                                const std::vector<Eigen::Matrix3d>* node_frames) {
  return CouplingMatrix(compliance, rows, node_frames).dense();
}

}  // namespace lumen::physics
