#pragma once
// mesh.type "surface_pair": a hollow organ's wall given as two closed surface files, inner (the lumen's) and outer,
// tetrahedralised at load by gmsh or Netgen (physics/pair_mesh.hpp) into the volume between them.
#include <string>

#include "engine/surface_file.hpp"
#include "physics/pair_mesh.hpp"

namespace lumen::engine {

// A point's winding number about a closed surface is taken as inside when above this (1 inside, 0 outside).
inline constexpr double kInsideWindingNumber = 0.5;

struct SurfacePairSpec {
  std::string inner_file;        // the lumen's surface (OBJ, STL, PLY, OFF), absolute path
  std::string outer_file;        // the outer wall's surface, absolute path
  double metres_per_unit = 1.0;  // the files' (and max_edge's) unit
  physics::PairMeshOptions options;  // the mesher and its sizes (metres)
  double target_edge = 0.0;      // metres: both surfaces remeshed to this edge first (0: as read)
};

// The tetrahedralised wall and how it was made.
struct SurfacePair {
  physics::TetMesh mesh;      // physics::tetrahedralise_pair: surfaces inner, outer, ends (empty); no node sets
  int inner_triangles = 0;    // of the inner surface file
  int outer_triangles = 0;
  int added_nodes = 0;        // nodes the mesher added inside the wall
  double check_ms = 0.0;      // reading both files and their checks (closed, intersections, enclosure), ms
  double mesher_ms = 0.0;     // the mesher's time, milliseconds
  physics::PairMesher mesher = physics::PairMesher::kNetgen;  // the mesher that made it
  std::string gmsh_failure;   // mesher "auto": why gmsh did not, when Netgen made it; "" otherwise
  double remesh_ms = 0.0;     // both surfaces remeshed to the target edge, milliseconds (0 without one)
};

// The winding number of point p about a closed, outward surface (the sum of its triangles' solid angles seen from
// p over 4 pi): 1 inside, 0 outside (p not on the surface).
double winding_number(const SurfaceMesh& s, const Eigen::Vector3d& p);

// Reads both surfaces (read_closed_surface each: a missing file, an unsupported format, an open, non-manifold,
// inconsistently oriented or degenerate surface refused naming its file; each turned to face outwards), refuses
// intersections by the exact triangle-triangle check on both together: "INNER: the inner surface intersects
// itself: triangles I and J intersect (K intersecting pairs)" (likewise the outer), "INNER and OUTER: the surfaces
// intersect each other: triangle I of the inner surface and triangle J of the outer surface intersect (K
// intersecting pairs)"; refuses an outer surface that does not enclose the inner one: "OUTER: does not enclose the
// inner surface INNER: its vertex V at [x, y, z] lies outside" (with ", and the outer surface lies inside the inner
// one: inner and outer are swapped" when so); then tetrahedralises the volume between them, refusing what the mesher
// fails on: "INNER and OUTER: <PairMesherError's message>". All as InputError.
SurfacePair mesh_surface_pair(const SurfacePairSpec& spec);

}  // namespace lumen::engine
