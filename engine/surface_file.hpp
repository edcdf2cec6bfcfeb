#pragma once
// Closed triangle surfaces read from files through assimp (an instrument's mesh; an organ's surface for
// engine/wall_growth.hpp and engine/surface_radius.hpp) and their checks: closed, edge-manifold, consistently
// oriented, no degenerate triangle.
// Messages name the file (`where`), the triangle index and the edge's vertices with their positions.
#include <string>

#include "physics/types.hpp"

namespace lumen::engine {

// A triangle of a surface file whose area is at most this fraction of the squared bounding-box diagonal is
// degenerate (collinear or coincident vertices, up to rounding).
inline constexpr double kDegenerateAreaRatio = 1e-12;

// A triangle surface: points (metres) and triangles, counter-clockwise seen from outside when oriented.
struct SurfaceMesh {
  Points points;  // n x 3, metres
  Tris tris;      // m x 3
};

// How long a surface file's reader may take before it is stopped and the file refused (seconds). The largest
// shipped surfaces read in well under a second.
inline constexpr double kSurfaceReadTimeoutS = 60.0;

// Read a surface file through assimp (faces triangulated, nothing else changed):
// every triangle in file order (through the node transforms), vertices at identical positions merged (ids in order
// of first use by the faces), positions times metres_per_unit. assimp runs in a child process (engine/isolated.hpp).
// Refuses (InputError "FILE: ...", naming `what`) an unreadable or empty file, a face that is not a triangle, and a
// file on which assimp crashes ("... the reader (assimp) crashed on it (signal 6 (Aborted))") or runs longer than
// timeout_s ("... did not finish within 60 s"); a .ply file's header is checked first (require_ply_header).
SurfaceMesh read_surface_file(const std::string& file, double metres_per_unit, const std::string& what,
                              double timeout_s = kSurfaceReadTimeoutS);

// A PLY file's header, checked before assimp reads the file (assimp loops without end on some malformed headers):
// "ply" (either case), one "format ascii|binary_little_endian|binary_big_endian 1.0" before the first element,
// "comment" and "obj_info" lines, blank lines, "element NAME COUNT" (COUNT a non-negative integer), "property TYPE
// NAME" and "property list COUNT_TYPE TYPE NAME" after an element (TYPE one of PLY's scalar types, COUNT_TYPE an
// integer one), "end_header" within the first kPlyHeaderMaxBytes; and each element's COUNT no more than the bytes
// after the header can hold (binary: its fixed properties' bytes and its lists' count fields; ascii: two characters
// a property, the last separator optional). Refuses (InputError) "FILE: PLY header line L: PROBLEM (\"LINE\")" (the
// line's first 80 characters, unprintable ones as '?') or "FILE: PLY header: PROBLEM" (no end_header, unreadable).
inline constexpr long kPlyHeaderMaxBytes = 64 * 1024;
void require_ply_header(const std::string& file);

// The formats the organ's surface sources read (mesh.type "surface_wall" and "surface_pair", a swept tube's radius
// from_surface): refuses another file extension, InputError "FILE: unsupported surface format \".EXT\" (OBJ, STL,
// PLY or OFF)".
void require_surface_format(const std::string& file);

// Refuse a surface that is not closed, edge-manifold and consistently oriented, or has a degenerate triangle:
// InputError "WHERE: triangle T is degenerate ...", "WHERE: not closed: edge between vertex A at [..] and vertex
// B at [..] belongs to triangle T only", "WHERE: non-manifold edge ...: shared by K triangles (...)",
// "WHERE: inconsistent orientation: triangles T, U run the edge ... the same way".
void require_closed_surface(const SurfaceMesh& mesh, const std::string& where);
// The same, and facing outwards (a positive enclosed volume; else "WHERE: triangles face inwards ...").
void require_closed_manifold(const SurfaceMesh& mesh, const std::string& where);
// The volume the surface encloses by the divergence theorem (positive when its triangles face outwards), m^3.
double enclosed_volume(const SurfaceMesh& mesh);
// An organ's closed surface file (mesh.type "surface_wall" and "surface_pair", a swept tube's radius
// from_surface): refuses a missing file ("FILE: no such surface file"), another format (require_surface_format),
// what read_surface_file and require_closed_surface refuse (naming the file); a consistently inward-facing surface
// is reversed so that it faces outwards. Positions times metres_per_unit.
SurfaceMesh read_closed_surface(const std::string& file, double metres_per_unit,
                                double timeout_s = kSurfaceReadTimeoutS);

// The surface with every triangle's orientation reversed (its last two vertices swapped).
SurfaceMesh reversed(const SurfaceMesh& mesh);
// A length (metres) in the scene's mesh.units with the unit's name ("2.5 mm" or "0.0025 m").
std::string length_in_units(double metres, double metres_per_unit);
// The surface (read from `file`) remeshed to edges of about target_edge metres (physics::remesh_isotropic, the
// scene's mesh.target_edge, which `target_text` spells in the scene's units, e.g. "1 mm"). Refuses with InputError
// "FILE: mesh.target_edge T would remesh the surface into about N triangles (at most 2000000)" before any work, and
// names the file in CGAL's failures.
SurfaceMesh remesh_surface(const SurfaceMesh& mesh, double target_edge, const std::string& file,
                           const std::string& target_text);

}  // namespace lumen::engine
