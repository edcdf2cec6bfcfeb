// Swept-tube generator: centreline frames (given or rotation-minimising), radii, bend clamp, structured mesh.
#include "physics/swept_tube.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "physics/detail/messages.hpp"

namespace lumen::physics {

namespace {

// Consecutive points closer than this fraction of the whole polyline's length count as repeated.
constexpr double kRepeatedPointFraction = 1e-9;
// A normal whose part normal to its tangent is shorter than this fraction of it is (nearly) parallel to it.
constexpr double kMinNormalPart = 1e-3;
// A centreline runs straight while the chords from its start leave the start tangent by less than this fraction.
constexpr double kStraightFraction = 1e-9;
// A normalised tangent has squared norm 1, a zero one (normalised, it stays zero) 0: the threshold between them.
constexpr double kMinTangentSquaredNorm = 0.5;
// Ring counts within this relative tolerance of a whole number are that number (range / segment_length).
constexpr double kRingCountTolerance = 1e-9;

// A 3-vector as "[x, y, z]" with 17 significant digits.
std::string vec_text(const Eigen::Vector3d& v) {
  return "[" + detail::num(v.x()) + ", " + detail::num(v.y()) + ", " + detail::num(v.z()) + "]";
}

// Throws std::invalid_argument "<source>: <field>[<i>]: <problem>".
[[noreturn]] void fail_sample(const std::string& source, const char* field, Eigen::Index i, const std::string& problem) {
  detail::fail(source + ": " + field + "[" + std::to_string(i) + "]: " + problem);
}

// Throws std::invalid_argument "SweptTubeSpec.<field> <rule>, got <value>".
template <typename T>
[[noreturn]] void fail_spec(const char* field, const char* rule, T value) {
  detail::fail_value(std::string("SweptTubeSpec.") + field, rule, value);
}

// Row i of an n x 3 array as a column vector.
Eigen::Vector3d row(const Points& p, Eigen::Index i) { return p.row(i).transpose(); }

// The part of v normal to the unit vector u.
Eigen::Vector3d normal_part(const Eigen::Vector3d& v, const Eigen::Vector3d& u) { return v - u * u.dot(v); }

// x reflected in the plane through the origin normal to v (c = v . v > 0).
Eigen::Vector3d reflect(const Eigen::Vector3d& x, const Eigen::Vector3d& v, double c) {
  return x - (2.0 / c) * v.dot(x) * v;
}

// Angle between two vectors, radians (robust near 0 and pi).
double angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

// Optional per-sample rows: none, or one per point, every value finite.
void check_rows(const Points& rows, Eigen::Index n, const std::string& source, const char* field) {
  if (rows.rows() != 0 && rows.rows() != n)
    detail::fail(source + ": " + field + ": must have one row per point (" + std::to_string(n) + "), got " +
                 std::to_string(rows.rows()));
  for (Eigen::Index i = 0; i < rows.rows(); ++i)
    if (!rows.row(i).allFinite()) fail_sample(source, field, i, "must be finite, got " + vec_text(row(rows, i)));
}

// Tangents (the given ones, else the estimated ones, field "points"): unit (a zero one stays zero when
// normalised), along the direction of travel, turning by less than 90 degrees between samples.
void check_tangents(const Centreline& c, const std::vector<Eigen::Vector3d>& t, const std::string& source) {
  const bool given = c.tangents.rows() != 0;
  const char* field = given ? "tangents" : "points";
  for (size_t k = 0; k < t.size(); ++k) {
    const Eigen::Index i = static_cast<Eigen::Index>(k);
    if (!(t[k].squaredNorm() > kMinTangentSquaredNorm)) fail_sample(source, field, i, given ? "must not be zero" : "the centreline turns back here");
    const Eigen::Index a = std::min<Eigen::Index>(i, c.points.rows() - 2);
    if (!(t[k].dot(row(c.points, a + 1) - row(c.points, a)) > 0.0))
      fail_sample(source, field, i, "the tangent points against the centreline's direction, got " + vec_text(t[k]));
    if (k > 0 && !(t[k].dot(t[k - 1]) > 0.0))
      fail_sample(source, field, i, "the tangent turns by 90 degrees or more from sample " + std::to_string(k - 1));
  }
}

// Given normals: not parallel to their tangent, turning by less than 90 degrees between samples.
void check_normals(const Centreline& c, const std::vector<Eigen::Vector3d>& tangents, const std::string& source) {
  Eigen::Vector3d last = Eigen::Vector3d::Zero();
  for (Eigen::Index i = 0; i < c.normals.rows(); ++i) {
    const Eigen::Vector3d n = row(c.normals, i);
    const Eigen::Vector3d& t = tangents[i];
    const Eigen::Vector3d part = normal_part(n, t);
    if (!(part.norm() > kMinNormalPart * n.norm()))
      fail_sample(source, "normals", i, "is zero or (nearly) parallel to the tangent, got " + vec_text(n));
    if (i > 0 && !(part.dot(last) > 0.0))
      fail_sample(source, "normals", i, "turns by 90 degrees or more from normals[" + std::to_string(i - 1) + "]");
    last = part;
  }
}

// Unit tangents at the samples: the given ones, else the sum of the unit chords on either side.
std::vector<Eigen::Vector3d> sample_tangents(const Centreline& c) {
  const Eigen::Index n = c.points.rows();
  std::vector<Eigen::Vector3d> t(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    if (c.tangents.rows() == n) {
      t[i] = row(c.tangents, i).normalized();
      continue;
    }
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    if (i > 0) sum += (row(c.points, i) - row(c.points, i - 1)).normalized();
    if (i + 1 < n) sum += (row(c.points, i + 1) - row(c.points, i)).normalized();
    t[i] = sum.normalized();
  }
  return t;
}

// First normal of the rotation-minimising frames: toward where the centreline first leaves its start tangent
// (its bend), else the coordinate axis most normal to the tangent (the first of equals), made normal to it.
Eigen::Vector3d first_normal(const Centreline& c, const Eigen::Vector3d& t0) {
  const Eigen::Vector3d x0 = row(c.points, 0);
  for (Eigen::Index k = 1; k < c.points.rows(); ++k) {
    const Eigen::Vector3d d = row(c.points, k) - x0;
    const Eigen::Vector3d off = normal_part(d, t0);
    if (off.norm() > kStraightFraction * d.norm()) return off.normalized();
  }
  int axis = 0;
  for (int a = 1; a < 3; ++a)
    if (std::abs(t0[a]) < std::abs(t0[axis])) axis = a;
  return normal_part(Eigen::Vector3d::Unit(axis), t0).normalized();
}

// Rotation-minimising normals by double reflection: reflect the frame in the bisector plane of the chord, then
// in the plane that takes the reflected tangent onto the next tangent.
std::vector<Eigen::Vector3d> rotation_minimising_normals(const Centreline& c, const std::vector<Eigen::Vector3d>& t) {
  std::vector<Eigen::Vector3d> r(t.size());
  r[0] = first_normal(c, t[0]);
  for (size_t i = 0; i + 1 < t.size(); ++i) {
    const Eigen::Vector3d v1 = row(c.points, static_cast<Eigen::Index>(i + 1)) - row(c.points, static_cast<Eigen::Index>(i));
    const double c1 = v1.dot(v1);
    const Eigen::Vector3d rL = reflect(r[i], v1, c1), tL = reflect(t[i], v1, c1);
    const Eigen::Vector3d v2 = t[i + 1] - tL;
    const double c2 = v2.dot(v2);
    const Eigen::Vector3d next = c2 > 0.0 ? reflect(rL, v2, c2) : rL;
    r[i + 1] = normal_part(next, t[i + 1]).normalized();
  }
  return r;
}

// Where x falls among increasing abscissae xs: the samples a <= b on either side and the weight of b (x held
// at the ends).
struct Bracket {
  size_t a = 0, b = 0;
  double w = 0.0;
};
Bracket bracket(const std::vector<double>& xs, double x) {
  Bracket k;
  k.b = std::min<size_t>(std::upper_bound(xs.begin(), xs.end(), x) - xs.begin(), xs.size() - 1);
  k.a = k.b == 0 ? 0 : k.b - 1;
  k.w = xs[k.b] > xs[k.a] ? std::clamp((x - xs[k.a]) / (xs[k.b] - xs[k.a]), 0.0, 1.0) : 0.0;
  return k;
}

// Linear interpolation between two values with the weight of the second.
template <class Value>
Value lerp(const Value& a, const Value& b, double w) {
  return (1.0 - w) * a + w * b;
}

// Spec values that need no centreline: radii, wall, counts, haustra, finite and in range.
void validate_wall(const SweptTubeSpec& s) {
  // Radius: constant, or a profile of at least 2 knots with s strictly increasing and r positive.
  if (s.radius_profile.empty() && (!(s.radius > 0.0) || !std::isfinite(s.radius)))
    fail_spec("radius", "must be > 0 and finite", s.radius);
  if (s.radius_profile.size() == 1) fail_spec("radius_profile", "must have at least 2 knots", 1);
  for (size_t k = 0; k < s.radius_profile.size(); ++k) {
    const RadiusKnot& knot = s.radius_profile[k];
    const std::string at = "radius_profile[" + std::to_string(k) + "]";
    if (!std::isfinite(knot.s)) fail_spec((at + ".s").c_str(), "must be finite", knot.s);
    if (!(knot.r > 0.0) || !std::isfinite(knot.r)) fail_spec((at + ".r").c_str(), "must be > 0 and finite", knot.r);
    if (k > 0 && !(knot.s > s.radius_profile[k - 1].s)) fail_spec((at + ".s").c_str(), "must increase", knot.s);
  }
  if (!(s.wall_thickness > 0.0) || !std::isfinite(s.wall_thickness))
    fail_spec("wall_thickness", "must be > 0 and finite", s.wall_thickness);
  if (s.segments_around < 3) fail_spec("segments_around", "must be >= 3", s.segments_around);
  if (s.layers < 1) fail_spec("layers", "must be >= 1", s.layers);
  if (!(s.segment_length > 0.0) || !std::isfinite(s.segment_length))
    fail_spec("segment_length", "must be > 0 and finite", s.segment_length);
  // Haustra: depth >= 0; with depth, a pitch resolved by at least kMinRingsPerHaustrum rings.
  if (!(s.haustra.depth >= 0.0) || !std::isfinite(s.haustra.depth))
    fail_spec("haustra.depth", "must be >= 0 and finite", s.haustra.depth);
  if (s.haustra.enabled() &&
      (!(s.haustra.pitch >= kMinRingsPerHaustrum * s.segment_length) || !std::isfinite(s.haustra.pitch)))
    fail_spec("haustra.pitch",
              ("must be finite and at least " + std::to_string(kMinRingsPerHaustrum) + " segment_length").c_str(),
              s.haustra.pitch);
}

// The range against the centreline's arc length, the profile covering it, the ring count bounded.
void validate_range(const SweptTubeSpec& s, double length) {
  if (!(s.range_start >= 0.0) || !std::isfinite(s.range_start))
    fail_spec("range_start", "must be >= 0 and finite", s.range_start);
  if (!(s.range_stop > s.range_start) || !(s.range_stop <= length))
    fail_spec("range_stop", ("must be > range_start and <= the arc length " + detail::num(length)).c_str(),
              s.range_stop);
  if (!s.radius_profile.empty() &&
      (s.radius_profile.front().s > s.range_start || s.radius_profile.back().s < s.range_stop))
    fail_spec("radius_profile", "must cover the range (first s <= range_start, last s >= range_stop), first s",
              s.radius_profile.front().s);
  const double rings = (s.range_stop - s.range_start) / s.segment_length;
  if (!(rings < kMaxSweptRings))
    fail_spec("segment_length", ("gives more than " + std::to_string(kMaxSweptRings) + " rings over the range").c_str(),
              s.segment_length);
}

// Rings along the range at equal spacing of at most segment_length.
int segments_along(const SweptTubeSpec& s) {
  const double exact = (s.range_stop - s.range_start) / s.segment_length;
  return std::max(1, static_cast<int>(std::ceil(exact * (1.0 - kRingCountTolerance))));
}

// Bend radius between two rings: chord / (2 sin(turn / 2)), the distance from the rings' centres to the line
// where their planes meet; infinite when their tangents are parallel.
double bend_radius(const CentrelineFrame& a, const CentrelineFrame& b) {
  const double turn = angle_between(a.tangent, b.tangent);
  if (!(turn > 0.0)) return std::numeric_limits<double>::infinity();
  return (b.point - a.point).norm() / (2.0 * std::sin(0.5 * turn));
}

// Scale each ring's radii so its outer wall stays within kBendClearance of the bend radius on either side, the
// scale changing by at most kClampTaper from ring to ring (so a clamped ring's neighbours narrow toward it instead
// of the wall stepping); returns how many rings it changed.
int clamp_to_bends(std::vector<TubeRing>& rings) {
  const size_t n = rings.size();
  std::vector<double> scale(n, 1.0);
  for (size_t j = 0; j + 1 < n; ++j) {
    const double rho = kBendClearance * bend_radius(rings[j].frame, rings[j + 1].frame);
    for (size_t k : {j, j + 1}) scale[k] = std::min(scale[k], rho / rings[k].outer_radius);
  }
  for (size_t j = 1; j < n; ++j) scale[j] = std::min(scale[j], scale[j - 1] + kClampTaper);
  for (size_t j = n - 1; j-- > 0;) scale[j] = std::min(scale[j], scale[j + 1] + kClampTaper);
  int clamped = 0;
  for (size_t j = 0; j < n; ++j) {
    if (!(scale[j] < 1.0)) continue;
    rings[j].inner_radius *= scale[j];
    rings[j].outer_radius *= scale[j];
    ++clamped;
  }
  return clamped;
}

}  // namespace

std::vector<double> arc_lengths(const Points& points) {
  std::vector<double> s(points.rows(), 0.0);
  for (Eigen::Index i = 1; i < points.rows(); ++i) s[i] = s[i - 1] + (points.row(i) - points.row(i - 1)).norm();
  return s;
}

double nearest_arc_length(const Points& points, const std::vector<double>& arc, const Eigen::Vector3d& x) {
  // Every segment's nearest point (the clamped projection); strictly nearer replaces, so ties keep the least s.
  double best_s = arc.empty() ? 0.0 : arc.front();
  double best_d2 = points.rows() > 0 ? (x - row(points, 0)).squaredNorm() : std::numeric_limits<double>::infinity();
  for (Eigen::Index i = 0; i + 1 < points.rows(); ++i) {
    const Eigen::Vector3d a = row(points, i), d = row(points, i + 1) - a;
    const double length2 = d.squaredNorm();
    const double t = length2 > 0.0 ? std::clamp((x - a).dot(d) / length2, 0.0, 1.0) : 0.0;
    const double d2 = (a + t * d - x).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best_s = arc[static_cast<size_t>(i)] + t * (arc[static_cast<size_t>(i) + 1] - arc[static_cast<size_t>(i)]);
    }
  }
  return best_s;
}

void validate_centreline(const Centreline& c, const std::string& source) {
  const Eigen::Index n = c.points.rows();
  if (n < 2) detail::fail(source + ": points: needs at least 2 points, got " + std::to_string(n));
  check_rows(c.points, n, source, "points");
  check_rows(c.tangents, n, source, "tangents");
  check_rows(c.normals, n, source, "normals");
  // Repeated points: a chord shorter than kRepeatedPointFraction of the whole length.
  const double length = arc_lengths(c.points).back();
  for (Eigen::Index i = 1; i < n; ++i)
    if (!((c.points.row(i) - c.points.row(i - 1)).norm() > kRepeatedPointFraction * length))
      fail_sample(source, "points", i, "repeats points[" + std::to_string(i - 1) + "], got " + vec_text(row(c.points, i)));
  const std::vector<Eigen::Vector3d> tangents = sample_tangents(c);
  check_tangents(c, tangents, source);
  check_normals(c, tangents, source);
}

std::vector<CentrelineFrame> centreline_frames(const Centreline& c) {
  const std::vector<Eigen::Vector3d> t = sample_tangents(c);
  std::vector<Eigen::Vector3d> normals;
  if (c.normals.rows() == c.points.rows()) {
    for (size_t i = 0; i < t.size(); ++i) {
      const Eigen::Vector3d n = row(c.normals, static_cast<Eigen::Index>(i));
      normals.push_back(normal_part(n, t[i]).normalized());
    }
  } else {
    normals = rotation_minimising_normals(c, t);
  }
  std::vector<CentrelineFrame> frames(t.size());
  for (size_t i = 0; i < t.size(); ++i)
    frames[i] = {row(c.points, static_cast<Eigen::Index>(i)), t[i], normals[i], t[i].cross(normals[i])};
  return frames;
}

CentrelineFrame frame_at_arc_length(const std::vector<CentrelineFrame>& frames, const std::vector<double>& arc,
                                    double s) {
  const Bracket k = bracket(arc, s);
  const CentrelineFrame &a = frames[k.a], &b = frames[k.b];
  CentrelineFrame f;
  f.point = lerp(a.point, b.point, k.w);
  f.tangent = lerp(a.tangent, b.tangent, k.w).normalized();
  f.normal = normal_part(lerp(a.normal, b.normal, k.w), f.tangent).normalized();
  f.binormal = f.tangent.cross(f.normal);
  return f;
}

double swept_tube_lumen_radius(const SweptTubeSpec& spec, double s) {
  double r = spec.radius;
  if (!spec.radius_profile.empty()) {
    std::vector<double> xs;
    for (const RadiusKnot& knot : spec.radius_profile) xs.push_back(knot.s);
    const Bracket k = bracket(xs, s);
    r = lerp(spec.radius_profile[k.a].r, spec.radius_profile[k.b].r, k.w);
  }
  if (spec.haustra.enabled()) {
    const double phase = std::sin(kPi * (s - spec.range_start) / spec.haustra.pitch);
    r += spec.haustra.depth * phase * phase;
  }
  return r;
}

RingFrames swept_tube_ring_frames(const SweptTubeSpec& spec) {
  const std::vector<double> arc = arc_lengths(spec.centreline.points);
  const std::vector<CentrelineFrame> frames = centreline_frames(spec.centreline);
  RingFrames rings;
  const int nl = segments_along(spec);
  for (int j = 0; j <= nl; ++j) {
    const double s = spec.range_start + (spec.range_stop - spec.range_start) * j / nl;
    rings.s.push_back(s);
    rings.frames.push_back(frame_at_arc_length(frames, arc, s));
  }
  return rings;
}

std::vector<double> smooth_profile(const std::vector<double>& values, double step, double half_window) {
  if (!(step > 0.0)) fail_spec("smooth_profile step", "must be > 0", step);
  if (!(half_window >= 0.0)) fail_spec("smooth_profile half_window", "must be >= 0", half_window);
  const long n = static_cast<long>(values.size());
  const long reach = static_cast<long>(std::floor(half_window / step * (1.0 + kRingCountTolerance)));
  std::vector<double> out(values.size());
  for (long j = 0; j < n; ++j) {
    const long k = std::min({reach, j, n - 1 - j});
    double sum = 0.0;
    for (long i = j - k; i <= j + k; ++i) sum += values[static_cast<size_t>(i)];
    out[static_cast<size_t>(j)] = sum / static_cast<double>(2 * k + 1);
  }
  return out;
}

SweptTube make_swept_tube(const SweptTubeSpec& spec) {
  validate_wall(spec);
  validate_centreline(spec.centreline, spec.source);
  validate_range(spec, arc_lengths(spec.centreline.points).back());

  // Rings at equal arc-length steps over the range, with the spec's radii, then clamped at tight bends.
  SweptTube tube;
  RingFrames frames = swept_tube_ring_frames(spec);
  tube.ring_s = std::move(frames.s);
  for (size_t j = 0; j < tube.ring_s.size(); ++j) {
    const double inner = swept_tube_lumen_radius(spec, tube.ring_s[j]);
    tube.rings.push_back({frames.frames[j], inner, inner + spec.wall_thickness});
  }
  tube.clamped_rings = clamp_to_bends(tube.rings);
  tube.mesh = make_structured_tube(tube.rings, spec.segments_around, spec.layers);
  return tube;
}

}  // namespace lumen::physics
