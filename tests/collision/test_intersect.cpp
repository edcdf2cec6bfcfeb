// Exact discrete intersection check: predicates against integer truth and known constructions,
// triangle-triangle cases (touching, coplanar, shared features), and the pruned count against all pairs.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "collision/intersect.hpp"
#include "support/soup.hpp"
#include "support/tube.hpp"

namespace lumen::collision {
namespace {

using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using Tris = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;
using test::make_tube;  // open tube along z (tests/support/tube.hpp)
using P3 = std::array<double, 3>;

int sign128(__int128 v) { return v > 0 ? 1 : (v < 0 ? -1 : 0); }

// Exact orient3d on integer coordinates (|c| < 2^24), same determinant as the predicate.
int orient3d_int(const long long* a, const long long* b, const long long* c, const long long* d) {
  const __int128 adx = a[0] - d[0], ady = a[1] - d[1], adz = a[2] - d[2];
  const __int128 bdx = b[0] - d[0], bdy = b[1] - d[1], bdz = b[2] - d[2];
  const __int128 cdx = c[0] - d[0], cdy = c[1] - d[1], cdz = c[2] - d[2];
  return sign128(adz * (bdx * cdy - cdx * bdy) + bdz * (cdx * ady - adx * cdy) + cdz * (adx * bdy - bdx * ady));
}

// Plain floating-point orient3d (what the filter evaluates), to show where rounding alone fails.
int orient3d_naive(const double* a, const double* b, const double* c, const double* d) {
  const double adx = a[0] - d[0], ady = a[1] - d[1], adz = a[2] - d[2];
  const double bdx = b[0] - d[0], bdy = b[1] - d[1], bdz = b[2] - d[2];
  const double cdx = c[0] - d[0], cdy = c[1] - d[1], cdz = c[2] - d[2];
  const double det = adz * (bdx * cdy - cdx * bdy) + bdz * (cdx * ady - adx * cdy) + cdz * (adx * bdy - bdx * ady);
  return det > 0 ? 1 : (det < 0 ? -1 : 0);
}

// ---------------------------------------------------------------------------------------------------
// Predicates.

TEST(Orient, Orient3dMatchesIntegerTruthScaledAndTranslated) {
  std::mt19937_64 rng(1);
  int zeros = 0;
  for (long long range : {2LL, 1000LL, 1LL << 22}) {
    std::uniform_int_distribution<long long> u(-range, range);
    for (int trial = 0; trial < 3000; ++trial) {
      long long q[4][3];
      for (auto& p : q) {
        for (auto& c : p) c = u(rng);
      }
      const int truth = orient3d_int(q[0], q[1], q[2], q[3]);
      zeros += truth == 0;
      // Power-of-two scalings (exact; tiny ones underflow and huge ones overflow the filter's products)
      // and an exact translation by 2^30 leave the sign unchanged.
      for (int e : {0, -600, -1070 + 25, 500, 960}) {
        double p[4][3], t[4][3];
        for (int i = 0; i < 4; ++i) {
          for (int d = 0; d < 3; ++d) {
            p[i][d] = std::ldexp(static_cast<double>(q[i][d]), e);
            t[i][d] = static_cast<double>(q[i][d]) + 1073741824.0;
          }
        }
        ASSERT_EQ(orient3d(p[0], p[1], p[2], p[3]), truth) << "scale 2^" << e;
        ASSERT_EQ(orient3d_exact(p[0], p[1], p[2], p[3]), truth);
        ASSERT_EQ(orient3d(t[0], t[1], t[2], t[3]), truth) << "translated";
      }
    }
  }
  EXPECT_GT(zeros, 100);  // coplanar cases were exercised
}

TEST(Orient, Orient3dExactNearTiltedPlane) {
  // a, b, c on the plane z = x; d near (0.5, y, 0.5) moved by single ulps: the sign is lambda * sign(dz - dx).
  const double a[3] = {12, -3, 12}, b[3] = {-5, 7.25, -5}, c[3] = {2.5, 20, 2.5};
  // Sign for dz - dx > 0: the same points times 4 (integers) with d = 4 (0, 0, 1).
  const long long ai[3] = {48, -12, 48}, bi[3] = {-20, 29, -20}, ci[3] = {10, 80, 10}, di[3] = {0, 0, 4};
  const int lambda = orient3d_int(ai, bi, ci, di);
  ASSERT_NE(lambda, 0);
  const double ulp = std::ldexp(1.0, -53);
  int naive_wrong = 0;
  for (int i = -12; i <= 12; ++i) {
    for (int k = -12; k <= 12; ++k) {
      for (double y : {0.1, 0.7, 3.3}) {
        const double d[3] = {0.5 + i * ulp, y, 0.5 + k * ulp};
        const int truth = d[2] > d[0] ? lambda : (d[2] < d[0] ? -lambda : 0);
        ASSERT_EQ(orient3d(a, b, c, d), truth) << i << " " << k << " " << y;
        ASSERT_EQ(orient3d(b, c, a, d), truth);  // even permutation
        ASSERT_EQ(orient3d(b, a, c, d), -truth);  // odd permutation
        naive_wrong += orient3d_naive(a, b, c, d) != truth;
      }
    }
  }
  EXPECT_GT(naive_wrong, 0);  // plain floating point gets some of these wrong
}

TEST(Orient, Orient2dExactNearLine) {
  // Shewchuk's example: a, b on y = x, c near (0.5, 0.5) moved by ulps: sign = sign(cy - cx) (counter-clockwise).
  const double a[3] = {12, 12, 7}, b[3] = {24, 24, -1};
  const double ulp = std::ldexp(1.0, -53);
  for (int i = -20; i <= 20; ++i) {
    for (int j = -20; j <= 20; ++j) {
      const double c[3] = {0.5 + i * ulp, 0.5 + j * ulp, 3.0};
      const int truth = c[1] > c[0] ? 1 : (c[1] < c[0] ? -1 : 0);
      ASSERT_EQ(orient2d(a, b, c, 2), truth) << i << " " << j;
      ASSERT_EQ(orient2d_exact(a, b, c, 2), truth);
      // The same points in the (y, z) and (z, x) projections.
      const double a0[3] = {7, a[0], a[1]}, b0[3] = {-1, b[0], b[1]}, c0[3] = {3, c[0], c[1]};
      ASSERT_EQ(orient2d(a0, b0, c0, 0), truth);
      const double a1[3] = {a[1], 7, a[0]}, b1[3] = {b[1], -1, b[0]}, c1[3] = {c[1], 3, c[0]};
      ASSERT_EQ(orient2d(a1, b1, c1, 1), truth);
    }
  }
}

TEST(Orient, FilterAgreesWithExactStageOnRandomPoints) {
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20000; ++trial) {
    double p[4][3];
    for (auto& q : p) {
      for (auto& c : q) c = std::ldexp(u(rng), static_cast<int>(trial % 7) * 3 - 10);
    }
    if (trial % 3 == 0) {
      // d an affine combination of a, b, c (nearly coplanar after rounding).
      const double s = u(rng), t = u(rng);
      for (int d = 0; d < 3; ++d) p[3][d] = p[0][d] + s * (p[1][d] - p[0][d]) + t * (p[2][d] - p[0][d]);
    }
    ASSERT_EQ(orient3d(p[0], p[1], p[2], p[3]), orient3d_exact(p[0], p[1], p[2], p[3]));
    ASSERT_EQ(orient2d(p[0], p[1], p[3], trial % 3), orient2d_exact(p[0], p[1], p[3], trial % 3));
  }
}

TEST(Orient, NonFiniteInputThrows) {
  const double a[3] = {0, 0, 0}, b[3] = {1, 0, 0}, c[3] = {0, 1, 0}, d[3] = {0, 0, std::nan("")};
  EXPECT_THROW(orient3d(a, b, c, d), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------------
// Triangle-triangle.

// triangles_intersect under every vertex order of both triangles and both argument orders.
void expect_tt(const std::array<P3, 3>& A, const std::array<P3, 3>& B, bool want, const char* what) {
  const int perm[6][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {0, 2, 1}, {2, 1, 0}, {1, 0, 2}};
  for (const auto& pa : perm) {
    for (const auto& pb : perm) {
      const double* a[3] = {A[pa[0]].data(), A[pa[1]].data(), A[pa[2]].data()};
      const double* b[3] = {B[pb[0]].data(), B[pb[1]].data(), B[pb[2]].data()};
      ASSERT_EQ(triangles_intersect(a[0], a[1], a[2], b[0], b[1], b[2]), want) << what;
      ASSERT_EQ(triangles_intersect(b[0], b[1], b[2], a[0], a[1], a[2]), want) << what;
    }
  }
}

TEST(TriTri, CrossingAndSeparated) {
  const std::array<P3, 3> t1 = {P3{0, 0, 0}, P3{1, 0, 0}, P3{0, 1, 0}};
  expect_tt(t1, {P3{0.2, 0.2, -1}, P3{0.3, 0.2, 1}, P3{0.2, 0.4, 1}}, true, "piercing");
  expect_tt(t1, {P3{-0.5, 0.3, -1}, P3{1.5, 0.3, -1}, P3{0.5, 0.3, 1}}, true, "crossing through both edges");
  expect_tt(t1, {P3{0.2, 0.2, 0.1}, P3{0.3, 0.2, 1}, P3{0.2, 0.4, 1}}, false, "above");
  expect_tt(t1, {P3{0.8, 0.8, -1}, P3{0.9, 0.8, 1}, P3{0.8, 0.9, 1}}, false, "line through plane outside");
}

TEST(TriTri, TouchingAtAPointWithTinyOffsets) {
  // Vertex of the second triangle on the plane z = 0 of the first, then +-1e-300 off it.
  const std::array<P3, 3> t1 = {P3{0, 0, 0}, P3{1, 0, 0}, P3{0, 1, 0}};
  for (double eps : {1e-300, 0.0, -1e-300}) {
    expect_tt(t1, {P3{0.25, 0.25, eps}, P3{0.25, 0.5, 1}, P3{0.5, 0.25, 1}}, eps <= 0.0, "1e-300 offset");
  }
  // Plane z = 1, offsets of one ulp (relative 1e-16 .. 2e-16).
  const std::array<P3, 3> t2 = {P3{0, 0, 1}, P3{1, 0, 1}, P3{0, 1, 1}};
  for (double z : {std::nextafter(1.0, 2.0), 1.0, std::nextafter(1.0, 0.0)}) {
    expect_tt(t2, {P3{0.25, 0.25, z}, P3{0.25, 0.5, 2}, P3{0.5, 0.25, 2}}, z <= 1.0, "ulp offset");
  }
  // Tilted plane z = x; the touching vertex exactly on it, or one ulp above / below.
  const std::array<P3, 3> t3 = {P3{0, 0, 0}, P3{1, 0, 1}, P3{0, 1, 0}};
  for (double z : {std::nextafter(0.3, 1.0), 0.3, std::nextafter(0.3, 0.0)}) {
    expect_tt(t3, {P3{0.3, 0.2, z}, P3{0.3, 0.5, 1.0}, P3{0.6, 0.2, 1.5}}, z <= 0.3, "tilted ulp offset");
  }
  // Edge against edge at a single point, then 1e-300 apart.
  const std::array<P3, 3> t4 = {P3{-1, 0, 0}, P3{1, 0, 0}, P3{0, -1, 0}};
  for (double eps : {0.0, 1e-300}) {
    expect_tt(t4, {P3{0, eps, -1}, P3{0, eps, 1}, P3{0, 1, 0}}, eps == 0.0, "edge-edge touch");
  }
}

TEST(TriTri, Coplanar) {
  const std::array<P3, 3> t1 = {P3{0, 0, 0}, P3{1, 0, 0}, P3{0, 1, 0}};
  expect_tt(t1, {P3{0.5, 0.5, 0}, P3{-0.5, 0.5, 0}, P3{0.5, -0.5, 0}}, true, "overlapping");
  expect_tt(t1, {P3{0.1, 0.1, 0}, P3{0.3, 0.1, 0}, P3{0.1, 0.3, 0}}, true, "contained");
  expect_tt(t1, {P3{0.6, 0.6, 0}, P3{1.6, 0.6, 0}, P3{0.6, 1.6, 0}}, false, "disjoint");
  expect_tt(t1, {P3{0.5, 0.5, 0}, P3{1.5, 0.5, 0}, P3{0.5, 1.5, 0}}, true, "vertex on the hypotenuse");
  expect_tt(t1, {P3{0.5, std::nextafter(0.5, 1.0), 0}, P3{1.5, 0.5, 0}, P3{0.5, 1.5, 0}}, false, "one ulp off");
  // A tilted common plane x + y + z = 1 (coordinates exact).
  expect_tt({P3{1, 0, 0}, P3{0, 1, 0}, P3{0, 0, 1}}, {P3{0.5, 0.5, 0}, P3{0.5, 0, 0.5}, P3{-1, 1, 1}}, true,
            "tilted coplanar");
  // A degenerate triangle (a segment) crossing or missing the first one.
  expect_tt(t1, {P3{0.2, 0.2, -1}, P3{0.2, 0.2, 1}, P3{0.2, 0.2, 0.5}}, true, "segment piercing");
  expect_tt(t1, {P3{2, 2, -1}, P3{2, 2, 1}, P3{2, 2, 0.5}}, false, "segment missing");
}

// mesh_triangles_intersect on a 6-point array with vertex ids.
bool mesh_pair(const std::vector<P3>& pts, std::array<int, 3> a, std::array<int, 3> b) {
  Points x(static_cast<int>(pts.size()), 3);
  for (std::size_t i = 0; i < pts.size(); ++i) x.row(static_cast<int>(i)) << pts[i][0], pts[i][1], pts[i][2];
  const bool r = mesh_triangles_intersect(x, a.data(), b.data());
  // Symmetric in the two triangles and their vertex order.
  EXPECT_EQ(mesh_triangles_intersect(x, b.data(), a.data()), r);
  const int a2[3] = {a[2], a[0], a[1]}, b2[3] = {b[1], b[0], b[2]};
  EXPECT_EQ(mesh_triangles_intersect(x, a2, b2), r);
  return r;
}

TEST(TriTri, SharedEdgeFoldedThroughOrNot) {
  // Triangles (0 1 2) and (0 1 3) share edge (0 1) on the x axis; 2 is at y = 1.
  std::vector<P3> pts = {P3{0, 0, 0}, P3{1, 0, 0}, P3{0.5, 1, 0}, P3{0.5, -1, 0}};
  EXPECT_FALSE(mesh_pair(pts, {0, 1, 2}, {0, 1, 3})) << "flat, opposite sides";
  pts[3] = {0.3, 0.5, 0};
  EXPECT_TRUE(mesh_pair(pts, {0, 1, 2}, {0, 1, 3})) << "folded flat onto each other";
  pts[3] = {0.3, 0.5, 1e-300};
  EXPECT_FALSE(mesh_pair(pts, {0, 1, 2}, {0, 1, 3})) << "folded to 1e-300 above: meet only on the edge";
  pts[3] = {0.3, 0.5, -1e-300};
  EXPECT_FALSE(mesh_pair(pts, {0, 1, 2}, {0, 1, 3})) << "folded to 1e-300 below";
  pts[3] = {0.5, -1, 1};
  EXPECT_FALSE(mesh_pair(pts, {0, 1, 2}, {0, 1, 3})) << "bent";
  pts[3] = {3, 0, 0};
  EXPECT_FALSE(mesh_pair(pts, {0, 1, 2}, {0, 1, 3})) << "degenerate neighbour on the edge's line";
  // The same positions with distinct ids: the shared edge alone is an intersection.
  pts = {P3{0, 0, 0}, P3{1, 0, 0}, P3{0.5, 1, 0}, P3{0.5, -1, 0}, P3{0, 0, 0}, P3{1, 0, 0}};
  EXPECT_TRUE(mesh_pair(pts, {0, 1, 2}, {4, 5, 3}));
  EXPECT_TRUE(mesh_pair(pts, {0, 1, 2}, {0, 1, 2})) << "the same triangle twice";
}

TEST(TriTri, SharedVertexBeyondTheVertexOnly) {
  // (0 1 2) in z = 0 and (0 3 4) share vertex 0 at the origin.
  std::vector<P3> pts = {P3{0, 0, 0}, P3{1, 0, 0}, P3{0, 1, 0}, P3{0.3, 0.3, 1}, P3{0.5, 0.1, 1}};
  EXPECT_FALSE(mesh_pair(pts, {0, 1, 2}, {0, 3, 4})) << "both above: only the vertex";
  pts[4] = {0.3, 0.3, -1};
  EXPECT_TRUE(mesh_pair(pts, {0, 1, 2}, {0, 3, 4})) << "opposite edge pierces";
  pts[3] = {1, 1, 1};
  pts[4] = {1, 1, -1};
  EXPECT_TRUE(mesh_pair(pts, {0, 1, 2}, {0, 3, 4})) << "cuts through from the vertex, opposite edge outside";
  pts[3] = {-1, -1, 1};
  pts[4] = {-1, -1, -1};
  EXPECT_FALSE(mesh_pair(pts, {0, 1, 2}, {0, 3, 4})) << "crosses the plane only outside, at the vertex";
  pts[3] = {0.5, 0.2, 0};
  pts[4] = {0.2, 0.5, 0};
  EXPECT_TRUE(mesh_pair(pts, {0, 1, 2}, {0, 3, 4})) << "coplanar wedge inside";
  pts[3] = {-1, 0.5, 0};
  pts[4] = {-0.5, -1, 0};
  EXPECT_FALSE(mesh_pair(pts, {0, 1, 2}, {0, 3, 4})) << "coplanar wedge outside";
  pts[3] = {0.5, 0, 0};
  pts[4] = {0.5, -1, 0};
  EXPECT_TRUE(mesh_pair(pts, {0, 1, 2}, {0, 3, 4})) << "coplanar, overlapping collinear edges";
  pts[4] = {0.5, 0, 1};
  EXPECT_TRUE(mesh_pair(pts, {0, 1, 2}, {0, 3, 4})) << "non-coplanar, overlapping collinear edges";
  pts[3] = {-0.5, 0, 0};
  pts[4] = {-0.5, -1, 0};
  EXPECT_FALSE(mesh_pair(pts, {0, 1, 2}, {0, 3, 4})) << "collinear edges pointing away";
}

// ---------------------------------------------------------------------------------------------------
// Counting over meshes.

// All pairs, the same per-pair test, no pruning.
long count_brute(const Points& x, const Tris& tris) {
  long n = 0;
  for (int i = 0; i < tris.rows(); ++i) {
    for (int j = i + 1; j < tris.rows(); ++j) {
      const int a[3] = {tris(i, 0), tris(i, 1), tris(i, 2)}, b[3] = {tris(j, 0), tris(j, 1), tris(j, 2)};
      n += mesh_triangles_intersect(x, a, b);
    }
  }
  return n;
}

TEST(CountIntersecting, UndeformedTubeHasNone) {
  Points x;
  Tris tris;
  make_tube(20, 26, 0.01, 0.1, x, tris);
  ASSERT_EQ(tris.rows(), 1040);
  EXPECT_EQ(count_intersecting_pairs(x, tris), 0);
}

TEST(CountIntersecting, FlatPinchedTubeWallsCross) {
  // Tube flattened to an ellipse, then pinched past zero so the two walls cross each other.
  Points x;
  Tris tris;
  make_tube(20, 26, 0.01, 0.1, x, tris);
  Points flat = x;
  flat.col(1) *= 0.3;
  EXPECT_EQ(count_intersecting_pairs(flat, tris), 0);
  Points pinched = flat;
  for (int i = 0; i < x.rows(); ++i) {
    const double g = std::exp(-std::pow((x(i, 2) - 0.05) / 0.02, 2));
    pinched(i, 1) *= 1.0 - 1.5 * g;
  }
  const long n = count_intersecting_pairs(pinched, tris);
  EXPECT_GT(n, 0);
  EXPECT_EQ(n, count_brute(pinched, tris));
}

TEST(CountIntersecting, PlanarGridExactCoplanarNeighbours) {
  // A flat 12 x 12 grid (all neighbours coplanar: the exact stage decides), then one vertex dragged over
  // a neighbour so coplanar triangles overlap.
  const int n = 12;
  Points x((n + 1) * (n + 1), 3);
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j <= n; ++j) x.row(i * (n + 1) + j) << 0.1 * i + 0.3, 0.1 * j - 0.7, 0.25;
  }
  Tris tris(2 * n * n, 3);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const int v = i * (n + 1) + j;
      tris.row(2 * (i * n + j)) << v, v + n + 1, v + n + 2;
      tris.row(2 * (i * n + j) + 1) << v, v + n + 2, v + 1;
    }
  }
  EXPECT_EQ(count_intersecting_pairs(x, tris), 0);
  EXPECT_EQ(count_brute(x, tris), 0);
  Points folded = x;
  folded(5 * (n + 1) + 5, 0) += 0.15;  // in-plane, past its neighbours
  const long c = count_intersecting_pairs(folded, tris);
  EXPECT_GT(c, 0);
  EXPECT_EQ(c, count_brute(folded, tris));
  // Lifted out of the plane instead: a bump, no intersection.
  Points bump = x;
  bump(5 * (n + 1) + 5, 2) += 0.05;
  EXPECT_EQ(count_intersecting_pairs(bump, tris), 0);
}

TEST(CountIntersecting, RandomDeformedMeshesEqualBruteForce) {
  Points rest;
  Tris tris;
  make_tube(12, 14, 0.01, 0.04, rest, tris);
  long total = 0;
  for (unsigned seed = 1; seed <= 4; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    Points x = rest;
    // Smooth squeeze plus noise of the order of the edge length (folds neighbours through each other).
    for (int i = 0; i < x.rows(); ++i) {
      x(i, 1) *= 1.0 - 1.2 * std::exp(-std::pow((rest(i, 2) - 0.02) / 0.008, 2));
      for (int d = 0; d < 3; ++d) x(i, d) += 0.0015 * seed * u(rng);
    }
    const long n = count_intersecting_pairs(x, tris);
    EXPECT_EQ(n, count_brute(x, tris)) << "seed " << seed;
    total += n;
  }
  EXPECT_GT(total, 0);
}

// Floating-point Moller-Trumbore segment-triangle test; `sure` is false when within 1e-9 of a boundary.
bool seg_tri_float(const P3& p, const P3& q, const P3& a, const P3& b, const P3& c, bool* sure) {
  const auto sub = [](const P3& s, const P3& t) { return P3{s[0] - t[0], s[1] - t[1], s[2] - t[2]}; };
  const auto cross = [](const P3& s, const P3& t) {
    return P3{s[1] * t[2] - s[2] * t[1], s[2] * t[0] - s[0] * t[2], s[0] * t[1] - s[1] * t[0]};
  };
  const auto dot = [](const P3& s, const P3& t) { return s[0] * t[0] + s[1] * t[1] + s[2] * t[2]; };
  const P3 dir = sub(q, p), e1 = sub(b, a), e2 = sub(c, a), h = cross(dir, e2);
  const double det = dot(e1, h);
  *sure = std::abs(det) > 1e-6;
  if (!*sure) return false;
  const P3 s = sub(p, a), qv = cross(s, e1);
  const double uu = dot(s, h) / det, vv = dot(dir, qv) / det, t = dot(e2, qv) / det;
  const double m = std::min({std::abs(uu), std::abs(vv), std::abs(1 - uu - vv), std::abs(t), std::abs(1 - t)});
  *sure = m > 1e-9;
  return t >= 0 && t <= 1 && uu >= 0 && vv >= 0 && uu + vv <= 1;
}

TEST(CountIntersecting, RandomSoupMatchesFloatingPointTwinAwayFromDegeneracy) {
  std::mt19937 rng(21);
  const int nt = 200;
  Points x;
  Tris tris;
  test::make_triangle_soup(rng, nt, 0.4, x, tris);
  long expected = 0, checked = 0;
  for (int i = 0; i < nt; ++i) {
    for (int j = i + 1; j < nt; ++j) {
      std::array<P3, 3> A, B;
      for (int k = 0; k < 3; ++k) {
        A[k] = {x(tris(i, k), 0), x(tris(i, k), 1), x(tris(i, k), 2)};
        B[k] = {x(tris(j, k), 0), x(tris(j, k), 1), x(tris(j, k), 2)};
      }
      bool any_true = false, all_sure = true;
      for (int k = 0; k < 3; ++k) {
        bool s1 = false, s2 = false;
        any_true |= seg_tri_float(A[k], A[(k + 1) % 3], B[0], B[1], B[2], &s1) && s1;
        any_true |= seg_tri_float(B[k], B[(k + 1) % 3], A[0], A[1], A[2], &s2) && s2;
        all_sure = all_sure && s1 && s2;
      }
      const bool exact = triangles_intersect(A[0].data(), A[1].data(), A[2].data(), B[0].data(), B[1].data(), B[2].data());
      if (any_true || all_sure) {
        EXPECT_EQ(exact, any_true) << i << " " << j;
        ++checked;
      }
      expected += exact;
    }
  }
  EXPECT_GT(checked, nt * (nt - 1) / 2 * 9 / 10);
  EXPECT_GT(expected, 50);
  std::printf("random soup: %ld intersecting pairs, %ld of %d checked against floating point\n", expected, checked, nt * (nt - 1) / 2);
  EXPECT_EQ(count_intersecting_pairs(x, tris), expected);
}

TEST(CountIntersecting, ValidatesInput) {
  Points x(3, 3);
  x << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  Tris tris(1, 3);
  tris << 0, 1, 3;
  try {
    count_intersecting_pairs(x, tris);
    ADD_FAILURE() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("tris(0, 2)"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("got 3"), std::string::npos);
  }
  tris << 0, 1, 2;
  x(1, 0) = INFINITY;
  EXPECT_THROW(count_intersecting_pairs(x, tris), std::invalid_argument);
}

}  // namespace
}  // namespace lumen::collision
