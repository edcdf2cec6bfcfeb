#include "physics/volume_mesh.hpp"
#include "physics/detail/messages.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <map>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

#include "physics/mesh_quality.hpp"

namespace lumen::physics {
namespace {

using Face = std::array<int, 3>;
using Edge = std::pair<int, int>;  // (low, high) node ids

using detail::fail;  // "<file>: <where>: <problem>"

Face sorted(Face f) {
  std::sort(f.begin(), f.end());
  return f;
}
Edge edge(int a, int b) { return {std::min(a, b), std::max(a, b)}; }

// The outward faces of a positive tet (a, b, c, d): (a, b, c) faces d, so each face is taken reversed.
constexpr int kOutwardFace[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};

Face face_of(const Tris& tris, int t) { return {tris(t, 0), tris(t, 1), tris(t, 2)}; }

Tris to_tris(const std::vector<Face>& faces) {
  Tris t(static_cast<Eigen::Index>(faces.size()), 3);
  for (size_t i = 0; i < faces.size(); ++i)
    for (int k = 0; k < 3; ++k) t(static_cast<Eigen::Index>(i), k) = faces[i][k];
  return t;
}

Eigen::Vector3d at(const Points& x, int v) { return x.row(v).transpose(); }

// Signed volume the cone from the origin over a triangle adds to a closed surface's enclosed volume.
double cone_volume(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  return a.dot(b.cross(c)) / 6.0;
}

// The faces of a surface connected through shared edges (`joins(f, g)` says whether two faces across an edge
// join), as lists of face indices. Every edge must have exactly two faces (a manifold closed surface).
template <class Joins>
std::vector<std::vector<int>> connected_faces(const std::vector<Face>& faces, const std::string& file, Joins joins) {
  std::map<Edge, std::vector<int>> faces_of;
  for (size_t f = 0; f < faces.size(); ++f)
    for (int k = 0; k < 3; ++k) faces_of[edge(faces[f][k], faces[f][(k + 1) % 3])].push_back(static_cast<int>(f));
  for (const auto& [e, list] : faces_of)
    if (list.size() != 2)
      fail(file, "boundary edge (nodes " + std::to_string(e.first) + ", " + std::to_string(e.second) +
                     "; 0-based, in the file's order of the nodes the tets use)",
           "has " + std::to_string(list.size()) + " boundary faces: the boundary is not a manifold surface");
  std::vector<int> component(faces.size(), -1);
  std::vector<std::vector<int>> out;
  for (size_t seed = 0; seed < faces.size(); ++seed) {
    if (component[seed] >= 0) continue;
    out.emplace_back();
    std::vector<int> stack{static_cast<int>(seed)};
    component[seed] = static_cast<int>(out.size()) - 1;
    while (!stack.empty()) {
      const int f = stack.back();
      stack.pop_back();
      out.back().push_back(f);
      for (int k = 0; k < 3; ++k)
        for (int g : faces_of[edge(faces[f][k], faces[f][(k + 1) % 3])])
          if (component[g] < 0 && joins(f, g)) {
            component[g] = component[f];
            stack.push_back(g);
          }
    }
  }
  return out;
}

// Enclosed volume of a patch by its normals, its open rims closed by fans to each rim loop's centroid.
double closed_volume(const std::vector<Face>& faces, const std::vector<int>& patch, const Points& x) {
  std::map<Edge, int> uses;
  for (int f : patch)
    for (int k = 0; k < 3; ++k) ++uses[edge(faces[f][k], faces[f][(k + 1) % 3])];
  // Rim edges, directed as their face runs them: the next rim node after each.
  std::unordered_map<int, int> next;
  double v = 0.0;
  for (int f : patch) {
    v += cone_volume(at(x, faces[f][0]), at(x, faces[f][1]), at(x, faces[f][2]));
    for (int k = 0; k < 3; ++k)
      if (uses[edge(faces[f][k], faces[f][(k + 1) % 3])] == 1) next[faces[f][k]] = faces[f][(k + 1) % 3];
  }
  // Each rim loop closed by the fan (b, a, centroid) over its edges a -> b.
  while (!next.empty()) {
    std::vector<int> loop{next.begin()->first};
    while (next.count(loop.back()) && next.at(loop.back()) != loop.front() && loop.size() <= next.size())
      loop.push_back(next.at(loop.back()));
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int a : loop) c += at(x, a);
    c /= static_cast<double>(loop.size());
    for (int a : loop) {
      const auto it = next.find(a);
      if (it == next.end()) continue;
      v += cone_volume(at(x, it->second), at(x, a), c);
      next.erase(it);
    }
  }
  return v;
}

Eigen::Vector3d unit_normal(const Face& f, const Points& x) {
  return (at(x, f[1]) - at(x, f[0])).cross(at(x, f[2]) - at(x, f[0])).normalized();
}

// The walls found on the boundary (make_volume_mesh): per boundary face 0 inner, 1 outer, 2 end cap.
std::vector<int> find_walls(const std::vector<Face>& faces, const Points& x, const std::string& file) {
  const auto components = connected_faces(faces, file, [](int, int) { return true; });
  std::vector<std::vector<int>> patches = components;
  std::vector<double> volume;
  if (components.size() == 1) {
    // An open tube: patches split at the rims.
    const double cos_feature = std::cos(kFeatureAngleDeg * kPi / 180.0);
    patches = connected_faces(faces, file, [&](int f, int g) {
      return unit_normal(faces[f], x).dot(unit_normal(faces[g], x)) >= cos_feature;
    });
  } else if (components.size() != 2) {
    fail(file, "boundary", "has " + std::to_string(components.size()) +
                               " connected components: expected 2 closed ones (a hollow organ's inner and outer "
                               "wall) or 1 (an open tube); give mesh.inner_tag and mesh.outer_tag");
  }
  for (const auto& p : patches) volume.push_back(closed_volume(faces, p, x));
  const size_t inner = static_cast<size_t>(std::min_element(volume.begin(), volume.end()) - volume.begin());
  const size_t outer = static_cast<size_t>(std::max_element(volume.begin(), volume.end()) - volume.begin());
  if (!(volume[inner] < 0.0 && volume[outer] > 0.0) || (components.size() == 2 && volume[1 - inner] < 0.0)) {
    std::ostringstream msg;
    msg << "has " << components.size() << " component(s) and " << patches.size()
        << " patch(es) between edges sharper than " << kFeatureAngleDeg
        << " degrees, and no pair of them encloses the other (a wall facing the lumen inside an outer wall); give "
           "mesh.inner_tag and mesh.outer_tag";
    fail(file, "boundary", msg.str());
  }
  std::vector<int> role(faces.size(), 2);
  for (int f : patches[inner]) role[static_cast<size_t>(f)] = 0;
  for (int f : patches[outer]) role[static_cast<size_t>(f)] = 1;
  return role;
}

// The walls from the file's tagged triangles (make_volume_mesh), in the file's order, into walls[0] (inner) and
// walls[1] (outer); per boundary face 0 inner, 1 outer, 2 end cap.
std::vector<int> tagged_walls(const std::vector<Face>& faces, const VolumeMeshFile& f, const std::vector<int>& row,
                              const WallTags& tags, std::array<std::vector<Face>, 3>& walls) {
  std::map<Face, int> boundary;
  for (size_t i = 0; i < faces.size(); ++i) boundary[sorted(faces[i])] = static_cast<int>(i);
  std::vector<int> role(faces.size(), 2);
  for (int t = 0; t < f.triangles.rows(); ++t) {
    const int tag = f.triangle_tags[static_cast<size_t>(t)];
    if (tag != tags.inner && tag != tags.outer) continue;
    const int wall = tag == tags.inner ? 0 : 1;
    const Face file_face = face_of(f.triangles, t);
    Face face{row[file_face[0]], row[file_face[1]], row[file_face[2]]};
    const auto it = face[0] < 0 || face[1] < 0 || face[2] < 0 ? boundary.end() : boundary.find(sorted(face));
    if (it == boundary.end())
      fail(f.file, "triangle " + std::to_string(t) + " (tag " + std::to_string(tag) + ")",
           "is not a boundary face of the tets");
    if (role[static_cast<size_t>(it->second)] != 2) continue;  // listed twice
    // Kept in the file's order when it faces out as the tet's face does (a rotation of it), else reversed.
    const Face& out = faces[static_cast<size_t>(it->second)];
    const int r = static_cast<int>(std::find(out.begin(), out.end(), face[0]) - out.begin());
    if (out[(r + 1) % 3] != face[1]) std::swap(face[1], face[2]);
    role[static_cast<size_t>(it->second)] = wall;
    walls[wall].push_back(face);
  }
  for (int w = 0; w < 2; ++w) {
    if (!walls[w].empty()) continue;
    std::vector<int> have;
    for (int tag : f.triangle_tags)
      if (tag != kNoTag && std::find(have.begin(), have.end(), tag) == have.end()) have.push_back(tag);
    std::string list;
    for (int tag : have) list += (list.empty() ? "" : ", ") + std::to_string(tag);
    fail(f.file, w == 0 ? "mesh.inner_tag" : "mesh.outer_tag",
         "no triangle has tag " + std::to_string(w == 0 ? tags.inner : tags.outer) + " (triangle tags in the file: " +
             (list.empty() ? std::string("none") : list) + ")");
  }
  return role;
}

// The end node sets: the end caps' nodes in vertex-connected pieces, when there are exactly two.
void add_end_sets(const Tris& ends, int n_nodes, TetMesh& mesh) {
  std::vector<int> parent(static_cast<size_t>(n_nodes));
  std::iota(parent.begin(), parent.end(), 0);
  auto root = [&](int v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for (int t = 0; t < ends.rows(); ++t)
    for (int k = 1; k < 3; ++k) parent[root(ends(t, k))] = root(ends(t, 0));
  std::vector<bool> on_end(static_cast<size_t>(n_nodes), false);
  for (int t = 0; t < ends.rows(); ++t)
    for (int k = 0; k < 3; ++k) on_end[ends(t, k)] = true;
  std::map<int, std::vector<int>> pieces;  // by root; each piece's nodes ascending
  std::vector<int> order;                  // roots by their lowest node
  for (int v = 0; v < n_nodes; ++v)
    if (on_end[v]) {
      auto& piece = pieces[root(v)];
      if (piece.empty()) order.push_back(root(v));
      piece.push_back(v);
    }
  if (pieces.size() != 2) return;
  mesh.node_sets.push_back({kStartEnd, pieces[order[0]]});
  mesh.node_sets.push_back({kStopEnd, pieces[order[1]]});
}

}  // namespace

Tris boundary_faces(const Tets& tets) {
  std::map<Face, int> count;
  for (int t = 0; t < tets.rows(); ++t)
    for (const auto& lf : kOutwardFace) ++count[sorted({tets(t, lf[0]), tets(t, lf[1]), tets(t, lf[2])})];
  std::vector<Face> faces;
  for (int t = 0; t < tets.rows(); ++t)
    for (const auto& lf : kOutwardFace) {
      const Face f{tets(t, lf[0]), tets(t, lf[1]), tets(t, lf[2])};
      if (count[sorted(f)] == 1) faces.push_back(f);
    }
  return to_tris(faces);
}

TetMesh make_volume_mesh(const VolumeMeshFile& f, double metres_per_unit, const WallTags& tags) {
  assert(f.tets.rows() > 0 && static_cast<size_t>(f.tets.rows()) == f.tet_ids.size());
  // The nodes the tets use, in the file's order (row[file row] = mesh node, -1 when unused).
  std::vector<int> row(static_cast<size_t>(f.nodes.rows()), -1);
  for (int t = 0; t < f.tets.rows(); ++t)
    for (int k = 0; k < 4; ++k) row[static_cast<size_t>(f.tets(t, k))] = 0;
  TetMesh mesh;
  int n = 0;
  for (int& r : row)
    if (r == 0) r = n++;
  mesh.rest.resize(n, 3);
  for (int v = 0; v < f.nodes.rows(); ++v)
    if (row[v] >= 0) mesh.rest.row(row[v]) = metres_per_unit * f.nodes.row(v);
  mesh.tets.resize(f.tets.rows(), 4);
  for (int t = 0; t < f.tets.rows(); ++t)
    for (int k = 0; k < 4; ++k) mesh.tets(t, k) = row[static_cast<size_t>(f.tets(t, k))];
  // Inverted or degenerate tets refused (their faces' orientation is derived from positive tets).
  const MeshQuality q = mesh_quality(mesh.rest, mesh.tets);
  if (q.first_degenerate >= 0) {
    std::ostringstream msg;
    msg << "is inverted or has zero volume (signed volume " << tet_volume(mesh.rest, mesh.tets, q.first_degenerate)
        << " m^3); " << q.degenerate_tets << " such tets of " << q.tets;
    fail(f.file, "tet " + std::to_string(q.first_degenerate) + " (element " +
                     std::to_string(f.tet_ids[static_cast<size_t>(q.first_degenerate)]) + " of the file)", msg.str());
  }
  // The boundary, split into walls and end caps.
  const Tris boundary = boundary_faces(mesh.tets);
  std::vector<Face> faces(static_cast<size_t>(boundary.rows()));
  for (int t = 0; t < boundary.rows(); ++t) faces[static_cast<size_t>(t)] = face_of(boundary, t);
  std::array<std::vector<Face>, 3> parts;  // inner, outer, end caps
  const std::vector<int> role =
      tags.given ? tagged_walls(faces, f, row, tags, parts) : find_walls(faces, mesh.rest, f.file);
  for (size_t i = 0; i < faces.size(); ++i)
    if (!tags.given || role[i] == 2) parts[static_cast<size_t>(role[i])].push_back(faces[i]);
  mesh.surfaces = {{kInnerWall, to_tris(parts[0])}, {kOuterWall, to_tris(parts[1])}, {kEndCaps, to_tris(parts[2])}};
  add_end_sets(mesh.surfaces[2].tris, n, mesh);
  return mesh;
}

}  // namespace lumen::physics
