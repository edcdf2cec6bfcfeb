#include "physics/support.hpp"

#include <vector>

#include <Eigen/Geometry>

namespace lumen::physics {

Eigen::VectorXd lumped_areas(const Points& rest, const Tris& surface) {
  Eigen::VectorXd area = Eigen::VectorXd::Zero(rest.rows());
  for (Eigen::Index t = 0; t < surface.rows(); ++t) {
    const Eigen::Vector3d a = rest.row(surface(t, 0)), b = rest.row(surface(t, 1)), c = rest.row(surface(t, 2));
    const double third = (b - a).cross(c - a).norm() / 6.0;
    for (int k = 0; k < 3; ++k) area[surface(t, k)] += third;
  }
  return area;
}

Eigen::SparseMatrix<double> support_stiffness(const Points& rest, const Tris& surface, double k) {
  const Eigen::VectorXd area = lumped_areas(rest, surface);
  std::vector<Eigen::Triplet<double>> entries;
  for (Eigen::Index v = 0; v < area.size(); ++v) {
    if (area[v] == 0.0) continue;
    for (int d = 0; d < 3; ++d) entries.emplace_back(3 * v + d, 3 * v + d, k * area[v]);
  }
  Eigen::SparseMatrix<double> S(3 * rest.rows(), 3 * rest.rows());
  S.setFromTriplets(entries.begin(), entries.end());
  return S;
}

}  // namespace lumen::physics
