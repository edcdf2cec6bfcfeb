// FEM vs the Lame thick-walled cylinder (plane strain, internal pressure): convergence under refinement.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

#include "physics/lame.hpp"

namespace lumen::physics {
namespace {

// Refinement levels (around x layers, both doubled per level); the finest level only in optimised builds.
std::vector<std::pair<int, int>> levels() {
#ifdef NDEBUG
  return {{20, 3}, {40, 6}, {80, 12}, {160, 24}};
#else
  return {{20, 3}, {40, 6}, {80, 12}};
#endif
}

void check_convergence(double nu) {
  std::vector<double> err;
  for (const auto& [around, layers] : levels()) {
    const LameResult r = lame_error(around, 1, layers, 5000.0, nu, 100.0);
    std::printf("Lame nu %.2f  %3d x %2d  (%5d nodes)  rel L2 u_r error %.5f  max %.5f  |u_theta| %.2e\n", nu, around,
                layers, r.n_nodes, r.rel_l2_error, r.max_rel_error, r.max_tangential);
    if (!err.empty()) {
      EXPECT_LT(r.rel_l2_error, err.back()) << "error must decrease under refinement";
      const double order = std::log2(err.back() / r.rel_l2_error);
      std::printf("  observed order %.3f\n", order);
      // Linear tets: nodal displacement error O(h^2); accept a clearly positive, sub-cubic order.
      EXPECT_GT(order, 1.0);
      EXPECT_LT(order, 3.0);
    }
    err.push_back(r.rel_l2_error);
  }
  // The finest level is close to the exact solution, not merely converging.
  EXPECT_LT(err.back(), 0.01);
}

TEST(Lame, ConvergesAtNu045) { check_convergence(0.45); }
TEST(Lame, ConvergesAtNu030) { check_convergence(0.30); }

// Plane strain holds along the section too: with several cells along, interior nodes are free in z but stay
// (nearly) in plane, and the error matches the single-cell section.
TEST(Lame, SeveralCellsAlongStayInPlane) {
  const LameResult one = lame_error(40, 1, 6, 5000.0, 0.45, 100.0);
  const LameResult three = lame_error(40, 3, 6, 5000.0, 0.45, 100.0);
  EXPECT_EQ(one.max_axial, 0.0);
  EXPECT_LT(three.max_axial, 0.01);
  EXPECT_NEAR(three.rel_l2_error, one.rel_l2_error, 0.5 * one.rel_l2_error);
}

TEST(Lame, ExactSolutionSatisfiesTheBoundaryTractions) {
  // sigma_r(a) = -p and sigma_r(b) = 0 in plane strain, from u_r by central differences.
  const LinearMaterial m{5000.0, 0.45};
  const double a = 0.01, b = 0.013, p = 100.0, h = 1e-7;
  const double E = m.young_modulus, nu = m.poisson_ratio;
  auto sigma_r = [&](double r) {
    const double ur = lame_radial_displacement(r, a, b, m, p);
    const double dur =
        (lame_radial_displacement(r + h, a, b, m, p) - lame_radial_displacement(r - h, a, b, m, p)) / (2 * h);
    return E / ((1 + nu) * (1 - 2 * nu)) * ((1 - nu) * dur + nu * ur / r);
  };
  EXPECT_NEAR(sigma_r(a), -p, 1e-4 * p);
  EXPECT_NEAR(sigma_r(b), 0.0, 1e-4 * p);
}

TEST(Lame, RejectsBadSetup) {
  EXPECT_THROW(lame_error(18, 1, 3, 5000.0, 0.45, 100.0), std::invalid_argument);  // not a multiple of 4
  EXPECT_THROW(lame_error(20, 1, 3, 5000.0, 0.5, 100.0), std::invalid_argument);
  EXPECT_THROW(lame_error(20, 1, 3, 5000.0, 0.45, 0.0), std::invalid_argument);
  EXPECT_THROW(lame_error(20, 0, 3, 5000.0, 0.45, 100.0), std::invalid_argument);
}

}  // namespace
}  // namespace lumen::physics
