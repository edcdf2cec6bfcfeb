#pragma once
// Off-screen OpenGL rendering (OSMesa) of the organ: outer wall, cut-away inner wall, probes.
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace lumen::render {

enum class CameraPreset { Side, Diagonal, Endoscope };
// Parse "side" | "diagonal" | "endoscope"; throws std::invalid_argument otherwise.
CameraPreset parse_camera(const std::string& name);

// A probe drawn as an arrow at `point` along `force`, length scaled by |force|.
struct ProbeGlyph {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  // metres
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  // newtons
};

// Everything one frame draws; arrays are borrowed for the call.
struct FrameView {
  const double* positions = nullptr;  // n_points x 3, metres, row-major
  int n_points = 0;
  const int* outer = nullptr;  // n_outer x 3
  int n_outer = 0;
  const int* inner = nullptr;  // n_inner x 3
  int n_inner = 0;
  const int* ends = nullptr;  // n_ends x 3
  int n_ends = 0;
  const std::uint8_t* contact = nullptr;  // per point, 1 = in contact (coloured), may be null
  std::vector<ProbeGlyph> probes;
  double force_scale = 0.02;  // arrow length per newton, metres / N
};

// Scene framing: the organ's rest bounding box and axis, so cameras are placed once per session.
struct Framing {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double radius = 0.05;                                  // bounding-sphere radius, metres
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();       // organ axis (lumen direction)
  double lumen_radius = 0.01;                            // for the endoscope camera, metres
  // Half the organ's length along the axis, metres, placing the endoscope camera
  // (0: estimated as sqrt(radius^2 - (1.3 lumen_radius)^2)).
  double half_length = 0.0;
  // Opening angle of the wedge cut out of the walls on the side facing the side camera, degrees
  // (0 = no cut, 180 = half the organ removed). The cut-away outer wall is drawn faintly translucent.
  // Side and diagonal views only; the endoscope is never cut.
  double cutaway_degrees = 100.0;
};

// RGB8 image, row 0 at the top.
struct Image {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  // width * height * 3
};

// One OSMesa context per Renderer, bound on the calling thread only for the duration of draw(); any thread may
// draw, one at a time (not thread-safe).
class Renderer {
 public:
  Renderer(int width, int height, CameraPreset camera, const Framing& framing);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;
  // Draw one frame and read it back into `out` (resized to width x height). Throws std::invalid_argument
  // on a malformed frame (null arrays, indices out of range, non-finite probes).
  void draw(const FrameView& frame, Image& out);
  // Pixel coordinates (x right, y down, pixel centres at +0.5) of a world point; NaN behind the camera.
  Eigen::Vector2d project(const Eigen::Vector3d& world) const;
  // Camera position, metres.
  Eigen::Vector3d eye() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lumen::render
