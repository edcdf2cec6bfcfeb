// Conservative per-vertex step bound: pair distances by a uniform spatial hash (or all pairs), truncation.
#include "collision/step_bound.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "collision/detail/checks.hpp"
#include "collision/distance.hpp"

namespace lumen::collision {

namespace {

using detail::check_points;

using Vec3 = Eigen::Vector3d;

constexpr double kMaxCellsPerAxis = 1 << 20;       // grid resolution limit (keeps cell keys well inside 64 bits)
constexpr std::int64_t kDenseCellsPerEntry = 16;  // a dense cell directory when cells <= 16 entries + 4096,
constexpr std::int64_t kDenseCellsMin = 4096;     // else binary search in the sorted entries

Vec3 point(const PointsRef& x, int i) { return Vec3(x(i, 0), x(i, 1), x(i, 2)); }

void check_inputs(const CollisionSurface& surface, const PointsRef& x0, const StepBoundOptions& options) {
  check_points(x0, surface.num_points(), "x0");
  if (!(options.radius > 0.0) || !std::isfinite(options.radius)) {
    std::ostringstream msg;
    msg << "StepBoundOptions.radius must be finite and > 0 metres, got " << options.radius;
    throw std::invalid_argument(msg.str());
  }
  if (!(options.fraction > 0.0 && options.fraction < 1.0)) {
    std::ostringstream msg;
    msg << "StepBoundOptions.fraction must be in (0, 1), got " << options.fraction;
    throw std::invalid_argument(msg.str());
  }
}

// The closest distance limiting each point (n_points, metres, starting at r), lowered pair by pair; the same
// pair visited twice or a pair farther than r changes nothing, so any superset of the pairs within r gives the
// same result (the hash and the brute force agree bit for bit).
class PairDistances {
 public:
  PairDistances(const CollisionSurface& s, const PointsRef& x0, double r)
      : s_(s), x_(x0), d_(Eigen::VectorXd::Constant(s.num_points(), r)) {}

  // Vertex p against triangle t (skipped when p is one of its vertices).
  void vertex_face(int p, int t) {
    const int* f = s_.triangle(t);
    if (f[0] == p || f[1] == p || f[2] == p) return;
    const double d = point_triangle_distance(point(x_, p), point(x_, f[0]), point(x_, f[1]), point(x_, f[2]));
    lower({p, f[0], f[1], f[2]}, d);
  }

  // Edge e against edge g (skipped when they share a vertex).
  void edge_edge(int e, int g) {
    const int* a = s_.edge(e);
    const int* b = s_.edge(g);
    if (a[0] == b[0] || a[0] == b[1] || a[1] == b[0] || a[1] == b[1]) return;
    const double d = segment_segment_distance(point(x_, a[0]), point(x_, a[1]), point(x_, b[0]), point(x_, b[1]));
    lower({a[0], a[1], b[0], b[1]}, d);
  }

  // b_v = gamma / 2 * d_v on the surface's vertices, +infinity elsewhere.
  Eigen::VectorXd bounds(double fraction) const {
    Eigen::VectorXd b = Eigen::VectorXd::Constant(d_.size(), std::numeric_limits<double>::infinity());
    for (int v : s_.used_vertices()) b[v] = 0.5 * fraction * d_[v];
    return b;
  }

 private:
  void lower(std::initializer_list<int> vs, double d) {
    for (int v : vs) d_[v] = std::min(d_[v], d);
  }
  const CollisionSurface& s_;
  const PointsRef& x_;
  Eigen::VectorXd d_;
};

// Integer cell range [lo, hi] (3 axes) of a box.
struct CellRange {
  std::int64_t lo[3], hi[3];
};

// Uniform grid of cell size h over the bounding box of x0, primitives stored as sorted (cell key, id) pairs.
class SpatialHash {
 public:
  SpatialHash(const PointsRef& x0, const std::vector<int>& used, double h) : h_(h) {
    assert(h > 0.0 && !used.empty());
    Vec3 lo = point(x0, used.front()), hi = lo;
    for (int v : used) {
      lo = lo.cwiseMin(point(x0, v));
      hi = hi.cwiseMax(point(x0, v));
    }
    origin_ = lo;
    for (int k = 0; k < 3; ++k) {
      const double cells = std::floor((hi[k] - lo[k]) / h) + 1.0;
      if (!(cells <= kMaxCellsPerAxis))
        throw std::invalid_argument("StepBoundOptions.radius is too small for the surface's extent: " +
                                    std::to_string(cells) + " cells along an axis");
      dims_[k] = static_cast<std::int64_t>(cells);
    }
  }

  // Cells of the box [lo - pad, hi + pad], clamped to the grid (primitives outside it are never stored).
  CellRange range(const Vec3& lo, const Vec3& hi, double pad) const {
    CellRange c{};
    for (int k = 0; k < 3; ++k) {
      const auto cell = [&](double x) {
        const double i = std::floor((x - origin_[k]) / h_);
        return static_cast<std::int64_t>(std::clamp(i, 0.0, static_cast<double>(dims_[k] - 1)));
      };
      c.lo[k] = cell(lo[k] - pad);
      c.hi[k] = cell(hi[k] + pad);
    }
    return c;
  }

  void insert(const CellRange& c, int id) {
    for_cells(c, [&](std::int64_t key) { entries_.emplace_back(key, id); });
  }
  // A dense directory of the cells (counting sort of the entries by cell) when the grid is not much larger than
  // the entries; else the entries sorted by cell for binary search.
  void finish() {
    const std::int64_t cells = dims_[0] * dims_[1] * dims_[2];
    dense_ = cells <= kDenseCellsPerEntry * static_cast<std::int64_t>(entries_.size()) + kDenseCellsMin;
    if (!dense_) {
      std::sort(entries_.begin(), entries_.end());
      return;
    }
    start_.assign(static_cast<std::size_t>(cells + 1), 0);
    for (const auto& e : entries_) ++start_[static_cast<std::size_t>(e.first + 1)];
    for (std::size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
    ids_.resize(entries_.size());
    std::vector<int> fill(start_.begin(), start_.end() - 1);
    for (const auto& e : entries_) ids_[static_cast<std::size_t>(fill[static_cast<std::size_t>(e.first)]++)] = e.second;
  }

  // Calls f(id) for every id stored in a cell of c (an id once per shared cell: callers deduplicate).
  template <class F>
  void query(const CellRange& c, F f) const {
    for_cells(c, [&](std::int64_t key) {
      if (dense_) {
        const std::size_t k = static_cast<std::size_t>(key);
        for (int i = start_[k]; i < start_[k + 1]; ++i) f(ids_[static_cast<std::size_t>(i)]);
        return;
      }
      auto it = std::lower_bound(entries_.begin(), entries_.end(), std::make_pair(key, -1));
      for (; it != entries_.end() && it->first == key; ++it) f(it->second);
    });
  }

 private:
  template <class F>
  void for_cells(const CellRange& c, F f) const {
    for (std::int64_t k = c.lo[2]; k <= c.hi[2]; ++k)
      for (std::int64_t j = c.lo[1]; j <= c.hi[1]; ++j)
        for (std::int64_t i = c.lo[0]; i <= c.hi[0]; ++i) f(i + dims_[0] * (j + dims_[1] * k));
  }
  double h_;
  Vec3 origin_;
  std::int64_t dims_[3] = {1, 1, 1};
  std::vector<std::pair<std::int64_t, int>> entries_;  // (cell key, primitive id); sorted unless dense
  bool dense_ = false;
  std::vector<int> start_;  // dense directory: the ids of cell k are ids_[start_[k] .. start_[k + 1])
  std::vector<int> ids_;
};

// Bounding box of the points ids[0..n) of x0.
std::pair<Vec3, Vec3> box(const PointsRef& x0, const int* ids, int n) {
  Vec3 lo = point(x0, ids[0]), hi = lo;
  for (int i = 1; i < n; ++i) {
    lo = lo.cwiseMin(point(x0, ids[i]));
    hi = hi.cwiseMax(point(x0, ids[i]));
  }
  return {lo, hi};
}

// Whether the boxes [alo, ahi] and [blo, bhi] are more than r apart along some axis (then so are the primitives:
// the pair cannot lower any bound below r).
bool apart(const Vec3& alo, const Vec3& ahi, const Vec3& blo, const Vec3& bhi, double r) {
  return ((blo - ahi).array() > r).any() || ((alo - bhi).array() > r).any();
}

// Mean edge length of the surface (metres; 0 without edges).
double mean_edge_length(const CollisionSurface& s, const PointsRef& x0) {
  double sum = 0.0;
  for (int e = 0; e < s.num_edges(); ++e) sum += (point(x0, s.edge(e)[1]) - point(x0, s.edge(e)[0])).norm();
  return s.num_edges() > 0 ? sum / s.num_edges() : 0.0;
}

// Boxes at x0 of `count` primitives (primitive i: the `corners` vertex ids at ids_of(i)), metres, each inserted
// into the grid under its index; the grid is finished.
template <class IdsOf>
std::vector<std::pair<Vec3, Vec3>> insert_boxes(SpatialHash& grid, const PointsRef& x0, int count, IdsOf ids_of,
                                                int corners) {
  std::vector<std::pair<Vec3, Vec3>> boxes(static_cast<std::size_t>(count));
  for (int i = 0; i < count; ++i) {
    auto& b = boxes[static_cast<std::size_t>(i)];
    b = box(x0, ids_of(i), corners);
    grid.insert(grid.range(b.first, b.second, 0.0), i);
  }
  grid.finish();
  return boxes;
}

// Vertex-face pairs within r: triangles hashed by their boxes, each vertex queries its r-box; a triangle whose
// box is more than r away is skipped before the exact distance.
void hash_vertex_face(const CollisionSurface& s, const PointsRef& x0, double r, double h, PairDistances& pd) {
  SpatialHash grid(x0, s.used_vertices(), h);
  const auto boxes = insert_boxes(grid, x0, s.num_triangles(), [&](int t) { return s.triangle(t); }, 3);
  std::vector<int> seen(static_cast<std::size_t>(s.num_triangles()), -1);  // last vertex that visited t
  for (int p : s.used_vertices()) {
    const Vec3 xp = point(x0, p);
    grid.query(grid.range(xp, xp, r), [&](int t) {
      const auto& b = boxes[static_cast<std::size_t>(t)];
      if (seen[static_cast<std::size_t>(t)] == p || apart(xp, xp, b.first, b.second, r)) return;
      seen[static_cast<std::size_t>(t)] = p;
      pd.vertex_face(p, t);
    });
  }
}

// Edge-edge pairs within r: edges hashed by their boxes, each edge queries its r-inflated box (pairs e < g); an
// edge whose box is more than r away is skipped before the exact distance.
void hash_edge_edge(const CollisionSurface& s, const PointsRef& x0, double r, double h, PairDistances& pd) {
  SpatialHash grid(x0, s.used_vertices(), h);
  const auto boxes = insert_boxes(grid, x0, s.num_edges(), [&](int e) { return s.edge(e); }, 2);
  std::vector<int> seen(static_cast<std::size_t>(s.num_edges()), -1);  // last edge that visited g
  for (int e = 0; e < s.num_edges(); ++e) {
    const auto& a = boxes[static_cast<std::size_t>(e)];
    grid.query(grid.range(a.first, a.second, r), [&](int g) {
      const auto& b = boxes[static_cast<std::size_t>(g)];
      if (g <= e || seen[static_cast<std::size_t>(g)] == e || apart(a.first, a.second, b.first, b.second, r)) return;
      seen[static_cast<std::size_t>(g)] = e;
      pd.edge_edge(e, g);
    });
  }
}

}  // namespace

Eigen::VectorXd vertex_step_bounds(const CollisionSurface& surface, const PointsRef& x0,
                                   const StepBoundOptions& options) {
  check_inputs(surface, x0, options);
  PairDistances pd(surface, x0, options.radius);
  if (surface.num_triangles() == 0) return pd.bounds(options.fraction);
  // Cell size: at least r (an r-box spans at most 3 cells an axis), at least the mean edge (few cells a primitive).
  const double h = std::max(options.radius, mean_edge_length(surface, x0));
  hash_vertex_face(surface, x0, options.radius, h, pd);
  hash_edge_edge(surface, x0, options.radius, h, pd);
  return pd.bounds(options.fraction);
}

Eigen::VectorXd vertex_step_bounds_brute_force(const CollisionSurface& surface, const PointsRef& x0,
                                               const StepBoundOptions& options) {
  check_inputs(surface, x0, options);
  PairDistances pd(surface, x0, options.radius);
  for (int p : surface.used_vertices())
    for (int t = 0; t < surface.num_triangles(); ++t) pd.vertex_face(p, t);
  for (int e = 0; e < surface.num_edges(); ++e)
    for (int g = e + 1; g < surface.num_edges(); ++g) pd.edge_edge(e, g);
  return pd.bounds(options.fraction);
}

TruncatedStep truncate_step(const Eigen::VectorXd& bounds, const PointsRef& dx) {
  const int n = static_cast<int>(bounds.size());
  check_points(dx, n, "dx");
  for (int v = 0; v < n; ++v)
    if (!(bounds[v] >= 0.0))
      throw std::invalid_argument("bounds[" + std::to_string(v) + "] must be >= 0, got " + std::to_string(bounds[v]));
  TruncatedStep out;
  out.dx = dx;
  // Shorten each motion longer than its bound, direction kept; sum the lengths before and after.
  double before = 0.0, after = 0.0;
  for (int v = 0; v < n; ++v) {
    const double len = out.dx.row(v).norm();
    before += len;
    if (len > bounds[v]) {
      out.dx.row(v) *= bounds[v] / len;
      ++out.truncated;
    }
    after += std::min(len, bounds[v]);
  }
  out.kept = before > 0.0 ? after / before : 1.0;
  return out;
}

TruncatedStep bound_step(const CollisionSurface& surface, const PointsRef& x0, const PointsRef& dx,
                         const StepBoundOptions& options) {
  return truncate_step(vertex_step_bounds(surface, x0, options), dx);
}

}  // namespace lumen::collision
