#pragma once
// The byte protocol between tetrahedralise_pair and its gmsh process (physics/gmsh_mesher/main.cpp): gmsh keeps
// process-wide state that changes its mesh from one call to the next and can crash, so each mesh is made in a
// process of its own. Native byte order (the same machine), each block written in full.
//   request (to the process's standard input):
//     kRequestMagic; int32 vertices, faces, inner_vertices, inner_faces, optimise_steps;
//     double[vertices x 3] (the meshers' frame); int32[faces x 3] (0-based, facing out of the volume)
//   reply (its standard output): kReplyMagic; int32 status (kReplyOk or kReplyFailed), then
//     kReplyOk:     int64 nodes, tets; double[nodes x 3] (the input vertices first, in their order); int32[tets x 4]
//     kReplyFailed: int64 length; char[length] (what gmsh said)
#include <cstdint>

namespace lumen::physics::pair_protocol {

inline constexpr char kRequestMagic[8] = {'L', 'M', 'P', 'A', 'I', 'R', '0', '1'};
inline constexpr char kReplyMagic[8] = {'L', 'M', 'M', 'E', 'S', 'H', '0', '1'};
inline constexpr std::int32_t kReplyOk = 0;
inline constexpr std::int32_t kReplyFailed = 1;
// The process's exit status when its request was cut short or malformed (it writes no reply then).
inline constexpr int kExitBadRequest = 3;
// gmsh's element type numbers (its documentation's table) and its HXT volume algorithm (Mesh.Algorithm3D).
inline constexpr int kGmshTriangle = 2;
inline constexpr int kGmshTet = 4;
inline constexpr int kGmshHxt = 10;

}  // namespace lumen::physics::pair_protocol
