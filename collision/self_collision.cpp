// Self-collision: swept k-DOP BVH refitted per call, self-traversal, deduplicated feature pairs, CCD.
#include "collision/self_collision.hpp"

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
#include "collision/kdop.hpp"

namespace lumen::collision {

namespace {

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

// True when v is one of the three ids in t.
bool has_vertex(const int* t, int v) { return t[0] == v || t[1] == v || t[2] == v; }

// Row i of a points array as a vector.
Vec3 row(const PointsRef& x, int i) { return Vec3(x(i, 0), x(i, 1), x(i, 2)); }

// Throw unless x is n x 3 with finite entries; `name` names the parameter.
void check_points(const PointsRef& x, int n, const char* name) {
  if (x.rows() != n) {
    throw std::invalid_argument(std::string(name) + " has " + std::to_string(x.rows()) +
                                " rows, expected n_points = " + std::to_string(n));
  }
  for (int i = 0; i < n; ++i) {
    for (int d = 0; d < 3; ++d) {
      if (!std::isfinite(x(i, d))) {
        std::ostringstream msg;
        msg << name << "(" << i << ", " << d << ") must be finite, got " << x(i, d);
        throw std::invalid_argument(msg.str());
      }
    }
  }
}

}  // namespace

struct SelfCollision::Impl {
  using AnyBvh = std::variant<KdopBvh<6>, KdopBvh<14>, KdopBvh<18>, KdopBvh<26>>;

  int n_points = 0;
  int k = 26;
  int n_tris = 0;
  std::vector<int> tris;       // triangles, n_tris x 3 vertex ids
  std::vector<int> edges;      // unique edges, n_edges x 2 vertex ids (first < second), sorted
  std::vector<int> tri_edges;  // edge ids of each triangle, n_tris x 3: (v0 v1), (v1 v2), (v2 v0)
  AnyBvh bvh;
  bool built = false;

  // Per-call scratch, reused across calls.
  std::vector<double> centres;          // triangle centroids, n_tris x 3, metres
  std::vector<std::uint64_t> vf_keys;   // vertex id << tri_bits | triangle id
  std::vector<std::uint64_t> ee_keys;   // edge id << edge_bits | edge id, first < second
  std::vector<std::uint64_t> sort_tmp;  // radix sort scratch
  std::vector<double> proj;             // vertex projections on the k-DOP axes at x0 then x1, n_points x k
  std::vector<double> vbox;             // swept axis-aligned box of each vertex: lo xyz, hi xyz, n_points x 6
  double feature_pad = 0.0;             // feature-box overlap margin: 2 gap plus rounding, metres
  std::vector<int> used_vertices;       // vertices referenced by the triangles, ascending
  int tri_bits = 0, edge_bits = 0, point_bits = 0;  // bit widths of the ids in the keys
  std::vector<FeaturePair> tested;      // the feature pairs run by the last call
  long bv_overlaps = 0;
  // k-DOP study (off by default): overlapping leaf pairs of the call and running totals.
  bool classify = false;
  std::vector<std::pair<int, int>> overlap_pairs;  // n_overlaps, triangle ids
  std::vector<std::uint64_t> hit_vf, hit_ee;       // keys of the feature pairs in contact, sorted
  SelfCollision::OverlapTotals totals;

  // Validate and store the topology; derive the unique edge list.
  Impl(const TrisRef& t, int n, int kdop) : n_points(n), k(validate_kdop(kdop)) {
    if (n < 0) throw std::invalid_argument("n_points must be >= 0, got " + std::to_string(n));
    n_tris = static_cast<int>(t.rows());
    tris.resize(static_cast<std::size_t>(3 * n_tris));
    for (int i = 0; i < n_tris; ++i) {
      for (int j = 0; j < 3; ++j) {
        const int v = t(i, j);
        if (v < 0 || v >= n) {
          throw std::invalid_argument("tris(" + std::to_string(i) + ", " + std::to_string(j) + ") must be in [0, " +
                                      std::to_string(n) + "), got " + std::to_string(v));
        }
        tris[static_cast<std::size_t>(3 * i + j)] = v;
      }
      if (t(i, 0) == t(i, 1) || t(i, 1) == t(i, 2) || t(i, 0) == t(i, 2)) {
        throw std::invalid_argument("tris row " + std::to_string(i) + " repeats a vertex: (" + std::to_string(t(i, 0)) +
                                    ", " + std::to_string(t(i, 1)) + ", " + std::to_string(t(i, 2)) + ")");
      }
    }
    // Unique edges: sort (edge key, triangle slot) and number the distinct keys.
    std::vector<std::pair<std::uint64_t, int>> slots;
    slots.reserve(static_cast<std::size_t>(3 * n_tris));
    for (int i = 0; i < n_tris; ++i) {
      for (int j = 0; j < 3; ++j) {
        const int a = tris[static_cast<std::size_t>(3 * i + j)];
        const int b = tris[static_cast<std::size_t>(3 * i + (j + 1) % 3)];
        slots.emplace_back(pack(std::min(a, b), std::max(a, b)), 3 * i + j);
      }
    }
    std::sort(slots.begin(), slots.end());
    tri_edges.resize(static_cast<std::size_t>(3 * n_tris));
    for (std::size_t s = 0; s < slots.size(); ++s) {
      if (s == 0 || slots[s].first != slots[s - 1].first) {
        edges.push_back(key_hi(slots[s].first));
        edges.push_back(key_lo(slots[s].first));
      }
      tri_edges[static_cast<std::size_t>(slots[s].second)] = static_cast<int>(edges.size() / 2) - 1;
    }
    for (int v : tris) used_vertices.push_back(v);
    std::sort(used_vertices.begin(), used_vertices.end());
    used_vertices.erase(std::unique(used_vertices.begin(), used_vertices.end()), used_vertices.end());
    tri_bits = id_bits(n_tris);
    edge_bits = id_bits(static_cast<int>(edges.size() / 2));
    point_bits = id_bits(n_points);
    // The BVH type for this k (the only switch on k; the hot loops are templates).
    switch (k) {
      case 6: bvh.emplace<KdopBvh<6>>(); break;
      case 14: bvh.emplace<KdopBvh<14>>(); break;
      case 18: bvh.emplace<KdopBvh<18>>(); break;
      default: bvh.emplace<KdopBvh<26>>(); break;
    }
  }

  // Compact feature pair keys, ordered as (first id, second id).
  std::uint64_t vf_key(int v, int t) const { return (static_cast<std::uint64_t>(v) << tri_bits) | static_cast<std::uint64_t>(t); }
  std::uint64_t ee_key(int e, int g) const { return (static_cast<std::uint64_t>(e) << edge_bits) | static_cast<std::uint64_t>(g); }

  const int* tri(int t) const { return &tris[static_cast<std::size_t>(3 * t)]; }
  const int* edge(int e) const { return &edges[static_cast<std::size_t>(2 * e)]; }

  // Median-split topology over the triangle centroids at positions x.
  void build(const PointsRef& x) {
    centres.resize(static_cast<std::size_t>(3 * n_tris));
    for (int t = 0; t < n_tris; ++t) {
      for (int d = 0; d < 3; ++d) {
        centres[static_cast<std::size_t>(3 * t + d)] =
            (x(tri(t)[0], d) + x(tri(t)[1], d) + x(tri(t)[2], d)) / 3.0;
      }
    }
    std::visit([&](auto& b) { b.build(centres.data(), n_tris); }, bvh);
    built = true;
  }

  // Swept k-DOPs of all triangles over x0 -> x1 (each the k-DOP of its 6 vertex positions), inflated by
  // gap, written to out(t). The vertex projections are computed once per vertex.
  template <int K, class Out>
  void swept_boxes(const PointsRef& x0, const PointsRef& x1, double gap, Out&& out) {
    constexpr int A = Kdop<K>::kAxes;
    proj.resize(static_cast<std::size_t>(2 * A) * static_cast<std::size_t>(n_points));
    for (const int v : used_vertices) {
      double all[13];
      double* p = &proj[static_cast<std::size_t>(2 * A) * static_cast<std::size_t>(v)];
      kdop_project_all(x0.data() + v * x0.outerStride(), all);
      for (int a = 0; a < A; ++a) p[a] = all[KdopAxisIds<K>::ids[a]];
      kdop_project_all(x1.data() + v * x1.outerStride(), all);
      for (int a = 0; a < A; ++a) p[A + a] = all[KdopAxisIds<K>::ids[a]];
    }
    // Swept axis-aligned box of each vertex (the first three axes of every k-DOP are x, y, z), for the
    // per-feature pre-test; the margin covers both features' gap inflation and rounding.
    vbox.resize(static_cast<std::size_t>(6) * static_cast<std::size_t>(n_points));
    double scale = 0.0;
    for (const int v : used_vertices) {
      const double* p = &proj[static_cast<std::size_t>(2 * A) * static_cast<std::size_t>(v)];
      double* b = &vbox[static_cast<std::size_t>(6) * static_cast<std::size_t>(v)];
      for (int a = 0; a < 3; ++a) {
        b[a] = std::min(p[a], p[A + a]);
        b[3 + a] = std::max(p[a], p[A + a]);
        scale = std::max({scale, std::abs(b[a]), std::abs(b[3 + a])});
      }
    }
    feature_pad = 2.0 * gap * (1.0 + 1e-12) + 64.0 * std::numeric_limits<double>::epsilon() * scale;
    for (int t = 0; t < n_tris; ++t) {
      Kdop<K>& box = out(t);
      const double* p[3];
      for (int j = 0; j < 3; ++j) p[j] = &proj[static_cast<std::size_t>(2 * A) * static_cast<std::size_t>(tri(t)[j])];
      for (int a = 0; a < A; ++a) {
        box.lo[a] = std::min({p[0][a], p[0][A + a], p[1][a], p[1][A + a], p[2][a], p[2][A + a]});
        box.hi[a] = std::max({p[0][a], p[0][A + a], p[1][a], p[1][A + a], p[2][a], p[2][A + a]});
      }
      box.inflate(gap);
    }
  }

  // Candidate features of an overlapping triangle pair: vertices against the other face and edge pairs,
  // skipping those that share a vertex (so neighbours still test their remaining features).
  void add_candidates(int ta, int tb) {
    ++bv_overlaps;
    if (classify) overlap_pairs.emplace_back(ta, tb);
    const int* A = tri(ta);
    const int* B = tri(tb);
    for (int i = 0; i < 3; ++i) {
      if (!has_vertex(B, A[i])) vf_keys.push_back(vf_key(A[i], tb));
      if (!has_vertex(A, B[i])) vf_keys.push_back(vf_key(B[i], ta));
    }
    for (int i = 0; i < 3; ++i) {
      const int ea = tri_edges[static_cast<std::size_t>(3 * ta + i)];
      const int* va = edge(ea);
      for (int j = 0; j < 3; ++j) {
        const int eb = tri_edges[static_cast<std::size_t>(3 * tb + j)];
        const int* vb = edge(eb);
        if (va[0] == vb[0] || va[0] == vb[1] || va[1] == vb[0] || va[1] == vb[1]) continue;
        ee_keys.push_back(ee_key(std::min(ea, eb), std::max(ea, eb)));
      }
    }
  }

  // Whether the swept boxes of two vertex sets overlap within feature_pad (false: no contact is possible).
  bool feature_boxes_overlap(const int* va, int na, const int* vb, int nb) const {
    for (int a = 0; a < 3; ++a) {
      double lo_a = vbox[6 * static_cast<std::size_t>(va[0]) + a], hi_a = vbox[6 * static_cast<std::size_t>(va[0]) + 3 + a];
      for (int i = 1; i < na; ++i) {
        lo_a = std::min(lo_a, vbox[6 * static_cast<std::size_t>(va[i]) + a]);
        hi_a = std::max(hi_a, vbox[6 * static_cast<std::size_t>(va[i]) + 3 + a]);
      }
      double lo_b = vbox[6 * static_cast<std::size_t>(vb[0]) + a], hi_b = vbox[6 * static_cast<std::size_t>(vb[0]) + 3 + a];
      for (int i = 1; i < nb; ++i) {
        lo_b = std::min(lo_b, vbox[6 * static_cast<std::size_t>(vb[i]) + a]);
        hi_b = std::max(hi_b, vbox[6 * static_cast<std::size_t>(vb[i]) + 3 + a]);
      }
      if (lo_a > hi_b + feature_pad || lo_b > hi_a + feature_pad) return false;
    }
    return true;
  }

  // Reset the per-call candidates and statistics.
  void begin_call() {
    vf_keys.clear();
    ee_keys.clear();
    tested.clear();
    bv_overlaps = 0;
    overlap_pairs.clear();
    hit_vf.clear();
    hit_ee.clear();
  }

  // Whether an overlapping pair has a feature pair in contact (the keys add_candidates would make).
  bool pair_has_contact(int ta, int tb) const {
    const int* A = tri(ta);
    const int* B = tri(tb);
    auto has = [](const std::vector<std::uint64_t>& v, std::uint64_t key) {
      return std::binary_search(v.begin(), v.end(), key);
    };
    for (int i = 0; i < 3; ++i) {
      if (!has_vertex(B, A[i]) && has(hit_vf, vf_key(A[i], tb))) return true;
      if (!has_vertex(A, B[i]) && has(hit_vf, vf_key(B[i], ta))) return true;
    }
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        const int ea = tri_edges[static_cast<std::size_t>(3 * ta + i)];
        const int eb = tri_edges[static_cast<std::size_t>(3 * tb + j)];
        if (has(hit_ee, ee_key(std::min(ea, eb), std::max(ea, eb)))) return true;
      }
    return false;
  }

  // Add this call's overlaps, split by whether they hold a contact, to the running totals.
  void classify_overlaps() {
    std::sort(hit_vf.begin(), hit_vf.end());
    std::sort(hit_ee.begin(), hit_ee.end());
    ++totals.calls;
    totals.overlaps += static_cast<long>(overlap_pairs.size());
    for (const auto& [ta, tb] : overlap_pairs) {
      const bool contact = pair_has_contact(ta, tb);
      totals.overlaps_with_contact += contact;
      const int* A = tri(ta);
      const int* B = tri(tb);
      if (has_vertex(B, A[0]) || has_vertex(B, A[1]) || has_vertex(B, A[2])) continue;
      ++totals.separate_overlaps;
      totals.separate_with_contact += contact;
    }
  }

  // Deduplicate the candidates and run each feature pair's elementary test once, in sorted order.
  void run_features(const PointsRef& x0, const PointsRef& x1, double gap, std::vector<Contact>& out,
                    CollisionStats* stats) {
    radix_sort(vf_keys, sort_tmp, point_bits + tri_bits);
    vf_keys.erase(std::unique(vf_keys.begin(), vf_keys.end()), vf_keys.end());
    radix_sort(ee_keys, sort_tmp, 2 * edge_bits);
    ee_keys.erase(std::unique(ee_keys.begin(), ee_keys.end()), ee_keys.end());
    tested.reserve(vf_keys.size() + ee_keys.size());
    // Vertex-face tests.
    for (const std::uint64_t key : vf_keys) {
      const int p = static_cast<int>(key >> tri_bits);
      const int* f = tri(static_cast<int>(key & ((std::uint64_t{1} << tri_bits) - 1)));
      tested.push_back(FeaturePair{FeatureKind::VertexFace, {p, f[0], f[1], f[2]}});
      if (!feature_boxes_overlap(&p, 1, f, 3)) continue;  // swept boxes apart: the elementary test would say no
      CcdHit hit;
      if (vertex_face_ccd(row(x0, p), row(x0, f[0]), row(x0, f[1]), row(x0, f[2]), row(x1, p), row(x1, f[0]),
                          row(x1, f[1]), row(x1, f[2]), gap, &hit)) {
        Contact c;
        c.kind = FeatureKind::VertexFace;
        c.v[0] = p;
        c.v[1] = f[0];
        c.v[2] = f[1];
        c.v[3] = f[2];
        c.toi = hit.toi;
        c.s = hit.s;
        c.t = hit.t;
        out.push_back(c);
        if (classify) hit_vf.push_back(key);
      }
    }
    // Edge-edge tests.
    for (const std::uint64_t key : ee_keys) {
      const int* e = edge(static_cast<int>(key >> edge_bits));
      const int* g = edge(static_cast<int>(key & ((std::uint64_t{1} << edge_bits) - 1)));
      tested.push_back(FeaturePair{FeatureKind::EdgeEdge, {e[0], e[1], g[0], g[1]}});
      if (!feature_boxes_overlap(e, 2, g, 2)) continue;  // swept boxes apart: the elementary test would say no
      CcdHit hit;
      if (edge_edge_ccd(row(x0, e[0]), row(x0, e[1]), row(x0, g[0]), row(x0, g[1]), row(x1, e[0]), row(x1, e[1]),
                        row(x1, g[0]), row(x1, g[1]), gap, &hit)) {
        Contact c;
        c.kind = FeatureKind::EdgeEdge;
        c.v[0] = e[0];
        c.v[1] = e[1];
        c.v[2] = g[0];
        c.v[3] = g[1];
        c.toi = hit.toi;
        c.s = hit.s;
        c.t = hit.t;
        out.push_back(c);
        if (classify) hit_ee.push_back(key);
      }
    }
    if (classify) classify_overlaps();
    if (stats) {
      stats->bv_overlaps = bv_overlaps;
      stats->feature_tests = static_cast<long>(tested.size());
      stats->contacts = static_cast<long>(out.size());
    }
  }

  // Throw unless x0, x1 are n_points x 3 and finite and gap is finite and >= 0.
  void check_call(const PointsRef& x0, const PointsRef& x1, double gap) const {
    check_points(x0, n_points, "x0");
    check_points(x1, n_points, "x1");
    if (!(gap >= 0.0) || !std::isfinite(gap)) {
      std::ostringstream msg;
      msg << "gap must be finite and >= 0 metres, got " << gap;
      throw std::invalid_argument(msg.str());
    }
  }
};

SelfCollision::SelfCollision(const TrisRef& tris, int n_points, int kdop)
    : impl_(std::make_unique<Impl>(tris, n_points, kdop)) {}

SelfCollision::SelfCollision(const TrisRef& tris, const PointsRef& rest, int kdop)
    : impl_(std::make_unique<Impl>(tris, static_cast<int>(rest.rows()), kdop)) {
  check_points(rest, impl_->n_points, "rest");
  impl_->build(rest);
}

SelfCollision::~SelfCollision() = default;
SelfCollision::SelfCollision(SelfCollision&&) noexcept = default;
SelfCollision& SelfCollision::operator=(SelfCollision&&) noexcept = default;

void SelfCollision::rebuild(const PointsRef& x) {
  check_points(x, impl_->n_points, "x");
  impl_->build(x);
}

void SelfCollision::detect(const PointsRef& x0, const PointsRef& x1, double gap, std::vector<Contact>& out,
                           CollisionStats* stats) {
  Impl& im = *impl_;
  im.check_call(x0, x1, gap);
  out.clear();
  im.begin_call();
  if (!im.built) im.build(x0);
  // Refit the swept leaves and internal nodes, then collect overlapping leaf pairs by self-traversal.
  std::visit(
      [&](auto& b) {
        constexpr int K = std::decay_t<decltype(b.leaf_box(0))>::kAxes * 2;
        im.swept_boxes<K>(x0, x1, gap, [&b](int t) -> Kdop<K>& { return b.leaf_box(t); });
        b.refit();
        b.self_pairs([&](int ta, int tb) { im.add_candidates(ta, tb); });
      },
      im.bvh);
  im.run_features(x0, x1, gap, out, stats);
}

void SelfCollision::detect_brute_force(const PointsRef& x0, const PointsRef& x1, double gap,
                                       std::vector<Contact>& out, CollisionStats* stats) {
  Impl& im = *impl_;
  im.check_call(x0, x1, gap);
  out.clear();
  im.begin_call();
  // All pairs of swept triangle k-DOPs, no hierarchy.
  auto all_pairs = [&](auto k_tag) {
    constexpr int K = decltype(k_tag)::value;
    std::vector<Kdop<K>> boxes(static_cast<std::size_t>(im.n_tris));
    im.swept_boxes<K>(x0, x1, gap, [&boxes](int t) -> Kdop<K>& { return boxes[static_cast<std::size_t>(t)]; });
    for (int a = 0; a < im.n_tris; ++a) {
      for (int b = a + 1; b < im.n_tris; ++b) {
        if (boxes[static_cast<std::size_t>(a)].overlaps(boxes[static_cast<std::size_t>(b)])) im.add_candidates(a, b);
      }
    }
  };
  switch (im.k) {
    case 6: all_pairs(std::integral_constant<int, 6>{}); break;
    case 14: all_pairs(std::integral_constant<int, 14>{}); break;
    case 18: all_pairs(std::integral_constant<int, 18>{}); break;
    default: all_pairs(std::integral_constant<int, 26>{}); break;
  }
  im.run_features(x0, x1, gap, out, stats);
}

const std::vector<FeaturePair>& SelfCollision::tested_features() const { return impl_->tested; }
int SelfCollision::kdop() const { return impl_->k; }
void SelfCollision::set_classify_overlaps(bool on) { impl_->classify = on; }
SelfCollision::OverlapTotals SelfCollision::overlap_totals() const { return impl_->totals; }
int SelfCollision::num_points() const { return impl_->n_points; }
int SelfCollision::num_triangles() const { return impl_->n_tris; }
int SelfCollision::num_edges() const { return static_cast<int>(impl_->edges.size() / 2); }

}  // namespace lumen::collision
