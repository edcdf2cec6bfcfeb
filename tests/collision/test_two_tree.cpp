// Two-tree CCD (detect_pair): an instrument surface against an organ surface, each with its own points and
// motion. The BVH traversal against its brute-force twin (all leaf pairs), ground truth where cheap.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <random>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "collision/kdop.hpp"
#include "collision/surface.hpp"

namespace lumen::collision {
namespace {

using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using Tris = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;

constexpr double kPi = 3.14159265358979323846;
constexpr int kAllK[] = {6, 14, 18, 26};

// A mesh: points and triangles into them.
struct Mesh {
  Points x;
  Tris tris;
};

// Open tube wall along z (radius r, length len, nz x nth quads of 2 triangles), its nodes placed after
// `interior` unused points (as an organ surface indexes only the boundary nodes of the volume mesh).
Mesh tube_wall(int nz, int nth, double r, double len, int interior) {
  Mesh m;
  m.x.resize(interior + (nz + 1) * nth, 3);
  for (int i = 0; i < interior; ++i) m.x.row(i) << 0.1 * r * i, -0.05 * r, 0.5 * len;  // inside, unused
  for (int k = 0; k <= nz; ++k) {
    for (int j = 0; j < nth; ++j) {
      const double th = 2.0 * kPi * j / nth;
      m.x.row(interior + k * nth + j) << r * std::cos(th), r * std::sin(th), len * k / nz;
    }
  }
  m.tris.resize(2 * nz * nth, 3);
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < nth; ++j) {
      const int v00 = interior + k * nth + j, v01 = interior + k * nth + (j + 1) % nth;
      const int v10 = v00 + nth, v11 = v01 + nth;
      m.tris.row(2 * (k * nth + j)) << v00, v01, v11;
      m.tris.row(2 * (k * nth + j) + 1) << v00, v11, v10;
    }
  }
  return m;
}

// Closed sphere-ish mesh of radius r at the origin: an octahedron subdivided `levels` times, projected.
Mesh sphere(double r, int levels) {
  std::vector<Eigen::Vector3d> v = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  std::vector<std::array<int, 3>> f = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                                       {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::make_pair(std::min(a, b), std::max(a, b));
      const auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back((v[static_cast<std::size_t>(a)] + v[static_cast<std::size_t>(b)]).normalized());
      return mid[key] = static_cast<int>(v.size()) - 1;
    };
    std::vector<std::array<int, 3>> g;
    for (const auto& t : f) {
      const int ab = midpoint(t[0], t[1]), bc = midpoint(t[1], t[2]), ca = midpoint(t[2], t[0]);
      g.push_back({t[0], ab, ca});
      g.push_back({ab, t[1], bc});
      g.push_back({ca, bc, t[2]});
      g.push_back({ab, bc, ca});
    }
    f = g;
  }
  Mesh m;
  m.x.resize(static_cast<int>(v.size()), 3);
  for (std::size_t i = 0; i < v.size(); ++i) m.x.row(static_cast<int>(i)) = r * v[i].normalized().transpose();
  m.tris.resize(static_cast<int>(f.size()), 3);
  for (std::size_t i = 0; i < f.size(); ++i) m.tris.row(static_cast<int>(i)) << f[i][0], f[i][1], f[i][2];
  return m;
}

// Rigid pose of rest points: rotation about `axis` by `angle`, then translation.
Points posed(const Points& rest, const Eigen::Vector3d& axis, double angle, const Eigen::Vector3d& shift) {
  const Eigen::Matrix3d R = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
  Points x(rest.rows(), 3);
  for (int i = 0; i < rest.rows(); ++i) x.row(i) = (R * rest.row(i).transpose() + shift).transpose();
  return x;
}

// The result of one detect_pair call (BVH or brute force) and its statistics.
struct PairRun {
  std::vector<PairContact> contacts;
  CollisionStats stats;
};

// Both traversals of one motion: instrument a (xa0 -> xa1) against organ b (xb0 -> xb1).
std::pair<PairRun, PairRun> both(const Mesh& a, const Points& xa0, const Points& xa1, const Mesh& b, const Points& xb0,
                         const Points& xb1, double gap, int k) {
  const CollisionSurface sa(a.tris, a.x), sb(b.tris, b.x);  // BVH topologies over rest
  CollisionWorkspace wa(k), wb(k);
  PairRun bvh, brute;
  detect_pair(sa, wa, xa0, xa1, sb, wb, xb0, xb1, gap, bvh.contacts, &bvh.stats);
  detect_pair_brute_force(sa, wa, xa0, xa1, sb, wb, xb0, xb1, gap, brute.contacts, &brute.stats);
  return {bvh, brute};
}

// Same contacts in the same order, bit for bit, and the same statistics.
void expect_same(const PairRun& got, const PairRun& want, const std::string& what) {
  ASSERT_EQ(got.contacts.size(), want.contacts.size()) << what;
  for (std::size_t i = 0; i < got.contacts.size(); ++i) {
    const PairContact& g = got.contacts[i];
    const PairContact& w = want.contacts[i];
    ASSERT_EQ(std::make_tuple(g.kind, g.vertex_side, g.v[0], g.v[1], g.v[2], g.v[3]),
              std::make_tuple(w.kind, w.vertex_side, w.v[0], w.v[1], w.v[2], w.v[3]))
        << what << " contact " << i;
    ASSERT_EQ(g.toi, w.toi) << what << " contact " << i;
    ASSERT_EQ(g.s, w.s) << what << " contact " << i;
    ASSERT_EQ(g.t, w.t) << what << " contact " << i;
  }
  EXPECT_EQ(got.stats.bv_overlaps, want.stats.bv_overlaps) << what;
  EXPECT_EQ(got.stats.feature_tests, want.stats.feature_tests) << what;
  EXPECT_EQ(got.stats.contacts, static_cast<long>(got.contacts.size())) << what;
}

// Contacts per category: vf with the vertex on A, vf with the vertex on B, ee.
struct Counts {
  int vf_a = 0, vf_b = 0, ee = 0;
};
Counts count(const std::vector<PairContact>& cs) {
  Counts n;
  for (const PairContact& c : cs) {
    if (c.kind == FeatureKind::EdgeEdge) {
      ++n.ee;
    } else {
      (c.vertex_side == Side::A ? n.vf_a : n.vf_b)++;
    }
  }
  return n;
}

// Output is in the documented order (vf on A, vf on B, ee; each sorted by its ids), without duplicates,
// and every id is a valid id of the side it belongs to, used by that side's triangles.
void expect_ordered_and_valid(const std::vector<PairContact>& cs, const Mesh& a, const Mesh& b) {
  auto rank = [](const PairContact& c) {
    return c.kind == FeatureKind::EdgeEdge ? 2 : (c.vertex_side == Side::A ? 0 : 1);
  };
  for (std::size_t i = 0; i < cs.size(); ++i) {
    const PairContact& c = cs[i];
    for (int j = 0; j < 4; ++j) {
      const Mesh& m = c.side_of(j) == Side::A ? a : b;
      ASSERT_GE(c.v[j], 0);
      ASSERT_LT(c.v[j], m.x.rows());
      ASSERT_TRUE((m.tris.array() == c.v[j]).any()) << "id " << c.v[j] << " is not a surface vertex";
    }
    EXPECT_GE(c.toi, 0.0);
    EXPECT_LE(c.toi, 1.0);
    if (i == 0) continue;
    const PairContact& p = cs[i - 1];
    ASSERT_LE(rank(p), rank(c));
    if (rank(p) == rank(c)) {
      ASSERT_TRUE(std::make_tuple(p.v[0], p.v[1], p.v[2], p.v[3]) != std::make_tuple(c.v[0], c.v[1], c.v[2], c.v[3]))
          << "duplicate contact " << i;
      if (c.kind == FeatureKind::EdgeEdge) {
        ASSERT_LE(std::make_tuple(p.v[0], p.v[1]), std::make_tuple(c.v[0], c.v[1]));
      } else {
        ASSERT_LE(p.v[0], c.v[0]);
      }
    }
  }
}

// Organ and instrument of the structured cases: tube of radius 10 mm (with 5 unused interior nodes before
// its wall nodes), sphere of radius 3 mm.
const Mesh& organ() {
  static const Mesh m = tube_wall(16, 24, 0.010, 0.040, 5);
  return m;
}
const Mesh& instrument() {
  static const Mesh m = sphere(0.003, 2);  // 128 triangles
  return m;
}

// The instrument moves rigidly from (pose A) to (pose B) with the organ static; both traversals for every
// k, checked equal; returns the BVH run for k = 26.
PairRun instrument_through(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double angle, double gap) {
  const Mesh& a = instrument();
  const Mesh& b = organ();
  const Points xa0 = posed(a.x, Eigen::Vector3d(0.3, 1.0, 0.2), 0.0, from);
  const Points xa1 = posed(a.x, Eigen::Vector3d(0.3, 1.0, 0.2), angle, to);
  PairRun last;
  for (const int k : kAllK) {
    const auto [bvh, brute] = both(a, xa0, xa1, b, b.x, b.x, gap, k);
    expect_same(bvh, brute, "k = " + std::to_string(k));
    expect_ordered_and_valid(bvh.contacts, a, b);
    last = bvh;
  }
  return last;
}

// ---------------------------------------------------------------------------------------------------

TEST(TwoTree, CrossTraversalReportsEachOverlappingLeafPairOnce) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto random_tree = [&](int n, double size, std::vector<Kdop<26>>& boxes, KdopBvh<26>& bvh) {
    std::vector<double> centres(static_cast<std::size_t>(3 * n));
    boxes.assign(static_cast<std::size_t>(n), Kdop<26>{});
    for (int i = 0; i < n; ++i) {
      const double c[3] = {u(rng), u(rng), u(rng)};
      boxes[static_cast<std::size_t>(i)].clear();
      for (int p = 0; p < 3; ++p) {
        const double q[3] = {c[0] + size * u(rng), c[1] + size * u(rng), c[2] + size * u(rng)};
        boxes[static_cast<std::size_t>(i)].add_point(q);
      }
      for (int d = 0; d < 3; ++d) centres[static_cast<std::size_t>(3 * i + d)] = c[d];
    }
    bvh.build(centres.data(), n);
    for (int i = 0; i < n; ++i) bvh.leaf_box(i) = boxes[static_cast<std::size_t>(i)];
    bvh.refit();
  };
  for (const auto& [na, nb] : {std::pair{1, 1}, std::pair{1, 40}, std::pair{37, 3}, std::pair{150, 90}}) {
    std::vector<Kdop<26>> ba, bb;
    KdopBvh<26> ta, tb;
    random_tree(na, 0.25, ba, ta);
    random_tree(nb, 0.2, bb, tb);
    std::vector<std::pair<int, int>> got, want;
    ta.cross_pairs(tb, [&](int i, int j) { got.emplace_back(i, j); });
    for (int i = 0; i < na; ++i)
      for (int j = 0; j < nb; ++j)
        if (ba[static_cast<std::size_t>(i)].overlaps(bb[static_cast<std::size_t>(j)])) want.emplace_back(i, j);
    std::sort(got.begin(), got.end());
    EXPECT_EQ(got, want) << na << " x " << nb;
    if (na * nb > 1000) {  // the test can fail: there are pairs to find, and pairs to prune
      EXPECT_GT(want.size(), 20u);
      EXPECT_LT(want.size(), static_cast<std::size_t>(na * nb) / 2);
    }
  }
}

// Ground truth: a small triangle falls straight through a large static one (A moving, B static), each
// vertex crossing the plane at t = 0.25; then the same with the roles swapped.
TEST(TwoTree, MovingVertexThroughStaticTriangleHasKnownTimeOfContact) {
  Mesh small, big;
  small.x.resize(3, 3);
  small.x << 0.10, 0.10, 0.0, 0.12, 0.10, 0.0, 0.10, 0.13, 0.0;
  small.tris.resize(1, 3);
  small.tris << 0, 1, 2;
  big.x.resize(4, 3);  // point 0 unused
  big.x << 9.0, 9.0, 9.0, -1.0, -1.0, 0.0, 2.0, -1.0, 0.0, -1.0, 2.0, 0.0;
  big.tris.resize(1, 3);
  big.tris << 1, 2, 3;
  Points s0 = small.x, s1 = small.x;
  s0.col(2).setConstant(0.25);
  s1.col(2).setConstant(-0.75);  // 1 m per frame downwards: the plane z = 0 at t = 0.25
  const double kTol = 1e-5;
  for (const bool small_is_a : {true, false}) {
    for (const int k : kAllK) {
      const Mesh& a = small_is_a ? small : big;
      const Mesh& b = small_is_a ? big : small;
      const CollisionSurface sa(a.tris, a.x), sb(b.tris, b.x);
      CollisionWorkspace wa(k), wb(k);
      std::vector<PairContact> out, brute;
      CollisionStats st;
      if (small_is_a) {
        detect_pair(sa, wa, s0, s1, sb, wb, big.x, big.x, 0.0, out, &st);
        detect_pair_brute_force(sa, wa, s0, s1, sb, wb, big.x, big.x, 0.0, brute);
      } else {
        detect_pair(sa, wa, big.x, big.x, sb, wb, s0, s1, 0.0, out, &st);
        detect_pair_brute_force(sa, wa, big.x, big.x, sb, wb, s0, s1, 0.0, brute);
      }
      ASSERT_EQ(out.size(), 3u) << "k = " << k;  // the three falling vertices, no edge crossings
      EXPECT_EQ(brute.size(), out.size());
      EXPECT_EQ(st.bv_overlaps, 1);
      EXPECT_EQ(st.feature_tests, 3 + 3 + 9);  // every vertex against the other face, every edge pair
      for (int i = 0; i < 3; ++i) {
        const PairContact& c = out[static_cast<std::size_t>(i)];
        EXPECT_EQ(c.kind, FeatureKind::VertexFace);
        EXPECT_EQ(c.vertex_side, small_is_a ? Side::A : Side::B);
        EXPECT_EQ(c.v[0], i);  // the small triangle's vertices, ascending, ids into its own points
        EXPECT_EQ(c.v[1], 1);  // the big face as stored, ids into its points (0 is unused)
        EXPECT_EQ(c.v[2], 2);
        EXPECT_EQ(c.v[3], 3);
        EXPECT_LE(c.toi, 0.25);  // conservative: never after the true time
        EXPECT_GT(c.toi, 0.25 - kTol);
        const double px = small.x(i, 0), py = small.x(i, 1);
        EXPECT_NEAR(c.s, (px + 1.0) / 3.0, kTol);  // p = a + s (b - a) + t (c - a)
        EXPECT_NEAR(c.t, (py + 1.0) / 3.0, kTol);
        EXPECT_EQ(c.side_of(0), small_is_a ? Side::A : Side::B);
        EXPECT_EQ(c.side_of(1), small_is_a ? Side::B : Side::A);
      }
    }
  }
}

// Ground truth for edge-edge: a segment-like sliver triangle sweeps across an edge of a static triangle.
TEST(TwoTree, EdgeSweepingAcrossEdgeHasKnownTimeOfContact) {
  Mesh a, b;
  a.x.resize(3, 3);  // sliver along x at y = 0.5, above the plane: its long edge crosses b's edge x = 0
  a.x << -1.0, 0.5, 0.0, 1.0, 0.5, 0.0, 0.0, 0.5, 0.5;
  a.tris.resize(1, 3);
  a.tris << 0, 1, 2;
  b.x.resize(3, 3);  // static triangle in the plane z = 0 with the edge (0,0,0)-(0,1,0) on x = 0
  b.x << 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.5, 0.0;
  b.tris.resize(1, 3);
  b.tris << 0, 1, 2;
  Points a0 = a.x, a1 = a.x;
  for (int i = 0; i < 3; ++i) {
    a0(i, 2) += 0.4;  // z of the long edge: 0.4 -> -0.6, through z = 0 at t = 0.4
    a1(i, 2) -= 0.6;
  }
  const auto [bvh, brute] = both(a, a0, a1, b, b.x, b.x, 0.0, 26);
  expect_same(bvh, brute, "edge sweep");
  const PairContact* found = nullptr;
  for (const PairContact& c : bvh.contacts) {
    if (c.kind == FeatureKind::EdgeEdge && c.v[0] == 0 && c.v[1] == 1 && c.v[2] == 0 && c.v[3] == 1) found = &c;
  }
  ASSERT_NE(found, nullptr) << "long edge of A against edge x = 0 of B";
  EXPECT_LE(found->toi, 0.4);
  EXPECT_GT(found->toi, 0.4 - 1e-5);
  EXPECT_NEAR(found->s, 0.5, 1e-5);  // the middle of A's edge
  EXPECT_NEAR(found->t, 0.5, 1e-5);  // the middle of B's edge
}

TEST(TwoTree, InstrumentThroughTubeWallEqualsBruteForce) {
  // From inside the lumen, radially out through the wall, turning on the way.
  const PairRun r = instrument_through({0.004, 0.0, 0.02}, {0.013, 0.001, 0.021}, 0.4, 0.0);
  const Counts n = count(r.contacts);
  EXPECT_GT(n.vf_a, 0) << "instrument vertices cross the wall's faces";
  EXPECT_GT(n.vf_b, 0) << "wall vertices cross the instrument's faces";
  EXPECT_GT(n.ee, 0) << "edges cross";
  EXPECT_GT(r.stats.bv_overlaps, 0);
  // With a gap there are at least as many contacts, and the same detection equals brute force.
  const PairRun g = instrument_through({0.004, 0.0, 0.02}, {0.013, 0.001, 0.021}, 0.4, 0.0005);
  EXPECT_GE(g.contacts.size(), r.contacts.size());
}

TEST(TwoTree, GrazingPassEqualsBruteForce) {
  // Along the wall (parallel to the axis), the sphere's surface 0.2 mm past the wall's nodes.
  const double depth = 0.010 - 0.003 + 0.0002;
  const PairRun r = instrument_through({depth, 0.0, 0.008}, {depth, 0.0, 0.030}, 0.1, 0.0);
  EXPECT_GT(r.contacts.size(), 0u) << "the graze touches the wall";
  const PairRun g = instrument_through({depth, 0.0, 0.008}, {depth, 0.0, 0.030}, 0.1, 0.0002);
  EXPECT_GE(g.contacts.size(), r.contacts.size());
}

TEST(TwoTree, AxialMotionInsideTheLumenHasNoContact) {
  for (const double gap : {0.0, 0.001}) {
    const PairRun r = instrument_through({0.0, 0.0, 0.005}, {0.0005, 0.0, 0.035}, 1.0, gap);
    EXPECT_TRUE(r.contacts.empty()) << "gap " << gap;
    EXPECT_EQ(r.stats.bv_overlaps, 0) << "gap " << gap;
  }
}

TEST(TwoTree, ContactWithinTheGapOnly) {
  // The sphere stops 0.5 mm short of the wall: nothing at gap 0, contacts at gap 1 mm.
  const double stop = 0.010 - 0.003 - 0.0005;
  const PairRun none = instrument_through({0.002, 0.0, 0.02}, {stop, 0.0, 0.02}, 0.0, 0.0);
  EXPECT_TRUE(none.contacts.empty());
  const PairRun some = instrument_through({0.002, 0.0, 0.02}, {stop, 0.0, 0.02}, 0.0, 0.001);
  ASSERT_GT(some.contacts.size(), 0u);
  const Counts n = count(some.contacts);
  EXPECT_GT(n.vf_a + n.vf_b + n.ee, 0);
  // The first contact within 1 mm happens when the sphere's surface is 1 mm from the wall: it moves
  // from 5 mm to 0.5 mm away over the frame, so at about t = 4 / 4.5 (a polygonal wall is a little
  // closer, never farther) and never after the end.
  double first = 1.0;
  for (const PairContact& c : some.contacts) first = std::min(first, c.toi);
  EXPECT_LT(first, 1.0);
  EXPECT_GT(first, 0.75);
}

TEST(TwoTree, BothSurfacesMovingRandomlyEqualBruteForce) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, 1.0);
  const Mesh& a = instrument();
  const Mesh& b = organ();
  int with_contacts = 0;
  for (int trial = 0; trial < 12; ++trial) {
    // Random rigid motion of the instrument near the wall; the wall deforms (squeezed and jittered).
    const Eigen::Vector3d axis(u(rng), u(rng), u(rng) + 1.5);
    const Eigen::Vector3d from(0.006 + 0.002 * u(rng), 0.003 * u(rng), 0.02 + 0.005 * u(rng));
    const Eigen::Vector3d to(0.009 + 0.003 * u(rng), 0.003 * u(rng), 0.02 + 0.005 * u(rng));
    const Points xa0 = posed(a.x, axis, 0.0, from);
    const Points xa1 = posed(a.x, axis, 0.8 * u(rng), to);
    Points xb0 = b.x, xb1 = b.x;
    for (int i = 0; i < b.x.rows(); ++i) {
      const double squeeze = 1.0 - 0.2 * std::exp(-std::pow((b.x(i, 2) - 0.02) / 0.008, 2));
      for (int d = 0; d < 3; ++d) {
        xb0(i, d) += 0.0002 * noise(rng);
        xb1(i, d) = (d < 2 ? squeeze : 1.0) * b.x(i, d) + 0.0002 * noise(rng);
      }
    }
    const int k = kAllK[trial % 4];
    const double gap = (trial % 3 == 0) ? 0.0 : 0.0003;
    const auto [bvh, brute] = both(a, xa0, xa1, b, xb0, xb1, gap, k);
    expect_same(bvh, brute, "trial " + std::to_string(trial));
    expect_ordered_and_valid(bvh.contacts, a, b);
    with_contacts += !bvh.contacts.empty();
  }
  EXPECT_GE(with_contacts, 6) << "most random trials should reach the wall";
}

TEST(TwoTree, RepeatedCallsAndReusedWorkspacesGiveTheSameResult) {
  const Mesh& a = instrument();
  const Mesh& b = organ();
  const Points xa0 = posed(a.x, Eigen::Vector3d::UnitZ(), 0.0, {0.004, 0.0, 0.02});
  const Points xa1 = posed(a.x, Eigen::Vector3d::UnitZ(), 0.3, {0.013, 0.0, 0.02});
  const CollisionSurface sa(a.tris, a.x), sb(b.tris, b.x);
  CollisionWorkspace wa(18), wb(18);
  PairRun first, again;
  detect_pair(sa, wa, xa0, xa1, sb, wb, b.x, b.x, 0.0, first.contacts, &first.stats);
  ASSERT_GT(first.contacts.size(), 0u);
  // A self detection in between reuses A's workspace for another surface.
  std::vector<Contact> self;
  detect_self(sb, wa, b.x, b.x, 0.0, self);
  EXPECT_TRUE(self.empty());
  detect_pair(sa, wa, xa0, xa1, sb, wb, b.x, b.x, 0.0, again.contacts, &again.stats);
  expect_same(again, first, "repeat");
  // Swapping the roles swaps the sides: the same feature pairs, vf with sides exchanged.
  std::vector<PairContact> swapped;
  detect_pair(sb, wb, b.x, b.x, sa, wa, xa0, xa1, 0.0, swapped);
  const Counts n = count(first.contacts), m = count(swapped);
  EXPECT_EQ(n.vf_a, m.vf_b);
  EXPECT_EQ(n.vf_b, m.vf_a);
  EXPECT_EQ(n.ee, m.ee);
}

TEST(TwoTree, ValidatesInputs) {
  const Mesh& a = instrument();
  const Mesh& b = organ();
  const CollisionSurface sa(a.tris, a.x), sb(b.tris, b.x);
  const CollisionSurface no_bvh(b.tris, static_cast<int>(b.x.rows()));
  CollisionWorkspace wa(26), wb(26), w14(14);
  std::vector<PairContact> out;
  auto message = [](auto&& f) {
    try {
      f();
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  EXPECT_NE(message([&] { detect_pair(sa, wa, a.x, a.x, sb, w14, b.x, b.x, 0.0, out); }).find("26 and 14"),
            std::string::npos);
  EXPECT_NE(message([&] { detect_pair(sa, wa, a.x, a.x, sb, wb, b.x, a.x, 0.0, out); }).find("xb1 has"),
            std::string::npos);
  EXPECT_NE(message([&] { detect_pair(sa, wa, b.x, a.x, sb, wb, b.x, b.x, 0.0, out); }).find("xa0 has"),
            std::string::npos);
  EXPECT_NE(message([&] { detect_pair(sa, wa, a.x, a.x, sb, wb, b.x, b.x, -1.0, out); }).find("gap"),
            std::string::npos);
  EXPECT_NE(message([&] { detect_pair(sa, wa, a.x, a.x, sa, wa, a.x, a.x, 0.0, out); }).find("two different"),
            std::string::npos);
  EXPECT_THROW(detect_pair(sa, wa, a.x, a.x, no_bvh, wb, b.x, b.x, 0.0, out), std::logic_error);
  // The brute force needs no BVH.
  EXPECT_NO_THROW(detect_pair_brute_force(sa, wa, a.x, a.x, no_bvh, wb, b.x, b.x, 0.0, out));
}

}  // namespace
}  // namespace lumen::collision
