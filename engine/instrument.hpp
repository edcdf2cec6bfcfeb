#pragma once
// Rigid instruments: closed, outward-oriented, edge-manifold triangle meshes in the instrument's own frame (tip
// at the origin, shaft along +y, metres), one mesh per rigid part, built from named shapes or read from a mesh
// file, and posed into the organ frame as the plain n x 3 arrays collision::detect_pair takes.
//
// The scene key `instruments` builds these (engine/scene.cpp); engine/instrument_contact.hpp puts them in a session.
// Dimensions and files are validated here with InputError messages naming `where`, the field and the value.
#include <array>
#include <string>
#include <variant>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "engine/pose_track.hpp"
#include "engine/surface_file.hpp"
#include "physics/types.hpp"

namespace lumen::engine {

// Sides of the polygons around the shaft axis. At 16 the polygon strays at most r (1 - cos(pi / 16)) = 2 % of
// the radius inside the true circle: 0.06 mm at a 3 mm tip, under the default collision gap of 0.1 mm.
inline constexpr int kDefaultSegmentsAround = 16;
// Latitude rings from the tip's pole to the sphere's junction with the shaft (0.3 rad apart at a 3 mm tip with a
// 2 mm shaft, chords 0.9 mm long: finer than the 6 mm triangles of a 2496-tet organ mesh).
inline constexpr int kDefaultRings = 8;
// Bands along a shaft, so that its triangles stay about 10 mm long on an 80 mm shaft.
inline constexpr int kDefaultShaftSegments = 8;
// Fewest sides around and rings over a sphere that still enclose a volume.
inline constexpr int kMinSegmentsAround = 3;
inline constexpr int kMinRings = 2;
// The grasper's widest opening between its jaws, radians (each jaw turned a right angle off the axis).
inline constexpr double kMaxOpeningAngle = static_cast<double>(EIGEN_PI);

// One rigid part's closed surface in the instrument frame (at zero opening for a grasper's jaws): points in
// metres, triangles counter-clockwise seen from outside.
using RigidMesh = SurfaceMesh;

// A sphere at the tip (tip at its lowest point, the origin; centre at y = tip_radius) joined to a cylinder
// shaft of shaft_radius <= tip_radius from the sphere's centre up to y = tip_radius + shaft_length, closed by a
// flat cap. One closed surface: the latitude-longitude sphere's last ring is where it meets the shaft.
struct SphereProbeSpec {
  double tip_radius = 0.003;    // metres
  double shaft_radius = 0.002;  // metres, <= tip_radius
  double shaft_length = 0.08;   // metres, from the sphere's centre, > tip_radius
  int segments_around = kDefaultSegmentsAround;
  int rings = kDefaultRings;
  int shaft_segments = kDefaultShaftSegments;
};

// A blunt rod along +y from its tip end (the origin: the centre of the flat end, or the lowest point of the
// rounded one) to y = length.
enum class RodEnd { kFlat, kRounded };  // a flat disc, or a hemisphere of the rod's radius
struct RodSpec {
  double radius = 0.002;  // metres
  double length = 0.08;   // metres, > 2 radius when rounded
  RodEnd end = RodEnd::kFlat;
  int segments_around = kDefaultSegmentsAround;
  int rings = kDefaultRings;  // over the rounded end
  int shaft_segments = kDefaultShaftSegments;
};

// Two box jaws hinged at the tip end of a cylinder shaft. Closed, the jaws lie side by side along +y from the
// tip (the origin, midway between the jaws' tips) to the hinge at y = jaw_length, one on each side of the plane
// x = 0 (x in [0, jaw_thickness] and [-jaw_thickness, 0], z in [-jaw_width / 2, jaw_width / 2]); the hinge axis
// is z through (0, jaw_length, 0); the shaft runs from the hinge to y = jaw_length + shaft_length. Opening by
// an angle turns each jaw by half of it away from the other, in the x-y plane.
struct GrasperSpec {
  double jaw_length = 0.012;     // metres
  double jaw_width = 0.004;      // metres (along z)
  double jaw_thickness = 0.0015; // metres (along x, each jaw)
  double opening_angle = 0.0;    // radians between the jaws, [0, kMaxOpeningAngle]: the opening at rest
  double shaft_radius = 0.0025;  // metres
  double shaft_length = 0.08;    // metres
  int segments_around = kDefaultSegmentsAround;
  int shaft_segments = kDefaultShaftSegments;
};

// Length unit of a file (an instrument mesh, a centreline) and of the lengths given with it: "m" | "mm".
enum class MeshUnits { kMetres, kMillimetres };
// Metres per unit, indexed by MeshUnits.
inline constexpr double kMetresPerUnit[] = {1.0, kMetresPerMillimetre};

// A closed triangle mesh read through assimp (OBJ, STL, PLY), already in the instrument-frame convention.
struct MeshFileSpec {
  std::string file;
  MeshUnits units = MeshUnits::kMetres;
};

using ShapeSpec = std::variant<SphereProbeSpec, RodSpec, GrasperSpec, MeshFileSpec>;

// How a part moves with the grasper's opening: not at all, or about the hinge by + or - half the opening (the
// jaw on the +x side turns its tip towards +x).
enum class PartJoint { kFixed, kJawPositive, kJawNegative };

struct InstrumentPart {
  std::string name;  // "body" (a one-part shape), "shaft", "jaw_positive", "jaw_negative"
  RigidMesh mesh;    // in the instrument frame at zero opening
  PartJoint joint = PartJoint::kFixed;
};

// An instrument: its rigid parts and, for a grasper, the hinge of its jaws.
struct Instrument {
  std::vector<InstrumentPart> parts;
  Eigen::Vector3d hinge = Eigen::Vector3d::Zero();  // a point on the jaws' hinge axis (z), instrument frame
  double rest_opening = 0.0;                        // radians, the grasper's opening at rest (0 for the others)
};

// Build a shape's instrument, validating its dimensions (positive and finite, shaft_radius <= tip_radius, ...)
// and resolution; messages "WHERE.FIELD: problem (value V)".
Instrument make_sphere_probe(const SphereProbeSpec& spec, const std::string& where = "sphere_probe");
Instrument make_rod(const RodSpec& spec, const std::string& where = "rod");
Instrument make_grasper(const GrasperSpec& spec, const std::string& where = "grasper");
// Read, merge vertices at identical positions (ids in order of first use by the faces), scale to metres and
// check the mesh (require_closed_manifold). Refuses a missing, unreadable or empty file, a face that is not a
// triangle, and what the check refuses, naming the file.
Instrument load_mesh_instrument(const MeshFileSpec& spec);
// Any of them; `where` prefixes a built-in shape's field names (a mesh file's errors name the file).
Instrument make_instrument(const ShapeSpec& shape, const std::string& where);

// A grasper's jaws' transforms within the instrument frame at an opening (radians, [0, kMaxOpeningAngle]), for
// the grasp logic and posing: {jaw_positive, jaw_negative} (identities for an instrument without jaws).
std::array<Eigen::Isometry3d, 2> jaw_poses(const Instrument& grasper, double opening_angle);
// One part's transform within the instrument frame at an opening (identity for a fixed part).
Eigen::Isometry3d part_transform(const Instrument& instrument, const InstrumentPart& part, double opening_angle);
// A part's points in the organ frame at a pose and opening, into out (n x 3, resized).
void pose_part(const Instrument& instrument, size_t part, const Pose& pose, double opening_angle, Points& out);
// Every part's points at a pose and opening (the grasper's rest opening by default), in part order: call
// collision::detect_pair with a part's points at the frame's start and end poses.
std::vector<Points> posed_parts(const Instrument& instrument, const Pose& pose);
std::vector<Points> posed_parts(const Instrument& instrument, const Pose& pose, double opening_angle);

}  // namespace lumen::engine
