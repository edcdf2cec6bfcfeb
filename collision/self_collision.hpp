#pragma once
// Self-collision of a triangle surface in motion: swept k-DOP BVH, feature pairs, contacts.
//
// SelfCollision is one CollisionSurface (immutable topology) and one CollisionWorkspace (refit boxes and
// buffers) in one object, with the API its callers (engine, tests, benchmarks, tools) already use. New
// code should keep the two apart (collision/surface.hpp): the surface in the immutable compiled model,
// shared; a workspace in each mutable state; detect_self / detect_pair on (const surface, workspace&).
#include <vector>

#include "collision/surface.hpp"

namespace lumen::collision {

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
  // (vertex, triangle), then ee by (edge, edge)), so the output is deterministic. (detect_self.)
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
  using OverlapTotals = collision::OverlapTotals;
  OverlapTotals overlap_totals() const;

  // The two halves.
  const CollisionSurface& surface() const { return surface_; }
  CollisionWorkspace& workspace() { return workspace_; }

 private:
  CollisionWorkspace workspace_;  // first: the k-DOP choice is validated before the triangles
  CollisionSurface surface_;
};

// Exact discrete check: number of pairs of triangles (not sharing a vertex) that intersect at positions x,
// with exact predicates (independent of the CCD code). Triangles sharing a vertex are checked for
// intersection beyond the shared vertex/edge.
// Closed sets: triangles touching at a point count as intersecting. Declared with more in intersect.hpp.
long count_intersecting_pairs(const PointsRef& x, const TrisRef& tris);

}  // namespace lumen::collision
