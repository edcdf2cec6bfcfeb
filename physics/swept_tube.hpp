#pragma once
// Swept-tube generator: the structured double wall of make_structured_tube swept along a centreline polyline (a
// real organ's path), with a lumen radius that is constant or a profile along the arc length, optional haustra,
// and the radius clamped where the centreline bends tighter than the wall.
#include <string>
#include <vector>

#include "physics/mesh.hpp"

namespace lumen::physics {

// A centreline polyline: sample points in order (metres), with optional tangents and normals per sample (either
// 0 rows, absent, or one row per point; unit length is not required, they are normalised).
struct Centreline {
  Points points;    // n x 3, metres
  Points tangents;  // 0 or n rows: the direction of travel at each sample
  Points normals;   // 0 or n rows: the rings' local x axis at each sample (its part normal to the tangent)
};

// One knot of a lumen-radius profile: the radius at arc length s, linear between knots.
struct RadiusKnot {
  double s = 0.0;  // arc length along the centreline from its first point, metres
  double r = 0.0;  // lumen (inner-wall) radius, metres
};

// Haustra (the colon's periodic sacculations): the lumen radius at arc length s is the base radius plus
// depth sin^2(pi (s - range_start) / pitch), so the range starts at a fold (the base radius) and bulges by depth
// half a pitch further on.
struct Haustra {
  double depth = 0.0;  // metres, >= 0 (0: no haustra)
  double pitch = 0.0;  // metres, fold to fold
  bool enabled() const { return depth > 0.0; }
};

// Parameters of a swept tube: the centreline, the arc-length interval [range_start, range_stop] swept, the wall.
struct SweptTubeSpec {
  std::string source = "centreline";  // names the centreline in messages (its file)
  Centreline centreline;
  double range_start = 0.0;              // metres of arc length from the first point, >= 0
  double range_stop = 0.0;               // metres, > range_start, at most the centreline's arc length
  double radius = 0.0;                   // constant lumen radius, metres (used when radius_profile is empty)
  std::vector<RadiusKnot> radius_profile;  // lumen radius along arc length; knots' s strictly increasing and
                                           // covering the range
  double wall_thickness = 0.0;           // metres, inner to outer wall
  int segments_around = 24;              // cells around the circumference
  double segment_length = 0.002;         // longest spacing of the rings along the range, metres
  int layers = 2;                        // cells through the wall
  Haustra haustra;
};

// The outer wall stays within this fraction of the local bend radius (the clamp).
inline constexpr double kBendClearance = 0.9;
// The clamp's scale of the radii changes by at most this much from one ring to the next.
inline constexpr double kClampTaper = 0.1;
// At least this many rings per haustral pitch (so the sacculation is resolved).
inline constexpr int kMinRingsPerHaustrum = 4;
// At most this many rings along a swept tube (a guard against a segment_length far too small).
inline constexpr int kMaxSweptRings = 100000;

// A generated swept tube: the mesh (names as make_hollow_cylinder's: surfaces inner, outer, ends; node sets
// start, stop) and how it was built.
struct SweptTube {
  TetMesh mesh;
  std::vector<TubeRing> rings;  // each ring's frame and radii as meshed (after the clamp)
  std::vector<double> ring_s;   // arc length of each ring, metres
  int clamped_rings = 0;        // rings whose radii the bend clamp reduced
};

// Cumulative arc length of a polyline at each point (0 at the first), metres.
std::vector<double> arc_lengths(const Points& points);

// The arc length (metres from the first point, as arc_lengths) of the point of the polyline `points` nearest to x:
// each segment's nearest point by the projection of x clamped to the segment, the nearest of those; of equally
// near points the one of least arc length. `arc` is arc_lengths(points).
double nearest_arc_length(const Points& points, const std::vector<double>& arc, const Eigen::Vector3d& x);

// Refuses a centreline that cannot be swept, throwing std::invalid_argument "<source>: <field>[<sample>]:
// <problem>": fewer than 2 points, a non-finite value, a point repeating the one before it, tangents or normals
// whose row count is neither 0 nor the points', a zero tangent, a tangent against the direction of travel or
// turning by 90 degrees or more from the sample before, a normal (nearly) parallel to its tangent or turning by
// 90 degrees or more from the one before.
void validate_centreline(const Centreline& c, const std::string& source);

// The frame at every sample of a valid centreline. Tangents: the given ones normalised, else the sum of the unit
// chords on either side (one chord at the ends). Normals: the given ones made normal to the tangent, else
// rotation-minimising frames by the double reflection method (Wang, Juettler, Zheng, Liu 2008) from a first
// normal toward where the centreline bends (a coordinate axis when it runs straight). Binormal: tangent x normal.
std::vector<CentrelineFrame> centreline_frames(const Centreline& c);

// The frame at arc length s (held at the ends) between the samples' frames (centreline_frames, at arc lengths
// `arc`): the point on the polyline, tangent and normal linearly interpolated, re-orthonormalised.
CentrelineFrame frame_at_arc_length(const std::vector<CentrelineFrame>& frames, const std::vector<double>& arc,
                                    double s);

// The rings of a swept tube before their radii: arc lengths at equal steps of at most segment_length over the
// range (first range_start, last range_stop) and the frame of frame_at_arc_length at each. The spec's centreline
// and range must be valid (make_swept_tube checks them first).
struct RingFrames {
  std::vector<double> s;                  // metres of arc length
  std::vector<CentrelineFrame> frames;    // one per ring
};
RingFrames swept_tube_ring_frames(const SweptTubeSpec& spec);

// A sampled profile smoothed along the arc length: each value the mean of the values within half_window of it
// on both sides, the window shrunk near the ends to stay symmetric (values at equal spacing `step`; so a profile
// linear in the arc length passes unchanged). Throws std::invalid_argument for a non-positive step or a negative
// half_window.
std::vector<double> smooth_profile(const std::vector<double>& values, double step, double half_window);

// Lumen radius of the spec at arc length s before the bend clamp: the constant radius or the profile
// (linear between knots), plus the haustra.
double swept_tube_lumen_radius(const SweptTubeSpec& spec, double s);

// The swept tube: rings at equal spacing (at most segment_length) over the range, each in the plane normal to
// the centreline with the frame of frame_at_arc_length, lumen radius swept_tube_lumen_radius and outer radius
// that plus wall_thickness; where the outer radius exceeds kBendClearance times the bend radius of the rings on
// either side (chord / (2 sin(turn / 2)) between ring tangents), both radii of the ring are scaled down to reach
// it, the scale changing by at most kClampTaper from ring to ring (rings scaled: clamped_rings). Throws std::invalid_argument naming the field and value for an invalid spec
// (the centreline as validate_centreline).
SweptTube make_swept_tube(const SweptTubeSpec& spec);

}  // namespace lumen::physics
