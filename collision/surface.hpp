#pragma once
// Collision surfaces in motion, split into what never changes and what every frame rewrites:
//
// - CollisionSurface (immutable once built): the triangles as an index map onto a point array (the
//   volume mesh's nodes), the unique edges, each triangle's edges, the vertices in use and the BVH
//   topology built over rest positions. An immutable compiled model can own one and share it.
// - CollisionWorkspace (mutable, one per simulation state or thread): the choice of k-DOP, the swept
//   k-DOP of every BVH node refitted per call, the per-call buffers and the statistics.
//
// Detection is a free function of (const surface, workspace&, x0, x1, gap, out, stats):
// - detect_self: the surface against itself (the organ's walls);
// - detect_pair: two different surfaces, each with its own points and motion (an instrument against the
//   organ), all vertex-face pairs in both directions and all edge-edge pairs.
// Each has a brute-force twin (all leaf pairs, no BVH) with the same output.
//
// New code should use these. SelfCollision (self_collision.hpp) is the older one-object form, a surface
// and a workspace together, kept for its callers.
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "collision/kdop.hpp"

namespace lumen::collision {

// Row-major n x 3 points (metres) and triangles (indices into the points); plain arrays, no physics types.
using PointsRef = Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>;
using TrisRef = Eigen::Ref<const Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>>;

enum class FeatureKind : std::uint8_t { VertexFace, EdgeEdge };

// One contact between two features of one surface, vertex ids refer to the point array (mesh node ids).
struct Contact {
  FeatureKind kind = FeatureKind::VertexFace;
  int v[4] = {-1, -1, -1, -1};  // vf: p, a, b, c; ee: a, b, c, d
  double toi = 1.0;             // time of contact in [0, 1]
  double s = 0.0, t = 0.0;      // vf: barycentric (u, v) on abc; ee: parameters on ab and cd
};

// Which surface of a pair a vertex id belongs to.
enum class Side : std::uint8_t { A, B };

// One contact between a feature of surface A and one of surface B (detect_pair).
// vf: v = p, a, b, c with p a vertex of surface `vertex_side` and (a, b, c) a face of the other surface,
//     ids into the point array of the surface each belongs to; s, t barycentric (u, v) on abc.
// ee: v = a, b, c, d with edge (a, b) of A and edge (c, d) of B (vertex_side is A); s, t along ab and cd.
struct PairContact {
  FeatureKind kind = FeatureKind::VertexFace;
  Side vertex_side = Side::A;
  int v[4] = {-1, -1, -1, -1};
  double toi = 1.0;
  double s = 0.0, t = 0.0;
  // The side of v[i]: vf -> vertex_side for i = 0, the other side for the face; ee -> A for 0, 1, B for 2, 3.
  Side side_of(int i) const {
    if (kind == FeatureKind::EdgeEdge) return i < 2 ? Side::A : Side::B;
    if (i == 0) return vertex_side;
    return vertex_side == Side::A ? Side::B : Side::A;
  }
};

// Per-call statistics.
struct CollisionStats {
  long bv_overlaps = 0;    // leaf-leaf bounding-volume overlaps between non-adjacent-or-adjacent triangle pairs
  long feature_tests = 0;  // elementary tests run (each feature pair once)
  long contacts = 0;       // features reported in contact
};

// One elementary test's features, vertex ids into the point array: vf -> p, a, b, c (face as stored);
// ee -> a, b, c, d with a < b, c < d and edge (a, b) before edge (c, d) in the unique edge list.
struct FeaturePair {
  FeatureKind kind = FeatureKind::VertexFace;
  int v[4] = {-1, -1, -1, -1};
};

// k-DOP study totals (CollisionWorkspace::set_classify_overlaps).
struct OverlapTotals {
  long calls = 0;
  long overlaps = 0;               // leaf-leaf k-DOP overlaps
  long overlaps_with_contact = 0;  // of which at least one feature pair reported a contact
  long separate_overlaps = 0;      // overlaps of triangles that share no vertex (neighbours always overlap)
  long separate_with_contact = 0;  // of which at least one feature pair reported a contact
};

// Which k-DOP: 6 (AABB), 14, 18 or 26 (the paper's 13 axes).
int validate_kdop(int k);  // returns k, throws std::invalid_argument otherwise

// The immutable topology of a triangle surface over a point array of n_points.
class CollisionSurface {
 public:
  // Validates tris (ids in [0, n_points), no repeated vertex in a row); no BVH yet (build_bvh).
  CollisionSurface(const TrisRef& tris, int n_points);
  // The same with the BVH topology built now over rest positions (n_points = rest.rows(), metres).
  CollisionSurface(const TrisRef& tris, const PointsRef& rest);

  // (Re)build the BVH topology by median split of the triangle centroids at positions x (n_points x 3).
  // The only mutation: call it before sharing the surface.
  void build_bvh(const PointsRef& x);
  bool has_bvh() const { return built_; }

  int num_points() const { return n_points_; }
  int num_triangles() const { return n_tris_; }
  int num_edges() const { return static_cast<int>(edges_.size() / 2); }  // unique edges of the triangle set
  const int* triangle(int t) const { return &tris_[static_cast<std::size_t>(3 * t)]; }  // 3 vertex ids
  const int* edge(int e) const { return &edges_[static_cast<std::size_t>(2 * e)]; }  // 2 ids, first < second
  // Edge id of side j of triangle t: (v0 v1), (v1 v2), (v2 v0).
  int triangle_edge(int t, int j) const { return tri_edges_[static_cast<std::size_t>(3 * t + j)]; }
  const std::vector<int>& used_vertices() const { return used_vertices_; }  // referenced by triangles, ascending
  // The features triangle t owns (each vertex and edge is owned by the lowest-numbered triangle that has it):
  // bit j (0..2) its corner j, bit 3 + j its side j. Self-collision tests a feature pair only from the triangle
  // pair of its owners (a feature's swept box lies inside its owner's), so each pair is generated once.
  std::uint8_t owned_features(int t) const { return owned_[static_cast<std::size_t>(t)]; }
  const BvhTopology& bvh() const { return bvh_; }
  // Bit widths of triangle, edge and point ids (for compact sorted feature keys).
  int tri_bits() const { return tri_bits_; }
  int edge_bits() const { return edge_bits_; }
  int point_bits() const { return point_bits_; }

 private:
  int n_points_ = 0;
  int n_tris_ = 0;
  std::vector<int> tris_;           // n_tris x 3 vertex ids
  std::vector<int> edges_;          // unique edges, n_edges x 2 vertex ids (first < second), sorted
  std::vector<int> tri_edges_;      // edge ids of each triangle, n_tris x 3
  std::vector<int> used_vertices_;  // vertices referenced by the triangles, ascending
  std::vector<std::uint8_t> owned_; // per triangle, the features it owns (owned_features)
  int tri_bits_ = 0, edge_bits_ = 0, point_bits_ = 0;
  BvhTopology bvh_;
  bool built_ = false;
};

// The mutable refit workspace: k-DOP choice, per-node swept boxes, per-call buffers, statistics. One
// workspace serves one surface at a time (its boxes are resized when used with another).
class CollisionWorkspace {
 public:
  explicit CollisionWorkspace(int kdop = 26);  // throws std::invalid_argument unless 6, 14, 18 or 26
  ~CollisionWorkspace();
  CollisionWorkspace(CollisionWorkspace&&) noexcept;
  CollisionWorkspace& operator=(CollisionWorkspace&&) noexcept;

  int kdop() const;
  // The feature pairs the last detect_self call ran, once each, in the order run (sorted by kind then ids).
  const std::vector<FeaturePair>& tested_features() const;
  // k-DOP study: when on, every detect_self call also classifies its overlapping leaf pairs into those with
  // at least one contact among their features and those without (bounding-volume false positives). Costs
  // about 15 lookups per overlap, so it is off by default. Totals accumulate over calls until reset.
  void set_classify_overlaps(bool on);
  OverlapTotals overlap_totals() const;

  struct Impl;

 private:
  friend Impl& workspace_impl(CollisionWorkspace& w);
  std::unique_ptr<Impl> impl_;
};

// Throw std::invalid_argument unless x0, x1 are surface.num_points() x 3 and finite and gap is finite and
// >= 0 (naming the parameter and the value).
void validate_motion(const CollisionSurface& surface, const PointsRef& x0, const PointsRef& x1, double gap);

// Refit the swept BVH for motion x0 -> x1 (both n_points x 3), traverse it against itself, and run
// each vertex-face and edge-edge feature pair once. Contacts within `gap` are appended to `out`
// (cleared first). Pairs sharing a vertex skip only the features that share it. Each leaf is the k-DOP
// of its triangle's 6 positions inflated by gap metres; feature pairs run in sorted order (vf by
// (vertex, triangle), then ee by (edge, edge)), so the output is deterministic.
// Throws std::logic_error when the surface has no BVH yet.
void detect_self(const CollisionSurface& surface, CollisionWorkspace& ws, const PointsRef& x0, const PointsRef& x1,
                 double gap, std::vector<Contact>& out, CollisionStats* stats = nullptr);
// Feature pairs of one surface, kept from one detection for later ones (detect_self_near, MoveFilter): the keys
// detect_self sorts its candidates by, ascending. vf: vertex id << tri_bits | triangle id; ee: edge id << edge_bits |
// edge id, first < second (CollisionSurface's bit widths and ids).
struct NearFeatures {
  std::vector<std::uint64_t> vf, ee;
  std::size_t size() const { return vf.size() + ee.size(); }
};

// detect_self at `gap` (the same contacts, times and order) by one detection at the wider `near_gap` whose hits are
// tested again at `gap`, and the proof a later detection can restrict itself with (MoveFilter): `near` gets every
// feature pair found within near_gap (the pairs of detect_self at near_gap); every other pair stayed farther than
// near_gap apart all along x0 -> x1. Statistics of the near_gap pass (contacts: those at gap).
// Throws std::invalid_argument as detect_self does, and for near_gap below gap.
void detect_self_near(const CollisionSurface& surface, CollisionWorkspace& ws, const PointsRef& x0, const PointsRef& x1,
                      double gap, double near_gap, std::vector<Contact>& out, NearFeatures& near,
                      CollisionStats* stats = nullptr);
// Which feature pairs a restricted self-detection tests: those with a flagged vertex, those listed as near, and
// those whose vertices
// moved relative to each other since a reference motion x0_ref -> x1_ref by at least `margin` metres, at the
// sweep's start or at its end; the relative move of a pair at an end is max |d_i - d_j| over a vertex i of one
// feature and j of the other (d = x0 - x0_ref at the start, x1 - x1_ref at the end; without x0_ref the sweep
// starts where the reference did, d = 0 there). Along both sweeps every vertex moves linearly in the same time, so
// a pair's separation differs between the two at every time by at most the larger of its two relative moves: a
// pair clear by more than g + margin all along the reference motion is clear by more than g on this one.
struct MoveFilter {
  const PointsRef* x1_ref = nullptr;         // n_points x 3; null: no move test (flags only)
  double margin = 0.0;                       // metres, >= 0
  const std::vector<std::uint8_t>* flagged = nullptr;  // n_points entries (nonzero: flagged); null: none
  const PointsRef* x0_ref = nullptr;         // n_points x 3 (needs x1_ref); null: the reference started at x0
  const NearFeatures* near = nullptr;        // pairs tested whatever they moved (detect_self_near's); null: none
};
// detect_self restricted to the pairs `filter` selects: the BVH is refitted in full, but the traversal skips node
// pairs whose vertices can hold no selected pair (none flagged, and the moves under the two nodes, as boxes, differ
// by less than the margin), and only selected features are tested; same order as detect_self, statistics of what
// ran. With every vertex flagged it equals detect_self. Throws std::invalid_argument for flags or reference
// positions of the wrong size, a non-finite reference or a negative margin.
void detect_self_moved(const CollisionSurface& surface, CollisionWorkspace& ws, const PointsRef& x0,
                       const PointsRef& x1, double gap, const MoveFilter& filter, std::vector<Contact>& out,
                       CollisionStats* stats = nullptr);
// The same with all pairs of triangle k-DOPs instead of the BVH (the paper's way; the oracle in tests).
void detect_self_brute_force(const CollisionSurface& surface, CollisionWorkspace& ws, const PointsRef& x0,
                             const PointsRef& x1, double gap, std::vector<Contact>& out,
                             CollisionStats* stats = nullptr);

// Two different surfaces A and B, each with its own points and motion (xa0 -> xa1, xb0 -> xb1) and its
// own workspace (same k). Refits both swept BVHs, traverses one against the other and runs once each:
// every vertex of A against every face of B, every vertex of B against every face of A and every edge
// of A against every edge of B whose triangles' swept k-DOPs (inflated by gap) overlap, with the same
// elementary tests and gap as detect_self and no shared-vertex exclusion (different meshes). Output
// order: vf with the vertex on A by (vertex, B triangle), then vf with the vertex on B by (vertex,
// A triangle), then ee by (A edge, B edge). `stats->bv_overlaps` counts overlapping (A, B) leaf pairs.
// Throws std::invalid_argument for bad motion or gap or different k, std::logic_error without a BVH.
void detect_pair(const CollisionSurface& a, CollisionWorkspace& wa, const PointsRef& xa0, const PointsRef& xa1,
                 const CollisionSurface& b, CollisionWorkspace& wb, const PointsRef& xb0, const PointsRef& xb1,
                 double gap, std::vector<PairContact>& out, CollisionStats* stats = nullptr);
// The same with all (A, B) pairs of triangle k-DOPs instead of the BVHs (the oracle in tests); needs
// no BVH.
void detect_pair_brute_force(const CollisionSurface& a, CollisionWorkspace& wa, const PointsRef& xa0,
                             const PointsRef& xa1, const CollisionSurface& b, CollisionWorkspace& wb,
                             const PointsRef& xb0, const PointsRef& xb1, double gap, std::vector<PairContact>& out,
                             CollisionStats* stats = nullptr);

}  // namespace lumen::collision
