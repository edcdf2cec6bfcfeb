// SurfaceCompliance blocks and displacements against direct solves and the dense twin.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "physics/surface_compliance.hpp"
#include "compliance_model.hpp"
#include "support/files.hpp"

namespace lumen::physics {
namespace {

TEST(SurfaceCompliance, BlocksEqualDirectSolves) {
  const Model& m = model();
  SurfaceCompliance sc(*m.solver, m.inner, 7);  // 7 columns per block: exercises a partial last block
  const int s = static_cast<int>(m.inner.size());
  ASSERT_EQ(sc.matrix().rows(), 3 * s);
  for (int a = 0; a < s; ++a)
    for (int b = 0; b < s; ++b)
      ASSERT_LE((sc.matrix().block<3, 3>(3 * a, 3 * b) - m.Kinv.block<3, 3>(3 * m.inner[a], 3 * m.inner[b])).norm(),
                1e-9 * m.Kinv.norm() / m.n());
  EXPECT_LE((sc.matrix() - sc.matrix().transpose()).norm(), 1e-12 * sc.matrix().norm());
  // Any pair of mesh nodes, inside or outside the set; outside columns are computed once and cached.
  const int in = m.inner[13], out1 = m.outer_free[2], out2 = m.outer_free[9];
  EXPECT_EQ(sc.index_of(in), 13);
  EXPECT_EQ(sc.index_of(out1), -1);
  const std::pair<int, int> pairs[] = {{in, in}, {in, out1}, {out1, in}, {out1, out2}, {out2, out2}, {in, out2}};
  for (const auto& [a, b] : pairs) {
    const Eigen::Matrix3d blk = sc.block(a, b), twin = m.Kinv.block(3 * a, 3 * b, 3, 3);
    EXPECT_LE((blk - twin).norm(), 1e-9 * twin.norm() + 1e-15);
  }
  EXPECT_EQ(sc.n_cached_nodes(), 2);
  EXPECT_THROW(SurfaceCompliance(*m.solver, {1, 2, 1}), std::invalid_argument);
  EXPECT_THROW(SurfaceCompliance(*m.solver, {-1}), std::invalid_argument);
  EXPECT_THROW(SurfaceCompliance(*m.solver, {1}, 0), std::invalid_argument);
  EXPECT_THROW(sc.block(0, m.n()), std::invalid_argument);
}

// A set whose matrix is over its byte budget (here 0) keeps its columns per node, solved on first use: blocks,
// set-only displacements and contact-row couplings equal the dense twin K^-1 and the eager compliance's.
TEST(SurfaceCompliance, LazySetColumnsEqualTheEagerOnes) {
  const Model& m = model();
  SurfaceCompliance eager(*m.solver, m.inner), lazy(*m.solver, m.inner, 64, 256L << 20, 0);
  EXPECT_FALSE(eager.lazy());
  ASSERT_TRUE(lazy.lazy());
  EXPECT_EQ(lazy.n_set_columns(), 0);
  EXPECT_THROW(lazy.matrix(), std::logic_error);
  const int s = static_cast<int>(m.inner.size());
  // Blocks between set nodes (and one outside node): only the columns asked for are solved.
  const int a = m.inner[3], b = m.inner[s - 2], out = m.outer_free[4];
  const std::pair<int, int> pairs[] = {{a, b}, {b, a}, {a, a}, {a, out}, {out, b}};
  for (const auto& [p, q] : pairs) {
    const Eigen::Matrix3d twin = m.Kinv.block(3 * p, 3 * q, 3, 3);
    EXPECT_LE((lazy.block(p, q) - twin).norm(), 1e-9 * twin.norm() + 1e-15);
    EXPECT_LE((lazy.block(p, q) - eager.block(p, q)).norm(), 1e-12 * twin.norm() + 1e-18);
  }
  EXPECT_LE(lazy.n_set_columns(), 2);
  // Set-only displacements of forces on a few set nodes and one outside node.
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * m.n());
  f.segment<3>(3 * m.inner[5]) << 0.01, -0.02, 0.005;
  f.segment<3>(3 * m.inner[9]) << -0.004, 0.01, 0.0;
  f.segment<3>(3 * out) << 0.0, 0.003, -0.002;
  Eigen::VectorXd du_lazy, du_eager;
  lazy.displacement_on_set(f, du_lazy, {m.outer_free[1]});
  eager.displacement_on_set(f, du_eager, {m.outer_free[1]});
  const Eigen::VectorXd twin = m.Kinv * f;
  EXPECT_LE((du_lazy - du_eager).norm(), 1e-12 * twin.norm());
  for (int v : m.inner) EXPECT_LE((du_lazy.segment<3>(3 * v) - twin.segment<3>(3 * v)).norm(), 1e-9 * twin.norm());
  // The whole mesh for the same forces (the set-only solve reused), for forces changed on a node whose columns are
  // cached (`out`: added to it), and changed on one whose columns are not (a solve): each the dense twin's.
  Eigen::VectorXd du;
  lazy.displacement(f, du);
  EXPECT_LE((du - twin).norm(), 1e-9 * twin.norm());
  Eigen::VectorXd f2 = f;
  f2.segment<3>(3 * out) << 0.002, -0.001, 0.004;
  lazy.displacement(f2, du);
  EXPECT_LE((du - m.Kinv * f2).norm(), 1e-9 * twin.norm());
  f2.segment<3>(3 * m.outer_free[7]) << -0.003, 0.0, 0.001;
  lazy.displacement(f2, du);
  EXPECT_LE((du - m.Kinv * f2).norm(), 1e-9 * twin.norm());
  EXPECT_EQ(lazy.n_cached_nodes(), 1);  // (out: the listed outer node and the last change came from solves)
}

// A lazy set's split solve: a node's displacement read from the forward half, and a force added to it, against the
// dense twin K^-1 (f + g); half columns solved on first use (half_entries 0 before); refused on an eager set, for a
// node outside the set and for a forward half of another size.
TEST(SurfaceCompliance, SplitSolveReadsAndLoadsSetNodesAsTheDenseTwin) {
  const Model& m = model();
  SurfaceCompliance eager(*m.solver, m.inner), lazy(*m.solver, m.inner, 64, 256L << 20, 0);
  ASSERT_TRUE(lazy.lazy());
  const int a = m.inner[m.inner.size() / 3], b = m.inner[m.inner.size() / 2];  // (free: mid-tube)
  EXPECT_EQ(lazy.half_entries(a), 0);
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * m.n()), g = Eigen::VectorXd::Zero(3 * m.n());
  f.segment<3>(3 * m.outer_free[3]) << 0.01, -0.02, 0.004;
  g.segment<3>(3 * b) << -0.003, 0.006, 0.001;
  std::vector<double> z;
  m.solver->half_forward(f, z);
  const Eigen::VectorXd u_f = m.Kinv * f, u_fg = m.Kinv * (f + g);
  for (int v : {a, b})
    EXPECT_LE((lazy.half_displacement(v, z) - u_f.segment<3>(3 * v)).norm(), 1e-9 * u_f.norm()) << "node " << v;
  EXPECT_GT(lazy.half_entries(a), 0);
  lazy.add_half_force(b, g.segment<3>(3 * b), z);
  Eigen::VectorXd u;
  m.solver->half_backward(z, u);
  EXPECT_LE((u - u_fg).norm(), 1e-9 * u_fg.norm());
  EXPECT_THROW(eager.half_displacement(a, z), std::logic_error);
  EXPECT_EQ(lumen::test::message_of<std::invalid_argument>([&] { lazy.half_displacement(m.outer_free[0], z); }),
            "SurfaceCompliance::half_displacement: node " + std::to_string(m.outer_free[0]) + " is not in the set");
  std::vector<double> short_z(5);
  EXPECT_EQ(lumen::test::message_of<std::invalid_argument>([&] { lazy.add_half_force(a, g.segment<3>(0), short_z); }),
            "SurfaceCompliance::add_half_force: z must have " + std::to_string(m.solver->n_free_dofs()) +
                " entries (the free DOFs), got 5");
}

// Whole-mesh and set-only displacements for sparse nodal forces equal the dense twin K^-1 f, with the
// whole-mesh columns kept and without them (a back-substitution).
TEST(SurfaceCompliance, DisplacementsEqualDenseTwin) {
  const Model& m = model();
  SurfaceCompliance kept(*m.solver, m.inner), lean(*m.solver, m.inner, 64, 0);
  EXPECT_TRUE(kept.keeps_mesh_columns());
  EXPECT_FALSE(lean.keeps_mesh_columns());
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> force(-0.02, 0.02);
  for (int trial = 0; trial < 6; ++trial) {
    // Forces on a few inner nodes, and in odd trials on an outer node too.
    Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * m.n());
    for (int k = 0; k < 2 + trial; ++k)
      for (int c = 0; c < 3; ++c) f[3 * m.inner[(7 * k + trial) % m.inner.size()] + c] = force(rng);
    const int outer = m.outer_free[trial];
    if (trial % 2) f.segment<3>(3 * outer) << force(rng), force(rng), force(rng);
    const Eigen::VectorXd twin = m.Kinv * f;
    for (SurfaceCompliance* sc : {&kept, &lean}) {
      Eigen::VectorXd du;
      sc->displacement(f, du);
      EXPECT_LE((du - twin).norm(), 1e-9 * twin.norm()) << "trial " << trial;
      // Set-only: exact on the set and the listed node, zero elsewhere.
      const int listed = m.outer_free[trial + 1];
      sc->displacement_on_set(f, du, {listed});
      std::vector<char> defined(m.n(), 0);
      for (int v : m.inner) defined[v] = 1;
      defined[listed] = 1;
      for (int v = 0; v < m.n(); ++v) {
        const Eigen::Vector3d expected = defined[v] ? Eigen::Vector3d(twin.segment<3>(3 * v)) : Eigen::Vector3d::Zero();
        EXPECT_LE((du.segment<3>(3 * v) - expected).norm(), 1e-9 * twin.norm()) << "trial " << trial << " node " << v;
      }
    }
  }
  Eigen::VectorXd du;
  EXPECT_THROW(kept.displacement(Eigen::VectorXd::Zero(5), du), std::invalid_argument);
  EXPECT_THROW(kept.displacement_on_set(Eigen::VectorXd::Zero(3 * m.n()), du, {m.n()}), std::invalid_argument);
  EXPECT_THROW(SurfaceCompliance(*m.solver, m.inner, 64, -1), std::invalid_argument);
}

// The view rows: the response on the set and the view nodes equals the dense twin K^-1 f there and is 0 elsewhere,
// for loads on set nodes and on an outside node; the rows are kept only without the whole-mesh columns and within
// their budget; needs_solve says what displacement() does.
TEST(SurfaceCompliance, ViewRowsEqualDenseTwin) {
  const Model& m = model();
  // View: half of the outer free nodes, one inner node (in the set: ignored) and a repeat.
  std::vector<int> view(m.outer_free.begin(), m.outer_free.begin() + m.outer_free.size() / 2);
  view.push_back(m.inner[3]);
  view.push_back(view.front());
  SurfaceCompliance sc(*m.solver, m.inner, 5, 0, 1L << 30, view);
  ASSERT_TRUE(sc.keeps_view_rows());
  EXPECT_EQ(sc.view_nodes().size(), m.outer_free.size() / 2);
  std::vector<char> defined(m.n(), 0);
  for (int v : m.inner) defined[v] = 1;
  for (int v : sc.view_nodes()) defined[v] = 1;
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> force(-0.02, 0.02);
  for (int trial = 0; trial < 4; ++trial) {
    Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * m.n());
    for (int k = 0; k < 3 + trial; ++k)
      for (int c = 0; c < 3; ++c) f[3 * m.inner[(11 * k + trial) % m.inner.size()] + c] = force(rng);
    // An outside load (not in the view): its whole-mesh columns are solved for on first use.
    if (trial % 2) f.segment<3>(3 * m.outer_free[m.outer_free.size() - 1 - trial]) << force(rng), force(rng), force(rng);
    const Eigen::VectorXd twin = m.Kinv * f;
    EXPECT_TRUE(sc.needs_solve(f));  // no whole-mesh columns of the set: a back-substitution
    Eigen::VectorXd du;
    sc.displacement_on_view(f, du);
    for (int v = 0; v < m.n(); ++v) {
      const Eigen::Vector3d expected = defined[v] ? Eigen::Vector3d(twin.segment<3>(3 * v)) : Eigen::Vector3d::Zero();
      EXPECT_LE((du.segment<3>(3 * v) - expected).norm(), 1e-9 * twin.norm()) << "trial " << trial << " node " << v;
    }
    // Loads on the set only (even trials): the interior's own solve completes du to the twin everywhere, and
    // displacement() takes that path; with the outside load it cannot (the interior is loaded).
    EXPECT_EQ(sc.loads_only_view(f), trial % 2 == 0) << "trial " << trial;
    if (trial % 2 == 0) {
      sc.complete_interior(du);
      EXPECT_LE((du - twin).norm(), 1e-9 * twin.norm()) << "trial " << trial;
    }
    sc.displacement(f, du);
    EXPECT_LE((du - twin).norm(), 1e-9 * twin.norm()) << "trial " << trial;
  }
  // Kept whole-mesh columns hold every row: no view rows; a budget too small for them: none either.
  SurfaceCompliance kept(*m.solver, m.inner, 64, 256L << 20, 1L << 30, view), tight(*m.solver, m.inner, 64, 0, 1L << 30, view, 8);
  EXPECT_FALSE(kept.keeps_view_rows());
  EXPECT_FALSE(tight.keeps_view_rows());
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * m.n()), du;
  f[3 * m.inner[0]] = 0.01;
  EXPECT_FALSE(kept.needs_solve(f));
  EXPECT_THROW(tight.displacement_on_view(f, du), std::logic_error);
  EXPECT_THROW(SurfaceCompliance(*m.solver, m.inner, 64, 0, 1L << 30, {m.n()}), std::invalid_argument);
  EXPECT_THROW(SurfaceCompliance(*m.solver, m.inner, 64, 0, 1L << 30, view, -1), std::invalid_argument);
}

// InteriorSolver against the dense twin: for loads on boundary nodes only, K^-1 f off the boundary from K^-1 f on
// it; what it is given on the boundary and the fixed DOFs stays.
TEST(InteriorSolver, CompletesTheDenseTwinFromTheBoundary) {
  const Model& m = model();
  std::vector<int> boundary = m.inner;
  boundary.insert(boundary.end(), m.outer_free.begin(), m.outer_free.begin() + m.outer_free.size() / 3);
  const InteriorSolver interior(*m.solver, boundary);
  EXPECT_GT(interior.n_interior_dofs(), 0);
  EXPECT_LT(interior.factor_nonzeros(), m.solver->factor_nonzeros());
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> force(-0.02, 0.02);
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * m.n());
  for (size_t k = 0; k < boundary.size(); k += 3)
    for (int c = 0; c < 3; ++c) f[3 * boundary[k] + c] = force(rng);
  const Eigen::VectorXd twin = m.Kinv * f;
  // The boundary's entries of the twin, garbage elsewhere.
  Eigen::VectorXd u = Eigen::VectorXd::Constant(3 * m.n(), 7.0);
  for (int v : boundary) u.segment<3>(3 * v) = twin.segment<3>(3 * v);
  const Eigen::VectorXd given = u;
  interior.complete(u);
  for (int d = 0; d < u.size(); ++d) {
    if (m.solver->is_fixed_dof(d))
      EXPECT_EQ(u[d], given[d]) << "dof " << d;  // untouched
    else
      EXPECT_NEAR(u[d], twin[d], 1e-9 * twin.norm()) << "dof " << d;
  }
  Eigen::VectorXd wrong(5);
  EXPECT_THROW(interior.complete(wrong), std::invalid_argument);
  EXPECT_THROW(InteriorSolver(*m.solver, {m.n()}), std::invalid_argument);
}

}  // namespace
}  // namespace lumen::physics
