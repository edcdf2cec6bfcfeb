// Implicit dynamics against independent truths: the polygonal tube volume (lumped mass), the backward Euler
// recurrence of a single vibration mode (dense generalised eigenproblem), the static solution (StaticSolver),
// energy decay, and the quasi-static corotational equilibrium.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "physics/corotational.hpp"
#include "physics/dynamics.hpp"
#include "physics/fem.hpp"
#include "physics/mesh.hpp"
#include "support/fem.hpp"

namespace lumen::physics {
namespace {

using lumen::test::kTissue;

using lumen::test::both_ends;
using lumen::test::small_tube;

// A transverse load spread over the nodes of the ring nearest to the middle of the tube, newtons (3n).
Eigen::VectorXd side_load(const TetMesh& m, double total) {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * m.n_nodes());
  const double mid = 0.5 * m.rest.col(2).maxCoeff();
  const double nearest = (m.rest.col(2).array() - mid).abs().minCoeff();
  std::vector<int> nodes;
  for (int v = 0; v < m.n_nodes(); ++v)
    if (std::abs(std::abs(m.rest(v, 2) - mid) - nearest) < 1e-9) nodes.push_back(v);
  for (int v : nodes) f[3 * v + 1] = -total / nodes.size();
  return f;
}

// Total energy with a constant load: kinetic + elastic - f . u, joules.
double total_energy(const DynamicModel& model, const DynamicState& s, const Eigen::VectorXd& f) {
  return kinetic_energy(model, s) + elastic_energy(model, s.u) - f.dot(s.u);
}

TEST(DynamicModel, LumpedMassTotalsThePolygonalTubeVolume) {
  const HollowCylinderSpec spec = lumen::test::small_tube_spec(10, 3, 2, 0.03);
  const TetMesh m = make_hollow_cylinder(spec);
  DynamicParams p;
  p.density = 1040.0;
  const DynamicModel model(m, kTissue, both_ends(m), p);
  // Every cross-section is the annulus between two regular N-gons: area N/2 sin(2 pi/N) (b^2 - a^2).
  const int N = spec.segments_around;
  const double area = 0.5 * N * std::sin(2 * EIGEN_PI / N) *
                      (spec.outer_radius * spec.outer_radius - spec.inner_radius * spec.inner_radius);
  const double expected = p.density * area * spec.length;
  const Eigen::VectorXd& M = model.mass();
  EXPECT_NEAR(M.sum() / 3.0, expected, 1e-12 * expected);
  for (int v = 0; v < m.n_nodes(); ++v) {
    EXPECT_GT(M[3 * v], 0.0);
    EXPECT_EQ(M[3 * v], M[3 * v + 1]);
    EXPECT_EQ(M[3 * v], M[3 * v + 2]);
  }
}

// Free vibration from one mode shape stays in that mode; its amplitude follows the 2 x 2 backward Euler
// recurrence (1 + h c + h^2 w^2) b1 = b0 - h w^2 a0, a1 = a0 + h b1 with c = alpha + beta w^2.
TEST(DynamicStep, SingleModeFollowsTheBackwardEulerRecurrence) {
  const TetMesh m = small_tube(6, 3, 1, 0.03);
  DynamicParams p;
  p.alpha = 0.5, p.beta = 1e-3, p.time_step = 0.01;
  const DynamicModel model(m, kTissue, both_ends(m), p);
  const int n = model.n_dofs();
  // Dense generalised eigenproblem K_ff phi = w^2 M_ff phi; the lowest mode.
  std::vector<int> free;
  for (int d = 0; d < n; ++d)
    if (!model.is_fixed_dof(d)) free.push_back(d);
  const Eigen::MatrixXd Kd(model.stiffness());
  Eigen::MatrixXd Kf(free.size(), free.size()), Mf = Eigen::MatrixXd::Zero(free.size(), free.size());
  for (size_t i = 0; i < free.size(); ++i) {
    Mf(i, i) = model.mass()[free[i]];
    for (size_t j = 0; j < free.size(); ++j) Kf(i, j) = Kd(free[i], free[j]);
  }
  const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> eig(Kf, Mf);
  ASSERT_EQ(eig.info(), Eigen::Success);
  const double w2 = eig.eigenvalues()[0];
  Eigen::VectorXd phi = Eigen::VectorXd::Zero(n);
  for (size_t i = 0; i < free.size(); ++i) phi[free[i]] = eig.eigenvectors()(i, 0);
  phi *= 1e-3 / phi.cwiseAbs().maxCoeff();  // 1 mm peak
  std::printf("lowest mode: %.1f rad/s, h w = %.2f\n", std::sqrt(w2), p.time_step * std::sqrt(w2));

  const Eigen::VectorXd no_load = Eigen::VectorXd::Zero(n);
  CorotationalOptions opt;
  opt.tolerance = 1e-10;
  for (const double h : {p.time_step, 0.7 * p.time_step}) {  // direct solve, and PCG at another step
    DynamicState s;
    s.u = phi;
    double a = 1.0, b = 0.0;
    const double c = p.alpha + p.beta * w2;
    for (int k = 0; k < 40; ++k) {
      const StepResult r = step(model, s, no_load, h, opt);
      ASSERT_TRUE(r.converged) << "h " << h << " step " << k;
      b = (b - h * w2 * a) / (1.0 + h * c + h * h * w2);
      a = a + h * b;
      ASSERT_LE((s.u - a * phi).norm(), 1e-7 * phi.norm()) << "h " << h << " step " << k;
      ASSERT_LE((s.v - b * phi).norm(), 1e-7 * std::sqrt(w2) * phi.norm()) << "h " << h << " step " << k;
    }
    EXPECT_LT(std::abs(a), 0.5);  // decayed
  }
}

TEST(DynamicStep, StepLoadSettlesToStaticSolutionWithDecayingEnergy) {
  const TetMesh m = small_tube(8, 4, 1, 0.04);
  const std::vector<int> fixed = both_ends(m);
  DynamicParams p;
  p.alpha = 5.0, p.beta = 2e-3, p.time_step = 0.01;
  const DynamicModel model(m, kTissue, fixed, p);
  const Eigen::VectorXd f = side_load(m, 0.01);
  const StaticSolver statics(model.stiffness(), fixed);
  Eigen::VectorXd u_static;
  statics.solve(f, u_static);
  DynamicState s;
  double energy = 0.0, max_u = 0.0;
  int k = 0;
  for (; k < 3000 && (s.u.size() == 0 || (s.u - u_static).norm() > 1e-8 * u_static.norm()); ++k) {
    const StepResult r = step(model, s, f, p.time_step);
    ASSERT_TRUE(r.converged);
    const double e = total_energy(model, s, f);
    ASSERT_LE(e, energy + 1e-12 * std::abs(energy)) << "step " << k;
    energy = e;
    max_u = std::max(max_u, s.u.cwiseAbs().maxCoeff());
  }
  std::printf("step load: settled in %d steps, overshoot %.1f%%\n", k,
              100 * (max_u / u_static.cwiseAbs().maxCoeff() - 1));
  EXPECT_LE((s.u - u_static).norm(), 1e-8 * u_static.norm());
  EXPECT_GT(max_u, 1.05 * u_static.cwiseAbs().maxCoeff());  // it did vibrate (overshoot)
  EXPECT_NEAR(energy, -0.5 * f.dot(u_static), 1e-6 * f.dot(u_static));
}

TEST(DynamicStep, UndampedBackwardEulerIsDissipativeAndStableForLargeSteps) {
  const TetMesh m = small_tube(8, 4, 1, 0.04);
  const std::vector<int> fixed = both_ends(m);
  const Eigen::VectorXd f = side_load(m, 0.01);
  Eigen::VectorXd u_static;
  StaticSolver(assemble_stiffness(m, kTissue), fixed).solve(f, u_static);
  for (const double h : {1e-3, 0.1, 10.0}) {
    DynamicParams p;
    p.time_step = h;
    const DynamicModel model(m, kTissue, fixed, p);
    DynamicState s;
    double energy = 0.0, first = 0.0;
    for (int k = 0; k < 60; ++k) {
      step(model, s, f, h);
      ASSERT_TRUE(s.u.allFinite() && s.v.allFinite());
      const double e = total_energy(model, s, f);
      ASSERT_LE(e, energy + 1e-12 * std::abs(energy)) << "h " << h << " step " << k;
      if (k == 0) first = e;
      energy = e;
    }
    EXPECT_LT(energy, first);  // strictly dissipative without damping
    if (h == 10.0) {  // huge steps: the static answer
      EXPECT_LE((s.u - u_static).norm(), 1e-6 * u_static.norm());
    }
  }
}

TEST(DynamicStep, CorotationalSettlesToTheQuasiStaticCorotationalSolution) {
  const TetMesh m = small_tube(6, 3, 1, 0.03);
  DynamicParams p;
  p.elastic = ElasticModel::kCorotational;
  p.alpha = 10.0, p.beta = 5e-3, p.time_step = 0.05;
  const DynamicModel model(m, kTissue, m.node_set(kStartEnd), p);
  // Cantilever with a large tip load: in the nonlinear range.
  Eigen::VectorXd f = Eigen::VectorXd::Zero(model.n_dofs());
  for (int v : m.node_set(kStopEnd)) f[3 * v + 1] = -0.015 / m.node_set(kStopEnd).size();
  CorotationalOptions opt;
  opt.tolerance = 1e-9;
  opt.max_iterations = 100;
  const CorotationalModel statics(m, kTissue, m.node_set(kStartEnd));
  CorotationalState qs;
  ASSERT_TRUE(solve_corotational(statics, f, qs, opt).converged);
  Eigen::VectorXd u_lin;
  statics.solver().solve(f, u_lin);
  DynamicState s;
  int k = 0, outer = 0, cg = 0;
  for (; k < 1500 && (s.u.size() == 0 || (s.u - qs.u).norm() > 1e-6 * qs.u.norm()); ++k) {
    const StepResult r = step(model, s, f, p.time_step, opt);
    ASSERT_TRUE(r.converged) << "step " << k << " residual " << r.residual;
    ASSERT_EQ(r.n_inverted, 0);
    outer += r.iterations, cg += r.cg_iterations;
  }
  std::printf("corotational dynamics settled in %d steps (%d outer, %d CG); linear differs by %.1f%%\n", k, outer, cg,
              100 * (u_lin - qs.u).norm() / qs.u.norm());
  EXPECT_LE((s.u - qs.u).norm(), 1e-6 * qs.u.norm());
  EXPECT_GT((u_lin - qs.u).norm(), 0.02 * qs.u.norm());  // the load is in the nonlinear range
}

TEST(DynamicStep, CorotationalMatchesLinearForTinyLoads) {
  const TetMesh m = small_tube(6, 2, 1, 0.02);
  DynamicParams p;
  p.alpha = 1.0, p.time_step = 0.01;
  const DynamicModel linear(m, kTissue, both_ends(m), p);
  p.elastic = ElasticModel::kCorotational;
  const DynamicModel corot(m, kTissue, both_ends(m), p);
  CorotationalOptions opt;
  opt.tolerance = 1e-8;  // the strain of a 1e-5 N load is ~1e-6: round-off in R^T F - I limits the residual
  for (const double load : {1e-4, 1e-5}) {
    const Eigen::VectorXd f = side_load(m, load);
    DynamicState a, b;
    double worst = 0.0;
    for (int k = 0; k < 10; ++k) {
      step(linear, a, f, p.time_step);
      ASSERT_TRUE(step(corot, b, f, p.time_step, opt).converged);
      worst = std::max(worst, (a.u - b.u).norm() / a.u.norm());
    }
    std::printf("load %g N: corotational vs linear trajectory, max relative difference %.2g\n", load, worst);
    EXPECT_LT(worst, load * 10.0);  // vanishes linearly with the load (measured ~ load x 1)
  }
}

TEST(DynamicStep, RejectsInvalidInput) {
  const TetMesh m = small_tube(6, 2, 1, 0.02);
  auto message = [&](const DynamicParams& p) {
    try {
      DynamicModel model(m, kTissue, both_ends(m), p);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  DynamicParams p;
  p.density = 0.0;
  EXPECT_NE(message(p).find("density"), std::string::npos);
  p = {};
  p.alpha = -1.0;
  EXPECT_NE(message(p).find("alpha"), std::string::npos);
  p = {};
  p.beta = NAN;
  EXPECT_NE(message(p).find("beta"), std::string::npos);
  p = {};
  p.time_step = 0.0;
  EXPECT_NE(message(p).find("time_step"), std::string::npos);
  const DynamicModel model(m, kTissue, both_ends(m), DynamicParams{});
  DynamicState s;
  const Eigen::VectorXd f = Eigen::VectorXd::Zero(model.n_dofs());
  EXPECT_THROW(step(model, s, f, -0.01), std::invalid_argument);
  EXPECT_THROW(step(model, s, Eigen::VectorXd::Zero(4), 0.01), std::invalid_argument);
  s.v = Eigen::VectorXd::Constant(model.n_dofs(), INFINITY);
  EXPECT_THROW(step(model, s, f, 0.01), std::invalid_argument);
}

}  // namespace
}  // namespace lumen::physics
