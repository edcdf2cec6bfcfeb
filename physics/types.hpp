#pragma once
// Plain array types shared by physics, collision, render and engine.
#include <Eigen/Dense>

namespace lumen {

// Row-major n x 3 array of points (one row per vertex), metres.
using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
// Row-major n x 4 tetrahedra (vertex indices), positively oriented.
using Tets = Eigen::Matrix<int, Eigen::Dynamic, 4, Eigen::RowMajor>;
// Row-major n x 3 triangles (vertex indices).
using Tris = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;

namespace physics {
// Pi as a double (Eigen's EIGEN_PI is a long double).
inline constexpr double kPi = static_cast<double>(EIGEN_PI);
}  // namespace physics

}  // namespace lumen
