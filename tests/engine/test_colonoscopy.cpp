// A swept tube's centreline used by the scene: "fixed" {"near_centreline": [s0, s1]} holds exactly the outer-wall
// nodes whose nearest centreline point (found here by dense sampling of the file's polyline) lies in the interval,
// and render.camera {"centreline": {"from", "to"}} flies the endoscope along the centreline (eye at the arc length
// walked along the file, on the centre of the tube's rings, looking down their axis, inside the lumen, seeing
// wall); every refusal names the key path and the value.
#include <gtest/gtest.h>


#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "collision/distance.hpp"
#include "engine/scene.hpp"
#include "engine/session.hpp"
#include "engine/simulation.hpp"
#include "render/renderer.hpp"
#include "support/files.hpp"

namespace fs = std::filesystem;
using lumen::engine::InputError;
using nlohmann::json;

namespace {

// The shipped colon segment's scene (arc length 200-400 mm of the CT centreline, rings every 5 mm, 16 around,
// 2 layers) and its centreline file.
const std::string kColonScene = std::string(LUMEN_SOURCE_DIR) + "/scenes/colon-sigmoid-pinch.json";
const std::string kColonCentreline =
    std::string(LUMEN_SOURCE_DIR) + "/data/organs/gca-EdinGCA_3D_00090-large_intestine_path.jsn";
// Its mesh: 16 nodes around each ring, 2 cells through the wall, rings every 5 mm from 200 mm.
constexpr int kAround = 16;
constexpr int kLayers = 2;
constexpr double kRingStartMm = 200.0;
constexpr double kRingStepMm = 5.0;
constexpr double kMetresPerMm = 0.001;

// The colon segment with the given fixed sets and camera, no probes, self-collision off (quick to compile), written
// to a temporary file with the centreline file's absolute path; the scene's path.
std::string colon_variant(const std::string& name, const json& fixed, const json& camera, int frames) {
  std::ifstream in(kColonScene);
  json scene = json::parse(in);
  scene["name"] = name;
  scene["mesh"]["centreline"] = kColonCentreline;
  scene["fixed"] = fixed;
  scene["probes"] = json::array();
  scene["collision"]["self"] = false;
  scene["frames"] = frames;
  scene["render"]["width"] = 160;
  scene["render"]["height"] = 120;
  scene["render"]["camera"] = camera;
  const fs::path path = fs::temp_directory_path() / ("lumen_colonoscopy_" + name + ".json");
  std::ofstream(path) << scene.dump();
  return path.string();
}

// Loads and compiles a scene file, removing the file.
std::unique_ptr<lumen::engine::Model> compile_file(const std::string& path) {
  struct Remove {
    std::string p;
    ~Remove() { fs::remove(p); }
  } remove{path};
  return lumen::engine::compile_model(lumen::engine::load_scene(path));
}

// The centreline file's points in metres (read here, independently of the scene loader).
std::vector<Eigen::Vector3d> file_points() {
  std::ifstream in(kColonCentreline);
  const json c = json::parse(in);
  std::vector<Eigen::Vector3d> p;
  for (const json& row : c.at("points"))
    p.emplace_back(kMetresPerMm * row[0].get<double>(), kMetresPerMm * row[1].get<double>(),
                   kMetresPerMm * row[2].get<double>());
  return p;
}

// The point at arc length s along the polyline, walking its segments from the first point.
Eigen::Vector3d point_at(const std::vector<Eigen::Vector3d>& p, double s) {
  double walked = 0.0;
  for (size_t i = 0; i + 1 < p.size(); ++i) {
    const double len = (p[i + 1] - p[i]).norm();
    if (s <= walked + len) return p[i] + (s - walked) / len * (p[i + 1] - p[i]);
    walked += len;
  }
  return p.back();
}

// Samples of the polyline at spacing at most h (every vertex included) with their arc lengths.
struct Samples {
  std::vector<Eigen::Vector3d> x;
  std::vector<double> s;
};
Samples sample_polyline(const std::vector<Eigen::Vector3d>& p, double h) {
  Samples out;
  double walked = 0.0;
  for (size_t i = 0; i + 1 < p.size(); ++i) {
    const double len = (p[i + 1] - p[i]).norm();
    const int n = std::max(1, static_cast<int>(std::ceil(len / h)));
    for (int k = 0; k < n; ++k) {
      out.x.push_back(p[i] + (static_cast<double>(k) / n) * (p[i + 1] - p[i]));
      out.s.push_back(walked + len * k / n);
    }
    walked += len;
  }
  out.x.push_back(p.back());
  out.s.push_back(walked);
  return out;
}

// The arc length of the sample nearest to x (brute force over every sample).
double nearest_sample_s(const Samples& samples, const Eigen::Vector3d& x) {
  double best = std::numeric_limits<double>::infinity(), s = 0.0;
  for (size_t k = 0; k < samples.x.size(); ++k) {
    const double d2 = (samples.x[k] - x).squaredNorm();
    if (d2 < best) {
      best = d2;
      s = samples.s[k];
    }
  }
  return s;
}

// Node id of the structured tube's grid point (i around, ring j, layer k): make_structured_tube's numbering.
int tube_node(int i, int j, int k) { return (j * (kLayers + 1) + k) * kAround + i; }

// The lumen program's exit status and output for a command line.
int run_lumen(const std::string& args, std::string& output) {
  const lumen::test::CommandRun r = lumen::test::run_command(std::string(LUMEN_BINARY) + " " + args + " 2>&1");
  output += r.output;
  return r.code;
}

// A swept tube on a straight 100 mm centreline along +z (millimetres, range 20-80 mm), for the refusals.
json straight_scene() {
  return json::parse(R"({
    "name": "straight",
    "mesh": {"type": "swept_tube", "centreline": "line.json", "units": "mm", "range": [20.0, 80.0],
             "radius": 8.0, "wall_thickness": 2.5, "segments_around": 12, "segment_length": 5.0, "layers": 2},
    "material": {"model": "linear", "young_modulus": 5000.0, "poisson_ratio": 0.45},
    "fixed": ["ends"], "probes": [], "frames": 4, "fps": 40,
    "render": {"width": 160, "height": 120}
  })");
}

// Writes the straight scene (and its centreline) into a fresh folder; the scene's path.
std::string write_straight(const std::string& name, const json& scene) {
  const fs::path d = fs::temp_directory_path() / ("lumen_colonoscopy_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  json line;
  for (int k = 0; k <= 10; ++k) line["points"].push_back({0.0, 0.0, 10.0 * k});
  std::ofstream(d / "line.json") << line.dump();
  std::ofstream(d / "s.json") << scene.dump();
  return (d / "s.json").string();
}

// The InputError of loading (and then compiling) a scene ("" when both succeed).
std::string compile_error_of(const std::string& path) {
  return lumen::test::message_of<InputError>([&] { lumen::engine::compile_model(lumen::engine::load_scene(path)); });
}

// Blue at most this fraction of red: the lumen wall's colour (mucosa, blue 0.28 of red under any white light), not the
// outer wall's (serosa, 0.65), the wall section's (0.57) or the background's (blue above red).
constexpr double kMucosaBlueToRed = 0.45;

// Share of an image's pixels coloured like the lumen's wall (the mucosa): red above green, blue at most
// kMucosaBlueToRed of red.
double mucosa_share(const lumen::render::Image& image) {
  size_t wall = 0;
  const size_t n = static_cast<size_t>(image.width) * image.height;
  for (size_t p = 0; p < n; ++p) {
    const int r = image.rgb[3 * p], g = image.rgb[3 * p + 1], b = image.rgb[3 * p + 2];
    wall += r > g && b <= kMucosaBlueToRed * r;
  }
  return static_cast<double>(wall) / static_cast<double>(n);
}

}  // namespace

// near_centreline on the real colon segment (a curved CT centreline): the fixed nodes are outer-wall nodes, and
// every outer-wall node whose nearest point on the whole file's polyline (dense sampling, 0.02 mm) lies clearly
// inside the interval is held, every one clearly outside is not.
TEST(NearCentreline, HoldsTheOuterWallNodesWhoseNearestCentrelinePointIsInTheInterval) {
  constexpr double kS0Mm = 252.5, kS1Mm = 280.0;
  const auto model = compile_file(colon_variant("near", json::parse(R"([{"near_centreline": [252.5, 280.0]}])"),
                                                "diagonal", 1));
  std::vector<int> outer(model->outer_wall().data(), model->outer_wall().data() + model->outer_wall().size());
  std::sort(outer.begin(), outer.end());
  outer.erase(std::unique(outer.begin(), outer.end()), outer.end());
  const std::vector<int>& fixed = model->fixed_nodes;
  for (int v : fixed) EXPECT_TRUE(std::binary_search(outer.begin(), outer.end(), v)) << v << " is not on the outer wall";

  // The twin: each outer node's nearest sample of the polyline, sampled far finer than the rings (5 mm).
  constexpr double kSpacing = 2e-5;  // metres between samples
  const Samples samples = sample_polyline(file_points(), kSpacing);
  const double s0 = kS0Mm * kMetresPerMm, s1 = kS1Mm * kMetresPerMm;
  int inside = 0, outside = 0, undecided = 0;
  double off_ring = 0.0;  // largest distance, in arc length, of a node's nearest centreline point from its ring's
  for (int v : outer) {
    const double s = nearest_sample_s(samples, model->mesh.rest.row(v).transpose());
    const int ring = v / (kAround * (kLayers + 1));
    off_ring = std::max(off_ring, std::abs(s - (kRingStartMm + kRingStepMm * ring) * kMetresPerMm));
    const bool held = std::binary_search(fixed.begin(), fixed.end(), v);
    if (s >= s0 + kSpacing && s <= s1 - kSpacing) {
      EXPECT_TRUE(held) << "node " << v << " nearest at " << s;
      ++inside;
    } else if (s <= s0 - kSpacing || s >= s1 + kSpacing) {
      EXPECT_FALSE(held) << "node " << v << " nearest at " << s;
      ++outside;
    } else {
      ++undecided;
    }
  }
  // Both sides are populated, and the interval's ends cut through rings (not between them): some nodes of a ring
  // held and some not, which a selection by whole rings would not give.
  EXPECT_GT(inside, 5 * kAround);
  EXPECT_GT(outside, 20 * kAround);
  EXPECT_LE(undecided, kAround);
  std::printf("outer-wall nodes: %d inside, %d outside, %d within %.2g m of an end; nearest centreline points up to "
              "%.3g mm from their ring's arc length\n", inside, outside, undecided, kSpacing, off_ring / kMetresPerMm);
  // Rings 10 and 11 (250 and 255 mm) lie on either side of the interval's start; ring 16 (280 mm) on its end.
  const int ring_250 = 10, ring_280 = 16;
  int held_250 = 0, held_255 = 0;
  for (int i = 0; i < kAround; ++i) {
    held_250 += std::binary_search(fixed.begin(), fixed.end(), tube_node(i, ring_250, kLayers));
    held_255 += std::binary_search(fixed.begin(), fixed.end(), tube_node(i, ring_250 + 1, kLayers));
  }
  EXPECT_EQ(held_250, 0);
  EXPECT_EQ(held_255, kAround);
  int held_280 = 0;
  for (int i = 0; i < kAround; ++i) held_280 += std::binary_search(fixed.begin(), fixed.end(), tube_node(i, ring_280, kLayers));
  EXPECT_GT(held_280, 0);
  EXPECT_LT(held_280, kAround);
}

// near_centreline's refusals: another mesh type, a malformed or reversed interval, one outside the centreline, and
// one that selects no outer-wall node (when the model compiles), each naming the key path and the value; lumen run
// exits 2 on the last with nothing written.
TEST(NearCentreline, RefusalsNameTheKeyPathAndTheValue) {
  json s = straight_scene();
  s["fixed"] = json::parse(R"(["ends", {"near_centreline": [30.0, 50.0]}])");
  const std::string ok = write_straight("ok", s);
  EXPECT_EQ(compile_error_of(ok), "");
  auto message = [](const std::string& name, const json& scene) {
    const std::string path = write_straight(name, scene);
    std::string m = compile_error_of(path);
    const std::string prefix = path + ": ";
    return m.rfind(prefix, 0) == 0 ? m.substr(prefix.size()) : "(no prefix) " + m;
  };
  s["fixed"][1]["near_centreline"] = json::parse("[50.0, 40.0]");
  EXPECT_EQ(message("reversed", s), "fixed[1].near_centreline: must be [s0, s1] with s0 < s1 (value [50.0,40.0])");
  s["fixed"][1]["near_centreline"] = json::parse("[50.0, 50.0]");
  EXPECT_EQ(message("empty", s), "fixed[1].near_centreline: must be [s0, s1] with s0 < s1 (value [50.0,50.0])");
  s["fixed"][1]["near_centreline"] = json::parse("[50.0, 120.0]");
  const std::string line = (fs::temp_directory_path() / "lumen_colonoscopy_outside" / "line.json").string();
  EXPECT_EQ(message("outside", s), "fixed[1].near_centreline[1]: must lie within the centreline's arc length of " +
                                       line + " [0, 100] (value 120.0)");
  s["fixed"][1]["near_centreline"] = json::parse("[-5.0, 10.0]");
  EXPECT_EQ(message("before", s), "fixed[1].near_centreline[0]: must lie within the centreline's arc length of " +
                                      (fs::temp_directory_path() / "lumen_colonoscopy_before" / "line.json").string() +
                                      " [0, 100] (value -5.0)");
  s["fixed"][1]["near_centreline"] = 30.0;
  EXPECT_EQ(message("scalar", s), "fixed[1].near_centreline: must be [s0, s1] (arc lengths along the centreline) (value 30.0)");
  // Outer-wall nodes lie around the range 20-80 mm only: [2, 10] holds none.
  s["fixed"][1]["near_centreline"] = json::parse("[2.0, 10.0]");
  EXPECT_EQ(message("none", s), "fixed[1]: selects no outer-wall node (none has its nearest centreline point in the "
                                "interval) (value {\"near_centreline\":[2.0,10.0]})");
  // Any other mesh type.
  json cylinder = straight_scene();
  cylinder["mesh"] = json::parse(R"({"type": "hollow_cylinder", "inner_radius": 0.01, "outer_radius": 0.013,
                                     "length": 0.1, "segments_around": 12, "segments_along": 10, "layers": 2})");
  cylinder["fixed"] = json::parse(R"([{"near_centreline": [1, 2]}])");
  EXPECT_EQ(message("cylinder", cylinder),
            "fixed[0].near_centreline: needs mesh.type \"swept_tube\" (got \"hollow_cylinder\") (value [1,2])");
  // lumen run: exit 2, the message, nothing written.
  const std::string none = write_straight("cli", s);
  const fs::path out = fs::path(none).parent_path() / "out";
  std::string output;
  EXPECT_EQ(run_lumen("run " + none + " --out " + out.string(), output), 2) << output;
  EXPECT_NE(output.find(none + ": fixed[1]: selects no outer-wall node"), std::string::npos) << output;
  EXPECT_TRUE(!fs::exists(out) || fs::is_empty(out));
}

// The flight's eye at frame k of 16, from 210 to 290 mm: the point of the file's polyline at arc length 210 + 5k mm
// (walked here), which is the centre of the tube's ring 2 + k; it looks along the ring's axis (normal to every one of
// the ring's spokes) the way it travels, up toward the ring's first node (the tube's own frame); the renderer's
// eye is the same after drawing the session's view of that frame.
TEST(CentrelineCamera, EyeRidesTheCentrelineOnTheTubesRings) {
  constexpr int kFrames = 16;
  constexpr double kFromMm = 210.0, kToMm = 290.0;
  const auto model = compile_file(colon_variant("eye", json::parse(R"(["ends"])"),
                                                json::parse(R"({"centreline": {"from": 210.0, "to": 290.0}})"),
                                                kFrames));
  ASSERT_TRUE(model->render.centreline_flight);
  const std::vector<Eigen::Vector3d> line = file_points();
  lumen::render::Renderer renderer(160, 120, model->render.camera, lumen::engine::session_framing(*model));
  lumen::engine::State state = lumen::engine::make_state(*model);
  lumen::render::Image image;
  for (int k = 0; k <= kFrames; ++k) {
    const double s_mm = kFromMm + (kToMm - kFromMm) * k / kFrames;
    const lumen::render::CameraPose pose = lumen::engine::centreline_camera(*model, k, kFrames);
    EXPECT_LE((pose.eye - point_at(line, s_mm * kMetresPerMm)).norm(), 1e-12) << "frame " << k;
    // The ring at that arc length: its centre (the mean of its inner nodes), its spokes, its first node.
    const int j = static_cast<int>(std::lround((s_mm - kRingStartMm) / kRingStepMm));
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (int i = 0; i < kAround; ++i) centre += model->mesh.rest.row(tube_node(i, j, 0)).transpose();
    centre /= kAround;
    EXPECT_LE((pose.eye - centre).norm(), 1e-12) << "frame " << k;
    for (int i = 0; i < kAround; ++i) {
      const Eigen::Vector3d spoke = model->mesh.rest.row(tube_node(i, j, 0)).transpose() - centre;
      EXPECT_LE(std::abs(pose.forward.normalized().dot(spoke)), 1e-9 * spoke.norm()) << "frame " << k << " node " << i;
    }
    const Eigen::Vector3d first = (model->mesh.rest.row(tube_node(0, j, 0)).transpose() - centre).normalized();
    EXPECT_LE((pose.up.normalized() - first).norm(), 1e-9) << "frame " << k;
    // Forward: toward the next ring (the way it travels), at least as much as the turn between samples allows.
    const Eigen::Vector3d ahead = point_at(line, (s_mm + kRingStepMm) * kMetresPerMm) - pose.eye;
    EXPECT_GT(pose.forward.normalized().dot(ahead.normalized()), 0.7) << "frame " << k;
    // The session's view places the renderer's camera there.
    state.frame = k;
    renderer.draw(lumen::engine::session_frame_view(*model, state, kFrames), image);
    EXPECT_LE((renderer.eye() - pose.eye).norm(), 1e-12) << "frame " << k;
  }
  // Flying back (from > to), it looks the other way.
  const auto back = compile_file(colon_variant("back", json::parse(R"(["ends"])"),
                                               json::parse(R"({"centreline": {"from": 290.0, "to": 210.0}})"), kFrames));
  const lumen::render::CameraPose there = lumen::engine::centreline_camera(*back, 0, kFrames);
  EXPECT_LE((there.eye - point_at(line, kToMm * kMetresPerMm)).norm(), 1e-12);
  EXPECT_LE((there.forward + lumen::engine::centreline_camera(*model, kFrames, kFrames).forward).norm(), 1e-12);
}

// Along the whole flight (every frame of 40 from 205 to 395 mm) the eye is inside the lumen: on the lumen side of
// the nearest inner-wall triangle, at least half the flight's lumen radius from the wall (so the near plane, a small
// fraction of it, never cuts the wall), and on the centreline (brute force over the file's segments).
namespace {

// The eye's distance to the nearest triangle of the inner wall at positions x, and whether it is on that triangle's
// lumen side (the inner wall faces the lumen); brute force over the triangles.
struct WallClearance {
  double distance = std::numeric_limits<double>::infinity();
  bool lumen_side = false;
};
WallClearance wall_clearance(const lumen::Tris& inner, const lumen::Points& x, const Eigen::Vector3d& eye) {
  WallClearance out;
  for (int t = 0; t < inner.rows(); ++t) {
    const Eigen::Vector3d a = x.row(inner(t, 0)), b = x.row(inner(t, 1)), c = x.row(inner(t, 2));
    const Eigen::Vector3d w = lumen::collision::closest_on_triangle(eye, a, b, c);
    const Eigen::Vector3d q = w[0] * a + w[1] * b + w[2] * c;
    if ((eye - q).norm() < out.distance) {
      out.distance = (eye - q).norm();
      out.lumen_side = (eye - q).dot((b - a).cross(c - a)) > 0.0;
    }
  }
  return out;
}

}  // namespace

TEST(CentrelineCamera, EyeStaysInsideTheLumen) {
  constexpr int kFrames = 40;
  const auto model = compile_file(colon_variant("inside", json::parse(R"(["ends"])"),
                                                json::parse(R"({"centreline": {"from": 205.0, "to": 395.0}})"),
                                                kFrames));
  const double radius = model->flight_lumen_radius;
  ASSERT_GT(radius, 0.0);
  const std::vector<Eigen::Vector3d> line = file_points();
  const lumen::Tris& inner = model->inner_wall();
  const lumen::Points& x = model->mesh.rest;
  for (int k = 0; k <= kFrames; ++k) {
    const Eigen::Vector3d eye = lumen::engine::centreline_camera(*model, k, kFrames).eye;
    const WallClearance wall = wall_clearance(inner, x, eye);
    EXPECT_GT(wall.distance, 0.5 * radius) << "frame " << k;
    EXPECT_TRUE(wall.lumen_side) << "frame " << k;
    double centreline = std::numeric_limits<double>::infinity();
    for (size_t i = 0; i + 1 < line.size(); ++i) {
      const Eigen::Vector3d d = line[i + 1] - line[i];
      const double t = std::clamp((eye - line[i]).dot(d) / d.squaredNorm(), 0.0, 1.0);
      centreline = std::min(centreline, (line[i] + t * d - eye).norm());
    }
    EXPECT_LE(centreline, 1e-12) << "frame " << k;
  }
}

// The flight carried by the deformed lumen (the session's view at state.x). A rigid translation of the organ moves
// the eye by the same and keeps the view. A sideways bulge of the bowel, 1.5 lumen radii at the flight's middle
// (each ring moved whole along its own up direction, a Gaussian of 20 mm along the arc length), puts the rest
// camera outside the lumen there; the carried camera stays inside on every frame: on the lumen side of the nearest
// deformed inner-wall triangle, more than half the lumen radius from it.
TEST(CentrelineCamera, EyeFollowsTheDeformedLumen) {
  constexpr int kFrames = 40;
  const auto model = compile_file(colon_variant("deformed", json::parse(R"(["ends"])"),
                                                json::parse(R"({"centreline": {"from": 205.0, "to": 395.0}})"),
                                                kFrames));
  const lumen::Points& rest = model->mesh.rest;
  const Eigen::Vector3d shift(0.004, -0.002, 0.003);
  const lumen::Points moved = rest.rowwise() + shift.transpose();
  for (int k = 0; k <= kFrames; ++k) {
    const lumen::render::CameraPose at_rest = lumen::engine::centreline_camera(*model, k, kFrames);
    const lumen::render::CameraPose carried = lumen::engine::centreline_camera(*model, moved, k, kFrames);
    EXPECT_LE((carried.eye - at_rest.eye - shift).norm(), 1e-12) << "frame " << k;
    EXPECT_LE((carried.forward - at_rest.forward).norm(), 1e-12) << "frame " << k;
    EXPECT_LE((carried.up - at_rest.up).norm(), 1e-12) << "frame " << k;
    // At rest positions the carried camera is the rest one.
    const lumen::render::CameraPose same = lumen::engine::centreline_camera(*model, rest, k, kFrames);
    EXPECT_LE((same.eye - at_rest.eye).norm() + (same.forward - at_rest.forward).norm(), 1e-12) << "frame " << k;
  }
  // The bulge: ring j (nodes as tube_node) moved by 1.5 r g(s_j) along (its first inner node - its centre).
  const double radius = model->flight_lumen_radius;
  const int rings = static_cast<int>(rest.rows()) / (kAround * (kLayers + 1));
  lumen::Points bulged = rest;
  for (int j = 0; j < rings; ++j) {
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (int i = 0; i < kAround; ++i) centre += rest.row(tube_node(i, j, 0)).transpose();
    centre /= kAround;
    const Eigen::Vector3d up = (rest.row(tube_node(0, j, 0)).transpose() - centre).normalized();
    const double s_mm = kRingStartMm + kRingStepMm * j, d = (s_mm - 300.0) / 20.0;
    const Eigen::Vector3d move = 1.5 * radius * std::exp(-d * d) * up;
    for (int k = 0; k <= kLayers; ++k)
      for (int i = 0; i < kAround; ++i) bulged.row(tube_node(i, j, k)) += move.transpose();
  }
  const lumen::Tris& inner = model->inner_wall();
  for (int k = 0; k <= kFrames; ++k) {
    const Eigen::Vector3d eye = lumen::engine::centreline_camera(*model, bulged, k, kFrames).eye;
    const WallClearance wall = wall_clearance(inner, bulged, eye);
    EXPECT_GT(wall.distance, 0.5 * radius) << "frame " << k;
    EXPECT_TRUE(wall.lumen_side) << "frame " << k;
  }
  // The rest camera at the bulge (frame 20: 300 mm) is not inside the moved lumen.
  const Eigen::Vector3d stale_eye = lumen::engine::centreline_camera(*model, kFrames / 2, kFrames).eye;
  const WallClearance stale = wall_clearance(inner, bulged, stale_eye);
  EXPECT_FALSE(stale.lumen_side && stale.distance > 0.5 * radius);
}

// A frame rendered from inside the lumen shows its wall: at the flight's start, middle and end more than 95 % of the
// pixels are the lumen wall's colour (the mucosa); the same renderer placed outside the organ looking away from it
// shows background, and looking at it from outside shows its outer wall (both controls under 5 %).
TEST(CentrelineCamera, AFrameFromInsideShowsTheWall) {
  constexpr int kFrames = 16;
  const auto model = compile_file(colon_variant("pixels", json::parse(R"(["ends"])"),
                                                json::parse(R"({"centreline": {"from": 210.0, "to": 290.0}})"),
                                                kFrames));
  const lumen::render::Framing framing = lumen::engine::session_framing(*model);
  EXPECT_DOUBLE_EQ(framing.lumen_radius, model->flight_lumen_radius);
  lumen::render::Renderer renderer(160, 120, model->render.camera, framing);
  lumen::engine::State state = lumen::engine::make_state(*model);
  lumen::render::Image image;
  for (int k : {0, kFrames / 2, kFrames}) {
    state.frame = k;
    renderer.draw(lumen::engine::session_frame_view(*model, state, kFrames), image);
    std::printf("frame %d from inside: %.3f of the pixels mucosa-coloured\n", k, mucosa_share(image));
    EXPECT_GT(mucosa_share(image), 0.95) << "frame " << k;
  }
  lumen::render::FrameView away = lumen::engine::session_frame_view(*model, state, kFrames);
  const Eigen::Vector3d out = framing.center + 3.0 * framing.radius * Eigen::Vector3d::UnitX();
  away.camera = lumen::render::CameraPose{out, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitZ()};
  renderer.draw(away, image);
  EXPECT_LT(mucosa_share(image), 0.05);
  // Outside, close to the middle ring's outer wall, looking at the centreline.
  const int j = 20;  // the ring at 300 mm
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (int i = 0; i < kAround; ++i) centre += model->mesh.rest.row(tube_node(i, j, 0)).transpose();
  centre /= kAround;
  const Eigen::Vector3d spoke = model->mesh.rest.row(tube_node(0, j, kLayers)).transpose() - centre;
  const Eigen::Vector3d outside = centre + 1.5 * spoke;
  const Eigen::Vector3d along = model->mesh.rest.row(tube_node(0, j + 1, 0)).transpose() -
                                model->mesh.rest.row(tube_node(0, j, 0)).transpose();
  away.camera = lumen::render::CameraPose{outside, -spoke, along};
  renderer.draw(away, image);
  std::printf("from outside: %.3f of the pixels mucosa-coloured\n", mucosa_share(image));
  EXPECT_LT(mucosa_share(image), 0.05);
}

// render.camera {"centreline": {"from", "to"}}: in mesh.units, within mesh.range; refusals name the key path.
TEST(CentrelineCamera, KeysAreValidatedNamingTheirPath) {
  json s = straight_scene();
  s["render"]["camera"] = json::parse(R"({"centreline": {"from": 30.0, "to": 70.0}})");
  const lumen::engine::Scene ok = lumen::engine::load_scene(write_straight("camera_ok", s));
  EXPECT_TRUE(ok.render.centreline_flight);
  EXPECT_EQ(ok.render.camera, lumen::render::CameraPreset::Endoscope);
  EXPECT_DOUBLE_EQ(ok.render.flight_from, 0.03);
  EXPECT_DOUBLE_EQ(ok.render.flight_to, 0.07);
  auto message = [](const std::string& name, const json& scene) {
    const std::string path = write_straight(name, scene);
    std::string m = compile_error_of(path);
    const std::string prefix = path + ": ";
    return m.rfind(prefix, 0) == 0 ? m.substr(prefix.size()) : "(no prefix) " + m;
  };
  s["render"]["camera"]["centreline"]["from"] = 10.0;
  EXPECT_EQ(message("from", s), "render.camera.centreline.from: must lie within mesh.range [20, 80] (value 10.0)");
  s["render"]["camera"]["centreline"]["from"] = 30.0;
  s["render"]["camera"]["centreline"]["to"] = 85.0;
  EXPECT_EQ(message("to", s), "render.camera.centreline.to: must lie within mesh.range [20, 80] (value 85.0)");
  s["render"]["camera"]["centreline"]["to"] = 30.0;
  EXPECT_EQ(message("same", s), "render.camera.centreline.to: must differ from render.camera.centreline.from (value 30.0)");
  s["render"]["camera"]["centreline"]["to"] = "end";
  EXPECT_EQ(message("text", s), "render.camera.centreline.to: must be a number (value \"end\")");
  s["render"]["camera"]["centreline"] = json::parse(R"({"from": 30.0})");
  EXPECT_EQ(message("missing", s), "render.camera.centreline.to: missing key");
  s["render"]["camera"]["centreline"] = json::parse(R"({"from": 30.0, "to": 70.0, "speed": 2.0})");
  EXPECT_EQ(message("speed", s), "render.camera.centreline.speed: unknown key");
  s["render"]["camera"]["centreline"] = 30.0;
  EXPECT_EQ(message("scalar", s), "render.camera.centreline: must be an object {\"from\", \"to\"} (value 30.0)");
  s["render"]["camera"] = json::parse(R"({"centreline": {"from": 30.0, "to": 70.0}, "endoscope": "scope"})");
  EXPECT_EQ(message("both", s), "render.camera: needs exactly one of \"endoscope\" or \"centreline\" (value "
                                "{\"centreline\":{\"from\":30.0,\"to\":70.0},\"endoscope\":\"scope\"})");
  json cylinder = straight_scene();
  cylinder["mesh"] = json::parse(R"({"type": "hollow_cylinder", "inner_radius": 0.01, "outer_radius": 0.013,
                                     "length": 0.1, "segments_around": 12, "segments_along": 10, "layers": 2})");
  cylinder["render"]["camera"] = json::parse(R"({"centreline": {"from": 0.01, "to": 0.02}})");
  EXPECT_EQ(message("cylinder", cylinder), "render.camera.centreline: needs mesh.type \"swept_tube\" (got "
                                           "\"hollow_cylinder\") (value {\"from\":0.01,\"to\":0.02})");
}

// The shipped colonoscopy scene runs under lumen run and writes its frames, with the flight in report.json.
TEST(ColonoscopyCli, LumenRunWritesTheFlightsFrames) {
  const fs::path out = fs::temp_directory_path() / "lumen_colonoscopy_run";
  fs::remove_all(out);
  std::string output;
  const std::string scene = std::string(LUMEN_SOURCE_DIR) + "/scenes/colon-sigmoid-colonoscopy.json";
  ASSERT_EQ(run_lumen("run " + scene + " --frames 4 --out " + out.string(), output), 0) << output;
  for (int k = 1; k <= 4; ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06d.png", k);
    EXPECT_TRUE(fs::is_regular_file(out / "frames" / name)) << name;
  }
  std::ifstream in(out / "report.json");
  const json report = json::parse(in);
  EXPECT_EQ(report.at("render").at("camera"), "endoscope");
  EXPECT_DOUBLE_EQ(report.at("render").at("centreline_flight_m").at("from").get<double>(), 0.205);
  EXPECT_DOUBLE_EQ(report.at("render").at("centreline_flight_m").at("to").get<double>(), 0.29);
}
