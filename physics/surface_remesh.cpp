#include "physics/surface_remesh.hpp"

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/detect_features.h>
#include <CGAL/Polygon_mesh_processing/remesh.h>
#include <CGAL/Surface_mesh.h>

#include "physics/detail/messages.hpp"

namespace lumen::physics {

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using CgalMesh = CGAL::Surface_mesh<Kernel::Point_3>;

// The input as a CGAL surface mesh; refuses a triangle that would make it non-manifold, and a surface with a
// border (not closed).
CgalMesh to_cgal(const Points& x, const Tris& tris) {
  CgalMesh m;
  std::vector<CgalMesh::Vertex_index> v(static_cast<size_t>(x.rows()));
  for (Eigen::Index i = 0; i < x.rows(); ++i) v[i] = m.add_vertex(Kernel::Point_3(x(i, 0), x(i, 1), x(i, 2)));
  for (Eigen::Index t = 0; t < tris.rows(); ++t) {
    if (m.add_face(v[tris(t, 0)], v[tris(t, 1)], v[tris(t, 2)]) == CgalMesh::null_face())
      detail::fail("remesh_isotropic: triangle " + std::to_string(t) +
                   " makes the surface non-manifold or runs against its neighbours");
  }
  for (CgalMesh::Halfedge_index h : m.halfedges())
    if (m.is_border(h))
      detail::fail("remesh_isotropic: the surface is not closed (a border edge at vertex " +
                   std::to_string(static_cast<int>(m.target(h))) + ")");
  return m;
}

}  // namespace

double remesh_triangle_estimate(const Points& x, const Tris& tris, double target_edge) {
  double area = 0.0;
  for (Eigen::Index t = 0; t < tris.rows(); ++t) {
    const Eigen::Vector3d a = x.row(tris(t, 0)), b = x.row(tris(t, 1)), c = x.row(tris(t, 2));
    area += 0.5 * (b - a).cross(c - a).norm();
  }
  return area / (std::sqrt(3.0) / 4.0 * target_edge * target_edge);
}

RemeshedSurface remesh_isotropic(const Points& x, const Tris& tris, double target_edge) {
  if (!(target_edge > 0.0) || !std::isfinite(target_edge))
    detail::fail_must("remesh_isotropic", "the target edge", "be > 0 and finite", target_edge);
  if (tris.rows() > 0 && (tris.minCoeff() < 0 || tris.maxCoeff() >= x.rows()))
    detail::fail("remesh_isotropic: a triangle names a vertex outside the surface's " + std::to_string(x.rows()));
  // The output's size, estimated before any work.
  const double estimate = remesh_triangle_estimate(x, tris, target_edge);
  if (!(estimate <= kRemeshMaxTriangles))
    detail::fail("remesh_isotropic: a target edge of " + detail::num(target_edge) + " would make about " +
                 detail::num(estimate) + " triangles (at most " + detail::num(kRemeshMaxTriangles) + ")");
  CgalMesh m = to_cgal(x, tris);
  try {
    // Creases sharper than kRemeshCreaseDeg stay where they are: their edges are split and collapsed only along
    // the crease (a flat cap's rim stays a rim instead of being cut by triangles across it).
    auto crease = m.add_property_map<CgalMesh::Edge_index, bool>("e:crease", false).first;
    CGAL::Polygon_mesh_processing::detect_sharp_edges(m, kRemeshCreaseDeg, crease);
    CGAL::Polygon_mesh_processing::isotropic_remeshing(
        faces(m), target_edge, m,
        CGAL::parameters::number_of_iterations(kRemeshIterations).edge_is_constrained_map(crease));
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string("remesh_isotropic: CGAL failed: ") + e.what());
  }
  m.collect_garbage();
  // Back to flat arrays (vertex ids are contiguous after the garbage collection).
  RemeshedSurface out;
  out.points.resize(static_cast<Eigen::Index>(m.number_of_vertices()), 3);
  for (CgalMesh::Vertex_index v : m.vertices()) {
    const Kernel::Point_3& p = m.point(v);
    out.points.row(static_cast<int>(v)) << p.x(), p.y(), p.z();
  }
  out.tris.resize(static_cast<Eigen::Index>(m.number_of_faces()), 3);
  int row = 0;
  for (CgalMesh::Face_index f : m.faces()) {
    int k = 0;
    for (CgalMesh::Vertex_index v : CGAL::vertices_around_face(m.halfedge(f), m)) out.tris(row, k++) = static_cast<int>(v);
    if (k != 3) throw std::runtime_error("remesh_isotropic: CGAL returned a face that is not a triangle");
    ++row;
  }
  return out;
}

}  // namespace lumen::physics
