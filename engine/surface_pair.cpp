// A wall between two closed surface files, checked and tetrahedralised at load (engine/surface_pair.hpp).
#include "engine/surface_pair.hpp"

#include <array>
#include <cmath>
#include <vector>

#include "collision/intersect.hpp"
#include "engine/clock.hpp"
#include "engine/input.hpp"
#include "engine/scene.hpp"

namespace lumen::engine {
namespace {

using physics::kPi;

using StackedPoints = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using StackedTris = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;

// Refuses an intersecting triangle pair of the two surfaces together (each with itself, or one with the other).
void require_no_intersections(const SurfacePairSpec& spec, const SurfaceMesh& in, const SurfaceMesh& out) {
  const Eigen::Index ni = in.points.rows(), ti = in.tris.rows();
  StackedPoints x(ni + out.points.rows(), 3);
  x << in.points, out.points;
  StackedTris tris(ti + out.tris.rows(), 3);
  tris << in.tris, (out.tris.array() + static_cast<int>(ni)).matrix();
  const std::vector<std::array<int, 2>> pairs = collision::intersecting_pairs(x, tris);
  if (pairs.empty()) return;
  // The first pair within one surface, else the first between them (pairs are sorted: i < j).
  auto count = [&](int which) {
    int n = 0;
    for (const auto& p : pairs) n += (p[0] >= ti) == (which == 1) && (p[1] >= ti) == (which == 1);
    return n;
  };
  for (int which = 0; which < 2; ++which) {
    const int n = count(which);
    if (n == 0) continue;
    for (const auto& p : pairs)
      if ((p[0] >= ti) == (which == 1) && (p[1] >= ti) == (which == 1)) {
        const int offset = which == 1 ? static_cast<int>(ti) : 0;
        throw InputError((which == 0 ? spec.inner_file : spec.outer_file) + ": the " + (which == 0 ? "inner" : "outer") +
                         " surface intersects itself: triangles " + std::to_string(p[0] - offset) + " and " +
                         std::to_string(p[1] - offset) + " intersect (" + std::to_string(n) + " intersecting pairs)");
      }
  }
  const auto& p = pairs.front();
  throw InputError(spec.inner_file + " and " + spec.outer_file + ": the surfaces intersect each other: triangle " +
                   std::to_string(p[0]) + " of the inner surface and triangle " + std::to_string(p[1] - ti) +
                   " of the outer surface intersect (" + std::to_string(pairs.size()) + " intersecting pairs)");
}

// Refuses an outer surface that does not enclose the inner one (they do not intersect: one inner vertex decides).
void require_enclosed(const SurfacePairSpec& spec, const SurfaceMesh& in, const SurfaceMesh& out) {
  const Eigen::Vector3d p = in.points.row(0).transpose();
  if (winding_number(out, p) > kInsideWindingNumber) return;
  const bool swapped = winding_number(in, out.points.row(0).transpose()) > kInsideWindingNumber;
  throw InputError(spec.outer_file + ": does not enclose the inner surface " + spec.inner_file + ": its vertex 0 at " +
                   values_text(in.points.row(0).data(), 3) + " lies outside" +
                   (swapped ? ", and the outer surface lies inside the inner one: inner and outer are swapped" : ""));
}

}  // namespace

double winding_number(const SurfaceMesh& s, const Eigen::Vector3d& p) {
  // Van Oosterom and Strackee's solid angle of each triangle seen from p.
  double solid = 0.0;
  for (Eigen::Index t = 0; t < s.tris.rows(); ++t) {
    const Eigen::Vector3d a = s.points.row(s.tris(t, 0)).transpose() - p, b = s.points.row(s.tris(t, 1)).transpose() - p,
                          c = s.points.row(s.tris(t, 2)).transpose() - p;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    solid += 2.0 * std::atan2(a.dot(b.cross(c)), la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la);
  }
  return solid / (4.0 * kPi);
}

SurfacePair mesh_surface_pair(const SurfacePairSpec& spec) {
  // Each surface read and checked on its own, then both together.
  const auto t0 = Clock::now();
  SurfaceMesh in = read_closed_surface(spec.inner_file, spec.metres_per_unit);
  SurfaceMesh out = read_closed_surface(spec.outer_file, spec.metres_per_unit);
  SurfacePair pair;
  pair.inner_triangles = static_cast<int>(in.tris.rows());
  pair.outer_triangles = static_cast<int>(out.tris.rows());
  // The resolution the scene asks for: both surfaces remeshed to the target edge, then checked as read ones are.
  if (spec.target_edge > 0.0) {
    const auto tr = Clock::now();
    const std::string target = length_in_units(spec.target_edge, spec.metres_per_unit);
    in = remesh_surface(in, spec.target_edge, spec.inner_file, target);
    out = remesh_surface(out, spec.target_edge, spec.outer_file, target);
    pair.remesh_ms = ms_since(tr);
  }
  require_no_intersections(spec, in, out);
  require_enclosed(spec, in, out);
  pair.check_ms = ms_since(t0) - pair.remesh_ms;
  // The volume between them.
  try {
    physics::PairMesh m = physics::tetrahedralise_pair(in.points, in.tris, out.points, out.tris, spec.options);
    pair.mesh = std::move(m.mesh);
    pair.added_nodes = m.added_nodes;
    pair.mesher_ms = m.mesher_ms;
    pair.mesher = m.mesher;
    pair.gmsh_failure = std::move(m.gmsh_failure);
  } catch (const physics::PairMesherError& e) {
    throw InputError(spec.inner_file + " and " + spec.outer_file + ": " + e.what());
  }
  return pair;
}

}  // namespace lumen::engine
