#pragma once
// k-DOPs (k = 6, 14, 18, 26 over the paper's 13 axes) and a binary BVH of them with a fixed topology.
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace lumen::collision {

// The paper's 13 k-DOP axes, unnormalised integer directions, in the paper's order.
inline constexpr int kKdopAxes[13][3] = {{1, 0, 0},  {0, 1, 0},  {0, 0, 1}, {1, 1, 1},  {1, 1, -1},
                                         {1, -1, 1}, {1, -1, -1}, {1, 1, 0}, {1, 0, 1},  {0, 1, 1},
                                         {1, -1, 0}, {1, 0, -1}, {0, 1, -1}};

// Which of the 13 axes a k-DOP uses: k = 6 the coordinate axes, 14 adds the 4 diagonals, 18 adds the
// 6 edge axes instead, 26 uses all 13.
template <int K>
struct KdopAxisIds;
template <>
struct KdopAxisIds<6> {
  static constexpr int ids[3] = {0, 1, 2};
};
template <>
struct KdopAxisIds<14> {
  static constexpr int ids[7] = {0, 1, 2, 3, 4, 5, 6};
};
template <>
struct KdopAxisIds<18> {
  static constexpr int ids[9] = {0, 1, 2, 7, 8, 9, 10, 11, 12};
};
template <>
struct KdopAxisIds<26> {
  static constexpr int ids[13] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
};

// Projections of point p (3 doubles, metres) on all 13 unnormalised axes, same order as kKdopAxes.
inline void kdop_project_all(const double* p, double out[13]) {
  const double x = p[0], y = p[1], z = p[2];
  out[0] = x;
  out[1] = y;
  out[2] = z;
  out[3] = x + y + z;
  out[4] = x + y - z;
  out[5] = x - y + z;
  out[6] = x - y - z;
  out[7] = x + y;
  out[8] = x + z;
  out[9] = y + z;
  out[10] = x - y;
  out[11] = x - z;
  out[12] = y - z;
}

// Euclidean length of axis `id` of kKdopAxes (1, sqrt 2 or sqrt 3).
inline double kdop_axis_norm(int id) {
  const int nz = (kKdopAxes[id][0] != 0) + (kKdopAxes[id][1] != 0) + (kKdopAxes[id][2] != 0);
  return std::sqrt(static_cast<double>(nz));
}

// A k-DOP: the interval of a point set's projections on each of the k/2 axes (struct of min and max arrays).
template <int K>
struct Kdop {
  static_assert(K == 6 || K == 14 || K == 18 || K == 26, "k must be 6, 14, 18 or 26");
  static constexpr int kAxes = K / 2;
  double lo[kAxes];  // minimum projection on each axis (metres times the axis length)
  double hi[kAxes];  // maximum projection on each axis

  // Empty k-DOP (contains nothing, overlaps nothing).
  void clear() {
    for (int a = 0; a < kAxes; ++a) {
      lo[a] = std::numeric_limits<double>::infinity();
      hi[a] = -std::numeric_limits<double>::infinity();
    }
  }
  // Grow to contain point p (3 doubles).
  void add_point(const double* p) {
    double all[13];
    kdop_project_all(p, all);
    for (int a = 0; a < kAxes; ++a) {
      const double v = all[KdopAxisIds<K>::ids[a]];
      lo[a] = std::min(lo[a], v);
      hi[a] = std::max(hi[a], v);
    }
  }
  // Grow to contain another k-DOP.
  void merge(const Kdop& o) {
    for (int a = 0; a < kAxes; ++a) {
      lo[a] = std::min(lo[a], o.lo[a]);
      hi[a] = std::max(hi[a], o.hi[a]);
    }
  }
  // Inflate so that every point within `margin` metres of the bounded set is inside, plus a relative pad
  // covering the rounding of the diagonal projections and of this subtraction (a few ulps of the
  // coordinates' magnitude, taken from the exact coordinate-axis intervals).
  void inflate(double margin) {
    const double scale = std::max(std::abs(lo[0]), std::abs(hi[0])) + std::max(std::abs(lo[1]), std::abs(hi[1])) +
                         std::max(std::abs(lo[2]), std::abs(hi[2]));
    const double pad_round = 8.0 * std::numeric_limits<double>::epsilon() * scale;
    for (int a = 0; a < kAxes; ++a) {
      const double pad = margin * kdop_axis_norm(KdopAxisIds<K>::ids[a]) * (1.0 + 1e-12) + pad_round;
      lo[a] -= pad;
      hi[a] += pad;
    }
  }
  // True when the intervals intersect (closed) on every axis.
  bool overlaps(const Kdop& o) const {
    for (int a = 0; a < kAxes; ++a) {
      if (lo[a] > o.hi[a] || o.lo[a] > hi[a]) return false;
    }
    return true;
  }
  // True when point p (3 doubles) projects inside every interval.
  bool contains(const double* p) const {
    double all[13];
    kdop_project_all(p, all);
    for (int a = 0; a < kAxes; ++a) {
      const double v = all[KdopAxisIds<K>::ids[a]];
      if (v < lo[a] || v > hi[a]) return false;
    }
    return true;
  }
  // Sum of the interval widths on the three coordinate axes (a size measure for traversal order), metres.
  double extent() const { return (hi[0] - lo[0]) + (hi[1] - lo[1]) + (hi[2] - lo[2]); }
};

// Topology of a binary BVH over n primitives, one primitive per leaf: built once (median split of the
// primitive centres), immutable afterwards, independent of k. The boxes live in BvhBoxes<K>, so that one
// topology can be shared by several refit workspaces.
class BvhTopology {
 public:
  struct Node {
    int left = -1, right = -1;  // children (internal nodes)
    int prim = -1;              // primitive (leaves), -1 for internal nodes
  };

  // Build from primitive centres (n x 3 row-major, metres); the previous topology is discarded.
  void build(const double* centres, int n) {
    nodes_.clear();
    leaf_of_prim_.assign(static_cast<std::size_t>(n), -1);
    if (n > 0) {
      nodes_.reserve(static_cast<std::size_t>(2 * n - 1));
      std::vector<int> prims(static_cast<std::size_t>(n));
      for (int i = 0; i < n; ++i) prims[static_cast<std::size_t>(i)] = i;
      build_range(centres, prims.data(), 0, n);
    }
  }
  int num_prims() const { return static_cast<int>(leaf_of_prim_.size()); }
  int num_nodes() const { return static_cast<int>(nodes_.size()); }
  // Node i (0 is the root; children always follow their parent).
  const Node& node(int i) const { return nodes_[static_cast<std::size_t>(i)]; }
  // Node index of primitive i's leaf.
  int leaf_of(int prim) const { return leaf_of_prim_[static_cast<std::size_t>(prim)]; }

 private:
  // Top-down median split of prims[begin, end) along the longest axis of their centres' bounds.
  int build_range(const double* c, int* prims, int begin, int end) {
    const int id = static_cast<int>(nodes_.size());
    nodes_.push_back(Node{});
    if (end - begin == 1) {
      nodes_[static_cast<std::size_t>(id)].prim = prims[begin];
      leaf_of_prim_[static_cast<std::size_t>(prims[begin])] = id;
      return id;
    }
    // Bounds of the centres, split axis and median.
    double lo[3] = {c[3 * prims[begin]], c[3 * prims[begin] + 1], c[3 * prims[begin] + 2]};
    double hi[3] = {lo[0], lo[1], lo[2]};
    for (int i = begin + 1; i < end; ++i) {
      for (int d = 0; d < 3; ++d) {
        lo[d] = std::min(lo[d], c[3 * prims[i] + d]);
        hi[d] = std::max(hi[d], c[3 * prims[i] + d]);
      }
    }
    int axis = 0;
    if (hi[1] - lo[1] > hi[axis] - lo[axis]) axis = 1;
    if (hi[2] - lo[2] > hi[axis] - lo[axis]) axis = 2;
    const int mid = begin + (end - begin) / 2;
    std::nth_element(prims + begin, prims + mid, prims + end, [c, axis](int p, int q) {
      const double cp = c[3 * p + axis], cq = c[3 * q + axis];
      return cp < cq || (cp == cq && p < q);
    });
    const int left = build_range(c, prims, begin, mid);
    const int right = build_range(c, prims, mid, end);
    nodes_[static_cast<std::size_t>(id)].left = left;
    nodes_[static_cast<std::size_t>(id)].right = right;
    return id;
  }

  std::vector<Node> nodes_;        // tree, root at 0, children after parents
  std::vector<int> leaf_of_prim_;  // node index of each primitive's leaf
};

// The mutable half of a BVH: one k-DOP per node of a BvhTopology, refitted per frame, and the traversal
// scratch. Every call takes the topology the boxes belong to; reset() sizes them for it.
template <int K>
class BvhBoxes {
 public:
  // Size for topology `topo`, all boxes empty.
  void reset(const BvhTopology& topo) {
    boxes_.resize(static_cast<std::size_t>(topo.num_nodes()));
    for (auto& b : boxes_) b.clear();
    extent_.assign(boxes_.size(), 0.0);
  }
  // reset() unless already sized for topo.
  void fit(const BvhTopology& topo) {
    if (boxes_.size() != static_cast<std::size_t>(topo.num_nodes())) reset(topo);
  }
  // The leaf k-DOP of primitive i, to be written before refit().
  Kdop<K>& leaf_box(const BvhTopology& topo, int prim) { return boxes_[static_cast<std::size_t>(topo.leaf_of(prim))]; }
  const Kdop<K>& leaf_box(const BvhTopology& topo, int prim) const {
    return boxes_[static_cast<std::size_t>(topo.leaf_of(prim))];
  }
  // k-DOP of node i (0 is the root).
  const Kdop<K>& node_box(int i) const { return boxes_[static_cast<std::size_t>(i)]; }

  // Recompute internal nodes from the leaves (children always follow their parent in the node array),
  // and each node's size for the traversal order.
  void refit(const BvhTopology& topo) {
    extent_.resize(boxes_.size());
    for (int i = topo.num_nodes() - 1; i >= 0; --i) {
      const BvhTopology::Node& nd = topo.node(i);
      Kdop<K>& b = boxes_[static_cast<std::size_t>(i)];
      if (nd.prim < 0) {
        b = boxes_[static_cast<std::size_t>(nd.left)];
        b.merge(boxes_[static_cast<std::size_t>(nd.right)]);
      }
      extent_[static_cast<std::size_t>(i)] = b.extent();
    }
  }

  // Self-traversal (after refit): calls f(i, j) (i != j) once for every unordered pair of primitives whose
  // leaf k-DOPs overlap. Each internal node against itself means its two children against each other
  // (each pair of leaves meets at one lowest common ancestor); a pair of overlapping nodes descends the
  // larger one, pushing only child pairs that overlap.
  template <class F>
  void self_pairs(const BvhTopology& topo, F&& f) const {
    self_pairs_where(topo, AnyPair{}, f);
  }

  // Self-traversal restricted to the node pairs keep(a, b) accepts: f(i, j) for the overlapping leaf pairs
  // whose every ancestor pair was accepted. keep must accept a pair whenever it accepts a pair of their
  // descendants (e.g. "either node holds a flagged primitive"), so that pruning loses no accepted leaf pair.
  template <class Keep, class F>
  void self_pairs_where(const BvhTopology& topo, Keep&& keep, F&& f) const {
    for (int i = 0; i < topo.num_nodes(); ++i) {
      const BvhTopology::Node& nd = topo.node(i);
      if (nd.prim >= 0 || !keep(nd.left, nd.right)) continue;
      stack_.clear();
      if (box(nd.left).overlaps(box(nd.right))) stack_.push_back({nd.left, nd.right});
      descend(topo, *this, topo, keep, f);
    }
  }

  // Traversal of two different trees (after both refits): calls f(i, j) once for every pair of a
  // primitive i of this tree (topology topo) and a primitive j of the other (boxes other, topology
  // other_topo) whose leaf k-DOPs overlap; same descent rule as self_pairs.
  template <class F>
  void cross_pairs(const BvhTopology& topo, const BvhBoxes& other, const BvhTopology& other_topo, F&& f) const {
    stack_.clear();
    if (topo.num_nodes() == 0 || other_topo.num_nodes() == 0) return;
    if (box(0).overlaps(other.box(0))) stack_.push_back({0, 0});
    descend(topo, other, other_topo, AnyPair{}, f);
  }

 private:
  struct Pair {
    int a, b;  // node of this tree (topology ta), node of the other (tb)
  };
  // The traversal's default filter: every node pair.
  struct AnyPair {
    bool operator()(int, int) const { return true; }
  };

  // Pop node pairs off stack_ until empty: a leaf pair is reported, otherwise the larger node (or the
  // one that is not a leaf) is descended, pushing only the child pairs that overlap.
  template <class Keep, class F>
  void descend(const BvhTopology& ta, const BvhBoxes& ob, const BvhTopology& tb, const Keep& keep, F& f) const {
    while (!stack_.empty()) {
      const Pair pr = stack_.back();
      stack_.pop_back();
      const BvhTopology::Node& na = ta.node(pr.a);
      const BvhTopology::Node& nb = tb.node(pr.b);
      if (na.prim >= 0 && nb.prim >= 0) {
        f(na.prim, nb.prim);
      } else if (nb.prim >= 0 || (na.prim < 0 && extent_[static_cast<std::size_t>(pr.a)] >= ob.extent_[static_cast<std::size_t>(pr.b)])) {
        const Kdop<K>& bb = ob.box(pr.b);
        if (keep(na.right, pr.b) && box(na.right).overlaps(bb)) stack_.push_back({na.right, pr.b});
        if (keep(na.left, pr.b) && box(na.left).overlaps(bb)) stack_.push_back({na.left, pr.b});
      } else {
        const Kdop<K>& ba = box(pr.a);
        if (keep(pr.a, nb.right) && ba.overlaps(ob.box(nb.right))) stack_.push_back({pr.a, nb.right});
        if (keep(pr.a, nb.left) && ba.overlaps(ob.box(nb.left))) stack_.push_back({pr.a, nb.left});
      }
    }
  }

  const Kdop<K>& box(int i) const { return boxes_[static_cast<std::size_t>(i)]; }

  std::vector<Kdop<K>> boxes_;       // one k-DOP per node
  std::vector<double> extent_;       // node sizes (Kdop::extent) from the last refit, metres
  mutable std::vector<Pair> stack_;  // traversal scratch
};

// A BVH with its own topology and boxes (BvhTopology + BvhBoxes<K>), for single-owner use: the caller
// builds the topology, writes the leaf k-DOPs and refits the internal nodes bottom-up.
template <int K>
class KdopBvh {
 public:
  // Build the topology from primitive centres (n x 3 row-major, metres); previous boxes are discarded.
  void build(const double* centres, int n) {
    topo_.build(centres, n);
    boxes_.reset(topo_);
  }
  int num_prims() const { return topo_.num_prims(); }
  int num_nodes() const { return topo_.num_nodes(); }
  // The leaf k-DOP of primitive i, to be written before refit().
  Kdop<K>& leaf_box(int prim) { return boxes_.leaf_box(topo_, prim); }
  const Kdop<K>& leaf_box(int prim) const { return boxes_.leaf_box(topo_, prim); }
  // k-DOP of node i (0 is the root).
  const Kdop<K>& node_box(int i) const { return boxes_.node_box(i); }
  // Recompute internal nodes from the leaves.
  void refit() { boxes_.refit(topo_); }
  // See BvhBoxes::self_pairs.
  template <class F>
  void self_pairs(F&& f) const {
    boxes_.self_pairs(topo_, f);
  }
  // See BvhBoxes::cross_pairs: f(i, j) for primitive i of this tree and j of `other`.
  template <class F>
  void cross_pairs(const KdopBvh& other, F&& f) const {
    boxes_.cross_pairs(topo_, other.boxes_, other.topo_, f);
  }
  const BvhTopology& topology() const { return topo_; }

 private:
  BvhTopology topo_;
  BvhBoxes<K> boxes_;
};

}  // namespace lumen::collision
