// Collision surfaces and their refit workspaces: swept k-DOP BVHs refitted per call, self and two-tree
// traversal, deduplicated feature pairs, CCD.
#include "collision/surface.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <variant>

#include "collision/ccd.hpp"
#include "collision/detail/checks.hpp"

namespace lumen::collision {

namespace {

using detail::check_gap;
using detail::check_points;

// Feature pair key: high 32 bits the first id, low 32 bits the second (both >= 0).
std::uint64_t pack(int hi, int lo) {
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(hi)) << 32) | static_cast<std::uint32_t>(lo);
}
int key_hi(std::uint64_t k) { return static_cast<int>(k >> 32); }
int key_lo(std::uint64_t k) { return static_cast<int>(k & 0xffffffffu); }

// Number of bits needed for ids in [0, n).
int id_bits(int n) {
  int b = 0;
  while (b < 31 && (1 << b) < n) ++b;
  return b;
}

// Sort keys (each < 2^bits) ascending: LSD radix sort, 11-bit digits; tmp is scratch.
void radix_sort(std::vector<std::uint64_t>& keys, std::vector<std::uint64_t>& tmp, int bits) {
  constexpr int kDigit = 11;
  constexpr std::size_t kBuckets = std::size_t{1} << kDigit;
  std::size_t offset[kBuckets];
  tmp.resize(keys.size());
  for (int shift = 0; shift < bits; shift += kDigit) {
    // Histogram of this digit, exclusive prefix sums, stable scatter.
    std::fill(offset, offset + kBuckets, std::size_t{0});
    for (const std::uint64_t k : keys) ++offset[(k >> shift) & (kBuckets - 1)];
    std::size_t sum = 0;
    for (std::size_t b = 0; b < kBuckets; ++b) {
      const std::size_t c = offset[b];
      offset[b] = sum;
      sum += c;
    }
    for (const std::uint64_t k : keys) tmp[offset[(k >> shift) & (kBuckets - 1)]++] = k;
    keys.swap(tmp);
  }
}

// Sort and deduplicate keys (each < 2^bits).
void sort_unique(std::vector<std::uint64_t>& keys, std::vector<std::uint64_t>& tmp, int bits) {
  radix_sort(keys, tmp, bits);
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
}

// True when v is one of the three ids in t.
bool has_vertex(const int* t, int v) { return t[0] == v || t[1] == v || t[2] == v; }

// Row i of a points array as a vector.
Vec3 row(const PointsRef& x, int i) { return Vec3(x(i, 0), x(i, 1), x(i, 2)); }

void require_bvh(const CollisionSurface& s) {
  if (!s.has_bvh()) throw std::logic_error("collision surface has no BVH: call build_bvh (or build over rest)");
}

// Whether the swept boxes (vbox arrays, 6 per vertex) of two vertex sets overlap within pad (false: no
// contact is possible).
bool feature_boxes_overlap(const double* box_a, const int* va, int na, const double* box_b, const int* vb, int nb,
                           double pad) {
  for (int a = 0; a < 3; ++a) {
    double lo_a = box_a[6 * static_cast<std::size_t>(va[0]) + a], hi_a = box_a[6 * static_cast<std::size_t>(va[0]) + 3 + a];
    for (int i = 1; i < na; ++i) {
      lo_a = std::min(lo_a, box_a[6 * static_cast<std::size_t>(va[i]) + a]);
      hi_a = std::max(hi_a, box_a[6 * static_cast<std::size_t>(va[i]) + 3 + a]);
    }
    double lo_b = box_b[6 * static_cast<std::size_t>(vb[0]) + a], hi_b = box_b[6 * static_cast<std::size_t>(vb[0]) + 3 + a];
    for (int i = 1; i < nb; ++i) {
      lo_b = std::min(lo_b, box_b[6 * static_cast<std::size_t>(vb[i]) + a]);
      hi_b = std::max(hi_b, box_b[6 * static_cast<std::size_t>(vb[i]) + 3 + a]);
    }
    if (lo_a > hi_b + pad || lo_b > hi_a + pad) return false;
  }
  return true;
}

// Vertex p (points xp) against face f (points xf), motion x*0 -> x*1: the elementary test.
bool vf_test(const PointsRef& xp0, const PointsRef& xp1, int p, const PointsRef& xf0, const PointsRef& xf1,
             const int* f, double gap, CcdHit* hit) {
  return vertex_face_ccd(row(xp0, p), row(xf0, f[0]), row(xf0, f[1]), row(xf0, f[2]), row(xp1, p), row(xf1, f[0]),
                         row(xf1, f[1]), row(xf1, f[2]), gap, hit);
}

// Edge e (points xe) against edge g (points xg): the elementary test.
bool ee_test(const PointsRef& xe0, const PointsRef& xe1, const int* e, const PointsRef& xg0, const PointsRef& xg1,
             const int* g, double gap, CcdHit* hit) {
  return edge_edge_ccd(row(xe0, e[0]), row(xe0, e[1]), row(xg0, g[0]), row(xg0, g[1]), row(xe1, e[0]), row(xe1, e[1]),
                       row(xg1, g[0]), row(xg1, g[1]), gap, hit);
}

}  // namespace

// ---------------------------------------------------------------------------------------------------
// CollisionSurface

CollisionSurface::CollisionSurface(const TrisRef& t, int n) : n_points_(n) {
  if (n < 0) throw std::invalid_argument("n_points must be >= 0, got " + std::to_string(n));
  n_tris_ = static_cast<int>(t.rows());
  tris_.resize(static_cast<std::size_t>(3 * n_tris_));
  for (int i = 0; i < n_tris_; ++i) {
    for (int j = 0; j < 3; ++j) {
      const int v = t(i, j);
      if (v < 0 || v >= n) {
        throw std::invalid_argument("tris(" + std::to_string(i) + ", " + std::to_string(j) + ") must be in [0, " +
                                    std::to_string(n) + "), got " + std::to_string(v));
      }
      tris_[static_cast<std::size_t>(3 * i + j)] = v;
    }
    if (t(i, 0) == t(i, 1) || t(i, 1) == t(i, 2) || t(i, 0) == t(i, 2)) {
      throw std::invalid_argument("tris row " + std::to_string(i) + " repeats a vertex: (" + std::to_string(t(i, 0)) +
                                  ", " + std::to_string(t(i, 1)) + ", " + std::to_string(t(i, 2)) + ")");
    }
  }
  // Unique edges: sort (edge key, triangle slot) and number the distinct keys.
  std::vector<std::pair<std::uint64_t, int>> slots;
  slots.reserve(static_cast<std::size_t>(3 * n_tris_));
  for (int i = 0; i < n_tris_; ++i) {
    for (int j = 0; j < 3; ++j) {
      const int a = tris_[static_cast<std::size_t>(3 * i + j)];
      const int b = tris_[static_cast<std::size_t>(3 * i + (j + 1) % 3)];
      slots.emplace_back(pack(std::min(a, b), std::max(a, b)), 3 * i + j);
    }
  }
  std::sort(slots.begin(), slots.end());
  tri_edges_.resize(static_cast<std::size_t>(3 * n_tris_));
  for (std::size_t s = 0; s < slots.size(); ++s) {
    if (s == 0 || slots[s].first != slots[s - 1].first) {
      edges_.push_back(key_hi(slots[s].first));
      edges_.push_back(key_lo(slots[s].first));
    }
    tri_edges_[static_cast<std::size_t>(slots[s].second)] = static_cast<int>(edges_.size() / 2) - 1;
  }
  // Feature owners: each vertex and edge goes to the first triangle (in id order) that has it.
  owned_.assign(static_cast<std::size_t>(n_tris_), 0);
  std::vector<char> vertex_taken(static_cast<std::size_t>(n_points_), 0), edge_taken(edges_.size() / 2, 0);
  for (int i = 0; i < n_tris_; ++i) {
    for (int j = 0; j < 3; ++j) {
      char& v = vertex_taken[static_cast<std::size_t>(tris_[static_cast<std::size_t>(3 * i + j)])];
      if (!v) v = 1, owned_[static_cast<std::size_t>(i)] |= static_cast<std::uint8_t>(1u << j);
      char& e = edge_taken[static_cast<std::size_t>(tri_edges_[static_cast<std::size_t>(3 * i + j)])];
      if (!e) e = 1, owned_[static_cast<std::size_t>(i)] |= static_cast<std::uint8_t>(8u << j);
    }
  }
  for (int v : tris_) used_vertices_.push_back(v);
  std::sort(used_vertices_.begin(), used_vertices_.end());
  used_vertices_.erase(std::unique(used_vertices_.begin(), used_vertices_.end()), used_vertices_.end());
  tri_bits_ = id_bits(n_tris_);
  edge_bits_ = id_bits(num_edges());
  point_bits_ = id_bits(n_points_);
}

CollisionSurface::CollisionSurface(const TrisRef& tris, const PointsRef& rest)
    : CollisionSurface(tris, static_cast<int>(rest.rows())) {
  check_points(rest, n_points_, "rest");
  build_bvh(rest);
}

void CollisionSurface::build_bvh(const PointsRef& x) {
  check_points(x, n_points_, "x");
  std::vector<double> centres(static_cast<std::size_t>(3 * n_tris_));
  for (int t = 0; t < n_tris_; ++t) {
    for (int d = 0; d < 3; ++d) {
      centres[static_cast<std::size_t>(3 * t + d)] =
          (x(triangle(t)[0], d) + x(triangle(t)[1], d) + x(triangle(t)[2], d)) / 3.0;
    }
  }
  bvh_.build(centres.data(), n_tris_);
  built_ = true;
}

void validate_motion(const CollisionSurface& surface, const PointsRef& x0, const PointsRef& x1, double gap) {
  check_points(x0, surface.num_points(), "x0");
  check_points(x1, surface.num_points(), "x1");
  check_gap(gap);
}

// ---------------------------------------------------------------------------------------------------
// CollisionWorkspace

struct CollisionWorkspace::Impl {
  static constexpr std::size_t kVertexMove = 6;  // doubles per vertex in `move`: start xyz, end xyz
  static constexpr std::size_t kNodeMove = 12;   // doubles per node in `node_move`: start box, end box
  using AnyBoxes = std::variant<BvhBoxes<6>, BvhBoxes<14>, BvhBoxes<18>, BvhBoxes<26>>;

  int k = 26;
  AnyBoxes boxes;  // per-node swept k-DOPs of the surface last refitted

  // Per-call scratch, reused across calls.
  std::vector<std::uint64_t> vf_keys;   // vertex id << tri_bits | triangle id (pairs: vertex of A, face of B)
  std::vector<std::uint64_t> vf_keys_b; // pairs only: vertex of B << A's tri_bits | face of A
  std::vector<std::uint64_t> ee_keys;   // edge id << edge_bits | edge id (self: first < second; pairs: A, B)
  std::vector<std::uint64_t> sort_tmp;  // radix sort scratch
  std::vector<double> proj;             // vertex projections on the k-DOP axes at x0 then x1, n_points x k
  std::vector<double> vbox;             // swept axis-aligned box of each vertex: lo xyz, hi xyz, n_points x 6
  double feature_pad = 0.0;             // feature-box overlap margin: 2 gap plus rounding, metres
  double pad_rounding = 0.0;            // its rounding part (64 eps times the largest coordinate), metres
  std::vector<FeaturePair> tested;      // the feature pairs run by the last detect_self call
  // detect_self_moved: per-vertex moves at the sweep's start and end (n_points x 6: start xyz, end xyz), and per
  // BVH node whether a flagged vertex is under it and the boxes of the moves under it (n_nodes x 12: start lo xyz,
  // start hi xyz, end lo xyz, end hi xyz).
  std::vector<double> move;
  std::vector<std::uint8_t> node_flagged;
  std::vector<double> node_move;
  long bv_overlaps = 0;
  // k-DOP study (off by default): overlapping leaf pairs of the call and running totals.
  bool classify = false;
  std::vector<std::pair<int, int>> overlap_pairs;  // n_overlaps, triangle ids
  std::vector<std::uint64_t> hit_vf, hit_ee;       // keys of the feature pairs in contact, sorted
  OverlapTotals totals;

  explicit Impl(int kdop) : k(validate_kdop(kdop)) {
    // The box type for this k (the only switch on k; the hot loops are templates).
    switch (k) {
      case 6: boxes.emplace<BvhBoxes<6>>(); break;
      case 14: boxes.emplace<BvhBoxes<14>>(); break;
      case 18: boxes.emplace<BvhBoxes<18>>(); break;
      default: boxes.emplace<BvhBoxes<26>>(); break;
    }
  }

  // The feature-box pre-test's margin at a gap: both features' inflation plus rounding, metres.
  double pad_for(double gap) const { return 2.0 * gap * (1.0 + 1e-12) + pad_rounding; }

  // Swept k-DOPs of all triangles of s over x0 -> x1 (each the k-DOP of its 6 vertex positions), inflated
  // by gap, written to out(t). The vertex projections are computed once per vertex.
  template <int K, class Out>
  void swept_boxes(const CollisionSurface& s, const PointsRef& x0, const PointsRef& x1, double gap, Out&& out) {
    constexpr int A = Kdop<K>::kAxes;
    const std::size_t n_points = static_cast<std::size_t>(s.num_points());
    proj.resize(static_cast<std::size_t>(2 * A) * n_points);
    for (const int v : s.used_vertices()) {
      double all[13];
      double* p = &proj[static_cast<std::size_t>(2 * A) * static_cast<std::size_t>(v)];
      kdop_project_all(x0.data() + v * x0.outerStride(), all);
      for (int a = 0; a < A; ++a) p[a] = all[KdopAxisIds<K>::ids[a]];
      kdop_project_all(x1.data() + v * x1.outerStride(), all);
      for (int a = 0; a < A; ++a) p[A + a] = all[KdopAxisIds<K>::ids[a]];
    }
    // Swept axis-aligned box of each vertex (the first three axes of every k-DOP are x, y, z), for the
    // per-feature pre-test; the margin covers both features' gap inflation and rounding.
    vbox.resize(static_cast<std::size_t>(6) * n_points);
    double scale = 0.0;
    for (const int v : s.used_vertices()) {
      const double* p = &proj[static_cast<std::size_t>(2 * A) * static_cast<std::size_t>(v)];
      double* b = &vbox[static_cast<std::size_t>(6) * static_cast<std::size_t>(v)];
      for (int a = 0; a < 3; ++a) {
        b[a] = std::min(p[a], p[A + a]);
        b[3 + a] = std::max(p[a], p[A + a]);
        scale = std::max({scale, std::abs(b[a]), std::abs(b[3 + a])});
      }
    }
    pad_rounding = 64.0 * std::numeric_limits<double>::epsilon() * scale;
    feature_pad = pad_for(gap);
    for (int t = 0; t < s.num_triangles(); ++t) {
      Kdop<K>& box = out(t);
      const double* p[3];
      for (int j = 0; j < 3; ++j) p[j] = &proj[static_cast<std::size_t>(2 * A) * static_cast<std::size_t>(s.triangle(t)[j])];
      for (int a = 0; a < A; ++a) {
        box.lo[a] = std::min({p[0][a], p[0][A + a], p[1][a], p[1][A + a], p[2][a], p[2][A + a]});
        box.hi[a] = std::max({p[0][a], p[0][A + a], p[1][a], p[1][A + a], p[2][a], p[2][A + a]});
      }
      box.inflate(gap);
    }
  }

  // Refit this workspace's tree over surface s for motion x0 -> x1: leaves, then internal nodes.
  template <int K>
  void refit(const CollisionSurface& s, const PointsRef& x0, const PointsRef& x1, double gap) {
    BvhBoxes<K>& b = std::get<BvhBoxes<K>>(boxes);
    b.fit(s.bvh());
    swept_boxes<K>(s, x0, x1, gap, [&b, &s](int t) -> Kdop<K>& { return b.leaf_box(s.bvh(), t); });
    b.refit(s.bvh());
  }

  // Per BVH node of s, bottom-up: whether a flagged vertex is under it and the boxes of the moves under it (moves:
  // n_points x 6 as in `move`, or null for none).
  void mark_nodes(const CollisionSurface& s, const std::uint8_t* flagged, const double* moves) {
    const BvhTopology& topo = s.bvh();
    const std::size_t n = static_cast<std::size_t>(topo.num_nodes());
    node_flagged.assign(n, 0);
    node_move.assign(kNodeMove * n, 0.0);
    for (int i = topo.num_nodes() - 1; i >= 0; --i) {
      const BvhTopology::Node& nd = topo.node(i);
      double* box = &node_move[kNodeMove * static_cast<std::size_t>(i)];
      if (nd.prim < 0) {
        // Internal: the union of its children, at each end.
        const double* l = &node_move[kNodeMove * static_cast<std::size_t>(nd.left)];
        const double* r = &node_move[kNodeMove * static_cast<std::size_t>(nd.right)];
        for (std::size_t e = 0; e < kNodeMove; e += 6)
          for (std::size_t d = 0; d < 3; ++d) {
            box[e + d] = std::min(l[e + d], r[e + d]);
            box[e + 3 + d] = std::max(l[e + 3 + d], r[e + 3 + d]);
          }
        node_flagged[static_cast<std::size_t>(i)] = node_flagged[static_cast<std::size_t>(nd.left)] |
                                                     node_flagged[static_cast<std::size_t>(nd.right)];
        continue;
      }
      // Leaf: its triangle's three vertices.
      const int* t = s.triangle(nd.prim);
      for (std::size_t e = 0; e < kNodeMove; e += 6)
        for (std::size_t d = 0; d < 3; ++d) {
          box[e + d] = std::numeric_limits<double>::infinity();
          box[e + 3 + d] = -std::numeric_limits<double>::infinity();
        }
      for (int j = 0; j < 3; ++j) {
        if (flagged && flagged[t[j]]) node_flagged[static_cast<std::size_t>(i)] = 1;
        for (int e = 0; e < 2; ++e)
          for (int d = 0; d < 3; ++d) {
            const double m = moves ? moves[kVertexMove * static_cast<std::size_t>(t[j]) + static_cast<std::size_t>(3 * e + d)] : 0.0;
            box[6 * e + d] = std::min(box[6 * e + d], m);
            box[6 * e + 3 + d] = std::max(box[6 * e + 3 + d], m);
          }
      }
    }
  }

  // Whether BVH nodes a and b can hold a selected pair: a flag under either, or moves under them differing by at
  // least the margin somewhere, at the start or at the end (the largest difference of two points of their boxes).
  bool node_pair_wanted(int a, int b, double margin2) const {
    if (node_flagged[static_cast<std::size_t>(a)] || node_flagged[static_cast<std::size_t>(b)]) return true;
    const double* p = &node_move[kNodeMove * static_cast<std::size_t>(a)];
    const double* q = &node_move[kNodeMove * static_cast<std::size_t>(b)];
    for (std::size_t e = 0; e < kNodeMove; e += 6) {
      double d2 = 0.0;
      for (std::size_t d = 0; d < 3; ++d) {
        const double span = std::max(p[e + 3 + d] - q[e + d], q[e + 3 + d] - p[e + d]);
        d2 += span * span;
      }
      if (d2 >= margin2) return true;
    }
    return false;
  }

  // Reset the per-call candidates and statistics.
  void begin_call() {
    vf_keys.clear();
    vf_keys_b.clear();
    ee_keys.clear();
    tested.clear();
    bv_overlaps = 0;
    overlap_pairs.clear();
    hit_vf.clear();
    hit_ee.clear();
  }
};

CollisionWorkspace::CollisionWorkspace(int kdop) : impl_(std::make_unique<Impl>(kdop)) {}
CollisionWorkspace::~CollisionWorkspace() = default;
CollisionWorkspace::CollisionWorkspace(CollisionWorkspace&&) noexcept = default;
CollisionWorkspace& CollisionWorkspace::operator=(CollisionWorkspace&&) noexcept = default;
int CollisionWorkspace::kdop() const { return impl_->k; }
const std::vector<FeaturePair>& CollisionWorkspace::tested_features() const { return impl_->tested; }
void CollisionWorkspace::set_classify_overlaps(bool on) { impl_->classify = on; }
OverlapTotals CollisionWorkspace::overlap_totals() const { return impl_->totals; }

CollisionWorkspace::Impl& workspace_impl(CollisionWorkspace& w) { return *w.impl_; }

// ---------------------------------------------------------------------------------------------------
// Self detection

namespace {

// Call f with std::integral_constant<int, k>.
template <class F>
void with_k(int k, F&& f) {
  switch (k) {
    case 6: f(std::integral_constant<int, 6>{}); break;
    case 14: f(std::integral_constant<int, 14>{}); break;
    case 18: f(std::integral_constant<int, 18>{}); break;
    default: f(std::integral_constant<int, 26>{}); break;
  }
}

using WsImpl = CollisionWorkspace::Impl;

// One surface against itself: candidates, feature tests and the k-DOP study, over a workspace.
struct SelfDetector {
  const CollisionSurface& s;
  WsImpl& w;
  // Restricted detection (detect_self_moved): flags and per-vertex moves (n_points x 6, row-major: start xyz, end
  // xyz, WsImpl::kVertexMove), or null.
  const std::uint8_t* flagged = nullptr;
  const double* move = nullptr;
  double margin2 = 0.0;  // squared margin
  bool restricted = false;

  // Whether vertex sets a and b hold a selected pair: a flag, or a relative move of at least the margin at the
  // sweep's start or end.
  bool wanted(const int* a, int na, const int* b, int nb) const {
    if (!restricted) return true;
    for (int i = 0; i < na; ++i)
      if (flagged && flagged[a[i]]) return true;
    for (int j = 0; j < nb; ++j)
      if (flagged && flagged[b[j]]) return true;
    if (!move) return false;
    for (int i = 0; i < na; ++i)
      for (int j = 0; j < nb; ++j)
        for (std::size_t e = 0; e < WsImpl::kVertexMove; e += 3) {
          const double* da = move + WsImpl::kVertexMove * static_cast<std::size_t>(a[i]) + e;
          const double* db = move + WsImpl::kVertexMove * static_cast<std::size_t>(b[j]) + e;
          const double dx = da[0] - db[0], dy = da[1] - db[1], dz = da[2] - db[2];
          if (dx * dx + dy * dy + dz * dz >= margin2) return true;
        }
    return false;
  }

  // Compact feature pair keys, ordered as (first id, second id).
  std::uint64_t vf_key(int v, int t) const {
    return (static_cast<std::uint64_t>(v) << s.tri_bits()) | static_cast<std::uint64_t>(t);
  }
  std::uint64_t ee_key(int e, int g) const {
    return (static_cast<std::uint64_t>(e) << s.edge_bits()) | static_cast<std::uint64_t>(g);
  }

  // Candidate features of an overlapping triangle pair: the vertices each owns against the other face and the
  // pairs of edges they own, skipping those that share a vertex (so neighbours still test their remaining
  // features). Owned features only: every feature pair comes from exactly one triangle pair, its owners'.
  void add_candidates(int ta, int tb) {
    ++w.bv_overlaps;
    if (w.classify) w.overlap_pairs.emplace_back(ta, tb);
    const int* A = s.triangle(ta);
    const int* B = s.triangle(tb);
    const unsigned own_a = s.owned_features(ta), own_b = s.owned_features(tb);
    for (int i = 0; i < 3; ++i) {
      if ((own_a >> i & 1u) && !has_vertex(B, A[i]) && wanted(&A[i], 1, B, 3)) w.vf_keys.push_back(vf_key(A[i], tb));
      if ((own_b >> i & 1u) && !has_vertex(A, B[i]) && wanted(&B[i], 1, A, 3)) w.vf_keys.push_back(vf_key(B[i], ta));
    }
    for (int i = 0; i < 3; ++i) {
      if (!(own_a >> (3 + i) & 1u)) continue;
      const int ea = s.triangle_edge(ta, i);
      const int* va = s.edge(ea);
      for (int j = 0; j < 3; ++j) {
        if (!(own_b >> (3 + j) & 1u)) continue;
        const int eb = s.triangle_edge(tb, j);
        const int* vb = s.edge(eb);
        if (va[0] == vb[0] || va[0] == vb[1] || va[1] == vb[0] || va[1] == vb[1]) continue;
        if (!wanted(va, 2, vb, 2)) continue;
        w.ee_keys.push_back(ee_key(std::min(ea, eb), std::max(ea, eb)));
      }
    }
  }

  // Whether an overlapping pair has a feature pair in contact (the keys add_candidates would make).
  bool pair_has_contact(int ta, int tb) const {
    const int* A = s.triangle(ta);
    const int* B = s.triangle(tb);
    auto has = [](const std::vector<std::uint64_t>& v, std::uint64_t key) {
      return std::binary_search(v.begin(), v.end(), key);
    };
    const unsigned own_a = s.owned_features(ta), own_b = s.owned_features(tb);
    for (int i = 0; i < 3; ++i) {
      if ((own_a >> i & 1u) && !has_vertex(B, A[i]) && has(w.hit_vf, vf_key(A[i], tb))) return true;
      if ((own_b >> i & 1u) && !has_vertex(A, B[i]) && has(w.hit_vf, vf_key(B[i], ta))) return true;
    }
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        if (!(own_a >> (3 + i) & 1u) || !(own_b >> (3 + j) & 1u)) continue;
        const int ea = s.triangle_edge(ta, i);
        const int eb = s.triangle_edge(tb, j);
        if (has(w.hit_ee, ee_key(std::min(ea, eb), std::max(ea, eb)))) return true;
      }
    return false;
  }

  // Add this call's overlaps, split by whether they hold a contact, to the running totals.
  void classify_overlaps() {
    std::sort(w.hit_vf.begin(), w.hit_vf.end());
    std::sort(w.hit_ee.begin(), w.hit_ee.end());
    ++w.totals.calls;
    w.totals.overlaps += static_cast<long>(w.overlap_pairs.size());
    for (const auto& [ta, tb] : w.overlap_pairs) {
      const bool contact = pair_has_contact(ta, tb);
      w.totals.overlaps_with_contact += contact;
      const int* A = s.triangle(ta);
      const int* B = s.triangle(tb);
      if (has_vertex(B, A[0]) || has_vertex(B, A[1]) || has_vertex(B, A[2])) continue;
      ++w.totals.separate_overlaps;
      w.totals.separate_with_contact += contact;
    }
  }

  // Refit the swept leaves and internal nodes at `gap`, then collect the candidates of every overlapping leaf pair by
  // self-traversal (detect_self, detect_self_near).
  void collect_all(const PointsRef& x0, const PointsRef& x1, double gap) {
    with_k(w.k, [&](auto k_tag) {
      constexpr int K = decltype(k_tag)::value;
      w.refit<K>(s, x0, x1, gap);
      std::get<BvhBoxes<K>>(w.boxes).self_pairs(s.bvh(), [this](int ta, int tb) { add_candidates(ta, tb); });
    });
  }

  // A detection at a wider gap than the contacts it reports (detect_self_near): each hit's key goes to `near` and
  // the hit is tested again at `gap` (with that gap's pre-test), and only those hits are reported.
  struct Narrow {
    double gap = 0.0;              // the reported contacts' gap, metres (below the detection's)
    NearFeatures* near = nullptr;  // the hits' keys
  };

  // Report a hit of the pass's gap: as it is, or (narrowing) kept as near and tested again at the narrow gap.
  template <class Test>
  void report(const int* v, FeatureKind kind, std::uint64_t key, const CcdHit& hit, const Narrow* narrow,
              Test&& test_at, std::vector<Contact>& out) {
    if (!narrow) {
      out.push_back(Contact{kind, {v[0], v[1], v[2], v[3]}, hit.toi, hit.s, hit.t});
      return;
    }
    (kind == FeatureKind::VertexFace ? narrow->near->vf : narrow->near->ee).push_back(key);
    CcdHit again;
    if (test_at(narrow->gap, w.pad_for(narrow->gap), &again))
      out.push_back(Contact{kind, {v[0], v[1], v[2], v[3]}, again.toi, again.s, again.t});
  }

  // Sort the candidates (and drop repeats) and run each feature pair's elementary test once, in sorted order.
  void run_features(const PointsRef& x0, const PointsRef& x1, double gap, std::vector<Contact>& out,
                    CollisionStats* stats, const Narrow* narrow = nullptr) {
    sort_unique(w.vf_keys, w.sort_tmp, s.point_bits() + s.tri_bits());
    sort_unique(w.ee_keys, w.sort_tmp, 2 * s.edge_bits());
    w.tested.reserve(w.vf_keys.size() + w.ee_keys.size());
    const double* vbox = w.vbox.data();
    // Vertex-face tests.
    for (const std::uint64_t key : w.vf_keys) {
      const int p = static_cast<int>(key >> s.tri_bits());
      const int* f = s.triangle(static_cast<int>(key & ((std::uint64_t{1} << s.tri_bits()) - 1)));
      w.tested.push_back(FeaturePair{FeatureKind::VertexFace, {p, f[0], f[1], f[2]}});
      // Swept boxes apart: the elementary test would say no.
      auto test_at = [&](double g, double pad, CcdHit* hit) {
        return feature_boxes_overlap(vbox, &p, 1, vbox, f, 3, pad) && vf_test(x0, x1, p, x0, x1, f, g, hit);
      };
      CcdHit hit;
      if (test_at(gap, w.feature_pad, &hit)) {
        const int v[4] = {p, f[0], f[1], f[2]};
        report(v, FeatureKind::VertexFace, key, hit, narrow, test_at, out);
        if (w.classify) w.hit_vf.push_back(key);
      }
    }
    // Edge-edge tests.
    for (const std::uint64_t key : w.ee_keys) {
      const int* e = s.edge(static_cast<int>(key >> s.edge_bits()));
      const int* g = s.edge(static_cast<int>(key & ((std::uint64_t{1} << s.edge_bits()) - 1)));
      w.tested.push_back(FeaturePair{FeatureKind::EdgeEdge, {e[0], e[1], g[0], g[1]}});
      auto test_at = [&](double gg, double pad, CcdHit* hit) {
        return feature_boxes_overlap(vbox, e, 2, vbox, g, 2, pad) && ee_test(x0, x1, e, x0, x1, g, gg, hit);
      };
      CcdHit hit;
      if (test_at(gap, w.feature_pad, &hit)) {
        const int v[4] = {e[0], e[1], g[0], g[1]};
        report(v, FeatureKind::EdgeEdge, key, hit, narrow, test_at, out);
        if (w.classify) w.hit_ee.push_back(key);
      }
    }
    if (w.classify) classify_overlaps();
    if (stats) {
      stats->bv_overlaps = w.bv_overlaps;
      stats->feature_tests = static_cast<long>(w.tested.size());
      stats->contacts = static_cast<long>(out.size());
    }
  }
};

}  // namespace

void detect_self(const CollisionSurface& surface, CollisionWorkspace& ws, const PointsRef& x0, const PointsRef& x1,
                 double gap, std::vector<Contact>& out, CollisionStats* stats) {
  WsImpl& w = workspace_impl(ws);
  validate_motion(surface, x0, x1, gap);
  require_bvh(surface);
  out.clear();
  w.begin_call();
  SelfDetector det{surface, w};
  det.collect_all(x0, x1, gap);
  det.run_features(x0, x1, gap, out, stats);
}

void detect_self_near(const CollisionSurface& surface, CollisionWorkspace& ws, const PointsRef& x0, const PointsRef& x1,
                      double gap, double near_gap, std::vector<Contact>& out, NearFeatures& near,
                      CollisionStats* stats) {
  WsImpl& w = workspace_impl(ws);
  validate_motion(surface, x0, x1, gap);
  if (!(near_gap >= gap) || !std::isfinite(near_gap)) {
    std::ostringstream msg;
    msg << "near_gap must be finite and >= gap (" << gap << " m), got " << near_gap;
    throw std::invalid_argument(msg.str());
  }
  require_bvh(surface);
  out.clear();
  near.vf.clear();
  near.ee.clear();
  w.begin_call();
  SelfDetector det{surface, w};
  // detect_self at the near gap; its hits are kept (keys, in sorted order) and tested again at the contact gap.
  det.collect_all(x0, x1, near_gap);
  const SelfDetector::Narrow narrow{gap, &near};
  det.run_features(x0, x1, near_gap, out, stats, &narrow);
}

namespace {

// Check a move filter against the surface (sizes, finite reference, margin).
void check_filter(const CollisionSurface& surface, const MoveFilter& f) {
  if (f.flagged && f.flagged->size() != static_cast<std::size_t>(surface.num_points())) {
    throw std::invalid_argument("flagged has " + std::to_string(f.flagged->size()) + " entries, expected n_points = " +
                                std::to_string(surface.num_points()));
  }
  if (f.x1_ref) check_points(*f.x1_ref, surface.num_points(), "x1_ref");
  if (f.x0_ref && !f.x1_ref) throw std::invalid_argument("x0_ref given without x1_ref");
  if (f.near) {
    // Every key a feature pair of this surface that detect_self could test: ids in range, edges in order, no shared
    // vertex.
    const std::uint64_t tri_mask = (std::uint64_t{1} << surface.tri_bits()) - 1;
    const std::uint64_t edge_mask = (std::uint64_t{1} << surface.edge_bits()) - 1;
    const auto bad_vf = [&](std::uint64_t k) {
      const std::uint64_t p = k >> surface.tri_bits(), t = k & tri_mask;
      return p >= static_cast<std::uint64_t>(surface.num_points()) ||
             t >= static_cast<std::uint64_t>(surface.num_triangles()) ||
             has_vertex(surface.triangle(static_cast<int>(t)), static_cast<int>(p));
    };
    const auto bad_ee = [&](std::uint64_t k) {
      const std::uint64_t e = k >> surface.edge_bits(), g = k & edge_mask;
      if (e >= g || g >= static_cast<std::uint64_t>(surface.num_edges())) return true;
      const int* a = surface.edge(static_cast<int>(e));
      const int* b = surface.edge(static_cast<int>(g));
      return a[0] == b[0] || a[0] == b[1] || a[1] == b[0] || a[1] == b[1];
    };
    if (std::any_of(f.near->vf.begin(), f.near->vf.end(), bad_vf) ||
        std::any_of(f.near->ee.begin(), f.near->ee.end(), bad_ee))
      throw std::invalid_argument("near holds a feature pair outside this surface");
  }
  if (f.x0_ref) check_points(*f.x0_ref, surface.num_points(), "x0_ref");
  if (!(f.margin >= 0.0) || !std::isfinite(f.margin)) {
    std::ostringstream msg;
    msg << "margin must be finite and >= 0 metres, got " << f.margin;
    throw std::invalid_argument(msg.str());
  }
}

}  // namespace

void detect_self_moved(const CollisionSurface& surface, CollisionWorkspace& ws, const PointsRef& x0,
                       const PointsRef& x1, double gap, const MoveFilter& filter, std::vector<Contact>& out,
                       CollisionStats* stats) {
  WsImpl& w = workspace_impl(ws);
  validate_motion(surface, x0, x1, gap);
  require_bvh(surface);
  check_filter(surface, filter);
  out.clear();
  w.begin_call();
  SelfDetector det{surface, w};
  det.restricted = true;
  det.flagged = filter.flagged ? filter.flagged->data() : nullptr;
  det.margin2 = filter.margin * filter.margin;
  // Each used vertex's move since the reference, at the sweep's start (0 when it starts where the reference did)
  // and at its end.
  if (filter.x1_ref) {
    w.move.assign(WsImpl::kVertexMove * static_cast<std::size_t>(surface.num_points()), 0.0);
    for (const int v : surface.used_vertices()) {
      double* m = &w.move[WsImpl::kVertexMove * static_cast<std::size_t>(v)];
      for (int d = 0; d < 3; ++d) {
        m[d] = filter.x0_ref ? x0(v, d) - (*filter.x0_ref)(v, d) : 0.0;
        m[3 + d] = x1(v, d) - (*filter.x1_ref)(v, d);
      }
    }
    det.move = w.move.data();
  }
  w.mark_nodes(surface, det.flagged, det.move);
  // Refit in full, traverse only the node pairs that can hold a selected pair.
  const double node_margin2 = det.move ? det.margin2 : std::numeric_limits<double>::infinity();
  auto keep = [&w, node_margin2](int a, int b) { return w.node_pair_wanted(a, b, node_margin2); };
  with_k(w.k, [&](auto k_tag) {
    constexpr int K = decltype(k_tag)::value;
    w.refit<K>(surface, x0, x1, gap);
    std::get<BvhBoxes<K>>(w.boxes).self_pairs_where(surface.bvh(), keep, [&](int ta, int tb) { det.add_candidates(ta, tb); });
  });
  // The listed pairs, always (sort_unique drops the ones the traversal found too).
  if (filter.near) {
    w.vf_keys.insert(w.vf_keys.end(), filter.near->vf.begin(), filter.near->vf.end());
    w.ee_keys.insert(w.ee_keys.end(), filter.near->ee.begin(), filter.near->ee.end());
  }
  det.run_features(x0, x1, gap, out, stats);
}

void detect_self_brute_force(const CollisionSurface& surface, CollisionWorkspace& ws, const PointsRef& x0,
                             const PointsRef& x1, double gap, std::vector<Contact>& out, CollisionStats* stats) {
  WsImpl& w = workspace_impl(ws);
  validate_motion(surface, x0, x1, gap);
  out.clear();
  w.begin_call();
  SelfDetector det{surface, w};
  // All pairs of swept triangle k-DOPs, no hierarchy.
  with_k(w.k, [&](auto k_tag) {
    constexpr int K = decltype(k_tag)::value;
    const int n = surface.num_triangles();
    std::vector<Kdop<K>> boxes(static_cast<std::size_t>(n));
    w.swept_boxes<K>(surface, x0, x1, gap, [&boxes](int t) -> Kdop<K>& { return boxes[static_cast<std::size_t>(t)]; });
    for (int a = 0; a < n; ++a) {
      for (int b = a + 1; b < n; ++b) {
        if (boxes[static_cast<std::size_t>(a)].overlaps(boxes[static_cast<std::size_t>(b)])) det.add_candidates(a, b);
      }
    }
  });
  det.run_features(x0, x1, gap, out, stats);
}

// ---------------------------------------------------------------------------------------------------
// Two-tree detection

namespace {

// Surface A against surface B: candidates in A's workspace, boxes of each side in its own workspace.
struct PairDetector {
  const CollisionSurface& a;
  const CollisionSurface& b;
  WsImpl& wa;
  WsImpl& wb;

  // Every vertex of each triangle against the other's face, and every edge pair; no exclusion.
  void add_candidates(int ta, int tb) {
    ++wa.bv_overlaps;
    const int* A = a.triangle(ta);
    const int* B = b.triangle(tb);
    for (int i = 0; i < 3; ++i) {
      wa.vf_keys.push_back((static_cast<std::uint64_t>(A[i]) << b.tri_bits()) | static_cast<std::uint64_t>(tb));
      wa.vf_keys_b.push_back((static_cast<std::uint64_t>(B[i]) << a.tri_bits()) | static_cast<std::uint64_t>(ta));
    }
    for (int i = 0; i < 3; ++i) {
      const auto ea = static_cast<std::uint64_t>(a.triangle_edge(ta, i));
      for (int j = 0; j < 3; ++j) {
        wa.ee_keys.push_back((ea << b.edge_bits()) | static_cast<std::uint64_t>(b.triangle_edge(tb, j)));
      }
    }
  }

  // Vertex-face tests of one direction: vertices of surface sp (points xp) against faces of sf (xf).
  static void run_vf(const std::vector<std::uint64_t>& keys, Side side, const CollisionSurface& sf,
                     const PointsRef& xp0, const PointsRef& xp1, const double* vbox_p, const PointsRef& xf0,
                     const PointsRef& xf1, const double* vbox_f, double gap, double pad, std::vector<PairContact>& out) {
    for (const std::uint64_t key : keys) {
      const int p = static_cast<int>(key >> sf.tri_bits());
      const int* f = sf.triangle(static_cast<int>(key & ((std::uint64_t{1} << sf.tri_bits()) - 1)));
      if (!feature_boxes_overlap(vbox_p, &p, 1, vbox_f, f, 3, pad)) continue;
      CcdHit hit;
      if (vf_test(xp0, xp1, p, xf0, xf1, f, gap, &hit)) {
        out.push_back(PairContact{FeatureKind::VertexFace, side, {p, f[0], f[1], f[2]}, hit.toi, hit.s, hit.t});
      }
    }
  }

  // Sort the candidates (and drop repeats) and run each feature pair's elementary test once, in sorted order.
  void run_features(const PointsRef& xa0, const PointsRef& xa1, const PointsRef& xb0, const PointsRef& xb1,
                    double gap, std::vector<PairContact>& out, CollisionStats* stats) {
    sort_unique(wa.vf_keys, wa.sort_tmp, a.point_bits() + b.tri_bits());
    sort_unique(wa.vf_keys_b, wa.sort_tmp, b.point_bits() + a.tri_bits());
    sort_unique(wa.ee_keys, wa.sort_tmp, a.edge_bits() + b.edge_bits());
    const double pad = std::max(wa.feature_pad, wb.feature_pad);
    const double* va = wa.vbox.data();
    const double* vb = wb.vbox.data();
    run_vf(wa.vf_keys, Side::A, b, xa0, xa1, va, xb0, xb1, vb, gap, pad, out);
    run_vf(wa.vf_keys_b, Side::B, a, xb0, xb1, vb, xa0, xa1, va, gap, pad, out);
    for (const std::uint64_t key : wa.ee_keys) {
      const int* e = a.edge(static_cast<int>(key >> b.edge_bits()));
      const int* g = b.edge(static_cast<int>(key & ((std::uint64_t{1} << b.edge_bits()) - 1)));
      if (!feature_boxes_overlap(va, e, 2, vb, g, 2, pad)) continue;
      CcdHit hit;
      if (ee_test(xa0, xa1, e, xb0, xb1, g, gap, &hit)) {
        out.push_back(PairContact{FeatureKind::EdgeEdge, Side::A, {e[0], e[1], g[0], g[1]}, hit.toi, hit.s, hit.t});
      }
    }
    if (stats) {
      stats->bv_overlaps = wa.bv_overlaps;
      stats->feature_tests = static_cast<long>(wa.vf_keys.size() + wa.vf_keys_b.size() + wa.ee_keys.size());
      stats->contacts = static_cast<long>(out.size());
    }
  }
};

// Validate both motions, the gap and the k of the two workspaces; clear out and the candidates.
void begin_pair(const CollisionSurface& a, WsImpl& wa, const PointsRef& xa0, const PointsRef& xa1,
                const CollisionSurface& b, WsImpl& wb, const PointsRef& xb0, const PointsRef& xb1, double gap,
                std::vector<PairContact>& out) {
  check_points(xa0, a.num_points(), "xa0");
  check_points(xa1, a.num_points(), "xa1");
  check_points(xb0, b.num_points(), "xb0");
  check_points(xb1, b.num_points(), "xb1");
  check_gap(gap);
  if (&wa == &wb) throw std::invalid_argument("detect_pair needs two different workspaces");
  if (wa.k != wb.k) {
    throw std::invalid_argument("workspaces use different k-DOPs: " + std::to_string(wa.k) + " and " +
                                std::to_string(wb.k));
  }
  out.clear();
  wa.begin_call();
  wb.begin_call();
}

}  // namespace

void detect_pair(const CollisionSurface& a, CollisionWorkspace& wsa, const PointsRef& xa0, const PointsRef& xa1,
                 const CollisionSurface& b, CollisionWorkspace& wsb, const PointsRef& xb0, const PointsRef& xb1,
                 double gap, std::vector<PairContact>& out, CollisionStats* stats) {
  WsImpl& wa = workspace_impl(wsa);
  WsImpl& wb = workspace_impl(wsb);
  begin_pair(a, wa, xa0, xa1, b, wb, xb0, xb1, gap, out);
  require_bvh(a);
  require_bvh(b);
  PairDetector det{a, b, wa, wb};
  with_k(wa.k, [&](auto k_tag) {
    constexpr int K = decltype(k_tag)::value;
    wa.refit<K>(a, xa0, xa1, gap);
    wb.refit<K>(b, xb0, xb1, gap);
    std::get<BvhBoxes<K>>(wa.boxes).cross_pairs(a.bvh(), std::get<BvhBoxes<K>>(wb.boxes), b.bvh(),
                                                [&](int ta, int tb) { det.add_candidates(ta, tb); });
  });
  det.run_features(xa0, xa1, xb0, xb1, gap, out, stats);
}

void detect_pair_brute_force(const CollisionSurface& a, CollisionWorkspace& wsa, const PointsRef& xa0,
                             const PointsRef& xa1, const CollisionSurface& b, CollisionWorkspace& wsb,
                             const PointsRef& xb0, const PointsRef& xb1, double gap, std::vector<PairContact>& out,
                             CollisionStats* stats) {
  WsImpl& wa = workspace_impl(wsa);
  WsImpl& wb = workspace_impl(wsb);
  begin_pair(a, wa, xa0, xa1, b, wb, xb0, xb1, gap, out);
  PairDetector det{a, b, wa, wb};
  with_k(wa.k, [&](auto k_tag) {
    constexpr int K = decltype(k_tag)::value;
    std::vector<Kdop<K>> ba(static_cast<std::size_t>(a.num_triangles())), bb(static_cast<std::size_t>(b.num_triangles()));
    wa.swept_boxes<K>(a, xa0, xa1, gap, [&ba](int t) -> Kdop<K>& { return ba[static_cast<std::size_t>(t)]; });
    wb.swept_boxes<K>(b, xb0, xb1, gap, [&bb](int t) -> Kdop<K>& { return bb[static_cast<std::size_t>(t)]; });
    for (int i = 0; i < a.num_triangles(); ++i) {
      for (int j = 0; j < b.num_triangles(); ++j) {
        if (ba[static_cast<std::size_t>(i)].overlaps(bb[static_cast<std::size_t>(j)])) det.add_candidates(i, j);
      }
    }
  });
  det.run_features(xa0, xa1, xb0, xb1, gap, out, stats);
}

}  // namespace lumen::collision
