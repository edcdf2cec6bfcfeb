#pragma once
// Self-collision of a triangle surface in motion: swept k-DOP BVH, feature pairs, contacts.
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

namespace lumen::collision {

// Row-major n x 3 points (metres) and triangles (indices into the points); plain arrays, no physics types.
using PointsRef = Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>;
using TrisRef = Eigen::Ref<const Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>>;

enum class FeatureKind : std::uint8_t { VertexFace, EdgeEdge };

// One contact between two features, vertex ids refer to the point array (mesh node ids).
struct Contact {
  FeatureKind kind = FeatureKind::VertexFace;
  int v[4] = {-1, -1, -1, -1};  // vf: p, a, b, c; ee: a, b, c, d
  double toi = 1.0;             // time of contact in [0, 1]
  double s = 0.0, t = 0.0;      // vf: barycentric (u, v) on abc; ee: parameters on ab and cd
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

// Which k-DOP: 6 (AABB), 14, 18 or 26 (the paper's 13 axes).
int validate_kdop(int k);  // returns k, throws std::invalid_argument otherwise

// Self-collision detector over a fixed triangle topology (the surface as an index map).
class SelfCollision {
 public:
  // The BVH topology is built by median split at the first detect() call, over its x0.
  SelfCollision(const TrisRef& tris, int n_points, int kdop = 26);
  // The same with the BVH topology built now over rest positions (n_points x 3, metres).
  SelfCollision(const TrisRef& tris, const PointsRef& rest, int kdop = 26);
  ~SelfCollision();
  SelfCollision(SelfCollision&&) noexcept;
  SelfCollision& operator=(SelfCollision&&) noexcept;

  // Refit the swept BVH for motion x0 -> x1 (both n_points x 3), traverse it against itself, and run
  // each vertex-face and edge-edge feature pair once. Contacts within `gap` are appended to `out`
  // (cleared first). Pairs sharing a vertex skip only the features that share it. Each leaf is the k-DOP
  // of its triangle's 6 positions inflated by gap metres; feature pairs run in sorted order (vf by
  // (vertex, triangle), then ee by (edge, edge)), so the output is deterministic.
  void detect(const PointsRef& x0, const PointsRef& x1, double gap, std::vector<Contact>& out,
              CollisionStats* stats = nullptr);
  // The same with all pairs of triangle k-DOPs instead of the BVH (the paper's way; the oracle in tests).
  void detect_brute_force(const PointsRef& x0, const PointsRef& x1, double gap, std::vector<Contact>& out,
                          CollisionStats* stats = nullptr);

  // Rebuild the BVH topology over positions x (n_points x 3, metres), e.g. after a large deformation.
  void rebuild(const PointsRef& x);
  // The feature pairs the last detect call ran, once each, in the order run (sorted by kind then ids).
  const std::vector<FeaturePair>& tested_features() const;
  int kdop() const;
  int num_points() const;
  int num_triangles() const;
  int num_edges() const;  // unique edges of the triangle set

  // k-DOP study: when on, every detect call also classifies its overlapping leaf pairs into those with at
  // least one contact among their features and those without (bounding-volume false positives). Costs about
  // 15 lookups per overlap, so it is off by default. Totals accumulate over calls until reset.
  void set_classify_overlaps(bool on);
  struct OverlapTotals {
    long calls = 0;
    long overlaps = 0;               // leaf-leaf k-DOP overlaps
    long overlaps_with_contact = 0;  // of which at least one feature pair reported a contact
    long separate_overlaps = 0;      // overlaps of triangles that share no vertex (neighbours always overlap)
    long separate_with_contact = 0;  // of which at least one feature pair reported a contact
  };
  OverlapTotals overlap_totals() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Exact discrete check: number of pairs of triangles (not sharing a vertex) that intersect at positions x,
// with exact predicates (independent of the CCD code). Triangles sharing a vertex are checked for
// intersection beyond the shared vertex/edge.
// Closed sets: triangles touching at a point count as intersecting. Declared with more in intersect.hpp.
long count_intersecting_pairs(const PointsRef& x, const TrisRef& tris);

}  // namespace lumen::collision
