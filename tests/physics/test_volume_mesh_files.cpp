// Volume mesh files: Lumen's hollow cylinder written to each format (by the test's writers and by meshio, an
// independent writer) and read back identical; walls found on the boundary equal the generator's; every refusal's
// message.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <array>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <string>

#include "physics/mesh.hpp"
#include "physics/volume_mesh.hpp"
#include "physics/volume_mesh_files.hpp"
#include "support/files.hpp"
#include "support/volume_files.hpp"

namespace lumen::physics {
namespace {

using lumen::test::TaggedVolume;
// Tags the writers give the generator's surfaces.
constexpr int kInnerTag = 1, kOuterTag = 2, kEndsTag = 3;

HollowCylinderSpec small_cylinder(double bend_radius = 0.0) {
  return {0.01, 0.013, 0.04, 8, 5, 2, bend_radius, {}, {}};
}

TaggedVolume tagged(const TetMesh& m) {
  return {m.rest, m.tets, {m.surface(kInnerWall), m.surface(kOuterWall), m.surface(kEndCaps)},
          {kInnerTag, kOuterTag, kEndsTag}, {"inner", "outer", "ends"}};
}

// A triangle set with each triangle rotated to start at its lowest node (orientation kept).
std::set<std::array<int, 3>> oriented_set(const Tris& t) {
  std::set<std::array<int, 3>> s;
  for (int i = 0; i < t.rows(); ++i) {
    std::array<int, 3> f{t(i, 0), t(i, 1), t(i, 2)};
    std::rotate(f.begin(), std::min_element(f.begin(), f.end()), f.end());
    s.insert(f);
  }
  return s;
}

void expect_same_walls_as_sets(const TetMesh& got, const TetMesh& want) {
  for (const char* name : {kInnerWall, kOuterWall, kEndCaps})
    EXPECT_EQ(oriented_set(got.surface(name)), oriented_set(want.surface(name))) << name;
  EXPECT_EQ(got.node_set(kStartEnd), want.node_set(kStartEnd));
  EXPECT_EQ(got.node_set(kStopEnd), want.node_set(kStopEnd));
}

// Read back identical: nodes bit for bit (within `tolerance` metres when the writer rounds them), tets, walls in
// the file's order, end caps and end sets.
void expect_identical(const TetMesh& got, const TetMesh& want, double tolerance = 0.0) {
  if (tolerance == 0.0) {
    EXPECT_EQ(got.rest, want.rest);
  }
  ASSERT_EQ(got.rest.rows(), want.rest.rows());
  EXPECT_LE((got.rest - want.rest).cwiseAbs().maxCoeff(), tolerance);
  EXPECT_EQ(got.tets, want.tets);
  EXPECT_EQ(got.surface(kInnerWall), want.surface(kInnerWall));
  EXPECT_EQ(got.surface(kOuterWall), want.surface(kOuterWall));
  expect_same_walls_as_sets(got, want);
}

struct Format {
  const char* extension;
  std::function<std::string(const TaggedVolume&)> write;
};
const Format kFormats[] = {{"msh", lumen::test::write_msh22},
                           {"msh", lumen::test::write_msh41},
                           {"vtu", lumen::test::write_vtu},
                           {"vtk", lumen::test::write_vtk}};

std::string write_file(const std::string& name, const std::string& text) { return lumen::test::write_temp(name, text); }

TEST(VolumeMeshFiles, EachFormatReadsBackTheGeneratedCylinderIdentical) {
  const TetMesh cylinder = make_hollow_cylinder(small_cylinder());
  int i = 0;
  for (const Format& format : kFormats) {
    SCOPED_TRACE(std::to_string(i) + " ." + format.extension);
    const std::string path = write_file("cylinder" + std::to_string(i++) + "." + format.extension, format.write(tagged(cylinder)));
    const VolumeMeshFile f = read_volume_mesh_file(path);
    EXPECT_EQ(f.nodes, cylinder.rest);
    EXPECT_EQ(f.tets, cylinder.tets);
    expect_identical(make_volume_mesh(f, 1.0, {true, kInnerTag, kOuterTag}), cylinder);
    // Walls found without the tags: the same triangles (in the boundary's order).
    expect_same_walls_as_sets(make_volume_mesh(f, 1.0, {}), cylinder);
  }
}

TEST(VolumeMeshFiles, GmshPhysicalNamesAreRead) {
  const TetMesh cylinder = make_hollow_cylinder(small_cylinder());
  const VolumeMeshFile f = parse_volume_mesh(lumen::test::write_msh41(tagged(cylinder)), "msh", "c.msh");
  ASSERT_EQ(f.tag_names.size(), 3u);
  EXPECT_EQ(f.tag_names[1].name, "outer");
  EXPECT_EQ(f.tag_names[1].tag, kOuterTag);
}

TEST(VolumeMeshFiles, MillimetreFilesAreScaledToMetres) {
  TetMesh cylinder = make_hollow_cylinder(small_cylinder());
  TaggedVolume mm = tagged(cylinder);
  mm.nodes *= 1000.0;
  const VolumeMeshFile f = parse_volume_mesh(lumen::test::write_vtk(mm), "vtk", "mm.vtk");
  const TetMesh m = make_volume_mesh(f, 1e-3, {true, kInnerTag, kOuterTag});
  EXPECT_LT((m.rest - cylinder.rest).cwiseAbs().maxCoeff(), 1e-15);
}

TEST(VolumeMeshFiles, WallsOfABentTubeAreFoundWithoutTags) {
  const TetMesh bent = make_hollow_cylinder(small_cylinder(0.02));
  const VolumeMeshFile f = parse_volume_mesh(lumen::test::write_vtu(tagged(bent)), "vtu", "bent.vtu");
  expect_same_walls_as_sets(make_volume_mesh(f, 1.0, {}), bent);
}

// A closed hollow organ: a tube bent into a full ring, its last ring of nodes merged into its first, so that its
// boundary is two closed surfaces (inner and outer torus) and it has no end caps.
TEST(VolumeMeshFiles, TheInnerOfTwoClosedBoundaryComponentsIsTheLumenWall) {
  constexpr int kRings = 12, kAround = 8, kLayers = 2;
  constexpr double kRingRadius = 0.05;
  std::vector<TubeRing> rings;
  for (int j = 0; j <= kRings; ++j) {
    const double a = kTwoPi * j / kRings;
    const Eigen::Vector3d point(kRingRadius * std::cos(a), kRingRadius * std::sin(a), 0.0);
    const Eigen::Vector3d tangent(-std::sin(a), std::cos(a), 0.0);
    const Eigen::Vector3d normal(std::cos(a), std::sin(a), 0.0);
    rings.push_back({{point, tangent, normal, tangent.cross(normal)}, 0.01, 0.013});
  }
  const TetMesh open = make_structured_tube(rings, kAround, kLayers);
  const int n = kRings * (kLayers + 1) * kAround;  // the nodes of rings 0 .. kRings - 1
  auto merged = [&](int v) { return v % n; };     // ring kRings is ring 0
  TaggedVolume ring{open.rest.topRows(n), open.tets.unaryExpr(merged), {}, {}, {}};
  const VolumeMeshFile f = parse_volume_mesh(lumen::test::write_msh22(ring), "msh", "torus.msh");
  const TetMesh m = make_volume_mesh(f, 1.0, {});
  EXPECT_EQ(oriented_set(m.surface(kInnerWall)), oriented_set(open.surface(kInnerWall).unaryExpr(merged)));
  EXPECT_EQ(oriented_set(m.surface(kOuterWall)), oriented_set(open.surface(kOuterWall).unaryExpr(merged)));
  EXPECT_EQ(m.surface(kEndCaps).rows(), 0);
  EXPECT_FALSE(m.has_node_set(kStartEnd));
}

// gmsh's own files (tests/data/volume/tube.geo meshed by Debian's gmsh 4.8 into .msh 4.1, .msh 2.2 and legacy
// .vtk): the same mesh from each; the tagged walls on the geometry's cylinders; the found walls equal them.
TEST(VolumeMeshFiles, FilesWrittenByGmshReadTheSameAndTheirWallsLieOnTheCylinders) {
  constexpr double kInner = 0.010, kOuter = 0.013, kLength = 0.040, kMetresPerMm = 1e-3;
  constexpr double kOnSurface = 1e-9;  // metres: gmsh places boundary nodes on the exact geometry
  const std::string dir = std::string(LUMEN_TEST_DATA_DIR) + "/volume/";
  const VolumeMeshFile v41 = read_volume_mesh_file(dir + "tube41.msh");
  const TetMesh tagged41 = make_volume_mesh(v41, kMetresPerMm, {true, 1, 2});
  for (const char* name : {"tube41.msh", "tube22.msh", "tube.vtk"}) {
    SCOPED_TRACE(name);
    const VolumeMeshFile f = read_volume_mesh_file(dir + name);
    EXPECT_EQ(f.nodes, v41.nodes);
    EXPECT_EQ(f.tets, v41.tets);
    expect_same_walls_as_sets(make_volume_mesh(f, kMetresPerMm, {}), tagged41);
  }
  EXPECT_EQ(read_volume_mesh_file(dir + "tube22.msh").triangle_tags, v41.triangle_tags);
  // Each wall's nodes on its cylinder, the end caps' on the end planes, the end sets one plane each.
  auto radius = [&](int v) { return std::hypot(tagged41.rest(v, 0), tagged41.rest(v, 1)); };
  const Tris& inner = tagged41.surface(kInnerWall);
  const Tris& outer = tagged41.surface(kOuterWall);
  ASSERT_GT(inner.rows(), 0);
  ASSERT_GT(outer.rows(), 0);
  for (int t = 0; t < inner.rows(); ++t)
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(radius(inner(t, k)), kInner, kOnSurface);
  for (int t = 0; t < outer.rows(); ++t)
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(radius(outer(t, k)), kOuter, kOnSurface);
  for (int v : tagged41.node_set(kStartEnd)) EXPECT_NEAR(tagged41.rest(v, 2), tagged41.rest(tagged41.node_set(kStartEnd)[0], 2), kOnSurface);
  for (int v : tagged41.node_set(kStopEnd)) EXPECT_NEAR(tagged41.rest(v, 2), tagged41.rest(tagged41.node_set(kStopEnd)[0], 2), kOnSurface);
  EXPECT_NEAR(std::abs(tagged41.rest(tagged41.node_set(kStartEnd)[0], 2) - tagged41.rest(tagged41.node_set(kStopEnd)[0], 2)), kLength, kOnSurface);
  // Outward walls: the inner wall's normals point to the axis, the outer wall's away from it.
  for (const auto& [wall, sign] : {std::pair<const Tris*, double>{&inner, -1.0}, {&outer, 1.0}})
    for (int t = 0; t < wall->rows(); ++t) {
      const Eigen::Vector3d a = tagged41.rest.row((*wall)(t, 0)), b = tagged41.rest.row((*wall)(t, 1)), c = tagged41.rest.row((*wall)(t, 2));
      const Eigen::Vector3d centre = (a + b + c) / 3.0;
      EXPECT_GT(sign * (b - a).cross(c - a).dot(Eigen::Vector3d(centre.x(), centre.y(), 0.0)), 0.0) << t;
    }
  // The volume: the annulus prism's, within the facets' chords (inscribed in both cylinders: under 1 %).
  double volume = 0.0;
  for (int t = 0; t < tagged41.tets.rows(); ++t) volume += tet_volume(tagged41.rest, tagged41.tets, t);
  const double annulus = static_cast<double>(EIGEN_PI) * (kOuter * kOuter - kInner * kInner) * kLength;
  EXPECT_NEAR(volume, annulus, 0.01 * annulus);
}

// meshio (Debian's python3-meshio for /usr/bin/python3) writes the generator's mesh from plain arrays in each
// format; Lumen reads each back equal.
TEST(VolumeMeshFiles, FilesWrittenByMeshioReadBackEqual) {
  // meshio's ASCII .vtu writes 12 significant digits: nodes of a 1.3 cm tube within this (metres).
  constexpr double kMeshioRounding = 1e-13;
  constexpr const char* kPython = "/usr/bin/python3";
  if (std::system((std::string(kPython) + " -c \"import meshio\" 2>/dev/null").c_str()) != 0)
    GTEST_SKIP() << "meshio is missing: install Debian's python3-meshio (for /usr/bin/python3) to run this test";
  const TetMesh cylinder = make_hollow_cylinder(small_cylinder());
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "lumen_test_meshio";
  std::filesystem::create_directories(dir);
  // The arrays as Python literals, triangles tagged as the writers above tag them.
  std::ostringstream py = lumen::test::exact_stream();
  auto rows = [&](const auto& a) {
    py << "[";
    for (int i = 0; i < a.rows(); ++i) {
      py << "[";
      for (int k = 0; k < a.cols(); ++k) py << a(i, k) << ",";
      py << "],";
    }
    py << "]";
  };
  py << "import meshio, numpy as np\npoints = np.array(";
  rows(cylinder.rest);
  py << ")\ntets = np.array(";
  rows(cylinder.tets);
  py << ")\ntris = np.array(";
  Tris walls(cylinder.surface(kInnerWall).rows() + cylinder.surface(kOuterWall).rows(), 3);
  walls << cylinder.surface(kInnerWall), cylinder.surface(kOuterWall);
  rows(walls);
  py << ")\ntags = np.array([" << kInnerTag << "] * " << cylinder.surface(kInnerWall).rows() << " + [" << kOuterTag
     << "] * " << cylinder.surface(kOuterWall).rows() << ")\n"
     << "m = meshio.Mesh(points, [('triangle', tris), ('tetra', tets)],\n"
     << "    cell_data={'gmsh:physical': [tags, np.full(len(tets), 9)], 'gmsh:geometrical': [tags, np.full(len(tets), 1)]},\n"
     << "    point_data={'gmsh:dim_tags': np.array([[3, 1]] * len(points))})\n"
     << "d = '" << dir.string() << "/'\n"
     << "m.write(d + 'c22.msh', file_format='gmsh22', binary=False)\n"
     << "m.write(d + 'c41.msh', file_format='gmsh', binary=False)\n"
     << "m.write(d + 'c.vtu', binary=False)\n"
     << "m.write(d + 'c.vtk', binary=False)\n";
  const std::string script = write_file("meshio_write.py", py.str());
  ASSERT_EQ(std::system((std::string(kPython) + " " + script).c_str()), 0) << "meshio failed to write";
  for (const char* name : {"c22.msh", "c41.msh", "c.vtu", "c.vtk"}) {
    SCOPED_TRACE(name);
    const VolumeMeshFile f = read_volume_mesh_file((dir / name).string());
    EXPECT_EQ(f.tets, cylinder.tets);
    // meshio 5.0's MSH 4.1 writer lists no surface entities, so its triangles carry no physical tag.
    if (std::string(name) != "c41.msh")
      expect_identical(make_volume_mesh(f, 1.0, {true, kInnerTag, kOuterTag}), cylinder, kMeshioRounding);
    expect_same_walls_as_sets(make_volume_mesh(f, 1.0, {}), cylinder);
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Refusals: one message naming the file, where and the problem.

// One positive tet in MSH 2.2 (line 13: the element), a triangle on its face (1, 3, 2) with tag 5 (line 14).
constexpr const char* kOneTet =
    "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n"
    "$Elements\n2\n1 4 2 1 1 1 2 3 4\n2 2 2 5 1 1 3 2\n$EndElements\n";

// The line of a text the first `what` is on.
std::string line_of(const std::string& text, const std::string& what) {
  return "line " + std::to_string(1 + std::count(text.begin(), text.begin() + static_cast<long>(text.find(what)), '\n'));
}

std::string refusal(const std::string& text, const std::string& format) {
  return lumen::test::message_of<std::invalid_argument>([&] { parse_volume_mesh(text, format, "f." + format); });
}
std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

TEST(VolumeMeshFiles, TheOneTetFileIsRead) {
  const VolumeMeshFile f = parse_volume_mesh(kOneTet, "msh", "f.msh");
  EXPECT_EQ(f.tets.rows(), 1);
  EXPECT_EQ(f.triangle_tags, std::vector<int>{5});
  EXPECT_EQ(f.tet_ids, std::vector<long>{1});
}

TEST(VolumeMeshFiles, RefusesMissingFilesAndUnknownFormats) {
  EXPECT_EQ(lumen::test::message_of<std::invalid_argument>([] { read_volume_mesh_file("/no/such/organ.msh"); }),
            "/no/such/organ.msh: file: no such volume mesh file");
  const std::string stl = write_file("organ.stl", "solid x\nendsolid x\n");
  EXPECT_EQ(lumen::test::message_of<std::invalid_argument>([&] { read_volume_mesh_file(stl); }),
            stl + ": file name: unsupported volume mesh format \".stl\" (supported: .msh, .vtu, .vtk)");
}

TEST(VolumeMeshFiles, RefusesGmshVersionsAndBinary) {
  EXPECT_EQ(refusal(replaced(kOneTet, "2.2 0 8", "3.0 0 8"), "msh"),
            "f.msh: line 2: unsupported gmsh format version 3.0 (supported: 2.2 and 4.1)");
  EXPECT_EQ(refusal(replaced(kOneTet, "2.2 0 8", "4.1 1 8"), "msh"),
            "f.msh: line 2: binary gmsh file: only ASCII .msh files are supported (save with \"-format msh22\" or "
            "msh41, not binary)");
}

TEST(VolumeMeshFiles, RefusesTruncatedSectionsAndUndefinedNodes) {
  EXPECT_EQ(refusal(std::string(kOneTet).substr(0, std::string(kOneTet).find("3 0 1 0")), "msh"),
            "f.msh: line 8: the file ends inside $Nodes (from line 4) (expected node id)");
  EXPECT_EQ(refusal(std::string(kOneTet).substr(0, std::string(kOneTet).find("$EndElements")), "msh"),
            "f.msh: line 15: the file ends inside $Elements (from line 11) (expected $EndElements)");
  EXPECT_EQ(refusal(replaced(kOneTet, "1 1 2 3 4", "1 1 2 3 9"), "msh"),
            "f.msh: line 13, element id 1: node id 9 is used but not defined");
  const std::string v41 = lumen::test::write_msh41(tagged(make_hollow_cylinder(small_cylinder())));
  const std::string block = "\n3 1 0 " + std::to_string(make_hollow_cylinder(small_cylinder()).rest.rows()) + "\n";
  EXPECT_EQ(refusal(replaced(v41, block, "\n3 1 0 2000000000\n"), "msh"),
            "f.msh: " + line_of(v41, block.substr(1)) + ": number of nodes in block 2000000000 is more than the rest "
            "of the file holds (truncated?)");
  EXPECT_EQ(refusal(replaced(kOneTet, "4 0 0 1", "4 0 0 x"), "msh"),
            "f.msh: line 9: expected z coordinate in $Nodes (from line 4) (got \"x\")");
}

TEST(VolumeMeshFiles, RefusesOtherVolumeElementsTet10AndFilesWithoutTets) {
  EXPECT_EQ(refusal(replaced(kOneTet, "1 4 2 1 1 1 2 3 4", "1 7 2 1 1 1 2 3 4 4"), "msh"),
            "f.msh: line 13, element id 1: a pyramid (gmsh type 7): only linear tetrahedra are supported");
  EXPECT_EQ(refusal(replaced(kOneTet, "1 4 2 1 1 1 2 3 4", "1 11 2 1 1 1 2 3 4 1 2 3 4 1 2"), "msh"),
            "f.msh: line 13, element id 1: a 10-node tetrahedron (gmsh type 11): only linear tetrahedra are "
            "supported; export the mesh with linear (4-node) tets");
  EXPECT_EQ(refusal(replaced(replaced(kOneTet, "1 4 2 1 1 1 2 3 4\n", ""), "$Elements\n2", "$Elements\n1"), "msh"),
            "f.msh: elements: no tetrahedra (4 nodes, 1 elements, none a linear tetrahedron)");
}

// The cylinder as a legacy VTK file, and as .vtu.
std::string cylinder_vtk() { return lumen::test::write_vtk(tagged(make_hollow_cylinder(small_cylinder()))); }
std::string cylinder_vtu() { return lumen::test::write_vtu(tagged(make_hollow_cylinder(small_cylinder()))); }

// Field data of the whole dataset (as VTK writes a time value) is read past.
TEST(VolumeMeshFiles, LegacyVtkDatasetFieldDataIsReadPast) {
  const std::string vtk = replaced(cylinder_vtk(), "POINTS", "FIELD FieldData 1\nTIME 1 1 double\n0.5\nPOINTS");
  const VolumeMeshFile f = parse_volume_mesh(vtk, "vtk", "f.vtk");
  EXPECT_EQ(f.tets, make_hollow_cylinder(small_cylinder()).tets);
  EXPECT_EQ(f.triangle_tags.front(), kInnerTag);
}

TEST(VolumeMeshFiles, RefusesBinaryAndOtherVtkDatasets) {
  EXPECT_EQ(refusal(replaced(cylinder_vtk(), "ASCII", "BINARY"), "vtk"),
            "f.vtk: line 3: binary VTK file: only ASCII .vtk files are supported");
  EXPECT_EQ(refusal(replaced(cylinder_vtk(), "UNSTRUCTURED_GRID", "POLYDATA"), "vtk"),
            "f.vtk: line 4: dataset POLYDATA: only UNSTRUCTURED_GRID is supported");
  EXPECT_EQ(refusal(replaced(cylinder_vtu(), "format=\"ascii\"", "format=\"binary\""), "vtu"),
            "f.vtu: line 6: DataArray in <Points> has format \"binary\": only ASCII .vtu files are supported");
  const std::string appended = replaced(cylinder_vtu(), "</UnstructuredGrid>", "</UnstructuredGrid>\n<AppendedData encoding=\"raw\"/>");
  EXPECT_EQ(refusal(appended, "vtu"),
            "f.vtu: " + line_of(appended, "<AppendedData") + ": appended (binary) data: only ASCII .vtu files are supported (DataArray format=\"ascii\")");
  EXPECT_EQ(refusal(replaced(cylinder_vtu(), "UnstructuredGrid\" version", "PolyData\" version"), "vtu"),
            "f.vtu: line 2: VTKFile type \"PolyData\": only UnstructuredGrid is supported");
}

TEST(VolumeMeshFiles, RefusesTruncatedAndInconsistentVtk) {
  const std::string vtu = cylinder_vtu();
  EXPECT_EQ(refusal(vtu.substr(0, vtu.find("</Cells>")), "vtu"),
            "f.vtu: " + line_of(vtu, "</Cells>") + ": malformed or truncated XML: no element found");
  // 704 cells: the 224 wall and end triangles (8 around, 5 along, 2 layers), then the 480 tets.
  const std::string vtk = cylinder_vtk();
  EXPECT_EQ(refusal(vtk.substr(0, vtk.find("CELL_TYPES")), "vtk"), "f.vtk: CELL_TYPES: 0 cell types for 704 cells");
  EXPECT_EQ(refusal(replaced(vtk, "\n10\n", "\n24\n"), "vtk"),
            "f.vtk: cell 224: a quadratic tetra (VTK type 24): only linear tetrahedra are supported; export the mesh "
            "with linear (4-node) tets");
  EXPECT_EQ(refusal(replaced(vtk, "\n4 0 ", "\n4 9999 "), "vtk"), "f.vtk: cell 224: node id 9999 is used but not defined");
}

TEST(VolumeMeshFiles, RefusesInvertedTetsAndMissingTags) {
  VolumeMeshFile f = parse_volume_mesh(kOneTet, "msh", "f.msh");
  EXPECT_EQ(lumen::test::message_of<std::invalid_argument>([&] { make_volume_mesh(f, 1.0, {true, 7, 5}); }),
            "f.msh: mesh.inner_tag: no triangle has tag 7 (triangle tags in the file: 5)");
  std::swap(f.tets(0, 1), f.tets(0, 2));
  EXPECT_EQ(lumen::test::message_of<std::invalid_argument>([&] { make_volume_mesh(f, 1.0, {true, 5, 6}); }),
            "f.msh: tet 0 (element 1 of the file): is inverted or has zero volume (signed volume -0.166667 m^3); 1 "
            "such tets of 1");
}

TEST(VolumeMeshFiles, RefusesATaggedTriangleInsideTheVolume) {
  const TetMesh cylinder = make_hollow_cylinder(small_cylinder());
  TaggedVolume v = tagged(cylinder);
  // A face of tet 0 shared with another tet: its first face that is not on the boundary.
  const auto boundary = oriented_set(boundary_faces(cylinder.tets));
  Tris inside(1, 3);
  for (const auto& lf : {std::array<int, 3>{0, 1, 2}, {0, 1, 3}, {0, 2, 3}, {1, 2, 3}}) {
    inside << cylinder.tets(0, lf[0]), cylinder.tets(0, lf[1]), cylinder.tets(0, lf[2]);
    if (!boundary.count(*oriented_set(inside).begin()) && !boundary.count(*oriented_set(inside.rowwise().reverse()).begin())) break;
  }
  v.surfaces[0].conservativeResize(v.surfaces[0].rows() + 1, 3);
  v.surfaces[0].bottomRows(1) = inside;
  const VolumeMeshFile f = parse_volume_mesh(lumen::test::write_msh22(v), "msh", "f.msh");
  EXPECT_EQ(lumen::test::message_of<std::invalid_argument>([&] { make_volume_mesh(f, 1.0, {true, kInnerTag, kOuterTag}); }),
            "f.msh: triangle " + std::to_string(cylinder.surface(kInnerWall).rows()) + " (tag 1): is not a boundary face of the tets");
}

// Two tets sharing only an edge: that edge has four boundary faces.
TEST(VolumeMeshFiles, RefusesANonManifoldBoundary) {
  VolumeMeshFile f;
  f.file = "bowtie.vtk";
  f.nodes.resize(6, 3);
  f.nodes << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, -1, 0, 0, 0, -1;
  f.tets.resize(2, 4);
  f.tets << 0, 1, 2, 3, 0, 1, 4, 5;
  f.tet_ids = {0, 1};
  ASSERT_GT(tet_volume(f.nodes, f.tets, 1), 0.0);
  EXPECT_EQ(lumen::test::message_of<std::invalid_argument>([&] { make_volume_mesh(f, 1.0, {}); }),
            "bowtie.vtk: boundary edge (nodes 0, 1; 0-based, in the file's order of the nodes the tets use): has 4 "
            "boundary faces: the boundary is not a manifold surface");
}

TEST(VolumeMeshFiles, RefusesABoundaryWithoutWallsFacingEachOther) {
  // One solid tet: one boundary component whose four flat patches enclose nothing.
  const VolumeMeshFile one = parse_volume_mesh(kOneTet, "msh", "f.msh");
  EXPECT_EQ(lumen::test::message_of<std::invalid_argument>([&] { make_volume_mesh(one, 1.0, {}); }),
            "f.msh: boundary: has 1 component(s) and 4 patch(es) between edges sharper than 60 degrees, and no pair "
            "of them encloses the other (a wall facing the lumen inside an outer wall); give mesh.inner_tag and "
            "mesh.outer_tag");
  // Three separate tets: three components.
  VolumeMeshFile three;
  three.file = "three.vtk";
  three.nodes.resize(12, 3);
  three.tets.resize(3, 4);
  for (int t = 0; t < 3; ++t) {
    three.nodes.middleRows(4 * t, 4) = one.nodes.rowwise() + Eigen::RowVector3d(2.0 * t, 0.0, 0.0);
    three.tets.row(t) = one.tets.row(0).array() + 4 * t;
    three.tet_ids.push_back(t);
  }
  EXPECT_EQ(lumen::test::message_of<std::invalid_argument>([&] { make_volume_mesh(three, 1.0, {}); }),
            "three.vtk: boundary: has 3 connected components: expected 2 closed ones (a hollow organ's inner and "
            "outer wall) or 1 (an open tube); give mesh.inner_tag and mesh.outer_tag");
}

}  // namespace
}  // namespace lumen::physics
