#pragma once
// The volume between two closed surfaces (a hollow organ's inner and outer wall) tetrahedralised by Netgen's nglib
// (LGPL), keeping every input triangle as a boundary face and every input vertex as a node.
#include <stdexcept>
#include <string>

#include "physics/mesh.hpp"

namespace lumen::physics {

// Netgen's name and the version Lumen was measured with (Debian's libnglib-dev), for reports and messages.
inline constexpr char kPairMesherName[] = "netgen nglib 6.2";
// Netgen meshes in a frame where the surfaces' bounding box has this diagonal (centred at the origin): some of its
// tolerances are absolute, so it sees the same geometry whatever the input's units. The input vertices keep their
// exact positions; only the nodes Netgen adds are mapped back.
inline constexpr double kPairMesherFrameDiagonal = 100.0;
// Netgen's mesh-optimisation passes after the advancing front by default (nglib's optsteps_3d default), and the
// most a scene may ask for.
inline constexpr int kPairMesherOptimiseSteps = 3;
inline constexpr int kPairMesherMaxOptimiseSteps = 10;

// How the volume is filled.
struct PairMeshSize {
  double max_edge = 0.0;  // longest tet edge Netgen aims for, metres; 0: no limit (the surfaces set the size)
  int optimise_steps = kPairMesherOptimiseSteps;  // Netgen's optimisation passes, [0, kPairMesherMaxOptimiseSteps]
};

// The tet mesh between the surfaces and how it was made.
struct PairMesh {
  TetMesh mesh;            // nodes: inner vertices, outer vertices, then the nodes Netgen added inside the wall
  int added_nodes = 0;     // nodes Netgen added (none on the surfaces)
  double mesher_ms = 0.0;  // Netgen's time (its input, meshing and output), milliseconds
};

// Netgen failed, or its mesh does not keep the input surfaces (what() says which and what Netgen said).
class PairMesherError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Tetrahedralises the volume between `inner` (closed, triangles facing outwards, i.e. away from the lumen it
// encloses) and `outer` (closed, facing outwards) with Netgen (size.optimise_steps optimisation passes, size.max_edge
// as its maxh). The caller has checked that both are closed, edge-manifold, consistently oriented and
// free of intersections, and that `outer` encloses `inner`. Every tet positive. Surfaces (make_hollow_cylinder's
// names, normals out of the volume): kInnerWall (the inner triangles reversed: facing the lumen), kOuterWall (the
// outer triangles, node ids offset by the inner vertex count), kEndCaps (empty: closed walls); no node sets.
// Throws PairMesherError "Netgen failed: <what it said>" when Netgen throws (its exception's words), "Netgen failed:
// <its result code> with N tets (its log ends: <its last two lines>)" when it returns a failure, and "Netgen did not
// keep the input surface: ..." when a boundary face of its tets is not an input triangle (or the reverse), an input
// vertex moved, or a tet is inverted or flat; std::invalid_argument when a surface has no triangles or a triangle
// names a vertex out of range.
PairMesh tetrahedralise_pair(const Points& inner, const Tris& inner_tris, const Points& outer, const Tris& outer_tris,
                             const PairMeshSize& size);

}  // namespace lumen::physics
