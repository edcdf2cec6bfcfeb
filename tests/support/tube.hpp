// Test support: an open triangulated tube (the surface the collision tests deform and count on).
#pragma once

#include <cmath>

#include <Eigen/Core>

namespace lumen::test {

inline constexpr double kPaperOuterRadius = 0.013;  // metres: the paper tube's outer wall (inner 0.010)

using TubePoints = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using TubeTris = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;

// Open tube of nz x nth quads (2 triangles each) along z: radius r, length len (metres).
inline void make_tube(int nz, int nth, double r, double len, TubePoints& x, TubeTris& tris) {
  x.resize((nz + 1) * nth, 3);
  for (int k = 0; k <= nz; ++k) {
    for (int j = 0; j < nth; ++j) {
      const double th = 2.0 * EIGEN_PI * j / nth;
      x.row(k * nth + j) << r * std::cos(th), r * std::sin(th), len * k / nz;
    }
  }
  tris.resize(2 * nz * nth, 3);
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < nth; ++j) {
      const int v00 = k * nth + j, v01 = k * nth + (j + 1) % nth;
      const int v10 = (k + 1) * nth + j, v11 = (k + 1) * nth + (j + 1) % nth;
      tris.row(2 * (k * nth + j)) << v00, v01, v11;
      tris.row(2 * (k * nth + j) + 1) << v00, v11, v10;
    }
  }
}

}  // namespace lumen::test
