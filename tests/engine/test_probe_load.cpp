// A probe's force at a surface point: the point found is the nearest on the outer wall (against dense
// sampling), and the nodal forces sum to the probe force with zero moment about the point.
#include <gtest/gtest.h>

#include <random>

#include "engine/simulation.hpp"

using namespace lumen;

TEST(ProbeLoad, SnapsToNearestOuterPointAndSpreadsWithoutMoment) {
  physics::HollowCylinderSpec spec;
  spec.segments_around = 12;
  spec.segments_along = 8;
  spec.layers = 2;
  const physics::TetMesh mesh = physics::make_hollow_cylinder(spec);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> angle(0, 6.283185307179586), z(0.0, spec.length), r(0.012, 0.016);
  for (int trial = 0; trial < 20; ++trial) {
    const double a = angle(rng), rr = r(rng);
    const Eigen::Vector3d p(rr * std::cos(a), rr * std::sin(a), z(rng));
    const engine::SurfacePoint sp = engine::snap_to_surface(mesh.rest, mesh.outer, p);
    ASSERT_GE(sp.triangle, 0);
    Eigen::Vector3d q = Eigen::Vector3d::Zero();
    double wsum = 0;
    for (int k = 0; k < 3; ++k) {
      EXPECT_GE(sp.weight[k], -1e-12);
      wsum += sp.weight[k];
      q += sp.weight[k] * mesh.rest.row(sp.node[k]).transpose();
    }
    EXPECT_NEAR(wsum, 1.0, 1e-12);
    // Brute-force twin: densely sampled points of every outer triangle are never closer.
    double best = 1e9;
    for (int t = 0; t < mesh.outer.rows(); ++t)
      for (int i = 0; i <= 20; ++i)
        for (int j = 0; i + j <= 20; ++j) {
          const Eigen::Vector3d s = (1 - (i + j) / 20.0) * mesh.rest.row(mesh.outer(t, 0)).transpose() +
                                    (i / 20.0) * mesh.rest.row(mesh.outer(t, 1)).transpose() +
                                    (j / 20.0) * mesh.rest.row(mesh.outer(t, 2)).transpose();
          best = std::min(best, (s - p).norm());
        }
    EXPECT_LE((q - p).norm(), best + 1e-12);
    // Nodal forces: same resultant, zero moment about the attachment point.
    const Eigen::Vector3d F(0.3, -1.2, 0.5);
    Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * mesh.n_nodes());
    engine::add_point_load(sp, F, f);
    Eigen::Vector3d sum = Eigen::Vector3d::Zero(), moment = Eigen::Vector3d::Zero();
    for (int i = 0; i < mesh.n_nodes(); ++i) {
      sum += f.segment<3>(3 * i);
      moment += (mesh.rest.row(i).transpose() - q).cross(Eigen::Vector3d(f.segment<3>(3 * i)));
    }
    EXPECT_LT((sum - F).norm(), 1e-12);
    EXPECT_LT(moment.norm(), 1e-14);
  }
}
