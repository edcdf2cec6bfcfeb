// lumen_grow_surface: the surfaces of a wall grown outward from a closed surface by Lumen's wall growth
// (engine/wall_growth.hpp), written as OFF files: a surface pair for mesh.type "surface_pair".
//   lumen_grow_surface IN THICKNESS INNER_OUT OUTER_OUT
// IN: a closed surface (OBJ, STL, PLY, OFF); THICKNESS in IN's units (the files keep IN's units). INNER_OUT is IN
// as the wall growth used it (the same vertices, but any it moved to untangle planar fold-overs), OUTER_OUT its
// offset; both with IN's triangles (outward), positions with 9 significant digits (assimp reads them as floats).
#include <cstdio>
#include <cstdlib>
#include <string>

#include "engine/input.hpp"
#include "engine/wall_growth.hpp"

namespace {

// Significant digits written: enough for a float (assimp's precision), so the file reads back as computed.
constexpr int kFloatDigits = 9;
constexpr int kArguments = 5;

// Writes the vertices first .. first + count - 1 of the mesh and the triangles (node ids offset by -first).
void write_off(const std::string& file, const lumen::Points& x, Eigen::Index first, Eigen::Index count,
               const lumen::Tris& tris) {
  FILE* f = std::fopen(file.c_str(), "w");
  if (!f) throw std::runtime_error(file + ": cannot write");
  std::fprintf(f, "OFF\n%ld %ld 0\n", static_cast<long>(count), static_cast<long>(tris.rows()));
  for (Eigen::Index v = first; v < first + count; ++v)
    std::fprintf(f, "%.*g %.*g %.*g\n", kFloatDigits, x(v, 0), kFloatDigits, x(v, 1), kFloatDigits, x(v, 2));
  for (Eigen::Index t = 0; t < tris.rows(); ++t)
    std::fprintf(f, "3 %ld %ld %ld\n", static_cast<long>(tris(t, 0) - first), static_cast<long>(tris(t, 1) - first),
                 static_cast<long>(tris(t, 2) - first));
  std::fclose(f);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != kArguments) {
    std::fprintf(stderr, "usage: lumen_grow_surface IN THICKNESS INNER_OUT OUTER_OUT\n");
    return 2;
  }
  try {
    lumen::engine::SurfaceWallSpec spec;
    spec.file = argv[1];
    spec.thickness = std::atof(argv[2]);
    spec.direction = lumen::engine::WallDirection::kOutward;
    const lumen::engine::SurfaceWall w = lumen::engine::grow_surface_wall(spec);
    // The inner wall is the surface reversed (facing the lumen): turned back to face outwards; the outer as is.
    lumen::Tris inner = w.mesh.surface(lumen::physics::kInnerWall);
    inner.col(1).swap(inner.col(2));
    write_off(argv[3], w.mesh.rest, 0, w.vertices, inner);
    write_off(argv[4], w.mesh.rest, w.vertices, w.vertices, w.mesh.surface(lumen::physics::kOuterWall));
    std::printf("%s: %d vertices, %d triangles, wall %g grown outward: %d vertices clamped below it (thinnest %g), "
                "%d shrink rounds, %d vertices moved to untangle fold-overs; wrote %s and %s\n",
                argv[1], w.vertices, w.triangles, spec.thickness, w.clamped_vertices, w.min_offset, w.shrink_rounds,
                w.untangled_vertices, argv[3], argv[4]);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lumen_grow_surface: error: %s\n", e.what());
    return 2;
  }
  return 0;
}
