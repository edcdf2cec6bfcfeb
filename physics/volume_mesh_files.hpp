#pragma once
// Readers of tetrahedral volume meshes made elsewhere (pure parsing, no geometry): gmsh .msh (ASCII v2.2 and
// v4.1) and VTK unstructured grids (XML .vtu and legacy .vtk, ASCII). Building a TetMesh from what they read is
// physics/volume_mesh.hpp's.
#include <climits>
#include <string>
#include <vector>

#include "physics/types.hpp"

namespace lumen::physics {

// A triangle's tag when the file gives it none (no physical tag, no cell-data tag array).
inline constexpr int kNoTag = INT_MIN;

// A gmsh physical name of dimension 2 (a name inner_tag / outer_tag may give instead of the number).
struct TagName {
  std::string name;
  int tag = 0;
};

// What a volume mesh file holds, in the file's units and order, with node ids turned into row indices.
struct VolumeMeshFile {
  std::string file;               // the path it was read from (for messages)
  Points nodes;                   // n_nodes x 3, file units, in the file's order
  Tets tets;                      // n_tets x 4, rows of nodes, Lumen's order (positive when the file's is)
  std::vector<long> tet_ids;      // n_tets: the element id (gmsh) or cell index (VTK) of each tet, for messages
  Tris triangles;                 // n_tris x 3, rows of nodes: the file's surface triangles, its vertex order
  std::vector<int> triangle_tags;  // n_tris: gmsh physical tag / VTK cell-data tag, kNoTag when none
  std::vector<TagName> tag_names;  // gmsh $PhysicalNames of dimension 2 (empty for VTK)
};

// Reads a volume mesh by its extension (.msh, .vtu, .vtk; any case). Throws std::invalid_argument with one
// message "<file>: <where>: <problem>" (where: a line number, an element or cell index, a section or array) for
// a missing or unreadable file, an unknown extension, an unsupported version, a binary or compressed file, a
// truncated or malformed section, a node id used but not defined, a volume element other than a linear tet
// (tet10 included: "export linear tets"), or no tets at all.
VolumeMeshFile read_volume_mesh_file(const std::string& path);

// The same from text: `format` is the extension ("msh", "vtu", "vtk") and `file` names it in messages.
VolumeMeshFile parse_volume_mesh(const std::string& text, const std::string& format, const std::string& file);

}  // namespace lumen::physics
