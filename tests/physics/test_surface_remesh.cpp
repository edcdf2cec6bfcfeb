// Isotropic remeshing of a closed surface to a target edge (physics/surface_remesh.hpp, CGAL), checked against
// what the input is: a latitude-longitude sphere whose polar triangles are slivers.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include "physics/surface_remesh.hpp"
#include "support/files.hpp"
#include "support/sphere.hpp"
#include "support/surface_measures.hpp"

using namespace lumen::physics;
using lumen::Points;
using lumen::Tris;

using lumen::test::enclosed_volume;
using lumen::test::sorted_angles_deg;
using lumen::test::sorted_side_lengths;

// A UV sphere of radius 1 (40 rings of 80: slivers of 4.5 degrees at the poles) remeshed to edges of 0.15: closed
// and consistently oriented (each directed edge once, its reverse once), every angle above 20 degrees, the median
// edge within 20 % of the target and 99 % of the edges below CGAL's split length (4/3 of it), every vertex on the
// input surface (between the input triangles' nearest plane to the centre and the circumscribed sphere), every face
// looking outward as the input's, the enclosed volume between the input's and the ball inside the nearest face
// plane (at least 0.98 from the centre).
TEST(SurfaceRemesh, MakesASliveredUvSphereIsotropicOnItsOwnSurface) {
  Points x;
  Tris tris;
  lumen::test::make_uv_sphere(1.0, 40, 80, x, tris);
  ASSERT_LT(sorted_angles_deg(x, tris).front(), 5.0);  // the input's polar slivers
  const double h = 0.15;
  const RemeshedSurface r = remesh_isotropic(x, tris, h);
  ASSERT_GT(r.tris.rows(), 100);
  // Closed, edge-manifold, consistently oriented.
  std::map<std::pair<int, int>, int> directed;
  for (Eigen::Index t = 0; t < r.tris.rows(); ++t)
    for (int k = 0; k < 3; ++k) ++directed[{r.tris(t, k), r.tris(t, (k + 1) % 3)}];
  for (const auto& [e, count] : directed) {
    EXPECT_EQ(count, 1) << e.first << "-" << e.second;
    EXPECT_EQ(directed.count({e.second, e.first}), 1u) << e.first << "-" << e.second;
  }
  EXPECT_GT(sorted_angles_deg(r.points, r.tris).front(), 20.0);
  const std::vector<double> l = sorted_side_lengths(r.points, r.tris);
  EXPECT_NEAR(l[l.size() / 2], h, 0.2 * h);
  EXPECT_LT(l[l.size() * 99 / 100], 4.0 / 3.0 * h);
  // On the input surface: no point of an input triangle is nearer the centre than its plane's distance.
  double inscribed = 1.0;
  for (Eigen::Index t = 0; t < tris.rows(); ++t) {
    const Eigen::Vector3d a = x.row(tris(t, 0)), b = x.row(tris(t, 1)), c = x.row(tris(t, 2));
    inscribed = std::min(inscribed, std::abs(a.dot((b - a).cross(c - a).normalized())));
  }
  for (Eigen::Index v = 0; v < r.points.rows(); ++v) {
    EXPECT_LE(r.points.row(v).norm(), 1.0 + 1e-12) << v;
    EXPECT_GE(r.points.row(v).norm(), inscribed - 1e-12) << v;
  }
  // Vertices on the convex input, so the output lies inside it and holds the ball its nearest face plane bounds.
  double nearest_plane = 1.0;
  for (Eigen::Index t = 0; t < r.tris.rows(); ++t) {
    const Eigen::Vector3d a = r.points.row(r.tris(t, 0)), b = r.points.row(r.tris(t, 1)), c = r.points.row(r.tris(t, 2));
    const double d = a.dot((b - a).cross(c - a).normalized());  // > 0: the face looks away from the centre
    EXPECT_GT(d, 0.0) << t;
    nearest_plane = std::min(nearest_plane, d);
  }
  const double v_in = enclosed_volume(x, tris), v_out = enclosed_volume(r.points, r.tris);
  EXPECT_LE(v_out, v_in * (1.0 + 1e-12));
  EXPECT_GE(v_out, 4.0 / 3.0 * static_cast<double>(EIGEN_PI) * std::pow(nearest_plane, 3));
  EXPECT_GT(nearest_plane, 0.98);
  std::printf("UV sphere %ld triangles (min angle %.1f deg) -> %ld triangles, min angle %.1f deg, edges median %.4f "
              "p99 %.4f (target %.2f), volume ratio %.5f\n",
              static_cast<long>(tris.rows()), sorted_angles_deg(x, tris).front(), static_cast<long>(r.tris.rows()),
              sorted_angles_deg(r.points, r.tris).front(), l[l.size() / 2], l[l.size() * 99 / 100], h, v_out / v_in);
}

// Coarser targets make fewer triangles, in proportion to the area over the target squared (the estimate).
TEST(SurfaceRemesh, TriangleCountFollowsTheTargetEdge) {
  Points x;
  Tris tris;
  lumen::test::make_uv_sphere(1.0, 30, 60, x, tris);
  for (double h : {0.1, 0.2, 0.4}) {
    const double n = static_cast<double>(remesh_isotropic(x, tris, h).tris.rows());
    const double estimate = remesh_triangle_estimate(x, tris, h);
    EXPECT_GT(n / estimate, 0.7) << h;
    EXPECT_LT(n / estimate, 1.5) << h;
  }
}

// Bad input: a non-positive or non-finite target edge, an open surface, a vertex out of range, an output that
// would be too large, each refused with its reason.
TEST(SurfaceRemesh, RefusesBadInputNamingWhy) {
  Points x;
  Tris tris;
  lumen::test::make_uv_sphere(1.0, 6, 12, x, tris);
  using lumen::test::message_of;
  EXPECT_EQ(message_of<std::invalid_argument>([&] { remesh_isotropic(x, tris, 0.0); }),
            "remesh_isotropic: the target edge must be > 0 and finite, got 0");
  EXPECT_EQ(message_of<std::invalid_argument>([&] { remesh_isotropic(x, tris, std::nan("")); }),
            "remesh_isotropic: the target edge must be > 0 and finite, got nan");
  const Tris open = tris.topRows(tris.rows() - 1);
  EXPECT_NE(message_of<std::invalid_argument>([&] { remesh_isotropic(x, open, 0.3); })
                .find("remesh_isotropic: the surface is not closed (a border edge at vertex "),
            std::string::npos);
  Tris bad = tris;
  bad(3, 1) = static_cast<int>(x.rows());
  EXPECT_EQ(message_of<std::invalid_argument>([&] { remesh_isotropic(x, bad, 0.3); }),
            "remesh_isotropic: a triangle names a vertex outside the surface's " + std::to_string(x.rows()));
  EXPECT_NE(message_of<std::invalid_argument>([&] { remesh_isotropic(x, tris, 1e-4); })
                .find("(at most 2000000)"),
            std::string::npos);
}
