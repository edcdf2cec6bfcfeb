// Scene key "instruments": accepted shapes and pose sources with their values; every refused input names the
// scene file, the key path and the value (exit 2 through InputError); a device-only instrument is refused by run.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <variant>

#include <nlohmann/json.hpp>

#include "engine/scene.hpp"
#include "engine/simulation.hpp"
#include "support/files.hpp"
#include "support/instruments.hpp"

using namespace lumen::engine;
using lumen::test::message_of;
using lumen::test::write_temp;
using nlohmann::json;

namespace {

// A short tube with the issue's instrument example (shape, track, device_name, to_organ).
json instrument_scene() {
  json s = lumen::test::small_tube_scene("tool");
  s["frames"] = 10;
  s["instruments"] = json::parse(R"([{
    "name": "probe",
    "shape": {"type": "sphere_probe", "tip_radius": 0.003, "shaft_radius": 0.002, "shaft_length": 0.08},
    "track": [{"t": 0.0, "position": [0.0, 0.03, 0.05], "rotation": [1, 0, 0, 0]},
              {"t": 2.0, "position": [0.0, 0.012, 0.05], "rotation": [1, 0, 0, 0]}],
    "device_name": "Tracker",
    "to_organ": [1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 0, 1]
  }])");
  return s;
}

const char* kScenePath = "dir/s.json";

std::string instrument_scene_error(const json& scene, const std::string& path = kScenePath) {
  return message_of<InputError>([&] { parse_scene(scene.dump(), path); });
}

// The instrument example with one key of instruments[0] replaced (or removed, for a null value).
json with_instrument_key(const std::string& key, const json& value) {
  json s = instrument_scene();
  if (value.is_null())
    s["instruments"][0].erase(key);
  else
    s["instruments"][0][key] = value;
  return s;
}

// A regular tetrahedron's OBJ text, faces outward, millimetres.
std::string tetrahedron_obj() {
  return "v 0 0 0\nv 10 0 0\nv 0 10 0\nv 0 0 10\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
}

}  // namespace

TEST(InstrumentScene, AcceptsTheIssueExampleWithItsValues) {
  const Scene s = parse_scene(instrument_scene().dump(), kScenePath);
  ASSERT_EQ(s.instruments.size(), 1u);
  const InstrumentSpec& in = s.instruments[0];
  EXPECT_EQ(in.name, "probe");
  const auto* probe = std::get_if<SphereProbeSpec>(&in.shape);
  ASSERT_NE(probe, nullptr);
  EXPECT_DOUBLE_EQ(probe->tip_radius, 0.003);
  EXPECT_DOUBLE_EQ(probe->shaft_radius, 0.002);
  EXPECT_DOUBLE_EQ(probe->shaft_length, 0.08);
  EXPECT_EQ(in.drive, InstrumentDrive::kTrack);
  ASSERT_EQ(in.poses.size(), 2u);
  EXPECT_DOUBLE_EQ(in.poses[1].t, 2.0);
  EXPECT_DOUBLE_EQ(in.poses[1].pose.position.y(), 0.012);
  EXPECT_EQ(in.device_name, "Tracker");
  EXPECT_TRUE(in.to_organ.matrix().isIdentity(0.0));
}

TEST(InstrumentScene, EveryShapeTypeAndAxisAngleRotations) {
  json s = instrument_scene();
  s["instruments"][0]["shape"] = {{"type", "rod"}, {"radius", 0.002}, {"length", 0.05}, {"end", "rounded"}};
  // A quarter turn about z as axis and angle (radians).
  s["instruments"][0]["track"][1]["rotation"] = {{"axis", {0, 0, 2}}, {"angle", EIGEN_PI / 2}};
  s["instruments"].push_back({{"name", "jaws"},
                              {"shape", {{"type", "grasper"}, {"jaw_length", 0.012}, {"jaw_width", 0.004},
                                         {"jaw_thickness", 0.0015}, {"opening_angle", 0.5},
                                         {"shaft_radius", 0.0025}, {"shaft_length", 0.08}}},
                              {"track", {{{"t", 0.0}, {"position", {0, 0.05, 0.05}}}}}});
  write_temp("tetra_tool.obj", tetrahedron_obj());
  s["instruments"].push_back({{"name", "file"},
                              {"shape", {{"type", "mesh"}, {"file", "lumen_test_tetra_tool.obj"}, {"units", "mm"}}},
                              {"track", {{{"t", 0.0}, {"position", {0, 0.05, 0.05}}}}}});
  const std::string path = (std::filesystem::temp_directory_path() / "s.json").string();
  const Scene scene = parse_scene(s.dump(), path);
  ASSERT_EQ(scene.instruments.size(), 3u);
  const auto& rod = std::get<RodSpec>(scene.instruments[0].shape);
  EXPECT_EQ(rod.end, RodEnd::kRounded);
  const Eigen::Quaterniond q = scene.instruments[0].poses[1].pose.rotation;
  EXPECT_NEAR((q * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), 0.0, 1e-15);
  EXPECT_DOUBLE_EQ(std::get<GrasperSpec>(scene.instruments[1].shape).opening_angle, 0.5);
  const auto& file = std::get<MeshFileSpec>(scene.instruments[2].shape);
  EXPECT_EQ(file.file, (std::filesystem::temp_directory_path() / "lumen_test_tetra_tool.obj").string());
  EXPECT_EQ(file.units, MeshUnits::kMillimetres);
  EXPECT_EQ(scene.instruments[2].name, "file");
}

TEST(InstrumentScene, ReplayIsReadBesideTheSceneFile) {
  write_temp("tool_poses.csv", "t,x,y,z,qw,qx,qy,qz\n0,0,0.03,0.05,1,0,0,0\n1,0,0.02,0.05,1,0,0,0\n");
  const std::string path = (std::filesystem::temp_directory_path() / "s.json").string();
  json replay = with_instrument_key("track", nullptr);
  replay["instruments"][0]["replay"] = "lumen_test_tool_poses.csv";
  const Scene r = parse_scene(replay.dump(), path);
  EXPECT_EQ(r.instruments[0].drive, InstrumentDrive::kReplay);
  ASSERT_EQ(r.instruments[0].poses.size(), 2u);
  EXPECT_DOUBLE_EQ(r.instruments[0].poses[1].pose.position.y(), 0.02);
}

TEST(InstrumentScene, KeysAndTypesNameFileKeyAndValue) {
  EXPECT_EQ(instrument_scene_error(with_instrument_key("colour", "red")), "dir/s.json: instruments[0].colour: unknown key");
  EXPECT_EQ(instrument_scene_error(with_instrument_key("shape", {{"type", "scalpel"}})),
            "dir/s.json: instruments[0].shape.type: must be one of sphere_probe, rod, grasper, mesh (value \"scalpel\")");
  EXPECT_EQ(instrument_scene_error(with_instrument_key("shape", {{"type", "rod"}, {"radius", 0.002}})),
            "dir/s.json: instruments[0].shape.length: missing key");
  EXPECT_EQ(instrument_scene_error(with_instrument_key("shape", {{"type", "rod"}, {"radius", 0.002}, {"length", 0.05},
                                                   {"tip_radius", 0.003}})),
            "dir/s.json: instruments[0].shape.tip_radius: unknown key");
  EXPECT_EQ(instrument_scene_error(with_instrument_key("name", 3)), "dir/s.json: instruments[0].name: must be a string (value 3)");
  json s = instrument_scene();
  s["instruments"] = {{{"name", "a"}}};
  EXPECT_EQ(instrument_scene_error(s), "dir/s.json: instruments[0].shape: missing key");
  s["instruments"] = json::object();
  EXPECT_EQ(instrument_scene_error(s), "dir/s.json: instruments: must be an array (value {})");
}

TEST(InstrumentScene, DimensionsAreCheckedByTheShapeBuilderUnderTheSceneKey) {
  json s = instrument_scene();
  s["instruments"][0]["shape"]["tip_radius"] = -0.003;
  EXPECT_EQ(instrument_scene_error(s), "dir/s.json: instruments[0].shape.tip_radius: must be > 0 (value -0.003)");
  s = instrument_scene();
  s["instruments"][0]["shape"]["shaft_radius"] = 0.004;
  EXPECT_EQ(instrument_scene_error(s),
            "dir/s.json: instruments[0].shape.shaft_radius: must be <= tip_radius (0.003) (value 0.004)");
  s = instrument_scene();
  s["instruments"][0]["shape"]["segments_around"] = 2;
  EXPECT_NE(instrument_scene_error(s).find("dir/s.json: instruments[0].shape.segments_around: out of range [3, "), std::string::npos);
  s["instruments"][0]["shape"]["segments_around"] = 2.5;
  EXPECT_EQ(instrument_scene_error(s), "dir/s.json: instruments[0].shape.segments_around: must be an integer (value 2.5)");
}

TEST(InstrumentScene, MeshFileErrorsNameTheSceneKeyAndTheFile) {
  const std::string missing = instrument_scene_error(with_instrument_key("shape", {{"type", "mesh"}, {"file", "/nonexistent/t.obj"}}));
  EXPECT_EQ(missing, "dir/s.json: instruments[0].shape.file: /nonexistent/t.obj: no such mesh file (value "
                     "\"/nonexistent/t.obj\")");
  // An open surface: the tetrahedron without its last face.
  const std::string open = write_temp("open_tool.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\n");
  const std::string msg = instrument_scene_error(with_instrument_key("shape", {{"type", "mesh"}, {"file", open}, {"units", "mm"}}));
  EXPECT_EQ(msg.rfind("dir/s.json: instruments[0].shape.file: " + open + ": not closed: ", 0), 0u) << msg;
  EXPECT_EQ(instrument_scene_error(with_instrument_key("shape", {{"type", "mesh"}, {"file", open}, {"units", "cm"}})),
            "dir/s.json: instruments[0].shape.units: must be one of m, mm (value \"cm\")");
}

TEST(InstrumentScene, PoseTrackErrorsNameTheKey) {
  json s = instrument_scene();
  s["instruments"][0]["track"][1]["t"] = 0.0;
  EXPECT_EQ(instrument_scene_error(s), "dir/s.json: instruments[0].track[1].t: times must be strictly increasing (value 0, after 0)");
  s = instrument_scene();
  s["instruments"][0]["track"][0]["t"] = -1.0;
  EXPECT_EQ(instrument_scene_error(s), "dir/s.json: instruments[0].track[0].t: must be >= 0 (value -1.0)");
  s = instrument_scene();
  s["instruments"][0]["track"][1]["rotation"] = {2, 0, 0, 0};
  EXPECT_EQ(instrument_scene_error(s).rfind("dir/s.json: instruments[0].track[1].rotation: not a unit quaternion: norm 2", 0), 0u)
      << instrument_scene_error(s);
  s["instruments"][0]["track"][1]["rotation"] = {1, 0, 0};
  EXPECT_EQ(instrument_scene_error(s), "dir/s.json: instruments[0].track[1].rotation: must be a quaternion [w, x, y, z] or "
                         "{\"axis\", \"angle\"} (value [1,0,0])");
  s["instruments"][0]["track"][1]["rotation"] = {{"axis", {0, 0, 0}}, {"angle", 1.0}};
  EXPECT_EQ(instrument_scene_error(s), "dir/s.json: instruments[0].track[1].rotation.axis: must not be zero (value [0, 0, 0])");
  s["instruments"][0]["track"][1]["rotation"] = {{"axis", {0, 0, 1}}, {"degrees", 1.0}};
  EXPECT_EQ(instrument_scene_error(s), "dir/s.json: instruments[0].track[1].rotation.degrees: unknown key");
  s = instrument_scene();
  s["instruments"][0]["track"][0]["position"] = {0, 1};
  EXPECT_EQ(instrument_scene_error(s), "dir/s.json: instruments[0].track[0].position: must be an array of 3 numbers (value [0,1])");
  EXPECT_EQ(instrument_scene_error(with_instrument_key("track", json::array())), "dir/s.json: instruments[0].track: must not be empty (value [])");
}

TEST(InstrumentScene, SourcesAndTransformAreValidated) {
  json both = instrument_scene();
  both["instruments"][0]["replay"] = "poses.csv";
  EXPECT_EQ(instrument_scene_error(both), "dir/s.json: instruments[0]: needs at most one of \"track\" or \"replay\"");
  json none = with_instrument_key("track", nullptr);
  none["instruments"][0].erase("device_name");
  EXPECT_EQ(instrument_scene_error(none), "dir/s.json: instruments[0]: needs one of \"track\", \"replay\" or \"device_name\"");
  json replay = with_instrument_key("track", nullptr);
  replay["instruments"][0]["replay"] = "missing_poses.csv";
  EXPECT_EQ(instrument_scene_error(replay), "dir/missing_poses.csv: no such pose replay file");
  EXPECT_EQ(instrument_scene_error(with_instrument_key("device_name", "")),
            "dir/s.json: instruments[0].device_name: must not be empty (value \"\")");
  // A scale of 2 is not a rigid transform.
  const std::string scaled = instrument_scene_error(with_instrument_key("to_organ", {2, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}));
  EXPECT_EQ(scaled.rfind("dir/s.json: instruments[0].to_organ", 0), 0u) << scaled;
  EXPECT_NE(scaled.find("orthonormal"), std::string::npos) << scaled;
  EXPECT_EQ(instrument_scene_error(with_instrument_key("to_organ", {1, 0, 0})),
            "dir/s.json: instruments[0].to_organ: must be an array of 16 numbers (row-major 4 x 4) (value [1,0,0])");
  json twice = instrument_scene();
  twice["instruments"].push_back(twice["instruments"][0]);
  EXPECT_EQ(instrument_scene_error(twice), "dir/s.json: instruments[1].name: must be unique among the instruments (value \"probe\")");
}

TEST(InstrumentScene, ResponseAndCouplingMustSuitToolContacts) {
  json paper = instrument_scene();
  paper["collision"] = {{"self", true}, {"response", "paper"}};
  EXPECT_EQ(instrument_scene_error(paper), "dir/s.json: collision.response: instruments need \"constraint\" (value \"paper\")");
  json carried = instrument_scene();
  carried["material"]["model"] = "corotational";
  carried["collision"] = {{"self", true}, {"coupling", "carried"}};
  EXPECT_EQ(instrument_scene_error(carried), "dir/s.json: collision.coupling: instruments need \"correct\" (value \"carried\")");
}

TEST(InstrumentScene, RunRefusesAnInstrumentDrivenOnlyByADevice) {
  // With a track as well, the track drives a run; the device name alone cannot.
  EXPECT_EQ(parse_scene(instrument_scene().dump(), kScenePath).instruments[0].drive, InstrumentDrive::kTrack);
  const Scene only_device = parse_scene(with_instrument_key("track", nullptr).dump(), kScenePath);
  ASSERT_EQ(only_device.instruments[0].drive, InstrumentDrive::kDevice);
  EXPECT_EQ(only_device.instruments[0].device_name, "Tracker");
  EXPECT_EQ(message_of<InputError>([&] { make_inputs(only_device); }),
            "dir/s.json: instruments[0].device_name: poses from a device need the OpenIGTLink bridge: run it with "
            "`lumen serve`, or give the instrument a \"track\" or a \"replay\" (value \"Tracker\")");
}

TEST(InstrumentScene, AStartThroughTheOrgansWallsIsRefusedWhenTheModelCompiles) {
  json s = instrument_scene();
  s["instruments"][0]["track"][0]["position"] = {0.0, 0.012, 0.05};  // the 3 mm tip across the outer wall (13 mm)
  const Scene scene = parse_scene(s.dump(), kScenePath);
  const std::string msg = message_of<InputError>([&] { compile_model(scene); });
  EXPECT_EQ(msg.rfind("dir/s.json: instruments[0].track: starts through the organ's walls at t = 0 (", 0), 0u) << msg;
  EXPECT_NE(msg.find("intersecting triangle pairs; value position [0, 0.012, 0.05])"), std::string::npos) << msg;
  // The example's start, 17 mm above the wall, compiles.
  EXPECT_NO_THROW(compile_model(parse_scene(instrument_scene().dump(), kScenePath)));
}

// render.camera {"endoscope": NAME}: the endoscope preset riding on the named instrument; the name must be one of
// the scene's instruments, and the object holds that key alone.
TEST(InstrumentScene, EndoscopeCameraRidesOnANamedInstrument) {
  json s = instrument_scene();
  s["render"] = {{"camera", {{"endoscope", "probe"}}}};
  const Scene ok = parse_scene(s.dump(), kScenePath);
  EXPECT_EQ(ok.render.camera, lumen::render::CameraPreset::Endoscope);
  EXPECT_EQ(ok.render.scope_instrument, "probe");
  EXPECT_TRUE(parse_scene(instrument_scene().dump(), kScenePath).render.scope_instrument.empty());
  s["render"]["camera"]["endoscope"] = "scope";
  EXPECT_EQ(instrument_scene_error(s), "dir/s.json: render.camera.endoscope: names no instrument of the scene (value \"scope\")");
  s["render"]["camera"] = {{"endoscope", 3}};
  EXPECT_NE(instrument_scene_error(s).find("render.camera.endoscope"), std::string::npos) << instrument_scene_error(s);
  s["render"]["camera"] = {{"endoscope", "probe"}, {"fov", 70}};
  EXPECT_NE(instrument_scene_error(s).find("render.camera"), std::string::npos) << instrument_scene_error(s);
  EXPECT_NE(instrument_scene_error(s).find("fov"), std::string::npos) << instrument_scene_error(s);
  s["render"]["camera"] = json::object();
  EXPECT_NE(instrument_scene_error(s).find("render.camera"), std::string::npos) << instrument_scene_error(s);
  EXPECT_NE(instrument_scene_error(s).find("endoscope"), std::string::npos) << instrument_scene_error(s);
}

namespace {
// The issue's example with its probe replaced by a grasper (jaws open 60 degrees).
json grasper_scene() {
  json s = instrument_scene();
  s["instruments"][0]["shape"] = {{"type", "grasper"}, {"jaw_length", 0.012}, {"jaw_width", 0.004},
                                  {"jaw_thickness", 0.0015}, {"opening_angle", 1.0}, {"shaft_radius", 0.0025},
                                  {"shaft_length", 0.08}};
  return s;
}
}  // namespace

// A grasper's track keys may give the jaws' opening, and "grasp" makes it hold what it closes on; both are a
// grasper's alone, checked with the key path and the value.
TEST(InstrumentScene, GrasperOpeningTrackAndGraspKeys) {
  json s = grasper_scene();
  s["instruments"][0]["track"][0]["opening"] = 1.0;
  s["instruments"][0]["track"][1]["opening"] = 0.25;
  s["instruments"][0]["grasp"] = {{"grip_force_n", 0.02}, {"release_margin", 0.1}};
  const Scene ok = parse_scene(s.dump(), kScenePath);
  const InstrumentSpec& in = ok.instruments[0];
  ASSERT_EQ(in.openings.size(), 2u);
  EXPECT_EQ(in.openings[1].t, 2.0);
  EXPECT_EQ(in.openings[1].angle, 0.25);
  EXPECT_TRUE(in.grasp.enabled);
  EXPECT_EQ(in.grasp.grip_force_n, 0.02);
  EXPECT_EQ(in.grasp.release_margin, 0.1);
  // Defaults, and no grasp without the key.
  json d = grasper_scene();
  d["instruments"][0]["grasp"] = json::object();
  const GraspSpec g = parse_scene(d.dump(), kScenePath).instruments[0].grasp;
  EXPECT_TRUE(g.enabled);
  EXPECT_EQ(g.grip_force_n, kDefaultGripForce);
  EXPECT_EQ(g.release_margin, kDefaultReleaseMargin);
  EXPECT_FALSE(parse_scene(grasper_scene().dump(), kScenePath).instruments[0].grasp.enabled);

  json bad = s;
  bad["instruments"][0]["track"][1]["opening"] = 4.0;
  EXPECT_NE(instrument_scene_error(bad).find("instruments[0].track[1].opening"), std::string::npos) << instrument_scene_error(bad);
  bad = s;
  bad["instruments"][0]["grasp"]["grip_force_n"] = -1.0;
  EXPECT_NE(instrument_scene_error(bad).find("instruments[0].grasp.grip_force_n"), std::string::npos) << instrument_scene_error(bad);
  bad = s;
  bad["instruments"][0]["grasp"]["release_margin"] = 0.0;
  EXPECT_NE(instrument_scene_error(bad).find("instruments[0].grasp.release_margin"), std::string::npos) << instrument_scene_error(bad);
  bad = s;
  bad["instruments"][0]["grasp"]["hold"] = true;
  EXPECT_NE(instrument_scene_error(bad).find("hold"), std::string::npos) << instrument_scene_error(bad);
  // A probe has no jaws.
  json probe = instrument_scene();
  probe["instruments"][0]["grasp"] = json::object();
  EXPECT_EQ(instrument_scene_error(probe), "dir/s.json: instruments[0].grasp: needs shape.type \"grasper\" (value {})");
  probe = instrument_scene();
  probe["instruments"][0]["track"][0]["opening"] = 0.5;
  EXPECT_NE(instrument_scene_error(probe).find("instruments[0].track[0]"), std::string::npos) << instrument_scene_error(probe);
  EXPECT_NE(instrument_scene_error(probe).find("opening"), std::string::npos) << instrument_scene_error(probe);
  // Holds are prescribed displacements of the linear quasi-static model.
  bad = s;
  bad["material"]["model"] = "corotational";
  EXPECT_EQ(instrument_scene_error(bad), "dir/s.json: instruments[0].grasp: needs material.model \"linear\" and solver.type "
                           "\"quasi_static\" (value {\"grip_force_n\":0.02,\"release_margin\":0.1})");
}

// The commanded opening: linear between keys, held outside them, the rest opening without keys.
TEST(Grasp, CommandedOpeningInterpolatesTheKeys) {
  const std::vector<OpeningKey> keys = {{0.5, 1.0}, {1.5, 0.0}, {2.5, 0.4}};
  EXPECT_EQ(commanded_opening({}, 0.7, 3.0), 0.7);
  EXPECT_EQ(commanded_opening(keys, 0.7, 0.0), 1.0);
  EXPECT_DOUBLE_EQ(commanded_opening(keys, 0.7, 0.75), 0.75);
  EXPECT_DOUBLE_EQ(commanded_opening(keys, 0.7, 1.5), 0.0);
  EXPECT_DOUBLE_EQ(commanded_opening(keys, 0.7, 2.0), 0.2);
  EXPECT_EQ(commanded_opening(keys, 0.7, 9.0), 0.4);
}

TEST(InstrumentScene, ADeviceHomeThroughTheOrgansWallsIsRefusedWhenTheModelCompiles) {
  // Device only: home is the device origin mapped by to_organ, here with the tip across the outer wall.
  json s = with_instrument_key("track", nullptr);
  s["instruments"][0]["to_organ"] = {1, 0, 0, 0, 0, 1, 0, 0.012, 0, 0, 1, 0.05, 0, 0, 0, 1};
  const Scene scene = parse_scene(s.dump(), kScenePath);
  EXPECT_EQ(home_pose(scene.instruments[0]).position, Eigen::Vector3d(0.0, 0.012, 0.05));
  const std::string msg = message_of<InputError>([&] { compile_model(scene); });
  EXPECT_EQ(msg.rfind("dir/s.json: instruments[0].to_organ: starts through the organ's walls at t = 0 (", 0), 0u) << msg;
  // 17 mm above the wall it compiles.
  s["instruments"][0]["to_organ"][7] = 0.03;
  EXPECT_NO_THROW(compile_model(parse_scene(s.dump(), kScenePath)));
}

// collision.max_contact_rows: a positive integer, default kDefaultMaxContactRows.
TEST(InstrumentScene, MaxContactRowsIsAPositiveInteger) {
  json s = instrument_scene();
  EXPECT_EQ(parse_scene(s.dump(), kScenePath).collision.max_contact_rows, kDefaultMaxContactRows);
  s["collision"] = {{"max_contact_rows", 250}};
  EXPECT_EQ(parse_scene(s.dump(), kScenePath).collision.max_contact_rows, 250);
  s["collision"]["max_contact_rows"] = 0;
  EXPECT_NE(instrument_scene_error(s).find("collision.max_contact_rows"), std::string::npos) << instrument_scene_error(s);
  EXPECT_NE(instrument_scene_error(s).find("value 0"), std::string::npos) << instrument_scene_error(s);
  s["collision"]["max_contact_rows"] = 2.5;
  EXPECT_NE(instrument_scene_error(s).find("collision.max_contact_rows"), std::string::npos) << instrument_scene_error(s);
}
