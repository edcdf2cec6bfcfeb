// The volume between two concentric spheres tetrahedralised by each mesher, gmsh and Netgen (physics/pair_mesh.hpp),
// against truths that do not come from the mesher: the shell's volume by the divergence theorem over the input triangles, the input
// triangles themselves as the tets' boundary (by vertex positions), the spheres' radii, every tet's sign.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>

#include <Eigen/Geometry>

#include "physics/mesh_quality.hpp"
#include "physics/pair_mesh.hpp"
#include "physics/volume_mesh.hpp"
#include "support/sphere.hpp"
#include "support/surface_measures.hpp"

namespace {

using lumen::physics::PairMesh;
using lumen::physics::PairMesher;
using Corner = std::array<double, 3>;
using Triangle = std::array<Corner, 3>;  // its corners' positions, sorted

// Radii (metres) and tessellations of the pair: different on each sphere, so the mesher has to join them.
constexpr double kInnerRadius = 0.010, kOuterRadius = 0.014;
constexpr int kInnerRings = 7, kInnerAround = 14, kOuterRings = 9, kOuterAround = 18;
// Round-off of a sum over a few thousand tets against the same volume summed over the surfaces, relative.
constexpr double kVolumeRoundOff = 1e-12;
// A node on a sphere lies at its radius up to the round-off of sin and cos (relative).
constexpr double kOnSphere = 1e-14;

struct Pair {
  lumen::test::TubePoints inner, outer;
  lumen::test::TubeTris inner_tris, outer_tris;
};
Pair spheres() {
  Pair p;
  lumen::test::make_uv_sphere(kInnerRadius, kInnerRings, kInnerAround, p.inner, p.inner_tris);
  lumen::test::make_uv_sphere(kOuterRadius, kOuterRings, kOuterAround, p.outer, p.outer_tris);
  return p;
}

// The volume a closed outward surface encloses, by the divergence theorem (the cones from the origin).
using lumen::test::enclosed_volume;

Triangle corners(const lumen::Points& x, int a, int b, int c) {
  Triangle t;
  const int v[3] = {a, b, c};
  for (int k = 0; k < 3; ++k) t[k] = {x(v[k], 0), x(v[k], 1), x(v[k], 2)};
  std::sort(t.begin(), t.end());
  return t;
}
std::multiset<Triangle> triangles(const lumen::Points& x, const lumen::Tris& t) {
  std::multiset<Triangle> s;
  for (Eigen::Index i = 0; i < t.rows(); ++i) s.insert(corners(x, t(i, 0), t(i, 1), t(i, 2)));
  return s;
}

PairMesh mesh(const Pair& p, PairMesher mesher, double max_edge = 0.0) {
  return lumen::physics::tetrahedralise_pair(p.inner, p.inner_tris, p.outer, p.outer_tris, {mesher, max_edge});
}



// The shell's tets fill exactly the volume between the input surfaces (the outer's enclosed volume minus the
// inner's, over the input triangles), every tet positive; the tets' boundary faces are exactly the input triangles
// (as sets of corner positions), the inner wall the inner sphere's (facing the centre) and the outer wall the outer
// sphere's (facing away); every boundary node lies on its sphere, every added node strictly between the spheres.
void expect_spheres_fill_the_shell(PairMesher mesher) {
  const Pair p = spheres();
  const PairMesh m = mesh(p, mesher);
  const lumen::physics::TetMesh& t = m.mesh;
  ASSERT_GT(t.tets.rows(), 0);
  double volume = 0.0;
  for (int e = 0; e < t.tets.rows(); ++e) {
    const double v = lumen::physics::tet_volume(t.rest, t.tets, e);
    EXPECT_GT(v, 0.0) << "tet " << e;
    volume += v;
  }
  const double shell = enclosed_volume(p.outer, p.outer_tris) - enclosed_volume(p.inner, p.inner_tris);
  EXPECT_NEAR(volume, shell, kVolumeRoundOff * shell);
  EXPECT_EQ(lumen::physics::mesh_quality(t.rest, t.tets).degenerate_tets, 0);
  // Boundary = inputs, by positions; walls tagged by the sphere they came from.
  std::multiset<Triangle> inputs = triangles(p.inner, p.inner_tris);
  for (const Triangle& tri : triangles(p.outer, p.outer_tris)) inputs.insert(tri);
  EXPECT_EQ(triangles(t.rest, lumen::physics::boundary_faces(t.tets)), inputs);
  EXPECT_EQ(triangles(t.rest, t.surface(lumen::physics::kInnerWall)), triangles(p.inner, p.inner_tris));
  EXPECT_EQ(triangles(t.rest, t.surface(lumen::physics::kOuterWall)), triangles(p.outer, p.outer_tris));
  EXPECT_EQ(t.surface(lumen::physics::kEndCaps).rows(), 0);
  // Wall normals out of the volume: the inner wall's toward the centre, the outer's away from it.
  for (const char* wall : {lumen::physics::kInnerWall, lumen::physics::kOuterWall}) {
    const lumen::Tris& w = t.surface(wall);
    const double sign = std::string(wall) == lumen::physics::kInnerWall ? -1.0 : 1.0;
    for (Eigen::Index i = 0; i < w.rows(); ++i) {
      const Eigen::RowVector3d a = t.rest.row(w(i, 0)), b = t.rest.row(w(i, 1)), c = t.rest.row(w(i, 2));
      EXPECT_GT(sign * (b - a).cross(c - a).dot(a + b + c), 0.0) << wall << " triangle " << i;
    }
  }
  // Nodes: the boundary ones on their sphere, the added ones between.
  std::set<int> on_boundary;
  const lumen::Tris b = lumen::physics::boundary_faces(t.tets);
  for (Eigen::Index i = 0; i < b.rows(); ++i)
    for (int k = 0; k < 3; ++k) on_boundary.insert(b(i, k));
  EXPECT_EQ(static_cast<Eigen::Index>(on_boundary.size()), p.inner.rows() + p.outer.rows());
  EXPECT_EQ(m.added_nodes, t.rest.rows() - p.inner.rows() - p.outer.rows());
  for (int v = 0; v < t.rest.rows(); ++v) {
    const double r = t.rest.row(v).norm();
    if (v < p.inner.rows()) {
      EXPECT_NEAR(r, kInnerRadius, kOnSphere * kInnerRadius) << "node " << v;
    } else if (v < p.inner.rows() + p.outer.rows()) {
      EXPECT_NEAR(r, kOuterRadius, kOnSphere * kOuterRadius) << "node " << v;
    } else {
      EXPECT_FALSE(on_boundary.count(v)) << "node " << v;
      EXPECT_GT(r, kInnerRadius * std::cos(EIGEN_PI / kInnerRings)) << "node " << v;
      EXPECT_LT(r, kOuterRadius) << "node " << v;
    }
  }
  EXPECT_GT(m.mesher_ms, 0.0);
}

// A max_edge well below the wall's thickness makes Netgen add nodes inside the wall (and more tets), still filling
// exactly the shell with the input triangles as its boundary. gmsh is refused one (kGmshMaxEdgeRefused).
void expect_max_edge_refines_the_inside(PairMesher mesher) {
  const Pair p = spheres();
  const PairMesh coarse = mesh(p, mesher);
  const double max_edge = 0.25 * (kOuterRadius - kInnerRadius);
  const PairMesh fine = mesh(p, mesher, max_edge);
  EXPECT_GT(fine.added_nodes, coarse.added_nodes);
  EXPECT_GT(fine.mesh.tets.rows(), coarse.mesh.tets.rows());
  double volume = 0.0;
  for (int e = 0; e < fine.mesh.tets.rows(); ++e) volume += lumen::physics::tet_volume(fine.mesh.rest, fine.mesh.tets, e);
  const double shell = enclosed_volume(p.outer, p.outer_tris) - enclosed_volume(p.inner, p.inner_tris);
  EXPECT_NEAR(volume, shell, kVolumeRoundOff * shell);
  EXPECT_EQ(lumen::physics::boundary_faces(fine.mesh.tets).rows(), p.inner_tris.rows() + p.outer_tris.rows());
}

}  // namespace

TEST(TetrahedralisePair, ConcentricSpheresFillExactlyTheShellAndKeepTheirTrianglesGmsh) {
  expect_spheres_fill_the_shell(PairMesher::kGmsh);
}
TEST(TetrahedralisePair, ConcentricSpheresFillExactlyTheShellAndKeepTheirTrianglesNetgen) {
  expect_spheres_fill_the_shell(PairMesher::kNetgen);
}
TEST(TetrahedralisePair, MaxEdgeRefinesTheInsideKeepingTheSurfacesNetgen) {
  expect_max_edge_refines_the_inside(PairMesher::kNetgen);
}
// gmsh meshes in a process of its own: the same input gives the same mesh however many meshes the process made
// before (in-process, gmsh 4.8 gave a different mesh on each call), and each way its process can fail is an error
// naming it: a crash inside it (a process killed by SIGSEGV), no executable, an exit without a reply.
TEST(TetrahedralisePair, GmshGivesTheSameMeshEachCallAndItsProcessFailuresAreErrors) {
  const Pair p = spheres();
  const PairMesh first = mesh(p, PairMesher::kGmsh);
  const PairMesh second = mesh(p, PairMesher::kGmsh);
  EXPECT_EQ(first.mesh.tets, second.mesh.tets);
  EXPECT_EQ(first.mesh.rest, second.mesh.rest);
  const std::string dir = ::testing::TempDir();
  const std::string crash = dir + "/lumen_crashing_mesher.sh", silent = dir + "/lumen_silent_mesher.sh";
  std::ofstream(crash) << "#!/bin/sh\nkill -SEGV $$\n";
  std::ofstream(silent) << "#!/bin/sh\nexit 0\n";
  std::filesystem::permissions(crash, std::filesystem::perms::owner_all);
  std::filesystem::permissions(silent, std::filesystem::perms::owner_all);
  auto failure = [&](const std::string& executable) {
    ::setenv("LUMEN_GMSH_MESHER", executable.c_str(), 1);
    std::string what;
    try {
      mesh(p, PairMesher::kGmsh);
    } catch (const lumen::physics::PairMesherError& e) {
      what = e.what();
    }
    ::unsetenv("LUMEN_GMSH_MESHER");
    return what;
  };
  EXPECT_EQ(failure(crash), "gmsh failed: its process " + crash + " died of signal 11 (Segmentation fault)");
  EXPECT_EQ(failure(dir + "/no_such_mesher"),
            "gmsh failed: cannot start its process " + dir + "/no_such_mesher (No such file or directory)");
  EXPECT_EQ(failure(silent), "gmsh failed: its process's reply was cut short or malformed");
  EXPECT_EQ(mesh(p, PairMesher::kGmsh).mesh.tets, first.mesh.tets);
  // Automatic: gmsh's mesh when gmsh meshes; Netgen's, with gmsh's failure said, when gmsh's process crashes; Netgen's
  // for a maximum edge.
  const PairMesh automatic = mesh(p, PairMesher::kAuto);
  EXPECT_EQ(automatic.mesher, PairMesher::kGmsh);
  EXPECT_EQ(automatic.mesh.tets, first.mesh.tets);
  EXPECT_EQ(automatic.gmsh_failure, "");
  const PairMesh by_netgen = mesh(p, PairMesher::kNetgen);
  ::setenv("LUMEN_GMSH_MESHER", crash.c_str(), 1);
  const PairMesh fallen_back = mesh(p, PairMesher::kAuto);
  ::unsetenv("LUMEN_GMSH_MESHER");
  EXPECT_EQ(fallen_back.mesher, PairMesher::kNetgen);
  EXPECT_EQ(fallen_back.mesh.tets, by_netgen.mesh.tets);
  EXPECT_EQ(fallen_back.gmsh_failure, "gmsh failed: its process " + crash + " died of signal 11 (Segmentation fault)");
  EXPECT_EQ(mesh(p, PairMesher::kAuto, 0.25 * (kOuterRadius - kInnerRadius)).mesher, PairMesher::kNetgen);
}

TEST(TetrahedralisePair, GmshIsRefusedAMaxEdge) {
  const Pair p = spheres();
  std::string what;
  try {
    mesh(p, PairMesher::kGmsh, 0.25 * (kOuterRadius - kInnerRadius));
  } catch (const std::invalid_argument& e) {
    what = e.what();
  }
  EXPECT_EQ(what, lumen::physics::kGmshMaxEdgeRefused);
}

// Two cubes 2^-21 of their size apart (parallel faces): Netgen gives up, and the error says what it said; gmsh fills
// the gap, and fails on surfaces that cross, in its words. A triangle naming a vertex that does not exist is refused before Netgen runs.
TEST(TetrahedralisePair, MesherFailureIsReportedWithItsWords) {
  auto cube = [](double h, lumen::Points& x, lumen::Tris& t) {
    x.resize(8, 3);
    for (int i = 0; i < 8; ++i) x.row(i) << (i & 1 ? h : -h), (i & 2 ? h : -h), (i & 4 ? h : -h);
    t.resize(12, 3);
    t << 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4, 2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5;
  };
  lumen::Points in, out;
  lumen::Tris in_t, out_t;
  cube(1.0, in, in_t);
  cube(1.0 + std::ldexp(1.0, -21), out, out_t);
  // The cubes themselves are fine: 1.5 apart they mesh into the 27 - 8 = 19 between.
  lumen::Points wide = 1.5 * out;
  const PairMesh ok = lumen::physics::tetrahedralise_pair(in, in_t, wide, out_t, {PairMesher::kNetgen});
  double volume = 0.0;
  for (int e = 0; e < ok.mesh.tets.rows(); ++e) volume += lumen::physics::tet_volume(ok.mesh.rest, ok.mesh.tets, e);
  EXPECT_NEAR(volume, 27.0 * std::pow(1.0 + std::ldexp(1.0, -21), 3) - 8.0, kVolumeRoundOff * 19.0);
  std::string what;
  try {
    lumen::physics::tetrahedralise_pair(in, in_t, out, out_t, {PairMesher::kNetgen});
  } catch (const lumen::physics::PairMesherError& e) {
    what = e.what();
  }
  EXPECT_EQ(what, "Netgen failed: Stop meshing since too many attempts");
  // gmsh meshes the same thin gap (its volume exactly), but fails on an outer cube turned 45 degrees about z whose
  // faces the inner cube's vertical edges pierce (surfaces the caller would have refused), in its own words.
  const PairMesh thin = lumen::physics::tetrahedralise_pair(in, in_t, out, out_t, {PairMesher::kGmsh});
  volume = 0.0;
  for (int e = 0; e < thin.mesh.tets.rows(); ++e)
    volume += lumen::physics::tet_volume(thin.mesh.rest, thin.mesh.tets, e);
  EXPECT_NEAR(volume, 8.0 * (std::pow(1.0 + std::ldexp(1.0, -21), 3) - 1.0), 1e-6 * 8.0 * 3.0 * std::ldexp(1.0, -21));
  lumen::Points turned = 1.2 * in;
  const Eigen::Matrix3d quarter = Eigen::AngleAxisd(0.25 * EIGEN_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  turned = (turned * quarter.transpose()).eval();
  what.clear();
  try {
    lumen::physics::tetrahedralise_pair(in, in_t, turned, out_t, {PairMesher::kGmsh});
  } catch (const lumen::physics::PairMesherError& e) {
    what = e.what();
  }
  EXPECT_EQ(what, "gmsh failed: HXT 3D mesh failed");
  lumen::Tris bad = out_t;
  bad(3, 1) = 8;
  EXPECT_THROW(lumen::physics::tetrahedralise_pair(in, in_t, out, bad, {}), std::invalid_argument);
  // An empty surface is refused before Netgen runs (Netgen crashed on two empty ones).
  const lumen::Points none(0, 3);
  const lumen::Tris no_tris(0, 3);
  EXPECT_THROW(lumen::physics::tetrahedralise_pair(none, no_tris, out, out_t, {}), std::invalid_argument);
  EXPECT_THROW(lumen::physics::tetrahedralise_pair(in, in_t, none, no_tris, {}), std::invalid_argument);
  EXPECT_THROW(lumen::physics::tetrahedralise_pair(none, no_tris, none, no_tris, {}), std::invalid_argument);
}
