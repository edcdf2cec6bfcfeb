// The prism wall between a closed surface and its offset (physics/surface_wall.hpp), vertex normals, and the
// smoothing of a sampled swept-tube radius profile (physics::smooth_profile).
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>

#include "physics/mesh.hpp"
#include "physics/surface_wall.hpp"
#include "physics/swept_tube.hpp"
#include "support/sphere.hpp"
#include "support/surface_measures.hpp"

using namespace lumen::physics;
using lumen::Points;
using lumen::Tris;

namespace {

// Volume enclosed by a closed surface (divergence theorem), independent of the tets.
using lumen::test::enclosed_volume;

}  // namespace

// Two layers between a sphere and its offset along the vertex normals: every tet positive, the tets' volumes sum
// to the difference of the two closed surfaces' enclosed volumes, and every tet face is either shared by exactly
// two tets (conforming: neighbouring prisms cut their common side the same way) or on one of the walls.
TEST(PrismWall, ConformingPositiveTetsFillTheVolumeBetweenTheSurfaces) {
  Points x;
  Tris tris;
  lumen::test::make_uv_sphere(0.01, 9, 16, x, tris);
  const Points n = vertex_normals(x, tris);
  const Points outer = x + 0.002 * n;
  const int layers = 2;
  const TetMesh m = make_prism_wall(x, outer, tris, layers);
  ASSERT_EQ(m.tets.rows(), 3 * layers * tris.rows());
  ASSERT_EQ(m.n_nodes(), (layers + 1) * x.rows());
  double sum = 0.0;
  for (int t = 0; t < m.tets.rows(); ++t) {
    const double v = tet_volume(m.rest, m.tets, t);
    EXPECT_GT(v, 0.0) << t;
    sum += v;
  }
  EXPECT_NEAR(sum, enclosed_volume(outer, tris) - enclosed_volume(x, tris), 1e-12 * enclosed_volume(outer, tris));
  // Faces: interior ones twice (opposite orientations), the rest exactly the inner and outer walls.
  std::map<std::array<int, 3>, int> faces;
  for (int t = 0; t < m.tets.rows(); ++t)
    for (int skip = 0; skip < 4; ++skip) {
      std::array<int, 3> f;
      int k = 0;
      for (int c = 0; c < 4; ++c)
        if (c != skip) f[static_cast<size_t>(k++)] = m.tets(t, c);
      std::sort(f.begin(), f.end());
      ++faces[f];
    }
  std::set<std::array<int, 3>> boundary;
  for (const auto& [f, count] : faces) {
    EXPECT_LE(count, 2);
    if (count == 1) boundary.insert(f);
  }
  std::set<std::array<int, 3>> walls;
  for (const char* name : {kInnerWall, kOuterWall})
    for (Eigen::Index t = 0; t < m.surface(name).rows(); ++t) {
      std::array<int, 3> f = {m.surface(name)(t, 0), m.surface(name)(t, 1), m.surface(name)(t, 2)};
      std::sort(f.begin(), f.end());
      walls.insert(f);
    }
  EXPECT_EQ(boundary, walls);
  EXPECT_EQ(m.surface(kEndCaps).rows(), 0);
  // The walls face out of the volume: the inner wall into the sphere (negative enclosed volume), the outer out.
  EXPECT_LT(enclosed_volume(m.rest, m.surface(kInnerWall)), 0.0);
  EXPECT_GT(enclosed_volume(m.rest, m.surface(kOuterWall)), 0.0);
}

// On a sphere, area-weighted vertex normals are radial at the poles and within the latitude step's tilt elsewhere;
// smoothing keeps them unit and radial where the neighbourhood is symmetric.
TEST(PrismWall, VertexNormalsOfASphereAreNearlyRadial) {
  Points x;
  Tris tris;
  lumen::test::make_uv_sphere(1.0, 15, 32, x, tris);
  const Points n = smooth_normals(vertex_normals(x, tris), tris, 3);
  for (Eigen::Index v = 0; v < x.rows(); ++v) {
    EXPECT_NEAR(n.row(v).norm(), 1.0, 1e-12);
    EXPECT_GT(n.row(v).dot(x.row(v)), std::cos(kPi / 16)) << v;
  }
  EXPECT_NEAR(n(1, 2), 1.0, 1e-12);
}

TEST(PrismWall, RefusesMismatchedArraysAndLayers) {
  Points x;
  Tris tris;
  lumen::test::make_uv_sphere(1.0, 3, 6, x, tris);
  EXPECT_THROW(make_prism_wall(x, x.topRows(3), tris, 1), std::invalid_argument);
  EXPECT_THROW(make_prism_wall(x, x, tris, 0), std::invalid_argument);
}

// The sampled radius's smoothing: a profile linear in the arc length passes unchanged (the window stays
// symmetric at the ends); a single outlier is spread over the window (2 k + 1 samples).
TEST(SmoothProfile, KeepsLinearProfilesAndAveragesOutliers) {
  std::vector<double> linear;
  for (int j = 0; j < 20; ++j) linear.push_back(0.008 + 0.0001 * j);
  const std::vector<double> same = smooth_profile(linear, 0.005, 0.01);
  for (size_t j = 0; j < linear.size(); ++j) EXPECT_NEAR(same[j], linear[j], 1e-15) << j;
  std::vector<double> spike(20, 0.01);
  spike[10] = 0.02;
  const std::vector<double> s = smooth_profile(spike, 0.005, 0.01);  // 2 samples either side: 5 in the mean
  for (int j = 8; j <= 12; ++j) EXPECT_NEAR(s[static_cast<size_t>(j)], 0.01 + 0.01 / 5, 1e-15) << j;
  EXPECT_NEAR(s[7], 0.01, 1e-15);
  EXPECT_NEAR(s[0], 0.01, 1e-15);
  EXPECT_THROW(smooth_profile(spike, 0.0, 0.01), std::invalid_argument);
}
