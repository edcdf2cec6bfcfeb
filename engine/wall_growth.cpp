// A wall grown from a closed surface: smoothed normals, offsets clamped to the ray-cast gap and shrunk where the
// walls still intersect, prisms between the surface and its offset.
#include "engine/wall_growth.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "collision/intersect.hpp"
#include "collision/raycast.hpp"
#include "engine/clock.hpp"
#include "engine/input.hpp"
#include "engine/scene.hpp"
#include "engine/surface_file.hpp"
#include "physics/mesh_quality.hpp"
#include "physics/surface_wall.hpp"

namespace lumen::engine {
namespace {

// Both walls as one point array: the surface's vertices, then the offset's (each triangle of the surface once
// on each wall).
using StackedPoints = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using StackedTris = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;

// A vertex's triangles lie in one plane when each normal is within this cosine of the fan's (anti)parallel.
constexpr double kFlatFanCosine = 0.999;

// Untangles planar fold-overs, a defect of some surfaces (the aneurysm's flat end caps have one): a vertex whose
// triangles all lie in one plane but do not all face the same way (one folded back over its neighbours, so no
// direction leaves all of them on one side and a prism over it would be inverted) moves to the mean of its
// neighbours, in that plane, when every one of its triangles then faces the fan's way (the area-weighted normal's);
// otherwise it stays (and the prism check refuses the wall). Returns how many vertices moved.
int untangle_flat_folds(SurfaceMesh& s) {
  const Eigen::Index nv = s.points.rows();
  std::vector<std::vector<int>> fan(static_cast<size_t>(nv));
  for (int t = 0; t < s.tris.rows(); ++t)
    for (int j = 0; j < 3; ++j) fan[static_cast<size_t>(s.tris(t, j))].push_back(t);
  auto area_vector = [&s](int t) {
    const Eigen::RowVector3d a = s.points.row(s.tris(t, 0)), b = s.points.row(s.tris(t, 1)), c = s.points.row(s.tris(t, 2));
    return Eigen::RowVector3d((b - a).cross(c - a));
  };
  int moved = 0;
  for (Eigen::Index v = 0; v < nv; ++v) {
    const std::vector<int>& faces = fan[static_cast<size_t>(v)];
    Eigen::RowVector3d sum = Eigen::RowVector3d::Zero(), ring = Eigen::RowVector3d::Zero();
    for (int t : faces) sum += area_vector(t);
    if (!(sum.norm() > 0.0)) continue;
    const Eigen::RowVector3d n = sum.normalized();
    bool flat = true, folded = false;
    for (int t : faces) {
      const double c = area_vector(t).normalized().dot(n);
      flat = flat && std::abs(c) > kFlatFanCosine;
      folded = folded || c < 0.0;
    }
    if (!flat || !folded) continue;
    int count = 0;
    for (int t : faces)
      for (int j = 0; j < 3; ++j)
        if (s.tris(t, j) != v) ring += s.points.row(s.tris(t, j)), ++count;
    const Eigen::RowVector3d old = s.points.row(v);
    s.points.row(v) = ring / count;
    bool untangled = true;
    for (int t : faces) untangled = untangled && area_vector(t).dot(n) > 0.0;
    if (untangled) ++moved;
    else s.points.row(v) = old;
  }
  return moved;
}

const char* direction_name(WallDirection d) { return kWallDirectionNames[static_cast<int>(d)]; }

// Each vertex's unit direction of growth: its smoothed normal, or its own area-weighted normal where the smoothed
// one makes less than kMinNormalCosine with an incident triangle's normal (a prism over that triangle would lean
// too far: thin offsets keep every prism tet positive only when each vertex's direction leaves all its triangles
// on the same side); turned inward for an inward wall.
Points growth_directions(const SurfaceMesh& s, WallDirection d) {
  const Points raw = physics::vertex_normals(s.points, s.tris);
  Points n = physics::smooth_normals(raw, s.tris, kWallNormalSmoothingRounds);
  std::vector<double> min_cos(static_cast<size_t>(n.rows()), 1.0);
  for (Eigen::Index t = 0; t < s.tris.rows(); ++t) {
    const Eigen::RowVector3d a = s.points.row(s.tris(t, 0)), b = s.points.row(s.tris(t, 1)), c = s.points.row(s.tris(t, 2));
    const Eigen::RowVector3d face = (b - a).cross(c - a).normalized();
    for (int j = 0; j < 3; ++j) {
      const int v = s.tris(t, j);
      min_cos[static_cast<size_t>(v)] = std::min(min_cos[static_cast<size_t>(v)], n.row(v).dot(face));
    }
  }
  for (Eigen::Index v = 0; v < n.rows(); ++v)
    if (min_cos[static_cast<size_t>(v)] < kMinNormalCosine) n.row(v) = raw.row(v);
  return d == WallDirection::kOutward ? n : Points(-n);
}

// The thickness at each vertex, clamped to kWallGapFraction of the distance to the surface along its direction.
std::vector<double> gap_clamped_offsets(const SurfaceMesh& s, const Points& dirs, double thickness) {
  const collision::RayCaster caster(s.points, s.tris);
  std::vector<double> offset(static_cast<size_t>(s.points.rows()), thickness);
  for (int v = 0; v < s.points.rows(); ++v) {
    const Eigen::Vector3d x = s.points.row(v), d = dirs.row(v);
    const collision::RayHit hit = caster.first_hit(x.data(), d.data(), v);
    if (hit.hit()) offset[static_cast<size_t>(v)] = std::min(thickness, kWallGapFraction * hit.t);
  }
  return offset;
}

// The surface and its offset stacked (x, then x + offset d), and their triangles (the surface's, then the same
// on the offset).
StackedPoints stacked_walls(const SurfaceMesh& s, const Points& dirs, const std::vector<double>& offset) {
  const Eigen::Index nv = s.points.rows();
  StackedPoints p(2 * nv, 3);
  p.topRows(nv) = s.points;
  for (Eigen::Index v = 0; v < nv; ++v) p.row(nv + v) = s.points.row(v) + offset[static_cast<size_t>(v)] * dirs.row(v);
  return p;
}
StackedTris stacked_tris(const SurfaceMesh& s) {
  StackedTris t(2 * s.tris.rows(), 3);
  t.topRows(s.tris.rows()) = s.tris;
  t.bottomRows(s.tris.rows()) = s.tris.array() + static_cast<int>(s.points.rows());
  return t;
}

// "triangle I of the surface" / "triangle I of the offset wall", for a stacked triangle index.
std::string wall_triangle(int stacked, int triangles) {
  return stacked < triangles ? "triangle " + std::to_string(stacked) + " of the surface"
                             : "triangle " + std::to_string(stacked - triangles) + " of the offset wall";
}

// The prism wall between the surface and its offset (`walls`, stacked): inner the surface when growing outward,
// else the offset.
physics::TetMesh prism_wall(const SurfaceMesh& s, const StackedPoints& walls, WallDirection d, int layers) {
  const Eigen::Index nv = s.points.rows();
  const bool outward = d == WallDirection::kOutward;
  return physics::make_prism_wall(outward ? walls.topRows(nv) : walls.bottomRows(nv),
                                  outward ? walls.bottomRows(nv) : walls.topRows(nv), s.tris, layers);
}

// The surface's triangles whose prism (one layer, between the stacked walls) has an inverted or flat tet.
std::vector<int> inverted_prisms(const SurfaceMesh& s, const StackedPoints& walls, WallDirection d) {
  const physics::TetMesh prisms = prism_wall(s, walls, d, 1);
  std::vector<int> bad;
  for (Eigen::Index t = 0; t < prisms.tets.rows(); ++t) {
    Eigen::Matrix<double, 4, 3> x;
    for (int c = 0; c < 4; ++c) x.row(c) = prisms.rest.row(prisms.tets(t, c));
    const int triangle = static_cast<int>(t / 3);
    if (physics::tet_shape(x).degenerate && (bad.empty() || bad.back() != triangle)) bad.push_back(triangle);
  }
  return bad;
}

// Scales the offsets of every vertex of the given surface triangles by kWallShrinkFactor (each vertex once).
void shrink_around(const SurfaceMesh& s, const std::vector<int>& triangles, std::vector<double>& offset) {
  std::vector<bool> hit(static_cast<size_t>(s.points.rows()), false);
  for (int f : triangles)
    for (int j = 0; j < 3; ++j) hit[static_cast<size_t>(s.tris(f, j))] = true;
  for (size_t v = 0; v < hit.size(); ++v)
    if (hit[v]) offset[v] *= kWallShrinkFactor;
}

// A length of the spec (metres) in the scene's mesh.units with the unit's name ("2.5 mm" or "0.0025 m").
std::string length_text(const SurfaceWallSpec& spec, double metres) { return length_in_units(metres, spec.metres_per_unit); }

// The message refusing a wall whose offsets still make the walls intersect or a prism invert.
std::string refusal(const SurfaceWallSpec& spec, const std::vector<std::array<int, 2>>& pairs,
                    const std::vector<int>& inverted, int triangles) {
  const std::string grown = "a wall of " + length_text(spec, spec.thickness) + " grown " + direction_name(spec.direction);
  const std::string after = " after " + std::to_string(kWallShrinkRounds) + " rounds of shrinking the offset around them";
  if (pairs.empty())
    return spec.file + ": " + grown + " has an inverted or zero-volume prism over triangle " +
           std::to_string(inverted[0]) + after + " (" + std::to_string(inverted.size()) +
           " such triangles): the surface turns too sharply there for its vertex normals";
  return spec.file + ": " + grown + " cannot be made intersection-free: " + wall_triangle(pairs[0][0], triangles) +
         " and " + wall_triangle(pairs[0][1], triangles) + " still intersect" + after + " (" +
         std::to_string(pairs.size()) + " intersecting pairs; offsetting along vertex normals fails where the "
         "surface folds more sharply than the wall is thick: for a tubular organ, sweep a tube along its centreline "
         "with the radius from the surface, mesh.type \"swept_tube\" with mesh.radius {\"from_surface\": ...})";
}

// Refuses a wall that the surface's own gaps clamp below kMinClampedThicknessFraction of its thickness at a vertex,
// naming the thinnest vertex, the room there and how many vertices are so clamped.
void require_room_for_the_wall(const SurfaceWallSpec& spec, const std::vector<double>& offset) {
  const double floor = kMinClampedThicknessFraction * spec.thickness;
  const auto thinnest = std::min_element(offset.begin(), offset.end());
  if (*thinnest >= floor) return;
  const long count = std::count_if(offset.begin(), offset.end(), [&](double o) { return o < floor; });
  throw InputError(spec.file + ": a wall of " + length_text(spec, spec.thickness) + " grown " +
                   direction_name(spec.direction) + " is thicker than the surface's gaps allow: at vertex " +
                   std::to_string(thinnest - offset.begin()) + " the surface across it leaves room for " +
                   length_text(spec, *thinnest) + " (" + std::to_string(count) + " vertices get less than half the " +
                   "thickness); make mesh.thickness smaller, or for a tubular organ sweep a tube along its centreline "
                   "with the radius from the surface, mesh.type \"swept_tube\" with mesh.radius {\"from_surface\": ...}");
}

// Offsets for which the surface and its offset have no intersecting triangle pair and every prism between them is
// positive (shrinking around the triangles where not); refuses the surface when kWallShrinkRounds are not enough.
std::vector<double> valid_offsets(const SurfaceWallSpec& spec, const SurfaceMesh& s, const Points& dirs, int& rounds) {
  std::vector<double> offset = gap_clamped_offsets(s, dirs, spec.thickness);
  require_room_for_the_wall(spec, offset);
  const StackedTris tris = stacked_tris(s);
  const int nt = static_cast<int>(s.tris.rows());
  for (rounds = 0;; ++rounds) {
    const StackedPoints walls = stacked_walls(s, dirs, offset);
    const std::vector<std::array<int, 2>> pairs = collision::intersecting_pairs(walls, tris);
    const std::vector<int> inverted = inverted_prisms(s, walls, spec.direction);
    if (pairs.empty() && inverted.empty()) return offset;
    if (rounds == kWallShrinkRounds) throw InputError(refusal(spec, pairs, inverted, nt));
    std::vector<int> around = inverted;
    for (const auto& p : pairs)
      for (int f : p) around.push_back(f % nt);
    shrink_around(s, around, offset);
  }
}

// Refuses a surface (`what`: the file's, or its remeshed copy) with an intersecting triangle pair by the exact check.
void require_no_self_intersection(const SurfaceWallSpec& spec, const SurfaceMesh& s, const std::string& what) {
  const std::vector<std::array<int, 2>> self = collision::intersecting_pairs(s.points, s.tris);
  if (!self.empty())
    throw InputError(spec.file + ": " + what + " intersects itself: triangles " + std::to_string(self[0][0]) + " and " +
                     std::to_string(self[0][1]) + " intersect (" + std::to_string(self.size()) + " intersecting pairs)");
}

// Refuses the wall when a tet of its layers is inverted or flat, naming the surface triangle it stands on.
void require_valid_prisms(const SurfaceWallSpec& spec, const physics::TetMesh& mesh) {
  const physics::MeshQuality q = physics::mesh_quality(mesh.rest, mesh.tets);
  if (q.first_degenerate < 0) return;
  const int triangle = q.first_degenerate / (3 * spec.layers);
  throw InputError(spec.file + ": the wall grown " + direction_name(spec.direction) + " has an inverted or zero-volume "
                   "tet over triangle " + std::to_string(triangle) + " (tet " + std::to_string(q.first_degenerate) +
                   "; " + std::to_string(q.degenerate_tets) + " such tets)");
}

}  // namespace

SurfaceWall grow_surface_wall(const SurfaceWallSpec& spec) {
  if (!(spec.thickness > 0.0) || !std::isfinite(spec.thickness))
    throw InputError(spec.file + ": the wall thickness must be > 0 and finite (value " + length_text(spec, spec.thickness) + ")");
  if (spec.layers < 1) throw InputError(spec.file + ": the wall needs at least 1 layer (value " + std::to_string(spec.layers) + ")");
  SurfaceMesh s = read_closed_surface(spec.file, spec.metres_per_unit);
  SurfaceWall wall;
  wall.untangled_vertices = untangle_flat_folds(s);
  require_no_self_intersection(spec, s, "the surface");
  wall.file_triangles = static_cast<int>(s.tris.rows());
  // The resolution the scene asks for: the surface remeshed to the target edge (on itself, so checked again).
  if (spec.target_edge > 0.0) {
    const auto tr = Clock::now();
    s = remesh_surface(s, spec.target_edge, spec.file, length_text(spec, spec.target_edge));
    wall.remesh_ms = ms_since(tr);
    require_no_self_intersection(spec, s, "the surface remeshed to a target edge of " + length_text(spec, spec.target_edge));
  }
  const auto t0 = Clock::now();
  wall.vertices = static_cast<int>(s.points.rows());
  wall.triangles = static_cast<int>(s.tris.rows());
  const Points dirs = growth_directions(s, spec.direction);
  const std::vector<double> offset = valid_offsets(spec, s, dirs, wall.shrink_rounds);
  wall.clamped_vertices = static_cast<int>(std::count_if(offset.begin(), offset.end(), [&](double o) { return o < spec.thickness; }));
  wall.min_offset = *std::min_element(offset.begin(), offset.end());
  wall.mesh = prism_wall(s, stacked_walls(s, dirs, offset), spec.direction, spec.layers);
  wall.grow_ms = ms_since(t0);
  require_valid_prisms(spec, wall.mesh);
  return wall;
}

}  // namespace lumen::engine
