// mesh.type "surface_pair": two closed surface files (inner, outer) tetrahedralised at load by gmsh (or Netgen). Every format
// the surface reader takes, the tets against the files' own triangles and volumes, every refusal by its message,
// the program's exit code, and report.json's mesh block from a short checked session.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/scene.hpp"
#include "engine/simulation.hpp"
#include "engine/surface_pair.hpp"
#include "physics/mesh_quality.hpp"
#include "physics/pair_mesh.hpp"
#include "physics/volume_mesh.hpp"
#include "support/files.hpp"
#include "support/instruments.hpp"
#include "support/model_runs.hpp"
#include "support/scene_files.hpp"
#include "support/sphere.hpp"
#include "support/surface_measures.hpp"

namespace fs = std::filesystem;
using lumen::engine::InputError;
using nlohmann::json;

namespace {

// The sphere pair (millimetres): radii and tessellations, different on each sphere.
constexpr double kInnerMm = 10.0, kOuterMm = 14.0;
constexpr int kInnerRings = 7, kInnerAround = 14, kOuterRings = 9, kOuterAround = 18;
// Round-off of the tets' summed volume against the surfaces' (relative).
constexpr double kVolumeRoundOff = 1e-12;
// The half-size of the unit cube, and the other cube's 2^-21 more (exact in a float: assimp's precision), too close
// for any tet between their parallel faces.
constexpr double kCubeGap = 1.0 / (1 << 21);

using Vertices = std::vector<std::array<double, 3>>;
using Faces = std::vector<std::array<int, 3>>;

// A latitude-longitude sphere of radius r about `centre` (tests/support/sphere.hpp).
void sphere(double r, int rings, int around, Vertices& v, Faces& f, double centre_x = 0.0) {
  lumen::test::TubePoints x;
  lumen::test::TubeTris t;
  lumen::test::make_uv_sphere(r, rings, around, x, t);
  v.clear();
  f.clear();
  for (Eigen::Index i = 0; i < x.rows(); ++i) v.push_back({x(i, 0) + centre_x, x(i, 1), x(i, 2)});
  for (Eigen::Index i = 0; i < t.rows(); ++i) f.push_back({t(i, 0), t(i, 1), t(i, 2)});
}

// A cube of half-size h about the origin, outward.
void cube(double h, Vertices& v, Faces& f) {
  v.clear();
  for (int i = 0; i < 8; ++i) v.push_back({i & 1 ? h : -h, i & 2 ? h : -h, i & 4 ? h : -h});
  f = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
       {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
}

// The surface as a file in the format its extension names (OBJ, OFF, ASCII STL, ASCII PLY).
void write_surface(const fs::path& file, const Vertices& v, const Faces& f) {
  std::ofstream out(file);
  out.precision(17);
  const std::string ext = file.extension().string();
  if (ext == ".obj") {
    for (const auto& p : v) out << "v " << p[0] << " " << p[1] << " " << p[2] << "\n";
    for (const auto& t : f) out << "f " << t[0] + 1 << " " << t[1] + 1 << " " << t[2] + 1 << "\n";
  } else if (ext == ".off") {
    out << "OFF\n" << v.size() << " " << f.size() << " 0\n";
    for (const auto& p : v) out << p[0] << " " << p[1] << " " << p[2] << "\n";
    for (const auto& t : f) out << "3 " << t[0] << " " << t[1] << " " << t[2] << "\n";
  } else if (ext == ".stl") {
    out << "solid s\n";
    for (const auto& t : f) {
      out << "facet normal 0 0 0\nouter loop\n";
      for (int k : t) out << "vertex " << v[k][0] << " " << v[k][1] << " " << v[k][2] << "\n";
      out << "endloop\nendfacet\n";
    }
    out << "endsolid s\n";
  } else {
    out << "ply\nformat ascii 1.0\nelement vertex " << v.size()
        << "\nproperty float x\nproperty float y\nproperty float z\nelement face " << f.size()
        << "\nproperty list uchar int vertex_indices\nend_header\n";
    for (const auto& p : v) out << p[0] << " " << p[1] << " " << p[2] << "\n";
    for (const auto& t : f) out << "3 " << t[0] << " " << t[1] << " " << t[2] << "\n";
  }
}

// The two spheres as d/<inner> and d/<outer> (the outer's centre shifted by outer_x mm).
void write_spheres(const fs::path& d, const std::string& inner, const std::string& outer, double outer_r = kOuterMm,
                   double outer_x = 0.0) {
  Vertices v;
  Faces f;
  sphere(kInnerMm, kInnerRings, kInnerAround, v, f);
  write_surface(d / inner, v, f);
  sphere(outer_r, kOuterRings, kOuterAround, v, f, outer_x);
  write_surface(d / outer, v, f);
}

// A surface pair scene in millimetres, held on its -x side, one probe pressing the outer wall at +x by 1 mm.
json pair_scene(const std::string& inner, const std::string& outer) {
  json s = json::parse(R"({
    "name": "pair",
    "mesh": {"type": "surface_pair", "units": "mm"},
    "material": {"model": "linear", "young_modulus": 5000.0, "poisson_ratio": 0.45},
    "fixed": [{"plane": {"point": [-0.012, 0, 0], "normal": [-1, 0, 0]}}],
    "probes": [{"name": "press", "point": [0.014, 0, 0],
                "track": [{"t": 0.0, "displacement": [0, 0, 0]}, {"t": 0.05, "displacement": [-0.001, 0, 0]}]}],
    "frames": 3, "fps": 40, "collision": {"self": true}
  })");
  s["mesh"]["inner"] = inner;
  s["mesh"]["outer"] = outer;
  return s;
}

using lumen::test::load_error;
using lumen::test::run_lumen;
using lumen::test::write_scene;

using Triangle = std::array<std::array<double, 3>, 3>;  // corner positions, sorted
std::multiset<Triangle> triangles(const lumen::Points& x, const lumen::Tris& t) {
  std::multiset<Triangle> s;
  for (Eigen::Index i = 0; i < t.rows(); ++i) {
    Triangle tri;
    for (int k = 0; k < 3; ++k) tri[k] = {x(t(i, k), 0), x(t(i, k), 1), x(t(i, k), 2)};
    std::sort(tri.begin(), tri.end());
    s.insert(tri);
  }
  return s;
}

}  // namespace

// The same sphere pair from every format the surface reader takes (OBJ, OFF, STL, PLY; inner and outer in different
// ones): each loads into tets that fill exactly the volume between the files' surfaces as read (the divergence
// theorem over their triangles), all positive, whose boundary faces are exactly the files' triangles (by corner
// positions), the inner wall the inner file's and the outer wall the outer file's.
TEST(SurfacePair, EveryFormatLoadsIntoTetsBoundedByTheFilesTriangles) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_pair_", "formats");
  for (const auto& [in, out] : std::vector<std::array<std::string, 2>>{{"in.obj", "out.off"}, {"in.stl", "out.ply"}}) {
    write_spheres(d, in, out);
    const lumen::engine::Scene s = lumen::engine::load_scene(write_scene(d, pair_scene(in, out)));
    ASSERT_EQ(s.mesh_type, lumen::engine::MeshType::kSurfacePair);
    const lumen::physics::TetMesh& m = s.surface_pair.pair.mesh;
    const lumen::engine::SurfaceMesh inner = lumen::engine::read_closed_surface((d / in).string(), 1e-3);
    const lumen::engine::SurfaceMesh outer = lumen::engine::read_closed_surface((d / out).string(), 1e-3);
    double volume = 0.0;
    for (int e = 0; e < m.tets.rows(); ++e) {
      EXPECT_GT(lumen::physics::tet_volume(m.rest, m.tets, e), 0.0) << in << " tet " << e;
      volume += lumen::physics::tet_volume(m.rest, m.tets, e);
    }
    const double between = lumen::engine::enclosed_volume(outer) - lumen::engine::enclosed_volume(inner);
    EXPECT_NEAR(volume, between, kVolumeRoundOff * between) << in;
    std::multiset<Triangle> both = triangles(inner.points, inner.tris);
    for (const Triangle& t : triangles(outer.points, outer.tris)) both.insert(t);
    EXPECT_EQ(triangles(m.rest, lumen::physics::boundary_faces(m.tets)), both) << in;
    EXPECT_EQ(triangles(m.rest, m.surface(lumen::physics::kInnerWall)), triangles(inner.points, inner.tris)) << in;
    EXPECT_EQ(triangles(m.rest, m.surface(lumen::physics::kOuterWall)), triangles(outer.points, outer.tris)) << in;
    EXPECT_EQ(s.surface_pair.pair.inner_triangles, 2 * kInnerRings * kInnerAround);
    EXPECT_EQ(s.surface_pair.pair.outer_triangles, 2 * kOuterRings * kOuterAround);
  }
}

// Every refusal names the file(s), the problem and where: missing file, unsupported format, an open surface, a
// surface through itself, the surfaces through each other, an outer surface that does not enclose the inner one
// (apart, or swapped), the mesher's failure in its own words; the keys; what a closed wall cannot combine with.
TEST(SurfacePair, RefusesBadPairsNamingFileProblemAndWhere) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_pair_", "bad");
  const std::string in = (d / "in.obj").string(), out = (d / "out.obj").string(), scene = (d / "s.json").string();
  auto error = [&](const std::string& inner, const std::string& outer) {
    return load_error(write_scene(d, pair_scene(inner, outer)));
  };
  write_spheres(d, "in.obj", "out.obj");
  EXPECT_EQ(error("in.obj", "out.obj"), "");
  // Files.
  EXPECT_EQ(error("in.obj", "missing.obj"), (d / "missing.obj").string() + ": no such surface file");
  std::ofstream(d / "out.dae") << "x";
  EXPECT_EQ(error("in.obj", "out.dae"), (d / "out.dae").string() + ": unsupported surface format \".dae\" (OBJ, STL, PLY or OFF)");
  std::ofstream(d / "open.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\n";
  EXPECT_EQ(error("open.obj", "out.obj"), (d / "open.obj").string() + ": not closed: edge between vertex 0 at [0, 0, 0] "
                                           "and vertex 1 at [0, 0.001, 0] belongs to triangle 0 only");
  // Two closed tetrahedra, the second through the first, inside the outer sphere.
  std::ofstream(d / "self.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 0.2 0.2 -0.5\nv 1.2 0.2 -0.5\nv 0.2 1.2 -0.5\n"
                                   "v 0.2 0.2 0.5\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\nf 5 7 6\nf 5 6 8\nf 6 7 8\nf 5 8 7\n";
  EXPECT_EQ(error("self.obj", "out.obj"),
            (d / "self.obj").string() + ": the inner surface intersects itself: triangles 0 and 5 intersect (3 intersecting pairs)");
  EXPECT_EQ(error("in.obj", "self.obj"),
            (d / "self.obj").string() + ": the outer surface intersects itself: triangles 0 and 5 intersect (3 intersecting pairs)");
  // The outer sphere shifted 6 mm along x: through the inner one (the spheres meet on the circle x = -5 mm), named by
  // the first intersecting pair in the exact check's order and the count.
  write_spheres(d, "in.obj", "shifted.obj", kOuterMm, 6.0);
  EXPECT_EQ(error("in.obj", "shifted.obj"),
            in + " and " + (d / "shifted.obj").string() + ": the surfaces intersect each other: triangle 58 of the inner "
            "surface and triangle 132 of the outer surface intersect (68 intersecting pairs)");
  // Apart (the outer sphere 30 mm along x), and swapped.
  write_spheres(d, "in.obj", "apart.obj", kOuterMm, 30.0);
  EXPECT_EQ(error("in.obj", "apart.obj"), (d / "apart.obj").string() + ": does not enclose the inner surface " + in +
                                               ": its vertex 0 at [0, 0, -0.01] lies outside");
  EXPECT_EQ(error("out.obj", "in.obj"), in + ": does not enclose the inner surface " + out +
                                            ": its vertex 0 at [0, 0, -0.014] lies outside, and the outer surface lies "
                                            "inside the inner one: inner and outer are swapped");
  // Two cubes 2^-21 apart: Netgen gives up (gmsh, the default, fills the gap).
  Vertices v;
  Faces f;
  cube(1.0, v, f);
  write_surface(d / "cube.obj", v, f);
  cube(1.0 + kCubeGap, v, f);
  write_surface(d / "cube2.obj", v, f);
  json cubes = pair_scene("cube.obj", "cube2.obj");
  cubes["mesh"]["mesher"] = "netgen";
  EXPECT_EQ(load_error(write_scene(d, cubes)), (d / "cube.obj").string() + " and " + (d / "cube2.obj").string() +
                                                   ": Netgen failed: Stop meshing since too many attempts");
  EXPECT_EQ(error("cube.obj", "cube2.obj"), "");
  // Keys.
  auto scene_error = [&](const std::function<void(json&)>& edit) {
    json j = pair_scene("in.obj", "out.obj");
    edit(j);
    return load_error(write_scene(d, j));
  };
  EXPECT_EQ(scene_error([](json& j) { j["mesh"].erase("inner"); }), scene + ": mesh.inner: missing key");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"].erase("outer"); }), scene + ": mesh.outer: missing key");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["outer"] = 3; }), scene + ": mesh.outer: must be a string (value 3)");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["max_edge"] = 0.0; }), scene + ": mesh.max_edge: must be > 0 (value 0.0)");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["mesher"] = "gmsh", j["mesh"]["max_edge"] = 1.0; }),
            scene + ": mesh.max_edge: " + lumen::physics::kGmshMaxEdgeRefused + " (value 1.0)");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["mesher"] = "netgen", j["mesh"]["max_edge"] = 1.0; }), "");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["mesher"] = "tetgen"; }),
            scene + ": mesh.mesher: must be one of auto, gmsh, netgen (value \"tetgen\")");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["optimise_steps"] = 11; }),
            scene + ": mesh.optimise_steps: out of range [0, 10] (value 11)");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["optimise_steps"] = 1.5; }),
            scene + ": mesh.optimise_steps: must be an integer (value 1.5)");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["target_edge"] = -1.0; }),
            scene + ": mesh.target_edge: must be > 0 (value -1.0)");
  EXPECT_NE(scene_error([](json& j) { j["mesh"]["target_edge"] = 1e-5; })
                .find(in + ": mesh.target_edge 1e-05 mm would remesh the surface into about "),
            std::string::npos);
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["thickness"] = 1.0; }), scene + ": mesh.thickness: unknown key");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["units"] = "cm"; }), scene + ": mesh.units: must be one of m, mm (value \"cm\")");
  EXPECT_EQ(scene_error([](json& j) { j["fixed"] = {"ends"}; }),
            scene + ": fixed[0]: the wall between " + in + " and " + out + " is closed and has no end node sets: hold "
            "nodes by {\"box\": ...} or {\"plane\": ...} (value \"ends\")");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["element"] = "tet10"; }), "");  // (10-node tets: straight-sided)
}

// The program on surfaces through each other: exit 2, the message, nothing written.
TEST(SurfacePair, LumenRunExitsTwoAndWritesNothing) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_pair_", "cli");
  write_spheres(d, "in.obj", "shifted.obj", kOuterMm, 6.0);
  std::string text;
  EXPECT_EQ(run_lumen(write_scene(d, pair_scene("in.obj", "shifted.obj")), d / "out", text, " --no-render"), 2) << text;
  EXPECT_NE(text.find("lumen: error: " + (d / "in.obj").string() + " and " + (d / "shifted.obj").string() +
                      ": the surfaces intersect each other"), std::string::npos) << text;
  EXPECT_TRUE(!fs::exists(d / "out") || fs::is_empty(d / "out"));
}

// A short checked session on the sphere pair (self-collision on, one probe pressing): exit 0, no intersecting
// inner-wall pair, and report.json's mesh block says where the mesh came from, the mesher and its time (within the
// build time), with the quality block over the same tets the scene loaded; the terminal's mesh line says so too.
TEST(SurfacePair, ShortCheckedSessionReportsTheMesherAndItsTime) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_pair_", "run");
  write_spheres(d, "in.off", "out.stl");
  const std::string scene = write_scene(d, pair_scene("in.off", "out.stl"));
  const lumen::engine::Scene s = lumen::engine::load_scene(scene);
  std::string text;
  ASSERT_EQ(run_lumen(scene, d / "out", text, " --no-render --check"), 0) << text;
  EXPECT_NE(text.find(" from " + (d / "in.off").string() + " and " + (d / "out.stl").string() +
                      ", tetrahedralised by gmsh 4.8 hxt in "), std::string::npos) << text;
  std::ifstream in(d / "out" / "report.json");
  const json r = json::parse(in);
  const json& m = r["mesh"];
  EXPECT_EQ(m["source"], "surface_pair");
  EXPECT_EQ(m["file"], (d / "in.off").string());
  EXPECT_EQ(m["outer_file"], (d / "out.stl").string());
  EXPECT_EQ(m["mesher"], "gmsh 4.8 hxt");
  EXPECT_GT(m["mesher_ms"].get<double>(), 0.0);
  EXPECT_LE(m["mesher_ms"].get<double>() + m["surface_check_ms"].get<double>(), m["build_ms"].get<double>());
  EXPECT_EQ(m["tets"], s.surface_pair.pair.mesh.tets.rows());
  EXPECT_EQ(m["mesher_added_nodes"], s.surface_pair.pair.added_nodes);
  EXPECT_EQ(m["inner_triangles"], 2 * kInnerRings * kInnerAround);
  EXPECT_EQ(m["outer_triangles"], 2 * kOuterRings * kOuterAround);
  EXPECT_EQ(m["degenerate_tets"], 0);
  EXPECT_GT(m["min_dihedral_deg"]["min"].get<double>(), 0.0);
  EXPECT_EQ(r["frames"], 3);
  EXPECT_EQ(r["frames_with_intersections"], 0);
  EXPECT_EQ(r["numerical_failures"], 0);
  ASSERT_EQ(r["per_frame"].size(), 3u);
  for (const json& f : r["per_frame"]) EXPECT_EQ(f["intersecting_pairs"], 0) << f.dump();
}

// Both spheres (latitude-longitude: slivers at the poles) remeshed to 2 mm edges before gmsh (mesh.target_edge):
// each wall of the tets has about the target's resolution (median edge within 20 %, every angle above 20 degrees,
// unlike the files' poles), the tets are positive and fill the volume between the remeshed walls exactly (the
// divergence theorem over the mesh's own wall triangles), and lumen run reports the target, the files' triangles
// and the remeshing's time, with 0 intersecting pairs on every frame.
TEST(SurfacePair, RemeshedToATargetEdgeBothWallsHaveThatResolution) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_pair_", "remesh");
  write_spheres(d, "in.off", "out.obj");
  json j = pair_scene("in.off", "out.obj");
  j["mesh"]["target_edge"] = 2.0;
  const std::string scene = write_scene(d, j);
  const lumen::engine::Scene s = lumen::engine::load_scene(scene);
  const lumen::physics::TetMesh& mesh = s.surface_pair.pair.mesh;
  EXPECT_GT(s.surface_pair.pair.remesh_ms, 0.0);
  double enclosed_difference = 0.0;
  for (const char* wall : {lumen::physics::kInnerWall, lumen::physics::kOuterWall}) {
    const lumen::Tris& t = mesh.surface(wall);
    const std::vector<double> edges = lumen::test::sorted_side_lengths(mesh.rest, t);
    EXPECT_NEAR(edges[edges.size() / 2], 0.002, 0.0004) << wall;
    EXPECT_GT(lumen::test::sorted_angles_deg(mesh.rest, t).front(), 20.0) << wall;
    // Walls face out of the wall's volume: the outer encloses it positively, the inner (facing the lumen) negatively.
    enclosed_difference += lumen::test::enclosed_volume(mesh.rest, t);
  }
  double tets_volume = 0.0;
  for (Eigen::Index t = 0; t < mesh.tets.rows(); ++t) tets_volume += lumen::physics::tet_volume(mesh.rest, mesh.tets, static_cast<int>(t));
  EXPECT_NEAR(tets_volume, enclosed_difference, 1e-9 * tets_volume);
  EXPECT_EQ(lumen::physics::mesh_quality(mesh.rest, mesh.tets).degenerate_tets, 0);
  std::string text;
  ASSERT_EQ(run_lumen(scene, d / "out", text, " --no-render --check"), 0) << text;
  const int file_triangles = 2 * kInnerRings * kInnerAround + 2 * kOuterRings * kOuterAround;
  EXPECT_NE(text.find(", " + std::to_string(file_triangles) + " file triangles remeshed to a target edge of 2 mm in "),
            std::string::npos) << text;
  std::ifstream in(d / "out" / "report.json");
  const json r = json::parse(in);
  EXPECT_DOUBLE_EQ(r["mesh"]["target_edge_m"].get<double>(), 0.002);
  EXPECT_EQ(r["mesh"]["file_triangles"], file_triangles);
  EXPECT_EQ(r["mesh"]["inner_triangles"], mesh.surface(lumen::physics::kInnerWall).rows());
  EXPECT_EQ(r["frames_with_intersections"], 0);
}

namespace {

// The pair of spheres pressed at +x by a force (newtons, reached at 0.05 s and held) instead of a displacement,
// under that material model, solver type and element: the probe's displacement at the last of `frames` frames.
Eigen::Vector3d pair_probe_displacement(const char* model, const char* solver, double force, int frames,
                                        const char* element) {
  json s = pair_scene("in.off", "out.stl");
  lumen::test::set_model(s, model, solver);
  s["mesh"]["element"] = element;
  s["probes"][0]["track"] = {{{"t", 0.0}, {"force", {0.0, 0.0, 0.0}}}, {{"t", 0.05}, {"force", {-force, 0.0, 0.0}}}};
  s["frames"] = frames;
  s["collision"]["self"] = false;
  const fs::path d = lumen::test::fresh_temp_dir("lumen_pair_", std::string(model) + "_" + solver + "_" + element);
  write_spheres(d, "in.off", "out.stl");
  return lumen::test::last_probe_displacement(lumen::engine::load_scene(write_scene(d, s)));
}

}  // namespace

// Every model on the wall gmsh meshes between two closed surfaces (unstructured tets, not a generated tube): the
// corotational quasi-static answer approaches the linear one to second order as the load shrinks, the dynamic runs
// settle on their quasi-static answers; and the 10-node tets on the same mesh (straight-sided) run with both
// quasi-static models, the corotational again approaching the linear one to second order, and move more than the
// 4-node tets (which lock in bending).
TEST(SurfacePair, EveryModelRunsOnTheWallBetweenTwoSurfaces) {
  constexpr double kForce = 2e-3;
  Eigen::Vector3d linear4;
  lumen::test::expect_every_model_agrees(
      [](const char* model, const char* solver, double force, int frames) {
        return pair_probe_displacement(model, solver, force, frames, "tet4");
      },
      kForce, "surface pair", &linear4);
  const Eigen::Vector3d linear10 = pair_probe_displacement("linear", "quasi_static", kForce, 8, "tet10");
  const Eigen::Vector3d corot10 = pair_probe_displacement("corotational", "quasi_static", kForce, 8, "tet10");
  const Eigen::Vector3d linear10_small = pair_probe_displacement("linear", "quasi_static", 0.1 * kForce, 8, "tet10");
  const Eigen::Vector3d corot10_small =
      pair_probe_displacement("corotational", "quasi_static", 0.1 * kForce, 8, "tet10");
  const double diff = (corot10 - linear10).norm() / linear10.norm();
  const double diff_small = (corot10_small - linear10_small).norm() / linear10_small.norm();
  std::printf("surface pair, tet10 at %.0f mN: linear %.4f mm (tet4 %.4f mm), corotational %.2f %% off (at a tenth "
              "%.3f %%)\n", kForce * 1e3, linear10.norm() * 1e3, linear4.norm() * 1e3, 100.0 * diff,
              100.0 * diff_small);
  EXPECT_GT(linear10.norm(), linear4.norm());
  EXPECT_LT(diff, 0.1);
  EXPECT_NEAR(diff_small / diff, 0.1, 0.05) << diff_small << " vs " << diff;
}

// A probe instrument pressing the wall between two surfaces (unstructured gmsh tets, no ends: the organ's boundary
// is its two walls): the 3 mm sphere tip from 0.5 mm above the outer sphere's top (14 mm) to 2.5 mm into it in 20
// frames, the wall held on its -x cap. The tool never penetrates (exact intersection count, brute-force clearance),
// the wall is pushed in by millimetres, and on every solved contact frame the force on the tool is minus the organ's
// elastic response K u (an independently assembled stiffness) and pushes the tool back up.
TEST(SurfacePair, AnInstrumentPressesTheWallAndNeverPenetrates) {
  constexpr double kGap = 1e-4;
  const fs::path d = lumen::test::fresh_temp_dir("lumen_pair_", "instrument");
  write_spheres(d, "in.off", "out.stl");
  json s = pair_scene("in.off", "out.stl");
  s["probes"] = json::array();
  s["frames"] = 24;
  s["collision"] = {{"self", true}, {"gap", kGap}};
  s["instruments"] = {{{"name", "probe"},
                       {"shape", {{"type", "sphere_probe"}, {"tip_radius", 0.003}, {"shaft_radius", 0.002},
                                  {"shaft_length", 0.04}}},
                       {"track", {{{"t", 0.0}, {"position", {0.0, 0.0145, 0.0}}},
                                  {{"t", 0.5}, {"position", {0.0, 0.0115, 0.0}}}}}}};
  const lumen::test::CheckedRun c = lumen::test::run_checked(lumen::engine::load_scene(write_scene(d, s)));
  const int touching = lumen::test::expect_tool_clear(c, kGap);
  int compared = 0;
  for (size_t i = 0; i < c.result.frames.size(); ++i) {
    const lumen::engine::FrameRecord& f = c.result.frames[i];
    if (f.fallback || f.instruments.empty() || f.instruments[0].contacts == 0) continue;
    ++compared;
    EXPECT_LE((f.instruments[0].force + c.elastic[i].force).norm(), 1e-6 * c.elastic[i].force.norm() + 1e-12)
        << "frame " << f.frame;
    EXPECT_GT(f.instruments[0].force.y(), 0.0) << "frame " << f.frame;
  }
  std::printf("instrument on a surface pair: %d touching frames, %d compared, wall moved %.2f mm\n", touching,
              compared, c.result.frames.back().max_displacement * 1e3);
  EXPECT_GT(touching, 8);
  EXPECT_GT(compared, 8);
  EXPECT_GT(c.result.frames.back().max_displacement, 0.001);
}
