// Test support: a random triangle soup (separate triangles scattered in the unit box), for twin tests of the
// collision queries against their brute-force or floating-point twins.
#pragma once

#include <random>

#include <Eigen/Core>

#include "support/tube.hpp"

namespace lumen::test {

// n triangles, each 3 vertices of its own (triangle k is vertices 3k, 3k + 1, 3k + 2): a centre uniform in the
// unit box, each vertex uniform within `size` of it along every axis (drawn in that order: the centre's x, y, z,
// then each vertex's x, y, z).
inline void make_triangle_soup(std::mt19937& rng, int n, double size, TubePoints& x, TubeTris& tris) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  x.resize(3 * n, 3);
  tris.resize(n, 3);
  for (int t = 0; t < n; ++t) {
    const double c[3] = {u(rng), u(rng), u(rng)};
    for (int k = 0; k < 3; ++k)
      for (int a = 0; a < 3; ++a) x(3 * t + k, a) = c[a] + size * (u(rng) - 0.5);
    tris.row(t) << 3 * t, 3 * t + 1, 3 * t + 2;
  }
}

}  // namespace lumen::test
