// Organ surfaces as mesh sources: a swept tube's radius sampled from a surface (mesh.radius {"from_surface"}) and
// a wall grown from a closed surface (mesh.type "surface_wall"): analytic radii and volumes, every refusal by its
// message, the real aneurysm grown intersection-free and the CT colon refused, and the program's exit code.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "collision/intersect.hpp"
#include "engine/scene.hpp"
#include "engine/simulation.hpp"
#include "engine/surface_radius.hpp"
#include "engine/wall_growth.hpp"
#include "physics/mesh_quality.hpp"
#include "support/files.hpp"
#include "support/model_runs.hpp"
#include "support/scene_files.hpp"
#include "support/sphere.hpp"
#include "support/surface_measures.hpp"
#include "support/build.hpp"

namespace fs = std::filesystem;
using lumen::engine::InputError;
using nlohmann::json;

namespace {

using lumen::test::kPi;
// assimp reads positions as single-precision floats: a point's distance from the origin is off by up to two float
// roundings (2 x 2^-24 relative).
constexpr double kFloatRounding = 1.2e-7;
const std::string kOrgans = std::string(LUMEN_SOURCE_DIR) + "/data/organs/";

// An OBJ file of vertices and 0-based triangles.
void write_obj(const fs::path& file, const std::vector<Eigen::Vector3d>& v, const std::vector<std::array<int, 3>>& f) {
  std::ofstream out(file);
  out.precision(17);
  for (const auto& p : v) out << "v " << p.x() << " " << p.y() << " " << p.z() << "\n";
  for (const auto& t : f) out << "f " << t[0] + 1 << " " << t[1] + 1 << " " << t[2] + 1 << "\n";
}

// A closed cone frustum about the z axis from z0 to z1 (radius r0 + slope (z - z0)), `around` sides, `along`
// bands, flat end caps fanned from their centres (the z0 cap's centre at x = cap_x on its plane); outward.
void write_cone(const fs::path& file, double z0, double z1, double r0, double slope, int around, int along,
                double cap_x = 0.0) {
  std::vector<Eigen::Vector3d> v = {{cap_x, 0, z0}, {0, 0, z1}};
  for (int k = 0; k <= along; ++k) {
    const double z = z0 + (z1 - z0) * k / along, r = r0 + slope * (z - z0);
    for (int i = 0; i < around; ++i) v.emplace_back(r * std::cos(2 * kPi * i / around), r * std::sin(2 * kPi * i / around), z);
  }
  auto id = [&](int k, int i) { return 2 + k * around + i % around; };
  std::vector<std::array<int, 3>> f;
  for (int i = 0; i < around; ++i) {
    f.push_back({0, id(0, i + 1), id(0, i)});
    f.push_back({1, id(along, i), id(along, i + 1)});
    for (int k = 0; k < along; ++k) {
      f.push_back({id(k, i), id(k, i + 1), id(k + 1, i + 1)});
      f.push_back({id(k, i), id(k + 1, i + 1), id(k + 1, i)});
    }
  }
  write_obj(file, v, f);
}

// A latitude-longitude sphere of radius r (mm) about the origin (tests/support/sphere.hpp) as an OBJ file.
void write_sphere(const fs::path& file, double r, int rings, int around) {
  lumen::test::TubePoints x;
  lumen::test::TubeTris t;
  lumen::test::make_uv_sphere(r, rings, around, x, t);
  std::vector<Eigen::Vector3d> v;
  for (Eigen::Index i = 0; i < x.rows(); ++i) v.emplace_back(x.row(i).transpose());
  std::vector<std::array<int, 3>> f;
  for (Eigen::Index i = 0; i < t.rows(); ++i) f.push_back({t(i, 0), t(i, 1), t(i, 2)});
  write_obj(file, v, f);
}

// A closed octahedron (vertices on the axes, 1 unit from the origin), outward.
const std::string kOctahedron =
    "v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n"
    "f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n";

// A straight centreline along +z from 0 to 100 (file units).
json straight_line() {
  json c;
  for (int k = 0; k <= 10; ++k) c["points"].push_back({0.0, 0.0, 10.0 * k});
  return c;
}

// A swept tube in millimetres along line.json with its radius from surf.obj.
json from_surface_scene(double range_stop) {
  json s = json::parse(R"({
    "name": "from-surface",
    "mesh": {"type": "swept_tube", "centreline": "line.json", "units": "mm", "range": [20.0, 80.0],
             "radius": {"from_surface": "surf.obj"}, "wall_thickness": 2.0, "segments_around": 12,
             "segment_length": 5.0, "layers": 1},
    "material": {"model": "linear", "young_modulus": 5000.0, "poisson_ratio": 0.45},
    "fixed": ["ends"], "probes": [], "frames": 2, "fps": 40
  })");
  s["mesh"]["range"][1] = range_stop;
  return s;
}

// A surface wall over the file `surface` (millimetres).
json wall_scene(const std::string& surface, double thickness, const char* direction) {
  json s = json::parse(R"({
    "name": "wall",
    "mesh": {"type": "surface_wall", "units": "mm", "layers": 1},
    "material": {"model": "linear", "young_modulus": 5000.0, "poisson_ratio": 0.45},
    "fixed": [{"plane": {"point": [0, 0, 0], "normal": [0, 0, -1]}}], "probes": [], "frames": 2, "fps": 40
  })");
  s["mesh"]["surface"] = surface;
  s["mesh"]["thickness"] = thickness;
  s["mesh"]["direction"] = direction;
  return s;
}

using lumen::test::load_error;
using lumen::test::run_lumen;
using lumen::test::write_scene;

}  // namespace

// A cone of known radius profile (6 mm at z = 0 widening by 0.05 a mm, 48 sides): at every ring the sampled
// radius lies between the polygon's inradius and circumradius of the analytic circle at that height (rays meet the
// 48-gon between r cos(pi / 48) and r; assimp holds positions as floats), smoothing kept it there (a linear profile is unchanged by it), and the
// tube is meshed with those radii.
TEST(SurfaceRadius, ConeProfileIsTheAnalyticRadiusWithinThePolygonError) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_organ_", "cone");
  std::ofstream(d / "line.json") << straight_line().dump();
  const int around = 48;
  write_cone(d / "surf.obj", 0.0, 100.0, 6.0, 0.05, around, 10);
  const lumen::engine::Scene s = lumen::engine::load_scene(write_scene(d, from_surface_scene(80.0)));
  EXPECT_EQ(s.radius_surface, (d / "surf.obj").string());
  const auto& profile = s.swept_tube.radius_profile;
  ASSERT_EQ(profile.size(), 13u);  // rings every 5 mm over 20..80 mm
  for (size_t j = 0; j < profile.size(); ++j) {
    const double r = 0.006 + 0.05 * profile[j].s;  // metres: the cone's radius at z = s
    EXPECT_NEAR(profile[j].s, 0.02 + 0.005 * j, 1e-15);
    EXPECT_LE(profile[j].r, r * (1 + kFloatRounding)) << j;
    EXPECT_GE(profile[j].r, r * std::cos(kPi / around) * (1 - kFloatRounding)) << j;
  }
  const auto model = lumen::engine::compile_model(s);
  EXPECT_EQ(model->mesh_file, (d / "surf.obj").string());
  const lumen::physics::SweptTube tube = lumen::physics::make_swept_tube(s.swept_tube);
  EXPECT_EQ(tube.clamped_rings, 0);
  for (size_t j = 0; j < tube.rings.size(); ++j) EXPECT_DOUBLE_EQ(tube.rings[j].inner_radius, profile[j].r);
}

// Bad input names the file, the problem and the ring: a missing file, an unsupported format, a ring past the
// surface's end (its plane misses the surface), an open surface; the keys of mesh.radius.
TEST(SurfaceRadius, RefusesBadSurfacesNamingFileProblemAndRing) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_organ_", "radius_bad");
  std::ofstream(d / "line.json") << straight_line().dump();
  write_cone(d / "surf.obj", 10.0, 90.0, 6.0, 0.0, 24, 8);
  json scene = from_surface_scene(80.0);
  EXPECT_EQ(load_error(write_scene(d, scene)), "");
  // Rings every 60 / 12 = 5 mm ... with the range to 97 mm: 16 steps of 4.8125 mm, ring 15 at 92.19 mm is past z = 90.
  EXPECT_EQ(load_error(write_scene(d, from_surface_scene(97.0))),
            (d / "surf.obj").string() + ": ring 15 (arc length 0.0921875 m, centreline point [0, 0, 0.0921875] m): its "
            "plane misses the surface: 0 of 16 rays from the centreline meet it from inside (at least 9 needed)");
  scene["mesh"]["radius"]["from_surface"] = "missing.obj";
  EXPECT_EQ(load_error(write_scene(d, scene)), (d / "missing.obj").string() + ": no such surface file");
  std::ofstream(d / "surf.xyz") << "0 0 0\n";
  scene["mesh"]["radius"]["from_surface"] = "surf.xyz";
  EXPECT_EQ(load_error(write_scene(d, scene)),
            (d / "surf.xyz").string() + ": unsupported surface format \".xyz\" (OBJ, STL, PLY or OFF)");
  std::ofstream(d / "open.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\n";
  scene["mesh"]["radius"]["from_surface"] = "open.obj";
  EXPECT_NE(load_error(write_scene(d, scene)).find((d / "open.obj").string() + ": not closed: edge between vertex "),
            std::string::npos) << load_error(write_scene(d, scene));
  scene["mesh"]["radius"] = json::parse(R"({"from_surface": "surf.obj", "rays": 8})");
  EXPECT_EQ(load_error(write_scene(d, scene)), (d / "s.json").string() + ": mesh.radius.rays: unknown key");
  scene["mesh"]["radius"] = json::object();
  EXPECT_EQ(load_error(write_scene(d, scene)), (d / "s.json").string() + ": mesh.radius.from_surface: missing key");
  scene["mesh"]["radius"]["from_surface"] = 5;
  EXPECT_EQ(load_error(write_scene(d, scene)),
            (d / "s.json").string() + ": mesh.radius.from_surface: must be a string (value 5)");
}

// The program on a ring that misses the surface: exit 2, the message, nothing written.
TEST(SurfaceRadius, LumenRunExitsTwoAndWritesNothing) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_organ_", "radius_cli");
  std::ofstream(d / "line.json") << straight_line().dump();
  write_cone(d / "surf.obj", 10.0, 90.0, 6.0, 0.0, 24, 8);
  std::string text;
  EXPECT_EQ(run_lumen(write_scene(d, from_surface_scene(97.0)), d / "out", text), 2) << text;
  EXPECT_NE(text.find("lumen: error: " + (d / "surf.obj").string() + ": ring 15 "), std::string::npos) << text;
  EXPECT_TRUE(!fs::exists(d / "out") || fs::is_empty(d / "out"));
}

// The shipped sigmoid segment with its radius from the CT colon's surface: every ring has a radius (no ring's plane
// misses the surface), the inner wall has no intersecting triangle pair by the exact check; the radii and the time
// are printed.
TEST(SurfaceRadius, ColonSegmentFromTheCtSurfaceIsIntersectionFree) {
  const auto t0 = std::chrono::steady_clock::now();
  const lumen::engine::Scene scene =
      lumen::engine::load_scene(std::string(LUMEN_SOURCE_DIR) + "/scenes/colon-sigmoid-surface-pinch.json");
  const double load_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  const lumen::physics::SweptTube tube = lumen::physics::make_swept_tube(scene.swept_tube);
  EXPECT_EQ(lumen::collision::count_intersecting_pairs(tube.mesh.rest, tube.mesh.surface(lumen::physics::kInnerWall)), 0);
  std::vector<double> r;
  for (const auto& k : scene.swept_tube.radius_profile) r.push_back(1e3 * k.r);
  ASSERT_EQ(r.size(), tube.rings.size());
  std::sort(r.begin(), r.end());
  std::printf("colon sigmoid from surface: %zu rings, sampled radius min %.2f mm, median %.2f, max %.2f; %d rings "
              "clamped; scene load (surface read and sampled) %.1f ms, sampling %.1f ms\n",
              r.size(), r.front(), r[r.size() / 2], r.back(), tube.clamped_rings, load_ms, scene.mesh_load_ms);
}

// A sphere of 10 mm grown 1 mm outward and inward: the wall's volume (the tets') is the analytic shell's,
// 4/3 pi ((R + t)^3 - R^3) and 4/3 pi (R^3 - (R - t)^3), within twice the polyhedron's own volume deficit against
// its sphere (the discretisation error, measured on the input), and every vertex's wall is t thick radially within
// 1 % (the smoothed normals tilt from the radius by at most the latitude step); no offset is clamped (the gap
// along the normal is the sphere's diameter, or none outward).
TEST(SurfaceWall, SphereShellHasTheAnalyticVolumeAndThickness) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_organ_", "sphere");
  const double R = 0.01, t = 0.001;
  write_sphere(d / "ball.obj", 10.0, 15, 32);
  const lumen::engine::SurfaceMesh ball = lumen::engine::read_closed_surface((d / "ball.obj").string(), 1e-3);
  const double deficit = 1.0 - lumen::engine::enclosed_volume(ball) / (4.0 / 3.0 * kPi * R * R * R);
  EXPECT_GT(deficit, 0.0);
  for (const char* dir : {"outward", "inward"}) {
    const lumen::engine::Scene s = lumen::engine::load_scene(write_scene(d, wall_scene("ball.obj", 1.0, dir)));
    const lumen::engine::SurfaceWall& w = s.surface_wall.wall;
    const bool out = std::string(dir) == "outward";
    const double exact = 4.0 / 3.0 * kPi * (out ? std::pow(R + t, 3) - R * R * R : R * R * R - std::pow(R - t, 3));
    double volume = 0.0;
    for (int k = 0; k < w.mesh.tets.rows(); ++k) volume += lumen::physics::tet_volume(w.mesh.rest, w.mesh.tets, k);
    EXPECT_NEAR(volume / exact, 1.0, 2.0 * deficit) << dir;
    EXPECT_EQ(w.clamped_vertices, 0) << dir;
    EXPECT_EQ(w.shrink_rounds, 0) << dir;
    const Eigen::Index nv = w.vertices;
    for (Eigen::Index v = 0; v < nv; ++v) {
      const double thick = std::abs(w.mesh.rest.row(nv + v).norm() - w.mesh.rest.row(v).norm());
      EXPECT_NEAR(thick, t, 0.01 * t) << dir << " vertex " << v;
    }
    // The input is the inner wall outward, the outer wall inward.
    const auto& input_wall = w.mesh.surface(out ? lumen::physics::kInnerWall : lumen::physics::kOuterWall);
    EXPECT_NEAR(w.mesh.rest.row(input_wall(0, 0)).norm(), R, kFloatRounding * R);
  }
}

// A closed box [-a, a] x [-b, b] x [-c, c] (file units), each face an n x n grid of cells split in two, outward.
void write_box(const fs::path& file, double a, double b, double c, int n) {
  std::vector<Eigen::Vector3d> v;
  std::map<std::array<long, 3>, int> index;  // grid coordinates (0..n per axis) -> vertex
  auto vertex = [&](std::array<long, 3> g) {
    const auto [it, added] = index.emplace(g, static_cast<int>(v.size()));
    if (added) v.emplace_back(a * (2.0 * g[0] / n - 1.0), b * (2.0 * g[1] / n - 1.0), c * (2.0 * g[2] / n - 1.0));
    return it->second;
  };
  std::vector<std::array<int, 3>> f;
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      const int u = (axis + 1) % 3, w = (axis + 2) % 3;  // (u, w, axis) right-handed
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
          std::array<long, 3> g[4];
          const int di[4] = {0, 1, 1, 0}, dj[4] = {0, 0, 1, 1};
          for (int k = 0; k < 4; ++k) {
            g[k][axis] = side ? n : 0;
            g[k][u] = i + di[k];
            g[k][w] = j + dj[k];
          }
          int q[4];
          for (int k = 0; k < 4; ++k) q[k] = vertex(g[k]);
          // Counter-clockwise about +axis on the far side, clockwise on the near one: outward either way.
          if (side) f.push_back({q[0], q[1], q[2]}), f.push_back({q[0], q[2], q[3]});
          else f.push_back({q[0], q[2], q[1]}), f.push_back({q[0], q[3], q[2]});
        }
    }
  write_obj(file, v, f);
}

// The gap clamp against a slab's own thickness. A 40 x 40 x 4 mm box grown 2 mm inward: the rays from the broad
// faces meet the opposite face 4 mm away, so their vertices are clamped to kWallGapFraction of that, 1.8 mm, above
// half the thickness: the wall is built, thinner there, and counts them (the rim's, crowded by the side walls'
// offsets, are shrunk further). Grown 5 mm inward it would be clamped to
// the same 1.8 mm, under half of 5: refused, naming the file, the thinnest vertex and its room; lumen run exits 2
// and writes nothing.
TEST(SurfaceWall, GapClampThinsAWallAndRefusesOneThickerThanTheGapsAllow) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_organ_", "slab_gap");
  write_box(d / "slab.obj", 20.0, 20.0, 2.0, 20);
  const double room = lumen::engine::kWallGapFraction * 0.004;  // the clamp across the slab, metres
  const lumen::engine::Scene s = lumen::engine::load_scene(write_scene(d, wall_scene("slab.obj", 2.0, "inward")));
  const lumen::engine::SurfaceWall& w = s.surface_wall.wall;
  // The broad faces' vertices away from the rim (|x|, |y| <= 10 mm, beyond the normal smoothing's reach from the
  // rim's turned normals): along -z or +z, 1.8 mm. (Grown inward, the
  // offset is the inner wall: rows [0, nv) of the mesh, the file's surface rows [nv, 2 nv).)
  const Eigen::Index nv = w.vertices;
  int broad = 0;
  for (Eigen::Index v = 0; v < nv; ++v) {
    const Eigen::RowVector3d x = w.mesh.rest.row(nv + v), y = w.mesh.rest.row(v);
    if (std::abs(std::abs(x.z()) - 0.002) > 1e-9 || std::abs(x.x()) > 0.0101 || std::abs(x.y()) > 0.0101) continue;
    ++broad;
    EXPECT_NEAR((y - x).norm(), room, 1e-9) << "vertex " << v << " at " << x;
    EXPECT_NEAR(std::abs(y.z()), 0.002 - room, 1e-9) << "vertex " << v;
  }
  EXPECT_EQ(broad, 2 * 11 * 11);
  EXPECT_GE(w.clamped_vertices, broad);
  EXPECT_LE(w.min_offset, room);  // (less at the rim, where the offsets were shrunk apart)
  // Too thick: refused, the room named in millimetres.
  const std::string scene = write_scene(d, wall_scene("slab.obj", 5.0, "inward"));
  const std::string msg = load_error(scene);
  const std::string head = (d / "slab.obj").string() + ": a wall of 5 mm grown inward is thicker than the surface's "
                           "gaps allow: at vertex ";
  ASSERT_NE(msg.find(head), std::string::npos) << msg;
  const size_t at = msg.find("leaves room for ");
  ASSERT_NE(at, std::string::npos) << msg;
  EXPECT_LE(std::stod(msg.substr(at + 16)) * 1e-3, room * (1.0 + 1e-6)) << msg;
  EXPECT_NE(msg.find(" vertices get less than half the thickness); make mesh.thickness smaller, or for a tubular "
                     "organ sweep a tube"), std::string::npos) << msg;
  std::string text;
  EXPECT_EQ(run_lumen(scene, d / "out", text), 2) << text;
  EXPECT_NE(text.find(head), std::string::npos) << text;
  EXPECT_TRUE(!fs::exists(d / "out") || fs::is_empty(d / "out"));
}

namespace {

// The probe's displacement at the last of `frames` frames of a 1 mm wall grown outward from a 10 mm sphere, held
// below its equator, pressed at its top pole (0, 0, 11 mm) along -z with `force` newtons (reached at 0.1 s and
// held), with that material model and solver type.
Eigen::Vector3d shell_probe_displacement(const fs::path& d, const char* model, const char* solver, double force,
                                         int frames) {
  json s = wall_scene("ball.obj", 1.0, "outward");
  lumen::test::set_model(s, model, solver);
  s["material"]["density"] = 1050.0;
  s["probes"] = json::parse(R"([{"point": [0.0, 0.0, 0.011], "track": [{"t": 0.0, "force": [0, 0, 0]}]}])");
  s["probes"][0]["track"].push_back({{"t", 0.1}, {"force", {0.0, 0.0, -force}}});
  s["frames"] = frames;
  return lumen::test::last_probe_displacement(lumen::engine::load_scene(write_scene(d, s)));
}

}  // namespace

// Every model on a surface wall (a 1 mm shell grown from a sphere, held below its equator, pressed at its pole):
// the corotational quasi-static answer approaches the linear one to second order as the load shrinks (10x less
// load: about 10x less relative difference), and the dynamic runs settle on their quasi-static answers.
TEST(SurfaceWall, EveryModelRunsOnAGrownWall) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_organ_", "shell_models");
  write_sphere(d / "ball.obj", 10.0, 15, 32);
  Eigen::Vector3d linear = Eigen::Vector3d::Zero();
  lumen::test::expect_every_model_agrees(
      [&](const char* model, const char* solver, double force, int frames) {
        return shell_probe_displacement(d, model, solver, force, frames);
      },
      1e-3, "sphere shell", &linear);
  EXPECT_LT(linear.z(), 0.0);  // pressed in
}

// Every refusal of a surface wall, one message each naming the file (or the scene's key), the problem and where.
TEST(SurfaceWall, RefusesBadSurfacesNamingFileProblemAndWhere) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_organ_", "wall_bad");
  const std::string tet = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n";
  auto error = [&](const std::string& name, const std::string& obj) {
    std::ofstream(d / name) << obj;
    return load_error(write_scene(d, wall_scene(name, 0.1, "outward")));
  };
  const std::string f = (d / "x.obj").string();
  // An octahedron grows (a tetrahedron's corners are too sharp for its vertex normals); the rest are refused.
  EXPECT_EQ(error("x.obj", kOctahedron), "");
  EXPECT_EQ(error("x.obj", tet + "f 1 3 2\nf 1 2 4\nf 2 3 4\n"),
            f + ": not closed: edge between vertex 0 at [0, 0, 0] and vertex 1 at [0, 0.001, 0] belongs to triangle 0 only");
  EXPECT_EQ(error("x.obj", tet + "f 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 3 4\n"),
            f + ": inconsistent orientation: triangles 0, 3 run the edge between vertex 0 at [0, 0, 0] and vertex 1 "
            "at [0, 0.001, 0] the same way");
  EXPECT_NE(error("x.obj", tet + "v 0.5 0 0\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\nf 1 5 2\n")
                .find(f + ": triangle 4 is degenerate (area 0 m^2): vertex 0 at [0, 0, 0], "), std::string::npos);
  // Two tetrahedra sharing one edge (0-1): four triangles on it.
  EXPECT_NE(error("x.obj", tet + "v 0 -1 0\nv 0 0 -1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\n"
                              "f 1 5 2\nf 1 2 6\nf 2 5 6\nf 1 6 5\n")
                .find(f + ": non-manifold edge between vertex 0 at [0, 0, 0] and vertex 2 at [0.001, 0, 0]: shared by 4 "
                          "triangles (0, 1, 4, 5)"),
            std::string::npos);
  // Two closed tetrahedra, the second through the first.
  EXPECT_EQ(error("x.obj", tet + "v 0.2 0.2 -0.5\nv 1.2 0.2 -0.5\nv 0.2 1.2 -0.5\nv 0.2 0.2 0.5\n"
                              "f 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\nf 5 7 6\nf 5 6 8\nf 6 7 8\nf 5 8 7\n"),
            f + ": the surface intersects itself: triangles 0 and 5 intersect (3 intersecting pairs)");
  // A closed tetrahedron: its corners turn too sharply for a wall along vertex normals. Outward, the prisms over
  // its faces stay inverted however far the offsets shrink; inward, the offset wall crosses the surface.
  const std::string closed_tet = tet + "f 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\n";
  EXPECT_EQ(error("x.obj", closed_tet),
            f + ": a wall of 0.1 mm grown outward has an inverted or zero-volume prism over triangle 0 after 8 rounds "
                "of shrinking the offset around them (3 such triangles): the surface turns too sharply there for its "
                "vertex normals");
  // The thickness in the scene's units: the same tetrahedron a thousand times larger, in metres.
  std::ofstream(d / "tet_m.obj") << closed_tet;
  lumen::engine::SurfaceWallSpec in_metres;
  in_metres.file = (d / "tet_m.obj").string();
  in_metres.thickness = 0.1;
  EXPECT_EQ(lumen::test::message_of<InputError>([&] { lumen::engine::grow_surface_wall(in_metres); }),
            in_metres.file + ": a wall of 0.1 m grown outward has an inverted or zero-volume prism over triangle 0 "
                             "after 8 rounds of shrinking the offset around them (3 such triangles): the surface turns "
                             "too sharply there for its vertex normals");
  EXPECT_EQ(load_error(write_scene(d, wall_scene("x.obj", 0.1, "inward"))),
            f + ": a wall of 0.1 mm grown inward cannot be made intersection-free: triangle 0 of the surface and "
                "triangle 0 of the offset wall still intersect after 8 rounds of shrinking the offset around them (12 "
                "intersecting pairs; offsetting along vertex normals fails where the surface folds more sharply than "
                "the wall is thick: for a tubular organ, sweep a tube along its centreline with the radius from the "
                "surface, mesh.type \"swept_tube\" with mesh.radius {\"from_surface\": ...})");
  EXPECT_EQ(error("missing.obj", tet).empty(), false);
  fs::remove(d / "missing.obj");
  EXPECT_EQ(load_error(write_scene(d, wall_scene("missing.obj", 0.1, "outward"))), (d / "missing.obj").string() + ": no such surface file");
  EXPECT_EQ(error("x.dae", tet), (d / "x.dae").string() + ": unsupported surface format \".dae\" (OBJ, STL, PLY or OFF)");
  std::ofstream(d / "x.obj") << kOctahedron;
  const std::string scene = (d / "s.json").string();
  EXPECT_EQ(load_error(write_scene(d, wall_scene("x.obj", 0.0, "outward"))), scene + ": mesh.thickness: must be > 0 (value 0.0)");
  EXPECT_EQ(load_error(write_scene(d, wall_scene("x.obj", -0.5, "outward"))), scene + ": mesh.thickness: must be > 0 (value -0.5)");
  EXPECT_EQ(load_error(write_scene(d, wall_scene("x.obj", 0.1, "out"))),
            scene + ": mesh.direction: must be one of inward, outward (value \"out\")");
  // Every key of mesh by its message: missing, of the wrong type, out of range, unknown; and what a closed wall
  // cannot be combined with.
  auto scene_error = [&](const std::function<void(json&)>& edit) {
    json j = wall_scene("x.obj", 0.1, "outward");
    edit(j);
    return load_error(write_scene(d, j));
  };
  EXPECT_EQ(scene_error([](json& j) { j["mesh"].erase("surface"); }), scene + ": mesh.surface: missing key");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["surface"] = 3; }), scene + ": mesh.surface: must be a string (value 3)");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"].erase("thickness"); }), scene + ": mesh.thickness: missing key");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["thickness"] = "thick"; }),
            scene + ": mesh.thickness: must be a number (value \"thick\")");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"].erase("direction"); }), scene + ": mesh.direction: missing key");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["layers"] = 0; }), scene + ": mesh.layers: out of range [1, 256] (value 0)");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["layers"] = 1.5; }), scene + ": mesh.layers: must be an integer (value 1.5)");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["target_edge"] = 0.0; }),
            scene + ": mesh.target_edge: must be > 0 (value 0.0)");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["target_edge"] = "fine"; }),
            scene + ": mesh.target_edge: must be a number (value \"fine\")");
  // A target edge that would remesh the surface into too many triangles (the octahedron's 8 mm² into ~10^11).
  EXPECT_NE(scene_error([](json& j) { j["mesh"]["target_edge"] = 1e-5; })
                .find((d / "x.obj").string() + ": mesh.target_edge 1e-05 mm would remesh the surface into about "),
            std::string::npos);
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["units"] = "cm"; }),
            scene + ": mesh.units: must be one of m, mm (value \"cm\")");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["radius"] = 5; }), scene + ": mesh.radius: unknown key");
  EXPECT_EQ(scene_error([](json& j) { j["mesh"]["element"] = "tet10"; }), "");  // (10-node tets: straight-sided)
  // The growth's own checks, for a caller that fills the spec (the scene reader refuses these first).
  lumen::engine::SurfaceWallSpec spec;
  spec.file = (d / "x.obj").string();
  spec.thickness = 0.0001;
  spec.layers = 0;
  EXPECT_EQ(lumen::test::message_of<InputError>([&] { lumen::engine::grow_surface_wall(spec); }),
            spec.file + ": the wall needs at least 1 layer (value 0)");
  json named = wall_scene("x.obj", 0.1, "outward");
  named["fixed"] = {"ends"};
  EXPECT_EQ(load_error(write_scene(d, named)), scene + ": fixed[0]: the wall grown from " + (d / "x.obj").string() +
                                                   " is closed and has no end node sets: hold nodes by {\"box\": ...} "
                                                   "or {\"plane\": ...} (value \"ends\")");
}

// The program on an open surface and on a PLY file with a bad header: exit 2, the message, nothing written.
TEST(SurfaceWall, LumenRunExitsTwoAndWritesNothing) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_organ_", "wall_cli");
  std::ofstream(d / "open.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\n";
  std::string text;
  EXPECT_EQ(run_lumen(write_scene(d, wall_scene("open.obj", 0.1, "outward")), d / "out", text), 2) << text;
  EXPECT_NE(text.find("lumen: error: " + (d / "open.obj").string() + ": not closed: edge between"), std::string::npos) << text;
  EXPECT_TRUE(!fs::exists(d / "out") || fs::is_empty(d / "out"));
  // A PLY file with a bad header: refused by its line before assimp reads it.
  std::ofstream(d / "bad.ply") << "ply\nformat ascii 1.0\nelement vertex three\nproperty float x\nend_header\n";
  text.clear();
  EXPECT_EQ(run_lumen(write_scene(d, wall_scene("bad.ply", 0.1, "outward")), d / "out", text), 2) << text;
  EXPECT_NE(text.find("lumen: error: " + (d / "bad.ply").string() + ": PLY header line 3: must be \"element NAME "
                      "COUNT\" with COUNT an integer in [0, 2147483647] (\"element vertex three\")"),
            std::string::npos)
      << text;
  EXPECT_TRUE(!fs::exists(d / "out") || fs::is_empty(d / "out"));
}

// The real aneurysm (SOFA's aneurysm3D_1, 14,186 triangles) grown 0.5 mm outward: both walls together have no
// intersecting triangle pair by the exact check, every tet is positive; the build time and quality are printed.
TEST(SurfaceWall, AneurysmGrownHalfAMillimetreOutwardIsIntersectionFree) {
  lumen::engine::SurfaceWallSpec spec;
  spec.file = kOrgans + "sofa-aneurysm3D_1.off";
  spec.metres_per_unit = 1e-3;
  spec.thickness = 0.0005;
  const auto t0 = std::chrono::steady_clock::now();
  const lumen::engine::SurfaceWall w = lumen::engine::grow_surface_wall(spec);
  const double load_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(w.triangles, 14186);
  EXPECT_EQ(w.mesh.tets.rows(), 3 * 14186);
  lumen::Tris both(2 * w.triangles, 3);
  both.topRows(w.triangles) = w.mesh.surface(lumen::physics::kInnerWall);
  both.bottomRows(w.triangles) = w.mesh.surface(lumen::physics::kOuterWall);
  EXPECT_EQ(lumen::collision::count_intersecting_pairs(w.mesh.rest, both), 0);
  const lumen::physics::MeshQuality q = lumen::physics::mesh_quality(w.mesh.rest, w.mesh.tets);
  EXPECT_EQ(q.degenerate_tets, 0);
  // The inner wall is the surface as read, but for the vertices moved to untangle a planar fold-over (the file has
  // one: a sliver folded back on a flat end cap), a few at most.
  const lumen::engine::SurfaceMesh read = lumen::engine::read_closed_surface(spec.file, spec.metres_per_unit);
  int moved = 0;
  for (Eigen::Index v = 0; v < read.points.rows(); ++v) moved += (w.mesh.rest.row(v) != read.points.row(v));
  EXPECT_LE(moved, 10);
  EXPECT_GT(moved, 0);
  EXPECT_EQ(w.untangled_vertices, moved);
  std::printf("aneurysm 0.5 mm outward: %d vertices, %d triangles, %d tets; grown in %.1f ms (read, checks and growth "
              "%.1f ms); %d vertices clamped, %d shrink rounds, thinnest %.3f mm; min dihedral %.2f deg (p1 %.2f, "
              "median %.2f), radius ratio min %.4f (median %.3f); %d vertices moved to untangle fold-overs\n",
              w.vertices, w.triangles, static_cast<int>(w.mesh.tets.rows()), w.grow_ms, load_ms, w.clamped_vertices,
              w.shrink_rounds, 1e3 * w.min_offset, q.min_dihedral_deg.min, q.min_dihedral_deg.p1,
              q.min_dihedral_deg.p50, q.radius_ratio.min, q.radius_ratio.p50, moved);
}

// The aneurysm remeshed to 1 mm edges (mesh.target_edge) before growing 0.5 mm outward: about a fifth of the file's
// 14,186 triangles, the inner wall's median edge within 20 % of the target, its smallest angle over twice the
// file's (13.6 against 2.6 degrees: the remeshing removes the file's slivers; creases sharper than 60 degrees are
// kept, so it does not reach the sphere's 30) and 99 % of its angles above 30 degrees, both walls together free of intersecting pairs by the exact check, every tet
// positive; lumen run says so on the mesh line and in report.json (mesh.target_edge_m, file_triangles, remesh_ms).
TEST(SurfaceWall, AneurysmRemeshedToATargetEdgeGrowsAnIntersectionFreeWall) {
  lumen::engine::SurfaceWallSpec spec;
  spec.file = kOrgans + "sofa-aneurysm3D_1.off";
  spec.metres_per_unit = 1e-3;
  spec.thickness = 0.0005;
  spec.target_edge = 0.001;
  const lumen::engine::SurfaceWall w = lumen::engine::grow_surface_wall(spec);
  EXPECT_EQ(w.file_triangles, 14186);
  EXPECT_GT(w.triangles, 14186 / 10);
  EXPECT_LT(w.triangles, 14186 / 3);
  EXPECT_GT(w.remesh_ms, 0.0);
  const lumen::Tris& inner = w.mesh.surface(lumen::physics::kInnerWall);
  const std::vector<double> edges = lumen::test::sorted_side_lengths(w.mesh.rest, inner);
  const std::vector<double> angles = lumen::test::sorted_angles_deg(w.mesh.rest, inner);
  const lumen::engine::SurfaceMesh read = lumen::engine::read_closed_surface(spec.file, spec.metres_per_unit);
  const std::vector<double> file_angles = lumen::test::sorted_angles_deg(read.points, read.tris);
  EXPECT_NEAR(edges[edges.size() / 2], spec.target_edge, 0.2 * spec.target_edge);
  EXPECT_GT(angles.front(), 2.0 * file_angles.front());
  EXPECT_GT(angles[angles.size() / 100], 30.0);
  lumen::Tris both(2 * w.triangles, 3);
  both.topRows(w.triangles) = inner;
  both.bottomRows(w.triangles) = w.mesh.surface(lumen::physics::kOuterWall);
  EXPECT_EQ(lumen::collision::count_intersecting_pairs(w.mesh.rest, both), 0);
  EXPECT_EQ(lumen::physics::mesh_quality(w.mesh.rest, w.mesh.tets).degenerate_tets, 0);
  std::printf("aneurysm remeshed to 1 mm: %d -> %d triangles in %.1f ms, median edge %.3f mm, angles min %.1f p1 %.1f "
              "deg (the file's: %.1f, %.1f)\n",
              w.file_triangles, w.triangles, w.remesh_ms, 1e3 * edges[edges.size() / 2], angles.front(),
              angles[angles.size() / 100], file_angles.front(), file_angles[file_angles.size() / 100]);
  // lumen run: the mesh line and report.json.
  const fs::path d = lumen::test::fresh_temp_dir("lumen_organ_", "remesh");
  json scene = wall_scene(spec.file, 0.5, "outward");
  scene["mesh"]["target_edge"] = 1.0;
  scene["fixed"] = json::parse(R"([{"plane": {"point": [0.0, -0.0165, 0.0], "normal": [0.0, -1.0, 0.0]}}])");
  scene["frames"] = 1;
  const fs::path out = d / "out";
  std::string text;
  ASSERT_EQ(run_lumen(write_scene(d, scene), out, text, " --no-render"), 0) << text;
  EXPECT_NE(text.find(", 14186 file triangles remeshed to a target edge of 1 mm in "), std::string::npos) << text;
  std::ifstream in(out / "report.json");
  const json report = json::parse(in);
  EXPECT_EQ(report["mesh"]["file_triangles"], 14186) << report["mesh"].dump();
  EXPECT_DOUBLE_EQ(report["mesh"]["target_edge_m"].get<double>(), 0.001) << report["mesh"].dump();
  EXPECT_EQ(report["mesh"]["inner_triangles"], w.triangles) << report["mesh"].dump();
}

// A planar fold-over: a cone's flat end cap fanned from a centre moved in the cap's plane 1.5 radii out, past the
// rim, so the fan triangles next to it fold back over their neighbours. The growth moves that one vertex (to the
// mean of its neighbours, the cap's centre) and says so; lumen run reports the count the growth returns in
// report.json (mesh.untangled_vertices) and on the mesh line.
TEST(SurfaceWall, UntangledFoldOverIsCountedInTheReportAndTheMeshLine) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_organ_", "untangle");
  write_cone(d / "cone.obj", 0.0, 20.0, 6.0, 0.0, 24, 4, 9.0);
  lumen::engine::SurfaceWallSpec spec;
  spec.file = (d / "cone.obj").string();
  spec.metres_per_unit = 1e-3;
  spec.thickness = 0.0005;
  const lumen::engine::SurfaceWall w = lumen::engine::grow_surface_wall(spec);
  EXPECT_EQ(w.untangled_vertices, 1);
  // The inner wall (outward: the surface) has the cap's centre at the mean of its ring (the origin), every other
  // vertex where the file put it.
  EXPECT_LT(w.mesh.rest.row(0).norm(), 1e-12) << w.mesh.rest.row(0);
  const std::string scene = write_scene(d, wall_scene("cone.obj", 0.5, "outward"));
  const fs::path out = d / "out";
  std::string text;
  ASSERT_EQ(run_lumen(scene, out, text, " --no-render"), 0) << text;
  EXPECT_NE(text.find(", " + std::to_string(w.untangled_vertices) + " vertices moved to untangle fold-overs"),
            std::string::npos) << text;
  std::ifstream in(out / "report.json");
  const json report = json::parse(in);
  EXPECT_EQ(report["mesh"]["untangled_vertices"], w.untangled_vertices) << report["mesh"].dump();
  EXPECT_EQ(report["mesh"]["clamped_vertices"], w.clamped_vertices) << report["mesh"].dump();
}

// The CT colon (20,000 triangles, haustral folds, creases sharper than 90 degrees): growing a 2.5 mm wall from it
// along vertex normals is refused: across the folds between haustra the surface leaves room for a fraction of a
// millimetre (a vertex with 0.22 mm), and the message says so and points to the swept tube.
TEST(SurfaceWall, CtColonIsRefusedSayingWhy) {
  lumen::engine::SurfaceWallSpec spec;
  spec.file = kOrgans + "gca-EdinGCA_3D_00090-large_intestine_20k.ply";
  spec.metres_per_unit = 1e-3;
  spec.thickness = 0.0025;
  const std::string msg = lumen::test::message_of<InputError>([&] { lumen::engine::grow_surface_wall(spec); });
  std::printf("colon 2.5 mm outward: %s\n", msg.c_str());
  EXPECT_NE(msg.find(spec.file + ": a wall of 2.5 mm grown outward is thicker than the surface's gaps allow: at vertex "),
            std::string::npos) << msg;
  EXPECT_NE(msg.find("mesh.type \"swept_tube\" with mesh.radius {\"from_surface\": ...}"), std::string::npos) << msg;
}
