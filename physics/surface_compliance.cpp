// Surface compliance: K^-1 restricted to a node set, cached outside columns, whole-mesh and on-set responses.
#include "physics/surface_compliance.hpp"

#include <cassert>
#include <algorithm>
#include <stdexcept>
#include <string>

#include "physics/detail/messages.hpp"

namespace lumen::physics {

using detail::fail;

SurfaceCompliance::SurfaceCompliance(const StaticSolver& solver, const std::vector<int>& nodes, int block_columns,
                                     long max_mesh_column_bytes, long max_set_matrix_bytes,
                                     const std::vector<int>& view_nodes, long max_view_bytes, int max_gram_nodes)
    : solver_(&solver), nodes_(nodes), max_gram_nodes_(max_gram_nodes) {
  const int n = solver.n_dofs(), n_mesh = n / 3, s = static_cast<int>(nodes_.size());
  if (block_columns < 1) fail("SurfaceCompliance: block_columns must be >= 1, got " + std::to_string(block_columns));
  if (max_gram_nodes < 1) fail("SurfaceCompliance: max_gram_nodes must be >= 1, got " + std::to_string(max_gram_nodes));
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
  if (max_set_matrix_bytes < 0)
    fail("SurfaceCompliance: max_set_matrix_bytes must be >= 0, got " + std::to_string(max_set_matrix_bytes));
  if (max_view_bytes < 0) fail("SurfaceCompliance: max_view_bytes must be >= 0, got " + std::to_string(max_view_bytes));
  // View nodes: in range; the ones outside the set, each once.
  for (size_t i = 0; i < view_nodes.size(); ++i) {
    const int v = view_nodes[i];
    if (v < 0 || v >= n_mesh)
      fail("SurfaceCompliance: view_nodes[" + std::to_string(i) + "] must be in [0, " + std::to_string(n_mesh) +
           "), got " + std::to_string(v));
    if (index_[v] < 0) view_nodes_.push_back(v);
  }
  std::sort(view_nodes_.begin(), view_nodes_.end());
  view_nodes_.erase(std::unique(view_nodes_.begin(), view_nodes_.end()), view_nodes_.end());
  // A set too large for its matrix keeps its columns per node, solved on first use.
  lazy_ = 9.0 * s * s * sizeof(double) > static_cast<double>(max_set_matrix_bytes);
  if (lazy_) {
    half_.resize(s);
    half_solved_.assign(s, 0);
    gram_slot_.assign(s, -1);
    half_z_.assign(solver.n_free_dofs(), 0.0);
    solver.prepare_half_columns();  // (now, not at the first contact)
    return;
  }
  // C by blocks of unit columns: solve, keep the rows of the set (and all rows when they fit the budget).
  const bool keep = static_cast<double>(n) * 3.0 * s * sizeof(double) <= static_cast<double>(max_mesh_column_bytes);
  // (the view rows only without the whole-mesh columns, which hold them)
  const int nv = static_cast<int>(view_nodes_.size());
  const bool view = !keep && nv > 0 && s > 0 &&
                    9.0 * nv * s * sizeof(double) <= static_cast<double>(max_view_bytes);
  C_.resize(3 * s, 3 * s);
  if (keep && s > 0) Kc_.resize(n, 3 * s);
  if (view) V_.resize(3 * nv, 3 * s);
  for (int c0 = 0; c0 < 3 * s; c0 += block_columns) {
    const int nc = std::min(block_columns, 3 * s - c0);
    Eigen::MatrixXd F = Eigen::MatrixXd::Zero(n, nc);
    for (int c = 0; c < nc; ++c) F(3 * nodes_[(c0 + c) / 3] + (c0 + c) % 3, c) = 1.0;
    const Eigen::MatrixXd X = solver.solve_many(F);
    for (int a = 0; a < s; ++a) C_.block(3 * a, c0, 3, nc) = X.middleRows(3 * nodes_[a], 3);
    if (Kc_.size() > 0) Kc_.middleCols(c0, nc) = X;
    if (V_.size() > 0)
      for (int i = 0; i < nv; ++i) V_.block(3 * i, c0, 3, nc) = X.middleRows(3 * view_nodes_[i], 3);
  }
  // With view rows, the interior's own factorisation (when any free DOF is off the set and the view).
  if (V_.size() == 0) return;
  on_view_.assign(n_mesh, 0);
  std::vector<int> boundary = nodes_;
  boundary.insert(boundary.end(), view_nodes_.begin(), view_nodes_.end());
  for (int v : boundary) on_view_[v] = 1;
  bool any_interior = false;
  for (int d = 0; d < n && !any_interior; ++d) any_interior = !on_view_[d / 3] && !solver.is_fixed_dof(d);
  if (any_interior) interior_ = std::make_unique<InteriorSolver>(solver, boundary);
}

const Eigen::MatrixXd& SurfaceCompliance::matrix() const {
  if (lazy_)
    throw std::logic_error("SurfaceCompliance::matrix: the set's " + std::to_string(nodes_.size()) +
                           " nodes keep their columns per node (lazy); use block()");
  return C_;
}

int SurfaceCompliance::n_set_columns() const {
  if (!lazy_) return static_cast<int>(nodes_.size());
  return static_cast<int>(std::count(half_solved_.begin(), half_solved_.end(), 1));
}

Eigen::Ref<const Eigen::MatrixXd> SurfaceCompliance::set_block(int a) const {
  if (lazy_)
    throw std::logic_error("SurfaceCompliance: set node " + std::to_string(nodes_[a]) + " has half columns (lazy)");
  return C_.middleCols(3 * a, 3);
}

void SurfaceCompliance::solve_half_columns(const std::vector<int>& positions) {
  for (int a : positions)
    if (!half_solved_[a]) solve_half_columns(a);
}

void SurfaceCompliance::solve_half_columns(int a) {
  HalfColumns& h = half_[a];
  const int v = nodes_[a];
  solver_->half_columns({3 * v, 3 * v + 1, 3 * v + 2}, h.index, h.value);
  half_solved_[a] = 1;
}

void SurfaceCompliance::scatter_half(int a, const Eigen::Vector3d& w, std::vector<double>& z) const {
  const HalfColumns& h = half_[a];
  const double* v = h.value.data();
  for (size_t e = 0; e < h.index.size(); ++e, v += 3) z[h.index[e]] += v[0] * w[0] + v[1] * w[1] + v[2] * w[2];
}

Eigen::Vector3d SurfaceCompliance::gather_half(int a, const std::vector<double>& z) const {
  const HalfColumns& h = half_[a];
  const double* v = h.value.data();
  double y0 = 0.0, y1 = 0.0, y2 = 0.0;
  for (size_t e = 0; e < h.index.size(); ++e, v += 3) {
    const double ze = z[h.index[e]];
    y0 += v[0] * ze;
    y1 += v[1] * ze;
    y2 += v[2] * ze;
  }
  return {y0, y1, y2};
}

void SurfaceCompliance::clear_half(int a, std::vector<double>& z) const {
  for (int i : half_[a].index) z[i] = 0.0;
}

Eigen::Matrix3d SurfaceCompliance::half_block(int a, int b) {
  if (!half_solved_[a]) solve_half_columns(a);
  if (!half_solved_[b]) solve_half_columns(b);
  // Column j of C_ab: Y_a^T (Y_b e_j), through the zeroed workspace.
  Eigen::Matrix3d block;
  for (int j = 0; j < 3; ++j) {
    scatter_half(b, Eigen::Vector3d::Unit(j), half_z_);
    block.col(j) = gather_half(a, half_z_);
    clear_half(b, half_z_);
  }
  return block;
}

Eigen::MatrixXd SurfaceCompliance::half_gram(const std::vector<int>& set_positions) {
  keep_gram(set_positions);
  return kept_blocks(set_positions);
}

void SurfaceCompliance::keep_gram(const std::vector<int>& set_positions) {
  assert(lazy_);
  solve_half_columns(set_positions);
  // The nodes without blocks in the kept gram join it (with the kept ones while it stays within its bound).
  std::vector<int> fresh, kept;
  for (int a : set_positions) (gram_slot_[a] < 0 ? fresh : kept).push_back(a);
  if (!fresh.empty()) {
    if (gram_nodes_.size() + fresh.size() <= static_cast<size_t>(max_gram_nodes_)) kept = gram_nodes_;
    extend_gram(kept, fresh);
  }
}

Eigen::MatrixXd SurfaceCompliance::kept_blocks(const std::vector<int>& positions) const {
  const int k = static_cast<int>(positions.size());
  Eigen::MatrixXd C(3 * k, 3 * k);
  for (int j = 0; j < k; ++j)
    for (int i = 0; i < k; ++i)
      C.block<3, 3>(3 * i, 3 * j) = gram_.block<3, 3>(3 * gram_slot_[positions[i]], 3 * gram_slot_[positions[j]]);
  return C;
}

void SurfaceCompliance::extend_gram(const std::vector<int>& kept, const std::vector<int>& fresh) {
  // The new gram's nodes: the kept ones (each with a slot in the old gram), then the fresh ones.
  std::vector<int> all = kept;
  all.insert(all.end(), fresh.begin(), fresh.end());
  const int g = static_cast<int>(all.size()), nk = static_cast<int>(kept.size()), nf = static_cast<int>(fresh.size());
  Eigen::MatrixXd G(3 * g, 3 * g);
  G.topLeftCorner(3 * nk, 3 * nk) = kept_blocks(kept);
  // The fresh rows Y_F^T Y over the union of the fresh half columns' rows (only there is Y_F nonzero), numbered in
  // order of first use: Y (rows x 3g) on them.
  std::vector<int> row_of(half_z_.size(), -1);
  int rows = 0;
  for (int a : fresh)
    for (int i : half_[a].index)
      if (row_of[i] < 0) row_of[i] = rows++;
  Eigen::MatrixXd Y = Eigen::MatrixXd::Zero(rows, 3 * g);
  for (int t = 0; t < g; ++t) {
    const HalfColumns& h = half_[all[t]];
    for (size_t e = 0; e < h.index.size(); ++e)
      if (row_of[h.index[e]] >= 0)
        for (int c = 0; c < 3; ++c) Y(row_of[h.index[e]], 3 * t + c) = h.value[3 * e + c];
  }
  if (nk == 0) {
    // All fresh: the lower triangle by a rank update, then mirrored.
    G.setZero();
    G.selfadjointView<Eigen::Lower>().rankUpdate(Y.transpose());
    G.triangularView<Eigen::StrictlyUpper>() = G.transpose();
  } else {
    const Eigen::MatrixXd B = Y.rightCols(3 * nf).transpose() * Y;  // 3f x 3g: the fresh rows
    G.bottomRows(3 * nf) = B;
    G.topRightCorner(3 * nk, 3 * nf) = B.leftCols(3 * nk).transpose();
  }
  for (int a : gram_nodes_) gram_slot_[a] = -1;
  for (int t = 0; t < g; ++t) gram_slot_[all[t]] = t;
  gram_nodes_ = std::move(all);
  gram_ = std::move(G);
}

namespace {

// Nodes with a nonzero load in f (3n), ascending.
std::vector<int> loaded_nodes(const Eigen::VectorXd& f) {
  std::vector<int> loaded;
  for (int v = 0; v < f.size() / 3; ++v)
    if (f[3 * v] != 0.0 || f[3 * v + 1] != 0.0 || f[3 * v + 2] != 0.0) loaded.push_back(v);
  return loaded;
}

}  // namespace

bool SurfaceCompliance::needs_solve(const Eigen::VectorXd& f) const {
  const int n = solver_->n_dofs();
  if (f.size() != n) fail("SurfaceCompliance::needs_solve: f must have " + std::to_string(n) + " entries, got " +
                          std::to_string(f.size()));
  // Whether each loaded node has whole-mesh columns at hand.
  const std::vector<int> loaded = loaded_nodes(f);
  for (int v : loaded)
    if (!((index_[v] >= 0 && Kc_.size() > 0) || extra_index_[v] >= 0)) return true;
  return !summing_is_cheaper(loaded.size());
}

bool SurfaceCompliance::summing_is_cheaper(size_t nodes) const {
  // 3 columns of 3n per node against two sweeps over the factor (forward and back).
  const double sum_cost = 3.0 * solver_->n_dofs() * static_cast<double>(nodes);
  const double solve_cost = 2.0 * static_cast<double>(solver_->factor_nonzeros());
  return sum_cost <= solve_cost;
}

void SurfaceCompliance::displacement(const Eigen::VectorXd& f, Eigen::VectorXd& du) {
  const int n = solver_->n_dofs();
  if (f.size() != n) fail("SurfaceCompliance::displacement: f must have " + std::to_string(n) + " entries, got " +
                          std::to_string(f.size()));
  // A lazy set's last back-substitution (the response's check) for the same forces, plus the cached whole-mesh
  // columns of nodes whose load changed since (the held probe points' forces): exact, without a solve.
  if (lazy_ && last_f_.size() == n) {
    const Eigen::VectorXd change = f - last_f_;
    const std::vector<int> changed = loaded_nodes(change);
    if (summing_is_cheaper(changed.size()) &&
        std::all_of(changed.begin(), changed.end(), [&](int v) { return extra_index_[v] >= 0; })) {
      du = last_du_;
      for (int v : changed) du.noalias() += extra_cols_[extra_index_[v]] * change.segment<3>(3 * v);
      return;
    }
  }
  if (needs_solve(f)) {
    if (keeps_view_rows() && loads_only_view(f)) {
      displacement_on_view(f, du);
      complete_interior(du);
    } else {
      solver_->solve(f, du);
    }
    return;
  }
  const std::vector<int> loaded = loaded_nodes(f);
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

int SurfaceCompliance::half_position(int node, const std::vector<double>& z, const char* where) {
  if (!lazy_) throw std::logic_error(std::string("SurfaceCompliance::") + where + ": the set is not lazy");
  const int a = index_of(node);
  if (a < 0) fail(std::string("SurfaceCompliance::") + where + ": node " + std::to_string(node) + " is not in the set");
  if (static_cast<int>(z.size()) != solver_->n_free_dofs())
    fail(std::string("SurfaceCompliance::") + where + ": z must have " + std::to_string(solver_->n_free_dofs()) +
         " entries (the free DOFs), got " + std::to_string(z.size()));
  if (!half_solved_[a]) solve_half_columns(a);
  return a;
}

Eigen::Vector3d SurfaceCompliance::half_displacement(int node, const std::vector<double>& z) {
  return gather_half(half_position(node, z, "half_displacement"), z);
}

long SurfaceCompliance::half_entries(int node) const {
  const int a = index_of(node);
  return lazy_ && a >= 0 && half_solved_[a] ? static_cast<long>(half_[a].index.size()) : 0L;
}

void SurfaceCompliance::add_half_force(int node, const Eigen::Vector3d& w, std::vector<double>& z) {
  scatter_half(half_position(node, z, "add_half_force"), w, z);
}

void SurfaceCompliance::ensure_columns(const std::vector<int>& nodes) {
  // Nodes whose columns are not at hand, each once: outside the set and not cached, or in a lazy set not solved.
  std::vector<int> missing;
  // (A lazy set's nodes get their half columns at once.)
  std::vector<int> half;
  for (int v : nodes) {
    check_node(v, "node");
    const int a = index_[v];
    if (a >= 0 && lazy_) half.push_back(a);
    if (a < 0 && extra_index_[v] < 0 && std::find(missing.begin(), missing.end(), v) == missing.end())
      missing.push_back(v);
  }
  if (!half.empty()) solve_half_columns(half);
  if (missing.empty()) return;
  // One multi-column solve for the nodes outside the set: their whole-mesh columns.
  const int n = solver_->n_dofs(), nm = static_cast<int>(missing.size());
  Eigen::MatrixXd F = Eigen::MatrixXd::Zero(n, 3 * nm);
  for (int k = 0; k < nm; ++k)
    for (int c = 0; c < 3; ++c) F(3 * missing[k] + c, 3 * k + c) = 1.0;
  const Eigen::MatrixXd X = solver_->solve_many(F);
  for (int k = 0; k < nm; ++k) {
    const int v = missing[k];
    extra_index_[v] = static_cast<int>(extra_nodes_.size());
    extra_nodes_.push_back(v);
    extra_cols_.push_back(X.middleCols(3 * k, 3));
  }
}

void SurfaceCompliance::prepare_couplings(const std::vector<int>& nodes) {
  ensure_columns(nodes);
  if (!lazy_) return;
  // The set's nodes among them, each once (a coupling's touched nodes are distinct).
  std::vector<int> positions;
  for (int v : nodes)
    if (index_[v] >= 0) positions.push_back(index_[v]);
  std::sort(positions.begin(), positions.end());
  positions.erase(std::unique(positions.begin(), positions.end()), positions.end());
  if (!positions.empty()) keep_gram(positions);
}

Eigen::Matrix3d SurfaceCompliance::block(int node_a, int node_b) {
  check_node(node_a, "node_a");
  check_node(node_b, "node_b");
  const int ia = index_[node_a], ib = index_[node_b];
  // Both in the set: the set's column block of b, or the product of their half columns.
  if (ia >= 0 && ib >= 0) return lazy_ ? half_block(ia, ib) : Eigen::Matrix3d(set_block(ib).middleRows<3>(3 * ia));
  // Otherwise a cached column of b (rows of a), or of a transposed (C is symmetric).
  if (ib < 0) {
    ensure_columns({node_b});
    return extra_cols_[extra_index_[node_b]].middleRows<3>(3 * node_a);
  }
  ensure_columns({node_a});
  return extra_cols_[extra_index_[node_a]].middleRows<3>(3 * node_b).transpose();
}

void SurfaceCompliance::displacement_on_view(const Eigen::VectorXd& f, Eigen::VectorXd& du) {
  const int n = solver_->n_dofs(), s = static_cast<int>(nodes_.size()), nv = static_cast<int>(view_nodes_.size());
  if (!keeps_view_rows()) throw std::logic_error("SurfaceCompliance::displacement_on_view: no view rows are kept");
  if (f.size() != n) fail("SurfaceCompliance::displacement_on_view: f must have " + std::to_string(n) +
                          " entries, got " + std::to_string(f.size()));
  // Loaded nodes; the columns of the ones outside the set at hand (whole-mesh: they hold every row).
  const std::vector<int> loaded = loaded_nodes(f);
  ensure_columns(loaded);
  // Set rows and view rows: the set's column blocks of set loads, the cached columns of outside loads.
  Eigen::VectorXd v_set = Eigen::VectorXd::Zero(3 * s), v_view = Eigen::VectorXd::Zero(3 * nv);
  for (int b : loaded) {
    const Eigen::Vector3d fb = f.segment<3>(3 * b);
    if (index_[b] >= 0) {
      v_set.noalias() += C_.middleCols<3>(3 * index_[b]) * fb;
      v_view.noalias() += V_.middleCols<3>(3 * index_[b]) * fb;
    } else {
      const Eigen::MatrixXd& X = extra_cols_[extra_index_[b]];
      for (int a = 0; a < s; ++a) v_set.segment<3>(3 * a).noalias() += X.middleRows<3>(3 * nodes_[a]) * fb;
      for (int i = 0; i < nv; ++i) v_view.segment<3>(3 * i).noalias() += X.middleRows<3>(3 * view_nodes_[i]) * fb;
    }
  }
  du.setZero(n);
  for (int a = 0; a < s; ++a) du.segment<3>(3 * nodes_[a]) = v_set.segment<3>(3 * a);
  for (int i = 0; i < nv; ++i) du.segment<3>(3 * view_nodes_[i]) = v_view.segment<3>(3 * i);
}

bool SurfaceCompliance::loads_only_view(const Eigen::VectorXd& f) const {
  if (!keeps_view_rows()) return false;
  for (int v : loaded_nodes(f))
    if (!on_view_[v]) return false;
  return true;
}

void SurfaceCompliance::complete_interior(Eigen::VectorXd& du) const {
  if (!keeps_view_rows()) throw std::logic_error("SurfaceCompliance::complete_interior: no view rows are kept");
  if (interior_) interior_->complete(du);
}

void SurfaceCompliance::displacement_on_set(const Eigen::VectorXd& f, Eigen::VectorXd& du, const std::vector<int>& also) {
  const int n = solver_->n_dofs(), s = static_cast<int>(nodes_.size());
  if (f.size() != n) fail("SurfaceCompliance::displacement_on_set: f must have " + std::to_string(n) +
                          " entries, got " + std::to_string(f.size()));
  // Lazy: one back-substitution (kept for displacement() of the same forces), on the set and the listed nodes.
  if (lazy_) {
    for (int v : also) check_node(v, "also");
    solver_->solve(f, last_du_);
    last_f_ = f;
    du.setZero(n);
    for (int v : nodes_) du.segment<3>(3 * v) = last_du_.segment<3>(3 * v);
    for (int v : also) du.segment<3>(3 * v) = last_du_.segment<3>(3 * v);
    return;
  }
  // Loaded nodes; columns of the ones outside the set, and of the listed outside nodes, at hand.
  const std::vector<int> loaded = loaded_nodes(f);
  std::vector<int> wanted = loaded;  // the loaded nodes, and the listed ones outside the set
  for (int v : also) {
    check_node(v, "also");
    if (index_[v] < 0) wanted.push_back(v);
  }
  ensure_columns(wanted);
  // Set nodes: C times the set loads plus the cached columns of outside loads, gathered on the set rows.
  Eigen::VectorXd v_set = Eigen::VectorXd::Zero(3 * s);
  for (int b : loaded) {
    const Eigen::Vector3d fb = f.segment<3>(3 * b);
    if (index_[b] >= 0) {
      v_set.noalias() += set_block(index_[b]) * fb;
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

}  // namespace lumen::physics
