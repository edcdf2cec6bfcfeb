#pragma once
// Scene description (JSON, SI units) and its validating loader.
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "physics/mesh.hpp"

namespace lumen::engine {

// A scene or input file was refused; the message names the file, the key path and the value.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// What a probe prescribes: the force at its point (force-driven), or the displacement of its point from rest
// (displacement-driven, as a position-controlled haptic device: the engine solves for the force and hands it
// back as the reaction, contacts included).
enum class ProbeDrive { Force, Displacement };

// One key of a scripted probe track: the force (newtons) or displacement (metres) reached at time t, linear
// in between.
struct TrackKey {
  double t = 0.0;                                   // seconds
  Eigen::Vector3d value = Eigen::Vector3d::Zero();  // newtons (force) or metres (displacement)
};

// A probe: a point on the organ's surface and where its force comes from.
struct ProbeSpec {
  std::string name;                                 // for reports; defaults to "probe<i>"
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  // metres, snapped to the nearest outer-wall point
  ProbeDrive drive = ProbeDrive::Force;             // what the track keys give
  std::vector<TrackKey> track;                      // scripted key frames (source "track")
  std::string replay;                               // recorded CSV (source "replay"), absolute path
};

struct MaterialSpec {
  std::string model = "linear";  // "linear" (prefactorised, the paper's) | "corotational" (large rotations)
  double young_modulus = 5000.0;  // pascals
  double poisson_ratio = 0.45;    // (-1, 0.5)
  double density = 1050.0;        // kg / m^3
};

struct RenderSpec {
  int width = 640, height = 480;   // pixels, even
  std::string camera = "diagonal";  // side | diagonal | endoscope
  bool video = false;               // write DIR/video.mp4 by default
  double force_scale = 1.0;         // arrow length per newton, metres / N
};

struct CollisionSpec {
  bool self = false;               // inner-wall self-collision on/off
  int kdop = 26;                   // 6, 14, 18, 26
  std::string response = "constraint";  // "paper" | "constraint"
  double gap = 1e-4;               // minimum separation, metres
  int max_iterations = 8;          // response/re-check rounds before the safe fallback
};

struct Scene {
  std::string path;  // the file it was read from
  std::string name;
  physics::HollowCylinderSpec mesh;
  MaterialSpec material;
  std::vector<std::string> fixed;  // named node sets held still: "ends", "start", "stop"
  std::vector<ProbeSpec> probes;
  int frames = 120;
  double fps = 40.0;  // frames per second of simulated time; the budget is 1 / fps
  RenderSpec render;
  CollisionSpec collision;
};

// Read and validate a scene file; throws InputError with "FILE: KEY.PATH: problem (value V)".
Scene load_scene(const std::string& path);
// The same from text (path used in messages and to resolve relative replay files).
Scene parse_scene(const std::string& text, const std::string& path);

}  // namespace lumen::engine
