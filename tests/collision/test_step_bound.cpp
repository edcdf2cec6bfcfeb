// The per-vertex step bound: the spatial hash against its all-pairs twin on perturbed, partly pinched tubes; the
// guarantee (a truncated motion that would have crossed the walls stays free of contact by the CCD and of
// intersection by the exact check); the rule on a known pair; zero and small motions; validation.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "collision/intersect.hpp"
#include "collision/step_bound.hpp"
#include "collision/surface.hpp"
#include "support/tube.hpp"

namespace lumen::collision {
namespace {

using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using Tris = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;
using test::make_tube;  // open tube along z (tests/support/tube.hpp)

constexpr double kRadius = 0.01;  // tube radius, metres
constexpr double kLength = 0.05;  // tube length, metres

// A tube pinched at mid-length by `pinch` of its radius (1 = the walls meet) plus uniform noise of `noise`
// metres on every coordinate.
Points pinched(const Points& rest, double pinch, double noise, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Points x = rest;
  for (int i = 0; i < x.rows(); ++i) {
    const double s = (rest(i, 2) - 0.5 * kLength) / (0.2 * kLength);
    x(i, 1) *= 1.0 - pinch * std::exp(-s * s);
    for (int k = 0; k < 3; ++k) x(i, k) += noise * u(rng);
  }
  return x;
}

// Whether the motion x0 -> x0 + dx has a contact by the CCD (gap 0) or ends intersecting by the exact check.
struct MotionCheck {
  std::size_t contacts = 0;
  long intersecting = 0;
};
MotionCheck check_motion(const CollisionSurface& s, const Tris& tris, const Points& x0, const Points& dx) {
  CollisionWorkspace ws;
  std::vector<Contact> out;
  const Points x1 = x0 + dx;
  detect_self(s, ws, x0, x1, 0.0, out);
  return {out.size(), count_intersecting_pairs(x1, tris)};
}

// The hash gives the brute-force twin's bounds on perturbed, partly pinched tubes, for radii from under an edge
// to over the tube's diameter.
TEST(StepBound, HashEqualsBruteForceOnPerturbedTubes) {
  Points rest;
  Tris tris;
  make_tube(8, 12, kRadius, kLength, rest, tris);
  std::mt19937 rng(5);
  int limited = 0;
  for (int trial = 0; trial < 3; ++trial) {
    const Points x0 = pinched(rest, 0.5 + 0.15 * trial, 3e-4, rng);
    const CollisionSurface s(tris, static_cast<int>(x0.rows()));
    for (const double r : {1e-3, 6e-3, 3e-2}) {
      StepBoundOptions opt;
      opt.radius = r;
      const Eigen::VectorXd fast = vertex_step_bounds(s, x0, opt);
      const Eigen::VectorXd brute = vertex_step_bounds_brute_force(s, x0, opt);
      ASSERT_EQ(fast.size(), brute.size());
      EXPECT_LE((fast - brute).cwiseAbs().maxCoeff(), 1e-12) << "trial " << trial << " r " << r;
      EXPECT_LE(fast.maxCoeff(), 0.5 * kStepFraction * r);
      EXPECT_GE(fast.minCoeff(), 0.0);
      for (Eigen::Index v = 0; v < fast.size(); ++v) limited += fast[v] < 0.5 * kStepFraction * r;
    }
  }
  EXPECT_GT(limited, 400);  // most bounds come from pair distances, not from the radius
}

// Large random motions of a partly pinched tube that cross its walls (asserted: the untruncated motion has CCD
// contacts and ends intersecting), truncated to the bounds: no contact, no intersection, some motion kept.
TEST(StepBound, TruncatedLargeMotionsStayFreeOfContactAndIntersection) {
  Points rest;
  Tris tris;
  make_tube(12, 16, kRadius, kLength, rest, tris);
  std::mt19937 rng(17);
  std::normal_distribution<double> nd;
  double kept_sum = 0.0;
  for (int trial = 0; trial < 8; ++trial) {
    const std::string what = "trial " + std::to_string(trial);
    const Points x0 = pinched(rest, 0.6 + 0.03 * trial, 2e-4, rng);
    const CollisionSurface s(tris, x0);
    ASSERT_EQ(count_intersecting_pairs(x0, tris), 0) << what;
    // The upper wall (y > 0) driven down through the lower one at mid-length, plus random vertex noise of about
    // an edge length on odd trials.
    const double amp = (1.0 + 0.1 * (trial % 5)) * kRadius;  // metres
    const double noise = trial % 2 ? 3e-3 : 0.0;             // metres
    Points dx = Points::Zero(x0.rows(), 3);
    for (int i = 0; i < x0.rows(); ++i) {
      const double t = (x0(i, 2) - 0.5 * kLength) / (0.2 * kLength);
      if (x0(i, 1) > 0.0) dx(i, 1) = -amp * std::exp(-t * t);
      for (int k = 0; k < 3; ++k) dx(i, k) += noise * nd(rng);
    }
    const MotionCheck full = check_motion(s, tris, x0, dx);
    ASSERT_GT(full.contacts, 0u) << what;
    ASSERT_GT(full.intersecting, 0) << what;

    StepBoundOptions opt;
    opt.radius = 1e-2;  // metres, a few edge lengths
    const TruncatedStep step = bound_step(s, x0, dx, opt);
    const MotionCheck cut = check_motion(s, tris, x0, step.dx);
    EXPECT_EQ(cut.contacts, 0u) << what;
    EXPECT_EQ(cut.intersecting, 0) << what;
    EXPECT_GT(step.kept, 0.02) << what;
    kept_sum += step.kept;
    EXPECT_LT(step.kept, 1.0) << what;
    EXPECT_GT(step.truncated, 0) << what;
  }
  std::printf("mean kept fraction of the truncated motions: %.3f\n", kept_sum / 8);
}

// Two parallel triangles d apart, offset so that the closest pair is known: every vertex is bounded by
// gamma / 2 * d, the third vertex far from the other triangle by its own (larger) distances.
TEST(StepBound, BoundsFollowTheRuleOnAKnownPair) {
  constexpr double d = 2e-3;  // metres
  Points x(6, 3);
  x << 0, 0, 0, 1e-2, 0, 0, 0, 1e-2, 0,  // triangle 0 in z = 0
      0, 0, d, 1e-2, 0, d, 0, 1e-2, d;   // triangle 1 in z = d, right above
  Tris tris(2, 3);
  tris << 0, 1, 2, 3, 4, 5;
  const CollisionSurface s(tris, static_cast<int>(x.rows()));
  StepBoundOptions opt;
  opt.radius = 5e-3;
  const Eigen::VectorXd b = vertex_step_bounds(s, x, opt);
  for (int v = 0; v < 6; ++v) EXPECT_DOUBLE_EQ(b[v], 0.5 * kStepFraction * d) << "vertex " << v;
  // Nothing within r: the bound is gamma / 2 * r.
  opt.radius = 1e-3;
  const Eigen::VectorXd far = vertex_step_bounds(s, x, opt);
  for (int v = 0; v < 6; ++v) EXPECT_DOUBLE_EQ(far[v], 0.5 * kStepFraction * opt.radius) << "vertex " << v;
  EXPECT_EQ(far, vertex_step_bounds_brute_force(s, x, opt));
}

// A small triangle whose vertex p hovers h above the middle of a large triangle, its edges pointing away: the
// large triangle's vertices are bounded by p's distance to their triangle (not only by edge-edge distances, which
// are about a centimetre here), so lifting the large triangle by 3 h, which would cross the small one, is cut
// to a safe step.
TEST(StepBound, TriangleVerticesAreBoundedByNearbyPoints) {
  constexpr double h = 1e-3;  // metres
  Points x0(6, 3);
  x0 << -0.01, -0.01, 0, 0.02, -0.01, 0, -0.01, 0.02, 0,  // a, b, c: the large triangle in z = 0
      0, 0, h, 1e-3, 0, h + 3e-3, 0, 1e-3, h + 3e-3;     // p, q, s: p above its middle, q and s higher
  Tris tris(2, 3);
  tris << 0, 1, 2, 3, 4, 5;
  const CollisionSurface s(tris, x0);
  Points dx = Points::Zero(6, 3);
  dx.col(2).head(3).setConstant(3.0 * h);  // the large triangle lifted through p
  const MotionCheck full = check_motion(s, tris, x0, dx);
  ASSERT_GT(full.contacts, 0u);
  ASSERT_GT(full.intersecting, 0);
  StepBoundOptions opt;
  opt.radius = 2e-2;
  const TruncatedStep step = bound_step(s, x0, dx, opt);
  for (int v = 0; v < 3; ++v) EXPECT_NEAR(step.dx(v, 2), 0.5 * kStepFraction * h, 1e-15) << "vertex " << v;
  const MotionCheck cut = check_motion(s, tris, x0, step.dx);
  EXPECT_EQ(cut.contacts, 0u);
  EXPECT_EQ(cut.intersecting, 0);
}

// dx = 0 stays 0 (kept fraction 1); vertices farther than r from every non-adjacent primitive keep a motion
// shorter than gamma / 2 * r in full; points not on the surface are never bounded.
TEST(StepBound, ZeroAndSmallMotionsAreKept) {
  Points rest;
  Tris tris;
  make_tube(8, 12, kRadius, kLength, rest, tris);
  Points x0(rest.rows() + 1, 3);
  x0 << rest, 1.0, 1.0, 1.0;  // an extra point no triangle references
  const CollisionSurface s(tris, static_cast<int>(x0.rows()));
  StepBoundOptions opt;
  opt.radius = 1e-3;  // under every non-adjacent distance of this coarse tube (edges about 5 mm)
  const Eigen::VectorXd b = vertex_step_bounds(s, x0, opt);
  EXPECT_EQ(b[rest.rows()], std::numeric_limits<double>::infinity());
  for (Eigen::Index v = 0; v < rest.rows(); ++v) ASSERT_DOUBLE_EQ(b[v], 0.5 * kStepFraction * opt.radius);

  const TruncatedStep zero = truncate_step(b, Points::Zero(x0.rows(), 3));
  EXPECT_EQ(zero.dx, Points::Zero(x0.rows(), 3));
  EXPECT_EQ(zero.kept, 1.0);
  EXPECT_EQ(zero.truncated, 0);

  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Points dx(x0.rows(), 3);
  for (int i = 0; i < dx.size(); ++i) dx.data()[i] = 0.25 * kStepFraction * opt.radius * u(rng) / std::sqrt(3.0);
  dx.row(rest.rows()) << 5.0, 0.0, 0.0;  // the free point moves far
  const TruncatedStep small = truncate_step(b, dx);
  EXPECT_EQ(small.dx, dx);
  EXPECT_EQ(small.kept, 1.0);
  EXPECT_EQ(small.truncated, 0);

  // Longer motions are cut to the bound, direction kept; the kept fraction is the sum of the lengths.
  const Points dx10 = 10.0 * dx;
  const TruncatedStep big = truncate_step(b, dx10);
  double before = 0.0, after = 0.0;
  int cut = 0;
  for (Eigen::Index v = 0; v < dx10.rows(); ++v) {
    const double len = dx10.row(v).norm();
    before += len;
    after += std::min(len, b[v]);
    if (len > b[v]) {
      ++cut;
      EXPECT_NEAR(big.dx.row(v).norm(), b[v], 1e-15);
      EXPECT_NEAR(big.dx.row(v).normalized().dot(dx10.row(v).normalized()), 1.0, 1e-12);
    } else {
      EXPECT_EQ(big.dx.row(v), dx10.row(v));
    }
  }
  EXPECT_EQ(big.truncated, cut);
  EXPECT_GT(cut, rest.rows() / 2);
  EXPECT_NEAR(big.kept, after / before, 1e-12);
}

TEST(StepBound, ValidatesInputs) {
  Points x;
  Tris tris;
  make_tube(2, 6, kRadius, kLength, x, tris);
  const CollisionSurface s(tris, static_cast<int>(x.rows()));
  const auto message = [](auto f) {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no throw");
  };
  StepBoundOptions opt;
  EXPECT_NE(message([&] { vertex_step_bounds(s, x, opt); }).find("radius"), std::string::npos);
  opt.radius = 1e-3;
  Points bad = x;
  bad(2, 1) = std::nan("");
  EXPECT_NE(message([&] { vertex_step_bounds(s, bad, opt); }).find("x0(2, 1)"), std::string::npos);
  EXPECT_NE(message([&] { vertex_step_bounds(s, x.topRows(3), opt); }).find("x0 has 3 rows"), std::string::npos);
  opt.fraction = 1.0;
  EXPECT_NE(message([&] { vertex_step_bounds_brute_force(s, x, opt); }).find("fraction"), std::string::npos);
  // Two micrometre triangles ten metres apart: a grid of more than 2^20 cells along an axis.
  opt.fraction = kStepFraction;
  opt.radius = 1e-6;
  Points tiny(6, 3);
  tiny << 0, 0, 0, 1e-6, 0, 0, 0, 1e-6, 0, 10, 0, 0, 10 + 1e-6, 0, 0, 10, 1e-6, 0;
  Tris two(2, 3);
  two << 0, 1, 2, 3, 4, 5;
  const CollisionSurface st(two, 6);
  EXPECT_NE(message([&] { vertex_step_bounds(st, tiny, opt); }).find("too small"), std::string::npos);
  const Eigen::VectorXd b = Eigen::VectorXd::Ones(x.rows());
  EXPECT_NE(message([&] { truncate_step(b, x.topRows(2)); }).find("dx has 2 rows"), std::string::npos);
  Eigen::VectorXd negative = b;
  negative[1] = -1.0;
  EXPECT_NE(message([&] { truncate_step(negative, x); }).find("bounds[1]"), std::string::npos);
}

}  // namespace
}  // namespace lumen::collision
