// LoadResponse against direct solves.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>
#include <vector>

#include "physics/load_response.hpp"
#include "compliance_model.hpp"

namespace lumen::physics {
namespace {

TEST(LoadResponse, EqualsDirectSolve) {
  const Model& m = model();
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> tri(0, static_cast<int>(m.mesh.surface(kInnerWall).rows()) - 1);
  std::uniform_real_distribution<double> u01(0.0, 1.0), force(-0.05, 0.05);
  std::vector<LoadPoint> points(3);
  for (LoadPoint& p : points) {
    const int t = tri(rng);
    double b0 = u01(rng), b1 = u01(rng) * (1 - b0);
    const double b[3] = {b0, b1, 1 - b0 - b1};
    for (int k = 0; k < 3; ++k) p.node[k] = m.mesh.surface(kInnerWall)(t, k), p.weight[k] = b[k];
  }
  points[2].node[2] = -1;  // a point on an edge (two nodes)
  const LoadResponse lr(*m.solver, points);
  ASSERT_EQ(lr.response().rows(), 3 * m.n());
  ASSERT_EQ(lr.response().cols(), 9);
  for (int trial = 0; trial < 5; ++trial) {
    Points F(3, 3);
    for (int i = 0; i < 9; ++i) F.data()[i] = force(rng);
    // Direct: nodal forces from the weights, one solve; twin: dense inverse.
    Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * m.n());
    for (int p = 0; p < 3; ++p)
      for (int k = 0; k < 3; ++k)
        if (points[p].node[k] >= 0) f.segment<3>(3 * points[p].node[k]) += points[p].weight[k] * F.row(p).transpose();
    Eigen::VectorXd u_direct, u;
    m.solver->solve(f, u_direct);
    lr.displacement(F, u);
    EXPECT_LE((u - u_direct).norm(), 1e-12 * u_direct.norm());
    EXPECT_LE((u - m.Kinv * f).norm(), 1e-9 * u_direct.norm());
    // Point compliance: the weighted displacement of each load point.
    const Eigen::Map<const Eigen::VectorXd> fv(F.data(), 9);
    const Eigen::VectorXd up = lr.point_compliance() * fv;
    for (int p = 0; p < 3; ++p) {
      Eigen::Vector3d d = Eigen::Vector3d::Zero();
      for (int k = 0; k < 3; ++k)
        if (points[p].node[k] >= 0) d += points[p].weight[k] * u.segment<3>(3 * points[p].node[k]);
      EXPECT_LE((up.segment<3>(3 * p) - d).norm(), 1e-12 * u.norm());
    }
  }
  EXPECT_LE((lr.point_compliance() - lr.point_compliance().transpose()).norm(), 1e-12 * lr.point_compliance().norm());
  LoadPoint bad;
  bad.node[0] = m.n();
  EXPECT_THROW(LoadResponse(*m.solver, {bad}), std::invalid_argument);
  EXPECT_THROW(LoadResponse(*m.solver, {LoadPoint{}}), std::invalid_argument);
  EXPECT_THROW(lr.displacement(Points(2, 3)), std::invalid_argument);
}

}  // namespace
}  // namespace lumen::physics
