// k-DOPs, the swept BVH and SelfCollision against brute-force twins (all pairs, direct enumeration).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "collision/ccd.hpp"
#include "collision/kdop.hpp"
#include "collision/self_collision.hpp"
#include "collision/surface.hpp"
#include "support/tube.hpp"

namespace lumen::collision {
namespace {

using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using Tris = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;
using test::make_tube;  // open tube along z (tests/support/tube.hpp)

// A random smooth deformation of a tube of radius r, length len (metres): a pinch at a random place
// plus a sideways bend.
struct Shape {
  double zc, w, ax, ay, fx, fy, px, py;
};
Shape random_shape(double r, double len, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  return Shape{len * (0.5 + 0.2 * u(rng)), len * (0.15 + 0.05 * u(rng)), 0.1 * r * u(rng), 0.1 * r * u(rng),
               2.0 + u(rng), 2.0 + u(rng), double(EIGEN_PI) * u(rng), double(EIGEN_PI) * u(rng)};
}
// The shape with pinch amplitude `pinch` (1 = the walls meet) and uniform noise of `noise` metres.
Points deform(const Points& rest, const Shape& s, double len, double pinch, double noise, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Points x = rest;
  for (int i = 0; i < x.rows(); ++i) {
    const double z = rest(i, 2);
    const double g = std::exp(-((z - s.zc) / s.w) * ((z - s.zc) / s.w));
    x(i, 1) *= 1.0 - pinch * g;
    x(i, 0) += s.ax * std::sin(s.fx * EIGEN_PI * z / len + s.px) + noise * u(rng);
    x(i, 1) += s.ay * std::sin(s.fy * EIGEN_PI * z / len + s.py) + noise * u(rng);
    x(i, 2) += noise * u(rng);
  }
  return x;
}

// Brute-force projection of p on the paper's axis `id` (generic dot product).
double project(const double* p, int id) {
  return p[0] * kKdopAxes[id][0] + p[1] * kKdopAxes[id][1] + p[2] * kKdopAxes[id][2];
}

// Contacts as a set of (kind, vertex ids).
using ContactKey = std::tuple<int, int, int, int, int>;
std::set<ContactKey> contact_set(const std::vector<Contact>& cs) {
  std::set<ContactKey> s;
  for (const Contact& c : cs) s.emplace(static_cast<int>(c.kind), c.v[0], c.v[1], c.v[2], c.v[3]);
  return s;
}

// ---------------------------------------------------------------------------------------------------
// k-DOP type.

TEST(Kdop, ValidateAcceptsOnlyThePapersK) {
  for (int k : {6, 14, 18, 26}) EXPECT_EQ(validate_kdop(k), k);
  for (int k : {0, 8, 12, 27, -6}) {
    try {
      validate_kdop(k);
      ADD_FAILURE() << "k = " << k << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("kdop"), std::string::npos);
      EXPECT_NE(std::string(e.what()).find(std::to_string(k)), std::string::npos);
    }
  }
}

TEST(Kdop, AxesAreThePapersInOrderAndSubsetsNest) {
  // The 13 axes of the paper, in its order.
  const int expected[13][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1},  {1, 1, -1}, {1, -1, 1}, {1, -1, -1},
                               {1, 1, 0}, {1, 0, 1}, {0, 1, 1}, {1, -1, 0}, {1, 0, -1}, {0, 1, -1}};
  for (int i = 0; i < 13; ++i) {
    for (int d = 0; d < 3; ++d) EXPECT_EQ(kKdopAxes[i][d], expected[i][d]);
  }
  // k = 14: the 3 axes and the 4 diagonals; k = 18: the 3 axes and the 6 edge axes.
  EXPECT_EQ(std::vector<int>(std::begin(KdopAxisIds<6>::ids), std::end(KdopAxisIds<6>::ids)), (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(std::vector<int>(std::begin(KdopAxisIds<14>::ids), std::end(KdopAxisIds<14>::ids)),
            (std::vector<int>{0, 1, 2, 3, 4, 5, 6}));
  EXPECT_EQ(std::vector<int>(std::begin(KdopAxisIds<18>::ids), std::end(KdopAxisIds<18>::ids)),
            (std::vector<int>{0, 1, 2, 7, 8, 9, 10, 11, 12}));
  EXPECT_EQ(Kdop<26>::kAxes, 13);
}

// Bounds contain every point and are attained (tight), overlap equals the per-axis definition, and points
// within 2 * margin of each other make the inflated k-DOPs overlap.
template <int K>
void check_kdop_against_brute(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int overlaps = 0, separated = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    // Two clouds of 1..6 points (swept triangles have 6), random centres.
    std::vector<std::array<double, 3>> pa(1 + trial % 6), pb(1 + (trial / 6) % 6);
    const double ca[3] = {0.5 * u(rng), 0.5 * u(rng), 0.5 * u(rng)}, cb[3] = {0.5 * u(rng), 0.5 * u(rng), 0.5 * u(rng)};
    for (auto& p : pa) p = {ca[0] + 0.4 * u(rng), ca[1] + 0.4 * u(rng), ca[2] + 0.4 * u(rng)};
    for (auto& p : pb) p = {cb[0] + 0.4 * u(rng), cb[1] + 0.4 * u(rng), cb[2] + 0.4 * u(rng)};
    Kdop<K> a, b;
    a.clear();
    b.clear();
    for (const auto& p : pa) a.add_point(p.data());
    for (const auto& p : pb) b.add_point(p.data());
    // Tight containment per axis.
    bool brute_overlap = true;
    for (int ax = 0; ax < Kdop<K>::kAxes; ++ax) {
      const int id = KdopAxisIds<K>::ids[ax];
      double lo_a = 1e300, hi_a = -1e300, lo_b = 1e300, hi_b = -1e300;
      for (const auto& p : pa) lo_a = std::min(lo_a, project(p.data(), id)), hi_a = std::max(hi_a, project(p.data(), id));
      for (const auto& p : pb) lo_b = std::min(lo_b, project(p.data(), id)), hi_b = std::max(hi_b, project(p.data(), id));
      ASSERT_EQ(a.lo[ax], lo_a);
      ASSERT_EQ(a.hi[ax], hi_a);
      if (lo_a > hi_b || lo_b > hi_a) brute_overlap = false;
    }
    for (const auto& p : pa) ASSERT_TRUE(a.contains(p.data()));
    ASSERT_EQ(a.overlaps(b), brute_overlap);
    ASSERT_EQ(b.overlaps(a), brute_overlap);
    (brute_overlap ? overlaps : separated)++;
    // Inflation: any two points within 2 * margin force an overlap.
    double dmin = 1e300;
    for (const auto& p : pa) {
      for (const auto& q : pb) {
        dmin = std::min(dmin, std::sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                                        (p[2] - q[2]) * (p[2] - q[2])));
      }
    }
    const double margin = 0.5 * dmin * (0.999 + 0.5 * (u(rng) + 1.0));  // around dmin / 2, both sides
    Kdop<K> ia = a, ib = b;
    ia.inflate(margin);
    ib.inflate(margin);
    if (2.0 * margin >= dmin) {
      ASSERT_TRUE(ia.overlaps(ib));
    }
  }
  // Both outcomes were exercised.
  EXPECT_GT(overlaps, 100);
  EXPECT_GT(separated, 100);
}

TEST(Kdop, BoundsAndOverlapMatchBruteDefinitions) {
  std::mt19937 rng(7);
  check_kdop_against_brute<6>(rng);
  check_kdop_against_brute<14>(rng);
  check_kdop_against_brute<18>(rng);
  check_kdop_against_brute<26>(rng);
}

TEST(Kdop, InflationCoversRoundingAtExactTouching) {
  // Two points separated along each of the 13 axes, each k-DOP inflated by half their distance: the
  // inflated k-DOPs touch exactly on that axis, so rounding of the projections must not separate them.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 3000; ++trial) {
    const int id = trial % 13;
    const double p[3] = {100.0 * u(rng), 100.0 * u(rng), 100.0 * u(rng)};
    const double s = std::ldexp(u(rng), -(trial % 40));
    const double q[3] = {p[0] + s * kKdopAxes[id][0], p[1] + s * kKdopAxes[id][1], p[2] + s * kKdopAxes[id][2]};
    const double dist = std::sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                                  (p[2] - q[2]) * (p[2] - q[2]));
    Kdop<26> a, b;
    a.clear();
    b.clear();
    a.add_point(p);
    b.add_point(q);
    a.inflate(0.5 * dist);
    b.inflate(0.5 * dist);
    ASSERT_TRUE(a.overlaps(b)) << "axis " << id << " trial " << trial;
  }
}

// Number of overlapping pairs among k-DOPs of the given triangles (9 doubles each).
template <int K>
int count_overlapping_pairs(const std::vector<std::array<double, 9>>& prims) {
  std::vector<Kdop<K>> boxes(prims.size());
  for (std::size_t i = 0; i < prims.size(); ++i) {
    boxes[i].clear();
    for (int k = 0; k < 3; ++k) boxes[i].add_point(&prims[i][static_cast<std::size_t>(3 * k)]);
  }
  int n = 0;
  for (std::size_t i = 0; i < prims.size(); ++i) {
    for (std::size_t j = i + 1; j < prims.size(); ++j) n += boxes[i].overlaps(boxes[j]);
  }
  return n;
}

TEST(Kdop, DiagonalConfigurationFewerOverlapsWithMoreAxes) {
  // Thin triangles along the (1, 1, 1) diagonal, offset sideways on a grid: AABBs overlap heavily, the
  // diagonal-aligned axes of larger k separate most of them.
  std::vector<std::array<double, 9>> prims;
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 6; ++j) {
      const double o[3] = {0.15 * i, 0.15 * j, -0.15 * (i + j) / 2.0};
      prims.push_back({o[0], o[1], o[2], o[0] + 1.0, o[1] + 1.0, o[2] + 1.0, o[0] + 0.2, o[1] - 0.2, o[2]});
    }
  }
  const int c6 = count_overlapping_pairs<6>(prims), c14 = count_overlapping_pairs<14>(prims);
  const int c18 = count_overlapping_pairs<18>(prims), c26 = count_overlapping_pairs<26>(prims);
  // Nested axis sets: never more overlaps with more axes; strictly fewer on this configuration.
  EXPECT_GE(c6, c14);
  EXPECT_GE(c6, c18);
  EXPECT_GE(c14, c26);
  EXPECT_GE(c18, c26);
  EXPECT_GT(c6, c26);
  EXPECT_GT(c26, 0);
  std::printf("diagonal triangles: overlapping pairs k=6 %d, k=14 %d, k=18 %d, k=26 %d\n", c6, c14, c18, c26);
}

// ---------------------------------------------------------------------------------------------------
// BVH self-traversal.

template <int K>
void check_bvh_pairs(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int n : {1, 2, 3, 17, 200}) {
    // Random small boxes: one point cloud of 3 points per primitive.
    std::vector<double> pts(static_cast<std::size_t>(9 * n)), centres(static_cast<std::size_t>(3 * n));
    for (int i = 0; i < n; ++i) {
      const double c[3] = {u(rng), u(rng), u(rng)};
      for (int k = 0; k < 3; ++k) {
        for (int d = 0; d < 3; ++d) pts[static_cast<std::size_t>(9 * i + 3 * k + d)] = c[d] + 0.1 * u(rng);
      }
      for (int d = 0; d < 3; ++d) centres[static_cast<std::size_t>(3 * i + d)] = c[d];
    }
    KdopBvh<K> bvh;
    bvh.build(centres.data(), n);
    ASSERT_EQ(bvh.num_nodes(), 2 * n - 1);
    std::vector<Kdop<K>> boxes(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) {
      boxes[static_cast<std::size_t>(i)].clear();
      for (int k = 0; k < 3; ++k) boxes[static_cast<std::size_t>(i)].add_point(&pts[static_cast<std::size_t>(9 * i + 3 * k)]);
      bvh.leaf_box(i) = boxes[static_cast<std::size_t>(i)];
    }
    bvh.refit();
    // Root bounds every leaf.
    for (int i = 0; i < n; ++i) {
      for (int k = 0; k < 3; ++k) ASSERT_TRUE(bvh.node_box(0).contains(&pts[static_cast<std::size_t>(9 * i + 3 * k)]));
    }
    std::vector<std::pair<int, int>> got;
    bvh.self_pairs([&](int a, int b) { got.emplace_back(std::min(a, b), std::max(a, b)); });
    std::vector<std::pair<int, int>> want;
    for (int a = 0; a < n; ++a) {
      for (int b = a + 1; b < n; ++b) {
        if (boxes[static_cast<std::size_t>(a)].overlaps(boxes[static_cast<std::size_t>(b)])) want.emplace_back(a, b);
      }
    }
    std::sort(got.begin(), got.end());
    // Same pairs, each reported once.
    EXPECT_EQ(got, want) << "n = " << n << " k = " << K;
  }
}

TEST(KdopBvh, SelfTraversalReportsEachOverlappingPairOnce) {
  std::mt19937 rng(11);
  check_bvh_pairs<6>(rng);
  check_bvh_pairs<14>(rng);
  check_bvh_pairs<18>(rng);
  check_bvh_pairs<26>(rng);
}

// ---------------------------------------------------------------------------------------------------
// SelfCollision.

TEST(SelfCollision, ValidatesInputsNamingFieldAndValue) {
  Points x;
  Tris tris;
  make_tube(2, 6, 0.01, 0.02, x, tris);
  const int n = static_cast<int>(x.rows());
  const auto message = [](auto&& f) {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no throw");
  };
  EXPECT_NE(message([&] { SelfCollision(tris, n, 8); }).find("kdop must be 6, 14, 18 or 26, got 8"), std::string::npos);
  Tris bad = tris;
  bad(1, 2) = n;
  EXPECT_NE(message([&] { SelfCollision(bad, n, 26); }).find("tris(1, 2)"), std::string::npos);
  EXPECT_NE(message([&] { SelfCollision(bad, n, 26); }).find(std::to_string(n)), std::string::npos);
  bad = tris;
  bad(0, 1) = -3;
  EXPECT_NE(message([&] { SelfCollision(bad, n, 26); }).find("-3"), std::string::npos);
  bad = tris;
  bad(2, 1) = bad(2, 0);
  EXPECT_NE(message([&] { SelfCollision(bad, n, 26); }).find("tris row 2"), std::string::npos);

  SelfCollision sc(tris, n, 14);
  std::vector<Contact> out;
  Points short_x = x.topRows(n - 1);
  EXPECT_NE(message([&] { sc.detect(short_x, x, 0.0, out); }).find("x0 has " + std::to_string(n - 1) + " rows"),
            std::string::npos);
  Points nan_x = x;
  nan_x(3, 1) = std::nan("");
  EXPECT_NE(message([&] { sc.detect(x, nan_x, 0.0, out); }).find("x1(3, 1)"), std::string::npos);
  EXPECT_NE(message([&] { sc.detect(x, x, -1e-3, out); }).find("gap"), std::string::npos);
  EXPECT_NE(message([&] { sc.detect_brute_force(x, x, -1e-3, out); }).find("-0.001"), std::string::npos);
}

TEST(SelfCollision, StaticTubeHasNoContactsButTestsNeighbours) {
  Points x;
  Tris tris;
  make_tube(6, 10, 0.01, 0.03, x, tris);
  SelfCollision sc(tris, static_cast<int>(x.rows()), 26);
  EXPECT_EQ(sc.num_triangles(), 120);
  EXPECT_EQ(sc.num_edges(), 6 * 10 * 3 + 10);  // per quad: ring edge, axial edge, diagonal; plus the last ring
  std::vector<Contact> out{Contact{}};
  CollisionStats st;
  sc.detect(x, x, 1e-5, out, &st);
  EXPECT_TRUE(out.empty());
  EXPECT_EQ(st.contacts, 0);
  // Neighbouring triangles always overlap, so their non-shared features are still tested.
  EXPECT_GT(st.bv_overlaps, 0);
  EXPECT_GT(st.feature_tests, 0);
}

// The tube the detection twins run on (10 around, 14 along) and one frame of a pinch pushing its walls through
// each other, plus noise, drawn from rng (deeper for some seeds).
constexpr double kTwinRadius = 0.01, kTwinLength = 0.05;  // metres
struct PinchedFrame {
  Points rest, x0, x1;
  Tris tris;
};
PinchedFrame random_pinched_frame(unsigned seed, std::mt19937& rng) {
  PinchedFrame pf;
  make_tube(10, 14, kTwinRadius, kTwinLength, pf.rest, pf.tris);
  const Shape shape = random_shape(kTwinRadius, kTwinLength, rng);
  pf.x0 = deform(pf.rest, shape, kTwinLength, 0.85, 1e-4, rng);
  pf.x1 = deform(pf.rest, shape, kTwinLength, 1.1 + 0.1 * (seed % 3), 1e-4, rng);
  return pf;
}

// BVH contacts and statistics equal the all-pairs ones on random deformed tubes.
void check_bvh_equals_brute(int k, unsigned seed, bool build_over_rest) {
  std::mt19937 rng(seed);
  const PinchedFrame pf = random_pinched_frame(seed, rng);
  const Points &rest = pf.rest, &x0 = pf.x0, &x1 = pf.x1;
  const Tris& tris = pf.tris;
  const double gap = 1e-4;
  SelfCollision sc = build_over_rest ? SelfCollision(tris, rest, k) : SelfCollision(tris, static_cast<int>(rest.rows()), k);
  std::vector<Contact> bvh, brute;
  CollisionStats sb, sf;
  sc.detect(x0, x1, gap, bvh, &sb);
  const std::vector<FeaturePair> tested_bvh = sc.tested_features();
  sc.detect_brute_force(x0, x1, gap, brute, &sf);
  EXPECT_EQ(contact_set(bvh), contact_set(brute)) << "k = " << k << " seed = " << seed;
  EXPECT_EQ(sb.bv_overlaps, sf.bv_overlaps);
  EXPECT_EQ(sb.feature_tests, sf.feature_tests);
  EXPECT_EQ(sb.contacts, sf.contacts);
  EXPECT_EQ(sb.contacts, static_cast<long>(bvh.size()));
  EXPECT_EQ(tested_bvh.size(), sc.tested_features().size());
  // Same order and same times (each feature pair run once, deterministically).
  ASSERT_EQ(bvh.size(), brute.size());
  for (std::size_t i = 0; i < bvh.size(); ++i) EXPECT_EQ(bvh[i].toi, brute[i].toi);
  // The walls were pushed through each other: there are contacts of both kinds.
  const auto s = contact_set(bvh);
  EXPECT_TRUE(std::any_of(s.begin(), s.end(), [](const ContactKey& c) { return std::get<0>(c) == 0; }));
  EXPECT_TRUE(std::any_of(s.begin(), s.end(), [](const ContactKey& c) { return std::get<0>(c) == 1; }));
}

TEST(SelfCollision, BvhContactsEqualBruteForceOnDeformedTubes) {
  for (int k : {6, 14, 18, 26}) {
    for (unsigned seed : {1u, 2u}) check_bvh_equals_brute(k, seed + 10u * static_cast<unsigned>(k), seed == 2u);
  }
}

TEST(SelfCollision, RefitOverManyFramesMatchesBruteForce) {
  // Topology built over the rest shape, then refitted over a sequence of frames pinching ever further.
  const double r = 0.01, len = 0.05;
  Points rest;
  Tris tris;
  make_tube(8, 12, r, len, rest, tris);
  SelfCollision sc(tris, rest, 18);
  std::mt19937 rng(5);
  const Shape shape = random_shape(r, len, rng);
  Points x0 = rest;
  long total = 0;
  for (int frame = 0; frame < 4; ++frame) {
    const Points x1 = deform(rest, shape, len, 0.3 * (frame + 1), 1e-4, rng);
    std::vector<Contact> a, b;
    sc.detect(x0, x1, 5e-5, a);
    sc.detect_brute_force(x0, x1, 5e-5, b);
    EXPECT_EQ(contact_set(a), contact_set(b)) << "frame " << frame;
    total += static_cast<long>(a.size());
    x0 = x1;
  }
  EXPECT_GT(total, 0);
}

// Each candidate feature pair is run exactly once; the set equals a direct enumeration of the feature
// pairs (not sharing a vertex) whose owners (the lowest-numbered triangle having the vertex or edge) have
// overlapping swept k-DOPs; and the contacts are those of every feature pair (no boxes at all).
template <int K>
void check_features_tested_once(unsigned seed) {
  const double r = 0.01, len = 0.04;
  Points rest;
  Tris tris;
  make_tube(8, 10, r, len, rest, tris);
  std::mt19937 rng(seed);
  const Shape shape = random_shape(r, len, rng);
  const Points x0 = deform(rest, shape, len, 0.8, 1e-4, rng);
  const Points x1 = deform(rest, shape, len, 1.2, 1e-4, rng);
  const double gap = 2e-4;
  const int nt = static_cast<int>(tris.rows()), np = static_cast<int>(rest.rows());
  SelfCollision sc(tris, np, K);
  std::vector<Contact> out;
  CollisionStats st;
  sc.detect(x0, x1, gap, out, &st);
  const std::vector<FeaturePair>& tested = sc.tested_features();

  // Swept k-DOPs of the triangles, computed here.
  std::vector<Kdop<K>> box(static_cast<std::size_t>(nt));
  for (int t = 0; t < nt; ++t) {
    box[static_cast<std::size_t>(t)].clear();
    for (int j = 0; j < 3; ++j) {
      const Eigen::RowVector3d p0 = x0.row(tris(t, j)), p1 = x1.row(tris(t, j));
      box[static_cast<std::size_t>(t)].add_point(p0.data());
      box[static_cast<std::size_t>(t)].add_point(p1.data());
    }
    box[static_cast<std::size_t>(t)].inflate(gap);
  }
  const auto overlap = [&](int a, int b) { return a != b && box[static_cast<std::size_t>(a)].overlaps(box[static_cast<std::size_t>(b)]); };
  const auto in_tri = [&](int t, int v) { return tris(t, 0) == v || tris(t, 1) == v || tris(t, 2) == v; };

  // Vertex-face pairs: vertex v not in face f, some triangle containing v overlaps f.
  std::vector<std::vector<int>> vertex_tris(static_cast<std::size_t>(np));
  for (int t = 0; t < nt; ++t) {
    for (int j = 0; j < 3; ++j) vertex_tris[static_cast<std::size_t>(tris(t, j))].push_back(t);
  }
  std::set<std::array<int, 5>> want;
  for (int v = 0; v < np; ++v) {
    for (int f = 0; f < nt; ++f) {
      if (in_tri(f, v)) continue;
      if (vertex_tris[static_cast<std::size_t>(v)].empty()) continue;
      if (overlap(vertex_tris[static_cast<std::size_t>(v)].front(), f)) want.insert({0, v, tris(f, 0), tris(f, 1), tris(f, 2)});
    }
  }
  // Edge-edge pairs: unique edges (sorted ids), no shared vertex, some containing triangles overlap.
  std::set<std::pair<int, int>> edge_set;
  for (int t = 0; t < nt; ++t) {
    for (int j = 0; j < 3; ++j) {
      const int a = tris(t, j), b = tris(t, (j + 1) % 3);
      edge_set.emplace(std::min(a, b), std::max(a, b));
    }
  }
  const std::vector<std::pair<int, int>> edges(edge_set.begin(), edge_set.end());
  std::vector<std::vector<int>> edge_tris(edges.size());
  for (std::size_t e = 0; e < edges.size(); ++e) {
    for (int t = 0; t < nt; ++t) {
      if (in_tri(t, edges[e].first) && in_tri(t, edges[e].second)) edge_tris[e].push_back(t);
    }
  }
  for (std::size_t e = 0; e < edges.size(); ++e) {
    for (std::size_t g = e + 1; g < edges.size(); ++g) {
      const auto [a, b] = edges[e];
      const auto [c, d] = edges[g];
      if (a == c || a == d || b == c || b == d) continue;
      if (overlap(edge_tris[e].front(), edge_tris[g].front())) want.insert({1, a, b, c, d});
    }
  }

  // Tested once each, and exactly the enumerated set.
  std::set<std::array<int, 5>> got;
  for (const FeaturePair& fp : tested) {
    const bool inserted = got.insert({static_cast<int>(fp.kind), fp.v[0], fp.v[1], fp.v[2], fp.v[3]}).second;
    EXPECT_TRUE(inserted) << "feature pair tested twice";
  }
  EXPECT_EQ(got, want) << "k = " << K;
  EXPECT_EQ(st.feature_tests, static_cast<long>(want.size()));
  // The contacts are every feature pair's: each vertex against each face without it, each pair of edges without a
  // shared vertex, by the elementary tests alone.
  std::set<ContactKey> every;
  const auto at = [](const Points& x, int i) { return Vec3(x(i, 0), x(i, 1), x(i, 2)); };
  for (int v = 0; v < np; ++v)
    for (int f = 0; f < nt; ++f) {
      if (vertex_tris[static_cast<std::size_t>(v)].empty() || in_tri(f, v)) continue;
      const int face[3] = {tris(f, 0), tris(f, 1), tris(f, 2)};
      if (vertex_face_ccd(at(x0, v), at(x0, face[0]), at(x0, face[1]), at(x0, face[2]), at(x1, v), at(x1, face[0]),
                          at(x1, face[1]), at(x1, face[2]), gap, nullptr))
        every.insert(ContactKey{0, v, face[0], face[1], face[2]});
    }
  for (std::size_t e = 0; e < edges.size(); ++e)
    for (std::size_t g = e + 1; g < edges.size(); ++g) {
      const int ev[2] = {edges[e].first, edges[e].second}, gv[2] = {edges[g].first, edges[g].second};
      if (ev[0] == gv[0] || ev[0] == gv[1] || ev[1] == gv[0] || ev[1] == gv[1]) continue;
      if (edge_edge_ccd(at(x0, ev[0]), at(x0, ev[1]), at(x0, gv[0]), at(x0, gv[1]), at(x1, ev[0]), at(x1, ev[1]),
                        at(x1, gv[0]), at(x1, gv[1]), gap, nullptr))
        every.insert(ContactKey{1, ev[0], ev[1], gv[0], gv[1]});
    }
  EXPECT_EQ(contact_set(out), every) << "k = " << K;
  // Deduplication matters: the triangle pairs alone would have run more elementary tests.
  EXPECT_LT(st.feature_tests, 15 * st.bv_overlaps);
  EXPECT_GT(st.contacts, 0);
}

TEST(SelfCollision, EachFeaturePairTestedOnce) {
  check_features_tested_once<6>(4u);
  check_features_tested_once<14>(9u);
  check_features_tested_once<18>(13u);
  check_features_tested_once<26>(21u);
}

TEST(SelfCollision, SharedVertexNeighboursStillReportVertexFaceContact) {
  // Triangles (0 1 2) and (0 3 4) share vertex 0; vertex 3 moves through the interior of (0 1 2).
  Points x0(5, 3), x1(5, 3);
  x0 << 0, 0, 0,  //
      1, 0, 0,    //
      0, 1, 0,    //
      0.3, 0.3, 0.5,  //
      -1, -1, 0.5;
  x1 = x0;
  x1(3, 2) = -0.5;
  Tris tris(2, 3);
  tris << 0, 1, 2,  //
      0, 3, 4;
  for (int k : {6, 14, 18, 26}) {
    SelfCollision sc(tris, 5, k);
    std::vector<Contact> out;
    CollisionStats st;
    sc.detect(x0, x1, 0.0, out, &st);
    EXPECT_EQ(st.bv_overlaps, 1);
    // Vertices 3, 4 against face (0 1 2) and 1, 2 against (0 3 4); edge pairs sharing no vertex:
    // (0 1) x (3 4), (1 2) x (0 3), (1 2) x (3 4), (1 2) x (0 4), (0 2) x (3 4).
    EXPECT_EQ(st.feature_tests, 9);
    const auto s = contact_set(out);
    EXPECT_EQ(s.count(ContactKey{0, 3, 0, 1, 2}), 1u) << "k = " << k;
    for (const FeaturePair& fp : sc.tested_features()) {
      if (fp.kind == FeatureKind::VertexFace) {
        EXPECT_NE(fp.v[0], 0);  // the shared vertex is never tested against a face containing it
      } else {
        EXPECT_TRUE(fp.v[0] != fp.v[2] && fp.v[0] != fp.v[3] && fp.v[1] != fp.v[2] && fp.v[1] != fp.v[3]);
      }
    }
    for (const Contact& c : out) {
      if (c.kind == FeatureKind::VertexFace && c.v[0] == 3) {
        EXPECT_GE(c.toi, 0.0);
        EXPECT_LE(c.toi, 0.5 + 1e-9);  // crosses z = 0 at t = 0.5 (conservative: never later)
      }
    }
  }
}

TEST(SelfCollision, EdgeNeighboursTestOppositeVertexAndFarEdges) {
  // Triangles (0 1 2) and (0 1 3) share edge (0 1): the features left are 2 vs (0 1 3), 3 vs (0 1 2) and
  // edge (1 2) x (0 3), (0 2) x (1 3). Vertex 3 folds through triangle (0 1 2).
  Points x0(4, 3), x1(4, 3);
  x0 << 0, 0, 0,  //
      1, 0, 0,    //
      0.3, 1, 0,  //
      0.3, 0.3, 1;
  x1 = x0;
  x1.row(3) << 0.3, 0.3, -1;
  Tris tris(2, 3);
  tris << 0, 1, 2,  //
      0, 1, 3;
  SelfCollision sc(tris, 4, 26);
  std::vector<Contact> out;
  CollisionStats st;
  sc.detect(x0, x1, 0.0, out, &st);
  EXPECT_EQ(st.feature_tests, 4);
  EXPECT_EQ(contact_set(out).count(ContactKey{0, 3, 0, 1, 2}), 1u);
}

TEST(SelfCollision, EmptyAndSingleTriangle) {
  Points x(3, 3);
  x << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  Tris none(0, 3), one(1, 3);
  one << 0, 1, 2;
  std::vector<Contact> out;
  CollisionStats st;
  SelfCollision a(none, 3, 6);
  a.detect(x, x, 0.1, out, &st);
  EXPECT_TRUE(out.empty());
  EXPECT_EQ(st.feature_tests, 0);
  SelfCollision b(one, 3, 6);
  b.detect(x, x, 0.1, out, &st);
  EXPECT_TRUE(out.empty());
  EXPECT_EQ(st.bv_overlaps, 0);
}

// Two contact lists equal entry by entry: kind, vertices, time and parameters (an ASSERT on the sizes first).
void expect_same_contacts(const std::vector<Contact>& got, const std::vector<Contact>& want, const std::string& where) {
  ASSERT_EQ(got.size(), want.size()) << where;
  for (std::size_t i = 0; i < want.size(); ++i) {
    EXPECT_EQ(static_cast<int>(got[i].kind), static_cast<int>(want[i].kind)) << where;
    EXPECT_TRUE(std::equal(got[i].v, got[i].v + 4, want[i].v)) << where;
    EXPECT_EQ(got[i].toi, want[i].toi) << where;
    EXPECT_EQ(got[i].s, want[i].s) << where;
    EXPECT_EQ(got[i].t, want[i].t) << where;
  }
}

// detect_self_moved against its twin, detect_self with its contacts filtered by the definition (a flagged vertex,
// or two vertices of the two features whose moves since the reference differ by at least the margin): the same
// contacts, times and order, on random pinched tubes with random flags and a random smooth reference (with_start:
// a reference that also started elsewhere, x0_ref, so that moves at both ends count). Returns the number of selected
// contacts.
// start_only (with_start): adds the selected contacts that only their move at the start selects.
std::size_t check_moved_equals_filtered_full(int k, unsigned seed, bool with_start = false,
                                             std::size_t* start_only = nullptr) {
  const double len = kTwinLength, gap = 1e-4, margin = 2e-4;
  std::mt19937 rng(seed);
  const PinchedFrame pf = random_pinched_frame(seed, rng);
  const Points &rest = pf.rest, &x0 = pf.x0, &x1 = pf.x1;
  const Tris& tris = pf.tris;
  // The reference: x1 off by a smooth bump along the tube (moves up to 1 mm, relative moves around the margin; 0.1 mm
  // with_start, so that the start's moves select pairs of their own).
  Points x1_ref = x1;
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double zc = len * u(rng), width = 0.2 * len;
  for (Eigen::Index i = 0; i < x1.rows(); ++i)
    x1_ref(i, 1) += (with_start ? 1e-4 : 1e-3) * std::exp(-std::pow((rest(i, 2) - zc) / width, 2));
  // The start's reference: x0 with the walls another bump apart (top and bottom moved by up to 0.3 mm in
  // opposite directions, so pairs across the lumen move relative to each other), or x0 itself.
  Points x0_ref = x0;
  const double zs = len * u(rng);
  if (with_start)
    for (Eigen::Index i = 0; i < x0.rows(); ++i)
      x0_ref(i, 1) += 3e-4 * (rest(i, 1) / kTwinRadius) * std::exp(-std::pow((rest(i, 2) - zs) / width, 2));
  std::bernoulli_distribution coin(0.05);
  std::vector<std::uint8_t> flags(static_cast<std::size_t>(rest.rows()));
  for (auto& f : flags) f = coin(rng);
  CollisionSurface surface(tris, rest);
  CollisionWorkspace ws(k);
  std::vector<Contact> full, moved;
  detect_self(surface, ws, x0, x1, gap, full);
  const PointsRef ref(x1_ref), ref0(x0_ref);
  detect_self_moved(surface, ws, x0, x1, gap, MoveFilter{&ref, margin, &flags, with_start ? &ref0 : nullptr}, moved);
  // The definition, pair by pair.
  auto relative = [](const Points& x, const Points& r, int i, int j) {
    return ((x.row(i) - r.row(i)) - (x.row(j) - r.row(j))).norm();
  };
  // (start: whether the moves at the sweep's start count.)
  auto selected_by = [&](const Contact& c, bool start) {
    const int n_first = c.kind == FeatureKind::VertexFace ? 1 : 2;
    for (int a = 0; a < 4; ++a) {
      if (flags[static_cast<std::size_t>(c.v[a])]) return true;
      for (int b = n_first; b < 4; ++b)
        if (a < n_first && std::max(relative(x1, x1_ref, c.v[a], c.v[b]),
                                    start ? relative(x0, x0_ref, c.v[a], c.v[b]) : 0.0) >= margin)
          return true;
    }
    return false;
  };
  auto selected = [&](const Contact& c) { return selected_by(c, true); };
  std::vector<Contact> expected;
  for (const Contact& c : full)
    if (selected(c)) expected.push_back(c);
  // Selected by the start alone: no flag, and every end move below the margin.
  if (start_only)
    for (const Contact& c : expected) *start_only += !selected_by(c, false);
  EXPECT_EQ(moved.size(), expected.size()) << "k = " << k << " seed = " << seed;
  if (moved.size() != expected.size()) return 0;
  if (!full.empty()) {
    EXPECT_LT(expected.size(), full.size()) << "every contact selected: the filter proves little";
  }
  expect_same_contacts(moved, expected, "k = " + std::to_string(k) + " seed = " + std::to_string(seed));
  // Every vertex flagged, or a zero margin: detect_self exactly, statistics included.
  CollisionStats s_full, s_all, s_zero;
  detect_self(surface, ws, x0, x1, gap, full, &s_full);
  const std::vector<std::uint8_t> all(flags.size(), 1);
  detect_self_moved(surface, ws, x0, x1, gap, MoveFilter{nullptr, 0.0, &all}, moved, &s_all);
  EXPECT_EQ(contact_set(moved), contact_set(full));
  detect_self_moved(surface, ws, x0, x1, gap, MoveFilter{&ref, 0.0, nullptr}, moved, &s_zero);
  EXPECT_EQ(contact_set(moved), contact_set(full));
  for (const CollisionStats& st : {s_all, s_zero}) {
    EXPECT_EQ(st.bv_overlaps, s_full.bv_overlaps);
    EXPECT_EQ(st.feature_tests, s_full.feature_tests);
  }
  return expected.size();
}

TEST(SelfCollision, MovedDetectionEqualsTheFullOneFilteredByTheDefinition) {
  std::size_t selected = 0;
  for (int k : {6, 26}) {
    for (unsigned seed : {3u, 4u, 5u}) selected += check_moved_equals_filtered_full(k, seed);
  }
  EXPECT_GT(selected, 10u);
}

// The same with a reference that started elsewhere too (a later frame against an earlier one): moves at the start
// count as well.
TEST(SelfCollision, MovedDetectionAgainstAnEarlierSweepEqualsTheFullOneFilteredByTheDefinition) {
  std::size_t selected = 0, start_only = 0;
  for (int k : {6, 26}) {
    for (unsigned seed : {3u, 4u, 5u}) selected += check_moved_equals_filtered_full(k, seed, true, &start_only);
  }
  EXPECT_GT(selected, 10u);
  EXPECT_GT(start_only, 0u) << "no contact was selected by its start move alone: ignoring x0_ref would pass";
}

// A contact's feature pair as NearFeatures keys it (kind, key), found by scanning the surface's triangles and edges.
std::pair<int, std::uint64_t> near_key(const CollisionSurface& s, const Contact& c) {
  if (c.kind == FeatureKind::VertexFace) {
    for (int t = 0; t < s.num_triangles(); ++t)
      if (std::equal(c.v + 1, c.v + 4, s.triangle(t)))
        return {0, (static_cast<std::uint64_t>(c.v[0]) << s.tri_bits()) | static_cast<std::uint64_t>(t)};
  } else {
    int e[2] = {-1, -1};
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < s.num_edges(); ++i)
        if (s.edge(i)[0] == c.v[2 * j] && s.edge(i)[1] == c.v[2 * j + 1]) e[j] = i;
    return {1, (static_cast<std::uint64_t>(std::min(e[0], e[1])) << s.edge_bits()) |
                   static_cast<std::uint64_t>(std::max(e[0], e[1]))};
  }
  return {-1, 0};
}

std::set<std::pair<int, std::uint64_t>> near_set(const NearFeatures& n) {
  std::set<std::pair<int, std::uint64_t>> s;
  for (std::uint64_t k : n.vf) s.insert({0, k});
  for (std::uint64_t k : n.ee) s.insert({1, k});
  return s;
}

// detect_self_near against its two twins: its contacts are detect_self's at the gap (same times, parameters and
// order), and its near pairs are exactly detect_self's contacts at the near gap.
TEST(SelfCollision, NearDetectionReportsTheGapsContactsAndKeepsThePairsWithinTheNearGap) {
  const double gap = 1e-4, near_gap = 4e-4;
  long more_near = 0;
  for (int k : {6, 26}) {
    for (unsigned seed : {3u, 4u, 5u}) {
      std::mt19937 rng(seed);
      const PinchedFrame pf = random_pinched_frame(seed, rng);
      CollisionSurface surface(pf.tris, pf.rest);
      CollisionWorkspace ws(k);
      std::vector<Contact> out, at_gap, at_near;
      NearFeatures near;
      CollisionStats st;
      detect_self_near(surface, ws, pf.x0, pf.x1, gap, near_gap, out, near, &st);
      detect_self(surface, ws, pf.x0, pf.x1, gap, at_gap);
      detect_self(surface, ws, pf.x0, pf.x1, near_gap, at_near);
      const std::string where = "k = " + std::to_string(k) + " seed = " + std::to_string(seed);
      expect_same_contacts(out, at_gap, where);
      EXPECT_EQ(st.contacts, static_cast<long>(out.size())) << where;
      std::set<std::pair<int, std::uint64_t>> expected;
      for (const Contact& c : at_near) expected.insert(near_key(surface, c));
      EXPECT_EQ(near.size(), at_near.size()) << where;
      EXPECT_TRUE(near_set(near) == expected) << where;
      EXPECT_TRUE(std::is_sorted(near.vf.begin(), near.vf.end()) && std::is_sorted(near.ee.begin(), near.ee.end()));
      more_near += static_cast<long>(at_near.size() - at_gap.size());
    }
  }
  EXPECT_GT(more_near, 0) << "the near gap finds nothing the gap does not: the test proves little";
}

// The frame-to-frame use, against the brute-force twin: a near detection of one sweep proves every pair it does not
// keep clear by the near gap, so a later sweep restricted to the kept pairs and to the pairs that moved relative to
// each other by at least near_gap - gap (at either end, against that sweep) finds exactly what detect_self finds on
// it, while testing fewer pairs.
TEST(SelfCollision, ADetectionRestrictedByAnEarlierNearDetectionFindsEveryContact) {
  const double gap = 1e-4, near_gap = 4e-4, len = kTwinLength;
  long found = 0, new_contacts = 0, tests_restricted = 0, tests_full = 0;
  for (int k : {6, 26}) {
    for (unsigned seed : {3u, 4u, 5u, 6u}) {
      std::mt19937 rng(seed);
      const PinchedFrame pf = random_pinched_frame(seed, rng);
      CollisionSurface surface(pf.tris, pf.rest);
      CollisionWorkspace ws(k);
      std::vector<Contact> ignored;
      NearFeatures near;
      detect_self_near(surface, ws, pf.x0, pf.x1, gap, near_gap, ignored, near);
      // The next sweep: the reference's with the walls closing further, smoothly (the top and bottom walls move
      // towards each other by up to 0.4 mm at the start and 1.2 mm at the end, more near a random point along
      // the tube), so that pairs farther than the near gap on the reference come into contact, some by relative
      // moves above the margin and many neighbours by less.
      std::uniform_real_distribution<double> u(0.0, 1.0);
      Points x0b = pf.x0, x1b = pf.x1;
      const double zc = len * u(rng), width = 0.3 * len;
      for (Eigen::Index i = 0; i < x0b.rows(); ++i) {
        const double side = pf.rest(i, 1) / kTwinRadius;  // +1 on top, -1 at the bottom
        const double bump = 0.5 + 0.5 * std::exp(-std::pow((pf.rest(i, 2) - zc) / width, 2));
        x0b(i, 1) -= 2e-4 * side * bump;
        x1b(i, 1) -= 6e-4 * side * bump;
      }
      const PointsRef r0(pf.x0), r1(pf.x1);
      std::vector<Contact> restricted, full;
      CollisionStats sr, sf;
      detect_self_moved(surface, ws, x0b, x1b, gap, MoveFilter{&r1, near_gap - gap, nullptr, &r0, &near}, restricted, &sr);
      detect_self(surface, ws, x0b, x1b, gap, full, &sf);
      const std::string where = "k = " + std::to_string(k) + " seed = " + std::to_string(seed);
      expect_same_contacts(restricted, full, where);
      found += static_cast<long>(full.size());
      std::vector<Contact> on_reference;
      detect_self(surface, ws, pf.x0, pf.x1, near_gap, on_reference);
      const auto known = contact_set(on_reference);
      for (const ContactKey& c : contact_set(full)) new_contacts += !known.count(c);
      tests_restricted += sr.feature_tests;
      tests_full += sf.feature_tests;
    }
  }
  EXPECT_GT(found, 20);
  EXPECT_GT(new_contacts, 0) << "every contact was within the near gap on the reference: the test proves little";
  EXPECT_LT(tests_restricted, tests_full) << "the restriction skipped nothing: the test proves little";
}

// The case the margin decides: on the reference the walls are held flattened 0.9 mm apart (farther than the near
// gap: only pairs at the folds at the sides are near), and the next sweep squeezes them through each other. Every contact must come from the move
// test at margin near_gap - gap; with a margin larger than the walls' relative moves (2 mm) they are missed, so this
// case would catch a margin that is too large.
TEST(SelfCollision, ARestrictedDetectionFindsWallsThatWereApartOnTheReference) {
  const double gap = 1e-4, near_gap = 4e-4, len = kTwinLength;
  Points rest;
  Tris tris;
  make_tube(10, 14, kTwinRadius, len, rest, tris);
  // Flatten the tube towards y = 0 around mid-length: y scaled by 1 - depth at the middle.
  auto flattened = [&](double depth) {
    Points x = rest;
    for (Eigen::Index i = 0; i < x.rows(); ++i)
      x(i, 1) *= 1.0 - depth * std::exp(-std::pow((rest(i, 2) - 0.5 * len) / (0.2 * len), 2));
    return x;
  };
  const Points ref = flattened(0.953), x1 = flattened(1.02);
  for (int k : {6, 26}) {
    CollisionSurface surface(tris, rest);
    CollisionWorkspace ws(k);
    std::vector<Contact> at_ref, restricted, full, wrong;
    NearFeatures near;
    detect_self_near(surface, ws, ref, ref, gap, near_gap, at_ref, near);
    EXPECT_TRUE(at_ref.empty());
    const PointsRef r(ref);
    detect_self_moved(surface, ws, ref, x1, gap, MoveFilter{&r, near_gap - gap, nullptr, &r, &near}, restricted);
    detect_self(surface, ws, ref, x1, gap, full);
    ASSERT_GT(full.size(), 10u) << "k = " << k;
    EXPECT_EQ(contact_set(restricted), contact_set(full)) << "k = " << k;
    const auto kept = near_set(near);
    const long not_near = std::count_if(full.begin(), full.end(), [&](const Contact& c) {
      return kept.count(near_key(surface, c)) == 0;
    });
    EXPECT_GT(not_near, 10) << "k = " << k << ": the contacts were near already, the move test decides nothing";
    detect_self_moved(surface, ws, ref, x1, gap, MoveFilter{&r, 2e-3, nullptr, &r, &near}, wrong);
    EXPECT_LT(wrong.size(), full.size()) << "k = " << k << ": a 2 mm margin misses nothing here";
  }
}

TEST(SelfCollision, MovedDetectionRefusesABadFilterNamingIt) {
  Points rest;
  Tris tris;
  make_tube(4, 4, 0.01, 0.02, rest, tris);
  CollisionSurface surface(tris, rest);
  CollisionWorkspace ws(26);
  std::vector<Contact> out;
  const std::vector<std::uint8_t> three(3, 1);
  const Points short_ref = rest.topRows(2);
  const PointsRef ref(short_ref);
  auto message = [&](const MoveFilter& f) {
    try {
      detect_self_moved(surface, ws, rest, rest, 1e-4, f, out);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no throw");
  };
  EXPECT_EQ(message(MoveFilter{nullptr, 0.0, &three}),
            "flagged has 3 entries, expected n_points = " + std::to_string(rest.rows()));
  EXPECT_EQ(message(MoveFilter{&ref, 0.0, nullptr}),
            "x1_ref has 2 rows, expected n_points = " + std::to_string(rest.rows()));
  EXPECT_EQ(message(MoveFilter{nullptr, -1.0, nullptr}), "margin must be finite and >= 0 metres, got -1");
  try {
    detect_self_moved(surface, ws, rest, rest, -1e-4, MoveFilter{}, out);
    ADD_FAILURE() << "a negative gap was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "gap must be finite and >= 0 metres, got -0.0001");
  }
  const PointsRef full_ref(rest);
  EXPECT_EQ(message(MoveFilter{nullptr, 0.0, nullptr, &full_ref}), "x0_ref given without x1_ref");
  // Keys outside the surface: beyond the bit widths, an edge id past the count within them, a vertex of its own
  // face, and two edges out of order.
  ASSERT_LT(surface.num_edges(), 1 << surface.edge_bits());
  const std::uint64_t past_edges = static_cast<std::uint64_t>(surface.num_edges());  // edge 0 with edge num_edges
  const std::uint64_t own_vertex =
      (static_cast<std::uint64_t>(surface.triangle(0)[0]) << surface.tri_bits()) | std::uint64_t{0};
  const std::uint64_t out_of_order = (std::uint64_t{5} << surface.edge_bits()) | std::uint64_t{2};
  for (const auto& [vf, ee] : std::vector<std::pair<std::uint64_t, std::uint64_t>>{
           {~std::uint64_t{0}, 0}, {0, past_edges}, {own_vertex, 0}, {0, out_of_order}}) {
    NearFeatures alien;
    if (ee == 0) alien.vf.push_back(vf);
    else alien.ee.push_back(ee);
    EXPECT_EQ(message(MoveFilter{nullptr, 0.0, nullptr, nullptr, &alien}), "near holds a feature pair outside this surface")
        << vf << " " << ee;
  }
  // detect_self_near names its wider gap.
  NearFeatures near;
  std::string near_message = "no throw";
  try {
    detect_self_near(surface, ws, rest, rest, 1e-4, 5e-5, out, near);
  } catch (const std::invalid_argument& e) {
    near_message = e.what();
  }
  EXPECT_EQ(near_message, "near_gap must be finite and >= gap (0.0001 m), got 5e-05");
  EXPECT_EQ(message(MoveFilter{&full_ref, 0.0, nullptr, &ref}),
            "x0_ref has 2 rows, expected n_points = " + std::to_string(rest.rows()));
}

}  // namespace
}  // namespace lumen::collision
