// Hollow-cylinder generator: counts, conformity, boundary = tagged surfaces, orientation, geometry, validation.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <set>
#include <stdexcept>
#include <string>

#include "physics/mesh.hpp"

namespace lumen::physics {
namespace {

using Tri = std::array<int, 3>;

// Triangle with its cyclic order kept and the smallest index first (same orientation <=> same key).
Tri oriented_key(int a, int b, int c) {
  Tri t{a, b, c};
  std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
  return t;
}
Tri sorted_key(Tri t) {
  std::sort(t.begin(), t.end());
  return t;
}

// Centreline geometry of a spec: the centreline point and tangent nearest to p, for straight or bent tubes.
struct Frame {
  Eigen::Vector3d c, t;
};
Frame frame_at(const HollowCylinderSpec& s, const Eigen::Vector3d& p) {
  if (s.bend_radius == 0.0) return {Eigen::Vector3d(0, 0, p.z()), Eigen::Vector3d::UnitZ()};
  const double R = s.bend_radius;
  const Eigen::Vector3d d = p - Eigen::Vector3d(R, 0, 0);
  const double phi = std::atan2(d.z(), -d.x());
  return {Eigen::Vector3d(R - R * std::cos(phi), 0, R * std::sin(phi)),
          Eigen::Vector3d(std::sin(phi), 0, std::cos(phi))};
}
Eigen::Vector3d point(const TetMesh& m, int v) { return m.rest.row(v).transpose(); }
Eigen::Vector3d area_normal(const TetMesh& m, const Tris& tris, int f) {
  const Eigen::Vector3d a = point(m, tris(f, 0)), b = point(m, tris(f, 1)), c = point(m, tris(f, 2));
  return 0.5 * (b - a).cross(c - a);
}

std::vector<HollowCylinderSpec> specs() {
  std::vector<HollowCylinderSpec> out;
  out.push_back(HollowCylinderSpec{});  // the paper mesh
  HollowCylinderSpec s;
  s.segments_around = 3, s.segments_along = 1, s.layers = 1;  // the coarsest
  out.push_back(s);
  s.segments_around = 7, s.segments_along = 5, s.layers = 2, s.bend_radius = 0.05;  // bent, odd counts
  out.push_back(s);
  s.segments_around = 12, s.segments_along = 9, s.layers = 3, s.bend_radius = 0.02, s.length = 0.11;  // strong bend
  out.push_back(s);
  HollowCylinderSpec g;  // graded toward two opposite tips at mid-length (the study's pinch)
  g.segments_around = 16, g.segments_along = 10, g.layers = 2;
  g.grading_around = {{0.5 * EIGEN_PI, 1.5 * EIGEN_PI}, 6.0};
  g.grading_along = {{0.05}, 12.0};
  out.push_back(g);
  return out;
}

TEST(HollowCylinder, PaperMeshCounts) {
  const TetMesh m = make_hollow_cylinder(HollowCylinderSpec{});
  EXPECT_EQ(m.n_nodes(), 2160);
  EXPECT_EQ(m.tets.rows(), 9360);
  EXPECT_EQ(m.surface(kInnerWall).rows(), 1040);
  EXPECT_EQ(m.surface(kOuterWall).rows(), 1040);
  EXPECT_EQ(m.surface(kEndCaps).rows(), 2 * 2 * 20 * 3);
  EXPECT_EQ(m.node_set(kStartEnd).size(), 80u);
  EXPECT_EQ(m.node_set(kStopEnd).size(), 80u);
}

TEST(HollowCylinder, CountsFollowTheSpec) {
  for (const HollowCylinderSpec& s : specs()) {
    const TetMesh m = make_hollow_cylinder(s);
    const int A = s.segments_around, L = s.segments_along, R = s.layers;
    EXPECT_EQ(m.n_nodes(), A * (L + 1) * (R + 1));
    EXPECT_EQ(m.tets.rows(), 6 * A * L * R);
    EXPECT_EQ(m.surface(kInnerWall).rows(), 2 * A * L);
    EXPECT_EQ(m.surface(kOuterWall).rows(), 2 * A * L);
    EXPECT_EQ(m.surface(kEndCaps).rows(), 4 * A * R);
  }
}

TEST(HollowCylinder, AllTetsPositive) {
  for (const HollowCylinderSpec& s : specs()) {
    const TetMesh m = make_hollow_cylinder(s);
    for (int t = 0; t < m.tets.rows(); ++t) ASSERT_GT(tet_volume(m.rest, m.tets, t), 0.0) << "tet " << t;
  }
}

// Faces of the tets: interior faces shared by exactly two tets with opposite orientation, boundary faces by
// one, and the boundary (outward orientation) is exactly inner + outer + ends with their stored orientation.
TEST(HollowCylinder, ConformingAndBoundaryIsTheTaggedSurfaces) {
  for (const HollowCylinderSpec& s : specs()) {
    const TetMesh m = make_hollow_cylinder(s);
    std::map<Tri, std::vector<Tri>> faces;  // sorted -> oriented occurrences (outward from their tet)
    static const int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
    for (int t = 0; t < m.tets.rows(); ++t)
      for (const auto& f : kFace) {
        const Tri o = oriented_key(m.tets(t, f[0]), m.tets(t, f[1]), m.tets(t, f[2]));
        faces[sorted_key(o)].push_back(o);
      }
    std::set<Tri> boundary;
    for (const auto& [key, occ] : faces) {
      ASSERT_LE(occ.size(), 2u);
      if (occ.size() == 2) {
        EXPECT_NE(occ[0], occ[1]) << "interior face with the same orientation in both tets";
      } else {
        boundary.insert(occ[0]);
      }
    }
    std::set<Tri> tagged;
    for (const Tris* tris : {&m.surface(kInnerWall), &m.surface(kOuterWall), &m.surface(kEndCaps)})
      for (int f = 0; f < tris->rows(); ++f)
        EXPECT_TRUE(tagged.insert(oriented_key((*tris)(f, 0), (*tris)(f, 1), (*tris)(f, 2))).second);
    EXPECT_EQ(boundary.size(), tagged.size());
    EXPECT_TRUE(boundary == tagged) << "boundary faces differ from inner + outer + ends (or their orientation)";
  }
}

TEST(HollowCylinder, SurfacesLieOnTheirRadiiWithStatedNormals) {
  for (const HollowCylinderSpec& s : specs()) {
    const TetMesh m = make_hollow_cylinder(s);
    const double tol = 1e-12;
    // Inner wall: vertices at the inner radius, normals toward the centreline (into the lumen).
    for (int f = 0; f < m.surface(kInnerWall).rows(); ++f) {
      for (int c = 0; c < 3; ++c) {
        const Eigen::Vector3d p = point(m, m.surface(kInnerWall)(f, c));
        const Frame fr = frame_at(s, p);
        EXPECT_NEAR((p - fr.c).norm(), s.inner_radius, tol);
        EXPECT_NEAR((p - fr.c).dot(fr.t), 0.0, tol);
      }
      const Eigen::Vector3d ctr = (point(m, m.surface(kInnerWall)(f, 0)) + point(m, m.surface(kInnerWall)(f, 1)) + point(m, m.surface(kInnerWall)(f, 2))) / 3;
      EXPECT_LT(area_normal(m, m.surface(kInnerWall), f).dot(ctr - frame_at(s, ctr).c), 0.0);
    }
    // Outer wall: outer radius, normals away from the centreline.
    for (int f = 0; f < m.surface(kOuterWall).rows(); ++f) {
      for (int c = 0; c < 3; ++c) {
        const Eigen::Vector3d p = point(m, m.surface(kOuterWall)(f, c));
        EXPECT_NEAR((p - frame_at(s, p).c).norm(), s.outer_radius, tol);
      }
      const Eigen::Vector3d ctr = (point(m, m.surface(kOuterWall)(f, 0)) + point(m, m.surface(kOuterWall)(f, 1)) + point(m, m.surface(kOuterWall)(f, 2))) / 3;
      EXPECT_GT(area_normal(m, m.surface(kOuterWall), f).dot(ctr - frame_at(s, ctr).c), 0.0);
    }
    // End caps: the start cap lies in z = 0 with normal -z; the stop cap is perpendicular to the end tangent
    // with the normal along it.
    const double phi_end = s.bend_radius > 0 ? s.length / s.bend_radius : 0.0;
    const Eigen::Vector3d t_end =
        s.bend_radius > 0 ? Eigen::Vector3d(std::sin(phi_end), 0, std::cos(phi_end)) : Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d c_end = s.bend_radius > 0 ? Eigen::Vector3d(s.bend_radius * (1 - std::cos(phi_end)), 0,
                                                                      s.bend_radius * std::sin(phi_end))
                                                    : Eigen::Vector3d(0, 0, s.length);
    std::set<int> start(m.node_set(kStartEnd).begin(), m.node_set(kStartEnd).end());
    std::set<int> stop(m.node_set(kStopEnd).begin(), m.node_set(kStopEnd).end());
    EXPECT_EQ(start.size(), static_cast<size_t>(s.segments_around * (s.layers + 1)));
    EXPECT_EQ(stop.size(), start.size());
    for (int v : start) {
      EXPECT_NEAR(m.rest(v, 2), 0.0, tol);
      const double r = point(m, v).norm();
      EXPECT_GE(r, s.inner_radius - tol);
      EXPECT_LE(r, s.outer_radius + tol);
    }
    for (int v : stop) {
      EXPECT_NEAR((point(m, v) - c_end).dot(t_end), 0.0, tol);
      const double r = (point(m, v) - c_end).norm();
      EXPECT_GE(r, s.inner_radius - tol);
      EXPECT_LE(r, s.outer_radius + tol);
    }
    int n_start = 0, n_stop = 0;
    for (int f = 0; f < m.surface(kEndCaps).rows(); ++f) {
      const bool on_start = start.count(m.surface(kEndCaps)(f, 0)) && start.count(m.surface(kEndCaps)(f, 1)) && start.count(m.surface(kEndCaps)(f, 2));
      const bool on_stop = stop.count(m.surface(kEndCaps)(f, 0)) && stop.count(m.surface(kEndCaps)(f, 1)) && stop.count(m.surface(kEndCaps)(f, 2));
      ASSERT_TRUE(on_start != on_stop) << "end triangle " << f << " is not on exactly one end";
      const Eigen::Vector3d nrm = area_normal(m, m.surface(kEndCaps), f).normalized();
      if (on_start) {
        EXPECT_NEAR(nrm.z(), -1.0, 1e-12);
        ++n_start;
      } else {
        EXPECT_NEAR(nrm.dot(t_end), 1.0, 1e-12);
        ++n_stop;
      }
    }
    EXPECT_EQ(n_start, n_stop);
  }
}

// The straight mesh fills the prism over the inscribed polygons exactly.
TEST(HollowCylinder, VolumeOfStraightMeshIsThePolygonalAnnulusPrism) {
  HollowCylinderSpec s;
  s.segments_around = 9, s.segments_along = 4, s.layers = 2, s.length = 0.07;
  const TetMesh m = make_hollow_cylinder(s);
  double v = 0.0;
  for (int t = 0; t < m.tets.rows(); ++t) v += tet_volume(m.rest, m.tets, t);
  const int A = s.segments_around;
  const double area =
      0.5 * A * std::sin(2 * EIGEN_PI / A) * (s.outer_radius * s.outer_radius - s.inner_radius * s.inner_radius);
  EXPECT_NEAR(v, area * s.length, 1e-12 * area * s.length);
}

// The bent mesh is the straight mesh rolled onto the arc: inner-wall centroids stay at the inner radius from
// the arc, and the end ring sits at arc length = length.
TEST(HollowCylinder, BendFollowsTheArc) {
  HollowCylinderSpec s;
  s.segments_around = 8, s.segments_along = 6, s.layers = 2, s.bend_radius = 0.04, s.length = 0.05;
  const TetMesh m = make_hollow_cylinder(s);
  const double R = s.bend_radius;
  for (int v = 0; v < m.n_nodes(); ++v) {
    const Eigen::Vector3d p = point(m, v);
    EXPECT_NEAR((p - frame_at(s, p).c).dot(frame_at(s, p).t), 0.0, 1e-12);
    // Distance from the centre of curvature in the bend plane is R -/+ the wall offset.
    const double rho = std::hypot(p.x() - R, p.z());
    EXPECT_GE(rho, R - s.outer_radius - 1e-12);
    EXPECT_LE(rho, R + s.outer_radius + 1e-12);
  }
  // Angle of the stop ring from the centre of curvature: length / R.
  for (int v : m.node_set(kStopEnd)) {
    const Eigen::Vector3d p = point(m, v);
    EXPECT_NEAR(std::atan2(p.z(), R - p.x()), s.length / R, 1e-12);
  }
}

TEST(HollowCylinder, NodeNumberingAsDocumented) {
  HollowCylinderSpec s;
  s.segments_around = 7, s.segments_along = 3, s.layers = 2, s.length = 0.06;
  const TetMesh m = make_hollow_cylinder(s);
  for (int j = 0; j <= 3; ++j)
    for (int k = 0; k <= 2; ++k)
      for (int i = 0; i < 7; ++i) {
        const int v = (j * 3 + k) * 7 + i;
        const double r = s.inner_radius + (s.outer_radius - s.inner_radius) * k / 2, th = 2 * EIGEN_PI * i / 7;
        EXPECT_LE((point(m, v) - Eigen::Vector3d(r * std::cos(th), r * std::sin(th), 0.02 * j)).norm(), 1e-15);
        if (j == 0) {
          EXPECT_EQ(m.node_set(kStartEnd)[k * 7 + i], v);
        }
        if (j == 3) {
          EXPECT_EQ(m.node_set(kStopEnd)[k * 7 + i], v);
        }
      }
}

template <typename F>
void expect_invalid(F&& make, const std::string& field, const std::string& value) {
  try {
    make();
    ADD_FAILURE() << "no exception for " << field;
  } catch (const std::invalid_argument& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(field), std::string::npos) << msg;
    EXPECT_NE(msg.find(value), std::string::npos) << msg;
  }
}

TEST(HollowCylinder, RejectsInvalidSpecsNamingFieldAndValue) {
  auto with = [](auto edit) {
    HollowCylinderSpec s;
    edit(s);
    return [s] { make_hollow_cylinder(s); };
  };
  expect_invalid(with([](auto& s) { s.inner_radius = -0.5; }), "inner_radius", "-0.5");
  expect_invalid(with([](auto& s) { s.outer_radius = 0.0; }), "outer_radius", "0");
  expect_invalid(with([](auto& s) { s.inner_radius = 0.02; }), "inner_radius", "0.02");
  expect_invalid(with([](auto& s) { s.length = -1.0; }), "length", "-1");
  expect_invalid(with([](auto& s) { s.segments_around = 2; }), "segments_around", "2");
  expect_invalid(with([](auto& s) { s.segments_along = 0; }), "segments_along", "0");
  expect_invalid(with([](auto& s) { s.layers = 0; }), "layers", "0");
  expect_invalid(with([](auto& s) { s.bend_radius = 0.012; }), "bend_radius", "0.012");
  expect_invalid(with([](auto& s) { s.bend_radius = -0.5; }), "bend_radius", "-0.5");
  expect_invalid(with([](auto& s) { s.bend_radius = 0.014; }), "bend_radius", "0.014");  // arc > 2 pi
  expect_invalid(with([](auto& s) { s.inner_radius = std::nan(""); }), "inner_radius", "nan");
  HollowCylinderSpec ok;
  ok.bend_radius = 0.02;
  EXPECT_NO_THROW(make_hollow_cylinder(ok));
  const TetMesh m = make_hollow_cylinder(HollowCylinderSpec{});
  expect_invalid([&] { tet_volume(m.rest, m.tets, 9360); }, "t", "9360");
}

// The centreline frame: orthonormal and right-handed (binormal = tangent x normal), the tangent is the derivative
// of the point (central differences), the normal points at the centre of curvature (R, 0, 0), and ring points
// are the point plus the normal and binormal at radius r; straight when bend_radius is 0.
TEST(HollowCylinder, CentrelineFrameIsTheArcsFrenetFrame) {
  for (const double R : {0.0, 0.05}) {
    HollowCylinderSpec spec;
    spec.bend_radius = R;
    for (const double s : {0.0, 0.013, 0.05, 0.1}) {
      const CentrelineFrame f = hollow_cylinder_frame(spec, s);
      EXPECT_NEAR(f.tangent.norm(), 1.0, 1e-15);
      EXPECT_NEAR(f.normal.norm(), 1.0, 1e-15);
      EXPECT_NEAR(f.tangent.dot(f.normal), 0.0, 1e-15);
      EXPECT_LE((f.tangent.cross(f.normal) - f.binormal).norm(), 1e-15);
      const double h = 1e-6;
      const Eigen::Vector3d fd =
          (hollow_cylinder_frame(spec, s + h).point - hollow_cylinder_frame(spec, s - h).point) / (2.0 * h);
      EXPECT_LE((fd - f.tangent).norm(), 1e-8);
      if (R > 0.0) {
        EXPECT_LE(((Eigen::Vector3d(R, 0.0, 0.0) - f.point) / R - f.normal).norm(), 1e-12);
      } else {
        EXPECT_EQ(f.point, Eigen::Vector3d(0.0, 0.0, s));
      }
      const double r = 0.011, theta = 0.7;
      EXPECT_EQ(hollow_cylinder_point(spec, s, r, theta),
                Eigen::Vector3d(f.point + r * std::cos(theta) * f.normal + r * std::sin(theta) * f.binormal));
    }
  }
}

}  // namespace
}  // namespace lumen::physics

namespace lumen::physics {
namespace {

// Cell sizes of a grid.
std::vector<double> cells_of(const std::vector<double>& grid) {
  std::vector<double> h;
  for (size_t i = 1; i < grid.size(); ++i) h.push_back(grid[i] - grid[i - 1]);
  return h;
}

// Uniform (ratio 1) grids are the plain formula bit for bit, so an ungraded mesh is unchanged.
TEST(Grading, RatioOneIsThePlainFormula) {
  const std::vector<double> g = graded_grid(CellGrading{{0.3}, 1.0}, 0.1, 26, false, "t");
  ASSERT_EQ(g.size(), 27u);
  for (int j = 0; j <= 26; ++j) EXPECT_EQ(g[j], 0.1 * j / 26);
  HollowCylinderSpec s;
  const TetMesh plain = make_hollow_cylinder(s);
  s.grading_along = {{0.05}, 1.0};
  EXPECT_TRUE(make_hollow_cylinder(s).rest == plain.rest);
}

// Graded: increasing from 0 to the extent, the smallest cell at the focus, the largest farthest from it, their
// ratio near the asked one (the continuum law gives it exactly; cells average the size over their width).
TEST(Grading, CellsShrinkTowardTheFocusByTheRatio) {
  const double L = 0.1;
  const std::vector<double> g = graded_grid(CellGrading{{0.05}, 12.0}, L, 20, false, "t");
  ASSERT_EQ(g.size(), 21u);
  EXPECT_EQ(g.front(), 0.0);
  EXPECT_EQ(g.back(), L);
  const std::vector<double> h = cells_of(g);
  for (double c : h) ASSERT_GT(c, 0.0);
  const auto [lo, hi] = std::minmax_element(h.begin(), h.end());
  // The smallest cells touch the focus (cells 9 and 10 share the node nearest 0.05), the largest are end cells.
  EXPECT_TRUE(lo - h.begin() == 9 || lo - h.begin() == 10) << lo - h.begin();
  EXPECT_TRUE(hi - h.begin() == 0 || hi - h.begin() == 19) << hi - h.begin();
  // Cells average the size law over their width, so the end cells' ratio falls short of 12 on 20 cells.
  EXPECT_GT(*hi / *lo, 0.5 * 12.0);
  EXPECT_LT(*hi / *lo, 12.0);
  // Equidistribution: each cell's size times the density 12^(-d / d_max) at its middle is the same (to the
  // variation of the density within a cell).
  std::vector<double> product;
  for (size_t i = 0; i < h.size(); ++i) {
    const double mid = 0.5 * (g[i] + g[i + 1]);
    product.push_back(h[i] * std::pow(12.0, -std::abs(mid - 0.05) / 0.05));
  }
  const auto [plo, phi] = std::minmax_element(product.begin(), product.end());
  EXPECT_LT(*phi / *plo, 1.1);
  // Symmetric about the focus in the middle.
  for (int j = 0; j <= 20; ++j) EXPECT_NEAR(g[j], L - g[20 - j], 1e-12 * L);
}

// Around a ring: distances wrap, so two opposite foci give a grid symmetric about each focus and about the x axis.
TEST(Grading, PeriodicGridIsSymmetricAboutOppositeFoci) {
  const double two_pi = 2.0 * EIGEN_PI;
  const std::vector<double> g = graded_grid(CellGrading{{0.5 * EIGEN_PI, -0.5 * EIGEN_PI}, 6.0}, two_pi, 32, true, "t");
  ASSERT_EQ(g.size(), 33u);
  for (int i = 0; i <= 8; ++i) {
    EXPECT_NEAR(g[8 + i] - 0.5 * EIGEN_PI, 0.5 * EIGEN_PI - g[8 - i], 1e-12);  // about 90 degrees
    EXPECT_NEAR(g[16 + i] - EIGEN_PI, EIGEN_PI - g[16 - i], 1e-12);            // about 180 degrees
  }
  const std::vector<double> h = cells_of(g);
  EXPECT_LT(h[8], h[0] / 4.0);  // cells at the focus a fraction of those at the sides
}

// A straight graded mesh fills the prism over its polygon exactly: the annulus of the graded polygon has area
// (ro^2 - ri^2) / 2 * sum sin(d theta_i), an analytic truth independent of the tets.
TEST(Grading, VolumeOfGradedStraightMeshIsItsPolygonPrism) {
  HollowCylinderSpec s;
  s.segments_around = 16, s.segments_along = 10, s.layers = 2;
  s.grading_around = {{0.5 * EIGEN_PI, 1.5 * EIGEN_PI}, 6.0};
  s.grading_along = {{0.05}, 12.0};
  const TetMesh m = make_hollow_cylinder(s);
  double v = 0.0;
  for (int t = 0; t < m.tets.rows(); ++t) v += tet_volume(m.rest, m.tets, t);
  const CylinderGrid grid = hollow_cylinder_grid(s);
  double sum_sin = 0.0;
  for (int i = 0; i < s.segments_around; ++i) sum_sin += std::sin(grid.angle[i + 1] - grid.angle[i]);
  const double area = 0.5 * sum_sin * (s.outer_radius * s.outer_radius - s.inner_radius * s.inner_radius);
  EXPECT_NEAR(v, area * s.length, 1e-12 * area * s.length);
  // Rings at the grid's arc lengths, nodes at its angles.
  for (int j = 0; j <= s.segments_along; ++j)
    for (int i = 0; i < s.segments_around; ++i) {
      const int node = (j * (s.layers + 1)) * s.segments_around + i;
      EXPECT_NEAR(m.rest(node, 2), grid.arc[j], 1e-15);
      EXPECT_NEAR(std::atan2(m.rest(node, 1), m.rest(node, 0)), std::remainder(grid.angle[i], 2.0 * EIGEN_PI), 1e-12);
    }
}

TEST(Grading, BadGradingIsNamed) {
  auto message = [](const CellGrading& g, bool periodic) {
    try {
      graded_grid(g, 0.1, 10, periodic, "spec.grading_along");
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message({{0.05}, 0.5}, false).find("spec.grading_along.ratio must be in [1, 100]"), std::string::npos);
  EXPECT_NE(message({{0.05}, 101.0}, false).find("spec.grading_along.ratio"), std::string::npos);
  EXPECT_NE(message({{}, 6.0}, false).find("spec.grading_along.focus must hold at least one point"), std::string::npos);
  EXPECT_NE(message({{0.2}, 6.0}, false).find("spec.grading_along.focus[0] must be within [0, length]"),
            std::string::npos);
  EXPECT_NE(message({{0.05, NAN}, 6.0}, true).find("spec.grading_along.focus[1] must be finite"), std::string::npos);
}

}  // namespace
}  // namespace lumen::physics
