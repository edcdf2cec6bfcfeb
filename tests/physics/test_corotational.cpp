// Corotational FEM against independent truths: SVD polar twin, explicit R K_e (R^T x - X) from tet_stiffness,
// rigid rotations (zero force), the linear limit for small loads, an explicit warped K solved by SimplicialLDLT,
// volume under a prescribed 180-degree twist, the lagged warped preconditioner against the rest one, and
// inverted elements.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "physics/corotational.hpp"
#include "physics/detail/element_lanes.hpp"
#include "physics/fem.hpp"
#include "physics/mesh.hpp"
#include "support/fem.hpp"

namespace lumen::physics {
namespace {

using Mat43 = Eigen::Matrix<double, 4, 3>;
using Mat12 = Eigen::Matrix<double, 12, 12>;
using lumen::test::kTissue;

using lumen::test::both_ends;
using lumen::test::small_tube;

// u (3n) of x = Q X + c - X for every node.
Eigen::VectorXd rigid_displacement(const TetMesh& m, const Eigen::Matrix3d& Q, const Eigen::Vector3d& c) {
  Eigen::VectorXd u(3 * m.n_nodes());
  for (int v = 0; v < m.n_nodes(); ++v) {
    const Eigen::Vector3d X = m.rest.row(v).transpose();
    u.segment<3>(3 * v) = Q * X + c - X;
  }
  return u;
}

Mat43 rest_of(const TetMesh& m, int t) {
  Mat43 X;
  for (int a = 0; a < 4; ++a) X.row(a) = m.rest.row(m.tets(t, a));
  return X;
}

// Explicit warped stiffness sum_e R_e K_e R_e^T (dense, 3n x 3n) from tet_stiffness.
Eigen::MatrixXd explicit_warped_stiffness(const TetMesh& m, const std::vector<Eigen::Matrix3d>& R) {
  const int n = 3 * m.n_nodes();
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(n, n);
  for (int t = 0; t < m.tets.rows(); ++t) {
    const Mat12 Ke = tet_stiffness(rest_of(m, t), kTissue);
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b)
        K.block<3, 3>(3 * m.tets(t, a), 3 * m.tets(t, b)) += R[t] * Ke.block<3, 3>(3 * a, 3 * b) * R[t].transpose();
  }
  return K;
}

Eigen::Matrix3d random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> d(0.0, 1.0);
  const Eigen::Quaterniond q(d(rng), d(rng), d(rng), d(rng));
  return q.normalized().toRotationMatrix();
}

// Loads: a transverse force split over the stop-end nodes, newtons (3n).
Eigen::VectorXd tip_load(const TetMesh& m, double total) {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * m.n_nodes());
  for (int v : m.node_set(kStopEnd)) f[3 * v + 1] = -total / m.node_set(kStopEnd).size();
  return f;
}

// Prescribed displacements of a twist (3n, metres): the stop end turned by theta about the axis, the rest 0.
Eigen::VectorXd end_twist(const TetMesh& m, double theta) {
  Eigen::VectorXd u_fixed = Eigen::VectorXd::Zero(3 * m.n_nodes());
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  for (int v : m.node_set(kStopEnd)) {
    const Eigen::Vector3d X = m.rest.row(v).transpose();
    u_fixed.segment<3>(3 * v) = Q * X - X;
  }
  return u_fixed;
}

// ---------------------------------------------------------------------------------------------------------------

TEST(ProperRotation, MatchesSvdPolarAndStaysProperWhenInverted) {
  std::mt19937 rng(3);
  std::normal_distribution<double> d(0.0, 0.3);
  for (int trial = 0; trial < 200; ++trial) {
    Eigen::Matrix3d F = random_rotation(rng);
    for (int i = 0; i < 9; ++i) F.data()[i] += d(rng);
    if (trial % 4 == 0) F.col(trial % 3) *= -1.0;  // some reflected (inverted) gradients
    bool inverted = false;
    const Eigen::Matrix3d R = proper_rotation(F, &inverted);
    // Twin: R = U diag(1, 1, sign det(U V^T)) V^T from Eigen's SVD.
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
    D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
    const Eigen::Matrix3d twin = svd.matrixU() * D * svd.matrixV().transpose();
    EXPECT_EQ(inverted, F.determinant() <= 0.0);
    EXPECT_NEAR(R.determinant(), 1.0, 1e-11);
    EXPECT_LE((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-11);
    EXPECT_LE((R - twin).norm(), 1e-9) << "trial " << trial << "\nF =\n" << F;
    const Eigen::Matrix3d S = R.transpose() * F;
    EXPECT_LE((S - S.transpose()).norm(), 1e-9 * S.norm());
  }
  // Small strains (|det F - 1| < 0.25, where the Newton scaling is its series) against the same twin.
  std::normal_distribution<double> small(0.0, 0.02);
  for (int trial = 0; trial < 200; ++trial) {
    Eigen::Matrix3d F = random_rotation(rng);
    for (int i = 0; i < 9; ++i) F.data()[i] += small(rng);
    ASSERT_LT(std::abs(F.determinant() - 1.0), 0.25);
    const Eigen::Matrix3d R = proper_rotation(F);
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
    EXPECT_LE((R - svd.matrixU() * svd.matrixV().transpose()).norm(), 1e-12) << "trial " << trial;
  }
  // Degenerate (flattened) gradient: a proper rotation, flagged inverted.
  Eigen::Matrix3d flat = Eigen::Matrix3d::Identity();
  flat(2, 2) = 0.0;
  bool inverted = false;
  const Eigen::Matrix3d R = proper_rotation(flat, &inverted);
  EXPECT_TRUE(inverted);
  EXPECT_TRUE(R.allFinite());
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
  Eigen::Matrix3d bad = Eigen::Matrix3d::Identity();
  bad(1, 2) = NAN;
  EXPECT_THROW(proper_rotation(bad), std::invalid_argument);
}

// The lockstep lanes against proper_rotation one matrix at a time: small and large strains (the series and cbrt
// scalings), reflected and flattened gradients (left to proper_rotation's SVD), and a last batch part full; a
// gradient that is not finite throws as proper_rotation does.
TEST(ProperRotations, LockstepLanesEqualOneAtATime) {
  std::mt19937 rng(11);
  std::normal_distribution<double> small(0.0, 0.02), large(0.0, 0.3);
  const int n = 5 * detail::kPolarLanes + 3;
  std::vector<Eigen::Matrix3d> F(n);
  int inverted_twin = 0;
  for (int i = 0; i < n; ++i) {
    F[i] = random_rotation(rng);
    for (int k = 0; k < 9; ++k) F[i].data()[k] += (i % 3 == 0 ? large : small)(rng);
    if (i % 7 == 0) F[i] *= 2.5;                // det about 16: the cbrt scaling
    if (i % 11 == 0) F[i].col(i % 3) *= -1.0;   // reflected
    if (i % 13 == 5) F[i].col(2) *= 1e-3;       // nearly flat: det below the Newton threshold
    inverted_twin += F[i].determinant() <= 0.0 ? 1 : 0;
  }
  ASSERT_GT(inverted_twin, 0);
  std::vector<Eigen::Matrix3d> R(n);
  EXPECT_EQ(proper_rotations(n, [&](int i) { return F[i]; }, R.data()), inverted_twin);
  for (int i = 0; i < n; ++i) {
    const Eigen::Matrix3d twin = proper_rotation(F[i]);
    EXPECT_LE((R[i] - twin).norm(), 1e-13) << "matrix " << i << "\nF =\n" << F[i];
  }
  F[n / 2](1, 1) = NAN;
  EXPECT_THROW(proper_rotations(n, [&](int i) { return F[i]; }, R.data()), std::invalid_argument);
}

TEST(CorotationalElements, ForcesAndWarpedProductMatchExplicitElementFormulas) {
  const TetMesh m = small_tube(6, 2, 1);
  const CorotationalElements el(m, kTissue);
  const int n = 3 * m.n_nodes();
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> du(-2e-4, 2e-4);
  Eigen::VectorXd u(n);
  for (int i = 0; i < n; ++i) u[i] = du(rng);
  // Identity rotations: f_int = K u with the assembled linear stiffness.
  const Eigen::SparseMatrix<double> K = assemble_stiffness(m, kTissue);
  const std::vector<Eigen::Matrix3d> I(el.n_tets(), Eigen::Matrix3d::Identity());
  Eigen::VectorXd f;
  el.elastic_forces(u, I, f);
  const Eigen::VectorXd Ku = K * u;
  EXPECT_LE((f - Ku).norm(), 1e-12 * Ku.norm());
  EXPECT_NEAR(el.elastic_energy(u, I), 0.5 * u.dot(Ku), 1e-12 * u.dot(Ku));

  // A large rotation plus the small displacement: rotations from the gradients, then f = sum R K_e (R^T x - X).
  const Eigen::Matrix3d Q = random_rotation(rng);
  const Eigen::VectorXd w = rigid_displacement(m, Q, Eigen::Vector3d(0.01, -0.02, 0.005)) + u;
  std::vector<Eigen::Matrix3d> R;
  EXPECT_EQ(el.rotations(w, R), 0);
  el.elastic_forces(w, R, f);
  Eigen::VectorXd twin = Eigen::VectorXd::Zero(n);
  for (int t = 0; t < el.n_tets(); ++t) {
    const Mat43 X = rest_of(m, t);
    Eigen::Matrix<double, 12, 1> local;
    for (int a = 0; a < 4; ++a) {
      const Eigen::Vector3d x = X.row(a).transpose() + w.segment<3>(3 * m.tets(t, a));
      local.segment<3>(3 * a) = R[t].transpose() * x - X.row(a).transpose();
    }
    const Eigen::Matrix<double, 12, 1> fl = tet_stiffness(X, kTissue) * local;
    for (int a = 0; a < 4; ++a) twin.segment<3>(3 * m.tets(t, a)) += R[t] * fl.segment<3>(3 * a);
  }
  EXPECT_LE((f - twin).norm(), 1e-10 * twin.norm());

  // Warped product against the explicit sum of R K_e R^T.
  Eigen::VectorXd p(n);
  for (int i = 0; i < n; ++i) p[i] = du(rng);
  Eigen::VectorXd y;
  el.warped_product(R, p, y);
  const Eigen::VectorXd y_twin = explicit_warped_stiffness(m, R) * p;
  EXPECT_LE((y - y_twin).norm(), 1e-12 * y_twin.norm());
}

// The assembled K_w (the lagged preconditioner's matrix) against the explicit sum of R K_e R^T from tet_stiffness,
// and with identity rotations against the assembled linear stiffness.
TEST(CorotationalElements, AssembledWarpedStiffnessMatchesExplicitSum) {
  const TetMesh m = small_tube(6, 3, 2);
  const CorotationalElements el(m, kTissue);
  std::mt19937 rng(11);
  std::vector<Eigen::Matrix3d> R(el.n_tets());
  for (Eigen::Matrix3d& r : R) r = random_rotation(rng);
  const Eigen::MatrixXd twin = explicit_warped_stiffness(m, R);
  const Eigen::MatrixXd Kw = Eigen::MatrixXd(el.warped_stiffness(R));
  EXPECT_LE((Kw - twin).norm(), 1e-12 * twin.norm());
  const std::vector<Eigen::Matrix3d> I(el.n_tets(), Eigen::Matrix3d::Identity());
  const Eigen::MatrixXd K = Eigen::MatrixXd(assemble_stiffness(m, kTissue));
  EXPECT_LE((Eigen::MatrixXd(el.warped_stiffness(I)) - K).norm(), 1e-12 * K.norm());
  EXPECT_THROW(el.warped_stiffness(std::vector<Eigen::Matrix3d>(3)), std::invalid_argument);
}

TEST(CorotationalElements, RigidRotationOfFreeMeshGivesZeroForceUnlikeLinear) {
  const TetMesh m = small_tube(8, 3, 1, 0.03);
  const CorotationalElements el(m, kTissue);
  const Eigen::SparseMatrix<double> K = assemble_stiffness(m, kTissue);
  // 90 degrees about a tilted axis, plus a translation.
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(EIGEN_PI / 2, Eigen::Vector3d(1.0, 2.0, -0.5).normalized()).toRotationMatrix();
  const Eigen::VectorXd u = rigid_displacement(m, Q, Eigen::Vector3d(0.003, 0.0, -0.01));
  std::vector<Eigen::Matrix3d> R;
  EXPECT_EQ(el.rotations(u, R), 0);
  for (const Eigen::Matrix3d& Re : R) EXPECT_LE((Re - Q).norm(), 1e-12);
  Eigen::VectorXd f;
  el.elastic_forces(u, R, f);
  const Eigen::VectorXd f_linear = K * u;
  // Linear: forces of the order of the stiffness times the displacement; corotational: round-off only.
  EXPECT_GT(f_linear.norm(), 1e-3);
  EXPECT_LE(f.norm(), 1e-12 * f_linear.norm());
  EXPECT_LE(el.elastic_energy(u, R), 1e-12 * 0.5 * u.dot(f_linear));
}

TEST(CorotationalSolve, EqualsLinearInTheSmallLoadLimit) {
  const TetMesh m = small_tube(8, 4, 1, 0.04);
  const CorotationalModel model(m, kTissue, m.node_set(kStartEnd));
  CorotationalOptions opt;
  opt.tolerance = 1e-10;
  opt.max_iterations = 100;
  double previous = 0.0;
  for (double s : {1.0, 0.1, 0.01, 0.001}) {
    const Eigen::VectorXd f = tip_load(m, 0.01 * s);
    Eigen::VectorXd u_lin;
    model.solver().solve(f, u_lin);
    CorotationalState state;
    const CorotationalResult r = solve_corotational(model, f, state, opt);
    ASSERT_TRUE(r.converged) << "scale " << s << " residual " << r.residual;
    const double diff = (state.u - u_lin).norm() / u_lin.norm();
    std::printf("load scale %g: tip deflection %.3g m, |u_corot - u_lin| / |u_lin| = %.3g (%d outer, %d CG)\n", s,
                u_lin.cwiseAbs().maxCoeff(), diff, r.iterations, r.cg_iterations);
    // Relative difference shrinks linearly with the load.
    if (s < 1.0) {
      EXPECT_GT(diff / previous, 0.05) << "scale " << s;
      EXPECT_LT(diff / previous, 0.2) << "scale " << s;
    } else {
      EXPECT_GT(diff, 1e-3);  // nonlinear at the full load
    }
    previous = diff;
  }
  EXPECT_LT(previous, 1e-3);
}

TEST(CorotationalSolve, PcgMatchesDirectSolveOfExplicitWarpedSystem) {
  const TetMesh m = small_tube(8, 2, 1, 0.02);
  const CorotationalModel model(m, kTissue, both_ends(m));
  const int n = model.n_dofs();
  // A strongly rotated state: each node turned about the axis by an angle growing along the tube (large twist).
  Eigen::VectorXd u(n);
  for (int v = 0; v < m.n_nodes(); ++v) {
    const Eigen::Vector3d X = m.rest.row(v).transpose();
    const Eigen::Matrix3d Q = Eigen::AngleAxisd(1.2 * X.z() / 0.02, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    u.segment<3>(3 * v) = Q * X - X;
  }
  std::vector<Eigen::Matrix3d> R, node_R;
  model.elements().rotations(u, R);
  model.elements().node_rotations(R, node_R);
  // Twin: explicit K_w on the free DOFs, SimplicialLDLT.
  std::vector<int> free;
  for (int d = 0; d < n; ++d)
    if (!model.is_fixed_dof(d)) free.push_back(d);
  const Eigen::MatrixXd Kw = explicit_warped_stiffness(m, R);
  Eigen::MatrixXd Kf(free.size(), free.size());
  for (size_t i = 0; i < free.size(); ++i)
    for (size_t j = 0; j < free.size(); ++j) Kf(i, j) = Kw(free[i], free[j]);
  const Eigen::SparseMatrix<double> Kfs = Kf.sparseView();
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(Kfs);
  ASSERT_EQ(ldlt.info(), Eigen::Success);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> df(-1e-3, 1e-3);
  Eigen::VectorXd b(n);
  for (int i = 0; i < n; ++i) b[i] = df(rng);
  Eigen::VectorXd bf(free.size());
  for (size_t i = 0; i < free.size(); ++i) bf[i] = b[free[i]];
  const Eigen::VectorXd xf = ldlt.solve(bf);
  Eigen::VectorXd twin = Eigen::VectorXd::Zero(n);
  for (size_t i = 0; i < free.size(); ++i) twin[free[i]] = xf[i];

  const WarpedSystem system{&model.elements(), &R, nullptr, 0.0, 1.0};
  for (const bool rotate : {false, true}) {
    Eigen::VectorXd x;
    const PcgResult r = solve_pcg(system, model.solver(), b, x, 1e-12, 500, rotate ? &node_R : nullptr);
    std::printf("PCG (rotated preconditioner %d): %d iterations, residual %.2g\n", rotate, r.iterations, r.residual);
    EXPECT_TRUE(r.converged);
    EXPECT_LE(r.residual, 1e-12);
    EXPECT_LE((x - twin).norm(), 1e-9 * twin.norm());
    for (int d = 0; d < n; ++d)
      if (model.is_fixed_dof(d)) {
        EXPECT_EQ(x[d], 0.0);
      }
  }
  // With a mass term: (c_m diag(m) + c_k K_w) x = b.
  Eigen::VectorXd mass = Eigen::VectorXd::Constant(n, 2e-4);
  const WarpedSystem dyn{&model.elements(), &R, &mass, 3.0, 0.5};
  const Eigen::MatrixXd Af = 3.0 * Eigen::MatrixXd(mass.head(free.size()).asDiagonal()) + 0.5 * Kf;
  const Eigen::VectorXd xf2 = Af.ldlt().solve(bf);
  Eigen::VectorXd x;
  const PcgResult r = solve_pcg(dyn, model.solver(), b, x, 1e-12, 500);
  EXPECT_TRUE(r.converged);
  for (size_t i = 0; i < free.size(); ++i) EXPECT_NEAR(x[free[i]], xf2[i], 1e-9 * xf2.norm());
}

// Volume of the deformed mesh: total relative change, RMS of the per-tet relative changes, inverted tets.
struct VolumeChange {
  double total = 0.0;
  double rms_element = 0.0;
  int inverted = 0;
};

VolumeChange volume_change(const TetMesh& m, const Eigen::VectorXd& u) {
  Points x = m.rest;
  for (int v = 0; v < m.n_nodes(); ++v) x.row(v) += u.segment<3>(3 * v).transpose();
  VolumeChange c;
  double volume = 0.0, rest = 0.0;
  for (int t = 0; t < m.tets.rows(); ++t) {
    const double v = tet_volume(x, m.tets, t), v0 = tet_volume(m.rest, m.tets, t);
    volume += v, rest += v0;
    c.rms_element += (v / v0 - 1.0) * (v / v0 - 1.0);
    c.inverted += v <= 0.0 ? 1 : 0;
  }
  c.total = volume / rest - 1.0;
  c.rms_element = std::sqrt(c.rms_element / m.tets.rows());
  return c;
}

// One end turned by 180 degrees about the axis (prescribed), the other held. Corotational: the tube twists and
// keeps its volume. Linear: the end's displacement (-2x, -2y, 0) is read as a radial squeeze, so the wall near
// the end collapses through the axis (inverted tets); its total volume changes little only because collapsed
// and over-stretched tets cancel, so the per-tet change is the measure.
TEST(CorotationalSolve, TwistOfOneEndBy180DegreesKeepsVolumeUnlikeLinear) {
  const TetMesh m = small_tube(12, 10, 1, 0.15);
  const CorotationalModel model(m, kTissue, both_ends(m));
  const int n = model.n_dofs();
  // Prescribed end displacements: the stop end turned by theta about the axis, the start end held.
  auto twist = [&](double theta) { return end_twist(m, theta); };
  // Corotational: 4 increments of 45 degrees, each warm-started from the last (extrapolated).
  CorotationalState state;
  CorotationalOptions opt;
  opt.max_iterations = 100;
  opt.rotate_preconditioner = true;
  opt.extrapolate = true;
  const Eigen::VectorXd no_load = Eigen::VectorXd::Zero(n);
  int outer = 0, cg = 0;
  for (int k = 1; k <= 4; ++k) {
    const CorotationalResult r = solve_corotational(model, no_load, state, opt, twist(k * EIGEN_PI / 4));
    ASSERT_TRUE(r.converged) << "increment " << k << " residual " << r.residual;
    EXPECT_EQ(r.n_inverted, 0);
    outer += r.iterations, cg += r.cg_iterations;
  }
  const Eigen::VectorXd u_end = twist(EIGEN_PI);
  for (int v : m.node_set(kStopEnd)) EXPECT_EQ(state.u.segment<3>(3 * v), u_end.segment<3>(3 * v));
  // Linear: u = u_p + K_ff^-1 (-K u_p) on the free DOFs.
  Eigen::VectorXd du;
  model.solver().solve(-(model.stiffness() * u_end), du);
  const Eigen::VectorXd u_lin = u_end + du;
  const VolumeChange corot = volume_change(m, state.u), lin = volume_change(m, u_lin);
  std::printf("180-degree twist (%d outer, %d CG iterations): volume change total / per-tet RMS / inverted tets:\n"
              "  corotational %+.2f%% / %.1f%% / %d\n  linear       %+.2f%% / %.1f%% / %d\n",
              outer, cg, 100 * corot.total, 100 * corot.rms_element, corot.inverted, 100 * lin.total,
              100 * lin.rms_element, lin.inverted);
  RecordProperty("volume_change_corotational", std::to_string(corot.total));
  RecordProperty("volume_change_linear", std::to_string(lin.total));
  EXPECT_LT(std::abs(corot.total), 0.05);
  EXPECT_LT(corot.rms_element, 0.1);
  EXPECT_EQ(corot.inverted, 0);
  EXPECT_GT(lin.rms_element, 5.0 * corot.rms_element);
  EXPECT_GT(lin.inverted, 0);
}

// The lagged warped preconditioner (factorised at once or on a background thread) reaches the same equilibrium
// as the rest-state preconditioner on the same 180-degree twist, in fewer CG iterations once it is in use.
TEST(CorotationalSolve, LaggedWarpedPreconditionerReachesTheSameEquilibriumInFewerIterations) {
  const TetMesh m = small_tube(8, 6, 1, 0.09);
  const CorotationalModel model(m, kTissue, both_ends(m));
  const int n = model.n_dofs();
  auto twist = [&](double theta) { return end_twist(m, theta); };
  const Eigen::VectorXd no_load = Eigen::VectorXd::Zero(n);
  // Six increments of 30 degrees with each preconditioner; CG iterations counted over the last three.
  struct Run {
    Eigen::VectorXd u;
    int late_cg = 0, refactorisations = 0;
  };
  auto run = [&](int refactor_cg_iterations, bool background) {
    CorotationalState state;
    CorotationalOptions opt;
    opt.tolerance = 1e-5;
    opt.max_iterations = 200;
    opt.extrapolate = true;
    opt.refactor_cg_iterations = refactor_cg_iterations;
    opt.refactor_in_background = background;
    Run out;
    for (int k = 1; k <= 6; ++k) {
      const CorotationalResult r = solve_corotational(model, no_load, state, opt, twist(k * EIGEN_PI / 6));
      EXPECT_TRUE(r.converged) << "increment " << k << " residual " << r.residual;
      if (k > 3) out.late_cg += r.cg_iterations;
      out.refactorisations += r.refactorisations;
    }
    if (state.pending.valid()) state.pending.wait();  // (no thread outlives the test)
    out.u = state.u;
    return out;
  };
  const Run rest = run(0, false), lagged = run(3, false), background = run(3, true);
  EXPECT_EQ(rest.refactorisations, 0);
  EXPECT_GT(lagged.refactorisations, 0);
  EXPECT_GT(background.refactorisations, 0);
  // The same equilibrium to the solve tolerance (relative to the largest displacement, about the tube radius).
  const double scale = rest.u.cwiseAbs().maxCoeff();
  EXPECT_LT((lagged.u - rest.u).cwiseAbs().maxCoeff(), 1e-4 * scale);
  EXPECT_LT((background.u - rest.u).cwiseAbs().maxCoeff(), 1e-4 * scale);
  EXPECT_LT(lagged.late_cg, rest.late_cg);
  std::printf("180-degree twist in 30-degree steps, CG iterations of the last three: rest %d, lagged %d (%d "
              "factorisations), background %d (%d)\n",
              rest.late_cg, lagged.late_cg, lagged.refactorisations, background.late_cg, background.refactorisations);
}

TEST(CorotationalElements, InvertedTetGivesFiniteRestoringForceAndIsCounted) {
  // Unit-corner tet; node 3 (on +z) pushed through the opposite face to z = -0.5 h: F = diag(1, 1, -0.5).
  TetMesh m;
  const double h = 0.01;
  m.rest.resize(4, 3);
  m.rest << 0, 0, 0, h, 0, 0, 0, h, 0, 0, 0, h;
  m.tets.resize(1, 4);
  m.tets << 0, 1, 2, 3;
  const CorotationalElements el(m, kTissue);
  Eigen::VectorXd u = Eigen::VectorXd::Zero(12);
  u[11] = -1.5 * h;
  std::vector<Eigen::Matrix3d> R;
  EXPECT_EQ(el.rotations(u, R), 1);
  // Irving: the smallest singular value flips sign, so R = I and the force is the linear K_e u, pushing node 3
  // back up (+z).
  EXPECT_LE((R[0] - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  Eigen::VectorXd f;
  el.elastic_forces(u, R, f);
  const Eigen::VectorXd twin = tet_stiffness(rest_of(m, 0), kTissue) * u;
  EXPECT_TRUE(f.allFinite());
  EXPECT_LE((f - twin).norm(), 1e-12 * twin.norm());
  EXPECT_LT(f[11], 0.0);  // f_int is along u; the restoring force -f_int pushes node 3 back to +z
  EXPECT_GT(u.dot(f), 0.0);

  // Flattened exactly (det F = 0) and inverted after a rotation: still finite, counted, energy finite.
  for (double z : {-h, -1.7 * h}) {
    u.setZero();
    u[11] = z;
    const Eigen::Matrix3d Q = Eigen::AngleAxisd(2.0, Eigen::Vector3d(0.3, -1.0, 0.4).normalized()).toRotationMatrix();
    Eigen::VectorXd w = rigid_displacement(m, Q, Eigen::Vector3d::Zero());
    for (int v = 0; v < 4; ++v) {
      const Eigen::Vector3d X = m.rest.row(v).transpose() + u.segment<3>(3 * v);
      w.segment<3>(3 * v) = Q * X - m.rest.row(v).transpose();
    }
    EXPECT_EQ(el.rotations(w, R), 1) << "z " << z;
    el.elastic_forces(w, R, f);
    EXPECT_TRUE(f.allFinite());
    EXPECT_TRUE(std::isfinite(el.elastic_energy(w, R)));
    EXPECT_GT(f.norm(), 0.0);
  }
}

// A tube of some 1500 tets under a large random displacement that inverts some
// of its tets.
struct InvertingTube {
  TetMesh mesh;
  CorotationalElements el{mesh, kTissue};
  Eigen::VectorXd u, p;
  explicit InvertingTube(const TetMesh& m = small_tube(16, 8, 2, 0.06)) : mesh(m) {
    std::mt19937 rng(21);
    std::uniform_real_distribution<double> d(-1.5e-3, 1.5e-3);
    u.resize(el.n_dofs());
    p.resize(el.n_dofs());
    for (int i = 0; i < el.n_dofs(); ++i) u[i] = d(rng), p[i] = d(rng);
  }
};

// Largest entry of |a - b| relative to the largest entry of |b|.
double relative_difference(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  return (a - b).cwiseAbs().maxCoeff() / b.cwiseAbs().maxCoeff();
}

// The kernels (rotations, forces, products, and rotations and forces in one pass) against a straightforward serial
// twin: per tet proper_rotation of the deformation gradient, the stress formula, nodal forces scattered in tet
// order, the energy summed in tet order. Returns the twin's count of inverted tets.
int expect_kernels_match_twin(const InvertingTube& tube) {
  const CorotationalElements& el = tube.el;
  const LameParameters lame = lame_parameters(kTissue);
  std::vector<Eigen::Matrix3d> R_twin(el.n_tets());
  Eigen::VectorXd f_twin = Eigen::VectorXd::Zero(el.n_dofs()), y_twin = f_twin;
  int inverted_twin = 0;
  double energy_twin = 0.0;
  for (int t = 0; t < el.n_tets(); ++t) {
    const Eigen::Matrix3d F = el.deformation_gradient(tube.u, t);
    bool inverted = false;
    R_twin[t] = proper_rotation(F, &inverted);
    inverted_twin += inverted ? 1 : 0;
    const Eigen::Matrix3d& R = R_twin[t];
    // Forces V R sigma(sym(R^T F) - I) grad^T on corners 1..3, minus their sum on corner 0; the same for the
    // warped product with the displacement gradient of p.
    Eigen::Matrix3d Dm;
    for (int a = 0; a < 3; ++a)
      Dm.col(a) = (tube.mesh.rest.row(el.tets()(t, a + 1)) - tube.mesh.rest.row(el.tets()(t, 0))).transpose();
    const Eigen::Matrix3d G = Dm.inverse();
    Eigen::Matrix3d Dp;
    for (int a = 0; a < 3; ++a) Dp.col(a) = tube.p.segment<3>(3 * el.tets()(t, a + 1)) - tube.p.segment<3>(3 * el.tets()(t, 0));
    const Eigen::Matrix3d strains[2] = {0.5 * (R.transpose() * F + F.transpose() * R) - Eigen::Matrix3d::Identity(),
                                        0.5 * (R.transpose() * Dp * G + (Dp * G).transpose() * R)};
    Eigen::VectorXd* out[2] = {&f_twin, &y_twin};
    for (int k = 0; k < 2; ++k) {
      const Eigen::Matrix3d sigma =
          2.0 * lame.mu * strains[k] + lame.lambda * strains[k].trace() * Eigen::Matrix3d::Identity();
      const Eigen::Matrix3d P = el.rest_volume(t) * R * sigma * G.transpose();
      for (int a = 0; a < 3; ++a) out[k]->segment<3>(3 * el.tets()(t, a + 1)) += P.col(a);
      out[k]->segment<3>(3 * el.tets()(t, 0)) -= P.rowwise().sum();
      if (k == 0) energy_twin += 0.5 * el.rest_volume(t) * strains[0].cwiseProduct(sigma).sum();
    }
  }
  std::vector<Eigen::Matrix3d> R;
  Eigen::VectorXd f, y;
  double energy = 0.0;
  EXPECT_EQ(el.rotations(tube.u, R), inverted_twin);
  for (int t = 0; t < el.n_tets(); ++t) EXPECT_LE((R[t] - R_twin[t]).norm(), 1e-12) << "tet " << t;
  el.elastic_forces(tube.u, R, f, &energy);
  el.warped_product(R, tube.p, y);
  EXPECT_LE(relative_difference(f, f_twin), 1e-12);
  EXPECT_LE(relative_difference(y, y_twin), 1e-12);
  EXPECT_NEAR(energy, energy_twin, 1e-12 * energy_twin);
  // The same in one pass (the evaluation at u).
  std::vector<Eigen::Matrix3d> R1;
  Eigen::VectorXd f1;
  double energy1 = 0.0;
  EXPECT_EQ(el.rotations_and_forces(tube.u, R1, f1, &energy1), inverted_twin);
  for (int t = 0; t < el.n_tets(); ++t) EXPECT_LE((R1[t] - R_twin[t]).norm(), 1e-12) << "tet " << t;
  EXPECT_LE(relative_difference(f1, f_twin), 1e-12);
  EXPECT_NEAR(energy1, energy_twin, 1e-12 * energy_twin);
  return inverted_twin;
}

TEST(CorotationalKernels, MatchSerialTwinWithInvertedTets) {
  const InvertingTube tube;
  const CorotationalElements& el = tube.el;
  ASSERT_GE(el.n_tets(), 1000);
  const int inverted = expect_kernels_match_twin(tube);
  EXPECT_GT(inverted, 0);
  EXPECT_LT(inverted, el.n_tets() / 2);
  // A non-finite deformation gradient (finite u that overflows) throws.
  std::vector<Eigen::Matrix3d> R;
  Eigen::VectorXd huge = tube.u;
  huge[3 * el.tets()(el.n_tets() / 2, 1)] = 1e308;
  EXPECT_THROW(el.rotations(huge, R), std::invalid_argument);
}

// The same where the kernels' last batch of tets is only partly full (the rotations' and the element lanes').
TEST(CorotationalKernels, APartlyFullLastBatchMatchesTheSerialTwin) {
  const InvertingTube tube(small_tube(9, 5, 1, 0.06));
  ASSERT_NE(tube.el.n_tets() % detail::kPolarLanes, 0);
  ASSERT_NE(tube.el.n_tets() % detail::kElementLanes, 0);
  expect_kernels_match_twin(tube);
}

TEST(CorotationalSolve, ContinuesThroughInvertedElementsWithoutNaN) {
  const TetMesh m = small_tube(8, 4, 1, 0.04);
  // An inner node in the middle and the outer node beside it are prescribed to swap places (and pass each
  // other by half the wall thickness), inverting the tets between them.
  std::vector<int> fixed = both_ends(m);
  const int inner_node = m.surface(kInnerWall)(m.surface(kInnerWall).rows() / 2, 0);
  int outer_node = -1;
  for (int v = 0; v < m.n_nodes(); ++v) {
    const Eigen::Vector3d d = m.rest.row(v) - m.rest.row(inner_node);
    const Eigen::Vector3d radial(m.rest(inner_node, 0), m.rest(inner_node, 1), 0.0);
    if (std::abs(d.z()) < 1e-12 && d.norm() > 1e-4 && d.cross(radial).norm() < 1e-12) {
      outer_node = v;
    }
  }
  ASSERT_GE(outer_node, 0);
  fixed.push_back(inner_node);
  fixed.push_back(outer_node);
  const CorotationalModel model(m, kTissue, fixed);
  const int n = model.n_dofs();
  Eigen::VectorXd u_fixed = Eigen::VectorXd::Zero(n);
  const Eigen::Vector3d across = m.rest.row(outer_node) - m.rest.row(inner_node);
  u_fixed.segment<3>(3 * inner_node) = 1.5 * across;
  u_fixed.segment<3>(3 * outer_node) = -1.5 * across;
  CorotationalState state;
  CorotationalOptions opt;
  opt.max_iterations = 8;
  const CorotationalResult r = solve_corotational(model, Eigen::VectorXd::Zero(n), state, opt, u_fixed);
  std::printf("through-wall probe: %d inverted, residual %.2g, converged %d\n", r.n_inverted, r.residual, r.converged);
  EXPECT_GT(r.n_inverted, 0);
  EXPECT_TRUE(state.u.allFinite());
  EXPECT_TRUE(std::isfinite(r.residual));
  std::vector<Eigen::Matrix3d> R;
  EXPECT_EQ(model.elements().rotations(state.u, R), r.n_inverted);
}

// A lagged factorisation preconditions turned by each node's rotation since it was factorised (R_now R_then^T).
// Truth by symmetry: the whole twisted tube turned rigidly by Q about an axis across the tube's (so Q does not
// commute with the twist's rotations) is again at equilibrium, its elements turned by Q, its warped stiffness
// Q K_w Q^T. So K_w factorised at the unturned state and turned by Q is exact there: each linear step converges
// at its first back-substitution (cg_tolerance 0.1, float factor). Unturned, the same factor needs several, and
// both reach Q's image of the unturned equilibrium.
TEST(CorotationalSolve, ALaggedFactorTurnsWithTheNodesSinceItWasFactorised) {
  const TetMesh m = small_tube(12, 10, 1, 0.15);
  const CorotationalModel model(m, kTissue, both_ends(m));
  const CorotationalElements& el = model.elements();
  const int n = model.n_dofs();
  const Eigen::VectorXd no_load = Eigen::VectorXd::Zero(n);
  const Eigen::VectorXd X = Eigen::Map<const Eigen::VectorXd>(Eigen::MatrixXd(m.rest.transpose()).data(), n);
  // Equilibria of the end turned by 60 and 50 degrees.
  CorotationalOptions tight;
  tight.tolerance = 1e-10, tight.max_iterations = 200, tight.rotate_preconditioner = true;
  CorotationalState at60, at50;
  ASSERT_TRUE(solve_corotational(model, no_load, at60, tight, end_twist(m, EIGEN_PI / 3)).converged);
  ASSERT_TRUE(solve_corotational(model, no_load, at50, tight, end_twist(m, 5 * EIGEN_PI / 18)).converged);
  // The 60-degree state's warped stiffness factorised, and its nodes' rotations.
  std::vector<Eigen::Matrix3d> R60, node_R60;
  el.rotations(at60.u, R60);
  el.node_rotations(R60, node_R60);
  const auto lagged = std::make_shared<const StaticSolver>(model.solver().refactorised(el.warped_stiffness(R60)));
  // Turned by Q: the equilibrium (the ends prescribed there) and a start off it (the turned 50-degree state).
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1.0, 0.3, 0.0).normalized()).toRotationMatrix();
  auto turned = [&](const Eigen::VectorXd& u) {
    Eigen::VectorXd v(n);
    for (int i = 0; i < n / 3; ++i) v.segment<3>(3 * i) = Q * (X + u).segment<3>(3 * i) - X.segment<3>(3 * i);
    return v;
  };
  const Eigen::VectorXd u_truth = turned(at60.u);
  int back_substitutions[2] = {0, 0}, steps[2] = {0, 0};
  for (int rotate = 0; rotate < 2; ++rotate) {
    CorotationalState s;
    s.u = turned(at50.u);
    s.preconditioner = lagged;
    s.preconditioner_node_rotations = node_R60;
    CorotationalOptions opt;
    opt.tolerance = 1e-9, opt.max_iterations = 200, opt.rotate_preconditioner = rotate == 1;
    opt.refactor_cg_iterations = 0;  // this factor throughout
    const CorotationalResult r = solve_corotational(model, no_load, s, opt, u_truth);
    ASSERT_TRUE(r.converged) << "rotate " << rotate << " residual " << r.residual;
    EXPECT_EQ(r.refactorisations, 0);
    EXPECT_LE((s.u - u_truth).norm(), 1e-6 * (u_truth - turned(Eigen::VectorXd::Zero(n))).norm()) << "rotate " << rotate;
    back_substitutions[rotate] = r.cg_iterations, steps[rotate] = r.iterations;
  }
  std::printf("turned lagged factor: %d back-substitutions in %d steps; unturned: %d in %d\n", back_substitutions[1],
              steps[1], back_substitutions[0], steps[0]);
  // (Each step converges at its first or second back-substitution turned: 12 in 10 steps when written; unturned
  // 277 in 11.)
  EXPECT_LE(back_substitutions[1], 2 * steps[1]);
  EXPECT_GE(back_substitutions[0], 10 * steps[0]);
}

TEST(CorotationalSolve, WarmStartAtEquilibriumCostsNoIteration) {
  const TetMesh m = small_tube();
  const CorotationalModel model(m, kTissue, m.node_set(kStartEnd));
  const Eigen::VectorXd f = tip_load(m, 0.005);
  CorotationalState state;
  const CorotationalResult first = solve_corotational(model, f, state);
  ASSERT_TRUE(first.converged);
  EXPECT_GE(first.iterations, 1);
  const Eigen::VectorXd u = state.u;
  const CorotationalResult again = solve_corotational(model, f, state);
  EXPECT_TRUE(again.converged);
  EXPECT_EQ(again.iterations, 0);
  EXPECT_EQ(state.u, u);
  EXPECT_NEAR(again.residual, first.residual, 1e-15);
  // Rotated preconditioner reaches the same equilibrium.
  CorotationalState rotated;
  CorotationalOptions opt;
  opt.rotate_preconditioner = true;
  opt.tolerance = 1e-10;
  ASSERT_TRUE(solve_corotational(model, f, rotated, opt).converged);
  opt.rotate_preconditioner = false;
  ASSERT_TRUE(solve_corotational(model, f, state, opt).converged);
  EXPECT_LE((rotated.u - state.u).norm(), 1e-8 * state.u.norm());
  // No load: back to the rest state exactly.
  const CorotationalResult rest = solve_corotational(model, Eigen::VectorXd::Zero(model.n_dofs()), state);
  EXPECT_TRUE(rest.converged);
  EXPECT_EQ(state.u.norm(), 0.0);
}

// The work bound (max_back_substitutions): each solve of a 90-degree twist stops within its bound, unconverged at
// first, and the solves that follow, each going on from the last one's iterate, reach the unbounded solve's
// equilibrium; also with Newton steps on the exact tangent (two linear steps in an iteration whose Newton step
// the line search refuses).
TEST(CorotationalSolve, WorkBoundStopsEachSolveAndTheNextOnesReachTheSameEquilibrium) {
  const TetMesh m = small_tube(8, 6, 1, 0.09);
  const CorotationalModel model(m, kTissue, both_ends(m));
  const Eigen::VectorXd no_load = Eigen::VectorXd::Zero(model.n_dofs());
  const Eigen::VectorXd twist = end_twist(m, EIGEN_PI / 2);
  for (const CorotationalTangent tangent : {CorotationalTangent::warped, CorotationalTangent::exact}) {
    const char* name = tangent == CorotationalTangent::exact ? "exact" : "warped";
    CorotationalOptions opt;
    opt.tolerance = 1e-7;
    opt.max_iterations = 500;
    opt.refactor_cg_iterations = 5;
    opt.tangent = tangent;
    CorotationalState unbounded;
    ASSERT_TRUE(solve_corotational(model, no_load, unbounded, opt, twist).converged) << name;
    const double scale = unbounded.u.cwiseAbs().maxCoeff();
    opt.max_back_substitutions = 4;
    CorotationalState state;
    int solves = 0;
    bool converged = false;
    for (; solves < 100 && !converged; ++solves) {
      const CorotationalResult r = solve_corotational(model, no_load, state, opt, twist);
      EXPECT_LE(r.cg_iterations, 4) << name << " solve " << solves;
      // (A warped solve stops only once it cannot step.)
      if (tangent == CorotationalTangent::warped) {
        EXPECT_GE(r.cg_iterations, r.converged ? 0 : 3) << "solve " << solves;
      }
      if (solves == 0) {
        EXPECT_FALSE(r.converged) << name;
      }
      converged = r.converged;
    }
    ASSERT_TRUE(converged) << name;
    EXPECT_LT((state.u - unbounded.u).cwiseAbs().maxCoeff(), 1e-4 * scale) << name;
    // Without the refresh of a step the bound cut short, the rest factorisation stays: about 400 warped solves.
    EXPECT_LT(solves, 40) << name;
    std::printf("90-degree twist, %s tangent, at most 4 back-substitutions a solve: converged after %d solves\n",
                name, solves);
  }
}

TEST(CorotationalSolve, RejectsInvalidInput) {
  const TetMesh m = small_tube(6, 2, 1);
  const CorotationalModel model(m, kTissue, both_ends(m));
  const Eigen::VectorXd f = Eigen::VectorXd::Zero(model.n_dofs());
  CorotationalState state;
  auto message = [&](const CorotationalOptions& o, const Eigen::VectorXd& load, const Eigen::VectorXd& u_fixed) {
    try {
      solve_corotational(model, load, state, o, u_fixed);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  CorotationalOptions o;
  o.tolerance = 0.0;
  EXPECT_NE(message(o, f, {}).find("tolerance"), std::string::npos);
  o = {};
  o.max_iterations = 0;
  EXPECT_NE(message(o, f, {}).find("max_iterations"), std::string::npos);
  o = {};
  o.cg_tolerance = 1.0;
  EXPECT_NE(message(o, f, {}).find("cg_tolerance"), std::string::npos);
  o = {};
  o.max_cg_iterations = 0;
  EXPECT_NE(message(o, f, {}).find("max_cg_iterations"), std::string::npos);
  o = {};
  o.max_back_substitutions = 1;
  EXPECT_NE(message(o, f, {}).find("max_back_substitutions"), std::string::npos);
  o = {};
  o.max_back_substitutions = 8;
  o.method = CorotationalMethod::chord;
  EXPECT_NE(message(o, f, {}).find("max_back_substitutions"), std::string::npos);
  EXPECT_NE(message({}, Eigen::VectorXd::Zero(5), {}).find("f_ext.size()"), std::string::npos);
  Eigen::VectorXd bad = f;
  bad[7] = NAN;
  EXPECT_NE(message({}, bad, {}).find("f_ext[7]"), std::string::npos);
  EXPECT_NE(message({}, f, bad).find("u_fixed[7]"), std::string::npos);
  EXPECT_THROW(CorotationalModel(m, LinearMaterial{-1.0, 0.3}, both_ends(m)), std::invalid_argument);
}

// Elastic supports are part of every kernel: against the same elements without them, at a deformed state, the
// forces differ by S u, the products by S p, the stiffness by diag(S), the energy by u^T S u / 2 (exactly, up to
// round-off; the energy the forces' loop sums is elastic_energy's); a negative spring is refused by name.
TEST(CorotationalSupport, EveryKernelGainsTheSpringsExactly) {
  const TetMesh mesh = small_tube();
  const int n = 3 * mesh.n_nodes();
  Eigen::VectorXd S(n), u(n), p(n);
  for (int d = 0; d < n; ++d) {
    S[d] = d % 7 == 0 ? 0.0 : 10.0 + d % 5;
    u[d] = 1e-3 * std::sin(0.7 * d);
    p[d] = std::cos(1.3 * d);
  }
  const CorotationalElements bare(mesh, kTissue), held(mesh, kTissue, S);
  std::vector<Eigen::Matrix3d> R;
  bare.rotations(u, R);
  Eigen::VectorXd f0, f1, y0, y1;
  double summed = 0.0;  // (the energy summed in the forces' loop, against elastic_energy's own below)
  bare.elastic_forces(u, R, f0);
  held.elastic_forces(u, R, f1, &summed);
  EXPECT_LE((f1 - f0 - S.cwiseProduct(u)).norm(), 1e-12 * f1.norm());
  EXPECT_NEAR(summed, held.elastic_energy(u, R), 1e-12 * held.elastic_energy(u, R));
  bare.warped_product(R, p, y0);
  held.warped_product(R, p, y1);
  EXPECT_LE((y1 - y0 - S.cwiseProduct(p)).norm(), 1e-12 * y1.norm());
  const Eigen::MatrixXd K0 = Eigen::MatrixXd(bare.warped_stiffness(R)), K1 = Eigen::MatrixXd(held.warped_stiffness(R));
  EXPECT_LE((K1 - K0 - Eigen::MatrixXd(S.asDiagonal())).norm(), 1e-12 * K1.norm());
  EXPECT_NEAR(held.elastic_energy(u, R) - bare.elastic_energy(u, R), 0.5 * S.dot(u.cwiseProduct(u)),
              1e-12 * held.elastic_energy(u, R));
  Eigen::VectorXd negative = S;
  negative[4] = -1.0;
  try {
    CorotationalElements(mesh, kTissue, negative);
    FAIL() << "a negative spring was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("support[4]"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace lumen::physics
