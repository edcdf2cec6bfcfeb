// Renderer tests on real pixels: framing of the camera presets, cut-away, lighting, contact colour, probe arrows.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <thread>
#include <vector>

#include <Eigen/Geometry>

#include "render/renderer.hpp"

namespace lumen::render {
namespace {

// Hollow tube along +z from z = 0 to z = length: outer ring nodes, then inner ring nodes; surface triangles
// wound so their normals point out of the wall (outer: away from the axis, inner: toward it, ends: along -z / +z).
struct Tube {
  int around = 20, along = 10;
  double inner_radius = 0.01, outer_radius = 0.013, length = 0.1;  // metres
  std::vector<double> pos;                                          // n x 3, metres
  std::vector<int> outer, inner, ends;                              // triangles, n x 3

  int n_points() const { return static_cast<int>(pos.size() / 3); }
  int outer_node(int i, int j) const { return j * around + (i % around); }
  int inner_node(int i, int j) const { return (along + 1) * around + j * around + (i % around); }
  bool is_inner(int k) const { return k >= (along + 1) * around; }

  Tube() {
    // Nodes: rings of `around` points at `along + 1` stations, outer layer first.
    for (double r : {outer_radius, inner_radius})
      for (int j = 0; j <= along; ++j)
        for (int i = 0; i < around; ++i) {
          const double th = 2 * EIGEN_PI * i / around;
          pos.insert(pos.end(), {r * std::cos(th), r * std::sin(th), length * j / along});
        }
    // Walls: two triangles per quad.
    for (int j = 0; j < along; ++j)
      for (int i = 0; i < around; ++i) {
        const int a = outer_node(i, j), b = outer_node(i + 1, j), c = outer_node(i + 1, j + 1), d = outer_node(i, j + 1);
        outer.insert(outer.end(), {a, b, d, b, c, d});
        const int e = inner_node(i, j), f = inner_node(i + 1, j), g = inner_node(i + 1, j + 1), h = inner_node(i, j + 1);
        inner.insert(inner.end(), {e, h, f, f, h, g});
      }
    // End annuli at z = 0 (facing -z) and z = length (facing +z).
    for (int i = 0; i < around; ++i) {
      int i0 = inner_node(i, 0), i1 = inner_node(i + 1, 0), o0 = outer_node(i, 0), o1 = outer_node(i + 1, 0);
      ends.insert(ends.end(), {i0, o1, o0, i0, i1, o1});
      i0 = inner_node(i, along), i1 = inner_node(i + 1, along), o0 = outer_node(i, along), o1 = outer_node(i + 1, along);
      ends.insert(ends.end(), {i0, o0, o1, i0, o1, i1});
    }
  }

  Framing framing(double cutaway_degrees) const {
    Framing f;
    f.center = Eigen::Vector3d(0, 0, length / 2);
    f.radius = std::hypot(length / 2, outer_radius);
    f.axis = Eigen::Vector3d::UnitZ();
    f.lumen_center = f.center;
    f.lumen_radius = inner_radius;
    f.half_length = length / 2;
    f.cutaway_degrees = cutaway_degrees;
    return f;
  }

  FrameView view() const {
    FrameView v;
    v.positions = pos.data();
    v.n_points = n_points();
    // Outermost first, in the organ walls' styles.
    v.surfaces.push_back({outer.data(), static_cast<int>(outer.size() / 3), SurfaceStyle::outer_wall()});
    v.surfaces.push_back({ends.data(), static_cast<int>(ends.size() / 3), SurfaceStyle::wall_ends()});
    v.surfaces.push_back({inner.data(), static_cast<int>(inner.size() / 3), SurfaceStyle::inner_wall()});
    return v;
  }
};

constexpr int kW = 320, kH = 240;

struct Rgb {
  int r, g, b;
};
Rgb pixel(const Image& im, int x, int y) {
  const std::uint8_t* p = &im.rgb[(static_cast<size_t>(y) * im.width + x) * 3];
  return {p[0], p[1], p[2]};
}
double luminance(Rgb c) { return 0.2126 * c.r + 0.7152 * c.g + 0.0722 * c.b; }
bool differs(const Image& a, const Image& b, int x, int y) {
  const Rgb p = pixel(a, x, y), q = pixel(b, x, y);
  return std::abs(p.r - q.r) + std::abs(p.g - q.g) + std::abs(p.b - q.b) > 24;
}
// Colour classes of the renderer's palette (tissue is red-dominant; the inner wall is orange: g clearly above b).
bool is_inner_colour(Rgb c) { return c.r > 60 && c.r > c.g + 25 && c.g > c.b + 12; }
bool is_contact_colour(Rgb c) { return c.g > c.r + 20 && c.g > c.b + 60; }
bool is_probe_colour(Rgb c) { return c.b > c.r + 60 && c.b > c.g + 30; }

struct Box {
  int x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;
  long count = 0;
  void add(double x, double y) {
    x0 = std::min(x0, static_cast<int>(std::floor(x)));
    y0 = std::min(y0, static_cast<int>(std::floor(y)));
    x1 = std::max(x1, static_cast<int>(std::floor(x)));
    y1 = std::max(y1, static_cast<int>(std::floor(y)));
    ++count;
  }
};

template <class Pred>
Box pixel_box(const Image& im, Pred pred) {
  Box b;
  for (int y = 0; y < im.height; ++y)
    for (int x = 0; x < im.width; ++x)
      if (pred(x, y)) b.add(x, y);
  return b;
}

Image draw(Renderer& r, const FrameView& v) {
  Image im;
  r.draw(v, im);
  return im;
}

// The background alone: the independent reference for "organ pixels".
Image background(Renderer& r) { return draw(r, FrameView{}); }

TEST(Renderer, ParseCamera) {
  EXPECT_EQ(parse_camera("side"), CameraPreset::Side);
  EXPECT_EQ(parse_camera("diagonal"), CameraPreset::Diagonal);
  EXPECT_EQ(parse_camera("endoscope"), CameraPreset::Endoscope);
  EXPECT_THROW(parse_camera("top"), std::invalid_argument);
}

TEST(Renderer, RejectsBadParameters) {
  const Tube t;
  EXPECT_THROW(Renderer(0, kH, CameraPreset::Side, t.framing(100)), std::invalid_argument);
  Framing f = t.framing(100);
  f.radius = -1;
  EXPECT_THROW(Renderer(kW, kH, CameraPreset::Side, f), std::invalid_argument);
  f = t.framing(100);
  f.axis = Eigen::Vector3d::Zero();
  EXPECT_THROW(Renderer(kW, kH, CameraPreset::Side, f), std::invalid_argument);
  f = t.framing(270);
  EXPECT_THROW(Renderer(kW, kH, CameraPreset::Side, f), std::invalid_argument);

  Renderer r(kW, kH, CameraPreset::Side, t.framing(100));
  Image im;
  std::vector<int> bad = t.outer;
  bad[7] = t.n_points();
  FrameView v = t.view();
  v.surfaces[0].triangles = bad.data();  // the outer wall
  try {
    r.draw(v, im);
    FAIL() << "index out of range accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("surfaces[0].triangles[7]"), std::string::npos) << e.what();
  }
  // A surface with its own points is checked against those, not the frame's.
  const std::vector<double> three = {0, 0, 0, 0.001, 0, 0, 0, 0.001, 0};
  const std::vector<int> tri = {0, 1, 3};
  v = t.view();
  v.surfaces.push_back({tri.data(), 1, SurfaceStyle::metal(), three.data(), 3});
  EXPECT_THROW(r.draw(v, im), std::invalid_argument);
  v.surfaces.back().positions = nullptr;  // n_points 3 without an array
  EXPECT_THROW(r.draw(v, im), std::invalid_argument);
  v = t.view();
  v.positions = nullptr;
  EXPECT_THROW(r.draw(v, im), std::invalid_argument);
  v = t.view();
  v.probes.push_back({Eigen::Vector3d(0, 0, NAN), Eigen::Vector3d::Zero()});
  EXPECT_THROW(r.draw(v, im), std::invalid_argument);
}

TEST(Renderer, ImageSizeAndRowsTopDown) {
  // The background gradient is lighter at the top: row 0 must be the top of the image.
  const Tube t;
  Renderer r(kW, kH, CameraPreset::Side, t.framing(100));
  const Image bg = background(r);
  ASSERT_EQ(bg.width, kW);
  ASSERT_EQ(bg.height, kH);
  ASSERT_EQ(bg.rgb.size(), static_cast<size_t>(kW * kH * 3));
  EXPECT_GT(luminance(pixel(bg, kW / 2, 2)), luminance(pixel(bg, kW / 2, kH - 3)) + 10);
}

TEST(Renderer, SideAndDiagonalFrameTheWholeOrgan) {
  const Tube t;
  for (CameraPreset preset : {CameraPreset::Side, CameraPreset::Diagonal}) {
    SCOPED_TRACE(preset == CameraPreset::Side ? "side" : "diagonal");
    Renderer r(kW, kH, preset, t.framing(100));
    const Image bg = background(r);
    const Image im = draw(r, t.view());
    // A plausible fraction of the image is organ, and its bounding box is roughly centred.
    const Box organ = pixel_box(im, [&](int x, int y) { return differs(im, bg, x, y); });
    const double fraction = static_cast<double>(organ.count) / (kW * kH);
    EXPECT_GT(fraction, 0.10);
    EXPECT_LT(fraction, 0.90);
    EXPECT_NEAR(0.5 * (organ.x0 + organ.x1), kW / 2.0, 0.1 * kW);
    EXPECT_NEAR(0.5 * (organ.y0 + organ.y1), kH / 2.0, 0.1 * kH);
    // Nothing touches the image border: the whole organ is in view.
    EXPECT_GT(organ.x0, 0);
    EXPECT_GT(organ.y0, 0);
    EXPECT_LT(organ.x1, kW - 1);
    EXPECT_LT(organ.y1, kH - 1);
    // The rasterised silhouette matches the projection of the outer-wall vertices.
    Box projected;
    for (int k = 0; k < t.n_points(); ++k) {
      const Eigen::Vector2d p = r.project(Eigen::Vector3d(t.pos[3 * k], t.pos[3 * k + 1], t.pos[3 * k + 2]));
      projected.add(p.x(), p.y());
    }
    EXPECT_NEAR(organ.x0, projected.x0, 2);
    EXPECT_NEAR(organ.x1, projected.x1, 2);
    EXPECT_NEAR(organ.y0, projected.y0, 2);
    EXPECT_NEAR(organ.y1, projected.y1, 2);
  }
}

TEST(Renderer, SideLooksAcrossTheAxisDiagonalFromAbove) {
  const Tube t;
  const Framing f = t.framing(100);
  const Eigen::Vector3d start = f.center - f.half_length * f.axis, stop = f.center + f.half_length * f.axis;
  {
    // Side: the axis projects horizontally, left to right; +y (up) is up in the image; the eye is level.
    Renderer r(kW, kH, CameraPreset::Side, f);
    const Eigen::Vector2d a = r.project(start), b = r.project(stop), c = r.project(f.center);
    EXPECT_NEAR(a.y(), b.y(), 0.5);
    EXPECT_GT(b.x() - a.x(), 0.5 * kW);
    EXPECT_LT(r.project(f.center + Eigen::Vector3d(0, t.outer_radius, 0)).y(), c.y() - 5);
    const Eigen::Vector3d to_eye = (r.eye() - f.center).normalized();
    EXPECT_NEAR(to_eye.dot(f.axis), 0.0, 1e-9);
    EXPECT_NEAR(to_eye.y(), 0.0, 1e-9);
  }
  {
    // Diagonal: elevation 35..45 degrees above the axis plane, and not square to the axis.
    Renderer r(kW, kH, CameraPreset::Diagonal, f);
    const Eigen::Vector3d to_eye = (r.eye() - f.center).normalized();
    const double elevation = std::asin(to_eye.y()) * 180 / EIGEN_PI;
    EXPECT_GE(elevation, 35.0);
    EXPECT_LE(elevation, 45.0);
    EXPECT_GT(std::abs(to_eye.dot(f.axis)), 0.2);
  }
}

TEST(Renderer, EndoscopeSeesTheInnerWallAroundAndTheFarLumenInTheCentre) {
  const Tube t;
  const Framing f = t.framing(100);
  Renderer r(kW, kH, CameraPreset::Endoscope, f);
  // The eye is inside the lumen, on the axis, near one end.
  const Eigen::Vector3d eye = r.eye();
  EXPECT_LT(std::hypot(eye.x(), eye.y()), 1e-9);
  EXPECT_GT(eye.z(), 0.0);
  EXPECT_LT(eye.z(), 0.25 * t.length);
  // Every border pixel shows the inner wall.
  const Image bg = background(r);
  const Image im = draw(r, t.view());
  long border = 0, wall = 0;
  double border_lum = 0;
  for (int x = 0; x < kW; ++x)
    for (int y : {0, kH - 1}) {
      ++border;
      wall += differs(im, bg, x, y) && is_inner_colour(pixel(im, x, y));
      border_lum += luminance(pixel(im, x, y));
    }
  for (int y = 0; y < kH; ++y)
    for (int x : {0, kW - 1}) {
      ++border;
      wall += differs(im, bg, x, y) && is_inner_colour(pixel(im, x, y));
      border_lum += luminance(pixel(im, x, y));
    }
  EXPECT_EQ(wall, border);
  // The far lumen (central tenth of the image) is much darker than the near walls.
  double centre_lum = 0;
  long centre = 0;
  for (int y = kH * 9 / 20; y < kH * 11 / 20; ++y)
    for (int x = kW * 9 / 20; x < kW * 11 / 20; ++x) {
      centre_lum += luminance(pixel(im, x, y));
      ++centre;
    }
  EXPECT_LT(centre_lum / centre, 0.5 * border_lum / border);
}

// The endoscope placed per frame (riding on an instrument): the eye where it is put, the viewing direction at the
// image centre, the preset's place back on a frame without a pose, and bad poses refused.
TEST(Renderer, PlacedEndoscopeLooksWhereItIsPutAndReturnsToItsPreset) {
  const Tube t;
  Renderer r(kW, kH, CameraPreset::Endoscope, t.framing(100));
  const Eigen::Vector3d preset_eye = r.eye();
  // Inside the lumen at mid-length, 4 mm off the axis, looking at the wall straight up (+y), up along the axis.
  FrameView v = t.view();
  v.camera = CameraPose{Eigen::Vector3d(0, 0.004, 0.05), Eigen::Vector3d(0, 2.0, 0), Eigen::Vector3d(0, 0.3, 1.0)};
  const Image bg = background(r);
  const Image im = draw(r, v);
  EXPECT_LT((r.eye() - Eigen::Vector3d(0, 0.004, 0.05)).norm(), 1e-15);
  // The wall point straight ahead projects to the image centre, the axis direction (+z) to the image's top half.
  const Eigen::Vector2d ahead = r.project(Eigen::Vector3d(0, t.inner_radius, 0.05));
  EXPECT_NEAR(ahead.x(), kW / 2.0, 1e-6);
  EXPECT_NEAR(ahead.y(), kH / 2.0, 1e-6);
  EXPECT_LT(r.project(Eigen::Vector3d(0, t.inner_radius, 0.055)).y(), kH / 2.0);
  // What is seen there is the inner wall, lit by the head light (brighter than the preset's far lumen centre).
  EXPECT_TRUE(differs(im, bg, kW / 2, kH / 2));
  EXPECT_TRUE(is_inner_colour(pixel(im, kW / 2, kH / 2)));
  // The next frame without a pose is drawn from the preset's place again.
  const Image back = draw(r, t.view());
  EXPECT_LT((r.eye() - preset_eye).norm(), 1e-15);
  Renderer fresh(kW, kH, CameraPreset::Endoscope, t.framing(100));
  EXPECT_EQ(back.rgb, draw(fresh, t.view()).rgb);
  // Refused: a pose for an orbit camera, forward parallel to up, a zero or non-finite direction.
  Renderer side(kW, kH, CameraPreset::Side, t.framing(100));
  Image out;
  EXPECT_THROW(side.draw(v, out), std::invalid_argument);
  FrameView bad = t.view();
  bad.camera = CameraPose{Eigen::Vector3d(0, 0, 0.05), Eigen::Vector3d::UnitZ(), 3.0 * Eigen::Vector3d::UnitZ()};
  EXPECT_THROW(r.draw(bad, out), std::invalid_argument);
  bad.camera->forward = Eigen::Vector3d::Zero();
  EXPECT_THROW(r.draw(bad, out), std::invalid_argument);
  bad.camera->forward = Eigen::Vector3d(0, std::nan(""), 1);
  EXPECT_THROW(r.draw(bad, out), std::invalid_argument);
}

TEST(Renderer, CutAwayShowsTheInnerWall) {
  // Without the cut only the outer wall is seen from the side; with it the inner wall shows through.
  const Tube t;
  Renderer closed(kW, kH, CameraPreset::Side, t.framing(0));
  Renderer cut(kW, kH, CameraPreset::Side, t.framing(100));
  const Image a = draw(closed, t.view()), b = draw(cut, t.view());
  const long inner_closed = pixel_box(a, [&](int x, int y) { return is_inner_colour(pixel(a, x, y)); }).count;
  const long inner_cut = pixel_box(b, [&](int x, int y) { return is_inner_colour(pixel(b, x, y)); }).count;
  EXPECT_EQ(inner_closed, 0);
  EXPECT_GT(inner_cut, kW * kH / 20);
}

TEST(Renderer, LightingIsNotFlat) {
  // Down the image column through the centre, the lit outer wall's luminance varies with its normal.
  const Tube t;
  Renderer r(kW, kH, CameraPreset::Side, t.framing(0));
  const Image bg = background(r);
  const Image im = draw(r, t.view());
  const int x = static_cast<int>(r.project(t.framing(0).center).x());
  std::vector<double> lum;
  for (int y = 0; y < kH; ++y)
    if (differs(im, bg, x, y)) lum.push_back(luminance(pixel(im, x, y)));
  ASSERT_GT(lum.size(), 20u);
  double mean = 0, var = 0;
  for (double l : lum) mean += l / lum.size();
  for (double l : lum) var += (l - mean) * (l - mean) / lum.size();
  EXPECT_GT(std::sqrt(var), 10.0);
  EXPECT_GT(*std::max_element(lum.begin(), lum.end()) - *std::min_element(lum.begin(), lum.end()), 40.0);
}

TEST(Renderer, ContactColourOnlyWhereFlagged) {
  const Tube t;
  Renderer r(kW, kH, CameraPreset::Side, t.framing(100));
  FrameView v = t.view();
  // No flags (null or all zero): no contact colour anywhere, and the two images are the same.
  const Image none = draw(r, v);
  std::vector<std::uint8_t> flags(t.n_points(), 0);
  v.contact = flags.data();
  const Image zeros = draw(r, v);
  EXPECT_EQ(none.rgb, zeros.rgb);
  EXPECT_EQ(pixel_box(none, [&](int x, int y) { return is_contact_colour(pixel(none, x, y)); }).count, 0);
  // Flag a patch of the lower inner wall (seen through the cut) in the middle third of the length.
  Box flagged;
  for (int k = 0; k < t.n_points(); ++k) {
    const double y = t.pos[3 * k + 1], z = t.pos[3 * k + 2];
    if (t.is_inner(k) && y < -0.5 * t.inner_radius && z > t.length / 3 && z < 2 * t.length / 3) {
      flags[k] = 1;
      const Eigen::Vector2d p = r.project(Eigen::Vector3d(t.pos[3 * k], y, z));
      flagged.add(p.x(), p.y());
    }
  }
  const Image im = draw(r, v);
  const Box contact = pixel_box(im, [&](int x, int y) { return is_contact_colour(pixel(im, x, y)); });
  EXPECT_GT(contact.count, 100);
  // The contact colour lies within the projected patch (one triangle ring of blending around it).
  EXPECT_GE(contact.x0, flagged.x0 - 20);
  EXPECT_LE(contact.x1, flagged.x1 + 20);
  EXPECT_GE(contact.y0, flagged.y0 - 20);
  EXPECT_LE(contact.y1, flagged.y1 + 20);
}

TEST(Renderer, ProbeArrowEndsAtThePointAndGrowsWithForce) {
  const Tube t;
  const Framing f = t.framing(0);
  Renderer r(kW, kH, CameraPreset::Side, f);
  const Eigen::Vector3d point(0, t.outer_radius, t.length / 2);
  const Eigen::Vector2d tip = r.project(point);
  long previous = 0;
  for (double force : {0.0, 1.0, 2.0}) {
    SCOPED_TRACE(force);
    FrameView v = t.view();
    v.force_scale = 0.015;
    v.probes.push_back({point, Eigen::Vector3d(0, -force, 0)});
    const Image im = draw(r, v);
    const Box arrow = pixel_box(im, [&](int x, int y) { return is_probe_colour(pixel(im, x, y)); });
    ASSERT_GT(arrow.count, 0);
    // The arrow ends at the probe point, pushing down into it, centred on it horizontally.
    EXPECT_NEAR(arrow.y1, tip.y(), 3.0);  // the last pixels of the cone tip are sub-pixel wide
    EXPECT_NEAR(0.5 * (arrow.x0 + arrow.x1), tip.x(), 1.5);
    if (force > 0) {
      // Its tail is at point - force * force_scale (projected), above the point.
      const Eigen::Vector2d tail = r.project(point - v.force_scale * v.probes[0].force);
      EXPECT_NEAR(arrow.y0, tail.y(), 2.5);
    }
    EXPECT_GT(arrow.count, previous);
    previous = arrow.count;
  }
}

TEST(Renderer, TranslatingTheOrganMovesItsPixels) {
  // Positions are read every frame: shifting them along the axis shifts the silhouette by the projected amount.
  const Tube t;
  Renderer r(kW, kH, CameraPreset::Side, t.framing(0));
  const Image bg = background(r);
  const Image a = draw(r, t.view());
  Tube moved = t;
  const double dz = 0.01;
  for (int k = 0; k < moved.n_points(); ++k) moved.pos[3 * k + 2] += dz;
  const Image b = draw(r, moved.view());
  const Box ba = pixel_box(a, [&](int x, int y) { return differs(a, bg, x, y); });
  const Box bb = pixel_box(b, [&](int x, int y) { return differs(b, bg, x, y); });
  // Expected: the shift of the right-most projected vertex.
  auto right_most = [&](const Tube& tube) {
    double x = -1e9;
    for (int k = 0; k < tube.n_points(); ++k)
      x = std::max(x, r.project(Eigen::Vector3d(tube.pos[3 * k], tube.pos[3 * k + 1], tube.pos[3 * k + 2])).x());
    return x;
  };
  const double shift = right_most(moved) - right_most(t);
  EXPECT_GT(shift, 5.0);
  EXPECT_NEAR(bb.x1 - ba.x1, shift, 2.0);
}

TEST(Renderer, SeveralRenderersOnOneThread) {
  // Each draw makes its own context current: interleaved renderers give the same images as alone.
  const Tube t;
  Renderer side(kW, kH, CameraPreset::Side, t.framing(100));
  Renderer endo(kW, kH, CameraPreset::Endoscope, t.framing(100));
  const Image s1 = draw(side, t.view());
  const Image e1 = draw(endo, t.view());
  const Image s2 = draw(side, t.view());
  const Image e2 = draw(endo, t.view());
  EXPECT_EQ(s1.rgb, s2.rgb);
  EXPECT_EQ(e1.rgb, e2.rgb);
  EXPECT_NE(s1.rgb, e1.rgb);
}

TEST(Renderer, DrawsOnAnotherThreadThanItWasBuiltOn) {
  // The simulation thread draws with a renderer built elsewhere: same pixels as drawing here.
  const Tube t;
  Renderer r(kW, kH, CameraPreset::Diagonal, t.framing(100));
  Image there;
  std::thread worker([&] { r.draw(t.view(), there); });
  worker.join();
  const Image here = draw(r, t.view());
  EXPECT_EQ(there.rgb, here.rgb);
}

// A closed box (8 corners, 12 outward-facing triangles) centred at `c`, half size `h`: an instrument's own points.
struct BoxMesh {
  std::vector<double> pos;
  std::vector<int> tris;
  BoxMesh(const Eigen::Vector3d& c, double h) {
    for (int k = 0; k < 8; ++k)
      pos.insert(pos.end(), {c.x() + ((k & 1) ? h : -h), c.y() + ((k & 2) ? h : -h), c.z() + ((k & 4) ? h : -h)});
    // Faces as corner quads (counter-clockwise seen from outside).
    const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (const auto& q : quads) tris.insert(tris.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
  }
  Surface surface() const { return {tris.data(), static_cast<int>(tris.size() / 3), SurfaceStyle::metal(), pos.data(), 8}; }
};

TEST(Renderer, ExtraSurfaceWithItsOwnPointsIsDrawnAsMetal) {
  // A metal box between the side camera and the organ, inside the cut-away wedge: instruments are never cut.
  const Tube t;
  const Framing f = t.framing(100);
  Renderer r(kW, kH, CameraPreset::Side, f);
  const Eigen::Vector3d to_eye = (r.eye() - f.center).normalized();
  const BoxMesh box(f.center + 0.025 * to_eye + Eigen::Vector3d(0, 0, 0.02), 0.005);
  const Image without = draw(r, t.view());
  FrameView v = t.view();
  v.surfaces.push_back(box.surface());
  const Image with = draw(r, v);
  Box projected;
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector2d p = r.project(Eigen::Vector3d(box.pos[3 * k], box.pos[3 * k + 1], box.pos[3 * k + 2]));
    projected.add(p.x(), p.y());
  }
  const Box changed = pixel_box(with, [&](int x, int y) { return differs(with, without, x, y); });
  // Pixels change where the box projects, and only there.
  const long area = static_cast<long>(projected.x1 - projected.x0 + 1) * (projected.y1 - projected.y0 + 1);
  EXPECT_GT(changed.count, area / 2);
  EXPECT_GE(changed.x0, projected.x0 - 2);
  EXPECT_LE(changed.x1, projected.x1 + 2);
  EXPECT_GE(changed.y0, projected.y0 - 2);
  EXPECT_LE(changed.y1, projected.y1 + 2);
  // It is grey metal, not tissue: at its projected centre red, green and blue are close.
  const Eigen::Vector2d mid = r.project(f.center + 0.025 * to_eye + Eigen::Vector3d(0, 0, 0.02));
  const Rgb c = pixel(with, static_cast<int>(mid.x()), static_cast<int>(mid.y()));
  EXPECT_LT(std::abs(c.r - c.g), 20) << c.r << " " << c.g << " " << c.b;
  EXPECT_LT(std::abs(c.g - c.b), 20) << c.r << " " << c.g << " " << c.b;
  EXPECT_GT(luminance(c), 40);
  // Styled as a cut wall instead, the box (wholly inside the wedge) is removed with it.
  v.surfaces.back().style.cutaway = CutAway::Removed;
  EXPECT_EQ(draw(r, v).rgb, without.rgb);
}

TEST(Renderer, FrameOrganOfTheTubeIsItsFraming) {
  // From the rest points and the inner-wall triangles alone: the tube's box, axis, lumen radius and length.
  const Tube t;
  Framing want = t.framing(100);
  want.radius = 0.5 * std::sqrt(t.length * t.length + 8 * t.outer_radius * t.outer_radius);  // half the box diagonal
  const Framing f = frame_organ(t.pos.data(), t.n_points(), t.inner.data(), static_cast<int>(t.inner.size() / 3));
  EXPECT_LT((f.center - want.center).norm(), 1e-12);
  EXPECT_NEAR(f.radius, want.radius, 1e-12);
  EXPECT_LT((f.axis - want.axis).norm(), 1e-9);
  EXPECT_LT((f.lumen_center - want.lumen_center).norm(), 1e-12);
  EXPECT_NEAR(f.lumen_radius, want.lumen_radius, 1e-12);
  EXPECT_NEAR(f.half_length, want.half_length, 1e-12);
  EXPECT_EQ(f.cutaway_degrees, 100.0);
  // Same images as the hand-made framing.
  for (CameraPreset preset : {CameraPreset::Side, CameraPreset::Diagonal, CameraPreset::Endoscope}) {
    Renderer a(kW, kH, preset, want), b(kW, kH, preset, f);
    EXPECT_EQ(draw(a, t.view()).rgb, draw(b, t.view()).rgb);
  }
  EXPECT_THROW(frame_organ(nullptr, 3, nullptr, 0), std::invalid_argument);
  const std::vector<int> bad = {0, 1, t.n_points()};
  EXPECT_THROW(frame_organ(t.pos.data(), t.n_points(), bad.data(), 1), std::invalid_argument);
}

TEST(Renderer, FrameOrganWithoutALumen) {
  // A solid (an instrument alone): framed on its box, a valid framing for every camera.
  const BoxMesh box(Eigen::Vector3d(0.1, 0.2, -0.3), 0.01);
  const Framing f = frame_organ(box.pos.data(), 8, nullptr, 0);
  EXPECT_LT((f.center - Eigen::Vector3d(0.1, 0.2, -0.3)).norm(), 1e-12);
  EXPECT_NEAR(f.radius, std::sqrt(3.0) * 0.01, 1e-12);
  EXPECT_LT((f.lumen_center - f.center).norm(), 1e-12);
  EXPECT_GT(f.lumen_radius, 0.0);
  EXPECT_LT(f.lumen_radius, f.radius);
  for (CameraPreset preset : {CameraPreset::Side, CameraPreset::Diagonal, CameraPreset::Endoscope})
    EXPECT_NO_THROW(Renderer(kW, kH, preset, f));
  // The box is drawn at the image centre by the side camera.
  Renderer r(kW, kH, CameraPreset::Side, f);
  FrameView v;
  v.surfaces.push_back(box.surface());
  const Image bg = background(r), im = draw(r, v);
  EXPECT_TRUE(differs(im, bg, kW / 2, kH / 2));
}

TEST(Renderer, FramingFollowsATranslatedRotatedOrgan) {
  // Move and turn the tube: the framing computed from its points follows, the organ stays centred in the image
  // and the endoscope stays inside the lumen, looking along it.
  const Tube t;
  const Eigen::Matrix3d rot =
      (Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 0.5).normalized()) * Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY()))
          .toRotationMatrix();
  const Eigen::Vector3d shift(0.3, -0.2, 0.15);
  Tube moved = t;
  for (int k = 0; k < t.n_points(); ++k) {
    const Eigen::Vector3d p = rot * Eigen::Vector3d(t.pos[3 * k], t.pos[3 * k + 1], t.pos[3 * k + 2]) + shift;
    for (int d = 0; d < 3; ++d) moved.pos[3 * k + d] = p[d];
  }
  const Framing f = frame_organ(moved.pos.data(), moved.n_points(), moved.inner.data(), static_cast<int>(moved.inner.size() / 3));
  const Eigen::Vector3d axis = rot * Eigen::Vector3d::UnitZ(), mid = rot * Eigen::Vector3d(0, 0, t.length / 2) + shift;
  EXPECT_NEAR(std::abs(f.axis.dot(axis)), 1.0, 1e-9);
  EXPECT_LT((f.lumen_center - mid).norm(), 1e-9);
  EXPECT_NEAR(f.lumen_radius, t.inner_radius, 1e-9);
  EXPECT_NEAR(f.half_length, t.length / 2, 1e-9);
  for (CameraPreset preset : {CameraPreset::Side, CameraPreset::Diagonal}) {
    SCOPED_TRACE(preset == CameraPreset::Side ? "side" : "diagonal");
    Renderer r(kW, kH, preset, f);
    // The organ's centre projects to the image centre, and its silhouette is centred and wholly in view.
    const Eigen::Vector2d c = r.project(mid);
    EXPECT_NEAR(c.x(), kW / 2.0, 1.0);
    EXPECT_NEAR(c.y(), kH / 2.0, 1.0);
    const Image bg = background(r);
    const Image im = draw(r, moved.view());
    const Box organ = pixel_box(im, [&](int x, int y) { return differs(im, bg, x, y); });
    EXPECT_GT(static_cast<double>(organ.count) / (kW * kH), 0.10);
    EXPECT_NEAR(0.5 * (organ.x0 + organ.x1), kW / 2.0, 0.1 * kW);
    EXPECT_NEAR(0.5 * (organ.y0 + organ.y1), kH / 2.0, 0.1 * kH);
    EXPECT_GT(organ.x0, 0);
    EXPECT_GT(organ.y0, 0);
    EXPECT_LT(organ.x1, kW - 1);
    EXPECT_LT(organ.y1, kH - 1);
    // The cut still shows the inner wall from the side.
    if (preset == CameraPreset::Side) {
      EXPECT_GT(pixel_box(im, [&](int x, int y) { return is_inner_colour(pixel(im, x, y)); }).count, kW * kH / 20);
    }
  }
  {
    Renderer r(kW, kH, CameraPreset::Endoscope, f);
    const Eigen::Vector3d rel = r.eye() - mid;
    EXPECT_LT((rel - axis * axis.dot(rel)).norm(), 1e-9);  // on the lumen axis
    EXPECT_GT(std::abs(axis.dot(rel)), 0.25 * t.length);   // near one end
    // The far lumen is at the image centre.
    const Eigen::Vector2d far = r.project(mid + (mid - r.eye()));
    EXPECT_NEAR(far.x(), kW / 2.0, 1.0);
    EXPECT_NEAR(far.y(), kH / 2.0, 1.0);
    const Image bg = background(r);
    const Image im = draw(r, moved.view());
    long wall = 0;
    for (int x = 0; x < kW; ++x) wall += differs(im, bg, x, 0) && is_inner_colour(pixel(im, x, 0));
    EXPECT_EQ(wall, kW);
  }
}

}  // namespace
}  // namespace lumen::render
