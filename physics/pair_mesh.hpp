#pragma once
// The volume between two closed surfaces (a hollow organ's inner and outer wall) tetrahedralised by gmsh (GPL-2+) or
// Netgen's nglib (LGPL), keeping every input triangle as a boundary face and every input vertex as a node.
#include <stdexcept>
#include <string>

#include "physics/mesh.hpp"

namespace lumen::physics {

// The meshers that fill the volume between two surfaces keeping both (chosen by measurement, docs/bench_meshers.csv):
// gmsh's HXT (Delaunay, Marot et al. 2019) with gmsh's tet optimiser, 7-10x faster than Netgen on the large pairs
// with close angles, but it fails on some pairs Netgen meshes (the full aneurysm with its fold-over vertex
// unmoved); Netgen's advancing front with its optimisation passes. kAuto (the default): gmsh, and Netgen where gmsh
// fails or for a maximum edge.
enum class PairMesher { kAuto, kGmsh, kNetgen };
// Their names and the versions Lumen was measured with (Debian's libgmsh-dev, libnglib-dev), for reports and
// messages.
inline constexpr char kGmshMesherName[] = "gmsh 4.8 hxt";
inline constexpr char kNetgenMesherName[] = "netgen nglib 6.2";
const char* pair_mesher_name(PairMesher mesher);
// The meshers work in a frame where the surfaces' bounding box has this diagonal (centred at the origin): some of
// their tolerances are absolute, so they see the same geometry whatever the input's units. The input vertices keep
// their exact positions; only the nodes a mesher adds are mapped back.
inline constexpr double kPairMesherFrameDiagonal = 100.0;
// Optimisation passes after the volume is filled by default (Netgen: nglib's optsteps_3d default; gmsh: one run
// of its tet optimiser, as its Mesh.Optimize), and the most a scene may ask for.
inline constexpr int kNetgenOptimiseSteps = 3;
inline constexpr int kGmshOptimiseSteps = 1;
inline constexpr int kPairMesherMaxOptimiseSteps = 10;

// gmsh 4.8.4's HXT (Debian's) crashes (a segmentation fault in hxtRefineTetrahedra) refining Lumen's test spheres to
// a maximum edge, with or without its optimiser, one thread or two; without one it meshed all 24 sphere pairs tried.
// A maximum edge therefore takes Netgen, and asking gmsh for one is refused with this message.
inline constexpr char kGmshMaxEdgeRefused[] =
    "a maximum edge needs Netgen: gmsh 4.8's HXT crashed refining to one (use the mesher netgen)";

// How the volume is filled.
struct PairMeshOptions {
  PairMesher mesher = PairMesher::kAuto;
  double max_edge = 0.0;    // longest tet edge Netgen aims for, metres; 0: no limit (the surfaces set the size)
  int optimise_steps = -1;  // optimisation passes, [0, kPairMesherMaxOptimiseSteps]; -1: the mesher's default
};

// The tet mesh between the surfaces and how it was made.
struct PairMesh {
  TetMesh mesh;            // nodes: inner vertices, outer vertices, then the nodes the mesher added inside the wall
  int added_nodes = 0;     // nodes the mesher added (none on the surfaces)
  double mesher_ms = 0.0;  // the mesher's time (its input, meshing and output), milliseconds
  PairMesher mesher = PairMesher::kNetgen;  // the one that made it (kGmsh or kNetgen)
  std::string gmsh_failure;                 // kAuto: gmsh's failure when Netgen made the mesh instead; "" otherwise
};

// The mesher failed, or its mesh does not keep the input surfaces (what() says which and what the mesher said).
class PairMesherError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Tetrahedralises the volume between `inner` (closed, triangles facing outwards, i.e. away from the lumen it
// encloses) and `outer` (closed, facing outwards) with options.mesher (options.optimise_steps optimisation passes,
// options.max_edge as its largest size). The caller has checked that both are closed, edge-manifold, consistently
// oriented and free of intersections, and that `outer` encloses `inner`. Every tet positive. Surfaces
// (make_hollow_cylinder's names, normals out of the volume): kInnerWall (the inner triangles reversed: facing the
// lumen), kOuterWall (the outer triangles, node ids offset by the inner vertex count), kEndCaps (empty: closed
// walls); no node sets. kAuto tries gmsh, then Netgen (out.gmsh_failure says why); both failing throw the two
// messages joined by "; then ". Throws PairMesherError "<Mesher> failed: <what it said>" when the mesher throws or
// reports an error (its words; Netgen: its result code and the last two lines of its log), and "<Mesher> did not
// keep the input surface: ..." when a boundary face of its tets is not an input triangle (or the reverse), an
// input vertex moved, or a tet is inverted or flat; std::invalid_argument when a surface has no triangles, a
// triangle names a vertex out of range, or gmsh is given a maximum edge (kGmshMaxEdgeRefused).
PairMesh tetrahedralise_pair(const Points& inner, const Tris& inner_tris, const Points& outer, const Tris& outer_tris,
                             const PairMeshOptions& options);

}  // namespace lumen::physics
