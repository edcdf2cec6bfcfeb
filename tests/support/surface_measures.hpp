// Test support: measures of a triangle surface (positions x, n x 3, metres or any unit; triangles, m x 3), the
// independent side of the mesh and remeshing tests.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace lumen::test {

using SurfacePoints = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using SurfaceTris = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;

// The volume a closed surface encloses by the divergence theorem (the cones from the origin): positive when its
// triangles face outward, negative when they face inward.
inline double enclosed_volume(const SurfacePoints& x, const SurfaceTris& tris) {
  double six = 0.0;
  for (Eigen::Index t = 0; t < tris.rows(); ++t)
    six += x.row(tris(t, 0)).dot(x.row(tris(t, 1)).cross(x.row(tris(t, 2))));
  return six / 6.0;
}

// Every triangle side's length (a closed surface's edges each twice, once per triangle), ascending.
inline std::vector<double> sorted_side_lengths(const SurfacePoints& x, const SurfaceTris& tris) {
  std::vector<double> l;
  for (Eigen::Index t = 0; t < tris.rows(); ++t)
    for (int k = 0; k < 3; ++k) l.push_back((x.row(tris(t, k)) - x.row(tris(t, (k + 1) % 3))).norm());
  std::sort(l.begin(), l.end());
  return l;
}

// Every interior angle of every triangle, degrees, ascending.
inline std::vector<double> sorted_angles_deg(const SurfacePoints& x, const SurfaceTris& tris) {
  std::vector<double> a;
  for (Eigen::Index t = 0; t < tris.rows(); ++t)
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p = x.row(tris(t, k)), q = x.row(tris(t, (k + 1) % 3)), r = x.row(tris(t, (k + 2) % 3));
      a.push_back(std::acos(std::clamp((q - p).normalized().dot((r - p).normalized()), -1.0, 1.0)) * 180.0 /
                  static_cast<double>(EIGEN_PI));
    }
  std::sort(a.begin(), a.end());
  return a;
}

}  // namespace lumen::test
