// The exported von Mises stress: a uniform stretch gives the analytic value on every tet; a rigid rotation none
// with the corotational material (its rotation taken out), but spurious stress with the linear one.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include <Eigen/Geometry>

#include "engine/volume_export.hpp"

using namespace lumen;

namespace {

std::string scene_text(const std::string& model) {
  return R"({"name": "v", "mesh": {"type": "hollow_cylinder", "inner_radius": 0.01, "outer_radius": 0.013,
    "length": 0.06, "segments_around": 8, "segments_along": 4, "layers": 1},
    "material": {"model": ")" + model + R"(", "young_modulus": 5000.0, "poisson_ratio": 0.45},
    "fixed": ["ends"], "probes": [{"point": [0.0, 0.013, 0.03], "track": [{"t": 0, "force": [0, 0, 0]}]}],
    "frames": 1, "fps": 40})";
}

// u = (A - I) X at every node, 3 n, metres.
Eigen::VectorXd affine_displacement(const engine::Model& m, const Eigen::Matrix3d& A) {
  Eigen::VectorXd u(3 * m.mesh.n_nodes());
  for (int i = 0; i < m.mesh.n_nodes(); ++i)
    u.segment<3>(3 * i) = (A - Eigen::Matrix3d::Identity()) * m.mesh.rest.row(i).transpose();
  return u;
}

TEST(VolumeExport, UniaxialStretchGivesTheAxialStressOnEveryTet) {
  const auto m = engine::compile_model(engine::parse_scene(scene_text("linear"), "v.json"));
  const physics::LinearMaterial material{5000.0, 0.45};
  // Strain diag(e, -nu e, -nu e): uniaxial stress E e along x, von Mises E e.
  const double e = 1e-3;
  const Eigen::Vector3d stretch(1.0 + e, 1.0 - material.poisson_ratio * e, 1.0 - material.poisson_ratio * e);
  const Eigen::VectorXd vm = engine::tet_von_mises(*m, affine_displacement(*m, stretch.asDiagonal()), material);
  ASSERT_EQ(vm.size(), m->mesh.tets.rows());
  EXPECT_NEAR(vm.minCoeff(), material.young_modulus * e, 1e-9);
  EXPECT_NEAR(vm.maxCoeff(), material.young_modulus * e, 1e-9);
}

TEST(VolumeExport, CorotationalStressIgnoresARigidRotation) {
  const physics::LinearMaterial material{5000.0, 0.45};
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const auto cor = engine::compile_model(engine::parse_scene(scene_text("corotational"), "v.json"));
  EXPECT_LT(engine::tet_von_mises(*cor, affine_displacement(*cor, R), material).maxCoeff(), 1e-9);
  // The linear material's small strain sees the rotation as strain.
  const auto lin = engine::compile_model(engine::parse_scene(scene_text("linear"), "v.json"));
  EXPECT_GT(engine::tet_von_mises(*lin, affine_displacement(*lin, R), material).minCoeff(), 100.0);
}

}  // namespace
