// Volume-mesh scenes (mesh.type "volume"): the shipped tube file is the generator's tube, the keys are refused
// with one message naming the file, key and value, and `lumen run` exits 2 on bad input writing nothing.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <stdlib.h>
#include <string>
#include <system_error>

#include <nlohmann/json.hpp>

#include "engine/mesh_check.hpp"
#include "engine/scene.hpp"
#include "engine/simulation.hpp"
#include "physics/mesh.hpp"
#include "support/files.hpp"
#include "support/volume_files.hpp"

namespace fs = std::filesystem;
using lumen::engine::InputError;
using lumen::engine::load_scene;
using nlohmann::json;
namespace physics = lumen::physics;

namespace {

const std::string kScenes = std::string(LUMEN_SOURCE_DIR) + "/scenes/";

// This process's own temporary folder, made once by mkdtemp (parallel runs of the tests never share it) and
// removed when the process ends.
class TempRoot {
 public:
  TempRoot() {
    std::string pattern = (fs::temp_directory_path() / "lumen_volume_XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed for " + pattern);
    path_ = pattern;
  }
  ~TempRoot() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

const fs::path& temp_root() {
  static const TempRoot root;
  return root.path();
}

// The folder of one case (name) under this process's temporary folder.
fs::path case_dir(const std::string& name) { return temp_root() / name; }

// The folder of one case, emptied.
fs::path fresh_case_dir(const std::string& name) {
  const fs::path d = case_dir(name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// A small generated tube and the same tube as a tagged .msh beside a volume scene that loads it.
physics::HollowCylinderSpec small_tube() { return {0.01, 0.013, 0.05, 10, 6, 2, 0.0, {}, {}}; }

json volume_scene() {
  return json::parse(R"({
    "name": "volume",
    "mesh": {"type": "volume", "file": "tube.msh", "inner_tag": 1, "outer_tag": 2},
    "material": {"model": "linear", "young_modulus": 5000.0, "poisson_ratio": 0.45},
    "fixed": ["ends"],
    "probes": [{"point": [0.0, 0.013, 0.025], "track": [{"t": 0.0, "force": [0, 0, 0]}, {"t": 0.1, "force": [0, -0.05, 0]}]}],
    "frames": 4, "fps": 40,
    "render": {"width": 160, "height": 120, "camera": "side"}
  })");
}

// Writes the tube file (its text, default the tagged small tube) and the scene into d; the scene's path.
std::string write_case(const fs::path& d, const json& scene, const std::string& mesh_text = "") {
  const physics::TetMesh m = physics::make_hollow_cylinder(small_tube());
  const lumen::test::TaggedVolume v{m.rest, m.tets,
                                    {m.surface(physics::kInnerWall), m.surface(physics::kOuterWall)},
                                    {1, 2},
                                    {"lumen", "serosa"}};
  std::ofstream(d / "tube.msh") << (mesh_text.empty() ? lumen::test::write_msh41(v) : mesh_text);
  std::ofstream(d / "s.json") << scene.dump();
  return (d / "s.json").string();
}

std::string volume_scene_error(const json& scene, const std::string& mesh_text = "") {
  const fs::path d = fresh_case_dir("error");
  const std::string path = write_case(d, scene, mesh_text);
  return lumen::test::message_of<InputError>([&] { load_scene(path); });
}

}  // namespace

// The shipped data/volume-tube.msh (tools/make_volume_tube.py) is fig5-squeeze's generated tube: same tets, walls
// and end sets, nodes within the millimetre file's rounding.
TEST(VolumeScene, TheShippedTubeFileIsTheGeneratorsTube) {
  const auto from_file = lumen::engine::compile_model(load_scene(kScenes + "volume-tube-pinch.json"));
  const auto generated = lumen::engine::compile_model(load_scene(kScenes + "fig5-squeeze.json"));
  const physics::TetMesh& a = from_file->mesh;
  const physics::TetMesh& b = generated->mesh;
  EXPECT_EQ(a.tets, b.tets);
  ASSERT_EQ(a.rest.rows(), b.rest.rows());
  EXPECT_LT((a.rest - b.rest).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_EQ(a.surface(physics::kInnerWall), b.surface(physics::kInnerWall));
  EXPECT_EQ(a.surface(physics::kOuterWall), b.surface(physics::kOuterWall));
  EXPECT_EQ(a.node_set(physics::kStartEnd), b.node_set(physics::kStartEnd));
  EXPECT_EQ(a.node_set(physics::kStopEnd), b.node_set(physics::kStopEnd));
  EXPECT_EQ(from_file->fixed_nodes, generated->fixed_nodes);
  EXPECT_EQ(from_file->mesh_type, lumen::engine::MeshType::kVolume);
  // The terminal line names the source and its file.
  const std::string file = fs::path(kScenes + "../data/volume-tube.msh").lexically_normal().string();
  EXPECT_EQ(from_file->mesh_file, file);
  const std::string line = lumen::engine::mesh_quality_line(*from_file, physics::mesh_quality(a.rest, a.tets));
  EXPECT_NE(line.find("0 inverted or zero-volume tets; volume built in "), std::string::npos) << line;
  EXPECT_NE(line.find(" ms from " + file), std::string::npos) << line;
}

// Tags by number or by physical name; without tags the walls are found; millimetres scaled.
TEST(VolumeScene, TagsByNumberOrNameAndFoundWalls) {
  const physics::TetMesh tube = physics::make_hollow_cylinder(small_tube());
  json by_name = volume_scene();
  by_name["mesh"]["inner_tag"] = "lumen";
  by_name["mesh"]["outer_tag"] = "serosa";
  json found = volume_scene();
  found["mesh"].erase("inner_tag");
  found["mesh"].erase("outer_tag");
  for (const json& scene : {volume_scene(), by_name, found}) {
    const fs::path d = fresh_case_dir("tags");
    const lumen::engine::Scene s = load_scene(write_case(d, scene));
    EXPECT_EQ(s.volume.file, (d / "tube.msh").string());
    EXPECT_EQ(s.volume.mesh.tets, tube.tets);
    EXPECT_EQ(s.volume.mesh.surface(physics::kInnerWall).rows(), tube.surface(physics::kInnerWall).rows());
    EXPECT_EQ(s.volume.mesh.node_set(physics::kStopEnd), tube.node_set(physics::kStopEnd));
  }
  json mm = volume_scene();
  mm["mesh"]["units"] = "mm";
  const lumen::engine::Scene s = load_scene(write_case(fresh_case_dir("mm"), mm));
  EXPECT_NEAR(s.volume.mesh.rest.cwiseAbs().maxCoeff(), 0.05e-3, 1e-18);
}

TEST(VolumeScene, RefusesBadKeysNamingFileKeyAndValue) {
  const std::string scene = (case_dir("error") / "s.json").string();
  const std::string mesh = (case_dir("error") / "tube.msh").string();
  json s = volume_scene();
  s["mesh"].erase("outer_tag");
  EXPECT_EQ(volume_scene_error(s), scene + ": mesh.inner_tag: give both mesh.inner_tag and mesh.outer_tag, or neither (the "
                                 "walls are then found on the boundary)");
  s = volume_scene();
  s["mesh"]["outer_tag"] = "muscle";
  EXPECT_EQ(volume_scene_error(s), scene + ": mesh.outer_tag: no physical surface of that name in " + mesh +
                             " (it has: \"lumen\", \"serosa\") (value \"muscle\")");
  s = volume_scene();
  s["mesh"]["outer_tag"] = 1;
  EXPECT_EQ(volume_scene_error(s), scene + ": mesh.outer_tag: must differ from mesh.inner_tag (value 1)");
  s = volume_scene();
  s["mesh"]["outer_tag"] = 7;
  EXPECT_EQ(volume_scene_error(s), mesh + ": mesh.outer_tag: no triangle has tag 7 (triangle tags in the file: 1, 2)");
  s = volume_scene();
  s["mesh"]["radius"] = 1.0;
  EXPECT_EQ(volume_scene_error(s), scene + ": mesh.radius: unknown key");
  s = volume_scene();
  s["mesh"]["file"] = "none.msh";
  EXPECT_EQ(volume_scene_error(s), (case_dir("error") / "none.msh").string() +
                             ": file: no such volume mesh file");
  s = volume_scene();
  s["twist"] = json::parse(R"({"end": "stop", "track": [{"t": 0.0, "degrees": 0.0}]})");
  EXPECT_EQ(volume_scene_error(s), "");  // (a tube file with two end caps: VolumeScene.ATwistedTubeFile...)
  s = volume_scene();
  s["mesh"]["element"] = "tet10";
  EXPECT_EQ(volume_scene_error(s), "");  // (10-node tets: straight-sided)
}

// A file whose end caps are one piece (here: none, the walls tagged on a tube with one end cap only tagged as
// wall) has no end sets: "fixed": ["ends"] is refused, a box is accepted.
TEST(VolumeScene, NamedEndsNeedTwoEndCaps) {
  const physics::TetMesh m = physics::make_hollow_cylinder(small_tube());
  // Both end caps tagged as outer wall: no end caps left.
  lumen::Tris outer(m.surface(physics::kOuterWall).rows() + m.surface(physics::kEndCaps).rows(), 3);
  outer << m.surface(physics::kOuterWall), m.surface(physics::kEndCaps);
  const lumen::test::TaggedVolume v{m.rest, m.tets, {m.surface(physics::kInnerWall), outer}, {1, 2}, {"a", "b"}};
  const std::string text = lumen::test::write_msh22(v);
  const std::string mesh = (case_dir("error") / "tube.msh").string();
  EXPECT_EQ(volume_scene_error(volume_scene(), text),
            (case_dir("error") / "s.json").string() + ": fixed[0]: the volume mesh " +
                mesh + " has no end node sets (its end caps are not two separate pieces): hold nodes by {\"box\": "
                "...} or {\"plane\": ...} (value \"ends\")");
  json boxed = volume_scene();
  boxed["fixed"] = json::parse(R"([{"box": [[-1, -1, -0.001], [1, 1, 0.001]]}])");
  EXPECT_EQ(volume_scene_error(boxed, text), "");
  // Nor an end to twist.
  boxed["twist"] = json::parse(R"({"end": "stop", "track": [{"t": 0.0, "degrees": 0.0}]})");
  EXPECT_EQ(volume_scene_error(boxed, text), (case_dir("error") / "s.json").string() + ": twist: the volume mesh " +
                                                 mesh + " has no end node sets (its end caps are not two separate "
                                                 "pieces), so it has no end to turn");
}

// A twist on a tube read from a file turns its end about the axis through the end ring's centroid along the normal
// of its plane: on the generator's tube written as .msh (the same nodes and tets), the axis, the centre, the end's
// prescribed motion and the whole twisted session are those of the same tube generated (the generator's centreline
// frame), to round-off.
TEST(VolumeScene, ATwistedTubeFileTurnsLikeTheGeneratedTube) {
  json file = volume_scene();
  file["probes"] = json::array();
  file["twist"] = json::parse(R"({"end": "stop", "track": [{"t": 0.0, "degrees": 0.0}, {"t": 0.1, "degrees": 60.0}]})");
  file["material"]["model"] = "corotational";
  const fs::path d = fresh_case_dir("twist");
  const engine::Scene from_file = engine::load_scene(write_case(d, file));
  json generated = file;
  const physics::HollowCylinderSpec t = small_tube();
  generated["mesh"] = {{"type", "hollow_cylinder"}, {"inner_radius", t.inner_radius}, {"outer_radius", t.outer_radius},
                       {"length", t.length}, {"segments_around", t.segments_around},
                       {"segments_along", t.segments_along}, {"layers", t.layers}};
  const engine::Scene from_generator = engine::parse_scene(generated.dump(), "generated.json");
  const auto a = engine::compile_model(from_file), b = engine::compile_model(from_generator);
  ASSERT_EQ(a->mesh.rest, b->mesh.rest);
  EXPECT_LT((a->twist_axis - b->twist_axis).norm(), 1e-12) << a->twist_axis.transpose();
  EXPECT_LT((a->twist_center - b->twist_center).norm(), 1e-12) << a->twist_center.transpose();
  EXPECT_EQ(a->prescribed.nodes, b->prescribed.nodes);
  EXPECT_LT((engine::twist_displacement(*a, 60.0) - engine::twist_displacement(*b, 60.0)).norm(), 1e-12);
  engine::State sa = engine::make_state(*a), sb = engine::make_state(*b);
  engine::Inputs ia = engine::make_inputs(from_file), ib = engine::make_inputs(from_generator);
  engine::FrameRecord ra, rb;
  for (int i = 0; i < from_file.frames; ++i) {
    engine::step(*a, ia, sa, ra);
    engine::step(*b, ib, sb, rb);
    ASSERT_FALSE(ra.numerical_failure) << "frame " << i;
    EXPECT_TRUE(ra.physics_converged) << "frame " << i;
    EXPECT_NEAR(ra.twist_degrees, rb.twist_degrees, 1e-12);
    EXPECT_LT((sa.sim.u - sb.sim.u).norm(), 1e-9 * sb.sim.u.norm()) << "frame " << i;
  }
  EXPECT_GT(sb.sim.u.norm(), 1e-3);  // it did turn
}

// lumen run on a bad volume file: exit 2, the reader's message, nothing written.
TEST(VolumeScene, LumenRunExitsTwoOnABadFileAndWritesNothing) {
  const fs::path d = fresh_case_dir("cli");
  const physics::TetMesh m = physics::make_hollow_cylinder(small_tube());
  const lumen::test::TaggedVolume v{m.rest, m.tets, {m.surface(physics::kInnerWall)}, {1}, {"a"}};
  std::string text = lumen::test::write_msh22(v);
  text = text.substr(0, text.find("$EndNodes") / 2);  // truncated inside $Nodes
  const std::string scene = write_case(d, volume_scene(), text);
  const auto [code, output] =
      lumen::test::run_command(std::string(LUMEN_BINARY) + " run " + scene + " --out " + (d / "out").string() + " 2>&1");
  EXPECT_EQ(code, 2) << output;
  EXPECT_NE(output.find((d / "tube.msh").string() + ": line "), std::string::npos) << output;
  EXPECT_NE(output.find(": the file ends inside $Nodes (from line 9) (expected "), std::string::npos) << output;
  EXPECT_FALSE(fs::exists(d / "out"));
}
