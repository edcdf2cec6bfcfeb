// Quadratic (10-node) tets: quadrature, shape functions, element stiffness vs finite differences and analytic
// energies, mesh construction vs brute force and geometry, patch tests on assembled hollow cylinders.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "physics/quadratic.hpp"

namespace lumen::physics {
namespace {

using Mat10x3 = Eigen::Matrix<double, 10, 3>;
double factorial(int n) { return n <= 1 ? 1.0 : n * factorial(n - 1); }

// Reference coordinates of the 10 nodes: corners, then the midpoints of kTet10Edges.
std::array<Eigen::Vector3d, 10> reference_nodes() {
  std::array<Eigen::Vector3d, 10> p;
  p[0] = Eigen::Vector3d::Zero();
  for (int a = 1; a < 4; ++a) p[a] = Eigen::Vector3d::Unit(a - 1);
  for (int e = 0; e < 6; ++e) p[4 + e] = 0.5 * (p[kTet10Edges[e][0]] + p[kTet10Edges[e][1]]);
  return p;
}

// A straight-sided tet10: the corners given, edge nodes at the midpoints.
Mat10x3 straight_tet10(const Eigen::Matrix<double, 4, 3>& corners) {
  Mat10x3 X;
  X.topRows<4>() = corners;
  for (int e = 0; e < 6; ++e) X.row(4 + e) = 0.5 * (corners.row(kTet10Edges[e][0]) + corners.row(kTet10Edges[e][1]));
  return X;
}

Eigen::Matrix<double, 4, 3> skewed_corners() {
  Eigen::Matrix<double, 4, 3> c;
  c << 0.0, 0.0, 0.0, 1.0, 0.1, 0.0, 0.2, 1.1, 0.1, 0.1, 0.2, 0.9;
  return c;
}

// A curved tet10: the skewed tet with every edge node moved off its midpoint by up to 0.08 per coordinate.
Mat10x3 curved_tet10() {
  Mat10x3 X = straight_tet10(skewed_corners());
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> d(-0.08, 0.08);
  for (int a = 4; a < 10; ++a)
    for (int c = 0; c < 3; ++c) X(a, c) += d(rng);
  return X;
}

Eigen::Matrix<double, 30, 1> flatten(const Mat10x3& u) {
  Eigen::Matrix<double, 30, 1> v;
  for (int a = 0; a < 10; ++a) v.segment<3>(3 * a) = u.row(a).transpose();
  return v;
}
Mat10x3 unflatten(const Eigen::Matrix<double, 30, 1>& v) {
  Mat10x3 u;
  for (int a = 0; a < 10; ++a) u.row(a) = v.segment<3>(3 * a).transpose();
  return u;
}

const LinearMaterial kMat{5000.0, 0.45};

// ---------------------------------------------------------------------------------------------------------------
// Quadrature and shape functions

TEST(Quadratic, TetRuleIntegratesMonomialsToDegree5) {
  // Exact: integral over the unit tet of x^i y^j z^k = i! j! k! / (i + j + k + 3)!.
  for (const auto& q : tet_quadrature()) EXPECT_GT(q.weight, 0.0);
  for (int i = 0; i <= 5; ++i)
    for (int j = 0; i + j <= 5; ++j)
      for (int k = 0; i + j + k <= 5; ++k) {
        double sum = 0.0;
        for (const auto& q : tet_quadrature())
          sum += q.weight * std::pow(q.xi[0], i) * std::pow(q.xi[1], j) * std::pow(q.xi[2], k);
        const double exact = factorial(i) * factorial(j) * factorial(k) / factorial(i + j + k + 3);
        EXPECT_NEAR(sum, exact, 1e-15) << i << " " << j << " " << k;
      }
}

TEST(Quadratic, TriangleRuleIntegratesMonomialsToDegree5) {
  // Exact: integral over the unit triangle of x^i y^j = i! j! / (i + j + 2)!.
  for (const auto& q : triangle_quadrature()) EXPECT_GT(q.weight, 0.0);
  for (int i = 0; i <= 5; ++i)
    for (int j = 0; i + j <= 5; ++j) {
      double sum = 0.0;
      for (const auto& q : triangle_quadrature()) sum += q.weight * std::pow(q.xi[0], i) * std::pow(q.xi[1], j);
      EXPECT_NEAR(sum, factorial(i) * factorial(j) / factorial(i + j + 2), 1e-15) << i << " " << j;
    }
}

TEST(Quadratic, ShapeFunctionsKroneckerAndPartitionOfUnity) {
  const auto nodes = reference_nodes();
  for (int b = 0; b < 10; ++b) {
    const Eigen::Matrix<double, 10, 1> N = tet10_shape(nodes[b]);
    for (int a = 0; a < 10; ++a) EXPECT_NEAR(N[a], a == b ? 1.0 : 0.0, 1e-15) << a << " at node " << b;
  }
  // Partition of unity, and sum of gradients zero, at random points; gradients vs central differences.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> d(0.0, 0.5);
  const double h = 1e-6;
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Vector3d xi(d(rng), d(rng), d(rng));
    EXPECT_NEAR(tet10_shape(xi).sum(), 1.0, 1e-14);
    const Mat10x3 g = tet10_shape_gradients(xi);
    EXPECT_LT(g.colwise().sum().norm(), 1e-13);
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d e = h * Eigen::Vector3d::Unit(k);
      const Eigen::Matrix<double, 10, 1> fd = (tet10_shape(xi + e) - tet10_shape(xi - e)) / (2 * h);
      EXPECT_LT((fd - g.col(k)).norm(), 1e-8);
    }
  }
}

TEST(Quadratic, Tri6ShapeFunctionsKroneckerAndGradients) {
  std::array<Eigen::Vector2d, 6> nodes = {Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 0), Eigen::Vector2d(0, 1)};
  for (int e = 0; e < 3; ++e) nodes[3 + e] = 0.5 * (nodes[kTri6Edges[e][0]] + nodes[kTri6Edges[e][1]]);
  for (int b = 0; b < 6; ++b) {
    const Eigen::Matrix<double, 6, 1> N = tri6_shape(nodes[b]);
    for (int a = 0; a < 6; ++a) EXPECT_NEAR(N[a], a == b ? 1.0 : 0.0, 1e-15) << a << " at node " << b;
  }
  const Eigen::Vector2d xi(0.21, 0.37);
  const double h = 1e-6;
  EXPECT_NEAR(tri6_shape(xi).sum(), 1.0, 1e-14);
  const Eigen::Matrix<double, 6, 2> g = tri6_shape_gradients(xi);
  for (int k = 0; k < 2; ++k) {
    const Eigen::Vector2d e = h * Eigen::Vector2d::Unit(k);
    EXPECT_LT(((tri6_shape(xi + e) - tri6_shape(xi - e)) / (2 * h) - g.col(k)).norm(), 1e-8);
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Element stiffness

void check_stiffness_against_energy(const Mat10x3& X) {
  const Eigen::Matrix<double, 30, 30> K = tet10_stiffness(X, kMat);
  const double scale = K.cwiseAbs().maxCoeff();
  EXPECT_LT((K - K.transpose()).cwiseAbs().maxCoeff(), 1e-14 * scale);

  std::mt19937 rng(11);
  std::uniform_real_distribution<double> d(-0.1, 0.1);
  Eigen::Matrix<double, 30, 1> u;
  for (int i = 0; i < 30; ++i) u[i] = d(rng);
  // Energy is 1/2 u^T K u.
  const double E = tet10_energy(X, unflatten(u), kMat);
  EXPECT_NEAR(E, 0.5 * u.dot(K * u), 1e-12 * std::abs(E));

  // Gradient dE/du = K u and Hessian d2E/du2 = K by central differences (exact for a quadratic up to round-off).
  const double h = 1e-3;
  auto energy = [&](const Eigen::Matrix<double, 30, 1>& v) { return tet10_energy(X, unflatten(v), kMat); };
  const Eigen::Matrix<double, 30, 1> Ku = K * u;
  for (int i = 0; i < 30; ++i) {
    const Eigen::Matrix<double, 30, 1> ei = h * Eigen::Matrix<double, 30, 1>::Unit(i);
    EXPECT_NEAR((energy(u + ei) - energy(u - ei)) / (2 * h), Ku[i], 1e-8 * scale) << "gradient " << i;
    for (int j = i; j < 30; ++j) {  // upper triangle (K is checked symmetric above)
      const Eigen::Matrix<double, 30, 1> ej = h * Eigen::Matrix<double, 30, 1>::Unit(j);
      const double fd =
          (energy(u + ei + ej) - energy(u + ei - ej) - energy(u - ei + ej) + energy(u - ei - ej)) / (4 * h * h);
      EXPECT_NEAR(fd, K(i, j), 1e-7 * scale) << "Hessian " << i << ", " << j;
    }
  }

  // Rigid motions give zero force: translations and infinitesimal rotations u = w x X.
  for (int c = 0; c < 3; ++c) {
    Mat10x3 t = Mat10x3::Zero();
    t.col(c).setConstant(1.0);
    EXPECT_LT((K * flatten(t)).norm(), 1e-10 * scale) << "translation " << c;
    Mat10x3 r;
    for (int a = 0; a < 10; ++a) r.row(a) = Eigen::Vector3d::Unit(c).cross(X.row(a).transpose()).transpose();
    EXPECT_LT((K * flatten(r)).norm(), 1e-10 * scale) << "rotation " << c;
  }
  // Exactly six zero eigenvalues (rigid motions), the other 24 positive: no spurious zero-energy modes.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 30, 30>> es(K);
  const auto& ev = es.eigenvalues();  // ascending
  for (int i = 0; i < 6; ++i) EXPECT_LT(std::abs(ev[i]), 1e-10 * ev[29]);
  EXPECT_GT(ev[6], 1e-6 * ev[29]);
}

TEST(Quadratic, StiffnessMatchesEnergyStraight) { check_stiffness_against_energy(straight_tet10(skewed_corners())); }
TEST(Quadratic, StiffnessMatchesEnergyCurved) { check_stiffness_against_energy(curved_tet10()); }

TEST(Quadratic, LinearFieldEnergyIsAnalytic) {
  // u = H X + c on a straight tet10: energy = V (mu eps:eps + lambda/2 tr(eps)^2), eps = sym(H).
  const Eigen::Matrix<double, 4, 3> C = skewed_corners();
  const Mat10x3 X = straight_tet10(C);
  Eigen::Matrix3d H;
  H << 0.01, -0.02, 0.005, 0.03, -0.015, 0.01, -0.004, 0.02, 0.025;
  const Eigen::Vector3d c(0.3, -0.2, 0.1);
  Mat10x3 u;
  for (int a = 0; a < 10; ++a) u.row(a) = (H * X.row(a).transpose() + c).transpose();
  Eigen::Matrix3d Dm;
  for (int a = 0; a < 3; ++a) Dm.col(a) = (C.row(a + 1) - C.row(0)).transpose();
  const double V = Dm.determinant() / 6.0;
  const double E = kMat.young_modulus, nu = kMat.poisson_ratio;
  const double lambda = E * nu / ((1 + nu) * (1 - 2 * nu)), mu = E / (2 * (1 + nu));
  const Eigen::Matrix3d eps = 0.5 * (H + H.transpose());
  const double exact = V * (mu * eps.squaredNorm() + 0.5 * lambda * eps.trace() * eps.trace());
  EXPECT_NEAR(tet10_energy(X, u, kMat), exact, 1e-13 * exact);
  EXPECT_NEAR(tet10_volume(X), V, 1e-15);
  // The straight tet10 and the linear tet agree on linear fields.
  Eigen::Matrix<double, 4, 3> u4 = u.topRows<4>();
  EXPECT_NEAR(tet_energy(C, u4, kMat), exact, 1e-13 * exact);
}

TEST(Quadratic, RejectsNonPositiveJacobian) {
  // An edge node dragged past the opposite face folds the element.
  Mat10x3 X = straight_tet10(skewed_corners());
  X.row(4) += Eigen::RowVector3d(0.0, 2.0, 2.0);
  EXPECT_THROW(tet10_stiffness(X, kMat), std::invalid_argument);
  EXPECT_THROW(tet10_volume(X), std::invalid_argument);
  // In an assembled mesh the message names the element.
  TetMesh lin = make_hollow_cylinder({0.01, 0.013, 0.01, 4, 1, 1, 0.0, {}, {}});
  QuadraticMesh q = make_quadratic(lin);
  q.rest.row(q.tets(5, 4)) += Eigen::RowVector3d(0.05, 0.05, 0.05);
  try {
    assemble_stiffness(q, kMat);
    ADD_FAILURE() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("tet10 element"), std::string::npos) << e.what();
  }
  EXPECT_THROW(tet10_stiffness(straight_tet10(skewed_corners()), {5000.0, 0.5}), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------------------------
// Pressure load on a 6-node face

TEST(Quadratic, PressureLoadFlatTriangle) {
  // Flat straight 6-node triangle: corners carry nothing, each edge node p A / 3, along -n.
  Eigen::Matrix<double, 6, 3> X;
  X.topRows<3>() << 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.5, 1.5, 0.0;
  for (int e = 0; e < 3; ++e) X.row(3 + e) = 0.5 * (X.row(kTri6Edges[e][0]) + X.row(kTri6Edges[e][1]));
  const double p = 7.0, area = 0.5 * 2.0 * 1.5;
  const Eigen::Matrix<double, 6, 3> f = tri6_pressure_load(X, p);
  for (int a = 0; a < 3; ++a) EXPECT_LT(f.row(a).norm(), 1e-14);
  for (int a = 3; a < 6; ++a) EXPECT_LT((f.row(a) - Eigen::RowVector3d(0, 0, -p * area / 3.0)).norm(), 1e-13);
}

TEST(Quadratic, PressureLoadCurvedTriangleTotal) {
  // Total force -p * integral n dA = -p/2 * loop integral of x cross dx over the three quadratic edges
  // (Stokes), each edge by 2-point Gauss-Legendre (exact: the integrand is cubic).
  Eigen::Matrix<double, 6, 3> X;
  X << 0.0, 0.0, 0.0, 1.0, 0.0, 0.2, 0.0, 1.0, -0.1, 0.5, 0.1, 0.3, 0.6, 0.5, 0.1, -0.1, 0.4, 0.2;
  const double p = 3.0;
  const Eigen::Vector3d total = tri6_pressure_load(X, p).colwise().sum().transpose();
  Eigen::Vector3d loop = Eigen::Vector3d::Zero();
  const double g = 0.5 / std::sqrt(3.0);
  for (int e = 0; e < 3; ++e) {
    // Edge from corner a to corner b through edge node m: x(t) = quadratic Lagrange in t in [0, 1].
    const Eigen::Vector3d xa = X.row(kTri6Edges[e][0]).transpose(), xb = X.row(kTri6Edges[e][1]).transpose();
    const Eigen::Vector3d xm = X.row(3 + e).transpose();
    for (double t : {0.5 - g, 0.5 + g}) {
      const Eigen::Vector3d x = (1 - t) * (1 - 2 * t) * xa + 4 * t * (1 - t) * xm + t * (2 * t - 1) * xb;
      const Eigen::Vector3d dx = (4 * t - 3) * xa + (4 - 8 * t) * xm + (4 * t - 1) * xb;
      loop += 0.5 * x.cross(dx);
    }
  }
  EXPECT_LT((total - (-p * 0.5 * loop)).norm(), 1e-14);
}

// ---------------------------------------------------------------------------------------------------------------
// Mesh construction

TEST(Quadratic, MakeQuadraticMatchesBruteForceEdges) {
  const HollowCylinderSpec spec{0.01, 0.013, 0.02, 6, 3, 2, 0.0, {}, {}};
  const TetMesh lin = make_hollow_cylinder(spec);
  const QuadraticMesh q = make_quadratic(lin);
  // Brute-force edge and face sets.
  std::set<std::pair<int, int>> edges;
  std::set<std::array<int, 3>> faces;
  for (int t = 0; t < lin.tets.rows(); ++t)
    for (int a = 0; a < 4; ++a) {
      for (int b = a + 1; b < 4; ++b)
        edges.insert({std::min(lin.tets(t, a), lin.tets(t, b)), std::max(lin.tets(t, a), lin.tets(t, b))});
      std::array<int, 3> f;
      for (int c = 0, k = 0; c < 4; ++c)
        if (c != a) f[k++] = lin.tets(t, c);
      std::sort(f.begin(), f.end());
      faces.insert(f);
    }
  ASSERT_EQ(q.n_corners, lin.n_nodes());
  ASSERT_EQ(q.edges.rows(), static_cast<long>(edges.size()));
  EXPECT_EQ(q.n_nodes(), lin.n_nodes() + static_cast<int>(edges.size()));
  // Euler characteristic of a tube (annulus x interval, homotopic to a circle): V - E + F - T = 0.
  EXPECT_EQ(lin.n_nodes() - static_cast<long>(edges.size()) + static_cast<long>(faces.size()) - lin.tets.rows(), 0);
  // Kuhn split of a periodic (around) grid: 7 edge directions; count per direction.
  const int na = spec.segments_around, nl = spec.segments_along, nr = spec.layers;
  const long kuhn = static_cast<long>(na) * ((nl + 1) * (nr + 1) + 2 * nl * (nr + 1) + 2 * (nl + 1) * nr + 2 * nl * nr);
  EXPECT_EQ(q.edges.rows(), kuhn);
  // Every edge listed once, sorted corners, at its midpoint.
  std::set<std::pair<int, int>> listed;
  for (int e = 0; e < q.edges.rows(); ++e) {
    EXPECT_LT(q.edges(e, 0), q.edges(e, 1));
    listed.insert({q.edges(e, 0), q.edges(e, 1)});
    const Eigen::RowVector3d mid = 0.5 * (lin.rest.row(q.edges(e, 0)) + lin.rest.row(q.edges(e, 1)));
    EXPECT_TRUE(q.rest.row(q.n_corners + e) == mid) << "edge " << e;
  }
  EXPECT_EQ(listed, edges);
  // Each tet: corners unchanged, edge node k joins the corners of kTet10Edges[k].
  for (int t = 0; t < q.tets.rows(); ++t)
    for (int k = 0; k < 6; ++k) {
      for (int a = 0; a < 4; ++a) ASSERT_EQ(q.tets(t, a), lin.tets(t, a));
      const int e = q.tets(t, 4 + k) - q.n_corners;
      const int a = lin.tets(t, kTet10Edges[k][0]), b = lin.tets(t, kTet10Edges[k][1]);
      ASSERT_EQ(q.edges(e, 0), std::min(a, b));
      ASSERT_EQ(q.edges(e, 1), std::max(a, b));
    }
  // Surfaces: edge nodes of each 6-node triangle join its corners.
  for (const Tris6* s : {&q.surface(kInnerWall), &q.surface(kOuterWall), &q.surface(kEndCaps)})
    for (int f = 0; f < s->rows(); ++f)
      for (int k = 0; k < 3; ++k) {
        const int e = (*s)(f, 3 + k) - q.n_corners;
        const int a = (*s)(f, kTri6Edges[k][0]), b = (*s)(f, kTri6Edges[k][1]);
        ASSERT_EQ(std::make_pair(q.edges(e, 0), q.edges(e, 1)), std::make_pair(std::min(a, b), std::max(a, b)));
      }
  // End nodes: exactly the nodes (corner and edge) in the planes z = 0 and z = length.
  std::set<int> start(q.node_set(kStartEnd).begin(), q.node_set(kStartEnd).end());
  std::set<int> stop(q.node_set(kStopEnd).begin(), q.node_set(kStopEnd).end());
  EXPECT_EQ(start.size(), q.node_set(kStartEnd).size());
  std::set<int> z0, zl;
  for (int v = 0; v < q.n_nodes(); ++v) {
    if (std::abs(q.rest(v, 2)) < 1e-12) z0.insert(v);
    if (std::abs(q.rest(v, 2) - spec.length) < 1e-12) zl.insert(v);
  }
  EXPECT_EQ(start, z0);
  EXPECT_EQ(stop, zl);
}

// Local radius of a point of the hollow cylinder of `spec` (distance from the centreline).
double local_radius(const HollowCylinderSpec& spec, const Eigen::Vector3d& p) {
  if (spec.bend_radius == 0.0) return std::hypot(p.x(), p.y());
  const double R = spec.bend_radius;
  return std::hypot(R - std::hypot(p.x() - R, p.z()), p.y());
}

void check_isoparametric(const HollowCylinderSpec& spec) {
  const TetMesh lin = make_hollow_cylinder(spec);
  const QuadraticMesh q = make_quadratic_cylinder(lin, spec);
  ASSERT_TRUE(q.rest.topRows(q.n_corners) == lin.rest);
  // The generator's map reproduces its own nodes.
  for (int v = 0; v < lin.n_nodes(); ++v) {
    const int na = spec.segments_around, nr = spec.layers;
    const int i = v % na, k = (v / na) % (nr + 1), j = v / (na * (nr + 1));
    const Eigen::Vector3d p = hollow_cylinder_point(
        spec, spec.length * j / spec.segments_along,
        spec.inner_radius + (spec.outer_radius - spec.inner_radius) * k / nr, 2 * EIGEN_PI * i / na);
    EXPECT_LT((p - lin.rest.row(v).transpose()).norm(), 1e-15);
  }
  // Edge nodes: local radius = mean of the corners' (so exactly a on the inner wall and b on the outer), and
  // for an edge at one radius of a straight tube, equally far from both corners (a half-turn about the midpoint's
  // radial line swaps them).
  int on_inner = 0, on_outer = 0;
  const double a = spec.inner_radius, b = spec.outer_radius;
  for (int e = 0; e < q.edges.rows(); ++e) {
    const Eigen::Vector3d p = q.rest.row(q.n_corners + e).transpose();
    const Eigen::Vector3d x0 = lin.rest.row(q.edges(e, 0)).transpose(), x1 = lin.rest.row(q.edges(e, 1)).transpose();
    const double r0 = local_radius(spec, x0), r1 = local_radius(spec, x1), r = local_radius(spec, p);
    EXPECT_NEAR(r, 0.5 * (r0 + r1), 1e-15);
    if (std::abs(r0 - a) < 1e-15 && std::abs(r1 - a) < 1e-15) {
      ++on_inner;
      EXPECT_NEAR(r, a, 1e-15);
    }
    if (std::abs(r0 - b) < 1e-15 && std::abs(r1 - b) < 1e-15) {
      ++on_outer;
      EXPECT_NEAR(r, b, 1e-15);
    }
    if (spec.bend_radius == 0.0 && std::abs(r0 - r1) < 1e-15) {
      EXPECT_NEAR((p - x0).norm(), (p - x1).norm(), 1e-15);
    }
  }
  // Inner/outer wall edges: around (along + 1) rings, around x along axial, around x along diagonal.
  EXPECT_EQ(on_inner, spec.segments_around * (3 * spec.segments_along + 1));
  EXPECT_EQ(on_outer, on_inner);
  // Every inner-wall 6-node triangle has all its nodes at radius a.
  for (int f = 0; f < q.surface(kInnerWall).rows(); ++f)
    for (int c = 0; c < 6; ++c) EXPECT_NEAR(local_radius(spec, q.rest.row(q.surface(kInnerWall)(f, c)).transpose()), a, 1e-15);
}

TEST(Quadratic, IsoparametricNodesOnTheWallsStraight) { check_isoparametric({0.01, 0.013, 0.02, 8, 2, 2, 0.0, {}, {}}); }
TEST(Quadratic, IsoparametricNodesOnTheWallsBent) { check_isoparametric({0.01, 0.013, 0.05, 8, 4, 2, 0.04, {}, {}}); }

TEST(Quadratic, IsoparametricVolumeConvergesAtFourthOrder) {
  // Exact volume pi (b^2 - a^2) L, also for the bent tube (Pappus: the annulus centroid is on the centreline).
  // The chordal (linear) mesh misses O(h^2) of it, the isoparametric one O(h^4). Around and along are both
  // refined (the bent tube's walls curve along it too).
  for (double bend : {0.0, 0.04}) {
    double prev_quad = 0.0;
    for (int na : {8, 16}) {
      const HollowCylinderSpec spec{0.01, 0.013, 0.02, na, na / 4, 1, bend, {}, {}};
      const TetMesh lin = make_hollow_cylinder(spec);
      const QuadraticMesh q = make_quadratic_cylinder(lin, spec);
      const double exact = EIGEN_PI * (0.013 * 0.013 - 0.01 * 0.01) * 0.02;
      double v_lin = 0.0, v_quad = 0.0;
      for (int t = 0; t < lin.tets.rows(); ++t) v_lin += tet_volume(lin.rest, lin.tets, t);
      for (int t = 0; t < q.tets.rows(); ++t) {
        Mat10x3 X;
        for (int c = 0; c < 10; ++c) X.row(c) = q.rest.row(q.tets(t, c));
        v_quad += tet10_volume(X);
      }
      const double e_lin = std::abs(v_lin - exact) / exact, e_quad = std::abs(v_quad - exact) / exact;
      std::printf("volume bend %.2f around %2d along %d: rel error linear %.3e, quadratic %.3e\n", bend, na, na / 4,
                  e_lin, e_quad);
      EXPECT_LT(e_quad, 0.05 * e_lin);
      if (prev_quad > 0.0) {
        EXPECT_GT(std::log2(prev_quad / e_quad), 3.5);
      }
      prev_quad = e_quad;
    }
  }
}

TEST(Quadratic, CylinderRejectsForeignMesh) {
  HollowCylinderSpec spec;
  spec.inner_radius = 0.01, spec.outer_radius = 0.013, spec.length = 0.02;
  spec.segments_around = 8, spec.segments_along = 2, spec.layers = 2;
  HollowCylinderSpec other = spec;
  other.layers = 3;
  EXPECT_THROW(make_quadratic_cylinder(make_hollow_cylinder(other), spec), std::invalid_argument);
  other = spec;
  other.bend_radius = 0.05;
  EXPECT_THROW(make_quadratic_cylinder(make_hollow_cylinder(other), spec), std::invalid_argument);
  TetMesh broken = make_hollow_cylinder(spec);
  broken.tets(0, 1) = broken.n_nodes();
  EXPECT_THROW(make_quadratic(broken), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------------------------
// Patch tests on assembled meshes

// Boundary nodes (every node of a surface 6-node triangle).
std::vector<char> boundary_mask(const QuadraticMesh& q) {
  std::vector<char> on(q.n_nodes(), 0);
  for (const Tris6* s : {&q.surface(kInnerWall), &q.surface(kOuterWall), &q.surface(kEndCaps)})
    for (int f = 0; f < s->rows(); ++f)
      for (int c = 0; c < 6; ++c) on[(*s)(f, c)] = 1;
  return on;
}

// Solves K u = f with u prescribed (= u_b) on boundary nodes, via StaticSolver (fixed DOFs return 0):
// u = u_b + K_ff^-1 (f - K u_b)_f.
Eigen::VectorXd solve_with_boundary(const Eigen::SparseMatrix<double>& K, const std::vector<char>& on,
                                    const Eigen::VectorXd& u_b, const Eigen::VectorXd& f) {
  std::vector<int> fixed;
  for (int v = 0; v < static_cast<int>(on.size()); ++v)
    if (on[v]) fixed.push_back(v);
  const StaticSolver solver(K, fixed);
  Eigen::VectorXd du;
  solver.solve(f - K * u_b, du);
  return u_b + du;
}

TEST(Quadratic, PatchTestLinearFieldOnCurvedMesh) {
  // Isoparametric elements contain every linear field: prescribed on the boundary, the interior reproduces it.
  for (double bend : {0.0, 0.04}) {
    const HollowCylinderSpec spec{0.01, 0.013, 0.02, 8, 2, 2, bend, {}, {}};
    const QuadraticMesh q = make_quadratic_cylinder(make_hollow_cylinder(spec), spec);
    const Eigen::SparseMatrix<double> K = assemble_stiffness(q, kMat);
    Eigen::Matrix3d A;
    A << 0.01, -0.02, 0.005, 0.03, -0.015, 0.01, -0.004, 0.02, 0.025;
    const Eigen::Vector3d c(1e-4, -2e-4, 3e-4);
    const int n = q.n_nodes();
    Eigen::VectorXd exact(3 * n), u_b = Eigen::VectorXd::Zero(3 * n);
    const std::vector<char> on = boundary_mask(q);
    int interior = 0;
    for (int v = 0; v < n; ++v) {
      exact.segment<3>(3 * v) = A * q.rest.row(v).transpose() + c;
      if (on[v]) {
        u_b.segment<3>(3 * v) = exact.segment<3>(3 * v);
      } else {
        ++interior;
      }
    }
    ASSERT_GT(interior, 0);
    // Zero residual at interior nodes for the exact field, and the solve reproduces it.
    const Eigen::VectorXd r = K * exact;
    double r_int = 0.0, f_scale = 0.0;
    for (int v = 0; v < n; ++v) {
      f_scale = std::max(f_scale, r.segment<3>(3 * v).norm());
      if (!on[v]) r_int = std::max(r_int, r.segment<3>(3 * v).norm());
    }
    EXPECT_LT(r_int, 1e-10 * f_scale);
    const Eigen::VectorXd u = solve_with_boundary(K, on, u_b, Eigen::VectorXd::Zero(3 * n));
    EXPECT_LT((u - exact).cwiseAbs().maxCoeff(), 1e-10 * exact.cwiseAbs().maxCoeff()) << "bend " << bend;
  }
}

TEST(Quadratic, PatchTestQuadraticFieldOnStraightMesh) {
  // Straight-sided tet10 contain every quadratic field. u_i = sum_jk Q_ijk x_j x_k has constant stress
  // divergence; with the matching body force b = -div sigma as consistent load and u prescribed on the boundary,
  // the interior reproduces u exactly.
  HollowCylinderSpec spec;
  spec.inner_radius = 0.01, spec.outer_radius = 0.013, spec.length = 0.02;
  spec.segments_around = 8, spec.segments_along = 2, spec.layers = 2;
  const QuadraticMesh q = make_quadratic(make_hollow_cylinder(spec));
  const Eigen::SparseMatrix<double> K = assemble_stiffness(q, kMat);
  double Q[3][3][3];
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> d(-1.0, 1.0);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = j; k < 3; ++k) Q[i][j][k] = Q[i][k][j] = d(rng);
  auto field = [&](const Eigen::Vector3d& x) {
    Eigen::Vector3d u = Eigen::Vector3d::Zero();
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        for (int k = 0; k < 3; ++k) u[i] += Q[i][j][k] * x[j] * x[k];
    return u;
  };
  // div sigma_i = lambda d_i tr(eps) + mu sum_j (d_j H_ij + d_j H_ji), with d_l H_ij = 2 Q_ijl.
  const double E = kMat.young_modulus, nu = kMat.poisson_ratio;
  const double lambda = E * nu / ((1 + nu) * (1 - 2 * nu)), mu = E / (2 * (1 + nu));
  Eigen::Vector3d body;
  for (int i = 0; i < 3; ++i) {
    double div = 0.0;
    for (int m = 0; m < 3; ++m) div += lambda * 2 * Q[m][m][i] + mu * (2 * Q[i][m][m] + 2 * Q[m][i][m]);
    body[i] = -div;  // N/m^3
  }
  // Consistent load f_a = integral N_a b dV per straight element (det J = 6 V, constant).
  const int n = q.n_nodes();
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * n);
  for (int t = 0; t < q.tets.rows(); ++t) {
    Eigen::Matrix3d Dm;
    for (int a = 0; a < 3; ++a) Dm.col(a) = (q.rest.row(q.tets(t, a + 1)) - q.rest.row(q.tets(t, 0))).transpose();
    const double det = Dm.determinant();
    for (const auto& qp : tet_quadrature()) {
      const Eigen::Matrix<double, 10, 1> N = tet10_shape(qp.xi);
      for (int a = 0; a < 10; ++a) f.segment<3>(3 * q.tets(t, a)) += qp.weight * det * N[a] * body;
    }
  }
  const std::vector<char> on = boundary_mask(q);
  Eigen::VectorXd exact(3 * n), u_b = Eigen::VectorXd::Zero(3 * n);
  for (int v = 0; v < n; ++v) {
    exact.segment<3>(3 * v) = field(q.rest.row(v).transpose());
    if (on[v]) u_b.segment<3>(3 * v) = exact.segment<3>(3 * v);
  }
  const Eigen::VectorXd u = solve_with_boundary(K, on, u_b, f);
  EXPECT_LT((u - exact).cwiseAbs().maxCoeff(), 1e-9 * exact.cwiseAbs().maxCoeff());
  // Without the body force the interior must differ (the check above is not vacuous).
  const Eigen::VectorXd u0 = solve_with_boundary(K, on, u_b, Eigen::VectorXd::Zero(3 * n));
  EXPECT_GT((u0 - exact).cwiseAbs().maxCoeff(), 1e-4 * exact.cwiseAbs().maxCoeff());
}

// ---------------------------------------------------------------------------------------------------------------
// The paper mesh in tet10 form: counts, and a printout of the factorisation and solve times.

// Counts in every build; the timed assembly, factorisation and solve (about 13 s) only in optimised builds.
TEST(Quadratic, PaperMeshSizesAndTimings) {
  const HollowCylinderSpec spec;  // 0.01 / 0.013 m, 0.1 m, 20 around, 26 along, 3 layers
  const TetMesh lin = make_hollow_cylinder(spec);
  const QuadraticMesh q = make_quadratic_cylinder(lin, spec);
  const int na = spec.segments_around, nl = spec.segments_along, nr = spec.layers;
  const int kuhn = na * ((nl + 1) * (nr + 1) + 2 * nl * (nr + 1) + 2 * (nl + 1) * nr + 2 * nl * nr);
  EXPECT_EQ(q.edges.rows(), kuhn);
  EXPECT_EQ(q.n_nodes(), lin.n_nodes() + kuhn);
  EXPECT_EQ(q.tets.rows(), lin.tets.rows());
#ifndef NDEBUG
  GTEST_SKIP() << "timed factorisation of the paper mesh runs in optimised builds only";
#endif
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  const Eigen::SparseMatrix<double> K = assemble_stiffness(q, kMat);
  const auto t1 = Clock::now();
  std::vector<int> fixed = q.node_set(kStartEnd);
  fixed.insert(fixed.end(), q.node_set(kStopEnd).begin(), q.node_set(kStopEnd).end());
  const StaticSolver solver(K, fixed);
  const auto t2 = Clock::now();
  // Unit pressure on the inner wall, one solve.
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * q.n_nodes());
  for (int t = 0; t < q.surface(kInnerWall).rows(); ++t) {
    Eigen::Matrix<double, 6, 3> X6;
    for (int c = 0; c < 6; ++c) X6.row(c) = q.rest.row(q.surface(kInnerWall)(t, c));
    const Eigen::Matrix<double, 6, 3> f6 = tri6_pressure_load(X6, 1.0);
    for (int c = 0; c < 6; ++c) f.segment<3>(3 * q.surface(kInnerWall)(t, c)) += f6.row(c).transpose();
  }
  Eigen::VectorXd u;
  const auto t3 = Clock::now();
  solver.solve(f, u);
  const auto t4 = Clock::now();
  auto ms = [](Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); };
  std::printf("paper mesh tet10: %d nodes (%d corners), %ld tets, %d DOFs (%d free), factor nnz %ld\n", q.n_nodes(),
              q.n_corners, static_cast<long>(q.tets.rows()), 3 * q.n_nodes(), solver.n_free_dofs(),
              solver.factor_nonzeros());
  std::printf("  assembly %.1f ms, CHOLMOD analyse+factorise %.1f ms, one solve %.2f ms\n", ms(t1 - t0), ms(t2 - t1),
              ms(t4 - t3));
  // The solve is a solve: residual on the free DOFs.
  Eigen::VectorXd r = K * u - f;
  for (int d = 0; d < r.size(); ++d)
    if (solver.is_fixed_dof(d)) r[d] = 0.0;
  EXPECT_LT(r.norm(), 1e-8 * f.norm());
}

// The split inner wall of an isoparametric cylinder is the polygonal tube through its nodes: 2 x around sides
// inscribed in the inner radius, so its area is exactly length x 2N a sin(pi / N), N = 2 around; every split
// triangle faces the axis and every edge is shared by two triangles or lies on an end ring.
TEST(Quadratic, LinearViewSplitsTheWallsIntoTheInscribedPolygonTube) {
  HollowCylinderSpec spec{0.01, 0.013, 0.03, 8, 3, 2, 0.0, {}, {}};
  const TetMesh lin = make_hollow_cylinder(spec);
  const QuadraticMesh q = make_quadratic_cylinder(lin, spec);
  const TetMesh v = linear_view(q);
  const Tris& inner = v.surface(kInnerWall);
  ASSERT_EQ(inner.rows(), 4 * lin.surface(kInnerWall).rows());
  ASSERT_EQ(v.surface(kOuterWall).rows(), 4 * lin.surface(kOuterWall).rows());
  ASSERT_EQ(v.n_nodes(), q.n_nodes());
  const int n_sides = 2 * spec.segments_around;
  double area = 0.0;
  std::map<std::pair<int, int>, int> edge_count;
  for (int t = 0; t < inner.rows(); ++t) {
    const Eigen::Vector3d a = v.rest.row(inner(t, 0)), b = v.rest.row(inner(t, 1)), c = v.rest.row(inner(t, 2));
    const Eigen::Vector3d n = (b - a).cross(c - a);
    area += 0.5 * n.norm();
    // Facing the axis: the normal points from the centroid toward the axis.
    const Eigen::Vector3d g = (a + b + c) / 3.0;
    EXPECT_LT(n.x() * g.x() + n.y() * g.y(), 0.0) << "triangle " << t;
    for (int k = 0; k < 3; ++k) {
      const int p = inner(t, k), r = inner(t, (k + 1) % 3);
      ++edge_count[{std::min(p, r), std::max(p, r)}];
    }
  }
  EXPECT_NEAR(area, spec.length * 2.0 * n_sides * spec.inner_radius * std::sin(EIGEN_PI / n_sides), 1e-12);
  for (const auto& [e, count] : edge_count) {
    const bool on_end = std::abs(v.rest(e.first, 2) - v.rest(e.second, 2)) < 1e-12 &&
                        (std::abs(v.rest(e.first, 2)) < 1e-12 || std::abs(v.rest(e.first, 2) - spec.length) < 1e-12);
    EXPECT_EQ(count, on_end ? 1 : 2) << "edge " << e.first << "-" << e.second;
  }
}

// The linear view is a real tet mesh on the quadratic mesh's nodes: on straight-sided elements the 8 sub-tets of
// each element have positive volumes summing to the element's (a partition); every node belongs to a sub-tet;
// and the faces that only one sub-tet has (the view's own boundary, found by brute force) are exactly its split
// surfaces, with the same orientation (out of the volume).
TEST(Quadratic, LinearViewIsATetMeshWhoseBoundaryIsItsSurfaces) {
  const HollowCylinderSpec spec{0.01, 0.013, 0.03, 6, 3, 2, 0.0, {}, {}};
  const TetMesh lin = make_hollow_cylinder(spec);
  const QuadraticMesh q = make_quadratic(lin);  // straight-sided
  const TetMesh v = linear_view(q);
  ASSERT_EQ(v.tets.rows(), 8 * lin.tets.rows());
  // Partition of each element.
  for (int t = 0; t < lin.tets.rows(); ++t) {
    double sum = 0.0;
    for (int s = 0; s < 8; ++s) {
      const double vol = tet_volume(v.rest, v.tets, 8 * t + s);
      EXPECT_GT(vol, 0.0) << "tet " << t << " sub-tet " << s;
      sum += vol;
    }
    EXPECT_NEAR(sum, tet_volume(lin.rest, lin.tets, t), 1e-12 * tet_volume(lin.rest, lin.tets, t)) << "tet " << t;
  }
  // Every node in a sub-tet.
  std::vector<char> used(v.n_nodes(), 0);
  for (int i = 0; i < v.tets.size(); ++i) used[v.tets.data()[i]] = 1;
  EXPECT_EQ(std::count(used.begin(), used.end(), 1), v.n_nodes());
  // Boundary faces of the sub-tets, oriented out of each (faces (1,2,3), (0,3,2), (0,1,3), (0,2,1)).
  static constexpr int kFaces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  std::map<std::array<int, 3>, std::array<int, 3>> faces;  // sorted ids -> oriented ids
  std::map<std::array<int, 3>, int> count;
  for (int t = 0; t < v.tets.rows(); ++t)
    for (const auto& f : kFaces) {
      std::array<int, 3> ids = {v.tets(t, f[0]), v.tets(t, f[1]), v.tets(t, f[2])}, key = ids;
      std::sort(key.begin(), key.end());
      faces[key] = ids;
      ++count[key];
    }
  // The split surfaces, as the same sorted keys with their cyclic orientation.
  auto cyclic_equal = [](const std::array<int, 3>& a, const std::array<int, 3>& b) {
    for (int r = 0; r < 3; ++r)
      if (a[0] == b[r] && a[1] == b[(r + 1) % 3] && a[2] == b[(r + 2) % 3]) return true;
    return false;
  };
  int surface_faces = 0;
  for (const MeshSurface& s : v.surfaces)
    for (int t = 0; t < s.tris.rows(); ++t) {
      std::array<int, 3> ids = {s.tris(t, 0), s.tris(t, 1), s.tris(t, 2)}, key = ids;
      std::sort(key.begin(), key.end());
      ASSERT_EQ(count[key], 1) << s.name << " triangle " << t << " is not a boundary face";
      EXPECT_TRUE(cyclic_equal(faces[key], ids)) << s.name << " triangle " << t << " faces into the volume";
      ++surface_faces;
    }
  int boundary = 0;
  for (const auto& [key, c] : count) boundary += c == 1;
  EXPECT_EQ(boundary, surface_faces);
  // Node sets carried over by name.
  EXPECT_EQ(v.node_set(kStartEnd), q.node_set(kStartEnd));
  EXPECT_EQ(v.node_set(kStopEnd), q.node_set(kStopEnd));
}

// Named lookups refuse a missing name and say what the mesh has.
TEST(Quadratic, MissingSurfaceNameIsRefusedWithTheNamesThereAre) {
  const TetMesh lin = make_hollow_cylinder(HollowCylinderSpec{0.01, 0.013, 0.03, 6, 3, 1, 0.0, {}, {}});
  try {
    lin.surface("lumen");
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "TetMesh has no surface \"lumen\" (it has: inner, outer, ends)");
  }
  EXPECT_THROW(make_quadratic(lin).node_set("middle"), std::invalid_argument);
}

}  // namespace
}  // namespace lumen::physics
