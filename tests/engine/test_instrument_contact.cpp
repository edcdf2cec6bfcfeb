// Instruments touching the organ (sessions on a small tube): the tool never penetrates (exact intersection count,
// signed distances by brute force, organ nodes inside the tool by ray parity), the force on the instrument is
// minus the organ's elastic response K u, the safe fallback stops the tool short, and a tool that touches nothing
// leaves the session exactly as it is without it.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "engine/session.hpp"
#include "support/files.hpp"
#include "support/instruments.hpp"
#include "support/tube.hpp"

using namespace lumen::engine;
using nlohmann::json;

namespace {

using lumen::test::kPaperOuterRadius;
constexpr double kGap = 1e-4;  // the scene's collision gap, metres

// A small tube pressed from above by a 3 mm sphere-tipped probe moving from 0.5 mm above the outer wall to
// `depth` metres below it in `press_frames` frames (40 fps), then held.
json press_scene(double depth, int press_frames, int frames) {
  json s = lumen::test::small_tube_scene("tool-press");
  s["instruments"] = {{{"name", "probe"},
                       {"shape", {{"type", "sphere_probe"}, {"tip_radius", 0.003}, {"shaft_radius", 0.002},
                                  {"shaft_length", 0.04}}}}};
  s["collision"] = {{"self", true}, {"gap", kGap}};
  constexpr double kStartClearance = 0.0005;
  const double t1 = press_frames / s["fps"].get<double>();
  s["frames"] = frames;
  s["instruments"][0]["track"] = {{{"t", 0.0}, {"position", {0.0, kPaperOuterRadius + kStartClearance, 0.05}}},
                                  {{"t", t1}, {"position", {0.0, kPaperOuterRadius - depth, 0.05}}}};
  return s;
}

lumen::test::CheckedRun run_checked(const json& scene_json, const std::string& path = "tool.json") {
  return lumen::test::run_checked(parse_scene(scene_json.dump(), path));
}

}  // namespace

TEST(InstrumentSession, ProbePressNeverPenetratesTheOrgan) {
  const lumen::test::CheckedRun c = run_checked(press_scene(0.003, 20, 24));
  const int touching = lumen::test::expect_tool_clear(c, kGap);
  // The tool really pressed (3 mm past the wall): contact on most frames, the wall pushed in by millimetres.
  EXPECT_GT(touching, 12);
  EXPECT_GT(c.result.frames.back().max_displacement, 0.002);
}

TEST(InstrumentSession, ForceOnTheToolIsMinusTheOrgansElasticResponse) {
  const lumen::test::CheckedRun c = run_checked(press_scene(0.002, 16, 20));
  int compared = 0;
  for (size_t i = 0; i < c.result.frames.size(); ++i) {
    const FrameRecord& f = c.result.frames[i];
    ASSERT_FALSE(f.fallback) << "frame " << f.frame;  // K u = contact forces holds for a solved frame
    const InstrumentRecord& tool = f.instruments[0];
    // Linear quasi-static without other loads: K u on the free nodes is what the contacts put on the organ.
    const Eigen::Vector3d organ = c.elastic[i].force;
    EXPECT_LE((tool.force + organ).norm(), 1e-6 * organ.norm() + 1e-12) << "frame " << f.frame;
    if (tool.contacts == 0) continue;
    ++compared;
    // The organ pushes the tool back up, against its motion (-y).
    EXPECT_GT(tool.force.y(), 0.0) << "frame " << f.frame;
    // Torque about the tip: the organ-side and tool-side points of a row are at most a few gaps apart, so the two
    // moments differ by at most |F| times that.
    EXPECT_LE((tool.torque + c.elastic[i].torque).norm(), tool.force.norm() * 10.0 * kGap) << "frame " << f.frame;
  }
  EXPECT_GT(compared, 5);
}

TEST(InstrumentSession, SafeFallbackStopsTheToolsShortOfTheirTargets) {
  // Two probes, above and below (turned half a turn about z), each 12 mm in over eight frames: the lumen shuts,
  // and with a single response round the re-check finds the walls' new self-contacts, so the fallback ends the
  // last frames.
  constexpr double kDepth = 0.012, kStart = kPaperOuterRadius + 0.0005;
  constexpr int kFrames = 8;
  json s = press_scene(kDepth, kFrames, kFrames);
  s["collision"]["max_iterations"] = 1;
  json below = s["instruments"][0];
  below["name"] = "below";
  for (json& key : below["track"]) {
    key["position"][1] = -key["position"][1].get<double>();
    key["rotation"] = {0, 0, 0, 1};
  }
  s["instruments"].push_back(below);
  const lumen::test::CheckedRun c = run_checked(s);
  int fallbacks = 0;
  for (size_t i = 0; i < c.result.frames.size(); ++i) {
    const FrameRecord& f = c.result.frames[i];
    EXPECT_EQ(f.instrument_intersecting_pairs, 0) << "frame " << f.frame;
    EXPECT_EQ(f.intersecting_pairs, 0) << "frame " << f.frame;
    EXPECT_GE(c.clearance[i].min_tool_vertex, 0.0) << "frame " << f.frame;
    EXPECT_EQ(c.clearance[i].organ_nodes_inside_tool, 0) << "frame " << f.frame;
    if (!f.fallback) continue;
    ++fallbacks;
    // Held back by the organ: each tool ends the frame short of where its track wanted it.
    const double target_y = kStart + (kPaperOuterRadius - kDepth - kStart) * f.frame / kFrames;
    EXPECT_GT(f.instruments[0].position.y(), target_y) << "frame " << f.frame;
    EXPECT_LT(f.instruments[1].position.y(), -target_y) << "frame " << f.frame;
  }
  EXPECT_GT(fallbacks, 0);
}

TEST(InstrumentSession, AToolThatTouchesNothingLeavesTheSessionExactlyAsWithout) {
  // A force press whose walls meet (self-contacts), with and without a static probe far above the tube.
  json with_tool = press_scene(0.0, 1, 30);
  with_tool["probes"] = {{{"point", {0.0, kPaperOuterRadius, 0.05}},
                          {"track", {{{"t", 0.0}, {"force", {0, 0, 0}}}, {{"t", 0.5}, {"force", {0, -0.3, 0}}}}}}};
  constexpr double kFarAbove = 0.05;
  with_tool["instruments"][0]["track"] = {{{"t", 0.0}, {"position", {0.0, kFarAbove, 0.05}}}};
  json without = with_tool;
  without.erase("instruments");
  const lumen::test::CheckedRun a = run_checked(with_tool);
  const lumen::test::CheckedRun b = run_checked(without);
  long self_contacts = 0;
  for (const FrameRecord& f : b.result.frames) self_contacts += f.contacts;
  EXPECT_GT(self_contacts, 0);  // the walls met, so the contact solve ran in both
  for (const FrameRecord& f : a.result.frames) EXPECT_EQ(f.instruments[0].contacts, 0);
  EXPECT_TRUE(a.final_x == b.final_x) << "largest difference " << (a.final_x - b.final_x).cwiseAbs().maxCoeff() << " m";
}

TEST(InstrumentSession, AReplayOfTheTrackGivesTheSameSessionAndTheSourceGetsTheForces) {
  const json tracked = press_scene(0.002, 10, 12);
  const Scene track_scene = parse_scene(tracked.dump(), "tool.json");
  // The track's own keys written as a pose file, replayed.
  const std::string csv = (std::filesystem::temp_directory_path() / "lumen_test_press_poses.csv").string();
  write_pose_csv(csv, track_scene.instruments[0].poses);
  json replayed = tracked;
  replayed["instruments"][0].erase("track");
  replayed["instruments"][0]["replay"] = csv;
  const lumen::test::CheckedRun a = lumen::test::run_checked(track_scene);
  const lumen::test::CheckedRun b = run_checked(replayed);
  EXPECT_TRUE(a.final_x == b.final_x);
  ASSERT_EQ(a.result.frames.size(), b.result.frames.size());
  for (size_t i = 0; i < a.result.frames.size(); ++i)
    EXPECT_EQ(a.result.frames[i].instruments[0].force, b.result.frames[i].instruments[0].force) << "frame " << i + 1;
  // Stepped by hand, the pose source is handed the force and torque of every frame, as the session reported them.
  Inputs inputs = make_inputs(track_scene);
  State state = make_state(*a.model);
  for (size_t i = 0; i < a.result.frames.size(); ++i) {
    FrameRecord rec;
    step(*a.model, inputs, state, rec);
    EXPECT_EQ(rec.instruments[0].force, a.result.frames[i].instruments[0].force) << "frame " << i + 1;
  }
  const auto& source = dynamic_cast<const PoseTrackSource&>(*inputs.instruments[0]);
  ASSERT_EQ(source.forces().size(), a.result.frames.size());
  for (size_t i = 0; i < a.result.frames.size(); ++i) {
    EXPECT_EQ(source.forces()[i], a.result.frames[i].instruments[0].force) << "frame " << i + 1;
    EXPECT_EQ(source.torques()[i], a.result.frames[i].instruments[0].torque) << "frame " << i + 1;
  }
  EXPECT_GT(a.result.frames.back().instruments[0].force.norm(), 0.0);  // the press touched
}

TEST(InstrumentSession, AProbeInsideTheLumenPressesTheInnerWallWithoutPenetrating) {
  // The probe lies along the lumen (its shaft turned from +y onto +z) and moves up from the axis until its 3 mm
  // tip reaches 2 mm past the inner wall (10 mm): it touches the inner wall only.
  constexpr double kInnerRadius = 0.01, kTipRadius = 0.003, kPastWall = 0.002;
  json s = press_scene(0.0, 1, 16);
  // A short shaft, ending 27 mm before the fixed end: a contact on a face with fixed nodes would put part of the
  // tool's force into the support, outside the free nodes' K u.
  s["instruments"][0]["shape"]["shaft_length"] = 0.02;
  const json along_lumen = {{"axis", {1, 0, 0}}, {"angle", EIGEN_PI / 2}};
  s["instruments"][0]["track"] = {
      {{"t", 0.0}, {"position", {0.0, 0.0, 0.05}}, {"rotation", along_lumen}},
      {{"t", 0.3}, {"position", {0.0, kInnerRadius - kTipRadius + kPastWall, 0.05}}, {"rotation", along_lumen}}};
  const lumen::test::CheckedRun c = run_checked(s);
  const std::vector<int>& inner = c.model->inner_nodes;
  int touching = 0;
  for (size_t i = 0; i < c.result.frames.size(); ++i) {
    const FrameRecord& f = c.result.frames[i];
    EXPECT_EQ(f.instrument_intersecting_pairs, 0) << "frame " << f.frame;
    EXPECT_EQ(f.intersecting_pairs, 0) << "frame " << f.frame;
    EXPECT_GE(c.clearance[i].min_tool_vertex, 0.25 * kGap) << "frame " << f.frame;
    EXPECT_EQ(c.clearance[i].organ_nodes_inside_tool, 0) << "frame " << f.frame;
    const InstrumentRecord& tool = f.instruments[0];
    EXPECT_LE((tool.force + c.elastic[i].force).norm(), 1e-6 * c.elastic[i].force.norm() + 1e-12) << "frame " << f.frame;
    if (tool.contacts == 0) continue;
    ++touching;
    EXPECT_LT(tool.force.y(), 0.0) << "frame " << f.frame;  // the wall pushes the probe back down, to the axis
  }
  EXPECT_GT(touching, 4);
  // The inner wall moved outwards (up) above the probe.
  double highest_rise = 0.0;
  for (int v : inner) highest_rise = std::max(highest_rise, c.final_x(v, 1) - c.model->mesh.rest(v, 1));
  EXPECT_GT(highest_rise, 0.5 * kPastWall);
}

// The same press on an organ mesh that is not the cylinder: a swept tube with haustra (8 mm lumen, 1.5 mm deep
// sacculations every 20 mm, 2.5 mm wall; a straight centreline file in millimetres), pressed 3 mm at a bulge
// (outer wall 12 mm from the axis). The tool never penetrates (exact intersection count, brute-force clearance),
// the wall is pushed in by millimetres, and the force on the tool is minus the organ's elastic response K u.
TEST(InstrumentSession, ProbePressOnASweptTubeWithHaustraNeverPenetrates) {
  const std::filesystem::path d = lumen::test::fresh_temp_dir("lumen_tool_", "swept");
  json line;
  line["n"] = 11;
  for (int k = 0; k <= 10; ++k) line["points"].push_back({0.0, 0.0, 10.0 * k});
  std::ofstream(d / "line.json") << line.dump();
  json s = json::parse(R"({
    "name": "tool-swept",
    "mesh": {"type": "swept_tube", "centreline": "line.json", "units": "mm", "range": [20.0, 80.0],
             "radius": 8.0, "wall_thickness": 2.5, "segments_around": 16, "segment_length": 2.5, "layers": 2,
             "haustra": {"depth": 1.5, "pitch": 20.0}},
    "material": {"model": "linear", "young_modulus": 5000.0, "poisson_ratio": 0.45, "density": 1050.0},
    "fixed": ["ends"], "probes": [], "frames": 24, "fps": 40,
    "instruments": [{"name": "probe", "shape": {"type": "sphere_probe", "tip_radius": 0.003, "shaft_radius": 0.002,
                                                "shaft_length": 0.04}}],
    "collision": {"self": true, "gap": 0.0001}
  })");
  // The tip from 0.5 mm above the bulge's outer wall (12 mm from the axis) to 3 mm below it in 20 frames.
  s["instruments"][0]["track"] = {{{"t", 0.0}, {"position", {0.0, 0.012 + 0.0005, 0.05}}},
                                  {{"t", 0.5}, {"position", {0.0, 0.012 - 0.003, 0.05}}}};
  std::ofstream(d / "s.json") << s.dump();
  const lumen::test::CheckedRun c = run_checked(s, (d / "s.json").string());
  lumen::test::expect_tool_clear(c, kGap);
  int compared = 0;  // solved frames with contact: the force on the tool balances K u
  for (size_t i = 0; i < c.result.frames.size(); ++i) {
    const FrameRecord& f = c.result.frames[i];
    if (f.fallback || f.instruments.empty() || f.instruments[0].contacts == 0) continue;
    ++compared;
    EXPECT_LE((f.instruments[0].force + c.elastic[i].force).norm(), 1e-6 * c.elastic[i].force.norm() + 1e-12)
        << "frame " << f.frame;
    EXPECT_GT(f.instruments[0].force.y(), 0.0) << "frame " << f.frame;
  }
  EXPECT_GT(compared, 8);
  EXPECT_GT(c.result.frames.back().max_displacement, 0.002);
}
