#pragma once
// mesh.type "surface_wall": a wall of given thickness grown from a closed surface file, inward or outward, in
// prism layers, proven free of intersections by the exact triangle-triangle check before a session starts.
#include <string>

#include "physics/mesh.hpp"

namespace lumen::engine {

// Each vertex moves at most this fraction of the ray-cast gap along its normal (the distance to the surface
// straight ahead of it), so two walls growing toward each other stop short of meeting.
inline constexpr double kWallGapFraction = 0.45;
// Rounds of normal smoothing (physics::smooth_normals) before offsetting.
inline constexpr int kWallNormalSmoothingRounds = 3;
// A vertex whose smoothed normal makes less than this cosine with one of its triangles' normals grows along its
// own (unsmoothed, area-weighted) normal instead.
inline constexpr double kMinNormalCosine = 0.1;
// Where the grown walls still intersect (or a prism between them is inverted), the offsets of those triangles'
// vertices are scaled by this, for at most kWallShrinkRounds rounds (then the surface is refused).
inline constexpr double kWallShrinkFactor = 0.5;
inline constexpr int kWallShrinkRounds = 8;
// A wall whose gap clamp leaves a vertex less than this fraction of the thickness is thicker than the surface's
// gaps allow: refused, naming the vertex (a clamp above it is a local thinning, counted in clamped_vertices).
inline constexpr double kMinClampedThicknessFraction = 0.5;

// Which way the wall grows from the surface: outward (the surface is the inner wall, the lumen's) or inward
// (the surface is the outer wall).
enum class WallDirection { kInward, kOutward };
// The names of WallDirection by value: what mesh.direction says and the messages repeat.
inline constexpr const char* kWallDirectionNames[] = {"inward", "outward"};

struct SurfaceWallSpec {
  std::string file;                                // the surface (OBJ, STL, PLY, OFF), absolute path
  double metres_per_unit = 1.0;                    // the file's (and the thickness's) unit
  double thickness = 0.0;                          // metres, > 0
  WallDirection direction = WallDirection::kOutward;
  int layers = 1;                                  // prisms through the wall, >= 1
  double target_edge = 0.0;                        // metres: the surface remeshed to this edge first (0: as read)
};

// The grown wall and how it was grown.
struct SurfaceWall {
  physics::TetMesh mesh;      // physics::make_prism_wall: surfaces inner, outer, ends (empty); no node sets
  int vertices = 0;           // of the surface
  int triangles = 0;
  int clamped_vertices = 0;   // vertices whose offset is less than the thickness (the gap clamp or the shrinking)
  int shrink_rounds = 0;      // rounds of shrinking the offsets around intersecting triangles
  int untangled_vertices = 0; // vertices of the surface moved to untangle planar fold-overs (before growing)
  int file_triangles = 0;     // of the surface as read (before remeshing; = triangles without a target edge)
  double remesh_ms = 0.0;     // the isotropic remeshing to the target edge, milliseconds (0 without one)
  double min_offset = 0.0;    // the thinnest wall at a vertex, metres
  double grow_ms = 0.0;       // normals, gaps, offsets, the intersection checks and the prisms, milliseconds
};

// Reads the surface (engine/surface_file.hpp read_closed_surface: closed, edge-manifold, consistently oriented,
// no degenerate triangle; reversed if it faces inwards), untangles planar fold-overs (a vertex whose triangles lie
// in one plane but do not all face one way moves to the mean of its neighbours when that unfolds them: the
// aneurysm's flat end cap has one), refuses a surface that intersects itself (the exact check), with a target edge
// remeshes it (physics::remesh_isotropic) and refuses the result if it intersects itself ("FILE: the surface
// remeshed to a target edge of E m intersects itself: triangles I and J ..."),
// offsets every vertex along its smoothed normal (outward: +, inward: -) by the thickness clamped to
// kWallGapFraction of its ray-cast gap (directions: smoothed normals, or a vertex's own where the smoothed one
// leans past kMinNormalCosine from a triangle), then while the two walls together (the surface and its offset)
// have an intersecting triangle pair by the exact check, or a prism between them has an inverted or flat tet,
// shrinks the offsets of those triangles' vertices by kWallShrinkFactor, and builds the prism wall (inner: the
// surface if outward, else the offset). Throws InputError naming the file: for a non-positive or non-finite
// thickness or layers < 1, what the reader refuses, "FILE: the surface intersects itself: triangles I and J
// intersect (K intersecting pairs)", "FILE: a wall of T m grown inward is thicker than the surface's gaps allow: at
// vertex V the surface across it leaves room for R m (K vertices get less than half the thickness); make
// mesh.thickness smaller, or ... \"swept_tube\" ...", "FILE: a
// wall of T m grown outward cannot be made intersection-free: triangle
// I of the surface and triangle J of the offset wall still intersect after 8 rounds of shrinking the offset around
// them (K intersecting pairs; ... mesh.type \"swept_tube\" with mesh.radius {\"from_surface\": ...})", "FILE: a wall of
// T m grown outward has an inverted or zero-volume prism over triangle I after 8 rounds ...", and (layers > 1)
// "FILE: the wall grown ... has an inverted or zero-volume tet over triangle I ...".
SurfaceWall grow_surface_wall(const SurfaceWallSpec& spec);

}  // namespace lumen::engine
