// Off-screen OpenGL rendering through OSMesa (llvmpipe), legacy fixed-function pipeline.
#include "render/renderer.hpp"

#include <GL/gl.h>
#include <GL/osmesa.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <Eigen/Geometry>

namespace lumen::render {

namespace {

constexpr double kPi = static_cast<double>(EIGEN_PI);  // Eigen's constant, a long double, as a double
static_assert(sizeof(int) == sizeof(GLuint), "index arrays are passed to GL as GL_UNSIGNED_INT");

// Colours, linear RGB in [0, 1].
constexpr float kOuterColor[3] = {0.92f, 0.62f, 0.60f};    // tissue pink (serosa)
constexpr float kInnerColor[3] = {0.86f, 0.38f, 0.24f};    // mucosa, orange-red
constexpr float kEndColor[3] = {0.84f, 0.50f, 0.48f};      // wall cross-section at the ends
constexpr float kCutColor[4] = {0.42f, 0.10f, 0.12f, 1.f};  // back faces seen through the cut
constexpr float kContactColor[3] = {0.70f, 1.00f, 0.10f};  // contact region, yellow-green
constexpr float kProbeColor[3] = {0.15f, 0.40f, 1.00f};    // probe arrows, blue
constexpr float kMetalColor[3] = {0.62f, 0.64f, 0.68f};    // instruments, steel grey
constexpr float kTissueSpecular[4] = {0.30f, 0.30f, 0.30f, 1.f};
constexpr float kTissueShininess = 40.f;
constexpr float kMetalSpecular[4] = {0.85f, 0.85f, 0.85f, 1.f};
constexpr float kMetalShininess = 90.f;
constexpr float kGhostAlpha = 0.16f;                        // cut-away outer wall, drawn faintly
constexpr float kBackgroundTop[3] = {0.20f, 0.22f, 0.26f};
constexpr float kBackgroundBottom[3] = {0.05f, 0.05f, 0.07f};

// Camera parameters of the presets.
constexpr double kOrbitFovyDeg = 30.0;       // side and diagonal, vertical field of view
constexpr double kEndoscopeFovyDeg = 72.0;   // endoscope, vertical (about 88 degrees across at 4:3)
constexpr double kDiagonalElevationDeg = 40.0;
constexpr double kDiagonalAzimuthDeg = 40.0;  // from the side direction toward the start end
constexpr double kMinCameraSine = 1e-6;      // a placed camera's forward and up must be further apart than this
constexpr double kEndoscopeDepth = 0.85;      // eye at this fraction of the half length from the centre
constexpr int kArrowSegments = 16;

using Mat4 = Eigen::Matrix4d;
using Vec3 = Eigen::Vector3d;

// Right-handed look-at view matrix (OpenGL convention: the camera looks down -z).
Mat4 look_at(const Vec3& eye, const Vec3& target, const Vec3& up_hint) {
  const Vec3 f = (target - eye).normalized();
  const Vec3 s = f.cross(up_hint).normalized();
  const Vec3 u = s.cross(f);
  Mat4 m = Mat4::Identity();
  m.block<1, 3>(0, 0) = s.transpose();
  m.block<1, 3>(1, 0) = u.transpose();
  m.block<1, 3>(2, 0) = -f.transpose();
  m(0, 3) = -s.dot(eye);
  m(1, 3) = -u.dot(eye);
  m(2, 3) = f.dot(eye);
  return m;
}

// Perspective projection (gluPerspective), fovy in radians.
Mat4 perspective(double fovy, double aspect, double znear, double zfar) {
  const double f = 1.0 / std::tan(fovy / 2.0);
  Mat4 m = Mat4::Zero();
  m(0, 0) = f / aspect;
  m(1, 1) = f;
  m(2, 2) = (zfar + znear) / (znear - zfar);
  m(2, 3) = 2.0 * zfar * znear / (znear - zfar);
  m(3, 2) = -1.0;
  return m;
}

bool finite3(const Vec3& v) { return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z()); }

std::string vec_text(const Vec3& v) {
  std::ostringstream s;
  s << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
  return s.str();
}

// Checks one index array; throws std::invalid_argument naming it (`name` is e.g. "FrameView.surfaces[1].triangles").
void check_tris(const std::string& name, const int* tris, int n_tris, int n_points) {
  if (n_tris < 0) throw std::invalid_argument(name + ": n_triangles must be >= 0 (value " + std::to_string(n_tris) + ")");
  if (n_tris > 0 && tris == nullptr) throw std::invalid_argument(name + " is null with " + std::to_string(n_tris) + " triangles");
  for (int k = 0; k < 3 * n_tris; ++k) {
    if (tris[k] < 0 || tris[k] >= n_points) {
      throw std::invalid_argument(name + "[" + std::to_string(k) + "] out of range [0, " + std::to_string(n_points) +
                                  ") (value " + std::to_string(tris[k]) + ")");
    }
  }
}

const float* base_colour(Material m) {
  switch (m) {
    case Material::Serosa: return kOuterColor;
    case Material::Mucosa: return kInnerColor;
    case Material::WallSection: return kEndColor;
    case Material::Metal: return kMetalColor;
  }
  return kOuterColor;
}

}  // namespace

CameraPreset parse_camera(const std::string& name) {
  if (name == "side") return CameraPreset::Side;
  if (name == "diagonal") return CameraPreset::Diagonal;
  if (name == "endoscope") return CameraPreset::Endoscope;
  throw std::invalid_argument("camera must be side, diagonal or endoscope (value \"" + name + "\")");
}

struct Renderer::Impl {
  int width = 0, height = 0;
  CameraPreset preset = CameraPreset::Side;
  Framing framing;
  OSMesaContext ctx = nullptr;
  std::vector<unsigned char> color_buffer;  // OSMesa colour buffer, width x height x 4 (RGBA8), bottom row first
  std::vector<unsigned char> readback;      // glReadPixels output, width x height x 4, bottom row first

  // Camera, world -> eye and eye -> clip, and the frame basis of the organ.
  Mat4 view = Mat4::Identity(), proj = Mat4::Identity();
  Vec3 eye = Vec3::Zero();
  Mat4 preset_view = Mat4::Identity();  // the preset's own placement, restored after a frame that moved the camera
  Vec3 preset_eye = Vec3::Zero();
  Vec3 axis = Vec3::UnitZ(), up = Vec3::UnitY(), side = Vec3::UnitX();  // orthonormal organ frame
  double half_length = 0.0;                                            // metres
  // Cut-away wedge: kept where plane_a >= 0 or plane_b >= 0 (world-space plane equations).
  bool cut = false;
  double plane_a[4] = {0, 0, 0, 0}, plane_b[4] = {0, 0, 0, 0};

  // Per-frame scratch: float copy of the frame's points; per surface its own points' float copy (if any),
  // normals and colours (each n_points x 3 of the surface's point array).
  std::vector<float> pos;
  struct SurfaceScratch {
    std::vector<float> pos, normals, colors;
  };
  std::vector<SurfaceScratch> surf;
  // Arrow triangles, interleaved per vertex: position (3) and normal (3), world units.
  std::vector<float> arrow;

  void setup_camera();
  void setup_gl_state();
  // This frame's view: the caller's pose (endoscope only) or the preset's, loaded as the GL modelview.
  void place_camera(const std::optional<CameraPose>& pose);
  void make_current();
  void build_surface(SurfaceScratch& s, const float* points, const int* tris, int n_tris, const float base[3],
                     const std::uint8_t* contact, int n_points);
  const float* points_of(const FrameView& f, size_t i) const {
    return f.surfaces[i].positions != nullptr ? surf[i].pos.data() : pos.data();
  }
  // Opaque pass over the surfaces whose cut-away is (or is not) Never; ghost pass over the Ghosted ones.
  void draw_surfaces(const FrameView& f, bool ghost, bool uncut);
  void build_arrow(const ProbeGlyph& probe, double force_scale);
  void draw_background();
  // Per-frame float geometry of every surface and the probe arrows.
  void build_frame(const FrameView& f);
  // The opaque organ (with the cut: the union of the two kept half-spaces), then uncut surfaces (instruments).
  void draw_opaque(const FrameView& f);
  // Probe arrows, opaque, never clipped.
  void draw_arrows();
  // Ghost of the cut-away outer wall: front faces only, blended, no depth writes.
  void draw_ghost(const FrameView& f);
  // Read the colour buffer back into an RGB image, row 0 the top.
  void read_back(Image& out);
};

Renderer::Renderer(int width, int height, CameraPreset camera, const Framing& framing) : impl_(std::make_unique<Impl>()) {
  // Validate the parameters at the boundary.
  if (width <= 0 || width > 16384) throw std::invalid_argument("Renderer width must be in [1, 16384] (value " + std::to_string(width) + ")");
  if (height <= 0 || height > 16384) throw std::invalid_argument("Renderer height must be in [1, 16384] (value " + std::to_string(height) + ")");
  if (!finite3(framing.center)) throw std::invalid_argument("Framing.center must be finite (value " + vec_text(framing.center) + ")");
  if (!(framing.radius > 0) || !std::isfinite(framing.radius))
    throw std::invalid_argument("Framing.radius must be > 0 (value " + std::to_string(framing.radius) + ")");
  if (!finite3(framing.axis) || framing.axis.norm() < 1e-12)
    throw std::invalid_argument("Framing.axis must be a non-zero finite vector (value " + vec_text(framing.axis) + ")");
  if (!finite3(framing.lumen_center)) throw std::invalid_argument("Framing.lumen_center must be finite (value " + vec_text(framing.lumen_center) + ")");
  if (!(framing.lumen_radius > 0) || !(framing.lumen_radius < framing.radius))
    throw std::invalid_argument("Framing.lumen_radius must be in (0, radius) (value " + std::to_string(framing.lumen_radius) + ")");
  if (!(framing.half_length >= 0) || !std::isfinite(framing.half_length))
    throw std::invalid_argument("Framing.half_length must be finite and >= 0 (value " + std::to_string(framing.half_length) + ")");
  if (!(framing.cutaway_degrees >= 0 && framing.cutaway_degrees <= 180))
    throw std::invalid_argument("Framing.cutaway_degrees must be in [0, 180] (value " + std::to_string(framing.cutaway_degrees) + ")");

  Impl& m = *impl_;
  m.width = width;
  m.height = height;
  m.preset = camera;
  m.framing = framing;
  m.color_buffer.assign(static_cast<size_t>(width) * height * 4, 0);
  m.readback.assign(static_cast<size_t>(width) * height * 4, 0);

  // Create the OSMesa context: RGBA8, 24-bit depth, compatibility profile (fixed-function GL).
  const int attribs[] = {OSMESA_FORMAT, OSMESA_RGBA, OSMESA_DEPTH_BITS, 24, OSMESA_STENCIL_BITS, 0, OSMESA_ACCUM_BITS, 0,
                         OSMESA_PROFILE, OSMESA_COMPAT_PROFILE, OSMESA_CONTEXT_MAJOR_VERSION, 2, OSMESA_CONTEXT_MINOR_VERSION, 1, 0};
  m.ctx = OSMesaCreateContextAttribs(attribs, nullptr);
  if (m.ctx == nullptr) m.ctx = OSMesaCreateContextExt(OSMESA_RGBA, 24, 0, 0, nullptr);
  if (m.ctx == nullptr) throw std::runtime_error("Renderer: could not create an OSMesa context (RGBA, 24-bit depth)");
  try {
    m.make_current();
  } catch (...) {
    OSMesaDestroyContext(m.ctx);
    throw;
  }
  m.setup_camera();
  m.preset_view = m.view;
  m.preset_eye = m.eye;
  m.setup_gl_state();
  // Release the context: each draw() binds it on the calling thread and releases it again (a fraction of a
  // microsecond), so no thread keeps it bound between frames.
  OSMesaMakeCurrent(nullptr, nullptr, 0, 0, 0);
}

Renderer::~Renderer() {
  // The context is never left bound (see draw()), so it can go directly.
  if (impl_ && impl_->ctx) OSMesaDestroyContext(impl_->ctx);
}

void Renderer::Impl::make_current() {
  if (!OSMesaMakeCurrent(ctx, color_buffer.data(), GL_UNSIGNED_BYTE, width, height))
    throw std::runtime_error("Renderer: OSMesaMakeCurrent failed for " + std::to_string(width) + "x" + std::to_string(height));
}

void Renderer::Impl::setup_camera() {
  // Organ frame: axis, an up direction (world +y made perpendicular to the axis), and the side.
  axis = framing.axis.normalized();
  Vec3 hint = std::abs(axis.y()) < 0.9 ? Vec3::UnitY() : Vec3::UnitZ();
  up = (hint - axis * axis.dot(hint)).normalized();
  side = axis.cross(up);  // the side camera sits here, so the axis points to the right of the image
  const double R = framing.radius;
  const double r_lumen = framing.lumen_radius;
  half_length = framing.half_length > 0 ? framing.half_length
                                        : std::sqrt(std::max(R * R - 1.69 * r_lumen * r_lumen, 0.25 * R * R));
  const double aspect = static_cast<double>(width) / height;
  const Vec3& c = framing.center;

  if (preset == CameraPreset::Endoscope) {
    // Inside the lumen on the axis near the start end, looking along the axis; wide field of view.
    const double fovy = kEndoscopeFovyDeg * kPi / 180.0;
    eye = framing.lumen_center - axis * (kEndoscopeDepth * half_length);
    view = look_at(eye, eye + axis, up);
    proj = perspective(fovy, aspect, 0.02 * r_lumen, 2.0 * half_length + 2.0 * R);
    cut = false;
    return;
  }

  // Side and diagonal: orbit cameras that fit the bounding sphere in the narrower field of view.
  const double fovy = kOrbitFovyDeg * kPi / 180.0;
  const double fovx = 2.0 * std::atan(std::tan(fovy / 2.0) * aspect);
  const double dist = 1.02 * R / std::sin(std::min(fovx, fovy) / 2.0);
  Vec3 dir = side;  // from the centre toward the eye
  if (preset == CameraPreset::Diagonal) {
    const double el = kDiagonalElevationDeg * kPi / 180.0, az = kDiagonalAzimuthDeg * kPi / 180.0;
    dir = (std::sin(el) * up + std::cos(el) * (std::cos(az) * side - std::sin(az) * axis)).normalized();
  }
  eye = c + dist * dir;
  view = look_at(eye, c, up);
  proj = perspective(fovy, aspect, std::max(0.05 * dist, dist - 3.0 * R), dist + 3.0 * R);

  // Cut-away wedge facing the side direction, its edge the lumen axis: removed where the angle from `side` is
  // below half the opening.
  const Vec3& l = framing.lumen_center;
  const double a = 0.5 * framing.cutaway_degrees * kPi / 180.0;
  cut = a > 0;
  const Vec3 n1 = std::sin(a) * side - std::cos(a) * up;  // n1.(p - c) > 0: angle below +a
  const Vec3 n2 = std::sin(a) * side + std::cos(a) * up;  // n2.(p - c) > 0: angle above -a
  // Kept half-spaces: -n.(p - c) >= 0.
  for (int k = 0; k < 3; ++k) {
    plane_a[k] = -n1[k];
    plane_b[k] = -n2[k];
  }
  plane_a[3] = n1.dot(l);
  plane_b[3] = n2.dot(l);
}

void Renderer::Impl::setup_gl_state() {
  glViewport(0, 0, width, height);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LEQUAL);
  glShadeModel(GL_SMOOTH);
  glDisable(GL_DITHER);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);

  // Lighting: two-sided (back faces seen through the cut get a dark cut colour), local viewer specular.
  glEnable(GL_LIGHTING);
  glLightModeli(GL_LIGHT_MODEL_TWO_SIDE, GL_TRUE);
  glLightModeli(GL_LIGHT_MODEL_LOCAL_VIEWER, GL_TRUE);
  const float global_ambient[4] = {0.18f, 0.18f, 0.18f, 1.f};
  glLightModelfv(GL_LIGHT_MODEL_AMBIENT, global_ambient);
  glEnable(GL_COLOR_MATERIAL);
  glColorMaterial(GL_FRONT, GL_AMBIENT_AND_DIFFUSE);
  glMaterialfv(GL_FRONT, GL_SPECULAR, kTissueSpecular);
  glMaterialf(GL_FRONT, GL_SHININESS, kTissueShininess);
  glMaterialfv(GL_BACK, GL_AMBIENT_AND_DIFFUSE, kCutColor);
  const float no_specular[4] = {0.f, 0.f, 0.f, 1.f};
  glMaterialfv(GL_BACK, GL_SPECULAR, no_specular);

  // Lights are placed in eye coordinates (identity modelview).
  glMatrixMode(GL_MODELVIEW);
  glLoadIdentity();
  const float white[4] = {1.f, 1.f, 1.f, 1.f};
  if (preset == CameraPreset::Endoscope) {
    // Head light at the eye, fading with distance down the lumen.
    const float at_eye[4] = {0.f, 0.f, 0.f, 1.f};
    const float diffuse[4] = {1.0f, 1.0f, 1.0f, 1.f};
    glLightfv(GL_LIGHT0, GL_POSITION, at_eye);
    glLightfv(GL_LIGHT0, GL_DIFFUSE, diffuse);
    glLightfv(GL_LIGHT0, GL_SPECULAR, white);
    const double reach = 4.0 * framing.lumen_radius;  // half intensity at this distance
    glLightf(GL_LIGHT0, GL_CONSTANT_ATTENUATION, 1.f);
    glLightf(GL_LIGHT0, GL_QUADRATIC_ATTENUATION, static_cast<float>(1.0 / (reach * reach)));
    glEnable(GL_LIGHT0);
    glDisable(GL_LIGHT1);
  } else {
    // Key light from the upper left of the camera, fill light from the lower right.
    const float key_dir[4] = {-0.35f, 0.75f, 0.55f, 0.f};
    const float key_diffuse[4] = {0.80f, 0.80f, 0.78f, 1.f};
    const float fill_dir[4] = {0.5f, -0.3f, 0.8f, 0.f};
    const float fill_diffuse[4] = {0.28f, 0.28f, 0.32f, 1.f};
    const float none[4] = {0.f, 0.f, 0.f, 1.f};
    glLightfv(GL_LIGHT0, GL_POSITION, key_dir);
    glLightfv(GL_LIGHT0, GL_DIFFUSE, key_diffuse);
    glLightfv(GL_LIGHT0, GL_SPECULAR, white);
    glLightfv(GL_LIGHT1, GL_POSITION, fill_dir);
    glLightfv(GL_LIGHT1, GL_DIFFUSE, fill_diffuse);
    glLightfv(GL_LIGHT1, GL_SPECULAR, none);
    glEnable(GL_LIGHT0);
    glEnable(GL_LIGHT1);
  }

  // Camera matrices (column-major for GL) and the clip planes, given in world coordinates.
  glMatrixMode(GL_PROJECTION);
  glLoadMatrixd(proj.data());
  glMatrixMode(GL_MODELVIEW);
  glLoadMatrixd(view.data());
  glClipPlane(GL_CLIP_PLANE0, plane_a);
  glClipPlane(GL_CLIP_PLANE1, plane_b);
  // GL_CLIP_PLANE2/3 together keep the complement: the cut-away wedge, for the ghost pass.
  const double ghost_a[4] = {-plane_a[0], -plane_a[1], -plane_a[2], -plane_a[3]};
  const double ghost_b[4] = {-plane_b[0], -plane_b[1], -plane_b[2], -plane_b[3]};
  glClipPlane(GL_CLIP_PLANE2, ghost_a);
  glClipPlane(GL_CLIP_PLANE3, ghost_b);
}

Eigen::Vector2d Renderer::project(const Eigen::Vector3d& world) const {
  const Eigen::Vector4d clip = impl_->proj * impl_->view * world.homogeneous();
  if (!(clip.w() > 0)) return Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  const double x_ndc = clip.x() / clip.w(), y_ndc = clip.y() / clip.w();
  return {0.5 * (x_ndc + 1.0) * impl_->width, 0.5 * (1.0 - y_ndc) * impl_->height};
}

Eigen::Vector3d Renderer::eye() const { return impl_->eye; }

void Renderer::Impl::build_surface(SurfaceScratch& s, const float* points, const int* tris, int n_tris, const float base[3],
                                   const std::uint8_t* contact, int n_points) {
  // Area-weighted vertex normals of this surface alone (so rims between surfaces stay crisp).
  const float* pos = points;
  std::vector<float>& nrm = s.normals;
  nrm.assign(static_cast<size_t>(n_points) * 3, 0.f);
  for (int t = 0; t < n_tris; ++t) {
    const int* v = tris + 3 * t;
    const float* a = &pos[3 * v[0]];
    const float* b = &pos[3 * v[1]];
    const float* c = &pos[3 * v[2]];
    const float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const float e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    for (int k = 0; k < 3; ++k) {
      float* out = &nrm[3 * v[k]];
      out[0] += n[0];
      out[1] += n[1];
      out[2] += n[2];
    }
  }
  for (int i = 0; i < n_points; ++i) {
    float* n = &nrm[3 * i];
    const float len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (len > 0.f) {
      n[0] /= len;
      n[1] /= len;
      n[2] /= len;
    }
  }
  // Vertex colours: the surface colour, or the contact colour where flagged.
  std::vector<float>& col = s.colors;
  col.resize(static_cast<size_t>(n_points) * 3);
  for (int i = 0; i < n_points; ++i) {
    const float* src = (contact != nullptr && contact[i] != 0) ? kContactColor : base;
    col[3 * i + 0] = src[0];
    col[3 * i + 1] = src[1];
    col[3 * i + 2] = src[2];
  }
}

void Renderer::Impl::draw_surfaces(const FrameView& f, bool ghost, bool uncut) {
  // Opaque: the surfaces with per-vertex colours (those cut by the wedge, or with `uncut` those never cut);
  // ghost: the Ghosted surfaces only, translucent in their material colour.
  glEnableClientState(GL_VERTEX_ARRAY);
  glEnableClientState(GL_NORMAL_ARRAY);
  const size_t n = f.surfaces.size();
  bool two_sided = true;  // the GL state set up in setup_gl_state()
  auto set_style = [&](const SurfaceStyle& st) {
    if (st.two_sided != two_sided) {
      two_sided = st.two_sided;
      glLightModeli(GL_LIGHT_MODEL_TWO_SIDE, two_sided ? GL_TRUE : GL_FALSE);
    }
    const bool metal = st.material == Material::Metal;
    glMaterialfv(GL_FRONT, GL_SPECULAR, metal ? kMetalSpecular : kTissueSpecular);
    glMaterialf(GL_FRONT, GL_SHININESS, metal ? kMetalShininess : kTissueShininess);
  };
  if (ghost) {
    for (size_t i = 0; i < n; ++i) {
      const Surface& s = f.surfaces[i];
      if (s.style.cutaway != CutAway::Ghosted || s.n_triangles == 0) continue;
      set_style(s.style);
      const float* c = base_colour(s.style.material);
      glColor4f(c[0], c[1], c[2], kGhostAlpha);
      glVertexPointer(3, GL_FLOAT, 0, points_of(f, i));
      glNormalPointer(GL_FLOAT, 0, surf[i].normals.data());
      glDrawElements(GL_TRIANGLES, 3 * s.n_triangles, GL_UNSIGNED_INT, s.triangles);
    }
  } else {
    glEnableClientState(GL_COLOR_ARRAY);
    const bool reverse = preset == CameraPreset::Endoscope;
    for (size_t k = 0; k < n; ++k) {
      const size_t i = reverse ? n - 1 - k : k;
      const Surface& s = f.surfaces[i];
      if (s.n_triangles == 0 || (s.style.cutaway == CutAway::Never) != uncut) continue;
      set_style(s.style);
      glVertexPointer(3, GL_FLOAT, 0, points_of(f, i));
      glNormalPointer(GL_FLOAT, 0, surf[i].normals.data());
      glColorPointer(3, GL_FLOAT, 0, surf[i].colors.data());
      glDrawElements(GL_TRIANGLES, 3 * s.n_triangles, GL_UNSIGNED_INT, s.triangles);
    }
    glDisableClientState(GL_COLOR_ARRAY);
  }
  if (!two_sided) glLightModeli(GL_LIGHT_MODEL_TWO_SIDE, GL_TRUE);
  glMaterialfv(GL_FRONT, GL_SPECULAR, kTissueSpecular);
  glMaterialf(GL_FRONT, GL_SHININESS, kTissueShininess);
  glDisableClientState(GL_NORMAL_ARRAY);
  glDisableClientState(GL_VERTEX_ARRAY);
}

void Renderer::Impl::build_arrow(const ProbeGlyph& probe, double force_scale) {
  // Arrow ending at the point and pointing along the force; a zero force points toward the axis.
  const Vec3 tip = probe.point;
  const double R = framing.radius;
  const double fmag = probe.force.norm();
  Vec3 dir;
  if (fmag > 1e-12) {
    dir = probe.force / fmag;
  } else {
    const Vec3 rel = tip - framing.lumen_center;
    const Vec3 radial = rel - axis * axis.dot(rel);
    dir = radial.norm() > 1e-9 * R ? Vec3(-radial.normalized()) : Vec3(-up);
  }
  const double min_length = 0.08 * R;
  const double length = std::max(fmag * force_scale, min_length);
  const double shaft_r = 0.012 * R, cone_r = 2.6 * shaft_r;
  const double cone_len = std::min(0.45 * length, 7.0 * shaft_r);
  const Vec3 tail = tip - length * dir, base = tip - cone_len * dir;
  // Orthonormal basis around the arrow direction.
  const Vec3 e1 = (std::abs(dir.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(dir).normalized();
  const Vec3 e2 = dir.cross(e1);
  auto emit = [this](const Vec3& p, const Vec3& n) {
    arrow.insert(arrow.end(), {float(p.x()), float(p.y()), float(p.z()), float(n.x()), float(n.y()), float(n.z())});
  };
  // Cone slant normal: radial and axial parts for a cone of radius cone_r and length cone_len.
  const double slant = std::hypot(cone_r, cone_len);
  for (int s = 0; s < kArrowSegments; ++s) {
    const double t0 = 2 * kPi * s / kArrowSegments, t1 = 2 * kPi * (s + 1) / kArrowSegments;
    const Vec3 r0 = std::cos(t0) * e1 + std::sin(t0) * e2, r1 = std::cos(t1) * e1 + std::sin(t1) * e2;
    // Shaft side (two triangles), wound counter-clockwise seen from outside, outward normals.
    emit(tail + shaft_r * r0, r0);
    emit(tail + shaft_r * r1, r1);
    emit(base + shaft_r * r1, r1);
    emit(tail + shaft_r * r0, r0);
    emit(base + shaft_r * r1, r1);
    emit(base + shaft_r * r0, r0);
    // Tail disk, facing backwards.
    emit(tail, -dir);
    emit(tail + shaft_r * r1, -dir);
    emit(tail + shaft_r * r0, -dir);
    // Cone side.
    const Vec3 n0 = (cone_len * r0 + cone_r * dir) / slant, n1 = (cone_len * r1 + cone_r * dir) / slant;
    emit(base + cone_r * r0, n0);
    emit(base + cone_r * r1, n1);
    emit(tip, ((n0 + n1) * 0.5).normalized());
    // Cone base disk, facing backwards.
    emit(base, -dir);
    emit(base + cone_r * r1, -dir);
    emit(base + cone_r * r0, -dir);
  }
}

void Renderer::Impl::draw_background() {
  // Vertical gradient over the whole viewport, no depth.
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_LIGHTING);
  glMatrixMode(GL_PROJECTION);
  glPushMatrix();
  glLoadIdentity();
  glMatrixMode(GL_MODELVIEW);
  glPushMatrix();
  glLoadIdentity();
  glBegin(GL_QUADS);
  glColor3fv(kBackgroundBottom);
  glVertex2f(-1.f, -1.f);
  glVertex2f(1.f, -1.f);
  glColor3fv(kBackgroundTop);
  glVertex2f(1.f, 1.f);
  glVertex2f(-1.f, 1.f);
  glEnd();
  glPopMatrix();
  glMatrixMode(GL_PROJECTION);
  glPopMatrix();
  glMatrixMode(GL_MODELVIEW);
  glEnable(GL_LIGHTING);
  glEnable(GL_DEPTH_TEST);
}

namespace {

// Validate a frame at the renderer's boundary, naming the field and the value.
void validate_frame(const FrameView& f) {
  if (f.n_points < 0) throw std::invalid_argument("FrameView.n_points must be >= 0 (value " + std::to_string(f.n_points) + ")");
  if (f.n_points > 0 && f.positions == nullptr) throw std::invalid_argument("FrameView.positions is null with n_points " + std::to_string(f.n_points));
  for (size_t i = 0; i < f.surfaces.size(); ++i) {
    const Surface& s = f.surfaces[i];
    const std::string name = "FrameView.surfaces[" + std::to_string(i) + "]";
    int n_points = f.n_points;
    if (s.positions != nullptr || s.n_points != 0) {
      if (s.n_points < 0) throw std::invalid_argument(name + ".n_points must be >= 0 (value " + std::to_string(s.n_points) + ")");
      if (s.n_points > 0 && s.positions == nullptr)
        throw std::invalid_argument(name + ".positions is null with n_points " + std::to_string(s.n_points));
      n_points = s.n_points;
    }
    check_tris(name + ".triangles", s.triangles, s.n_triangles, n_points);
  }
  if (!(f.force_scale >= 0) || !std::isfinite(f.force_scale))
    throw std::invalid_argument("FrameView.force_scale must be finite and >= 0 (value " + std::to_string(f.force_scale) + ")");
  // A placed camera: finite, forward and up non-zero and not parallel (look_at needs their cross product).
  if (f.camera) {
    const CameraPose& c = *f.camera;
    const bool finite = finite3(c.eye) && finite3(c.forward) && finite3(c.up);
    const double fn = c.forward.norm(), un = c.up.norm();
    if (!finite || !(fn > 0) || !(un > 0) || !(c.forward.cross(c.up).norm() > kMinCameraSine * fn * un))
      throw std::invalid_argument("FrameView.camera must be finite with forward and up non-zero and not parallel (eye " +
                                  vec_text(c.eye) + ", forward " + vec_text(c.forward) + ", up " + vec_text(c.up) + ")");
  }
  for (size_t i = 0; i < f.probes.size(); ++i) {
    if (!finite3(f.probes[i].point) || !finite3(f.probes[i].force))
      throw std::invalid_argument("FrameView.probes[" + std::to_string(i) + "] must be finite (point " + vec_text(f.probes[i].point) +
                                  ", force " + vec_text(f.probes[i].force) + ")");
  }
}

}  // namespace

void Renderer::Impl::place_camera(const std::optional<CameraPose>& pose) {
  if (pose) {
    eye = pose->eye;
    view = look_at(eye, eye + pose->forward.normalized(), pose->up);
  } else {
    eye = preset_eye;
    view = preset_view;
  }
  // Lights were placed in eye coordinates, so the endoscope's head light follows the eye.
  glMatrixMode(GL_MODELVIEW);
  glLoadMatrixd(view.data());
}

void Renderer::Impl::build_frame(const FrameView& f) {
  pos.resize(static_cast<size_t>(f.n_points) * 3);
  for (size_t k = 0; k < pos.size(); ++k) pos[k] = static_cast<float>(f.positions[k]);
  surf.resize(f.surfaces.size());
  for (size_t i = 0; i < f.surfaces.size(); ++i) {
    const Surface& s = f.surfaces[i];
    SurfaceScratch& sc = surf[i];
    const bool own = s.positions != nullptr;
    if (own) {
      sc.pos.resize(static_cast<size_t>(s.n_points) * 3);
      for (size_t k = 0; k < sc.pos.size(); ++k) sc.pos[k] = static_cast<float>(s.positions[k]);
    }
    // Contact flags are per frame point: a surface with its own points is never contact-coloured.
    const std::uint8_t* contact = (s.style.contact_colouring && !own) ? f.contact : nullptr;
    build_surface(sc, points_of(f, i), s.triangles, s.n_triangles, base_colour(s.style.material), contact,
                  own ? s.n_points : f.n_points);
  }
  arrow.clear();
  for (const ProbeGlyph& p : f.probes) build_arrow(p, f.force_scale);
}

void Renderer::Impl::draw_opaque(const FrameView& f) {
  if (cut) {
    glEnable(GL_CLIP_PLANE0);
    draw_surfaces(f, false, false);
    glDisable(GL_CLIP_PLANE0);
    glEnable(GL_CLIP_PLANE1);
    draw_surfaces(f, false, false);
    glDisable(GL_CLIP_PLANE1);
    draw_surfaces(f, false, true);
  } else if (preset == CameraPreset::Endoscope) {
    // From inside the lumen every visible wall faces the eye: cull back faces (the outer wall, hidden anyway).
    glEnable(GL_CULL_FACE);
    glCullFace(GL_BACK);
    draw_surfaces(f, false, false);
    draw_surfaces(f, false, true);
    glDisable(GL_CULL_FACE);
  } else {
    draw_surfaces(f, false, false);
    draw_surfaces(f, false, true);
  }
}

void Renderer::Impl::draw_arrows() {
  if (arrow.empty()) return;
  glColor3fv(kProbeColor);
  glEnableClientState(GL_VERTEX_ARRAY);
  glEnableClientState(GL_NORMAL_ARRAY);
  glVertexPointer(3, GL_FLOAT, 6 * sizeof(float), arrow.data());
  glNormalPointer(GL_FLOAT, 6 * sizeof(float), arrow.data() + 3);
  glDrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(arrow.size() / 6));
  glDisableClientState(GL_NORMAL_ARRAY);
  glDisableClientState(GL_VERTEX_ARRAY);
}

void Renderer::Impl::draw_ghost(const FrameView& f) {
  const bool any_ghost = std::any_of(f.surfaces.begin(), f.surfaces.end(), [](const Surface& s) {
    return s.style.cutaway == CutAway::Ghosted && s.n_triangles > 0;
  });
  if (!cut || !any_ghost) return;
  glEnable(GL_CLIP_PLANE2);
  glEnable(GL_CLIP_PLANE3);
  glEnable(GL_CULL_FACE);
  glCullFace(GL_BACK);
  glEnable(GL_BLEND);
  glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
  glDepthMask(GL_FALSE);
  draw_surfaces(f, true, false);
  glDepthMask(GL_TRUE);
  glDisable(GL_BLEND);
  glDisable(GL_CULL_FACE);
  glDisable(GL_CLIP_PLANE3);
  glDisable(GL_CLIP_PLANE2);
}

void Renderer::Impl::read_back(Image& out) {
  // Read back (bottom row first) and flip so row 0 is the top of the image.
  glFinish();
  glReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, readback.data());
  const size_t w = static_cast<size_t>(width), h = static_cast<size_t>(height);
  out.width = width;
  out.height = height;
  out.rgb.resize(w * h * 3);
  for (size_t y = 0; y < h; ++y) {
    const unsigned char* src = readback.data() + (h - 1 - y) * w * 4;
    unsigned char* dst = out.rgb.data() + y * w * 3;
    for (size_t x = 0; x < w; ++x, src += 4, dst += 3) {
      dst[0] = src[0];
      dst[1] = src[1];
      dst[2] = src[2];
    }
  }
}

void Renderer::draw(const FrameView& f, Image& out) {
  validate_frame(f);
  Impl& m = *impl_;
  if (f.camera && m.preset != CameraPreset::Endoscope)
    throw std::invalid_argument("FrameView.camera is for the endoscope camera only");
  // Bind the context on this thread for the duration of the call.
  m.make_current();
  struct Release {
    ~Release() { OSMesaMakeCurrent(nullptr, nullptr, 0, 0, 0); }
  } release;
  m.place_camera(f.camera);
  m.build_frame(f);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  m.draw_background();
  m.draw_opaque(f);
  m.draw_arrows();
  m.draw_ghost(f);
  m.read_back(out);
}

}  // namespace lumen::render
