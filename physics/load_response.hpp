#pragma once
// Probe coupling: the whole-mesh displacement for forces at a few fixed surface points (probe tips) of a
// prefactorised FEM model, precomputed. A frame is then u = U * forces, a dense 3n x 3m mat-vec (m = number of
// load points), no back-substitution at all.
#include <Eigen/Core>
#include <vector>

#include "physics/fem.hpp"
#include "physics/types.hpp"

namespace lumen::physics {

// A load point on the surface: up to 3 mesh nodes with barycentric weights (unused entries: node = -1).
struct LoadPoint {
  int node[3] = {-1, -1, -1};
  double weight[3] = {0.0, 0.0, 0.0};
  int triangle = -1;  // the surface triangle it lies on (-1 when it is not given by one)
};

// Spread a force (newtons) at a load point over its nodes by their weights: f (3n) += ...
void add_point_force(const LoadPoint& p, const Eigen::Vector3d& force, Eigen::VectorXd& f);

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

}  // namespace lumen::physics
