// The exact corotational tangent (K_w plus the twist modes of the rotations' derivative) against central finite
// differences of the elastic forces, its positive semi-definite projection against each element's eigenvalues,
// and the assembled tangent against the matrix-free product.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "physics/corotational.hpp"
#include "physics/mesh.hpp"
#include "support/fem.hpp"

namespace lumen::physics {
namespace {

using lumen::test::kTissue;

// A 8 x 4 x 1 tube, 4 cm long, deformed by x = Q (A X) + bend, with A a stretch (diagonal: sx, sy, sz) and the
// bend a displacement along y quadratic in z of amplitude `bend` (metres); u (3n) = x - X.
struct Deformed {
  TetMesh mesh;
  Eigen::VectorXd u;
};
Deformed deformed_tube(const Eigen::Vector3d& stretch, double bend) {
  HollowCylinderSpec s;
  s.segments_around = 8, s.segments_along = 4, s.layers = 1, s.length = 0.04;
  Deformed d{make_hollow_cylinder(s), {}};
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1.0, 2.0, 3.0).normalized()).toRotationMatrix();
  d.u.resize(3 * d.mesh.n_nodes());
  for (int v = 0; v < d.mesh.n_nodes(); ++v) {
    const Eigen::Vector3d X = d.mesh.rest.row(v).transpose();
    const double z = X.z() / s.length;
    Eigen::Vector3d x = stretch.asDiagonal() * X;
    x.y() += bend * 4.0 * z * (1.0 - z);
    d.u.segment<3>(3 * v) = Q * x - X;
  }
  return d;
}

// Elastic forces at u (3n, newtons), with the rotations of u.
Eigen::VectorXd forces_at(const CorotationalElements& el, const Eigen::VectorXd& u) {
  std::vector<Eigen::Matrix3d> R;
  el.rotations(u, R);
  Eigen::VectorXd f;
  el.elastic_forces(u, R, f);
  return f;
}

// One tet (a corner of the unit cube scaled to 1 cm) deformed by x = F X: its elements and u (12).
struct OneTet {
  TetMesh mesh;
  Eigen::VectorXd u;
};
OneTet one_tet(const Eigen::Matrix3d& F) {
  OneTet o;
  o.mesh.rest.resize(4, 3);
  o.mesh.rest << 0, 0, 0, 0.01, 0, 0, 0, 0.01, 0, 0, 0, 0.01;
  o.mesh.tets.resize(1, 4);
  o.mesh.tets << 0, 1, 2, 3;
  o.u.resize(12);
  for (int v = 0; v < 4; ++v) {
    const Eigen::Vector3d X = o.mesh.rest.row(v).transpose();
    o.u.segment<3>(3 * v) = F * X - X;
  }
  return o;
}

// Dense tangent K_t (3n x 3n) assembled at u with projected or exact twist modes.
Eigen::MatrixXd dense_tangent(const CorotationalElements& el, const Eigen::VectorXd& u, bool project) {
  std::vector<Eigen::Matrix3d> R;
  el.rotations(u, R);
  std::vector<TwistModes> modes;
  el.twist_modes(u, R, project, modes);
  return Eigen::MatrixXd(el.tangent_stiffness(R, modes));
}

// The exact tangent (unprojected twist modes) is the derivative of the elastic forces: against central
// differences on a tube stretched, bent by 1 cm and rotated by 40 degrees, where K_w alone is off.
TEST(CorotationalTangent, ExactTangentMatchesFiniteDifferencesOfTheForces) {
  const Deformed d = deformed_tube(Eigen::Vector3d(1.3, 0.8, 1.2), 0.01);
  const CorotationalElements el(d.mesh, kTissue);
  std::vector<Eigen::Matrix3d> R;
  ASSERT_EQ(el.rotations(d.u, R), 0);
  std::vector<TwistModes> modes;
  el.twist_modes(d.u, R, /*project=*/false, modes);
  std::mt19937 rng(7);
  std::normal_distribution<double> normal(0.0, 1.0);
  double worst_tangent = 0.0, best_warped = INFINITY;
  for (int trial = 0; trial < 4; ++trial) {
    // A random direction; a step of 1e-7 of the displacement scale (central differences: error ~ h^2).
    Eigen::VectorXd p(d.u.size());
    for (Eigen::Index i = 0; i < p.size(); ++i) p[i] = normal(rng);
    p.normalize();
    const double h = 1e-7 * d.u.norm();
    const Eigen::VectorXd fd = (forces_at(el, d.u + h * p) - forces_at(el, d.u - h * p)) / (2.0 * h);
    Eigen::VectorXd kt, kw;
    el.tangent_product(R, modes, p, kt);
    el.warped_product(R, p, kw);
    worst_tangent = std::max(worst_tangent, (kt - fd).norm() / fd.norm());
    best_warped = std::min(best_warped, (kw - fd).norm() / fd.norm());
  }
  std::printf("relative error against finite differences: tangent %.2e (worst of 4), warped %.2e (best of 4)\n",
              worst_tangent, best_warped);
  EXPECT_LT(worst_tangent, 1e-6);
  EXPECT_GT(best_warped, 1e-2);  // the rotations' derivative matters at this deformation
}

// Projection: where a tet is compressed across a pair of axes the exact element Hessian has a negative
// eigenvalue; the projected one has none, and equals the exact one where every twist eigenvalue is >= 0
// (stretched). Eigenvalues from Eigen's dense solver on the assembled one-tet tangent.
TEST(CorotationalTangent, ProjectionRemovesNegativeEigenvaluesAndKeepsTheStretchedTangent) {
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(1.1, Eigen::Vector3d(-1.0, 0.5, 2.0).normalized()).toRotationMatrix();
  // Compressed to 0.5 x 0.6 x 1.1 and rotated.
  const OneTet squeezed = one_tet(Q * Eigen::Vector3d(0.5, 0.6, 1.1).asDiagonal());
  const CorotationalElements el(squeezed.mesh, kTissue);
  const Eigen::MatrixXd exact = dense_tangent(el, squeezed.u, false), projected = dense_tangent(el, squeezed.u, true);
  const double scale = exact.cwiseAbs().maxCoeff();
  const Eigen::VectorXd e_exact = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(exact).eigenvalues();
  const Eigen::VectorXd e_proj = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(projected).eigenvalues();
  std::printf("squeezed tet: least eigenvalue exact %.3e, projected %.3e (largest %.3e) N/m\n", e_exact.minCoeff(),
              e_proj.minCoeff(), e_exact.maxCoeff());
  EXPECT_LT(e_exact.minCoeff(), -1e-3 * scale);
  EXPECT_GT(e_proj.minCoeff(), -1e-12 * scale);
  // Stretched to 1.3 x 1.2 x 1.1: every twist eigenvalue is positive, nothing to clamp.
  const OneTet stretched = one_tet(Q * Eigen::Vector3d(1.3, 1.2, 1.1).asDiagonal());
  const CorotationalElements el2(stretched.mesh, kTissue);
  const Eigen::MatrixXd a = dense_tangent(el2, stretched.u, false), b = dense_tangent(el2, stretched.u, true);
  EXPECT_LT((a - b).cwiseAbs().maxCoeff(), 1e-12 * a.cwiseAbs().maxCoeff());
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(a).eigenvalues().minCoeff(), -1e-12 * scale);
}

// The assembled tangent against the matrix-free product (its twin), and at rest both are the linear K.
TEST(CorotationalTangent, AssembledTangentMatchesTheProductAndIsTheLinearStiffnessAtRest) {
  const Deformed d = deformed_tube(Eigen::Vector3d(0.7, 1.2, 0.9), 0.008);
  const CorotationalElements el(d.mesh, kTissue);
  std::vector<Eigen::Matrix3d> R;
  el.rotations(d.u, R);
  std::vector<TwistModes> modes;
  el.twist_modes(d.u, R, /*project=*/true, modes);
  const Eigen::SparseMatrix<double> K = el.tangent_stiffness(R, modes);
  Eigen::VectorXd p = Eigen::VectorXd::LinSpaced(d.u.size(), -1.0, 1.0), y;
  el.tangent_product(R, modes, p, y);
  EXPECT_LT((K * p - y).norm(), 1e-12 * y.norm());
  // At rest: the twist eigenvalues vanish, and K_t = K_w(I) = K.
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(d.u.size());
  std::vector<Eigen::Matrix3d> I;
  el.rotations(zero, I);
  el.twist_modes(zero, I, /*project=*/false, modes);
  const Eigen::SparseMatrix<double> K0 = el.tangent_stiffness(I, modes), Kw = el.warped_stiffness(I);
  EXPECT_LT(Eigen::MatrixXd(K0 - Kw).cwiseAbs().maxCoeff(), 1e-12 * Eigen::MatrixXd(Kw).cwiseAbs().maxCoeff());
}

// Truncated CG against its twin, Eigen's CG (solve_pcg), on a positive definite system (K_w on a tube held at both
// ends): the same solution. On the exact tangent of a tube crushed to half its width (indefinite), it stops at a
// direction of negative curvature and returns a descent direction, b . x > 0.
TEST(TruncatedPcg, MatchesCgWhenPositiveDefiniteAndStopsWithADescentDirectionWhenNot) {
  const Deformed d = deformed_tube(Eigen::Vector3d(0.5, 0.5, 1.0), 0.0);
  std::vector<int> ends = d.mesh.node_set(kStartEnd);
  ends.insert(ends.end(), d.mesh.node_set(kStopEnd).begin(), d.mesh.node_set(kStopEnd).end());
  const CorotationalModel model(d.mesh, kTissue, ends);
  const CorotationalElements& el = model.elements();
  std::vector<Eigen::Matrix3d> R;
  el.rotations(d.u, R);
  std::vector<TwistModes> exact;
  el.twist_modes(d.u, R, /*project=*/false, exact);
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(el.n_dofs(), -1.0, 2.0);
  // Positive definite: K_w.
  const WarpedSystem warped{&el, &R};
  Eigen::VectorXd x_cg, x_truncated;
  const PcgResult cg = solve_pcg(warped, model.solver(), b, x_cg, 1e-10, 500);
  const PcgResult truncated = solve_truncated_pcg(warped, model.solver(), b, x_truncated, 1e-10, 500);
  ASSERT_TRUE(cg.converged);
  ASSERT_TRUE(truncated.converged);
  EXPECT_FALSE(truncated.negative_curvature);
  EXPECT_LT((x_truncated - x_cg).norm(), 1e-8 * x_cg.norm());
  // Indefinite: the exact tangent of the crushed tube (a negative eigenvalue checked by the dense solver).
  Eigen::MatrixXd Kt(el.tangent_stiffness(R, exact));
  std::vector<int> free_dofs;
  for (int dof = 0; dof < el.n_dofs(); ++dof)
    if (!model.is_fixed_dof(dof)) free_dofs.push_back(dof);
  Eigen::MatrixXd Kf(free_dofs.size(), free_dofs.size());
  for (size_t i = 0; i < free_dofs.size(); ++i)
    for (size_t j = 0; j < free_dofs.size(); ++j) Kf(i, j) = Kt(free_dofs[i], free_dofs[j]);
  ASSERT_LT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Kf).eigenvalues().minCoeff(), 0.0);
  const WarpedSystem tangent{&el, &R, nullptr, 0.0, 1.0, nullptr, nullptr, &exact};
  Eigen::VectorXd x;
  const PcgResult r = solve_truncated_pcg(tangent, model.solver(), b, x, 1e-10, 500);
  std::printf("indefinite tangent: stopped after %d iterations, negative curvature %d, b.x / (|b||x|) %.3e\n",
              r.iterations, r.negative_curvature, b.dot(x) / (b.norm() * x.norm()));
  EXPECT_TRUE(r.negative_curvature);
  EXPECT_GT(b.dot(x), 0.0);
}

}  // namespace
}  // namespace lumen::physics
