// Structured tube tet mesh (shared by the generated tubes), the hollow-cylinder generator and tet volume.
#include "physics/mesh.hpp"

#include "physics/detail/messages.hpp"

#include <algorithm>
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
    if (!(s.length / s.bend_radius < kTwoPi))
      fail_spec("bend_radius", "must make the arc angle length / bend_radius < 2 pi", s.bend_radius);
  }
}

}  // namespace

TetMesh make_structured_tube(const std::vector<TubeRing>& rings, int segments_around, int layers,
                             const std::vector<double>& angles) {
  if (rings.size() < 2) detail::fail_value("make_structured_tube: rings", "must number at least 2", rings.size());
  if (segments_around < 3) detail::fail_value("make_structured_tube: segments_around", "must be >= 3", segments_around);
  if (layers < 1) detail::fail_value("make_structured_tube: layers", "must be >= 1", layers);
  // Given angles: one per step around, increasing in [0, 2 pi).
  if (!angles.empty()) {
    if (static_cast<int>(angles.size()) != segments_around)
      detail::fail_value("make_structured_tube: angles.size()", "must equal segments_around", angles.size());
    for (int i = 0; i < segments_around; ++i)
      if (!(angles[i] >= 0.0 && angles[i] < kTwoPi && (i == 0 || angles[i] > angles[i - 1])))
        detail::fail_value("make_structured_tube: angles[" + std::to_string(i) + "]",
                           "must increase within [0, 2 pi)", angles[i]);
  }
  const int na = segments_around;                        // cells around (periodic)
  const int nl = static_cast<int>(rings.size()) - 1;     // cells along
  const int nr = layers;                                 // cells through the wall
  const int n_nodes = na * (nl + 1) * (nr + 1);
  // Node id of grid point (i around, j along, k layer); i is taken modulo na.
  auto node = [&](int i, int j, int k) { return structured_tube_node(na, nr, i % na, j, k); };

  TetMesh mesh;
  mesh.rest.resize(n_nodes, 3);

  // Node positions: ring j at radius r, angle theta in its local frame (e1, e2) = (normal, binormal).
  for (int j = 0; j <= nl; ++j) {
    const TubeRing& ring = rings[j];
    for (int k = 0; k <= nr; ++k) {
      const double r = ring.inner_radius + (ring.outer_radius - ring.inner_radius) * k / nr;
      for (int i = 0; i < na; ++i) {
        const double theta = angles.empty() ? kTwoPi * i / na : angles[i];
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
  // Rings at the grid's arc lengths along the centreline (equal steps unless graded), all with the spec's radii.
  const CylinderGrid grid = hollow_cylinder_grid(spec);
  std::vector<TubeRing> rings(spec.segments_along + 1);
  for (int j = 0; j <= spec.segments_along; ++j)
    rings[j] = {hollow_cylinder_frame(spec, grid.arc[j]), spec.inner_radius, spec.outer_radius};
  // Angles: the grid's (uniform, it is the same 2 pi i / around as make_structured_tube's default), without 2 pi.
  const std::vector<double> angles(grid.angle.begin(), grid.angle.end() - 1);
  return make_structured_tube(rings, spec.segments_around, spec.layers, angles);
}

CylinderGrid hollow_cylinder_grid(const HollowCylinderSpec& spec) {
  return {graded_grid(spec.grading_around, kTwoPi, spec.segments_around, true, "HollowCylinderSpec.grading_around"),
          graded_grid(spec.grading_along, spec.length, spec.segments_along, false, "HollowCylinderSpec.grading_along")};
}

std::vector<double> graded_grid(const CellGrading& grading, double extent, int cells, bool periodic,
                                const char* what) {
  const std::string w(what);
  // Validate the interval, the ratio and the foci.
  if (cells < 1) detail::fail_value(w + ": cells", "must be >= 1", cells);
  if (!(extent > 0.0) || !std::isfinite(extent)) detail::fail_value(w + ": extent", "must be > 0 and finite", extent);
  if (!(grading.ratio >= 1.0 && grading.ratio <= kMaxGradingRatio))
    detail::fail_value(w + ".ratio", "must be in [1, 100]", grading.ratio);
  std::vector<double> grid(cells + 1);
  // Uniform: the plain formula (the same numbers as an ungraded mesh).
  if (grading.ratio == 1.0) {
    for (int i = 0; i <= cells; ++i) grid[i] = extent * i / cells;
    return grid;
  }
  if (grading.focus.empty()) detail::fail_value(w + ".focus", "must hold at least one point when ratio > 1", 0);
  for (size_t f = 0; f < grading.focus.size(); ++f) {
    const double x = grading.focus[f];
    if (!std::isfinite(x) || (!periodic && (x < 0.0 || x > extent)))
      detail::fail_value(w + ".focus[" + std::to_string(f) + "]",
                         periodic ? "must be finite" : "must be within [0, length]", x);
  }
  // Foci in [0, extent) when periodic (an angle taken modulo a turn).
  std::vector<double> focus = grading.focus;
  if (periodic)
    for (double& f : focus) f -= extent * std::floor(f / extent);
  // Distance of every sample to its nearest focus (wrapping around when periodic), and the largest one.
  const int n = kGradingSamples * cells;
  std::vector<double> d(n + 1);
  double d_max = 0.0;
  for (int k = 0; k <= n; ++k) {
    const double x = extent * k / n;
    double best = extent;
    for (double f : focus) {
      double dist = std::abs(x - f);
      if (periodic) dist = std::min(dist, extent - dist);
      best = std::min(best, dist);
    }
    d[k] = best;
    d_max = std::max(d_max, best);
  }
  // Cumulative density 1 / h (trapezoid rule); grid point i where it reaches i / cells of its total.
  std::vector<double> cumulative(n + 1, 0.0);
  auto density = [&](int k) { return std::pow(grading.ratio, -d[k] / d_max); };
  for (int k = 1; k <= n; ++k) cumulative[k] = cumulative[k - 1] + 0.5 * (density(k - 1) + density(k)) * extent / n;
  grid[0] = 0.0;
  grid[cells] = extent;
  int k = 0;
  for (int i = 1; i < cells; ++i) {
    const double target = cumulative[n] * i / cells;
    while (cumulative[k + 1] < target) ++k;
    const double t = (target - cumulative[k]) / (cumulative[k + 1] - cumulative[k]);
    grid[i] = extent * (k + t) / n;
  }
  return grid;
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
