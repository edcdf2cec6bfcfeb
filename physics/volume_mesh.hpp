#pragma once
// A TetMesh from a volume mesh file's contents (physics/volume_mesh_files.hpp): the tets checked, the walls taken
// from tagged triangles or found on the boundary, the end caps and end node sets around them.
#include "physics/mesh.hpp"
#include "physics/volume_mesh_files.hpp"

namespace lumen::physics {

// Which boundary triangles are the walls: the file's triangles with these tags (given), or found on the boundary.
struct WallTags {
  bool given = false;
  int inner = 0, outer = 0;
};

// Faces of an open tube's boundary meeting at more than this angle (between their normals) lie on different
// patches (the rims between the walls and the end caps). A structured tube needs more than 360 / 60 = 6 cells
// around for its walls to stay one patch each.
inline constexpr double kFeatureAngleDeg = 60.0;

// The boundary faces of tets (faces of one tet only), each oriented out of the volume (tets positive), in the
// order of the tets and their faces (the face opposite vertex 3, 2, 1, 0).
Tris boundary_faces(const Tets& tets);

// The mesh of a volume mesh file, positions times metres_per_unit, keeping only the nodes the tets use (in the
// file's order) and the tets in the file's order. Surfaces (make_hollow_cylinder's names, normals out of the
// volume): kInnerWall and kOuterWall, by tags the file's triangles with tags.inner / tags.outer (each a boundary
// face, oriented as it; the file's vertex order kept when it already faces out), else found on the boundary: two
// closed components (a closed hollow organ: the inner wall is the one whose enclosed volume, by its outward
// normals, is negative: it faces the lumen), or one component (an open tube) split into patches at edges sharper
// than kFeatureAngleDeg, each patch closed by fans over its rim loops: the inner wall is the patch of most negative
// closed volume, the outer wall the most positive; kEndCaps: the rest of the boundary. Node sets kStartEnd and
// kStopEnd (sorted ids) when the end caps are two vertex-connected pieces: start is the one with the lowest node id.
// Throws std::invalid_argument "<file>: <where>: <problem>" for an inverted or degenerate tet (its index and file
// element id), a wall tag no boundary triangle has, a tagged triangle that is not a boundary face, a non-manifold
// boundary edge, or a boundary whose walls cannot be found.
TetMesh make_volume_mesh(const VolumeMeshFile& f, double metres_per_unit, const WallTags& tags);

}  // namespace lumen::physics
