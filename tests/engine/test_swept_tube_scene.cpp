// Swept-tube scenes: the mesh keys in millimetres with the centreline relative to the scene file, refused input
// naming the file, key and sample, the colon segment's inner wall intersection-free by the exact check, probes
// snapped onto its outer wall, and the build facts in report.json and on the terminal.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "collision/self_collision.hpp"
#include "engine/mesh_check.hpp"
#include "engine/scene.hpp"
#include "engine/session.hpp"
#include "engine/simulation.hpp"
#include "support/files.hpp"
#include "support/model_runs.hpp"

namespace fs = std::filesystem;
using lumen::engine::InputError;
using lumen::engine::MeshType;
using nlohmann::json;

namespace {

// A fresh folder for one test's files.
// A centreline file: n points along +z from z = 0 to z = length (file units), optional extra keys.
json straight_centreline(int n, double length) {
  json c;
  c["n"] = n;
  for (int k = 0; k < n; ++k) c["points"].push_back({0.0, 0.0, length * k / (n - 1)});
  return c;
}

// A swept-tube scene over the centreline file "line.json" (millimetres): an 8 mm lumen, 2.5 mm wall, 60 mm range.
json swept_scene() {
  return json::parse(R"({
    "name": "swept",
    "mesh": {"type": "swept_tube", "centreline": "line.json", "units": "mm", "range": [20.0, 80.0],
             "radius": 8.0, "wall_thickness": 2.5, "segments_around": 12, "segment_length": 5.0, "layers": 2,
             "haustra": {"depth": 1.5, "pitch": 20.0}},
    "material": {"model": "linear", "young_modulus": 5000.0, "poisson_ratio": 0.45, "density": 1050.0},
    "fixed": ["ends"],
    "probes": [{"point": [0.0, 0.0122, 0.05], "track": [{"t": 0.0, "force": [0, 0, 0]}, {"t": 0.1, "force": [0, -0.05, 0]}]}],
    "frames": 4, "fps": 40,
    "render": {"width": 160, "height": 120, "camera": "side"}
  })");
}

// Writes the scene and its centreline into d; the scene's path.
std::string write_case(const fs::path& d, const json& scene, const json& centreline) {
  std::ofstream(d / "line.json") << centreline.dump();
  std::ofstream(d / "s.json") << scene.dump();
  return (d / "s.json").string();
}

// The InputError message of loading that case ("" when it loads).
std::string swept_scene_error(const json& scene, const json& centreline) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_swept_", "error");
  const std::string path = write_case(d, scene, centreline);
  return lumen::test::message_of<InputError>([&] { lumen::engine::load_scene(path); });
}

}  // namespace

// Lengths in millimetres become metres; the centreline is read relative to the scene file.
TEST(SweptTubeScene, LoadsMillimetresRelativeToTheSceneFile) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_swept_", "load");
  const lumen::engine::Scene s = lumen::engine::load_scene(write_case(d, swept_scene(), straight_centreline(11, 100.0)));
  ASSERT_EQ(s.mesh_type, MeshType::kSweptTube);
  const lumen::physics::SweptTubeSpec& t = s.swept_tube;
  EXPECT_EQ(t.source, (d / "line.json").string());
  EXPECT_EQ(t.centreline.points.rows(), 11);
  EXPECT_DOUBLE_EQ(t.centreline.points(10, 2), 0.1);
  EXPECT_DOUBLE_EQ(t.range_start, 0.02);
  EXPECT_DOUBLE_EQ(t.range_stop, 0.08);
  EXPECT_DOUBLE_EQ(t.radius, 0.008);
  EXPECT_DOUBLE_EQ(t.wall_thickness, 0.0025);
  EXPECT_DOUBLE_EQ(t.segment_length, 0.005);
  EXPECT_DOUBLE_EQ(t.haustra.depth, 0.0015);
  EXPECT_DOUBLE_EQ(t.haustra.pitch, 0.02);
  EXPECT_EQ(t.segments_around, 12);
  EXPECT_EQ(t.layers, 2);
  // A profile [[s, r], ...] in the same units; no range: the whole centreline.
  json scene = swept_scene();
  scene["mesh"]["radius"] = json::parse("[[0, 8], [100, 10]]");
  scene["mesh"].erase("range");
  const lumen::engine::Scene p = lumen::engine::load_scene(write_case(d, scene, straight_centreline(11, 100.0)));
  ASSERT_EQ(p.swept_tube.radius_profile.size(), 2u);
  EXPECT_DOUBLE_EQ(p.swept_tube.radius_profile[1].s, 0.1);
  EXPECT_DOUBLE_EQ(p.swept_tube.radius_profile[1].r, 0.01);
  EXPECT_DOUBLE_EQ(p.swept_tube.range_start, 0.0);
  EXPECT_DOUBLE_EQ(p.swept_tube.range_stop, 0.1);
}

// Every refusal names the file (scene or centreline), the key or field with the sample index, and the value.
TEST(SweptTubeScene, RefusesBadInputNamingFileKeyAndSample) {
  const json line = straight_centreline(11, 100.0);
  const std::string scene_file = (fs::temp_directory_path() / "lumen_swept_error" / "s.json").string();
  const std::string line_file = (fs::temp_directory_path() / "lumen_swept_error" / "line.json").string();
  auto scene_with = [](const char* key, const json& value) {
    json s = swept_scene();
    s["mesh"][key] = value;
    return s;
  };
  EXPECT_EQ(swept_scene_error(swept_scene(), line), "");
  // The centreline file: repeated points, too few, a non-finite or malformed value, a count that disagrees.
  json repeated = line;
  repeated["points"][4] = repeated["points"][3];
  EXPECT_NE(swept_scene_error(swept_scene(), repeated).find(line_file + ": points[4]: repeats points[3], got [0, 0, "),
            std::string::npos) << swept_scene_error(swept_scene(), repeated);
  json one = straight_centreline(2, 100.0);
  one["points"].erase(1);
  one["n"] = 1;
  EXPECT_EQ(swept_scene_error(swept_scene(), one), line_file + ": points: needs at least 2 points, got 1");
  json text = line;
  text["points"][2][1] = "x";
  EXPECT_EQ(swept_scene_error(swept_scene(), text), line_file + ": points[2][1]: must be a number (value \"x\")");
  json count = line;
  count["n"] = 12;
  EXPECT_EQ(swept_scene_error(swept_scene(), count), line_file + ": n: must equal the number of points (11) (value 12)");
  json normals = line;
  normals["normals"] = json::array();
  for (int k = 0; k < 11; ++k) normals["normals"].push_back({0.0, 0.0, 1.0});
  EXPECT_NE(swept_scene_error(swept_scene(), normals).find(line_file + ": normals[0]: is zero or (nearly) parallel to the tangent"),
            std::string::npos);
  EXPECT_NE(swept_scene_error(scene_with("centreline", "missing.json"), line)
                .find((fs::path(scene_file).parent_path() / "missing.json").string() + ": no such centreline file"),
            std::string::npos);
  // The scene's mesh keys.
  EXPECT_EQ(swept_scene_error(scene_with("range", {20.0, 120.0}), line),
            scene_file + ": mesh.range: must lie within the centreline's arc length [0, 100] of " + line_file +
                ", start < stop (value [20.0,120.0])");
  EXPECT_NE(swept_scene_error(scene_with("range", {50.0, 50.0}), line).find("mesh.range: must lie within"), std::string::npos);
  EXPECT_EQ(swept_scene_error(scene_with("radius", 0.0), line), scene_file + ": mesh.radius: must be > 0 (value 0.0)");
  EXPECT_EQ(swept_scene_error(scene_with("wall_thickness", -1.0), line),
            scene_file + ": mesh.wall_thickness: must be > 0 (value -1.0)");
  EXPECT_EQ(swept_scene_error(scene_with("radius", json::parse(R"({"from_surface": "colon.ply"})")), line),
            (fs::path(scene_file).parent_path() / "colon.ply").string() + ": no such surface file");
  EXPECT_EQ(swept_scene_error(scene_with("radius", json::parse("[[30, 8], [100, 9]]")), line),
            scene_file + ": mesh.radius: the profile must cover mesh.range (first s <= range start, last s >= range "
                         "stop) (value [[30,8],[100,9]])");
  EXPECT_EQ(swept_scene_error(scene_with("radius", json::parse("[[0, 8], [0, 9]]")), line),
            scene_file + ": mesh.radius[1][0]: arc lengths must be strictly increasing (value 0)");
  EXPECT_EQ(swept_scene_error(scene_with("units", "cm"), line), scene_file + ": mesh.units: must be one of m, mm (value \"cm\")");
  EXPECT_EQ(swept_scene_error(scene_with("haustra", json::parse(R"({"depth": 1.0, "pitch": 10.0})")), line),
            scene_file + ": mesh.haustra.pitch: must be at least 4 mesh.segment_length (value 10.0)");
  EXPECT_EQ(swept_scene_error(scene_with("inner_radius", 8.0), line), scene_file + ": mesh.inner_radius: unknown key");
  EXPECT_EQ(swept_scene_error(scene_with("element", "tet10"), line), "");  // (10-node tets: straight-sided)
}

// The shipped colon segment: its inner wall has no intersecting triangle pair by the exact check; a helix whose
// turns are closer than the tube's diameter (the control) has some.
TEST(SweptTubeScene, ColonSegmentInnerWallIsIntersectionFree) {
  const lumen::engine::Scene scene = lumen::engine::load_scene(std::string(LUMEN_SOURCE_DIR) + "/scenes/colon-sigmoid-pinch.json");
  const lumen::physics::SweptTube tube = lumen::physics::make_swept_tube(scene.swept_tube);
  EXPECT_GT(tube.mesh.surface(lumen::physics::kInnerWall).rows(), 0);
  EXPECT_EQ(lumen::collision::count_intersecting_pairs(tube.mesh.rest, tube.mesh.surface(lumen::physics::kInnerWall)), 0);

  lumen::physics::SweptTubeSpec helix = scene.swept_tube;
  const int n = 400;
  helix.centreline = lumen::physics::Centreline{};
  helix.centreline.points.resize(n, 3);
  for (int k = 0; k < n; ++k) {
    const double t = 4.0 * EIGEN_PI * k / (n - 1);
    helix.centreline.points.row(k) << 0.03 * std::cos(t), 0.03 * std::sin(t), 0.002 * t;  // 12.6 mm between turns
  }
  helix.range_start = 0.0;
  helix.range_stop = lumen::physics::arc_lengths(helix.centreline.points).back();
  helix.haustra = {};
  const lumen::physics::SweptTube crossing = lumen::physics::make_swept_tube(helix);
  EXPECT_GT(lumen::collision::count_intersecting_pairs(crossing.mesh.rest, crossing.mesh.surface(lumen::physics::kInnerWall)), 0);
}

// Probes given as organ-frame points in metres snap onto the swept tube's outer wall; the mesh line says how it was
// built.
TEST(SweptTubeScene, ProbesSnapToTheOuterWallAndTheMeshLineSaysHowItWasBuilt) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_swept_", "probe");
  const lumen::engine::Scene scene =
      lumen::engine::load_scene(write_case(d, swept_scene(), straight_centreline(11, 100.0)));
  const auto model = lumen::engine::compile_model(scene);
  ASSERT_EQ(model->probe_points.size(), 1u);
  // At z = 50 mm (s - s0 = 1.5 pitches: a bulge) the outer wall is 8 + 1.5 + 2.5 = 12 mm from the axis, widest
  // there, so the point 12.2 mm out along y snaps to the outer-wall node at 12 mm along y (angle 3 of 12 steps).
  const Eigen::Vector3d q = lumen::engine::point_of(model->mesh.rest, model->probe_points[0]);
  EXPECT_LE((q - Eigen::Vector3d(0.0, 0.012, 0.05)).norm(), 1e-12) << q.transpose();
  EXPECT_EQ(model->mesh_type, MeshType::kSweptTube);
  EXPECT_EQ(model->clamped_rings, 0);
  const std::string line =
      lumen::engine::mesh_quality_line(*model, lumen::physics::mesh_quality(model->mesh.rest, model->mesh.tets));
  EXPECT_NE(line.find("0 inverted or zero-volume tets; swept_tube built in "), std::string::npos) << line;
  EXPECT_NE(line.find(" ms, 0 rings clamped at bends"), std::string::npos) << line;
}

// "fixed" by a box and by a plane side: exactly the nodes whose rest positions the box holds or lie on the
// normal's side (counted here by the hollow cylinder's documented ring positions); one selecting nothing is refused.
TEST(FixedNodeSets, BoxAndPlaneSelectTheNodesInsideAndOnTheNormalsSide) {
  json scene = json::parse(R"({
    "name": "fixed",
    "mesh": {"type": "hollow_cylinder", "inner_radius": 0.01, "outer_radius": 0.013, "length": 0.1,
             "segments_around": 12, "segments_along": 10, "layers": 2},
    "material": {"model": "linear", "young_modulus": 5000.0, "poisson_ratio": 0.45},
    "fixed": [{"box": [[-1, -1, -0.001], [1, 1, 0.015]]}, {"plane": {"point": [0, 0, 0.085], "normal": [0, 0, 2]}}],
    "probes": [], "frames": 1, "fps": 40
  })");
  const auto model = lumen::engine::compile_model(lumen::engine::parse_scene(scene.dump(), "f.json"));
  // Rings at z = 0.01 j: the box holds rings 0 and 1, the plane rings 9 and 10; 12 x 3 nodes a ring.
  std::vector<int> expected;
  for (int j : {0, 1, 9, 10})
    for (int n = 0; n < 36; ++n) expected.push_back(j * 36 + n);
  EXPECT_EQ(model->fixed_nodes, expected);
  scene["fixed"] = json::parse(R"([{"box": [[1, 1, 1], [2, 2, 2]]}])");
  EXPECT_EQ(lumen::test::message_of<InputError>([&] { lumen::engine::compile_model(lumen::engine::parse_scene(scene.dump(), "f.json")); }),
            "f.json: fixed[0]: selects no node of the mesh (value {\"box\":[[1,1,1],[2,2,2]]})");
  scene["fixed"] = json::parse(R"([{"box": [[-1, -1, -1], [1, 1, 1]]}])");
  EXPECT_EQ(lumen::test::message_of<InputError>([&] { lumen::engine::compile_model(lumen::engine::parse_scene(scene.dump(), "f.json")); }),
            "f.json: fixed: holds every node of the mesh (396 nodes), nothing is left to move");
  // One ring of cells held by its ends: every node too (it ran into the solver's internal error before).
  json one_ring = scene;
  one_ring["mesh"]["segments_along"] = 1;
  one_ring["fixed"] = json::parse(R"(["ends"])");
  EXPECT_EQ(lumen::test::message_of<InputError>([&] { lumen::engine::compile_model(lumen::engine::parse_scene(one_ring.dump(), "f.json")); }),
            "f.json: fixed: holds every node of the mesh (72 nodes), nothing is left to move");
  scene["fixed"] = json::parse(R"([{"box": [[1, 1, 1], [0, 2, 2]]}])");
  EXPECT_EQ(lumen::test::message_of<InputError>([&] { lumen::engine::parse_scene(scene.dump(), "f.json"); }),
            "f.json: fixed[0].box: the first corner must be the low one (x0 <= x1, y0 <= y1, z0 <= z1) (value "
            "[[1,1,1],[0,2,2]])");
  scene["fixed"] = json::parse(R"(["ends", {"plane": {"point": [0, 0, 0], "normal": [0, 0, 0]}}])");
  EXPECT_EQ(lumen::test::message_of<InputError>([&] { lumen::engine::parse_scene(scene.dump(), "f.json"); }),
            "f.json: fixed[1].plane.normal: must not be zero (value [0,0,0])");
  scene["fixed"] = json::parse(R"([{"sphere": 1}])");
  EXPECT_NE(lumen::test::message_of<InputError>([&] { lumen::engine::parse_scene(scene.dump(), "f.json"); })
                .find("f.json: fixed[0]: must be a node-set name (ends, start, stop), {\"box\""),
            std::string::npos);
}

// The lumen program on a bad centreline: exit 2, one message naming the centreline file, the field and the sample,
// and nothing written into the output folder.
TEST(SweptTubeScene, BadCentrelineExitsTwoAndWritesNothing) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_swept_", "cli");
  json line = straight_centreline(11, 100.0);
  line["points"][7] = line["points"][6];
  const std::string scene = write_case(d, swept_scene(), line);
  const fs::path out = d / "out";
  const auto [code, output] =
      lumen::test::run_command(std::string(LUMEN_BINARY) + " run " + scene + " --out " + out.string() + " 2>&1");
  EXPECT_EQ(code, 2) << output;
  EXPECT_NE(output.find("lumen: error: " + (d / "line.json").string() + ": points[7]: repeats points[6], got [0, 0, "),
            std::string::npos) << output;
  EXPECT_TRUE(!fs::exists(out) || fs::is_empty(out));
}

// A twist turns a swept tube's end ring about that ring's own centreline tangent and centre: on a straight
// centreline its prescribed displacement is the hollow cylinder's (the same node numbering, the tube shifted by the
// range start), and on a bent one every turned node stays at its distance from the end ring's centre.
TEST(SweptTubeScene, TwistTurnsTheEndRingAboutItsOwnTangent) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_swept_", "twist");
  json swept = swept_scene();
  swept["mesh"].erase("haustra");
  swept["mesh"]["segment_length"] = 5.0;
  swept["fixed"] = {"start"};
  swept["probes"] = json::array();
  swept["twist"] = json::parse(R"({"end": "stop", "track": [{"t": 0.0, "degrees": 0.0}, {"t": 1.0, "degrees": 90.0}]})");
  json cylinder = swept;
  cylinder["mesh"] = json::parse(R"({"type": "hollow_cylinder", "inner_radius": 0.008, "outer_radius": 0.0105,
                                     "length": 0.06, "segments_around": 12, "segments_along": 12, "layers": 2})");
  const auto tube = lumen::engine::compile_model(lumen::engine::load_scene(write_case(d, swept, straight_centreline(11, 100.0))));
  const auto cyl = lumen::engine::compile_model(lumen::engine::parse_scene(cylinder.dump(), "c.json"));
  ASSERT_EQ(tube->mesh.n_nodes(), cyl->mesh.n_nodes());
  EXPECT_LE((tube->twist_axis - Eigen::Vector3d::UnitZ()).norm(), 1e-15);
  EXPECT_LE((tube->twist_center - Eigen::Vector3d(0.0, 0.0, 0.08)).norm(), 1e-15);
  EXPECT_LE((lumen::engine::twist_displacement(*tube, 30.0) - lumen::engine::twist_displacement(*cyl, 30.0)).lpNorm<Eigen::Infinity>(),
            1e-12);
  // The shipped colon segment (a bent, clamped end): turned nodes keep their distance from the ring's centre.
  lumen::engine::Scene colon = lumen::engine::load_scene(std::string(LUMEN_SOURCE_DIR) + "/scenes/colon-sigmoid-pinch.json");
  colon.twist.end = lumen::engine::TwistEnd::kStop;
  colon.twist.track = {{0.0, 0.0}, {1.0, 90.0}};
  colon.probes.clear();
  colon.collision.self = false;
  const auto m = lumen::engine::compile_model(colon);
  const Eigen::VectorXd u = lumen::engine::twist_displacement(*m, 90.0);
  for (int v : m->mesh.node_set(lumen::physics::kStopEnd)) {
    const Eigen::Vector3d x = m->mesh.rest.row(v).transpose();
    const Eigen::Vector3d moved = x + u.segment<3>(3 * v);
    EXPECT_NEAR((moved - m->twist_center).norm(), (x - m->twist_center).norm(), 1e-12) << v;
    EXPECT_NEAR((moved - x).dot(m->twist_axis), 0.0, 1e-12) << v;
  }
}

namespace {

// The probe's displacement at the last of `frames` frames of the swept-tube case with that material model, solver
// type and peak force (newtons, reached at 0.1 s and held).
Eigen::Vector3d swept_probe_displacement(const char* model, const char* solver, double force, int frames) {
  json s = swept_scene();
  lumen::test::set_model(s, model, solver);
  s["probes"][0]["track"][1]["force"] = {0.0, -force, 0.0};
  s["frames"] = frames;
  const fs::path d = lumen::test::fresh_temp_dir("lumen_swept_", std::string(model) + "_" + solver);
  return lumen::test::last_probe_displacement(
      lumen::engine::load_scene(write_case(d, s, straight_centreline(11, 100.0))));
}

}  // namespace

// Every model on a swept tube with haustra (not a cylinder): the corotational quasi-static answer approaches the
// linear one as the load shrinks, to second order (10x less load: about 10x less relative difference), and the
// dynamic runs (backward Euler, Rayleigh mass damping, the load held) settle on their quasi-static answers.
TEST(SweptTubeScene, EveryModelRunsOnASweptTube) {
  lumen::test::expect_every_model_agrees(swept_probe_displacement, 4e-3, "swept tube");
}

namespace {

// A hairpin centreline (millimetres): up the z axis 60 mm, a half turn of radius 12 mm, back down at x = 24 mm.
json hairpin_centreline() {
  json c;
  std::vector<std::array<double, 3>> p;
  for (int k = 0; k <= 6; ++k) p.push_back({0.0, 0.0, 10.0 * k});
  for (int k = 1; k < 12; ++k) {
    const double phi = EIGEN_PI * k / 12;
    p.push_back({12.0 - 12.0 * std::cos(phi), 0.0, 60.0 + 12.0 * std::sin(phi)});
  }
  for (int k = 6; k >= 0; --k) p.push_back({24.0, 0.0, 10.0 * k});
  c["n"] = p.size();
  for (const auto& q : p) c["points"].push_back({q[0], q[1], q[2]});
  return c;
}

// The outer wall's intersecting triangle pairs at the end of the hairpin whose first leg's outer wall is pulled 6 mm
// toward the second leg by a probe (a grasper's pull; the legs' outer walls start 3 mm apart), with the outer wall
// colliding or not; the frames' total contacts and the worst frame's intersecting pairs by the session's own check.
struct HairpinRun {
  int outer_pairs_at_end = 0;
  long contacts = 0;
  long worst_checked_pairs = 0;
};
HairpinRun squeeze_hairpin(bool outer_collides) {
  json s = json::parse(R"({
    "name": "hairpin",
    "mesh": {"type": "swept_tube", "centreline": "line.json", "units": "mm",
             "radius": 8.0, "wall_thickness": 2.5, "segments_around": 12, "segment_length": 3.0, "layers": 1},
    "material": {"model": "linear", "young_modulus": 5000.0, "poisson_ratio": 0.45, "density": 1050.0},
    "fixed": ["ends"],
    "probes": [{"point": [0.0105, 0.0, 0.03],
                "track": [{"t": 0.0, "displacement": [0, 0, 0]}, {"t": 0.5, "displacement": [0.006, 0, 0]}]}],
    "frames": 20, "fps": 40,
    "collision": {"self": true, "gap": 0.0001}
  })");
  if (outer_collides) s["collision"]["surfaces"] = {"inner", "outer"};
  const fs::path d = lumen::test::fresh_temp_dir("lumen_swept_", outer_collides ? "hairpin_outer" : "hairpin_inner");
  const lumen::engine::Scene scene = lumen::engine::load_scene(write_case(d, s, hairpin_centreline()));
  const auto model = lumen::engine::compile_model(scene);
  lumen::engine::SessionOptions opt;
  opt.render = false;
  opt.check = true;
  lumen::Points last;
  opt.on_frame = [&](const lumen::engine::Model&, const lumen::engine::State& st, const lumen::engine::FrameRecord&) {
    last = st.x;
  };
  const lumen::engine::SessionResult r = lumen::engine::run_session(*model, lumen::engine::make_inputs(scene), opt);
  HairpinRun h;
  for (const auto& f : r.frames) {
    h.contacts += f.contacts;
    h.worst_checked_pairs = std::max(h.worst_checked_pairs, f.intersecting_pairs);
    EXPECT_FALSE(f.numerical_failure) << "frame " << f.frame;
  }
  h.outer_pairs_at_end =
      lumen::collision::count_intersecting_pairs(last, model->mesh.surface(lumen::physics::kOuterWall));
  return h;
}

}  // namespace

// The outer wall colliding on an organ mesh that is not the cylinder: a swept tube bent into a hairpin, one leg's
// wall pulled 6 mm toward the other across their 3 mm gap. With collision.surfaces ["inner", "outer"] the legs' outer
// walls meet and never intersect (the exact check on every frame, and on the outer wall at the end); with the inner
// wall only they pass through each other.
TEST(SweptTubeScene, HairpinLegsPressedTogetherMeetOnTheOuterWall) {
  const HairpinRun with = squeeze_hairpin(true), without = squeeze_hairpin(false);
  EXPECT_GT(with.contacts, 0);
  EXPECT_EQ(with.worst_checked_pairs, 0);
  EXPECT_EQ(with.outer_pairs_at_end, 0);
  EXPECT_GT(without.outer_pairs_at_end, 0);
}

namespace {

// The probe's displacement (metres) after a 2 mN press on the top of the middle ring of a straight 60 mm tube (8 mm
// lumen, 2.5 mm wall, `around` x 12 x 2 cells, ends held, linear model) built as a swept tube or as the generated
// hollow cylinder (the same corner nodes), on the given element; where: the probe point's rest position relative
// to the start ring's centre.
Eigen::Vector3d straight_tube_press(bool swept, const char* element, int around, Eigen::Vector3d& where) {
  json s = swept_scene();
  s["mesh"].erase("haustra");
  s["mesh"]["segments_around"] = around;
  if (!swept)
    s["mesh"] = {{"type", "hollow_cylinder"}, {"inner_radius", 0.008}, {"outer_radius", 0.0105}, {"length", 0.06},
                 {"segments_around", around}, {"segments_along", 12}, {"layers", 2}};
  s["mesh"]["element"] = element;
  const double z0 = swept ? 0.02 : 0.0;  // the start ring's z (the swept range starts 20 mm along its centreline)
  s["probes"][0]["point"] = {0.0, 0.0105, z0 + 0.03};
  s["probes"][0]["track"][1]["force"] = {0.0, -2e-3, 0.0};
  s["frames"] = 4;
  const fs::path d = lumen::test::fresh_temp_dir(
      "lumen_swept_", std::string(swept ? "swept_" : "cylinder_") + element + "_" + std::to_string(around));
  const lumen::engine::Scene scene = lumen::engine::load_scene(write_case(d, s, straight_centreline(11, 100.0)));
  const auto m = lumen::engine::compile_model(scene);
  where = lumen::engine::point_of(m->mesh.rest, m->probe_points.at(0)) - Eigen::Vector3d(0.0, 0.0, z0);
  return lumen::test::last_probe_displacement(scene);
}

}  // namespace

// 10-node tets on a swept tube (any mesh but the generated cylinder: edge nodes at the edge midpoints, the walls as
// faceted as the 4-node mesh's). On a straight swept tube with the hollow cylinder's corner nodes, the
// straight-sided quadratic answer differs from the isoparametric cylinder's (whose 10-node answers were checked
// against CalculiX: tests/scenes, docs/study_reference.csv) by the facets' geometry alone, so the difference
// shrinks at second order as the facets do (12 -> 24 around: about 4x less); the 4-node tets on the same mesh lock
// (tens of per cent stiffer).
TEST(SweptTubeScene, QuadraticTetsOnASweptTubeApproachTheIsoparametricCylinder) {
  double difference[2] = {0.0, 0.0};
  for (int k = 0; k < 2; ++k) {
    const int around = 12 * (k + 1);
    Eigen::Vector3d at_swept, at_cylinder, at_linear;
    const Eigen::Vector3d swept = straight_tube_press(true, "tet10", around, at_swept);
    const Eigen::Vector3d cylinder = straight_tube_press(false, "tet10", around, at_cylinder);
    const Eigen::Vector3d linear = straight_tube_press(true, "tet4", around, at_linear);
    ASSERT_LT((at_swept - at_cylinder).norm(), 1e-9) << at_swept.transpose() << " vs " << at_cylinder.transpose();
    ASSERT_LT((at_linear - at_cylinder).norm(), 1e-9);
    ASSERT_GT(cylinder.norm(), 1e-4);
    difference[k] = (swept - cylinder).norm() / cylinder.norm();
    const double locking = (linear - cylinder).norm() / cylinder.norm();
    std::printf("press on a straight tube, %d around: tet10 isoparametric cylinder %.4f mm, tet10 swept %.4f mm "
                "(%.2f %%), tet4 swept %.4f mm (%.1f %%)\n", around, cylinder.norm() * 1e3, swept.norm() * 1e3,
                100.0 * difference[k], linear.norm() * 1e3, 100.0 * locking);
    EXPECT_GT(locking, 2.0 * difference[k]);
    EXPECT_LT(linear.norm(), swept.norm());
  }
  EXPECT_NEAR(difference[0] / difference[1], 4.0, 1.5);
}
