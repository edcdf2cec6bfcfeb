// Instrument shapes and posing against independent truths: the enclosed volume (divergence theorem) between
// analytic bounds (the inscribed polygon's area ratio around the axis, the inscribed chords along the sphere),
// closedness by a brute-force count of every edge, the tip at the origin and the shaft along +y, mesh files
// written here and read back, each refusal's message, and a sphere probe swept into a flat patch through
// collision::detect_pair (contact exactly when its lowest point crosses the patch's plane).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>

#include "collision/ccd.hpp"
#include "collision/surface.hpp"
#include "engine/instrument.hpp"
#include "engine/scene.hpp"
#include "support/files.hpp"
#include "support/build.hpp"

using namespace lumen;
using namespace lumen::engine;

namespace {

using lumen::test::kPi;
// Positions and exact volumes computed two ways agree to rounding (relative).
constexpr double kTight = 1e-12;
// The scenes' default collision gap, metres.
constexpr double kDetectGap = 1e-4;

using lumen::test::write_temp;

// The message of the InputError that f throws ("" when it throws none).
std::string instrument_error_of(const std::function<void()>& f) { return lumen::test::message_of<InputError>(f); }

std::string mesh_error(const std::string& path, MeshUnits units = MeshUnits::kMetres) {
  return instrument_error_of([&] { load_mesh_instrument({path, units}); });
}

// Brute force, every triangle against every other: each side a -> b of each triangle is run b -> a by exactly
// one other triangle and a -> b by none, and no triangle repeats a vertex.
::testing::AssertionResult closed_by_brute_force(const RigidMesh& m) {
  for (int t = 0; t < m.tris.rows(); ++t) {
    if (m.tris(t, 0) == m.tris(t, 1) || m.tris(t, 1) == m.tris(t, 2) || m.tris(t, 2) == m.tris(t, 0))
      return ::testing::AssertionFailure() << "triangle " << t << " repeats a vertex";
    for (int j = 0; j < 3; ++j) {
      const int a = m.tris(t, j), b = m.tris(t, (j + 1) % 3);
      int same = 0, opposite = 0;
      for (int u = 0; u < m.tris.rows(); ++u)
        for (int k = 0; k < 3 && u != t; ++k) {
          const int c = m.tris(u, k), d = m.tris(u, (k + 1) % 3);
          same += c == a && d == b;
          opposite += c == b && d == a;
        }
      if (same != 0 || opposite != 1)
        return ::testing::AssertionFailure() << "edge " << a << " -> " << b << " of triangle " << t << ": run the same way "
                                             << same << " times, the other way " << opposite << " times";
    }
  }
  return ::testing::AssertionSuccess();
}

// Area of the regular n-gon inscribed in a circle over the circle's: n sin(2 pi / n) / (2 pi). A solid of
// revolution whose rings are such n-gons (aligned ring to ring) encloses exactly this fraction of the volume its
// polygonal profile sweeps (each band is a frustum of a regular pyramid).
double polygon_ratio(int n) { return n * std::sin(2.0 * kPi / n) / (2.0 * kPi); }

// Volume of a ball of radius r (centre on the axis at height r) joined to a cylinder of radius rs from the
// ball's centre up by len (len > r): the ball, plus the cylinder outside it, minus nothing twice.
double sphere_shaft_volume(double r, double rs, double len) {
  if (rs >= r) return 2.0 / 3.0 * kPi * r * r * r + kPi * rs * rs * len;  // the upper half-ball inside the shaft
  const double s = std::sqrt(r * r - rs * rs), cap = r - s;                 // junction above the centre; cap height
  return 4.0 / 3.0 * kPi * r * r * r + kPi * rs * rs * (len - s) - kPi * cap * cap * (3.0 * r - cap) / 3.0;
}

// Bounds of a sphere-and-shaft mesh's volume: its rings are inscribed polygons and its meridian chords (rings
// evenly spaced by dphi in the polar angle) stay outside the ball of radius r cos(dphi / 2), so
// ratio V(r cos(dphi / 2)) <= volume <= ratio V(r).
void expect_sphere_shaft_volume(const RigidMesh& m, double r, double rs, double len, int segments, int rings) {
  const double dphi = (kPi - std::asin(rs / r)) / rings;
  const double ratio = polygon_ratio(segments), v = enclosed_volume(m);
  EXPECT_LE(v, ratio * sphere_shaft_volume(r, rs, len) * (1 + kTight));
  EXPECT_GE(v, ratio * sphere_shaft_volume(r * std::cos(0.5 * dphi), rs, len));
}

// The tip at the origin (the lowest point, a vertex on the axis) and the shaft along +y up to `top`, within
// `radius` of the axis.
void expect_tip_and_axis(const RigidMesh& m, double top, double radius) {
  EXPECT_EQ(m.points.col(1).minCoeff(), 0.0);
  EXPECT_NEAR(m.points.col(1).maxCoeff(), top, kTight * top);
  const bool tip_vertex = (m.points.rowwise().norm().array() == 0.0).any();
  EXPECT_TRUE(tip_vertex);
  for (int i = 0; i < m.points.rows(); ++i)
    EXPECT_LE(std::hypot(m.points(i, 0), m.points(i, 2)), radius * (1 + kTight)) << "point " << i;
}

// A square of 2 n^2 triangles in the plane y = 0, x and z in [-half, half], facing +y.
RigidMesh flat_patch(double half, int n) {
  RigidMesh m;
  m.points.resize((n + 1) * (n + 1), 3);
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j) m.points.row(i * (n + 1) + j) << -half + 2 * half * i / n, 0.0, -half + 2 * half * j / n;
  m.tris.resize(2 * n * n, 3);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const int p00 = i * (n + 1) + j, p01 = p00 + 1, p10 = p00 + n + 1, p11 = p10 + 1;
      m.tris.row(2 * (i * n + j)) << p00, p01, p11;
      m.tris.row(2 * (i * n + j) + 1) << p00, p11, p10;
    }
  return m;
}

// A cube of side `side` at the origin as OBJ text: its 8 corners (corner c at bits x, y, z of c) and 6 outward
// quads; `faces` picks and orders them (a face index negative: that face reversed).
std::string cube_obj(double side, const std::vector<int>& faces) {
  static const int quads[6][4] = {{1, 5, 7, 3}, {2, 4, 8, 6}, {1, 2, 6, 5}, {3, 7, 8, 4}, {1, 3, 4, 2}, {5, 6, 8, 7}};
  std::string s;
  for (int c = 0; c < 8; ++c)
    s += "v " + std::to_string(side * (c & 1)) + " " + std::to_string(side * (c >> 1 & 1)) + " " +
         std::to_string(side * (c >> 2 & 1)) + "\n";
  for (int f : faces) {
    const int* q = quads[std::abs(f) - 1];
    s += f > 0 ? "f " + std::to_string(q[0]) + " " + std::to_string(q[1]) + " " + std::to_string(q[2]) + " " +
                     std::to_string(q[3]) + "\n"
               : "f " + std::to_string(q[3]) + " " + std::to_string(q[2]) + " " + std::to_string(q[1]) + " " +
                     std::to_string(q[0]) + "\n";
  }
  return s;
}
const std::vector<int> kCubeFaces = {1, 2, 3, 4, 5, 6};  // faces of cube_obj, 1-based, all outward

// The unit tetrahedron's corners and outward faces as OBJ lines.
const char* kTetObj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

}  // namespace

TEST(Instrument, SphereProbeIsClosedWithTheVolumeBetweenItsDiscretisationBounds) {
  const SphereProbeSpec s;  // the defaults: 3 mm tip, 2 mm shaft, 80 mm
  const Instrument probe = make_sphere_probe(s);
  ASSERT_EQ(probe.parts.size(), 1u);
  const RigidMesh& m = probe.parts[0].mesh;
  EXPECT_TRUE(closed_by_brute_force(m));
  EXPECT_EQ(m.tris.rows(), 2 * s.segments_around * (s.rings + s.shaft_segments));
  expect_sphere_shaft_volume(m, s.tip_radius, s.shaft_radius, s.shaft_length, s.segments_around, s.rings);
  expect_tip_and_axis(m, s.tip_radius + s.shaft_length, s.tip_radius);
  // Above the sphere only the shaft.
  for (int i = 0; i < m.points.rows(); ++i) {
    if (m.points(i, 1) > 2 * s.tip_radius) {
      EXPECT_LE(std::hypot(m.points(i, 0), m.points(i, 2)), s.shaft_radius * (1 + kTight));
    }
  }
  EXPECT_NO_THROW(require_closed_manifold(m, "probe"));
  // Finer: the same bounds, now within 0.3 % of the analytic volume (the same construction, so the library's
  // check of closedness instead of the quadratic brute force).
  SphereProbeSpec fine = s;
  fine.segments_around = 64;
  fine.rings = 32;
  const RigidMesh f = make_sphere_probe(fine).parts[0].mesh;
  EXPECT_NO_THROW(require_closed_manifold(f, "fine probe"));
  expect_sphere_shaft_volume(f, s.tip_radius, s.shaft_radius, s.shaft_length, 64, 32);
  EXPECT_NEAR(enclosed_volume(f) / sphere_shaft_volume(s.tip_radius, s.shaft_radius, s.shaft_length), 1.0, 3e-3);
}

TEST(Instrument, RodsFlatAndRounded) {
  // Flat: a prism on the inscribed polygon, exactly ratio pi r^2 L.
  RodSpec s;
  s.radius = 0.0025;
  s.length = 0.05;
  const RigidMesh flat = make_rod(s).parts[0].mesh;
  EXPECT_TRUE(closed_by_brute_force(flat));
  EXPECT_NEAR(enclosed_volume(flat), polygon_ratio(s.segments_around) * kPi * s.radius * s.radius * s.length,
              kTight * enclosed_volume(flat));
  expect_tip_and_axis(flat, s.length, s.radius);
  // Rounded: a hemisphere of the rod's radius at the tip, the shaft from its centre.
  s.end = RodEnd::kRounded;
  const RigidMesh round = make_rod(s).parts[0].mesh;
  EXPECT_TRUE(closed_by_brute_force(round));
  expect_sphere_shaft_volume(round, s.radius, s.radius, s.length - s.radius, s.segments_around, s.rings);
  expect_tip_and_axis(round, s.length, s.radius);
}

TEST(Instrument, GrasperHasAShaftAndTwoJawsOpeningSymmetricallyAboutTheHinge) {
  GrasperSpec s;
  s.opening_angle = 0.4;
  const Instrument g = make_grasper(s);
  ASSERT_EQ(g.parts.size(), 3u);
  EXPECT_EQ(g.parts[0].name, "shaft");
  EXPECT_EQ(g.parts[1].name, "jaw_positive");
  EXPECT_EQ(g.parts[2].name, "jaw_negative");
  // Each part closed; the jaws boxes, the shaft a prism from the hinge.
  for (const InstrumentPart& p : g.parts) EXPECT_TRUE(closed_by_brute_force(p.mesh)) << p.name;
  const double jaw_volume = s.jaw_length * s.jaw_width * s.jaw_thickness;
  EXPECT_NEAR(enclosed_volume(g.parts[1].mesh), jaw_volume, kTight * jaw_volume);
  EXPECT_NEAR(enclosed_volume(g.parts[2].mesh), jaw_volume, kTight * jaw_volume);
  const double shaft = polygon_ratio(s.segments_around) * kPi * s.shaft_radius * s.shaft_radius * s.shaft_length;
  EXPECT_NEAR(enclosed_volume(g.parts[0].mesh), shaft, kTight * shaft);
  EXPECT_EQ(g.parts[0].mesh.points.col(1).minCoeff(), s.jaw_length);
  // Closed, the jaws' tips are at the origin, one on each side of x = 0.
  EXPECT_EQ(g.parts[1].mesh.points.col(1).minCoeff(), 0.0);
  EXPECT_EQ(g.parts[1].mesh.points.col(0).minCoeff(), 0.0);
  EXPECT_EQ(g.parts[2].mesh.points.col(0).maxCoeff(), 0.0);
  // Open by theta: each jaw's tip turned by theta / 2 about the hinge, away from the other.
  const double theta = 0.6, h = s.jaw_length;
  const auto poses = jaw_poses(g, theta);
  const Eigen::Vector3d tip_pos = poses[0] * Eigen::Vector3d::Zero(), tip_neg = poses[1] * Eigen::Vector3d::Zero();
  EXPECT_LT((tip_pos - Eigen::Vector3d(h * std::sin(theta / 2), h - h * std::cos(theta / 2), 0)).norm(), kTight);
  EXPECT_LT((tip_neg - Eigen::Vector3d(-h * std::sin(theta / 2), h - h * std::cos(theta / 2), 0)).norm(), kTight);
  const Eigen::Vector3d axis_pos = poses[0].linear() * -Eigen::Vector3d::UnitY(),
                        axis_neg = poses[1].linear() * -Eigen::Vector3d::UnitY();
  EXPECT_NEAR(std::acos(axis_pos.dot(axis_neg)), theta, kTight);
  EXPECT_TRUE(jaw_poses(g, 0.0)[0].isApprox(Eigen::Isometry3d::Identity()));
}

TEST(Instrument, PosedPartsAreTheRigidMotionOfTheirPoints) {
  Pose pose;
  pose.position = {0.01, 0.02, 0.03};
  pose.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 1, 0).normalized()));
  const Eigen::Matrix3d r = pose.rotation.toRotationMatrix();
  // The probe: its tip goes to the position, its far end along the turned +y.
  const SphereProbeSpec s;
  const Instrument probe = make_sphere_probe(s);
  const std::vector<Points> world = posed_parts(probe, pose);
  ASSERT_EQ(world.size(), 1u);
  const RigidMesh& m = probe.parts[0].mesh;
  ASSERT_EQ(world[0].rows(), m.points.rows());
  EXPECT_LT((world[0].row(0).transpose() - pose.position).norm(), kTight);
  const Eigen::Vector3d top = pose.position + r.col(1) * (s.tip_radius + s.shaft_length);
  EXPECT_LT((world[0].row(m.points.rows() - 1).transpose() - top).norm(), kTight);
  for (int i = 0; i < m.points.rows(); ++i)
    EXPECT_LT((world[0].row(i).transpose() - (r * m.points.row(i).transpose() + pose.position)).norm(), kTight);
  // The grasper at an opening: the positive jaw's corner (0, 0, -w/2) after its turn about the hinge, then posed.
  const GrasperSpec gs;
  const Instrument g = make_grasper(gs);
  const double theta = 0.6, h = gs.jaw_length;
  const std::vector<Points> parts = posed_parts(g, pose, theta);
  const Eigen::Vector3d corner(h * std::sin(theta / 2), h - h * std::cos(theta / 2), -0.5 * gs.jaw_width);
  EXPECT_EQ(g.parts[1].mesh.points.row(0), Eigen::RowVector3d(0, 0, -0.5 * gs.jaw_width));
  EXPECT_LT((parts[1].row(0).transpose() - (r * corner + pose.position)).norm(), kTight);
  // The shaft does not move with the opening.
  EXPECT_LT((parts[0] - posed_parts(g, pose, 0.0)[0]).cwiseAbs().maxCoeff(), kTight);
}

TEST(Instrument, ShapeDimensionsAreValidatedNamingTheFieldAndValue) {
  auto probe_error = [](const std::function<void(SphereProbeSpec&)>& edit) {
    SphereProbeSpec s;
    edit(s);
    return instrument_error_of([&] { make_sphere_probe(s, "instruments[0].shape"); });
  };
  EXPECT_EQ(probe_error([](SphereProbeSpec& s) { s.tip_radius = -0.003; }),
            "instruments[0].shape.tip_radius: must be > 0 (value -0.003)");
  EXPECT_EQ(probe_error([](SphereProbeSpec& s) { s.shaft_length = NAN; }),
            "instruments[0].shape.shaft_length: must be finite (value nan)");
  EXPECT_EQ(probe_error([](SphereProbeSpec& s) { s.shaft_radius = 0.004; }),
            "instruments[0].shape.shaft_radius: must be <= tip_radius (0.003) (value 0.004)");
  EXPECT_EQ(probe_error([](SphereProbeSpec& s) { s.shaft_length = 0.002; }),
            "instruments[0].shape.shaft_length: must be > tip_radius (0.003) (value 0.002)");
  EXPECT_EQ(probe_error([](SphereProbeSpec& s) { s.segments_around = 2; }),
            "instruments[0].shape.segments_around: out of range [3, 4096] (value 2)");
  EXPECT_EQ(probe_error([](SphereProbeSpec& s) { s.rings = 1; }),
            "instruments[0].shape.rings: out of range [2, 4096] (value 1)");
  RodSpec rod;
  rod.end = RodEnd::kRounded;
  rod.radius = 0.002;
  rod.length = 0.003;
  EXPECT_EQ(instrument_error_of([&] { make_rod(rod); }), "rod.length: must be > 2 radius (0.004) for a rounded end (value 0.003)");
  rod.radius = INFINITY;
  EXPECT_EQ(instrument_error_of([&] { make_rod(rod); }), "rod.radius: must be finite (value inf)");
  GrasperSpec g;
  g.opening_angle = 4.0;
  EXPECT_EQ(instrument_error_of([&] { make_grasper(g); }), "grasper.opening_angle: out of range [0, 3.14159] radians (value 4)");
  g.opening_angle = 0.0;
  g.jaw_width = 0.0;
  EXPECT_EQ(instrument_error_of([&] { make_grasper(g); }), "grasper.jaw_width: must be > 0 (value 0)");
  // Through the shape variant.
  EXPECT_EQ(instrument_error_of([] { make_instrument(GrasperSpec{0.01, 0.004, -1.0}, "tool"); }),
            "tool.jaw_thickness: must be > 0 (value -1)");
}

TEST(InstrumentMesh, ReadsObjStlAndPlyMergingVerticesAndScalingUnits) {
  // OBJ quads in millimetres: a 10 mm cube, triangulated, 8 corners, 1e-6 m^3.
  const Instrument cube =
      load_mesh_instrument({write_temp("cube.obj", cube_obj(10.0, kCubeFaces)), MeshUnits::kMillimetres});
  const RigidMesh& c = cube.parts[0].mesh;
  EXPECT_EQ(c.points.rows(), 8);
  EXPECT_EQ(c.tris.rows(), 12);
  EXPECT_TRUE(closed_by_brute_force(c));
  EXPECT_NEAR(enclosed_volume(c), 1e-6, kTight);
  EXPECT_NEAR(c.points.maxCoeff(), 0.01, kTight);
  // ASCII STL repeats each facet's corners: merged to the tetrahedron's 4; volume 1/6.
  const std::string stl = "solid tet\n"
                          "facet normal 0 0 -1\nouter loop\nvertex 0 0 0\nvertex 0 1 0\nvertex 1 0 0\nendloop\nendfacet\n"
                          "facet normal 0 -1 0\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 0 1\nendloop\nendfacet\n"
                          "facet normal -1 0 0\nouter loop\nvertex 0 0 0\nvertex 0 0 1\nvertex 0 1 0\nendloop\nendfacet\n"
                          "facet normal 1 1 1\nouter loop\nvertex 1 0 0\nvertex 0 1 0\nvertex 0 0 1\nendloop\nendfacet\n"
                          "endsolid tet\n";
  const RigidMesh t = load_mesh_instrument({write_temp("tet.stl", stl)}).parts[0].mesh;
  EXPECT_EQ(t.points.rows(), 4);
  EXPECT_TRUE(closed_by_brute_force(t));
  EXPECT_NEAR(enclosed_volume(t), 1.0 / 6.0, kTight);
  // ASCII PLY.
  const std::string ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                          "property float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n"
                          "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
  const RigidMesh p = load_mesh_instrument({write_temp("tet.ply", ply), MeshUnits::kMillimetres}).parts[0].mesh;
  EXPECT_TRUE(closed_by_brute_force(p));
  EXPECT_NEAR(enclosed_volume(p), 1e-9 / 6.0, kTight);
}

TEST(InstrumentMesh, RefusesBadFilesAndBadSurfacesNamingFileAndWhere) {
  EXPECT_EQ(mesh_error("/nonexistent/tool.obj"), "/nonexistent/tool.obj: no such mesh file");
  const std::string dir = std::filesystem::temp_directory_path().string();
  EXPECT_EQ(mesh_error(dir), dir + ": is a folder, not a mesh file");
  const std::string garbage = write_temp("garbage.stl", "not a mesh\n");
  EXPECT_EQ(mesh_error(garbage).rfind(garbage + ": cannot read instrument mesh (", 0), 0u) << mesh_error(garbage);
  const std::string bare = write_temp("bare.obj", "v 0 0 0\nv 1 0 0\n");
  EXPECT_EQ(mesh_error(bare), bare + ": no triangles in instrument mesh");
  const std::string lines = write_temp("lines.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\n");
  EXPECT_EQ(mesh_error(lines), lines + ": mesh 0 face 0 has 2 vertices: not a triangle (points and lines enclose nothing)");
  // Vertex ids are the merged vertices in order of first use (the cube's first face is corners 0, 4, 6, 2).
  // A face missing: open.
  const std::string open = write_temp("open.obj", cube_obj(1.0, {1, 2, 3, 4, 5}));
  EXPECT_EQ(mesh_error(open),
            open + ": not closed: edge between vertex 1 at [0, 0, 1] and vertex 2 at [0, 1, 1] belongs to triangle 0 only");
  // One face reversed: inconsistent orientation.
  const std::string flipped = write_temp("flipped.obj", cube_obj(1.0, {1, 2, 3, 4, 5, -6}));
  EXPECT_EQ(mesh_error(flipped), flipped + ": inconsistent orientation: triangles 0, 11 run the edge between vertex 1 at "
                                           "[0, 0, 1] and vertex 2 at [0, 1, 1] the same way");
  // All faces reversed: consistently inwards.
  const std::string inward = write_temp("inward.obj", cube_obj(1.0, {-1, -2, -3, -4, -5, -6}));
  EXPECT_EQ(mesh_error(inward), inward + ": triangles face inwards: enclosed volume -1 m^3 (must be > 0, triangles "
                                         "counter-clockwise seen from outside)");
  // Two tetrahedra sharing an edge (the second is the first turned half a turn about x): four triangles on it.
  const std::string fin = write_temp("nonmanifold.obj", std::string(kTetObj) +
                                                            "v 0 -1 0\nv 0 0 -1\nf 1 5 2\nf 1 2 6\nf 1 6 5\nf 2 5 6\n");
  EXPECT_EQ(mesh_error(fin), fin + ": non-manifold edge between vertex 0 at [0, 0, 0] and vertex 2 at [1, 0, 0]: "
                                   "shared by 4 triangles (0, 1, 4, 5)");
  // A triangle on three collinear points.
  const std::string flat = write_temp("degenerate.obj", std::string(kTetObj) + "v 2 0 0\nf 1 2 5\n");
  EXPECT_EQ(mesh_error(flat), flat + ": triangle 4 is degenerate (area 0 m^2): vertex 0 at [0, 0, 0], vertex 2 at "
                                     "[1, 0, 0], vertex 4 at [2, 0, 0]");
}

TEST(InstrumentContact, SweptSphereProbeTouchesAFlatPatchOnlyWhenItCrossesIt) {
  // A 3 mm sphere probe, upright and tilted 30 degrees, swept down onto a 20 mm patch in the plane y = 0: its
  // lowest point (analytic: the sphere's centre minus the radius) goes from 5 mm above the plane to 1 mm below it
  // (contact) or to 1 mm above it (none).
  const SphereProbeSpec s;
  const Instrument probe = make_sphere_probe(s);
  const RigidMesh& body = probe.parts[0].mesh;
  const RigidMesh patch = flat_patch(0.01, 4);
  const collision::CollisionSurface probe_surface(body.tris, body.points), patch_surface(patch.tris, patch.points);
  collision::CollisionWorkspace wa(26), wb(26);
  const double start = 0.005, below = -0.001, short_of = 0.001;
  for (double tilt : {0.0, kPi / 6}) {
    Pose pose;
    pose.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(tilt, Eigen::Vector3d::UnitZ()));
    // The position that puts the lowest point of the sphere at height y.
    const double centre_above_tip = s.tip_radius * std::cos(tilt);
    auto at_lowest = [&](double y) {
      Pose p = pose;
      p.position = Eigen::Vector3d(0.001, y + s.tip_radius - centre_above_tip, 0.0013);
      return posed_parts(probe, p)[0];
    };
    const Points x0 = at_lowest(start);
    std::vector<collision::PairContact> out;
    collision::detect_pair(probe_surface, wa, x0, at_lowest(below), patch_surface, wb, patch.points, patch.points, kDetectGap,
                           out);
    EXPECT_FALSE(out.empty()) << "tilt " << tilt;
    double first = 1.0;
    for (const auto& c : out) first = std::min(first, c.toi);
    // It touches no later than the mesh's lowest point reaches the gap; the mesh holds the ball of radius
    // r cos(dphi / 2) cos(pi / n) (chords along, then polygons around), so that point is at most lag above the
    // analytic one.
    const double dphi = (kPi - std::asin(s.shaft_radius / s.tip_radius)) / s.rings;
    const double lag = s.tip_radius * (1.0 - std::cos(0.5 * dphi) * std::cos(kPi / s.segments_around));
    EXPECT_LE(first, (start - kDetectGap + lag) / (start - below)) << "tilt " << tilt;
    // And no earlier than the analytic sphere (which holds the mesh) comes within the gap plus the elementary
    // tests' accuracy (a contact has its features within gap + 2 tolerance).
    const double accuracy = 2.0 * collision::CcdOptions{}.tolerance;
    EXPECT_GE(first, (start - kDetectGap - accuracy) / (start - below)) << "tilt " << tilt;
    collision::detect_pair(probe_surface, wa, x0, at_lowest(short_of), patch_surface, wb, patch.points, patch.points,
                           kDetectGap, out);
    EXPECT_TRUE(out.empty()) << "tilt " << tilt << ": " << out.size() << " contacts";
  }
}
