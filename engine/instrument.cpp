#include "engine/instrument.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>

#include "engine/input.hpp"
#include "engine/scene.hpp"

namespace lumen::engine {
namespace {

using physics::kPi;

// Most sides, rings or bands a shape may ask for (a resolution past it is a typo, not a mesh).
constexpr int kMaxResolution = 4096;

// A closed profile of revolution about +y: (radius, height) points from the tip end's pole (radius 0) to the far
// end's pole (radius 0), the points between with radius > 0.
using Profile = std::vector<Eigen::Vector2d>;

// Refuse a non-finite or non-positive dimension, naming where.field.
double positive(double v, const std::string& where, const char* field) {
  const std::string key = where + "." + field;
  if (!std::isfinite(v)) throw InputError(key + ": must be finite (value " + value_text(v) + ")");
  if (!(v > 0.0)) throw InputError(key + ": must be > 0 (value " + value_text(v) + ")");
  return v;
}

// Refuse a resolution outside [lo, kMaxResolution], naming where.field.
void resolution(int n, int lo, const std::string& where, const char* field) {
  if (n < lo || n > kMaxResolution)
    throw InputError(where + "." + field + ": out of range [" + std::to_string(lo) + ", " +
                     std::to_string(kMaxResolution) + "] (value " + std::to_string(n) + ")");
}

// Refuse a > limit (named by limit_name), naming where.field.
void at_most(double a, double limit, const std::string& where, const char* field, const std::string& limit_name) {
  if (a > limit)
    throw InputError(where + "." + field + ": must be <= " + limit_name + " (" + value_text(limit) + ") (value " +
                     value_text(a) + ")");
}

// The surface of revolution of a profile: each inner point a ring of `segments` vertices at angles
// 2 pi i / segments, (r cos a, y, -r sin a), the poles single vertices; bands of two triangles per segment
// between neighbouring rings and fans at the poles, outward for a profile running from the tip end up.
RigidMesh revolve(const Profile& profile, int segments) {
  const int n_rings = static_cast<int>(profile.size()) - 2;
  assert(n_rings >= 1 && profile.front().x() == 0.0 && profile.back().x() == 0.0);
  const int top = 1 + n_rings * segments;
  RigidMesh m;
  m.points.resize(top + 1, 3);  // bottom pole, rings, top pole
  m.points.row(0) << 0.0, profile.front().y(), 0.0;
  m.points.row(top) << 0.0, profile.back().y(), 0.0;
  // Ring k (profile point k + 1), vertex i.
  auto id = [segments](int k, int i) { return 1 + k * segments + (i % segments); };
  for (int k = 0; k < n_rings; ++k) {
    const Eigen::Vector2d& p = profile[static_cast<size_t>(k + 1)];
    assert(p.x() > 0.0);
    for (int i = 0; i < segments; ++i) {
      const double a = 2.0 * kPi * i / segments;
      m.points.row(id(k, i)) << p.x() * std::cos(a), p.y(), -p.x() * std::sin(a);
    }
  }
  // Bands (a, b, c), (a, c, d) with a, b on the lower ring, d, c above; a fan at each pole.
  m.tris.resize(2 * segments * n_rings, 3);
  int t = 0;
  for (int i = 0; i < segments; ++i) {
    m.tris.row(t++) << 0, id(0, i + 1), id(0, i);
    m.tris.row(t++) << id(n_rings - 1, i), id(n_rings - 1, i + 1), top;
    for (int k = 0; k + 1 < n_rings; ++k) {
      m.tris.row(t++) << id(k, i), id(k, i + 1), id(k + 1, i + 1);
      m.tris.row(t++) << id(k, i), id(k + 1, i + 1), id(k + 1, i);
    }
  }
  assert(t == m.tris.rows());
  return m;
}

// A profile's shaft: `bands` rings of radius r from just above y0 up to y1, then the far end's flat cap.
void append_shaft(Profile& profile, double r, double y0, double y1, int bands) {
  for (int s = 1; s <= bands; ++s) profile.emplace_back(r, y0 + (y1 - y0) * s / bands);
  profile.emplace_back(0.0, y1);
}

// A cylinder of radius r from y0 to y1 with flat ends.
Profile cylinder_profile(double r, double y0, double y1, int bands) {
  Profile p = {{0.0, y0}, {r, y0}};
  append_shaft(p, r, y0, y1, bands);
  return p;
}

// A sphere of radius tip_r on the origin (centre (0, tip_r)) joined to a shaft of radius shaft_r from the
// sphere's centre up to y = tip_r + shaft_len: `rings` latitude rings evenly spaced in the angle from the tip's
// pole up to the junction (where the sphere's radius is shaft_r), then the shaft.
Profile sphere_shaft_profile(double tip_r, double shaft_r, double shaft_len, int rings, int bands) {
  const double junction = kPi - std::asin(shaft_r / tip_r);  // polar angle from the tip's pole
  Profile p = {{0.0, 0.0}};
  for (int k = 1; k <= rings; ++k) {
    const double phi = junction * k / rings;
    p.emplace_back(tip_r * std::sin(phi), tip_r - tip_r * std::cos(phi));
  }
  p.back().x() = shaft_r;  // exactly the shaft's radius, so the shaft's rings stack on it
  append_shaft(p, shaft_r, p.back().y(), tip_r + shaft_len, bands);
  return p;
}

// A box from lo to hi, two triangles per face, outward.
RigidMesh box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  RigidMesh m;
  m.points.resize(8, 3);  // corner c: bit j of c picks hi along axis j
  for (int c = 0; c < 8; ++c)
    for (int j = 0; j < 3; ++j) m.points(c, j) = (c >> j & 1) ? hi[j] : lo[j];
  m.tris.resize(12, 3);
  int t = 0;
  // The face normal to axis a on side s: corners (0,0), (1,0), (1,1), (0,1) along axes u, v with e_u x e_v = e_a,
  // counter-clockwise seen from +a, so reversed on the low side.
  for (int a = 0; a < 3; ++a) {
    const int u = (a + 1) % 3, v = (a + 2) % 3;
    for (int s = 0; s < 2; ++s) {
      auto corner = [&](int cu, int cv) { return (s << a) | (cu << u) | (cv << v); };
      int q[4] = {corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)};
      if (s == 0) std::swap(q[1], q[3]);
      m.tris.row(t++) << q[0], q[1], q[2];
      m.tris.row(t++) << q[0], q[2], q[3];
    }
  }
  return m;
}

// A one-part instrument.
Instrument single_part(RigidMesh mesh) {
  Instrument inst;
  inst.parts.push_back({"body", std::move(mesh), PartJoint::kFixed});
  return inst;
}

}  // namespace

Instrument make_sphere_probe(const SphereProbeSpec& s, const std::string& where) {
  // Dimensions: the shaft no wider than the tip and reaching past the sphere.
  positive(s.tip_radius, where, "tip_radius");
  positive(s.shaft_radius, where, "shaft_radius");
  positive(s.shaft_length, where, "shaft_length");
  at_most(s.shaft_radius, s.tip_radius, where, "shaft_radius", "tip_radius");
  if (!(s.shaft_length > s.tip_radius))
    throw InputError(where + ".shaft_length: must be > tip_radius (" + value_text(s.tip_radius) + ") (value " +
                     value_text(s.shaft_length) + ")");
  resolution(s.segments_around, kMinSegmentsAround, where, "segments_around");
  resolution(s.rings, kMinRings, where, "rings");
  resolution(s.shaft_segments, 1, where, "shaft_segments");
  return single_part(revolve(
      sphere_shaft_profile(s.tip_radius, s.shaft_radius, s.shaft_length, s.rings, s.shaft_segments),
      s.segments_around));
}

Instrument make_rod(const RodSpec& s, const std::string& where) {
  // Dimensions: a rounded end needs a shaft beyond its hemisphere.
  positive(s.radius, where, "radius");
  positive(s.length, where, "length");
  resolution(s.segments_around, kMinSegmentsAround, where, "segments_around");
  resolution(s.shaft_segments, 1, where, "shaft_segments");
  if (s.end == RodEnd::kFlat)
    return single_part(revolve(cylinder_profile(s.radius, 0.0, s.length, s.shaft_segments), s.segments_around));
  resolution(s.rings, kMinRings, where, "rings");
  if (!(s.length > 2.0 * s.radius))
    throw InputError(where + ".length: must be > 2 radius (" + value_text(2.0 * s.radius) +
                     ") for a rounded end (value " + value_text(s.length) + ")");
  return single_part(revolve(sphere_shaft_profile(s.radius, s.radius, s.length - s.radius, s.rings, s.shaft_segments),
                             s.segments_around));
}

Instrument make_grasper(const GrasperSpec& s, const std::string& where) {
  // Dimensions and the rest opening.
  const double len = positive(s.jaw_length, where, "jaw_length");
  const double half_w = 0.5 * positive(s.jaw_width, where, "jaw_width");
  const double thick = positive(s.jaw_thickness, where, "jaw_thickness");
  positive(s.shaft_radius, where, "shaft_radius");
  positive(s.shaft_length, where, "shaft_length");
  if (!(s.opening_angle >= 0.0 && s.opening_angle <= kMaxOpeningAngle))
    throw InputError(where + ".opening_angle: out of range [0, " + value_text(kMaxOpeningAngle) +
                     "] radians (value " + value_text(s.opening_angle) + ")");
  resolution(s.segments_around, kMinSegmentsAround, where, "segments_around");
  resolution(s.shaft_segments, 1, where, "shaft_segments");
  // The shaft above the hinge, a jaw on each side of x = 0.
  Instrument inst;
  inst.hinge = Eigen::Vector3d(0.0, len, 0.0);
  inst.rest_opening = s.opening_angle;
  inst.parts.push_back({"shaft",
                        revolve(cylinder_profile(s.shaft_radius, len, len + s.shaft_length, s.shaft_segments),
                                s.segments_around),
                        PartJoint::kFixed});
  inst.parts.push_back({"jaw_positive", box({0.0, 0.0, -half_w}, {thick, len, half_w}), PartJoint::kJawPositive});
  inst.parts.push_back({"jaw_negative", box({-thick, 0.0, -half_w}, {0.0, len, half_w}), PartJoint::kJawNegative});
  return inst;
}

Instrument load_mesh_instrument(const MeshFileSpec& spec) {
  // Read through assimp, vertices at identical positions merged, scaled to metres; then the surface checked.
  require_file(spec.file, "mesh file");
  RigidMesh m = read_surface_file(spec.file, kMetresPerUnit[static_cast<int>(spec.units)], "instrument mesh");
  require_closed_manifold(m, spec.file);
  return single_part(std::move(m));
}

Instrument make_instrument(const ShapeSpec& shape, const std::string& where) {
  if (const auto* s = std::get_if<SphereProbeSpec>(&shape)) return make_sphere_probe(*s, where);
  if (const auto* s = std::get_if<RodSpec>(&shape)) return make_rod(*s, where);
  if (const auto* s = std::get_if<GrasperSpec>(&shape)) return make_grasper(*s, where);
  return load_mesh_instrument(std::get<MeshFileSpec>(shape));
}

Eigen::Isometry3d part_transform(const Instrument& instrument, const InstrumentPart& part, double opening_angle) {
  assert(opening_angle >= 0.0 && opening_angle <= kMaxOpeningAngle);
  // A jaw turns by half the opening about the hinge axis z, the positive one counter-clockwise.
  if (part.joint == PartJoint::kFixed) return Eigen::Isometry3d::Identity();
  const double half = 0.5 * (part.joint == PartJoint::kJawPositive ? opening_angle : -opening_angle);
  return Eigen::Translation3d(instrument.hinge) * Eigen::AngleAxisd(half, Eigen::Vector3d::UnitZ()) *
         Eigen::Translation3d(-instrument.hinge);
}

std::array<Eigen::Isometry3d, 2> jaw_poses(const Instrument& grasper, double opening_angle) {
  std::array<Eigen::Isometry3d, 2> poses = {Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity()};
  for (const InstrumentPart& p : grasper.parts)
    if (p.joint != PartJoint::kFixed)
      poses[p.joint == PartJoint::kJawPositive ? 0 : 1] = part_transform(grasper, p, opening_angle);
  return poses;
}

void pose_part(const Instrument& instrument, size_t part, const Pose& pose, double opening_angle, Points& out) {
  // x = T_pose T_part p for each point p of the part.
  const InstrumentPart& p = instrument.parts[part];
  const Eigen::Isometry3d x = pose.transform() * part_transform(instrument, p, opening_angle);
  out = (p.mesh.points * x.linear().transpose()).rowwise() + x.translation().transpose();
}

std::vector<Points> posed_parts(const Instrument& instrument, const Pose& pose) {
  return posed_parts(instrument, pose, instrument.rest_opening);
}

std::vector<Points> posed_parts(const Instrument& instrument, const Pose& pose, double opening_angle) {
  std::vector<Points> out(instrument.parts.size());
  for (size_t i = 0; i < out.size(); ++i) pose_part(instrument, i, pose, opening_angle, out[i]);
  return out;
}

}  // namespace lumen::engine
