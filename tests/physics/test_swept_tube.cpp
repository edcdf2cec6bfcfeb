// Swept-tube generator: the straight tube is the hollow cylinder, arc and helix frames against their analytic
// frames, volumes against closed forms, the bend clamp, haustra and profiles, and refused input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "physics/mesh.hpp"
#include "physics/swept_tube.hpp"
#include "support/files.hpp"

namespace lumen::physics {
namespace {


// A centreline of n samples c(k), optionally with tangents t(k).
template <class Point>
Centreline sampled(int n, Point&& c) {
  Centreline line;
  line.points.resize(n, 3);
  for (int k = 0; k < n; ++k) line.points.row(k) = c(k).transpose();
  return line;
}

// Straight centreline along +z from z0 to z1 in n samples (unevenly spaced: the rings fall between them).
Centreline straight(double z0, double z1, int n) {
  return sampled(n, [&](int k) {
    const double u = static_cast<double>(k) / (n - 1);
    return Eigen::Vector3d(0.0, 0.0, z0 + (z1 - z0) * u * u);
  });
}

// Arc of radius R in the x-z plane from the origin along +z, curving toward +x: c(phi) = (R - R cos phi, 0, R sin
// phi), n samples over [0, angle], with its exact tangents (sin phi, 0, cos phi) when asked.
Centreline arc(double R, double angle, int n, bool tangents) {
  Centreline line = sampled(n, [&](int k) {
    const double phi = angle * k / (n - 1);
    return Eigen::Vector3d(R - R * std::cos(phi), 0.0, R * std::sin(phi));
  });
  if (tangents) {
    line.tangents.resize(n, 3);
    for (int k = 0; k < n; ++k) {
      const double phi = angle * k / (n - 1);
      line.tangents.row(k) << std::sin(phi), 0.0, std::cos(phi);
    }
  }
  return line;
}

// The spec of today's paper cylinder as a swept tube over the centreline `line` from arc length s0.
SweptTubeSpec paper_spec(const Centreline& line, double s0) {
  const HollowCylinderSpec c;
  SweptTubeSpec s;
  s.source = "line.json";
  s.centreline = line;
  s.range_start = s0;
  s.range_stop = s0 + c.length;
  s.radius = c.inner_radius;
  s.wall_thickness = c.outer_radius - c.inner_radius;
  s.segments_around = c.segments_around;
  s.segment_length = c.length / c.segments_along;
  s.layers = c.layers;
  return s;
}

double total_volume(const TetMesh& m) {
  double v = 0.0;
  for (int t = 0; t < m.tets.rows(); ++t) v += tet_volume(m.rest, m.tets, t);
  return v;
}

int inverted_tets(const TetMesh& m) {
  int n = 0;
  for (int t = 0; t < m.tets.rows(); ++t) n += tet_volume(m.rest, m.tets, t) <= 0.0;
  return n;
}

// A straight centreline gives the hollow cylinder: the same tets, surfaces and node sets, and every node where the
// documented numbering puts it (brute force: ring j at z = s0 + length j / along, radius and angle by k and i), with
// and without given tangents and normals, starting at 0 or inside the line.
TEST(SweptTube, StraightCentrelineIsTheHollowCylinder) {
  const HollowCylinderSpec c;
  const TetMesh cylinder = make_hollow_cylinder(c);
  for (const double s0 : {0.0, 0.023}) {
    for (const bool frames_given : {false, true}) {
      Centreline line = straight(0.0, 0.2, 13);
      if (frames_given) {
        line.tangents = Points::Zero(13, 3);
        line.tangents.col(2).setOnes();
        line.normals = Points::Zero(13, 3);
        line.normals.col(0).setOnes();
      }
      const SweptTube tube = make_swept_tube(paper_spec(line, s0));
      ASSERT_EQ(tube.mesh.n_nodes(), cylinder.n_nodes());
      EXPECT_EQ(tube.clamped_rings, 0);
      EXPECT_TRUE(tube.mesh.tets == cylinder.tets);
      for (const char* name : {kInnerWall, kOuterWall, kEndCaps})
        EXPECT_TRUE(tube.mesh.surface(name) == cylinder.surface(name)) << name;
      EXPECT_EQ(tube.mesh.node_set(kStartEnd), cylinder.node_set(kStartEnd));
      EXPECT_EQ(tube.mesh.node_set(kStopEnd), cylinder.node_set(kStopEnd));
      double worst = 0.0;
      for (int j = 0; j <= c.segments_along; ++j)
        for (int k = 0; k <= c.layers; ++k)
          for (int i = 0; i < c.segments_around; ++i) {
            const double r = c.inner_radius + (c.outer_radius - c.inner_radius) * k / c.layers;
            const double th = 2.0 * kPi * i / c.segments_around;
            const Eigen::Vector3d truth(r * std::cos(th), r * std::sin(th), s0 + c.length * j / c.segments_along);
            const int v = (j * (c.layers + 1) + k) * c.segments_around + i;
            worst = std::max(worst, (tube.mesh.rest.row(v).transpose() - truth).norm());
            EXPECT_LE((tube.mesh.rest.row(v) - cylinder.rest.row(v) - Eigen::RowVector3d(0, 0, s0)).norm(), 1e-12);
          }
      EXPECT_LE(worst, 1e-12) << "s0 " << s0 << " frames given " << frames_given;
    }
  }
}

// Given tangents and normals are the frames the rings are built in, not the computed ones: on the straight line,
// tangents tilted 10 degrees from it and normals turned 30 degrees about it put every node of ring j at
// c(s_j) + r (cos th N + sin th B), with T the given tangent, N the given normal made normal to T and B = T x N
// (brute force over every node). The computed frames (tangent +z, normal +x) would miss by centimetres.
TEST(SweptTube, GivenTangentsAndNormalsAreTheRingsFrames) {
  const HollowCylinderSpec c;
  const double tilt = 10.0 * kPi / 180.0, turn = 30.0 * kPi / 180.0;
  Centreline line = straight(0.0, 0.2, 13);
  line.tangents = Points::Zero(13, 3);
  line.normals = Points::Zero(13, 3);
  for (int k = 0; k < 13; ++k) {
    line.tangents.row(k) << std::sin(tilt), 0.0, std::cos(tilt);
    line.normals.row(k) << std::cos(turn), std::sin(turn), 0.0;
  }
  const Eigen::Vector3d T(std::sin(tilt), 0.0, std::cos(tilt));
  const Eigen::Vector3d n(std::cos(turn), std::sin(turn), 0.0);
  const Eigen::Vector3d N = (n - n.dot(T) * T).normalized(), B = T.cross(N);
  const double s0 = 0.023;
  const SweptTube tube = make_swept_tube(paper_spec(line, s0));
  double worst = 0.0;
  for (int j = 0; j <= c.segments_along; ++j)
    for (int k = 0; k <= c.layers; ++k)
      for (int i = 0; i < c.segments_around; ++i) {
        const double r = c.inner_radius + (c.outer_radius - c.inner_radius) * k / c.layers;
        const double th = 2.0 * kPi * i / c.segments_around;
        const Eigen::Vector3d centre(0.0, 0.0, s0 + c.length * j / c.segments_along);
        const Eigen::Vector3d truth = centre + r * (std::cos(th) * N + std::sin(th) * B);
        const int v = (j * (c.layers + 1) + k) * c.segments_around + i;
        worst = std::max(worst, (tube.mesh.rest.row(v).transpose() - truth).norm());
      }
  EXPECT_LE(worst, 1e-12);
  EXPECT_EQ(inverted_tets(tube.mesh), 0);
}

// On an arc (tilted out of the coordinate planes), the rotation-minimising frames are the arc's own: the normal
// toward the centre of curvature, in the arc's plane, the binormal the plane's normal. Interior samples have exact
// chord-sum tangents; the end tangents are one chord's, half a step off, so there the normal is checked to stay in
// the plane and normal to the tangent.
TEST(SweptTube, ArcFramesAreTheAnalyticArcFrames) {
  const double R = 0.05, angle = 1.3;
  const int n = 41;
  const Eigen::Matrix3d Q = (Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized())).toRotationMatrix();
  Centreline line = arc(R, angle, n, false);
  line.points = (line.points * Q.transpose()).eval();
  const std::vector<CentrelineFrame> f = centreline_frames(line);
  const Eigen::Vector3d plane_normal = Q * Eigen::Vector3d::UnitY();
  for (int k = 0; k < n; ++k) {
    const double phi = angle * k / (n - 1);
    EXPECT_NEAR(f[k].normal.dot(plane_normal), 0.0, 1e-12) << k;
    EXPECT_NEAR(f[k].normal.dot(f[k].tangent), 0.0, 1e-12) << k;
    EXPECT_LE((f[k].binormal - f[k].tangent.cross(f[k].normal)).norm(), 1e-15) << k;
    if (k == 0 || k == n - 1) continue;
    EXPECT_LE((f[k].tangent - Q * Eigen::Vector3d(std::sin(phi), 0.0, std::cos(phi))).norm(), 1e-12) << k;
    EXPECT_LE((f[k].normal - Q * Eigen::Vector3d(std::cos(phi), 0.0, -std::sin(phi))).norm(), 1e-12) << k;
    EXPECT_LE((f[k].binormal - plane_normal).norm(), 1e-12) << k;
  }
}

// On a helix the rotation-minimising normal turns against the Frenet normal at minus the torsion: after arc length
// s it is at angle -tau s from it about the tangent (tau = b / (a^2 + b^2) for (a cos t, a sin t, b t)). Frenet
// frames, or frames transported with any twist, fail this.
TEST(SweptTube, HelixFramesTurnAgainstTheTorsion) {
  const double a = 0.03, b = 0.01, turns = 1.5;
  const int n = 601;
  const double speed = std::hypot(a, b), tau = b / (a * a + b * b);
  auto param = [&](int k) { return 2.0 * kPi * turns * k / (n - 1); };
  Centreline line = sampled(n, [&](int k) {
    const double t = param(k);
    return Eigen::Vector3d(a * std::cos(t), a * std::sin(t), b * t);
  });
  line.tangents.resize(n, 3);
  for (int k = 0; k < n; ++k)
    line.tangents.row(k) << -a * std::sin(param(k)) / speed, a * std::cos(param(k)) / speed, b / speed;
  // The first normal is the start's bend direction, near the Frenet normal (toward the axis): its offset is kept.
  const std::vector<CentrelineFrame> f = centreline_frames(line);
  const Eigen::Vector3d N0(-1.0, 0.0, 0.0);
  const double start_offset = std::atan2(f[0].normal.dot(f[0].tangent.cross(N0)), f[0].normal.dot(N0));
  double worst = 0.0;
  for (int k = 0; k < n; ++k) {
    const double t = param(k);
    const Eigen::Vector3d N(-std::cos(t), -std::sin(t), 0.0);  // Frenet normal
    const Eigen::Vector3d B = f[k].tangent.cross(N);
    const double turned = std::atan2(f[k].normal.dot(B), f[k].normal.dot(N)) - start_offset;
    worst = std::max(worst, std::abs(std::remainder(turned + tau * speed * t, 2.0 * kPi)));
  }
  EXPECT_LE(worst, 1e-6);
}

// The polygonal annulus area of a ring: 0.5 A sin(2 pi / A) (ro^2 - ri^2).
double polygon_annulus_area(int around, double ri, double ro) {
  return 0.5 * around * std::sin(2.0 * kPi / around) * (ro * ro - ri * ri);
}

// Straight: the prism over the polygonal annulus. Torus section (rings on the arc's samples): each segment between
// rings turned by d phi about the bend axis is the union of the chords p -> R p, perpendicular to the bisector plane,
// of volume sin(d phi) times the first moment of the ring about the axis, R A (Pappus, the centroid at the centre),
// so the whole is n R A sin(angle / n), which tends to Pappus' pi (ro^2 - ri^2) R angle.
TEST(SweptTube, VolumeOfStraightAndTorusSectionTubesIsTheClosedForm) {
  SweptTubeSpec s = paper_spec(straight(0.0, 0.15, 7), 0.01);
  s.segments_around = 9, s.layers = 2;
  const SweptTube straight_tube = make_swept_tube(s);
  EXPECT_EQ(inverted_tets(straight_tube.mesh), 0);
  const double a = polygon_annulus_area(9, s.radius, s.radius + s.wall_thickness);
  EXPECT_NEAR(total_volume(straight_tube.mesh), a * 0.1, 1e-12 * a * 0.1);

  const double R = 0.04, angle = 2.0;
  const int n = 30;
  s.segments_around = 24;
  s.centreline = arc(R, angle, n + 1, true);
  s.range_start = 0.0;
  s.range_stop = arc_lengths(s.centreline.points).back();
  s.segment_length = 2.0 * R * std::sin(0.5 * angle / n);  // the chord: one ring per sample
  const SweptTube torus = make_swept_tube(s);
  ASSERT_EQ(torus.rings.size(), static_cast<size_t>(n + 1));
  EXPECT_EQ(torus.clamped_rings, 0);
  EXPECT_EQ(inverted_tets(torus.mesh), 0);
  const double ring_area = polygon_annulus_area(24, s.radius, s.radius + s.wall_thickness);
  const double exact = n * R * ring_area * std::sin(angle / n);
  EXPECT_NEAR(total_volume(torus.mesh), exact, 1e-10 * exact);
  // Against Pappus' continuum volume: 24 sides lose 1.1 % of the annulus, the chords 0.07 % of the sweep.
  const double pappus = kPi * (std::pow(s.radius + s.wall_thickness, 2) - s.radius * s.radius) * R * angle;
  EXPECT_NEAR(exact, pappus, 0.015 * pappus);
}

// A bend tighter than the wall: without the clamp the rings' walls cross on the inside of the bend (inverted tets);
// with it every ring is scaled to kBendClearance of the bend radius and no tet inverts. A gentle bend clamps none.
TEST(SweptTube, ClampPreventsInversionOnATightBend) {
  SweptTubeSpec s = paper_spec(arc(0.008, 2.5, 60, false), 0.0);
  s.radius = 0.008, s.wall_thickness = 0.0025, s.segment_length = 0.002, s.segments_around = 16, s.layers = 2;
  s.range_stop = arc_lengths(s.centreline.points).back();
  const SweptTube tube = make_swept_tube(s);
  EXPECT_EQ(tube.clamped_rings, static_cast<int>(tube.rings.size()));
  EXPECT_EQ(inverted_tets(tube.mesh), 0);
  // Interior rings to kBendClearance of the arc's 8 mm (the end rings' tangents are one chord's, half a sample
  // step off, so their bend reads wider); every ring keeps its wall-to-lumen proportion.
  for (size_t j = 0; j < tube.rings.size(); ++j) {
    const TubeRing& ring = tube.rings[j];
    if (j > 0 && j + 1 < tube.rings.size()) {
      EXPECT_LE(ring.outer_radius, kBendClearance * 0.008 * (1.0 + 1e-3)) << j;
    }
    EXPECT_NEAR(ring.outer_radius / ring.inner_radius, (0.008 + 0.0025) / 0.008, 1e-12);
  }
  // The same rings with the radii unclamped fold: some tets invert.
  std::vector<TubeRing> unclamped = tube.rings;
  for (TubeRing& ring : unclamped) ring.inner_radius = 0.008, ring.outer_radius = 0.0105;
  EXPECT_GT(inverted_tets(make_structured_tube(unclamped, 16, 2)), 0);
  // A quarter turn of 8 mm radius between two straight runs (1 mm samples): the rings at the turn are clamped and
  // their neighbours on the straight runs narrow toward them, the scale changing by at most kClampTaper a ring.
  Centreline kinked = sampled(41, [](int k) { return Eigen::Vector3d(0.0, 0.0, 0.001 * (k - 40)); });
  const int turn_samples = 13;
  kinked.points.conservativeResize(41 + turn_samples + 40, 3);
  for (int k = 1; k <= turn_samples; ++k) {
    const double phi = 0.5 * kPi * k / turn_samples;
    kinked.points.row(40 + k) << 0.008 - 0.008 * std::cos(phi), 0.0, 0.008 * std::sin(phi);
  }
  for (int k = 1; k <= 40; ++k) kinked.points.row(40 + turn_samples + k) << 0.008 + 0.001 * k, 0.0, 0.008;
  s.centreline = kinked;
  s.range_stop = arc_lengths(kinked.points).back();
  const SweptTube kink = make_swept_tube(s);
  EXPECT_EQ(inverted_tets(kink.mesh), 0);
  int turn_rings = 0;
  double smallest = 1.0;
  for (size_t j = 0; j < kink.rings.size(); ++j) {
    const double scale = kink.rings[j].outer_radius / 0.0105;
    smallest = std::min(smallest, scale);
    turn_rings += kink.ring_s[j] > 0.040 && kink.ring_s[j] < 0.040 + 0.004 * kPi;
    if (j > 0) {
      EXPECT_LE(std::abs(scale - kink.rings[j - 1].outer_radius / 0.0105), kClampTaper + 1e-12) << j;
    }
  }
  EXPECT_LE(smallest, kBendClearance * 0.008 / 0.0105 * 1.01);
  EXPECT_GT(kink.clamped_rings, turn_rings + 2);
  // A bend radius of 5 cm is wider than the wall: nothing clamped.
  s.centreline = arc(0.05, 1.0, 60, false);
  s.range_stop = arc_lengths(s.centreline.points).back();
  EXPECT_EQ(make_swept_tube(s).clamped_rings, 0);
}

// Haustra and a radius profile: every ring's inner-wall nodes lie at r(s) = profile(s) + depth sin^2(pi (s - s0) /
// pitch) from the centreline, the outer ones wall_thickness further out.
TEST(SweptTube, HaustraAndProfileRadiusIsTheFormula) {
  SweptTubeSpec s = paper_spec(straight(0.0, 0.2, 9), 0.03);
  s.radius_profile = {{0.0, 0.008}, {0.2, 0.012}};
  s.haustra = {0.0015, 0.012};
  s.segment_length = 0.002;
  const SweptTube tube = make_swept_tube(s);
  const int around = s.segments_around, layers = s.layers;
  for (size_t j = 0; j < tube.rings.size(); ++j) {
    const double z = tube.ring_s[j];
    const double phase = std::sin(kPi * (z - 0.03) / 0.012);
    const double r = 0.008 + 0.02 * z + 0.0015 * phase * phase;
    EXPECT_NEAR(swept_tube_lumen_radius(s, z), r, 1e-15);
    for (int i = 0; i < around; ++i) {
      const int inner = static_cast<int>(j) * (layers + 1) * around + i, outer = inner + layers * around;
      EXPECT_NEAR(tube.mesh.rest.row(inner).head<2>().norm(), r, 1e-12);
      EXPECT_NEAR(tube.mesh.rest.row(outer).head<2>().norm(), r + s.wall_thickness, 1e-12);
      EXPECT_NEAR(tube.mesh.rest(inner, 2), z, 1e-12);
    }
  }
  EXPECT_EQ(inverted_tets(tube.mesh), 0);
}

// Bad input: the message names the source, the field and the sample index (or the spec field) and the value.
TEST(SweptTube, RefusesBadCentrelinesAndSpecsNamingWhere) {
  using test::message_of;
  const SweptTubeSpec good = paper_spec(straight(0.0, 0.2, 9), 0.0);
  auto error = [&](auto edit) {
    SweptTubeSpec s = good;
    edit(s);
    return message_of<std::invalid_argument>([&] { make_swept_tube(s); });
  };
  EXPECT_EQ(error([](SweptTubeSpec&) {}), "");
  EXPECT_EQ(error([](SweptTubeSpec& s) { s.centreline.points.conservativeResize(1, 3); }),
            "line.json: points: needs at least 2 points, got 1");
  EXPECT_NE(error([](SweptTubeSpec& s) { s.centreline.points.row(4) = s.centreline.points.row(3); })
                .find("line.json: points[4]: repeats points[3]"), std::string::npos);
  EXPECT_NE(error([](SweptTubeSpec& s) { s.centreline.points(2, 1) = std::nan(""); })
                .find("line.json: points[2]: must be finite, got [0, nan"), std::string::npos);
  EXPECT_NE(error([](SweptTubeSpec& s) { s.centreline.tangents = Points::Zero(3, 3); })
                .find("line.json: tangents: must have one row per point (9), got 3"), std::string::npos);
  EXPECT_NE(error([](SweptTubeSpec& s) {
              s.centreline.tangents = Points::Zero(9, 3);
              s.centreline.tangents.col(2).setOnes();
              s.centreline.tangents(5, 2) = -1.0;
            }).find("line.json: tangents[5]: the tangent points against the centreline's direction"),
            std::string::npos);
  EXPECT_NE(error([](SweptTubeSpec& s) {
              s.centreline.normals = Points::Zero(9, 3);
              s.centreline.normals.col(0).setOnes();
              s.centreline.normals.row(6) << 0.0, 0.0, 2.0;
            }).find("line.json: normals[6]: is zero or (nearly) parallel to the tangent, got [0, 0, 2]"),
            std::string::npos);
  // A centreline that turns straight back on itself.
  EXPECT_NE(error([](SweptTubeSpec& s) { s.centreline.points.row(8) = s.centreline.points.row(6); })
                .find("line.json: points[7]: the centreline turns back here"), std::string::npos);
  EXPECT_NE(error([](SweptTubeSpec& s) { s.range_stop = 0.3; }).find("SweptTubeSpec.range_stop must be > range_start"),
            std::string::npos);
  EXPECT_NE(error([](SweptTubeSpec& s) { s.range_start = s.range_stop; }).find("range_stop"), std::string::npos);
  EXPECT_NE(error([](SweptTubeSpec& s) { s.range_start = -0.01; }).find("range_start must be >= 0"), std::string::npos);
  EXPECT_NE(error([](SweptTubeSpec& s) { s.radius = 0.0; }).find("SweptTubeSpec.radius must be > 0 and finite, got 0"),
            std::string::npos);
  EXPECT_NE(error([](SweptTubeSpec& s) { s.wall_thickness = -0.001; }).find("wall_thickness must be > 0 and finite, got -0.001"),
            std::string::npos);
  EXPECT_NE(error([](SweptTubeSpec& s) { s.segment_length = 1e-9; }).find("gives more than 100000 rings"),
            std::string::npos);
  EXPECT_NE(error([](SweptTubeSpec& s) { s.haustra = {0.001, 0.005}; }).find("haustra.pitch must be finite and at least 4"),
            std::string::npos);
  EXPECT_NE(error([](SweptTubeSpec& s) { s.radius_profile = {{0.01, 0.008}, {0.2, 0.01}}; }).find("must cover the range"),
            std::string::npos);
  EXPECT_NE(error([](SweptTubeSpec& s) { s.radius_profile = {{0.0, 0.008}, {0.0, 0.01}}; }).find("radius_profile[1].s must increase"),
            std::string::npos);
}

}  // namespace
}  // namespace lumen::physics

namespace lumen::physics {

// The nearest point of a polyline by arc length, against dense sampling (every vertex and 2000 points a segment) on
// a coarse helix (30 samples over two turns), for points scattered around it at up to twice its pitch; and of
// equally near segments the first: the centre of a square's three sides is 0.5 from each, arc length 0.5.
TEST(NearestArcLength, MatchesDenseSamplingOnAHelixAndTiesTakeTheLeastArcLength) {
  constexpr int kSamples = 30, kPerSegment = 2000, kPoints = 400;
  constexpr double kRadius = 0.03, kRise = 0.01, kTurns = 2.0;
  const double pi = static_cast<double>(EIGEN_PI);
  Points helix(kSamples, 3);
  for (int k = 0; k < kSamples; ++k) {
    const double a = 2.0 * pi * kTurns * k / (kSamples - 1);
    helix.row(k) << kRadius * std::cos(a), kRadius * std::sin(a), kRise * a / (2.0 * pi);
  }
  const std::vector<double> arc = arc_lengths(helix);
  // The twin: every sample's arc length walked along the segments, the nearest sample by brute force.
  std::vector<Eigen::Vector3d> xs;
  std::vector<double> ss;
  double spacing = 0.0;
  for (int i = 0; i + 1 < kSamples; ++i) {
    const Eigen::Vector3d a = helix.row(i).transpose(), b = helix.row(i + 1).transpose();
    spacing = std::max(spacing, (b - a).norm() / kPerSegment);
    for (int k = 0; k < kPerSegment; ++k) {
      xs.push_back(a + (static_cast<double>(k) / kPerSegment) * (b - a));
      ss.push_back(arc[i] + (b - a).norm() * k / kPerSegment);
    }
  }
  xs.push_back(helix.row(kSamples - 1).transpose());
  ss.push_back(arc.back());
  std::srand(7);
  for (int p = 0; p < kPoints; ++p) {
    const Eigen::Vector3d x = Eigen::Vector3d(0.0, 0.0, kRise) + 2.0 * kRise * Eigen::Vector3d::Random() +
                              Eigen::Vector3d(kRadius * std::cos(p), kRadius * std::sin(p), 0.0);
    size_t best = 0;
    for (size_t k = 1; k < xs.size(); ++k)
      if ((xs[k] - x).squaredNorm() < (xs[best] - x).squaredNorm()) best = k;
    EXPECT_NEAR(nearest_arc_length(helix, arc, x), ss[best], spacing) << x.transpose();
  }
  Points square(4, 3);
  square << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0;
  EXPECT_EQ(nearest_arc_length(square, arc_lengths(square), Eigen::Vector3d(0.5, 0.5, 0.0)), 0.5);
  EXPECT_EQ(nearest_arc_length(square, arc_lengths(square), Eigen::Vector3d(2.0, 2.0, 0.0)), 2.0);
}

}  // namespace lumen::physics
