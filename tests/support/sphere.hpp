// Test support: a closed latitude-longitude sphere (the surface the wall-growth tests grow from).
#pragma once

#include <cmath>

#include <Eigen/Core>

#include "support/tube.hpp"

namespace lumen::test {

// A latitude-longitude sphere of radius r about the origin: the two poles (vertices 0 at -z and 1 at +z) and
// `rings` x `around` vertices between, triangles counter-clockwise seen from outside.
inline void make_uv_sphere(double r, int rings, int around, TubePoints& x, TubeTris& tris) {
  x.resize(2 + rings * around, 3);
  x.row(0) << 0.0, 0.0, -r;
  x.row(1) << 0.0, 0.0, r;
  auto id = [&](int k, int i) { return 2 + k * around + (i % around); };
  for (int k = 0; k < rings; ++k)
    for (int i = 0; i < around; ++i) {
      const double phi = EIGEN_PI * (k + 1) / (rings + 1), a = 2.0 * EIGEN_PI * i / around;
      x.row(id(k, i)) << r * std::sin(phi) * std::cos(a), r * std::sin(phi) * std::sin(a), -r * std::cos(phi);
    }
  tris.resize(2 * around * rings, 3);
  int t = 0;
  for (int i = 0; i < around; ++i) {
    tris.row(t++) << 0, id(0, i + 1), id(0, i);
    tris.row(t++) << 1, id(rings - 1, i), id(rings - 1, i + 1);
    for (int k = 0; k + 1 < rings; ++k) {
      tris.row(t++) << id(k, i), id(k, i + 1), id(k + 1, i + 1);
      tris.row(t++) << id(k, i), id(k + 1, i + 1), id(k + 1, i);
    }
  }
}

}  // namespace lumen::test
