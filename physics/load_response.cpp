// Probe coupling: precomputed whole-mesh response to forces at fixed load points.
#include "physics/load_response.hpp"

#include <cmath>
#include <string>

#include "physics/detail/messages.hpp"

namespace lumen::physics {

void add_point_force(const LoadPoint& p, const Eigen::Vector3d& force, Eigen::VectorXd& f) {
  for (int k = 0; k < 3; ++k)
    if (p.node[k] >= 0) f.segment<3>(3 * p.node[k]) += p.weight[k] * force;
}

using detail::check_slot;
using detail::fail;
using detail::num;

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

}  // namespace lumen::physics
