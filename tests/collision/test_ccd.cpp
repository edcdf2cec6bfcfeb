// Elementary CCD tests (vertex-face, edge-edge) against exact ground truth: the dev-set queries, generated
// degenerate cases with analytic answers, and a brute-force twin (sampled exact distances) on random motions.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

#include <Eigen/Geometry>

#include "collision/ccd.hpp"
#include "collision/ccd_queries.hpp"

namespace lumen::collision {
namespace {

const std::string kDataDir = std::string(LUMEN_TEST_DATA_DIR) + "/ccd/";

// ---------------------------------------------------------------------------------------------------------
// Independent geometry (Ericson, Real-Time Collision Detection, 5.1.5 and 5.1.9): exact closest distances.

// Distance from point p to triangle abc.
double point_triangle_distance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return (p - a).norm();
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return (p - b).norm();
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return (p - (a + d1 / (d1 - d3) * ab)).norm();
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return (p - c).norm();
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return (p - (a + d2 / (d2 - d6) * ac)).norm();
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return (p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b))).norm();
  const double denom = 1.0 / (va + vb + vc);
  return (p - (a + ab * (vb * denom) + ac * (vc * denom))).norm();
}

// Distance between segments p1q1 and p2q2.
double segment_distance(const Vec3& p1, const Vec3& q1, const Vec3& p2, const Vec3& q2) {
  const Vec3 d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = d1.dot(d1), e = d2.dot(d2), f = d2.dot(r);
  double s = 0, t = 0;
  if (a <= 1e-300 && e <= 1e-300) return r.norm();
  if (a <= 1e-300) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= 1e-300) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2), denom = a * e - b * b;
      s = denom > 0 ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0) {
        t = 0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1) {
        t = 1;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  return ((p1 + d1 * s) - (p2 + d2 * t)).norm();
}

// ---------------------------------------------------------------------------------------------------------
// Queries: 4 points at t = 0 and t = 1, moved into a random rigid frame so nothing is axis-aligned.

struct Query {
  Vec3 x0[4], x1[4];
};

Vec3 lerp(const Vec3& a, const Vec3& b, double t) { return (1.0 - t) * a + t * b; }

// Distance between the primitives at time t (vf: x[0] vs triangle x[1..3]; ee: x[0]x[1] vs x[2]x[3]).
double distance_at(const Query& q, bool ee, double t) {
  Vec3 x[4];
  for (int i = 0; i < 4; ++i) x[i] = lerp(q.x0[i], q.x1[i], t);
  return ee ? segment_distance(x[0], x[1], x[2], x[3]) : point_triangle_distance(x[0], x[1], x[2], x[3]);
}

bool run(const Query& q, bool ee, double gap, CcdHit* hit, const CcdOptions& options = {}) {
  const Vec3* a = q.x0;
  const Vec3* b = q.x1;
  return ee ? edge_edge_ccd(a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3], gap, options, hit)
            : vertex_face_ccd(a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3], gap, options, hit);
}

// A rigid motion (rotation from a random unit quaternion, translation in [-1, 1]^3); seed 0 = identity.
struct Frame {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Vec3 o = Vec3::Zero();
  Vec3 operator()(const Vec3& x) const { return R * x + o; }
};

Frame random_frame(unsigned seed) {
  Frame f;
  if (seed == 0) return f;
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  f.R = Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized().toRotationMatrix();
  f.o = Vec3(u(rng), u(rng), u(rng));
  return f;
}

Query make_query(const Frame& f, const Vec3 (&x0)[4], const Vec3 (&x1)[4]) {
  Query q;
  for (int i = 0; i < 4; ++i) {
    q.x0[i] = f(x0[i]);
    q.x1[i] = f(x1[i]);
  }
  return q;
}

constexpr double kTol = CcdOptions{}.tolerance;  // default acceptance width, metres
constexpr double kSlack = 1e-12;                  // rounding of the rotated inputs, in time units

// The reported contact is consistent: toi in [lo, hi] and, unless the work bound was hit, the primitives
// within gap + 2 tolerance of each other at toi (by the independent distance).
void expect_contact(const Query& q, bool ee, double gap, double lo, double hi, const CcdOptions& o = {}) {
  CcdHit hit;
  ASSERT_TRUE(run(q, ee, gap, &hit, o));
  EXPECT_GE(hit.toi, lo);
  EXPECT_LE(hit.toi, hi);
  EXPECT_FALSE(hit.bounded);
  EXPECT_LE(distance_at(q, ee, hit.toi), gap + 2.0 * o.tolerance + 1e-12);
  EXPECT_GE(hit.s, 0.0);
  EXPECT_GE(hit.t, 0.0);
  EXPECT_LE(ee ? hit.s : hit.s + hit.t, 1.0 + 1e-15);
  EXPECT_LE(hit.t, 1.0);
}

// Unit right triangle a = 0, b = e_x, c = e_y (static) and a vertex p moving from p0 to p1.
Query vf_static_triangle(const Frame& f, const Vec3& p0, const Vec3& p1) {
  const Vec3 x0[4] = {p0, Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  const Vec3 x1[4] = {p1, Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  return make_query(f, x0, x1);
}

// ---------------------------------------------------------------------------------------------------------
// Dev set: zero false negatives, false positives within those of Tight-Inclusion at tolerance 1e-6.

TEST(CcdDevSet, HandcraftedHasNoFalseNegatives) {
  const CcdFileStats s = run_ccd_file(kDataDir + "handcrafted.csv");
  EXPECT_EQ(s.vf.queries, 1440);
  EXPECT_EQ(s.ee.queries, 2036);
  EXPECT_EQ(s.vf.labelled, s.vf.queries);
  EXPECT_EQ(s.vf.false_negatives, 0);
  EXPECT_EQ(s.ee.false_negatives, 0);
  EXPECT_LE(s.vf.false_positives, 43);
  EXPECT_LE(s.ee.false_positives, 65);
}

TEST(CcdDevSet, SimulationHasNoFalseNegatives) {
  const CcdFileStats s = run_ccd_file(kDataDir + "simulation.csv");
  EXPECT_EQ(s.vf.queries, 10000);
  EXPECT_EQ(s.ee.queries, 10000);
  EXPECT_EQ(s.vf.false_negatives, 0);
  EXPECT_EQ(s.ee.false_negatives, 0);
  EXPECT_LE(s.vf.false_positives, 53);
  EXPECT_LE(s.ee.false_positives, 181);
}

// Every reported dev-set contact has its toi in [0, 1], parameters in the domain and, unless the work
// bound was reached (then the contact is conservative; a handful of queries), the primitives within 2
// tolerances at toi (independent distance).
TEST(CcdDevSet, ContactsAreConsistentWithTheDistance) {
  for (const char* name : {"handcrafted.csv", "simulation.csv"}) {
    const std::vector<CcdQuery> queries = read_ccd_queries(kDataDir + name);
    int contacts = 0, bounded = 0;
    for (const CcdQuery& cq : queries) {
      Query q;
      std::copy(cq.x0, cq.x0 + 4, q.x0);
      std::copy(cq.x1, cq.x1 + 4, q.x1);
      CcdHit hit;
      if (!run(q, cq.edge_edge, 0.0, &hit)) continue;
      ++contacts;
      ASSERT_GE(hit.toi, 0.0) << name << " line " << cq.line;
      ASSERT_LE(hit.toi, 1.0) << name << " line " << cq.line;
      ASSERT_GE(hit.s, 0.0) << name << " line " << cq.line;
      ASSERT_GE(hit.t, 0.0) << name << " line " << cq.line;
      ASSERT_LE(cq.edge_edge ? std::max(hit.s, hit.t) : hit.s + hit.t, 1.0 + 1e-15) << name << " line " << cq.line;
      if (hit.bounded) {
        ++bounded;
        continue;
      }
      ASSERT_LE(distance_at(q, cq.edge_edge, hit.toi), 2.0 * kTol) << name << " line " << cq.line;
    }
    EXPECT_GT(contacts, 0);
    EXPECT_LE(bounded, 10) << name;
  }
}

// ---------------------------------------------------------------------------------------------------------
// Generated cases with analytic answers (each in several random frames).

// A vertex falls at speed s onto a static triangle from height h: contact at t* = h / s at (x, y).
TEST(CcdVertexFace, FallingVertexHitsAtTheAnalyticTime) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  for (unsigned seed = 0; seed < 50; ++seed) {
    const Frame f = random_frame(seed);
    const double x = 0.05 + 0.4 * u01(rng), y = 0.05 + 0.4 * u01(rng);
    const double h = 0.01 + 0.5 * u01(rng), s = h / (0.02 + 0.96 * u01(rng));
    const double t_star = h / s;
    const Query q = vf_static_triangle(f, Vec3(x, y, h), Vec3(x, y, h - s));
    CcdHit hit;
    ASSERT_TRUE(run(q, false, 0.0, &hit)) << "seed " << seed;
    EXPECT_LE(hit.toi, t_star + kSlack) << "seed " << seed;
    EXPECT_GE(hit.toi, t_star - kTol / s - kSlack) << "seed " << seed;
    EXPECT_NEAR(hit.s, x, 1e-6) << "seed " << seed;
    EXPECT_NEAR(hit.t, y, 1e-6) << "seed " << seed;
  }
}

// With gap g, a head-on approach at speed s reports contact g / s earlier (within the tolerance).
TEST(CcdVertexFace, GapTriggersEarlierByGapOverSpeed) {
  for (unsigned seed = 0; seed < 10; ++seed) {
    const Frame f = random_frame(seed + 100);
    const double h = 0.5, s = 0.8, t_star = h / s;
    const Query q = vf_static_triangle(f, Vec3(0.25, 0.3, h), Vec3(0.25, 0.3, h - s));
    CcdHit hit0;
    ASSERT_TRUE(run(q, false, 0.0, &hit0));
    for (double gap : {1e-5, 1e-3, 0.05}) {
      CcdHit hit;
      ASSERT_TRUE(run(q, false, gap, &hit)) << "gap " << gap;
      const double expected = t_star - gap / s;
      EXPECT_LE(hit.toi, expected + kSlack) << "gap " << gap;
      EXPECT_GE(hit.toi, expected - 2.0 * kTol / s - kSlack) << "gap " << gap;
      EXPECT_NEAR(hit0.toi - hit.toi, gap / s, 2.0 * kTol / s + kSlack) << "gap " << gap;
    }
  }
}

// A vertex passing the plane beside the triangle (1e-3 outside an edge) never touches it, with or
// without a gap below that distance; with a larger gap it does.
TEST(CcdVertexFace, NearMissBesideAnEdge) {
  for (unsigned seed = 0; seed < 10; ++seed) {
    const Frame f = random_frame(seed + 200);
    const Query q = vf_static_triangle(f, Vec3(0.5, -1e-3, 0.3), Vec3(0.5, -1e-3, -0.3));
    EXPECT_FALSE(run(q, false, 0.0, nullptr));
    EXPECT_FALSE(run(q, false, 5e-4, nullptr));
    expect_contact(q, false, 2e-3, 0.0, 0.5 + kSlack);
  }
}

// Coplanar motion: a vertex sliding in the plane enters the triangle through the edge x = 0 at t = 2/3;
// sliding along y = 2 it misses it by 1.
TEST(CcdVertexFace, CoplanarSlidingEntersOrMisses) {
  for (unsigned seed = 0; seed < 10; ++seed) {
    const Frame f = random_frame(seed + 300);
    const Query in = vf_static_triangle(f, Vec3(-1.0, 0.25, 0.0), Vec3(0.5, 0.25, 0.0));
    expect_contact(in, false, 0.0, 2.0 / 3.0 - kTol / 1.5 - kSlack, 2.0 / 3.0 + kSlack);
    const Query out = vf_static_triangle(f, Vec3(-1.0, 2.0, 0.0), Vec3(0.5, 2.0, 0.0));
    EXPECT_FALSE(run(out, false, 0.0, nullptr));
  }
}

// Motion along the face (inside it all the time), and no motion: touching at t = 0.
TEST(CcdVertexFace, MotionAlongTheFaceAndRestingContact) {
  for (unsigned seed = 0; seed < 10; ++seed) {
    const Frame f = random_frame(seed + 400);
    expect_contact(vf_static_triangle(f, Vec3(0.2, 0.2, 0.0), Vec3(0.4, 0.3, 0.0)), false, 0.0, 0.0, 0.0);
    // Resting on the face, on an edge, on a vertex.
    for (const Vec3& p : {Vec3(0.3, 0.3, 0.0), Vec3(0.5, 0.0, 0.0), Vec3(0.5, 0.5, 0.0), Vec3(1.0, 0.0, 0.0)})
      expect_contact(vf_static_triangle(f, p, p), false, 0.0, 0.0, 0.0);
    // Resting 1e-3 above: no contact (and none with a gap below 1e-3; contact with a larger one).
    const Query above = vf_static_triangle(f, Vec3(0.3, 0.3, 1e-3), Vec3(0.3, 0.3, 1e-3));
    EXPECT_FALSE(run(above, false, 0.0, nullptr));
    EXPECT_FALSE(run(above, false, 0.9e-3, nullptr));
    expect_contact(above, false, 1.1e-3, 0.0, 0.0);
  }
}

// Separations far below the default tolerance are resolved with a smaller tolerance.
TEST(CcdVertexFace, TinySeparationWithFineTolerance) {
  for (double eps : {1e-8, 1e-12}) {
    CcdOptions o;
    o.tolerance = eps / 100.0;
    for (unsigned seed = 0; seed < 5; ++seed) {
      const Frame f = random_frame(seed + 500);
      // Resting, and sliding parallel to the face, at height eps.
      EXPECT_FALSE(run(vf_static_triangle(f, Vec3(0.3, 0.3, eps), Vec3(0.3, 0.3, eps)), false, 0.0, nullptr, o))
          << eps;
      EXPECT_FALSE(run(vf_static_triangle(f, Vec3(-0.5, 0.3, eps), Vec3(0.8, 0.1, eps)), false, 0.0, nullptr, o))
          << eps;
    }
  }
}

// The vertex crosses the line of edge ab exactly at t = 1/2 (a contact on the boundary of the face).
TEST(CcdVertexFace, VertexThroughAnEdge) {
  for (unsigned seed = 0; seed < 10; ++seed) {
    const Frame f = random_frame(seed + 600);
    const Query q = vf_static_triangle(f, Vec3(0.5, -0.25, 0.25), Vec3(0.5, 0.25, -0.25));
    const double speed = std::sqrt(0.5);
    expect_contact(q, false, 0.0, 0.5 - kTol / speed - kSlack, 0.5 + kSlack);
  }
}

// Contact exactly at the ends of the interval, and just outside it.
TEST(CcdVertexFace, ContactAtTheEndsOfTheStep) {
  for (unsigned seed = 0; seed < 10; ++seed) {
    const Frame f = random_frame(seed + 700);
    const double s = 0.5;
    // Reaches the plane at t = 1 exactly; at t = 1 + 1e-3 (misses by 5e-4 at t = 1).
    expect_contact(vf_static_triangle(f, Vec3(0.2, 0.2, s), Vec3(0.2, 0.2, 0.0)), false, 0.0,
                   1.0 - kTol / s - kSlack, 1.0);
    const double late = s * (1.0 + 1e-3);
    EXPECT_FALSE(run(vf_static_triangle(f, Vec3(0.2, 0.2, late), Vec3(0.2, 0.2, late - s)), false, 0.0, nullptr));
    // At t = 1 + 1e-9 the vertex is 5e-10 away at t = 1: within tolerance, a contact may be reported,
    // but not earlier than the tolerance allows.
    const double barely = s * (1.0 + 1e-9);
    CcdHit hit;
    if (run(vf_static_triangle(f, Vec3(0.2, 0.2, barely), Vec3(0.2, 0.2, barely - s)), false, 0.0, &hit)) {
      EXPECT_GE(hit.toi, 1.0 - 2.0 * kTol / s - kSlack);
    }
    // Leaves the plane at t = 0 exactly (touching at the start); left it at t = -1e-3.
    expect_contact(vf_static_triangle(f, Vec3(0.2, 0.2, 0.0), Vec3(0.2, 0.2, -s)), false, 0.0, 0.0, 0.0);
    EXPECT_FALSE(run(vf_static_triangle(f, Vec3(0.2, 0.2, -1e-3 * s), Vec3(0.2, 0.2, -1.001 * s)), false, 0.0,
                     nullptr));
  }
}

// A moving, rotating triangle: the vertex is placed so that it meets the face at a chosen time t* and point
// (u*, v*); the reported toi is never later than t* (an earlier contact is allowed) and consistent with the
// distance.
TEST(CcdVertexFace, MovingTriangleMetAtAChosenTime) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0), u01(0.0, 1.0);
  for (int k = 0; k < 200; ++k) {
    Vec3 x0[4], x1[4];
    for (int i = 1; i < 4; ++i) {
      x0[i] = Vec3(u(rng), u(rng), u(rng));
      x1[i] = x0[i] + 0.3 * Vec3(u(rng), u(rng), u(rng));
    }
    const double t_star = 0.05 + 0.9 * u01(rng);
    double us = u01(rng), vs = u01(rng);
    if (us + vs > 1.0) {
      us = 1.0 - us;
      vs = 1.0 - vs;
    }
    Vec3 x[4];
    for (int i = 1; i < 4; ++i) x[i] = lerp(x0[i], x1[i], t_star);
    const Vec3 target = x[1] + us * (x[2] - x[1]) + vs * (x[3] - x[1]);
    x0[0] = target + Vec3(u(rng), u(rng), u(rng));
    x1[0] = x0[0] + (target - x0[0]) / t_star;
    Query q;
    std::copy(x0, x0 + 4, q.x0);
    std::copy(x1, x1 + 4, q.x1);
    CcdHit hit;
    ASSERT_TRUE(run(q, false, 0.0, &hit)) << k;
    EXPECT_LE(hit.toi, t_star + 1e-9) << k;
    EXPECT_FALSE(hit.bounded) << k;
    EXPECT_LE(distance_at(q, false, hit.toi), 2.0 * kTol) << k;
  }
}

// ---------------------------------------------------------------------------------------------------------
// Edge-edge.

// Edge ab = [-1, 1] e_x (static) and edge cd along e_y at height z = h - s t: they cross at t* = h / s,
// at the middle of both.
TEST(CcdEdgeEdge, CrossingEdgesMeetAtTheAnalyticTime) {
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  for (unsigned seed = 0; seed < 50; ++seed) {
    const Frame f = random_frame(seed + 800);
    const double h = 0.01 + 0.5 * u01(rng), s = h / (0.02 + 0.96 * u01(rng)), t_star = h / s;
    const double xc = -0.8 + 1.6 * u01(rng), yc = -0.8 + 1.6 * u01(rng);
    const Vec3 x0[4] = {Vec3(-1, yc, 0), Vec3(1, yc, 0), Vec3(xc, -1, h), Vec3(xc, 1, h)};
    const Vec3 x1[4] = {Vec3(-1, yc, 0), Vec3(1, yc, 0), Vec3(xc, -1, h - s), Vec3(xc, 1, h - s)};
    const Query q = make_query(f, x0, x1);
    CcdHit hit;
    ASSERT_TRUE(run(q, true, 0.0, &hit)) << seed;
    EXPECT_LE(hit.toi, t_star + kSlack) << seed;
    EXPECT_GE(hit.toi, t_star - kTol / s - kSlack) << seed;
    EXPECT_NEAR(hit.s, 0.5 * (xc + 1.0), 1e-6) << seed;
    EXPECT_NEAR(hit.t, 0.5 * (yc + 1.0), 1e-6) << seed;
    // The same edges passing 1e-3 beyond the end of ab never touch.
    const Vec3 y0[4] = {Vec3(-1, yc, 0), Vec3(1, yc, 0), Vec3(1.001, -1, h), Vec3(1.001, 1, h)};
    const Vec3 y1[4] = {Vec3(-1, yc, 0), Vec3(1, yc, 0), Vec3(1.001, -1, h - s), Vec3(1.001, 1, h - s)};
    EXPECT_FALSE(run(make_query(f, y0, y1), true, 0.0, nullptr)) << seed;
  }
}

// Parallel edges: passing through each other (a whole segment of contacts at t = 1/2), touching at rest,
// and separated by eps (relative to their length 1) at rest and while sliding along each other: eps = 1e-8
// in rotated frames with a tolerance of eps / 100; eps = 1e-12 in the axis frame (rotated, the rounding of
// the inputs alone tilts the edges by ~1e-16, which hides a 1e-12 offset from any double-precision
// direction: there a contact within the default tolerance is reported, conservatively).
TEST(CcdEdgeEdge, ParallelEdges) {
  for (unsigned seed = 0; seed < 10; ++seed) {
    const Frame f = random_frame(seed + 900);
    {
      const Vec3 x0[4] = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.25, 0.5, 0), Vec3(0.75, 0.5, 0)};
      const Vec3 x1[4] = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.25, -0.5, 0), Vec3(0.75, -0.5, 0)};
      expect_contact(make_query(f, x0, x1), true, 0.0, 0.5 - kTol - kSlack, 0.5 + kSlack);
    }
    {
      const Vec3 x[4] = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.25, 0, 0), Vec3(1.75, 0, 0)};
      expect_contact(make_query(f, x, x), true, 0.0, 0.0, 0.0);
    }
    for (double eps : {1e-8, 1e-12, 10.0 * kTol}) {
      const Frame g = eps == 1e-12 ? random_frame(0) : f;
      CcdOptions o;
      if (eps < kTol) o.tolerance = eps / 100.0;
      for (double sign : {1.0, -1.0}) {
        const double y = sign * eps;
        const Vec3 r[4] = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.25, y, 0), Vec3(0.75, y, 0)};
        EXPECT_FALSE(run(make_query(g, r, r), true, 0.0, nullptr, o)) << eps;
        const Vec3 s1[4] = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.75, y, 0), Vec3(1.25, y, 0)};
        EXPECT_FALSE(run(make_query(g, r, s1), true, 0.0, nullptr, o)) << eps;
        // At rest eps apart with the default tolerance: a contact may be reported (within tolerance),
        // then at the start.
        CcdHit hit;
        if (run(make_query(f, r, r), true, 0.0, &hit)) {
          EXPECT_EQ(hit.toi, 0.0) << eps;
        }
      }
    }
  }
}

// Collinear edges: ends overlapping by eps touch at rest; ends eps apart do not (fine tolerance).
TEST(CcdEdgeEdge, CollinearEndsOverlappingOrApart) {
  for (unsigned seed = 0; seed < 10; ++seed) {
    const Frame f = random_frame(seed + 1000);
    for (double eps : {1e-8, 1e-12}) {
      CcdOptions o;
      o.tolerance = eps / 100.0;
      const Vec3 overlap[4] = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1 - eps, 0, 0), Vec3(2, 0, 0)};
      expect_contact(make_query(f, overlap, overlap), true, 0.0, 0.0, 0.0, o);
      const Vec3 apart[4] = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1 + eps, 0, 0), Vec3(2, 0, 0)};
      EXPECT_FALSE(run(make_query(f, apart, apart), true, 0.0, nullptr, o)) << eps;
    }
  }
}

// A gap makes crossing edges report contact gap / s earlier (head-on: the lines stay parallel to the
// separating direction).
TEST(CcdEdgeEdge, GapTriggersEarlierByGapOverSpeed) {
  for (unsigned seed = 0; seed < 10; ++seed) {
    const Frame f = random_frame(seed + 1100);
    const double h = 0.6, s = 1.2, t_star = h / s;
    const Vec3 x0[4] = {Vec3(-1, 0.1, 0), Vec3(1, 0.1, 0), Vec3(0.2, -1, h), Vec3(0.2, 1, h)};
    const Vec3 x1[4] = {Vec3(-1, 0.1, 0), Vec3(1, 0.1, 0), Vec3(0.2, -1, h - s), Vec3(0.2, 1, h - s)};
    const Query q = make_query(f, x0, x1);
    for (double gap : {1e-5, 1e-3, 0.05}) {
      CcdHit hit;
      ASSERT_TRUE(run(q, true, gap, &hit));
      const double expected = t_star - gap / s;
      EXPECT_LE(hit.toi, expected + kSlack) << gap;
      EXPECT_GE(hit.toi, expected - 2.0 * kTol / s - kSlack) << gap;
    }
  }
}

// ---------------------------------------------------------------------------------------------------------
// Brute-force twin on random motions: a crossing seen by dense sampling (the sign of the plane distance or
// of the line distance flips between two samples with the crossing point well inside the primitives), or
// with a gap a sample within the gap, must be reported no later than that sample; every reported contact
// (gap 0 and gap > 0) is within gap + 2 tolerances at toi; a query reported free keeps distance > gap at
// every sample.

// Signed distance of the vf point from the face plane / of edge cd from the line of ab along their common
// normal, and whether the closest points then lie inside with margin m (parameter units).
double signed_separation(const Query& q, bool ee, double t, double m, bool* inside) {
  Vec3 x[4];
  for (int i = 0; i < 4; ++i) x[i] = lerp(q.x0[i], q.x1[i], t);
  if (!ee) {
    const Vec3 n = (x[2] - x[1]).cross(x[3] - x[1]);
    const Vec3 ab = x[2] - x[1], ac = x[3] - x[1], ap = x[0] - x[1];
    const double d00 = ab.dot(ab), d01 = ab.dot(ac), d11 = ac.dot(ac), d20 = ap.dot(ab), d21 = ap.dot(ac);
    const double den = d00 * d11 - d01 * d01;
    const double v = (d11 * d20 - d01 * d21) / den, w = (d00 * d21 - d01 * d20) / den;
    *inside = v > m && w > m && v + w < 1.0 - m;
    return n.dot(ap) / n.norm();
  }
  const Vec3 d1 = x[1] - x[0], d2 = x[3] - x[2], r = x[0] - x[2];
  const Vec3 n = d1.cross(d2);
  const double a = d1.dot(d1), b = d1.dot(d2), e = d2.dot(d2), c = d1.dot(r), f = d2.dot(r);
  const double den = a * e - b * b;
  const double s = (b * f - c * e) / den, u = (a * f - b * c) / den;
  *inside = s > m && s < 1.0 - m && u > m && u < 1.0 - m;
  return n.dot(r) / n.norm();
}

TEST(CcdBruteForce, RandomMotionsAgreeWithSampledDistances) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  constexpr int kSamples = 256;
  int crossings = 0, free_queries = 0;
  for (int k = 0; k < 600; ++k) {
    const bool ee = k % 2 == 1;
    Query q;
    for (int i = 0; i < 4; ++i) {
      q.x0[i] = Vec3(u(rng), u(rng), u(rng));
      q.x1[i] = q.x0[i] + 0.8 * Vec3(u(rng), u(rng), u(rng));
    }
    // First sampled crossing, the first sample within the gap used below, and the smallest distance.
    constexpr double kGap = 0.02;
    double first_crossing = 2.0, first_within_gap = 2.0, min_distance = 1e300;
    bool prev_inside = false;
    double prev = signed_separation(q, ee, 0.0, 0.02, &prev_inside);
    for (int i = 0; i <= kSamples; ++i) {
      const double t = static_cast<double>(i) / kSamples;
      const double d = distance_at(q, ee, t);
      min_distance = std::min(min_distance, d);
      if (d <= kGap && first_within_gap > 1.0) first_within_gap = t;
      if (i == 0) continue;
      bool inside = false;
      const double cur = signed_separation(q, ee, t, 0.02, &inside);
      if (first_crossing > 1.0 && (prev < 0) != (cur < 0) && inside && prev_inside) first_crossing = t;
      prev = cur;
      prev_inside = inside;
    }
    for (double gap : {0.0, kGap}) {
      CcdHit hit;
      const bool contact = run(q, ee, gap, &hit);
      const double first = gap > 0.0 ? std::min(first_crossing, first_within_gap) : first_crossing;
      if (first <= 1.0) {
        ++crossings;
        ASSERT_TRUE(contact) << k << " gap " << gap;
        EXPECT_LE(hit.toi, first) << k << " gap " << gap;
      }
      if (contact) {
        ASSERT_FALSE(hit.bounded) << k;
        EXPECT_LE(distance_at(q, ee, hit.toi), gap + 2.0 * kTol) << k << " gap " << gap;
      } else {
        ++free_queries;
        EXPECT_GT(min_distance, gap) << k << " gap " << gap;
      }
    }
  }
  // The random set exercises both outcomes.
  EXPECT_GT(crossings, 50);
  EXPECT_GT(free_queries, 50);
}

// ---------------------------------------------------------------------------------------------------------
// Work bound and validation.

// A query that needs many boxes (parallel edges passing through each other, a segment of contacts at
// t = 1/2) with a tiny work bound reports a conservative contact: flagged, and no later than t = 1/2.
TEST(CcdWorkBound, TinyBoundReportsAConservativeContact) {
  const Frame f = random_frame(1200);
  const Vec3 x0[4] = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.25, 0.5, 0), Vec3(0.75, 0.5, 0)};
  const Vec3 x1[4] = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.25, -0.5, 0), Vec3(0.75, -0.5, 0)};
  const Query q = make_query(f, x0, x1);
  CcdOptions o;
  CcdHit hit;
  ASSERT_TRUE(run(q, true, 0.0, &hit, o));
  EXPECT_FALSE(hit.bounded);
  ASSERT_GT(hit.boxes, 10);
  o.max_boxes = 5;
  ASSERT_TRUE(run(q, true, 0.0, &hit, o));
  EXPECT_TRUE(hit.bounded);
  EXPECT_LE(hit.boxes, o.max_boxes + 2);
  EXPECT_GE(hit.toi, 0.0);
  EXPECT_LE(hit.toi, 0.5 + kSlack);
}

TEST(CcdValidation, RejectsBadInput) {
  const Vec3 z = Vec3::Zero(), x = Vec3::UnitX(), y = Vec3::UnitY();
  const Vec3 bad(0.0, std::nan(""), 0.0);
  try {
    vertex_face_ccd(z, x, y, bad, z, x, y, z, 0.0, nullptr);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("c0"), std::string::npos) << e.what();
  }
  try {
    edge_edge_ccd(z, x, y, z, z, x, y, Vec3(std::numeric_limits<double>::infinity(), 0, 0), 0.0, nullptr);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("d1"), std::string::npos) << e.what();
  }
  try {
    vertex_face_ccd(z, x, y, z, z, x, y, z, -1e-3, nullptr);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "ccd: gap must be finite and >= 0, got -0.001");
  }
  // Differences that overflow: a conservative contact at t = 0.
  CcdHit hit;
  const Vec3 far(1e308, 0, 0);
  EXPECT_TRUE(vertex_face_ccd(far, -far, y, z, far, -far, y, z, 0.0, &hit));
  EXPECT_TRUE(hit.bounded);
  EXPECT_EQ(hit.toi, 0.0);
  CcdOptions o;
  o.tolerance = 0.0;
  EXPECT_THROW(validate_ccd_options(o), std::invalid_argument);
  o.tolerance = 1e-6;
  o.max_boxes = 0;
  try {
    validate_ccd_options(o);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_boxes"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace lumen::collision
