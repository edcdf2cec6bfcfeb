// The contact solves against a dense twin (Eigen LDLT of K on the free DOFs) and brute-force active-set
// enumeration (brute_force_lcp, also the twin of the dense-LCP test here), and solve_contacts (active set on
// columns of A computed on demand) against solve_lcp (Lemke on all of A) on random contact rows of a real
// inner-wall compliance (SolveContacts, moved as-is from tests/engine/test_response.cpp).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <memory>
#include <random>
#include <stdexcept>
#include <vector>

#include "physics/contact_solve.hpp"
#include "physics/fem.hpp"
#include "physics/mesh.hpp"
#include "support/lcp.hpp"
#include "compliance_model.hpp"

namespace lumen::physics {
namespace {

// A coarse tube with both ends fixed and its inner-wall compliance.
struct Tube {
  physics::TetMesh mesh;
  std::unique_ptr<physics::StaticSolver> solver;
  std::vector<int> inner, outer_free;
  std::unique_ptr<physics::SurfaceCompliance> compliance;
  Tube() {
    physics::HollowCylinderSpec s;
    s.segments_around = 8, s.segments_along = 5, s.layers = 2, s.length = 0.04;
    mesh = physics::make_hollow_cylinder(s);
    std::vector<int> fixed = mesh.node_set(kStartEnd);
    fixed.insert(fixed.end(), mesh.node_set(kStopEnd).begin(), mesh.node_set(kStopEnd).end());
    solver = std::make_unique<physics::StaticSolver>(physics::assemble_stiffness(mesh, {5000.0, 0.45}), fixed);
    std::vector<char> on(mesh.n_nodes(), 0), is_fixed(mesh.n_nodes(), 0);
    for (int i = 0; i < mesh.surface(kInnerWall).size(); ++i) on[mesh.surface(kInnerWall).data()[i]] = 1;
    for (int v : fixed) is_fixed[v] = 1;
    for (int v = 0; v < mesh.n_nodes(); ++v) {
      if (on[v]) inner.push_back(v);
      if (!on[v] && !is_fixed[v]) outer_free.push_back(v);
    }
    compliance = std::make_unique<physics::SurfaceCompliance>(*solver, inner);
  }
};

Tube& tube() {
  static Tube t;
  return t;
}

// Random vertex-face or edge-edge rows on inner nodes (with_outer: some nodes off the compliance's set).
ContactRow random_row(std::mt19937& rng, const Tube& t, bool edge_edge, bool with_outer) {
  std::uniform_int_distribution<size_t> pick(0, t.inner.size() - 1), pick_out(0, t.outer_free.size() - 1);
  std::uniform_real_distribution<double> u01(0.05, 0.95);
  std::normal_distribution<double> nd;
  ContactRow r;
  for (int k = 0; k < 4; ++k) r.node[k] = t.inner[pick(rng)];
  if (with_outer) r.node[3] = t.outer_free[pick_out(rng)];
  if (edge_edge) {
    const double s = u01(rng), tt = u01(rng);
    r.weight[0] = 1 - s, r.weight[1] = s, r.weight[2] = -(1 - tt), r.weight[3] = -tt;
  } else {
    const double a = u01(rng), b = u01(rng) * (1 - a);
    r.weight[0] = 1, r.weight[1] = -(1 - a - b), r.weight[2] = -a, r.weight[3] = -b;
  }
  // Drawn one by one (a constructor's arguments are evaluated in an unspecified order: GCC from the right, clang
  // from the left), in the order GCC has always drawn them, so that every compiler tests the same rows.
  const double nz = nd(rng), ny = nd(rng), nx = nd(rng);
  r.n = Eigen::Vector3d(nx, ny, nz).normalized();
  return r;
}

// Gaps that make a contact problem feasible by construction. Multipliers lambda_t >= 0 (about a third of them
// zero) push the mesh through the operator the solve itself uses, K^-1 H^T (with held points, minus the hold's
// correction U S U^T H^T, from the columns twin), to u_target = u_free + du; each row's gap is H u_target less a
// slack of up to 0.2 mm. A displacement under arbitrary other loads would not do: the solve moves the rows' nodes
// only by pushing along the rows' normals, and rows made feasible that way need not be: clang's draw of the held
// test's trial 2 ended Lemke 1.4e-4 m short in both formulations, and on a positive semidefinite problem Lemke
// ends short (on a ray) only when the problem has no solution.
void make_feasible(const Tube& t, std::vector<ContactRow>& rows, const Eigen::VectorXd& u_free, std::mt19937& rng,
                   const HeldPoints* held_columns = nullptr) {
  std::uniform_real_distribution<double> u01(0.0, 1.0), slack(0.0, 2e-4);
  constexpr double kMaxPush = 0.02;  // newtons per row, the size of the random loads
  Eigen::VectorXd lambda_t(static_cast<Eigen::Index>(rows.size()));
  for (Eigen::Index r = 0; r < lambda_t.size(); ++r) {
    const double on = u01(rng), size = u01(rng);
    lambda_t[r] = on < 1.0 / 3.0 ? 0.0 : kMaxPush * size;
  }
  const Eigen::VectorXd push = contact_force(rows, lambda_t, static_cast<int>(u_free.size()));
  Eigen::VectorXd du;
  t.solver->solve(push, du);
  if (held_columns) du -= held_columns->U * (held_columns->S * (held_columns->U.transpose() * push));
  const Eigen::VectorXd h_target = row_values(rows, u_free + du);
  for (size_t r = 0; r < rows.size(); ++r) rows[r].g = h_target[static_cast<Eigen::Index>(r)] - slack(rng);
}

// solve_contacts (active set on columns on demand) equals solve_lcp (all of A, Lemke) on contact rows of a real
// compliance, with duplicated rows and rows reaching off the set: same contact force (unique) and correction,
// every row satisfied (the problems are feasible by construction); the set-only correction equals the whole-mesh one on the set and the rows' nodes.
TEST(SolveContacts, EqualsLemkeOnContactRows) {
  Tube& t = tube();
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> force(-0.02, 0.02);
  int pushing = 0;
  for (int trial = 0; trial < 16; ++trial) {
    const int m = 4 + 3 * trial;
    Eigen::VectorXd f(3 * t.mesh.n_nodes());
    for (int i = 0; i < f.size(); ++i) f[i] = force(rng);
    Eigen::VectorXd u_free;
    t.solver->solve(f, u_free);
    std::vector<ContactRow> rows;
    for (int r = 0; r < m; ++r) rows.push_back(random_row(rng, t, r % 2 == 1, trial % 4 == 3 && r % 5 == 0));
    make_feasible(t, rows, u_free, rng);
    for (int r = 0; r < m / 4; ++r) rows.push_back(rows[r]);  // duplicates
    const std::vector<int> warm = {0, 1};
    const std::string what = "trial " + std::to_string(trial);

    const physics::ContactResult fast = physics::solve_contacts(*t.compliance, rows, u_free, warm);
    const physics::ContactResult lemke = physics::solve_lcp(*t.compliance, rows, u_free);
    ASSERT_TRUE(fast.converged) << what << " residual " << fast.residual;
    ASSERT_TRUE(lemke.converged) << what;
    EXPECT_FALSE(fast.used_lemke) << what;
    EXPECT_LE((fast.force - lemke.force).norm(), 1e-7 * (lemke.force.norm() + 1e-12)) << what;
    EXPECT_LE((fast.correction - lemke.correction).norm(), 1e-7 * (lemke.correction.norm() + 1e-15)) << what;
    const Eigen::VectorXd h = physics::row_values(rows, u_free + fast.correction);
    for (size_t r = 0; r < rows.size(); ++r) {
      EXPECT_GE(fast.lambda[r], 0.0);
      EXPECT_GE(h[r], rows[r].g - 1e-12) << what << " row " << r;
      if (fast.lambda[r] > 0.0) {
        EXPECT_NEAR(h[r], rows[r].g, 1e-12) << what << " row " << r;
      }
      pushing += fast.lambda[r] > 0.0;
    }
    // Set-only correction: equal where it is defined, zero elsewhere.
    const physics::ContactResult part = physics::solve_contacts(*t.compliance, rows, u_free, warm, {}, false);
    std::vector<char> defined(t.mesh.n_nodes(), 0);
    for (int v : t.inner) defined[v] = 1;
    for (const ContactRow& r : rows)
      for (int k = 0; k < 4; ++k) defined[r.node[k]] = 1;
    for (int v = 0; v < t.mesh.n_nodes(); ++v) {
      const Eigen::Vector3d expected = defined[v] ? Eigen::Vector3d(fast.correction.segment<3>(3 * v)) : Eigen::Vector3d::Zero();
      EXPECT_LE((part.correction.segment<3>(3 * v) - expected).norm(), 1e-12 * (1e-9 + fast.correction.norm())) << what;
    }
    EXPECT_EQ(part.residual <= 1e-9, fast.residual <= 1e-9) << what;
  }
  EXPECT_GT(pushing, 30);
  EXPECT_THROW(physics::solve_contacts(*t.compliance, {random_row(rng, t, false, false)},
                                       Eigen::VectorXd::Zero(3 * t.mesh.n_nodes()), {1}),
               std::invalid_argument);
}

// Held points on the inner wall (single nodes, one point spread over three nodes) and one off the set.
std::vector<LoadPoint> held_test_points(const Tube& t) {
  std::vector<int> free_inner;
  for (int v : t.inner)
    if (!t.solver->is_fixed_dof(3 * v)) free_inner.push_back(v);
  std::vector<LoadPoint> points;
  for (size_t k : {3u, 11u, 12u, 20u}) {
    LoadPoint p;
    p.node[0] = free_inner[k % free_inner.size()];
    p.weight[0] = 1.0;
    points.push_back(p);
  }
  LoadPoint spread;
  for (int k = 0; k < 3; ++k) spread.node[k] = free_inner[(30 + 2 * k) % free_inner.size()];
  spread.weight[0] = 0.2, spread.weight[1] = 0.5, spread.weight[2] = 0.3;
  points.push_back(spread);
  LoadPoint outside;
  outside.node[0] = t.outer_free[7];
  outside.weight[0] = 1.0;
  points.push_back(outside);
  return points;
}

// The brute-force twin: the held points with their whole-mesh columns U = K^-1 E (one solve_many) and
// S = (E^T U)^-1.
HeldPoints held_with_columns(const Tube& t, const std::vector<LoadPoint>& points) {
  const Eigen::Index n = t.solver->n_dofs(), d3 = 3 * static_cast<Eigen::Index>(points.size());
  Eigen::MatrixXd E = Eigen::MatrixXd::Zero(n, d3);
  for (size_t p = 0; p < points.size(); ++p)
    for (int c = 0; c < 3; ++c) {
      Eigen::VectorXd col = Eigen::VectorXd::Zero(n);
      add_point_force(points[p], Eigen::Vector3d::Unit(c), col);
      E.col(3 * static_cast<Eigen::Index>(p) + c) = col;
    }
  HeldPoints held;
  held.points = points;
  held.U = t.solver->solve_many(E);
  const Eigen::MatrixXd P = E.transpose() * held.U;
  held.S = P.ldlt().solve(Eigen::MatrixXd::Identity(d3, d3));
  return held;
}

// Relative distance of two results, scaled by the twin's size.
double relative(const Eigen::MatrixXd& a, const Eigen::MatrixXd& twin) { return (a - twin).norm() / (twin.norm() + 1e-300); }

// Held points without columns (S and G from the compliance's blocks, the hold's whole-mesh move by one
// displacement) equal the U-columns formulation to round-off: the point compliance and S, the hold correction
// U S d, and solve_contacts on the Schur complement (multipliers, held forces, force, correction, whole mesh and
// on the set and the rows' nodes), on feasible random rows; the held points do not move under the contacts.
TEST(SolveContacts, HeldPointsFromBlocksEqualTheColumnsFormulation) {
  constexpr double kRoundOff = 1e-10;  // relative, far above the round-off of these well-conditioned solves
  constexpr double kHeldStill = 1e-12;  // metres the contacts may move a held point (round-off of ~1e-4 m motions)
  Tube& t = tube();
  const std::vector<LoadPoint> points = held_test_points(t);
  const HeldPoints twin = held_with_columns(t, points);
  const HeldPoints blocks = held_points_on(*t.compliance, points);
  EXPECT_FALSE(blocks.has_columns());
  // The point compliance and its inverse.
  const Eigen::MatrixXd P = point_compliance(*t.compliance, points);
  EXPECT_LE(relative(P, twin.S.inverse()), kRoundOff);
  EXPECT_LE(relative(blocks.S, twin.S), kRoundOff);
  // The hold correction of a shortfall: U S d against one displacement of the holding forces.
  std::mt19937 rng(41);
  std::uniform_real_distribution<double> d(-1e-3, 1e-3), force(-0.02, 0.02);
  Eigen::VectorXd shortfall(3 * static_cast<Eigen::Index>(points.size()));
  for (Eigen::Index i = 0; i < shortfall.size(); ++i) shortfall[i] = d(rng);
  Eigen::VectorXd du;
  held_displacement(*t.compliance, blocks, blocks.S * shortfall, du);
  EXPECT_LE(relative(du, twin.U * (twin.S * shortfall)), kRoundOff);
  long pushing = 0;
  for (int trial = 0; trial < 8; ++trial) {
    // Feasible rows (some reaching off the set) on a free displacement with the points held.
    const int m = 6 + 4 * trial;
    Eigen::VectorXd f(t.solver->n_dofs());
    for (Eigen::Index i = 0; i < f.size(); ++i) f[i] = force(rng);
    Eigen::VectorXd u_free;
    t.solver->solve(f, u_free);
    std::vector<ContactRow> rows;
    for (int r = 0; r < m; ++r) rows.push_back(random_row(rng, t, r % 2 == 1, trial % 2 == 1 && r % 5 == 0));
    make_feasible(t, rows, u_free, rng, &twin);
    const std::string what = "trial " + std::to_string(trial);
    for (bool whole_mesh : {true, false}) {
      const ContactResult a = solve_contacts(*t.compliance, rows, u_free, {}, {}, whole_mesh, &blocks);
      const ContactResult b = solve_contacts(*t.compliance, rows, u_free, {}, {}, whole_mesh, &twin);
      ASSERT_TRUE(a.converged && b.converged) << what;
      pushing += (a.lambda.array() > 0.0).count();
      EXPECT_LE(relative(a.lambda, b.lambda), kRoundOff) << what;
      EXPECT_LE(relative(a.held_force, b.held_force), kRoundOff) << what;
      EXPECT_LE(relative(a.force, b.force), kRoundOff) << what;
      // The correction where both define it: the whole mesh, or the set and the rows' nodes.
      std::vector<int> defined = t.inner;
      for (const ContactRow& r : rows) defined.insert(defined.end(), r.node, r.node + 4);
      if (whole_mesh) {
        EXPECT_LE(relative(a.correction, b.correction), kRoundOff) << what;
      } else {
        for (int v : defined)
          EXPECT_LE((a.correction.segment<3>(3 * v) - b.correction.segment<3>(3 * v)).norm(),
                    kRoundOff * b.correction.norm()) << what << " node " << v;
      }
      // The held points keep their displacement (the correction is whole-mesh, or the set holds them).
      for (size_t p = 0; whole_mesh && p < points.size(); ++p) {
        Eigen::Vector3d moved = Eigen::Vector3d::Zero();
        for (int k = 0; k < 3; ++k)
          if (points[p].node[k] >= 0) moved += points[p].weight[k] * a.correction.segment<3>(3 * points[p].node[k]);
        EXPECT_LE(moved.norm(), kHeldStill) << what << " point " << p;
      }
    }
  }
  EXPECT_GT(pushing, 20);
}

// The iterative solve (NNCG on all of A) against the exact active-set solve on the same feasible contact
// problems (no duplicated rows, so A is definite and the multipliers unique): the same multipliers and correction
// to the tolerance asked, the residual reported within it; warm-started from the exact multipliers it needs at
// most one round (2 sweeps); a budget of 2 sweeps from zero is reported as not converged, with a finite residual.
TEST(SolveContacts, IterativeMatchesTheExactSolveWithinItsTolerance) {
  Tube& t = tube();
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> force(-0.02, 0.02);
  int pushing = 0, unconverged_small_budget = 0;
  for (int trial = 0; trial < 10; ++trial) {
    const int m = 6 + 4 * trial;
    Eigen::VectorXd f(3 * t.mesh.n_nodes());
    for (int i = 0; i < f.size(); ++i) f[i] = force(rng);
    Eigen::VectorXd u_free;
    t.solver->solve(f, u_free);
    std::vector<ContactRow> rows;
    for (int r = 0; r < m; ++r) rows.push_back(random_row(rng, t, r % 2 == 1, false));
    make_feasible(t, rows, u_free, rng);
    const std::string what = "trial " + std::to_string(trial);
    const physics::ContactResult exact = physics::solve_contacts(*t.compliance, rows, u_free);
    ASSERT_TRUE(exact.converged) << what;
    physics::IterativeLcpOptions o;
    o.max_sweeps = 20000;
    o.tolerance = 1e-10;  // metres
    const physics::ContactResult it = physics::solve_contacts_iterative(*t.compliance, rows, u_free, o);
    ASSERT_TRUE(it.converged) << what << " residual " << it.residual << " after " << it.iterations << " sweeps";
    EXPECT_LE(it.residual, o.tolerance) << what;
    EXPECT_LE((it.correction - exact.correction).norm(), 1e-4 * exact.correction.norm() + 1e-9) << what;
    EXPECT_LE((it.lambda - exact.lambda).norm(), 1e-3 * exact.lambda.norm() + 1e-9) << what;
    pushing += static_cast<int>((exact.lambda.array() > 0).count());
    // Warm start from the exact multipliers.
    o.warm = exact.lambda;
    const physics::ContactResult warm = physics::solve_contacts_iterative(*t.compliance, rows, u_free, o);
    EXPECT_TRUE(warm.converged) << what;
    EXPECT_LE(warm.iterations, 2) << what;
    // A tiny budget from zero.
    o.warm.resize(0);
    o.max_sweeps = 2;
    const physics::ContactResult small = physics::solve_contacts_iterative(*t.compliance, rows, u_free, o);
    EXPECT_TRUE(std::isfinite(small.residual)) << what;
    EXPECT_EQ(small.converged, small.residual <= o.tolerance) << what;
    unconverged_small_budget += !small.converged;
  }
  EXPECT_GT(pushing, 20);
  EXPECT_GT(unconverged_small_budget, 5);  // 2 sweeps are not enough for these problems
}

// Holding nodes at prescribed displacements (3 unit rows per node, the paper's response) equals the dense
// constrained solve [K_ff -H^T; H 0] [u; lambda] = [f; g].
TEST(Contact, EqualityHoldsNodesExactlyAndMatchesConstrainedSolve) {
  const Model& m = model();
  SurfaceCompliance sc(*m.solver, m.inner);
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> d(-1e-3, 1e-3), force(-0.02, 0.02);
  Eigen::VectorXd f(3 * m.n());
  for (int i = 0; i < f.size(); ++i) f[i] = force(rng);
  Eigen::VectorXd u_free;
  m.solver->solve(f, u_free);
  // Three inner nodes and one node outside the set held at targets, plus one vertex-face equality.
  std::vector<ContactRow> rows;
  const int held[] = {m.inner[12], m.inner[20], m.inner[27], m.outer_free[5]};
  for (int v : held)
    for (int c = 0; c < 3; ++c) {
      ContactRow r;
      r.node[0] = v, r.weight[0] = 1.0;
      r.n = Eigen::Vector3d::Unit(c);
      r.g = d(rng);
      rows.push_back(r);
    }
  ContactRow vf = random_vertex_face(rng, m, false);
  vf.g = d(rng);
  rows.push_back(vf);
  const ContactResult res = solve_equality(sc, rows, u_free);
  EXPECT_TRUE(res.converged);
  const Eigen::VectorXd u = u_free + res.correction;
  for (size_t k = 0; k < 4; ++k)
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(u[3 * held[k] + c], rows[3 * k + c].g, 1e-12);
  EXPECT_NEAR(row_values({vf}, u)[0], vf.g, 1e-12);
  // Twin: dense KKT on the free DOFs.
  const Eigen::MatrixXd H = dense_H(rows, m.n());
  EXPECT_LE((res.force - H.transpose() * res.lambda).norm(), 1e-12 * res.force.norm());
  const int mr = static_cast<int>(rows.size()), nn = 3 * m.n();
  Eigen::MatrixXd KKT = Eigen::MatrixXd::Zero(nn + mr, nn + mr);
  KKT.topLeftCorner(nn, nn) = Eigen::MatrixXd(m.K);
  KKT.topRightCorner(nn, mr) = -H.transpose();
  KKT.bottomLeftCorner(mr, nn) = H;
  Eigen::VectorXd rhs(nn + mr);
  rhs.head(nn) = f;
  for (int r = 0; r < mr; ++r) rhs[nn + r] = rows[r].g;
  // Fixed DOFs: replace their equations by u = 0.
  for (int dof = 0; dof < nn; ++dof)
    if (m.solver->is_fixed_dof(dof)) {
      KKT.row(dof).setZero();
      KKT.col(dof).setZero();
      KKT(dof, dof) = 1.0;
      rhs[dof] = 0.0;
    }
  const Eigen::VectorXd sol = KKT.fullPivLu().solve(rhs);
  EXPECT_LE((u - sol.head(nn)).norm(), 1e-9 * u.norm());
  EXPECT_LE((res.lambda - sol.tail(mr)).norm(), 1e-7 * res.lambda.norm());
}

// Brute-force twin (tests/support/lcp.hpp, every active set), tolerances relative to max |q|: whether a solution
// was found and the first such z.
bool brute_force_lcp(const Eigen::MatrixXd& A, const Eigen::VectorXd& q, Eigen::VectorXd& z_out) {
  Eigen::VectorXd w;
  return test::brute_force_lcp(A, q, q.cwiseAbs().maxCoeff(), z_out, w);
}

TEST(Contact, LcpMatchesBruteForceActiveSets) {
  const Model& m = model();
  SurfaceCompliance sc(*m.solver, m.inner);
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> d(-1e-3, 1e-3), force(-0.02, 0.02);
  int n_active_total = 0;
  for (int trial = 0; trial < 24; ++trial) {
    const int mr = 1 + trial % 8;
    Eigen::VectorXd f(3 * m.n());
    for (int i = 0; i < f.size(); ++i) f[i] = force(rng);
    Eigen::VectorXd u_free;
    m.solver->solve(f, u_free);
    std::vector<ContactRow> rows;
    for (int r = 0; r < mr; ++r) rows.push_back(random_vertex_face(rng, m, trial % 2 == 1));
    const Eigen::VectorXd h_free = row_values(rows, u_free);
    for (int r = 0; r < mr; ++r) rows[r].g = h_free[r] + d(rng);  // about half the rows violated
    const ContactResult res = solve_lcp(sc, rows, u_free);
    ASSERT_TRUE(res.converged) << "trial " << trial << " residual " << res.residual;
    // Twin problem from the dense inverse.
    const Eigen::MatrixXd H = dense_H(rows, m.n());
    const Eigen::MatrixXd A = H * m.Kinv * H.transpose();
    Eigen::VectorXd q(mr);
    for (int r = 0; r < mr; ++r) q[r] = h_free[r] - rows[r].g;
    Eigen::VectorXd z;
    ASSERT_TRUE(brute_force_lcp(A, q, z));
    EXPECT_LE((res.lambda - z).norm(), 1e-7 * (z.norm() + 1e-12)) << "trial " << trial;
    // The corrected displacement satisfies the conditions.
    const Eigen::VectorXd u = u_free + res.correction;
    EXPECT_LE((u - (u_free + m.Kinv * H.transpose() * z)).norm(), 1e-8 * u.norm());
    const Eigen::VectorXd h = row_values(rows, u);
    for (int r = 0; r < mr; ++r) {
      EXPECT_GE(res.lambda[r], 0.0);
      EXPECT_GE(h[r], rows[r].g - 1e-12);
      if (res.lambda[r] > 0) {
        EXPECT_NEAR(h[r], rows[r].g, 1e-12);
      }
      n_active_total += res.lambda[r] > 0;
    }
  }
  EXPECT_GT(n_active_total, 10);  // the problems were not trivial
}

// A larger problem with redundant (duplicated) rows: A is singular, the pivoting still converges.
TEST(Contact, LcpLargeAndDegenerate) {
  const Model& m = model();
  SurfaceCompliance sc(*m.solver, m.inner);
  std::mt19937 rng(14);
  std::uniform_real_distribution<double> d(-1e-3, 1e-3), force(-0.02, 0.02);
  Eigen::VectorXd f(3 * m.n());
  for (int i = 0; i < f.size(); ++i) f[i] = force(rng);
  Eigen::VectorXd u_free;
  m.solver->solve(f, u_free);
  std::vector<ContactRow> rows;
  for (int r = 0; r < 60; ++r) rows.push_back(random_vertex_face(rng, m, r % 3 == 0));
  const Eigen::VectorXd h_free = row_values(rows, u_free);
  for (int r = 0; r < 60; ++r) rows[r].g = h_free[r] + 0.3 * std::abs(d(rng));  // all violated
  for (int r = 0; r < 10; ++r) rows.push_back(rows[r]);                         // duplicates
  const ContactResult res = solve_lcp(sc, rows, u_free);
  EXPECT_TRUE(res.converged) << "residual " << res.residual << " after " << res.iterations << " pivots";
  const Eigen::VectorXd h = row_values(rows, u_free + res.correction);
  for (size_t r = 0; r < rows.size(); ++r) {
    EXPECT_GE(res.lambda[r], 0.0);
    EXPECT_GE(h[r], rows[r].g - 1e-9);
    if (res.lambda[r] > 0) {
      EXPECT_NEAR(h[r], rows[r].g, 1e-9);
    }
  }
}

TEST(Contact, InfeasibleLcpIsReported) {
  const Model& m = model();
  SurfaceCompliance sc(*m.solver, m.inner);
  const Eigen::VectorXd u_free = Eigen::VectorXd::Zero(3 * m.n());
  // n . u >= 1 mm and -n . u >= 1 mm on the same node cannot both hold.
  ContactRow a;
  a.node[0] = m.inner[12], a.weight[0] = 1.0, a.n = Eigen::Vector3d::UnitX(), a.g = 1e-3;
  ContactRow b = a;
  b.n = -a.n;
  const ContactResult res = solve_lcp(sc, {a, b}, u_free);
  EXPECT_FALSE(res.converged);
}

// The dense LCP on random positive semidefinite (rank-deficient) matrices with a known solvable q: w = A z + q is
// unique for PSD A and must match the brute-force twin.
TEST(Lcp, DenseRandomSemidefiniteMatchesBruteForce) {
  std::mt19937 rng(15);
  std::normal_distribution<double> nd;
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  for (int trial = 0; trial < 40; ++trial) {
    const int m = 2 + trial % 7, k = 1 + trial % m;
    Eigen::MatrixXd B(m, k);
    for (int i = 0; i < B.size(); ++i) B.data()[i] = nd(rng);
    const Eigen::MatrixXd A = B * B.transpose();
    // q from a complementary pair (z*, w*) >= 0.
    Eigen::VectorXd zs = Eigen::VectorXd::Zero(m), ws = Eigen::VectorXd::Zero(m);
    for (int i = 0; i < m; ++i) (u01(rng) < 0.5 ? zs[i] : ws[i]) = u01(rng);
    const Eigen::VectorXd q = ws - A * zs;
    const LcpResult r = solve_lcp_dense(A, q);
    ASSERT_TRUE(r.converged) << "trial " << trial << " residual " << r.residual;
    EXPECT_GE(r.z.minCoeff(), 0.0);
    EXPECT_GE(r.w.minCoeff(), -1e-9);
    EXPECT_LE(std::abs(r.z.dot(r.w)), 1e-9);
    EXPECT_LE((r.w - (A * r.z + q)).norm(), 1e-12 * (1 + q.norm()));
    Eigen::VectorXd zb;
    ASSERT_TRUE(brute_force_lcp(A, q, zb));
    EXPECT_LE((r.w - (A * zb + q)).norm(), 1e-8) << "trial " << trial;
  }
  // Degenerate q (equal entries) and q >= 0.
  const Eigen::MatrixXd A = Eigen::MatrixXd::Identity(3, 3) + Eigen::MatrixXd::Ones(3, 3);
  const LcpResult r = solve_lcp_dense(A, -Eigen::VectorXd::Ones(3));
  EXPECT_TRUE(r.converged);
  EXPECT_LE((r.z - Eigen::VectorXd::Constant(3, 0.25)).norm(), 1e-12);
  const LcpResult r0 = solve_lcp_dense(A, Eigen::VectorXd::Ones(3));
  EXPECT_TRUE(r0.converged);
  EXPECT_EQ(r0.z.norm(), 0.0);
  EXPECT_EQ(r0.iterations, 0);
  EXPECT_THROW(solve_lcp_dense(A, Eigen::VectorXd::Ones(2)), std::invalid_argument);
}

// Holding nodes that include fixed ones (zero rows of A): the fixed rows get lambda = 0 and the rest equals the
// minimum-norm least-squares twin.
TEST(Contact, EqualityWithRowsOnFixedNodes) {
  const Model& m = model();
  SurfaceCompliance sc(*m.solver, m.inner);
  int fixed_inner = -1;
  for (int v : m.inner)
    if (m.solver->is_fixed_dof(3 * v)) fixed_inner = v;
  ASSERT_GE(fixed_inner, 0);
  std::mt19937 rng(18);
  std::uniform_real_distribution<double> d(-1e-3, 1e-3);
  std::vector<ContactRow> rows;
  for (int v : {m.inner_free[2], fixed_inner, m.inner_free[9]})
    for (int c = 0; c < 3; ++c) {
      ContactRow r;
      r.node[0] = v, r.weight[0] = 1.0, r.n = Eigen::Vector3d::Unit(c);
      r.g = v == fixed_inner ? 0.0 : d(rng);
      rows.push_back(r);
    }
  const Eigen::VectorXd u_free = Eigen::VectorXd::Zero(3 * m.n());
  const ContactResult res = solve_equality(sc, rows, u_free);
  EXPECT_TRUE(res.converged) << res.residual;
  for (int c = 0; c < 3; ++c) EXPECT_EQ(res.lambda[3 + c], 0.0);
  const Eigen::MatrixXd H = dense_H(rows, m.n());
  const Eigen::MatrixXd A = H * m.Kinv * H.transpose();
  Eigen::VectorXd g(rows.size());
  for (size_t r = 0; r < rows.size(); ++r) g[r] = rows[r].g;
  const Eigen::VectorXd twin = A.completeOrthogonalDecomposition().solve(g);
  EXPECT_LE((res.lambda - twin).norm(), 1e-7 * twin.norm());
}

TEST(Contact, RejectsBadRows) {
  const Model& m = model();
  SurfaceCompliance sc(*m.solver, m.inner);
  const Eigen::VectorXd u_free = Eigen::VectorXd::Zero(3 * m.n());
  ContactRow r;
  r.node[0] = m.n(), r.weight[0] = 1, r.n = Eigen::Vector3d::UnitX();
  EXPECT_THROW(solve_lcp(sc, {r}, u_free), std::invalid_argument);
  r.node[0] = -1;
  EXPECT_THROW(solve_equality(sc, {r}, u_free), std::invalid_argument);
  r.node[0] = m.inner[0], r.g = std::nan("");
  EXPECT_THROW(solve_lcp(sc, {r}, u_free), std::invalid_argument);
  r.g = 0;
  EXPECT_THROW(solve_lcp(sc, {r}, Eigen::VectorXd::Zero(4)), std::invalid_argument);
}

}  // namespace
}  // namespace lumen::physics
