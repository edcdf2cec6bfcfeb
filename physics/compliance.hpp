#pragma once
// Precomputed responses of a prefactorised FEM model (what makes a frame cheap) and contact solves on them.
//
// Per-frame physics path: the loads of a frame act at a few fixed surface points (probe tips). LoadResponse
// precomputes U = K^-1 [unit forces at those points] once (one multi-column CHOLMOD solve); a frame is then
// u = U * forces, a dense 3n x 3m mat-vec (m = number of load points), no back-substitution at all.
//
// Contact path: SurfaceCompliance holds C = K^-1 restricted to a node set (the inner wall). Contacts are rows
// of a constraint matrix H; their coupling A = H C H^T is small and dense, so the multipliers lambda come from
// a dense solve (equality, the paper's "hold the colliding vertices") or an LCP (non-penetration: Lemke on all
// of A, or an active-set method that needs only the columns of A of its active rows, CouplingMatrix), and the
// whole-mesh correction du = K^-1 H^T lambda is a short sum of precomputed columns (few loaded nodes) or one
// back-substitution.
#include <Eigen/Core>
#include <functional>
#include <vector>

#include "physics/fem.hpp"
#include "physics/types.hpp"

namespace lumen::physics {

// A load point on the surface: up to 3 mesh nodes with barycentric weights (unused entries: node = -1), and the
// surface triangle it lies on (-1 when it is not given by one).
struct LoadPoint {
  int node[3] = {-1, -1, -1};
  double weight[3] = {0.0, 0.0, 0.0};
  int triangle = -1;
};

// Displacement of the whole mesh for forces at fixed load points, precomputed.
// Keeps no reference to the solver.
class LoadResponse {
 public:
  // One solve_many with 3m unit-force columns (x, y, z at each point, split over its nodes by the weights).
  LoadResponse(const StaticSolver& solver, const std::vector<LoadPoint>& points);

  int n_points() const { return static_cast<int>(points_.size()); }
  const std::vector<LoadPoint>& points() const { return points_; }
  // U, 3n x 3m, metres per newton: column 3p + c is the displacement for a unit force along axis c at point p.
  const Eigen::MatrixXd& response() const { return U_; }
  // Compliance between load points, 3m x 3m, metres per newton: row 3q + i is the displacement of point q
  // (weighted over its nodes) along axis i; use it to find the force that moves a point to a target.
  const Eigen::MatrixXd& point_compliance() const { return P_; }

  // u = U * forces: forces m x 3 (row p = force at point p), newtons; u 3n, metres. No allocation when u has
  // the right size already.
  void displacement(const Points& forces, Eigen::VectorXd& u) const;
  Eigen::VectorXd displacement(const Points& forces) const;

 private:
  std::vector<LoadPoint> points_;
  Eigen::MatrixXd U_;  // 3n x 3m, m/N
  Eigen::MatrixXd P_;  // 3m x 3m, m/N
};

// Dense compliance C = K^-1 restricted to a set of nodes (e.g. the inner wall), plus on-demand columns for
// nodes outside the set. Keeps a reference to the solver, which must outlive it.
//
// The whole-mesh columns K^-1 e of the set's DOFs (3n x 3s) come out of the same solves; they are kept when
// they take at most max_mesh_column_bytes, so that the whole-mesh response to forces on a few set nodes is a
// short sum of columns instead of a back-substitution (see displacement()).
class SurfaceCompliance {
 public:
  // nodes: distinct mesh node ids. Columns are computed block_columns at a time (solve_many).
  SurfaceCompliance(const StaticSolver& solver, const std::vector<int>& nodes, int block_columns = 64,
                    long max_mesh_column_bytes = 256L << 20);

  const StaticSolver& solver() const { return *solver_; }
  int n_nodes_mesh() const { return solver_->n_dofs() / 3; }
  const std::vector<int>& nodes() const { return nodes_; }
  // Position of a mesh node in nodes(), or -1.
  int index_of(int node) const;
  // C, 3s x 3s, metres per newton: C(3a + i, 3b + j) = d u(nodes[a], i) / d f(nodes[b], j).
  const Eigen::MatrixXd& matrix() const { return C_; }

  // 3 x 3 block d u(node_a) / d f(node_b) for any two mesh nodes; columns of nodes outside the set are
  // solved for and cached on first use.
  Eigen::Matrix3d block(int node_a, int node_b);
  // Solves for the columns of every listed node outside the set not cached yet, in one solve_many.
  void ensure_columns(const std::vector<int>& nodes);
  // Number of nodes outside the set whose columns are cached.
  int n_cached_nodes() const { return static_cast<int>(extra_nodes_.size()); }
  // Whether the whole-mesh columns of the set nodes are kept (3n x 3s, m/N).
  bool keeps_mesh_columns() const { return Kc_.size() > 0; }

  // du = K^-1 f (3n, metres) for nodal forces f (3n, newtons). When f acts on few nodes whose whole-mesh
  // columns are at hand (kept set columns, cached outside columns) and summing them is cheaper than a
  // back-substitution, du is that sum; otherwise one StaticSolver::solve. Both give K^-1 f to round-off.
  void displacement(const Eigen::VectorXd& f, Eigen::VectorXd& du);
  // du = K^-1 f on the set nodes and on the nodes listed in `also` only, every other entry 0 (3n, metres): what
  // a check of the set (the inner wall) needs, for a fraction of the whole-mesh cost.
  void displacement_on_set(const Eigen::VectorXd& f, Eigen::VectorXd& du, const std::vector<int>& also = {});

 private:
  void check_node(int node, const char* what) const;
  friend class CouplingMatrix;
  const StaticSolver* solver_;
  std::vector<int> nodes_;
  std::vector<int> index_;                   // mesh node -> position in nodes_, or -1
  Eigen::MatrixXd C_;                        // 3s x 3s, m/N
  Eigen::MatrixXd Kc_;                       // 3n x 3s whole-mesh columns of the set DOFs, m/N (or empty)
  std::vector<int> extra_index_;             // mesh node -> position in extra_nodes_, or -1
  std::vector<int> extra_nodes_;             // nodes outside the set with cached columns
  std::vector<Eigen::MatrixXd> extra_cols_;  // per cached node: 3n x 3, K^-1 columns of its DOFs, m/N
};

// One contact constraint row of H: (H u)_r = n . sum_k weight[k] * u(node[k]), metres.
// Vertex-face: weights (1, -b0, -b1, -b2) on (vertex, face nodes); edge-edge: (1 - s, s, -(1 - t), -t);
// a prescribed node displacement: one node, weight 1, n a unit axis, g the wanted displacement component.
// Unused entries: node = -1.
struct ContactRow {
  int node[4] = {-1, -1, -1, -1};
  double weight[4] = {0.0, 0.0, 0.0, 0.0};
  Eigen::Vector3d n = Eigen::Vector3d::Zero();  // direction (usually the unit contact normal)
  double g = 0.0;                               // required value of the row (equality) or minimum (LCP), metres
};

// Options of the dense LCP solver.
struct LcpOptions {
  double tolerance = 1e-9;  // residual accepted as converged, metres
  int max_iterations = 0;   // pivot bound; 0 = 10 * rows + 100
};

// Result of a dense LCP w = A z + q, w >= 0, z >= 0, w . z = 0.
struct LcpResult {
  Eigen::VectorXd z;    // multipliers, >= 0
  Eigen::VectorXd w;    // A z + q
  int iterations = 0;   // pivots
  double residual = 0;  // max_i |min(w_i, A_ii z_i)| and max(-w_i, 0), units of q
  bool converged = false;
};

// Lemke's complementary pivoting (lexicographic tie-break, covering vector 1) on a dense symmetric positive
// semidefinite A (m x m), with a final polish on the active set. Fails (converged = false) on ray termination
// (infeasible problem) or at the pivot bound.
LcpResult solve_lcp_dense(const Eigen::MatrixXd& A, const Eigen::VectorXd& q, const LcpOptions& options = {});

// Active-set solve of the same LCP for a symmetric positive semidefinite A given column by column
// (column(j) = A e_j, called only for indices that enter the active set), in the manner of Lawson and Hanson's
// NNLS on the equivalent convex QP min 1/2 z^T A z + q^T z, z >= 0: solve A_PP z_P = -q_P on the passive set P
// (incrementally updated Cholesky), step back and drop indices whose z would turn negative, add the index of
// the most negative w, until w >= -tolerance off P. A row that is linearly dependent on P is exchanged with a
// member of P along the null direction; an unbounded such direction (infeasible problem) ends the solve.
// warm: indices guessed to be active (e.g. the last solve's), tried first. iterations counts the rounds (adds,
// drops, exchanges); max_iterations 0 = 10 * rows + 100. converged = false (never a throw) on an infeasible
// problem or at the round bound: callers fall back to solve_lcp_dense.
LcpResult solve_lcp_active_set(const std::function<const Eigen::VectorXd&(int)>& column, const Eigen::VectorXd& q,
                               const std::vector<int>& warm = {}, const LcpOptions& options = {});
// The same on a dense A (m x m).
LcpResult solve_lcp_active_set(const Eigen::MatrixXd& A, const Eigen::VectorXd& q, const std::vector<int>& warm = {},
                               const LcpOptions& options = {});

// Result of a contact solve.
struct ContactResult {
  Eigen::VectorXd lambda;      // row multipliers, newtons, one per row (>= 0 for the LCP)
  Eigen::VectorXd force;       // f_c = H^T lambda, nodal contact forces, 3n, newtons
  Eigen::VectorXd correction;  // du = K^-1 f_c, 3n, metres: whole mesh, or (whole_mesh = false) only on the
                               // compliance's set and the rows' nodes (SurfaceCompliance::displacement_on_set)
  int iterations = 0;          // LCP pivots or active-set rounds (1 for the equality solve)
  double residual = 0.0;       // max row violation at u_free + du, metres (see solve_equality / solve_lcp)
  bool converged = false;      // residual <= tolerance
  bool used_lemke = false;     // solve_contacts: the active-set method failed and Lemke's pivoting was used
  Eigen::VectorXd held_force;  // solve_contacts with held points: change of their forces, 3d, newtons
};

// Load points held at prescribed displacements while contacts are solved (displacement-driven probes): their
// forces change so that the contacts do not move them. U: K^-1 of unit loads at the points (3n x 3d, m/N, e.g.
// columns of LoadResponse::response()); S: the inverse of their point compliance (3d x 3d, N/m).
struct HeldPoints {
  std::vector<LoadPoint> points;  // d points
  Eigen::MatrixXd U;              // 3n x 3d, metres per newton
  Eigen::MatrixXd S;              // 3d x 3d, newtons per metre
};

// The coupling matrix A = H C H^T (rows x rows, metres per newton) of a fixed set of rows, evaluated a column
// at a time on first use and cached: a column costs O(touched nodes + rows), so a solver that needs only the
// columns of its active rows never pays for all of A. Keeps references to the compliance and the rows, which
// must outlive it and stay unchanged.
class CouplingMatrix {
 public:
  // Validates the rows and solves once for the columns of every touched node outside the compliance's set.
  CouplingMatrix(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows);
  int size() const { return static_cast<int>(rows_->size()); }
  // A e_s: entry r is h_r . C h_s, metres per newton.
  const Eigen::VectorXd& column(int s);
  // All of A, symmetrised (computes the missing columns).
  Eigen::MatrixXd dense();
  // Number of columns computed so far.
  int columns_computed() const { return n_computed_; }

 private:
  SurfaceCompliance* compliance_;
  const std::vector<ContactRow>* rows_;
  std::vector<int> touched_;                  // distinct nodes of the rows
  std::vector<int> touched_set_index_;        // per touched node: position in the compliance set, or -1
  std::vector<int> entry_begin_;              // rows + 1: row r's used entries are [begin[r], begin[r + 1])
  std::vector<int> entry_slot_;               // per entry: position of its node in touched_
  std::vector<Eigen::Vector3d> entry_wn_;     // per entry: weight * n
  std::vector<Eigen::VectorXd> columns_;      // cached columns (empty until computed)
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> y_;  // workspace: C h_s on the touched nodes
  int n_computed_ = 0;
};

// H u for the rows, metres (u: 3n).
Eigen::VectorXd row_values(const std::vector<ContactRow>& rows, const Eigen::VectorXd& u);
// H^T lambda, a nodal force vector of length n_dofs, newtons.
Eigen::VectorXd contact_force(const std::vector<ContactRow>& rows, const Eigen::VectorXd& lambda, int n_dofs);
// A = H C H^T, rows x rows, metres per newton (computes missing compliance columns on demand).
Eigen::MatrixXd coupling_matrix(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows);

// Equality constraints H (u_free + du) = g: A lambda = g - H u_free (Cholesky, or the minimum-norm least-squares
// solution when A is singular; rows on fixed DOFs only, whose diagonal of A is 0, get lambda = 0 and do not
// spoil the Cholesky). residual = max |H u - g|; converged when <= tolerance (metres). whole_mesh = false: the
// correction only on the set and the rows' nodes (enough for the residual and for a check of the set).
ContactResult solve_equality(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows,
                             const Eigen::VectorXd& u_free, double tolerance = 1e-9, bool whole_mesh = true);

// Non-penetration H u >= g with lambda >= 0 and lambda . (H u - g) = 0, by solve_lcp_dense on A.
// residual = max over rows of (g - H u)^+ and, where lambda > 0, |H u - g|.
ContactResult solve_lcp(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows,
                        const Eigen::VectorXd& u_free, const LcpOptions& options = {});

// The same non-penetration problem by solve_lcp_active_set on columns of A computed on demand (a few per
// active row instead of all of A), warm-started from `warm` (row indices guessed to push, e.g. the rows of
// last frame's pushing contacts); when that does not converge, solve_lcp_dense on the whole A (used_lemke).
// whole_mesh as for solve_equality.
// With `held` (may be null), the held points keep their displacement: the LCP is on the Schur complement
// A - G S G^T (G = H U, rows x 3d), their force change is -S G^T lambda (held_force), and force and correction
// include it, so the points stay where they were in u_free (exactly, up to round-off).
ContactResult solve_contacts(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows,
                             const Eigen::VectorXd& u_free, const std::vector<int>& warm = {},
                             const LcpOptions& options = {}, bool whole_mesh = true,
                             const HeldPoints* held = nullptr);

}  // namespace lumen::physics
