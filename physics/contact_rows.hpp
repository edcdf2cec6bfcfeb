#pragma once
// Contact rows and their coupling: the rows of the constraint matrix H (vertex-face, edge-edge, prescribed
// displacements), H u, H^T lambda, and A = H C H^T on a SurfaceCompliance, whole or a column at a time.
#include <Eigen/Core>
#include <vector>

#include "physics/surface_compliance.hpp"

namespace lumen::physics {

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

// The coupling matrix A = H C H^T (rows x rows, metres per newton) of a fixed set of rows, evaluated a column
// at a time on first use and cached: a column costs O(touched nodes + rows), so a solver that needs only the
// columns of its active rows never pays for all of A. Keeps references to the compliance and the rows, which
// must outlive it and stay unchanged.
class CouplingMatrix {
 public:
  // Validates the rows and solves once for the columns of every touched node outside the compliance's set.
  // node_frames (n_nodes rotations, or null): A = (H Rn) C (H Rn)^T, the coupling of the warped compliance
  // Rn C Rn^T (Rn block-diagonal, one rotation per node): each row's entry on node v is weight * R_v^T n.
  CouplingMatrix(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows,
                 const std::vector<Eigen::Matrix3d>* node_frames = nullptr);
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
  // h_r . y for y holding a 3-vector per touched node, in touched_ order (3t entries): row r's entries against it.
  double row_times(int r, const double* y) const;
};

// The distinct nodes of the rows, ascending.
std::vector<int> row_nodes(const std::vector<ContactRow>& rows);
// H u for the rows, metres (u: 3n).
Eigen::VectorXd row_values(const std::vector<ContactRow>& rows, const Eigen::VectorXd& u);
// g for the rows: each row's required value, metres.
Eigen::VectorXd row_targets(const std::vector<ContactRow>& rows);
// H^T lambda, a nodal force vector of length n_dofs, newtons.
Eigen::VectorXd contact_force(const std::vector<ContactRow>& rows, const Eigen::VectorXd& lambda, int n_dofs);
// A = H C H^T, rows x rows, metres per newton (computes missing compliance columns on demand); with node_frames,
// H Rn C Rn^T H^T (CouplingMatrix).
Eigen::MatrixXd coupling_matrix(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows,
                                const std::vector<Eigen::Matrix3d>* node_frames = nullptr);

}  // namespace lumen::physics
