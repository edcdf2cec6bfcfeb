#pragma once
// Off-screen OpenGL rendering (OSMesa) of a list of surfaces (organ walls, instruments) and probes.
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
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

// Base colour and specular response of a surface.
enum class Material {
  Serosa,       // outer wall, tissue pink
  Mucosa,       // inner (lumen) wall, orange-red
  WallSection,  // cut wall cross-section (tube ends)
  Metal,        // rigid instruments: grey, strong sharp highlight
};

// How the cut-away wedge (Framing::cutaway_degrees, side and diagonal views) treats a surface.
enum class CutAway {
  Never,    // drawn whole (instruments)
  Removed,  // the part inside the wedge is not drawn
  Ghosted,  // the part inside the wedge is drawn faintly translucent (front faces only)
};

// What distinguishes one drawn surface from another.
struct SurfaceStyle {
  Material material = Material::Serosa;
  CutAway cutaway = CutAway::Removed;
  bool contact_colouring = true;  // points flagged in FrameView::contact take the contact colour (frame points only)
  bool two_sided = true;          // back faces lit in the dark cut colour (seen through the cut); else front material

  // The styles of today's organ surfaces and of a rigid instrument.
  static SurfaceStyle outer_wall() { return {Material::Serosa, CutAway::Ghosted, true, true}; }
  static SurfaceStyle inner_wall() { return {Material::Mucosa, CutAway::Removed, true, true}; }
  static SurfaceStyle wall_ends() { return {Material::WallSection, CutAway::Removed, true, true}; }
  static SurfaceStyle metal() { return {Material::Metal, CutAway::Never, false, false}; }
};

// One drawn surface: triangles as an index map onto a point array, borrowed for the draw call.
struct Surface {
  const int* triangles = nullptr;  // n_triangles x 3, counter-clockwise seen from the front (normal side)
  int n_triangles = 0;
  SurfaceStyle style;
  // Its own point array (n_points x 3, metres, row-major), e.g. a rigid instrument's vertices; null: the
  // triangles index FrameView::positions.
  const double* positions = nullptr;
  int n_points = 0;
};

// A camera the caller places for one frame (the endoscope riding on an instrument's tip): eye position, metres,
// and the viewing and up directions (finite, non-zero, not parallel; up is made perpendicular to forward).
struct CameraPose {
  Eigen::Vector3d eye = Eigen::Vector3d::Zero();
  Eigen::Vector3d forward = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d up = Eigen::Vector3d::UnitY();
};

// Everything one frame draws; arrays are borrowed for the call.
struct FrameView {
  const double* positions = nullptr;  // n_points x 3, metres, row-major: the organ's points
  int n_points = 0;
  // Surfaces, outermost first: cameras outside the organ draw them in this order, the endoscope (inside the
  // lumen) in reverse, so the nearest surface is drawn first and hidden fragments fail the depth test early.
  std::vector<Surface> surfaces;
  const std::uint8_t* contact = nullptr;  // per frame point, 1 = in contact (coloured), may be null
  std::vector<ProbeGlyph> probes;
  double force_scale = 0.02;  // arrow length per newton, metres / N
  // The endoscope camera only: placed here for this frame instead of on the lumen axis (the preset's place).
  std::optional<CameraPose> camera;
};

// Scene framing: where the organ and its lumen are, so cameras are placed once per session. frame_organ() fills
// it from rest geometry.
struct Framing {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  // bounding-box centre: the orbit cameras look here
  double radius = 0.05;                              // bounding-sphere radius (half the box diagonal), metres
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();   // organ axis (lumen direction)
  // A point on the lumen axis, midway along the lumen: the cut-away wedge's edge runs through it along the axis,
  // and the endoscope sits on that line.
  Eigen::Vector3d lumen_center = Eigen::Vector3d::Zero();
  double lumen_radius = 0.01;  // for the endoscope camera, metres
  // Half the lumen's length along the axis, metres, placing the endoscope camera
  // (0: estimated as sqrt(radius^2 - (1.3 lumen_radius)^2)).
  double half_length = 0.0;
  // Opening angle of the wedge cut out of the walls on the side facing the side camera, degrees
  // (0 = no cut, 180 = half the organ removed). The cut-away outer wall is drawn faintly translucent.
  // Side and diagonal views only; the endoscope is never cut.
  double cutaway_degrees = 100.0;
};

// Framing from geometry alone: the bounding box of `points` (n_points x 3, metres, row-major) and the lumen as
// the nodes of `lumen_triangles` (n x 3 indices into points, e.g. the inner wall): its axis is the principal axis
// of those nodes (largest-variance direction of their covariance about their mean, signed so its largest
// component is positive), its radius their mean distance from that axis, its centre and half length the mid-point
// and half extent of their projections onto the axis. With no lumen triangles the principal axis of all points is
// used, through the box centre, with lumen radius a tenth of the bounding radius. Throws std::invalid_argument on
// no points, a null array, an index out of range or non-finite coordinates.
Framing frame_organ(const double* points, int n_points, const int* lumen_triangles, int n_lumen_triangles,
                    double cutaway_degrees = 100.0);

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
  // on a malformed frame (null arrays, indices out of range, non-finite probes, a camera pose that is not finite
  // or degenerate, or given to a preset other than the endoscope).
  void draw(const FrameView& frame, Image& out);
  // Pixel coordinates (x right, y down, pixel centres at +0.5) of a world point; NaN behind the camera.
  Eigen::Vector2d project(const Eigen::Vector3d& world) const;
  // Camera position, metres (the last frame's, for an endoscope placed by FrameView::camera).
  Eigen::Vector3d eye() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lumen::render
