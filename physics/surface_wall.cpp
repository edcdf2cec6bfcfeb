// Vertex normals and the prism wall between a closed surface and its offset.
#include "physics/surface_wall.hpp"

#include <algorithm>
#include <array>
#include <string>

#include <Eigen/Geometry>

#include "physics/detail/messages.hpp"

namespace lumen::physics {

namespace {

// The three tets of a prism over bottom vertices (a, b, c) (a < b < c) and their copies one layer up, as
// (corner, layer) pairs: layer 0 is the bottom. See make_prism_wall.
constexpr int kPrismTets[3][4][2] = {{{0, 0}, {1, 0}, {2, 0}, {2, 1}},
                                     {{0, 0}, {1, 0}, {2, 1}, {1, 1}},
                                     {{0, 0}, {0, 1}, {1, 1}, {2, 1}}};

}  // namespace

Points vertex_normals(const Points& x, const Tris& tris) {
  Points n = Points::Zero(x.rows(), 3);
  for (Eigen::Index t = 0; t < tris.rows(); ++t) {
    const Eigen::RowVector3d a = x.row(tris(t, 0)), b = x.row(tris(t, 1)), c = x.row(tris(t, 2));
    const Eigen::RowVector3d area = (b - a).cross(c - a);
    for (int j = 0; j < 3; ++j) n.row(tris(t, j)) += area;
  }
  for (Eigen::Index v = 0; v < n.rows(); ++v)
    if (n.row(v).norm() > 0.0) n.row(v).normalize();
  return n;
}

Points smooth_normals(const Points& normals, const Tris& tris, int rounds) {
  Points n = normals;
  for (int r = 0; r < rounds; ++r) {
    // Each triangle side adds either end's normal to the other (an edge shared by two triangles twice: the
    // weight is the same for every edge of a closed surface).
    Points sum = n;
    for (Eigen::Index t = 0; t < tris.rows(); ++t)
      for (int j = 0; j < 3; ++j) {
        const int a = tris(t, j), b = tris(t, (j + 1) % 3);
        sum.row(a) += n.row(b);
        sum.row(b) += n.row(a);
      }
    for (Eigen::Index v = 0; v < sum.rows(); ++v)
      if (sum.row(v).norm() > 0.0) sum.row(v).normalize();
    n = std::move(sum);
  }
  return n;
}

TetMesh make_prism_wall(const Points& inner, const Points& outer, const Tris& tris, int layers) {
  const Eigen::Index nv = inner.rows();
  if (outer.rows() != nv) detail::fail_value("make_prism_wall: outer must have one row per inner vertex (" + std::to_string(nv) + "), rows", "differ", outer.rows());
  if (layers < 1) detail::fail_value("make_prism_wall: layers", "must be >= 1", layers);
  if (tris.rows() > 0 && (tris.minCoeff() < 0 || tris.maxCoeff() >= nv))
    detail::fail("make_prism_wall: a triangle names a vertex outside [0, " + std::to_string(nv) + ")");
  TetMesh m;
  m.rest.resize(nv * (layers + 1), 3);
  for (int k = 0; k <= layers; ++k)
    m.rest.middleRows(k * nv, nv) = inner + (outer - inner) * (static_cast<double>(k) / layers);
  m.tets.resize(3 * layers * tris.rows(), 4);
  Eigen::Index row = 0;
  for (Eigen::Index t = 0; t < tris.rows(); ++t) {
    // The corners by vertex id; an odd permutation of the triangle's order flips the tets' orientation.
    std::array<int, 3> v = {tris(t, 0), tris(t, 1), tris(t, 2)};
    const bool odd = ((v[0] > v[1]) + (v[0] > v[2]) + (v[1] > v[2])) % 2 == 1;  // inversions
    std::sort(v.begin(), v.end());
    for (int k = 0; k < layers; ++k)
      for (const auto& tet : kPrismTets) {
        for (int c = 0; c < 4; ++c) m.tets(row, c) = static_cast<int>((k + tet[c][1]) * nv + v[static_cast<size_t>(tet[c][0])]);
        if (odd) std::swap(m.tets(row, 0), m.tets(row, 1));
        ++row;
      }
  }
  // The walls: layer 0 reversed (normals out of the wall, into what it encloses), the last layer as given.
  Tris in = tris, out = tris.array() + static_cast<int>(layers * nv);
  in.col(1).swap(in.col(2));
  m.surfaces = {{kInnerWall, in}, {kOuterWall, out}, {kEndCaps, Tris(0, 3)}};
  return m;
}

}  // namespace lumen::physics
