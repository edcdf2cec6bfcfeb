// Rays against a triangle surface (collision/raycast.hpp): the tree against its brute-force twin on random rays,
// and distances against a cube's analytic ones; the listing of intersecting triangle pairs.
#include <gtest/gtest.h>

#include <random>

#include "collision/intersect.hpp"
#include "collision/raycast.hpp"
#include "support/soup.hpp"

using namespace lumen::collision;

namespace {

using P = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using T = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;

// A unit cube [0, 1]^3 as 12 outward triangles.
void cube(P& x, T& t) {
  x.resize(8, 3);
  for (int c = 0; c < 8; ++c) x.row(c) << (c & 1), (c >> 1 & 1), (c >> 2 & 1);
  t.resize(12, 3);
  t << 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4, 2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5;
}

}  // namespace

TEST(RayCaster, CubeDistancesAreTheAnalyticOnes) {
  P x;
  T t;
  cube(x, t);
  const RayCaster caster(x, t);
  const double o[3] = {0.25, 0.5, 0.5};
  const double right[3] = {1, 0, 0}, left[3] = {-1, 0, 0};
  EXPECT_NEAR(caster.first_hit(o, right).t, 0.75, 1e-15);
  EXPECT_NEAR(caster.first_hit(o, left).t, 0.25, 1e-15);
  const double away[3] = {2, 0.5, 0.5};
  EXPECT_FALSE(caster.first_hit(away, right).hit());
  // From a vertex, skipping its own triangles: along the diagonal into the cube to the opposite corner.
  const double corner[3] = {0, 0, 0};
  const double diag[3] = {1 / std::sqrt(3.0), 1 / std::sqrt(3.0), 1 / std::sqrt(3.0)};
  EXPECT_NEAR(caster.first_hit(corner, diag, 0).t, std::sqrt(3.0), 1e-12);
}

TEST(RayCaster, TreeEqualsBruteForceOnRandomRays) {
  // A random triangle soup in the unit box.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  P x;
  T t;
  lumen::test::make_triangle_soup(rng, 300, 0.1, x, t);
  const RayCaster caster(x, t);
  int hits = 0;
  for (int r = 0; r < 2000; ++r) {
    const Eigen::Vector3d o(u(rng), u(rng), u(rng));
    const Eigen::Vector3d d = Eigen::Vector3d(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5).normalized();
    const RayHit a = caster.first_hit(o.data(), d.data()), b = caster.first_hit_brute_force(o.data(), d.data());
    ASSERT_EQ(a.triangle, b.triangle) << r;
    if (a.hit()) {
      EXPECT_EQ(a.t, b.t);
    }
    hits += a.hit();
  }
  EXPECT_GT(hits, 100);  // enough rays meet a triangle for the comparison to mean something
}

// intersecting_pairs lists the pairs count_intersecting_pairs counts: a cube and a copy shifted into it.
TEST(IntersectingPairs, ListsThePairsItCounts) {
  P a;
  T ta;
  cube(a, ta);
  P x(16, 3);
  x.topRows(8) = a;
  x.bottomRows(8) = a.rowwise() + Eigen::RowVector3d(0.5, 0.25, 0.125);
  T t(24, 3);
  t.topRows(12) = ta;
  t.bottomRows(12) = ta.array() + 8;
  const auto pairs = intersecting_pairs(x, t);
  EXPECT_EQ(static_cast<long>(pairs.size()), count_intersecting_pairs(x, t));
  ASSERT_FALSE(pairs.empty());
  for (const auto& p : pairs) {
    EXPECT_LT(p[0], 12);  // each cube alone is free of intersections: every pair is across
    EXPECT_GE(p[1], 12);
  }
  EXPECT_TRUE(intersecting_pairs(a, ta).empty());
}
