#pragma once
// Surface compliance: C = K^-1 of a prefactorised FEM model restricted to a node set (the inner wall), with
// on-demand columns outside the set and the whole-mesh response to forces on few nodes.
#include <Eigen/Core>
#include <memory>
#include <vector>

#include "physics/fem.hpp"

namespace lumen::physics {

class CouplingMatrix;

// Dense compliance C = K^-1 restricted to a set of nodes (e.g. the inner wall), plus on-demand columns for
// nodes outside the set. Keeps a reference to the solver, which must outlive it.
//
// The whole-mesh columns K^-1 e of the set's DOFs (3n x 3s) come out of the same solves; they are kept when
// they take at most max_mesh_column_bytes, so that the whole-mesh response to forces on a few set nodes is a
// short sum of columns instead of a back-substitution (see displacement()).
//
// C itself (3s x 3s) is solved for at construction when it takes at most max_set_matrix_bytes; a larger set (a
// whole organ's wall: 4,200 nodes of the whole colon are 1.3 GB) is lazy: each node keeps half columns
// y = L^-1 P e (StaticSolver::half_column, solved on first use), and a block is C_ab = Y_a^T Y_b, with the same
// values to round-off. A half column is a sparse forward solve over the node's path in the elimination tree (on the
// whole colon's factor a small part of it), where a column of C needs both whole sweeps (3.5 ms a column there); a
// lazy set's displacements are one back-substitution, kept for the whole-mesh correction of the same forces. The default budget, 1 GiB,
// keeps the shipped real-time scenes eager: lazily, their first-contact frames pay for the columns (the
// oesophagus scope, 525 MB eager: 2 frames over budget, response max 72 ms, against 0 over and 5.6 ms; its start
// 1.8 s instead of 20 s).
class SurfaceCompliance {
 public:
  // nodes: distinct mesh node ids. Columns are computed block_columns at a time (solve_many).
  // view_nodes: nodes whose response to set loads is wanted without a solve (what is drawn: the outer wall, the end
  // caps); when the whole-mesh columns are not kept and the set is eager, their rows of the set's columns (3v x 3s)
  // come out of the same solves and are kept if they take at most max_view_bytes (see displacement_on_view()).
  // View nodes in the set, or repeated, count once.
  static constexpr int kBlockColumns = 64;
  static constexpr long kMeshColumnBytes = 256L << 20, kSetMatrixBytes = 1L << 30, kViewBytes = 512L << 20;
  // A lazy set keeps the blocks of C among the nodes of its recent couplings (the gram of their half columns), so that
  // the next coupling on mostly the same nodes computes only its new nodes' blocks: at most max_gram_nodes (>= 1)
  // nodes' (512: (3 x 512)^2 doubles, 19 MB); past it only the last coupling's nodes are kept.
  static constexpr int kGramNodes = 512;
  SurfaceCompliance(const StaticSolver& solver, const std::vector<int>& nodes, int block_columns = kBlockColumns,
                    long max_mesh_column_bytes = kMeshColumnBytes, long max_set_matrix_bytes = kSetMatrixBytes,
                    const std::vector<int>& view_nodes = {}, long max_view_bytes = kViewBytes,
                    int max_gram_nodes = kGramNodes);

  const StaticSolver& solver() const { return *solver_; }
  int n_nodes_mesh() const { return solver_->n_dofs() / 3; }
  const std::vector<int>& nodes() const { return nodes_; }
  // Position of a mesh node in nodes(), or -1.
  int index_of(int node) const;
  // C, 3s x 3s, metres per newton: C(3a + i, 3b + j) = d u(nodes[a], i) / d f(nodes[b], j). Only when it was
  // solved for at construction (std::logic_error otherwise: see lazy()).
  const Eigen::MatrixXd& matrix() const;
  // Whether the set keeps half columns per node, solved on first use, instead of C solved at construction.
  bool lazy() const { return lazy_; }
  // Number of set nodes whose columns (lazy: half columns) are at hand (all of them unless lazy).
  int n_set_columns() const;

  // 3 x 3 block d u(node_a) / d f(node_b) for any two mesh nodes; columns of nodes outside the set are
  // solved for and cached on first use.
  Eigen::Matrix3d block(int node_a, int node_b);
  // Solves for the columns of every listed node not at hand yet: outside the set and not cached (in one
  // solve_many), or in a lazy set without its half columns.
  void ensure_columns(const std::vector<int>& nodes);
  // Readies couplings (CouplingMatrix) on the listed nodes: their columns, as ensure_columns, and in a lazy set the kept
  // gram's blocks among those of them in the set, so that a coupling on them solves and multiplies nothing more (what
  // a contact Hessian factorised on another thread is given before it replaces the one in use).
  void prepare_couplings(const std::vector<int>& nodes);
  // Number of nodes outside the set whose columns are cached.
  int n_cached_nodes() const { return static_cast<int>(extra_nodes_.size()); }
  // A lazy set's solves split in halves (StaticSolver::half_forward / half_backward on its solver, z over the
  // factor's rows): a set node's displacement Y_a^T z, and a force w on it added, z += Y_a w, its half columns solved
  // for first if not at hand. std::logic_error when the set is not lazy, std::invalid_argument for a node outside
  // it or z of another size.
  Eigen::Vector3d half_displacement(int node, const std::vector<double>& z);
  void add_half_force(int node, const Eigen::Vector3d& w, std::vector<double>& z);
  // Rows of a lazy set's node's half columns (their common pattern; 0 when not solved yet, or not lazy, or outside
  // the set): what half_displacement and add_half_force each read, three values a row.
  long half_entries(int node) const;
  // Whether the whole-mesh columns of the set nodes are kept (3n x 3s, m/N).
  bool keeps_mesh_columns() const { return Kc_.size() > 0; }
  // Whether the view nodes' rows of the set's columns are kept (3v x 3s, m/N), and those nodes (outside the set).
  bool keeps_view_rows() const { return V_.size() > 0; }
  const std::vector<int>& view_nodes() const { return view_nodes_; }

  // du = K^-1 f (3n, metres) for nodal forces f (3n, newtons). When f acts on few nodes whose whole-mesh
  // columns are at hand (kept set columns, cached outside columns) and summing them is cheaper than a
  // back-substitution, du is that sum; otherwise, with view rows kept and f on the set and view nodes only, the
  // view rows and the interior's solve (displacement_on_view, complete_interior); otherwise one
  // StaticSolver::solve. All give K^-1 f to round-off.
  void displacement(const Eigen::VectorXd& f, Eigen::VectorXd& du);
  // Whether displacement(f) would back-substitute (f loads a node without whole-mesh columns at hand, or summing
  // them costs more than the two sweeps over the factor).
  bool needs_solve(const Eigen::VectorXd& f) const;
  // du = K^-1 f on the set nodes and the view nodes only, every other entry 0 (3n, metres), from C, the view rows
  // and the cached outside columns (solving first for the columns of loaded outside nodes not cached yet): what
  // is drawn, exact, while the interior is solved elsewhere. Needs keeps_view_rows() (std::logic_error otherwise).
  void displacement_on_view(const Eigen::VectorXd& f, Eigen::VectorXd& du);
  // Whether f loads no node but the set's and the view's (complete_interior's condition).
  bool loads_only_view(const Eigen::VectorXd& f) const;
  // du (3n) exact on the set and view nodes for loads on them only (displacement_on_view), completed on every other
  // node: the interior's own solve, u_I = -K_II^-1 K_IB u_B (InteriorSolver, made with the view rows), instead of a
  // back-substitution over the whole mesh. Uses no other solver and changes nothing here, so it may run on another
  // thread while this object is not used. Needs keeps_view_rows() (std::logic_error otherwise).
  void complete_interior(Eigen::VectorXd& du) const;
  // du = K^-1 f on the set nodes and on the nodes listed in `also` only, every other entry 0 (3n, metres): what
  // a check of the set (the inner wall) needs, for a fraction of the whole-mesh cost. Lazy: one back-substitution,
  // whose whole-mesh result displacement() reuses for the same f (or one changed only on nodes whose whole-mesh
  // columns are cached) without solving again.
  void displacement_on_set(const Eigen::VectorXd& f, Eigen::VectorXd& du, const std::vector<int>& also = {});

 private:
  void check_node(int node, const char* what) const;
  int half_position(int node, const std::vector<double>& z, const char* where);  // checked, half columns at hand
  // Whether summing the whole-mesh columns of this many loaded nodes costs no more than a back-substitution.
  bool summing_is_cheaper(size_t nodes) const;
  // Column block of set node a (position in nodes_): 3s x 3, C's columns 3a .. 3a + 2 (not lazy).
  Eigen::Ref<const Eigen::MatrixXd> set_block(int a) const;
  // Half columns of a lazy set's node: its 3 DOFs' sparse columns over the factor's rows, on one pattern
  // (StaticSolver::half_columns): rows index (ascending), values row-major, value[3 e + c] of DOF c at index[e].
  struct HalfColumns {
    std::vector<int> index;
    std::vector<double> value;
  };
  void solve_half_columns(int a);  // half_[a] of set node a (position in nodes_)
  void solve_half_columns(const std::vector<int>& positions);  // the same for each listed node without them
  // z (n_free) += Y_a w; y = Y_a^T z (3); C_ab = Y_a^T Y_b (3 x 3).
  void scatter_half(int a, const Eigen::Vector3d& w, std::vector<double>& z) const;
  Eigen::Vector3d gather_half(int a, const std::vector<double>& z) const;
  Eigen::Matrix3d half_block(int a, int b);
  // C on the listed distinct set nodes of a lazy set (positions in nodes_), 3k x 3k, m/N: blocks of the kept gram,
  // to which nodes without them are added first (their half columns solved for if not at hand).
  Eigen::MatrixXd half_gram(const std::vector<int>& set_positions);
  void keep_gram(const std::vector<int>& set_positions);  // the same, without the copy out
  // The kept gram becomes that of kept (nodes with slots in it) then fresh (without): the kept blocks copied, the
  // fresh rows Y_F^T Y from one dense product over the fresh half columns' rows (all fresh: Y^T Y, a rank update).
  void extend_gram(const std::vector<int>& kept, const std::vector<int>& fresh);
  Eigen::MatrixXd kept_blocks(const std::vector<int>& positions) const;  // 3k x 3k: C on nodes with gram slots
  void clear_half(int a, std::vector<double>& z) const;  // z = 0 on Y_a's pattern
  friend class CouplingMatrix;
  const StaticSolver* solver_;
  std::vector<int> nodes_;
  std::vector<int> index_;                   // mesh node -> position in nodes_, or -1
  bool lazy_ = false;
  Eigen::MatrixXd C_;                        // 3s x 3s, m/N (empty when lazy)
  std::vector<HalfColumns> half_;            // lazy: per set node, its half columns (sqrt(m/N))
  std::vector<char> half_solved_;            // lazy: per set node, 1 when half_ holds them
  std::vector<double> half_z_;               // lazy: workspace over the factor's rows (n_free), kept 0 between uses
  int max_gram_nodes_;
  std::vector<int> gram_nodes_;              // lazy: set positions with blocks in gram_, in its order
  std::vector<int> gram_slot_;               // lazy: per set node, its position in gram_nodes_, or -1
  Eigen::MatrixXd gram_;                     // lazy: 3g x 3g, C among gram_nodes_, m/N
  Eigen::VectorXd last_f_, last_du_;         // lazy: the last back-substitution's forces and whole-mesh result
  Eigen::MatrixXd Kc_;                       // 3n x 3s whole-mesh columns of the set DOFs, m/N (or empty)
  std::vector<int> view_nodes_;              // nodes outside the set whose rows are kept (sorted)
  Eigen::MatrixXd V_;                        // 3v x 3s, rows of view_nodes_ in the set's columns, m/N (or empty)
  std::vector<char> on_view_;                // per mesh node: 1 in the set or the view (with view rows)
  std::unique_ptr<InteriorSolver> interior_; // the nodes off the set and the view (null: none, or no view rows)
  std::vector<int> extra_index_;             // mesh node -> position in extra_nodes_, or -1
  std::vector<int> extra_nodes_;             // nodes outside the set with cached columns
  std::vector<Eigen::MatrixXd> extra_cols_;  // per cached node: 3n x 3, K^-1 columns of its DOFs, m/N
};

}  // namespace lumen::physics
