// Structured tube tet mesh (shared by the generated tubes), the hollow-cylinder generator and tet volume.
#include "physics/mesh.hpp"

#include "physics/detail/messages.hpp"

#include <utility>

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace lumen::physics {

namespace {

// Throws std::invalid_argument "HollowCylinderSpec.<field> <rule>, got <value>".
template <typename T>
[[noreturn]] void fail_spec(const char* field, const char* rule, T value) {
  detail::fail_value(std::string("HollowCylinderSpec.") + field, rule, value);
}

void validate(const HollowCylinderSpec& s) {
  // Radii and length: positive and finite, inner < outer.
  if (!(s.inner_radius > 0.0) || !std::isfinite(s.inner_radius))
    fail_spec("inner_radius", "must be > 0 and finite", s.inner_radius);
  if (!(s.outer_radius > 0.0) || !std::isfinite(s.outer_radius))
    fail_spec("outer_radius", "must be > 0 and finite", s.outer_radius);
  if (!(s.inner_radius < s.outer_radius)) fail_spec("inner_radius", "must be < outer_radius", s.inner_radius);
  if (!(s.length > 0.0) || !std::isfinite(s.length)) fail_spec("length", "must be > 0 and finite", s.length);
  // Cell counts.
  if (s.segments_around < 3) fail_spec("segments_around", "must be >= 3", s.segments_around);
  if (s.segments_along < 1) fail_spec("segments_along", "must be >= 1", s.segments_along);
  if (s.layers < 1) fail_spec("layers", "must be >= 1", s.layers);
  // Bend: 0 (straight) or a radius larger than the tube, and an arc shorter than a full turn.
  if (s.bend_radius != 0.0) {
    if (!(s.bend_radius > s.outer_radius) || !std::isfinite(s.bend_radius))
      fail_spec("bend_radius", "must be 0 (straight) or finite and > outer_radius", s.bend_radius);
    if (!(s.length / s.bend_radius < 2.0 * static_cast<double>(EIGEN_PI)))
      fail_spec("bend_radius", "must make the arc angle length / bend_radius < 2 pi", s.bend_radius);
  }
}

}  // namespace

TetMesh make_structured_tube(const std::vector<TubeRing>& rings, int segments_around, int layers) {
  if (rings.size() < 2) detail::fail_value("make_structured_tube: rings", "must number at least 2", rings.size());
  if (segments_around < 3) detail::fail_value("make_structured_tube: segments_around", "must be >= 3", segments_around);
  if (layers < 1) detail::fail_value("make_structured_tube: layers", "must be >= 1", layers);
  const int na = segments_around;                        // cells around (periodic)
  const int nl = static_cast<int>(rings.size()) - 1;     // cells along
  const int nr = layers;                                 // cells through the wall
  const int n_nodes = na * (nl + 1) * (nr + 1);
  // Node id of grid point (i around, j along, k layer); i is taken modulo na.
  auto node = [&](int i, int j, int k) { return (j * (nr + 1) + k) * na + (i % na); };

  TetMesh mesh;
  mesh.rest.resize(n_nodes, 3);

  // Node positions: ring j at radius r, angle theta in its local frame (e1, e2) = (normal, binormal).
  for (int j = 0; j <= nl; ++j) {
    const TubeRing& ring = rings[j];
    for (int k = 0; k <= nr; ++k) {
      const double r = ring.inner_radius + (ring.outer_radius - ring.inner_radius) * k / nr;
      for (int i = 0; i < na; ++i) {
        const double theta = 2.0 * static_cast<double>(EIGEN_PI) * i / na;
        mesh.rest.row(node(i, j, k)) = ring_point(ring.frame, r, theta).transpose();
      }
    }
  }

  // Tets: Kuhn split of each hex cell along its (0,0,0)-(1,1,1) diagonal in local (around, along, layer) axes.
  // Every cell uses the same split, so shared faces carry the same diagonal (conforming, also across the seam).
  // The local axes (theta, z, r) form a right-handed frame, so a tet from an even axis permutation is positive;
  // odd permutations swap their last two vertices.
  static const int kPerm[6][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {0, 2, 1}, {2, 1, 0}, {1, 0, 2}};
  mesh.tets.resize(6 * na * nl * nr, 4);
  int t = 0;
  for (int j = 0; j < nl; ++j)
    for (int k = 0; k < nr; ++k)
      for (int i = 0; i < na; ++i)
        for (int p = 0; p < 6; ++p) {
          int a[3] = {i, j, k};
          int v[4];
          v[0] = node(a[0], a[1], a[2]);
          for (int q = 0; q < 3; ++q) {
            ++a[kPerm[p][q]];
            v[q + 1] = node(a[0], a[1], a[2]);
          }
          if (p >= 3) std::swap(v[2], v[3]);
          mesh.tets.row(t++) << v[0], v[1], v[2], v[3];
        }

  // Inner (k = 0) and outer (k = nr) walls: each quad split on its (i, j)-(i+1, j+1) diagonal like the tets.
  // (p00, p10, p11) has normal along +r, so the inner wall reverses it to point into the lumen.
  Tris inner(2 * na * nl, 3), outer(2 * na * nl, 3);
  int f = 0;
  for (int j = 0; j < nl; ++j)
    for (int i = 0; i < na; ++i) {
      inner.row(f) << node(i, j, 0), node(i + 1, j + 1, 0), node(i + 1, j, 0);
      inner.row(f + 1) << node(i, j, 0), node(i, j + 1, 0), node(i + 1, j + 1, 0);
      outer.row(f) << node(i, j, nr), node(i + 1, j, nr), node(i + 1, j + 1, nr);
      outer.row(f + 1) << node(i, j, nr), node(i + 1, j + 1, nr), node(i, j + 1, nr);
      f += 2;
    }

  // End caps: quads in (i, k) split on the (i, k)-(i+1, k+1) diagonal. (p00, p10, p11) has normal along -z,
  // which is outward at the start end; the stop end reverses it.
  Tris ends(4 * na * nr, 3);
  f = 0;
  for (int k = 0; k < nr; ++k)
    for (int i = 0; i < na; ++i) {
      ends.row(f++) << node(i, 0, k), node(i + 1, 0, k), node(i + 1, 0, k + 1);
      ends.row(f++) << node(i, 0, k), node(i + 1, 0, k + 1), node(i, 0, k + 1);
      ends.row(f++) << node(i, nl, k), node(i + 1, nl, k + 1), node(i + 1, nl, k);
      ends.row(f++) << node(i, nl, k), node(i, nl, k + 1), node(i + 1, nl, k + 1);
    }
  mesh.surfaces = {{kInnerWall, std::move(inner)}, {kOuterWall, std::move(outer)}, {kEndCaps, std::move(ends)}};

  // End node sets: every node of the first and last ring of cells.
  NodeSet start{kStartEnd, {}}, stop{kStopEnd, {}};
  for (int k = 0; k <= nr; ++k)
    for (int i = 0; i < na; ++i) {
      start.nodes.push_back(node(i, 0, k));
      stop.nodes.push_back(node(i, nl, k));
    }
  mesh.node_sets = {std::move(start), std::move(stop)};
  return mesh;
}

TetMesh make_hollow_cylinder(const HollowCylinderSpec& spec) {
  validate(spec);
  // Rings at equal arc-length steps along the centreline, all with the spec's radii.
  std::vector<TubeRing> rings(spec.segments_along + 1);
  for (int j = 0; j <= spec.segments_along; ++j)
    rings[j] = {hollow_cylinder_frame(spec, spec.length * j / spec.segments_along), spec.inner_radius,
                spec.outer_radius};
  return make_structured_tube(rings, spec.segments_around, spec.layers);
}

CentrelineFrame hollow_cylinder_frame(const HollowCylinderSpec& spec, double s) {
  CentrelineFrame f{Eigen::Vector3d(0.0, 0.0, s), Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitX(),
                    Eigen::Vector3d::UnitY()};
  if (spec.bend_radius > 0.0) {
    const double R = spec.bend_radius, phi = s / R, cos_phi = std::cos(phi), sin_phi = std::sin(phi);
    f.point = Eigen::Vector3d(R - R * cos_phi, 0.0, R * sin_phi);
    f.tangent = Eigen::Vector3d(sin_phi, 0.0, cos_phi);
    f.normal = Eigen::Vector3d(cos_phi, 0.0, -sin_phi);
  }
  return f;
}

Eigen::Vector3d ring_point(const CentrelineFrame& f, double r, double theta) {
  return f.point + r * std::cos(theta) * f.normal + r * std::sin(theta) * f.binormal;
}

Eigen::Vector3d hollow_cylinder_point(const HollowCylinderSpec& spec, double s, double r, double theta) {
  // Same frame as the generator: the ring at s has local axes normal (x) and binormal (y).
  return ring_point(hollow_cylinder_frame(spec, s), r, theta);
}

double tet_volume(const Points& x, const Tets& tets, int t) {
  if (t < 0 || t >= tets.rows()) {
    throw std::invalid_argument("tet_volume: t must be in [0, " + std::to_string(tets.rows()) + "), got " +
                                std::to_string(t));
  }
  const Eigen::Vector3d x0 = x.row(tets(t, 0)).transpose();
  const Eigen::Vector3d e1 = x.row(tets(t, 1)).transpose() - x0;
  const Eigen::Vector3d e2 = x.row(tets(t, 2)).transpose() - x0;
  const Eigen::Vector3d e3 = x.row(tets(t, 3)).transpose() - x0;
  return e1.dot(e2.cross(e3)) / 6.0;
}

}  // namespace lumen::physics
