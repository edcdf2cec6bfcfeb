// Contact response: the active-set LCP solver against brute-force enumeration and Lemke's pivoting (random
// semidefinite problems with duplicate and dependent rows, warm starts, infeasible problems), solve_contacts
// against solve_lcp on real contact rows, contact_row against the separation it constrains (direct and finite
// differences), and whole sessions of a small squeezed tube checked by the exact intersection count.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <memory>
#include <random>
#include <stdexcept>
#include <vector>

#include "collision/self_collision.hpp"
#include "engine/response.hpp"
#include "engine/scene.hpp"
#include "engine/session.hpp"
#include "engine/simulation.hpp"
#include "physics/compliance.hpp"
#include "physics/fem.hpp"
#include "physics/mesh.hpp"
#include "support/lcp.hpp"

namespace lumen::engine {
namespace {

using physics::ContactRow;
using physics::LcpResult;

// Brute-force twin (tests/support/lcp.hpp, every active set), tolerances relative to 1 + max |q|: w of the first
// solution found. For a positive semidefinite A, w is the same for every solution.
bool brute_force_w(const Eigen::MatrixXd& A, const Eigen::VectorXd& q, Eigen::VectorXd& w_out) {
  Eigen::VectorXd z;
  return test::brute_force_lcp(A, q, 1.0 + q.cwiseAbs().maxCoeff(), z, w_out);
}

// The conditions of a solution: z >= 0, w = A z + q >= 0, complementary.
void expect_lcp_solution(const Eigen::MatrixXd& A, const Eigen::VectorXd& q, const LcpResult& r, double tol,
                         const std::string& what) {
  ASSERT_EQ(r.z.size(), q.size()) << what;
  EXPECT_GE(r.z.minCoeff(), 0.0) << what;
  EXPECT_LE((r.w - (A * r.z + q)).norm(), 1e-10 * (1.0 + q.norm())) << what;
  EXPECT_GE(r.w.minCoeff(), -tol) << what;
  for (int i = 0; i < q.size(); ++i)
    if (r.z[i] > 0.0) {
      EXPECT_LE(std::abs(r.w[i]), tol) << what << " row " << i;
    }
}

// Random positive semidefinite problems (full rank, rank deficient, duplicated rows with different q) that are
// solvable by construction: q = w* - A z* from a complementary pair. The active set's w equals brute force's and
// Lemke's (w is unique for a semidefinite LCP).
TEST(ActiveSetLcp, MatchesBruteForceAndLemkeOnSemidefiniteProblems) {
  std::mt19937 rng(21);
  std::normal_distribution<double> nd;
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  int exchanges_possible = 0;
  for (int trial = 0; trial < 90; ++trial) {
    const int m = 2 + trial % 8;
    const int rank = trial % 3 == 0 ? m + 2 : 1 + (trial / 3) % m;  // full rank, or rank deficient
    Eigen::MatrixXd B(m, rank);
    for (int i = 0; i < B.size(); ++i) B.data()[i] = nd(rng);
    if (trial % 4 == 1) B.row(m - 1) = B.row(0);  // a duplicated row (its q differs)
    const Eigen::MatrixXd A = B * B.transpose();
    Eigen::VectorXd zs = Eigen::VectorXd::Zero(m), ws = Eigen::VectorXd::Zero(m);
    for (int i = 0; i < m; ++i) (u01(rng) < 0.6 ? zs[i] : ws[i]) = u01(rng);
    const Eigen::VectorXd q = ws - A * zs;
    exchanges_possible += rank < m;
    const std::string what = "trial " + std::to_string(trial);

    const LcpResult r = physics::solve_lcp_active_set(A, q);
    ASSERT_TRUE(r.converged) << what << " residual " << r.residual;
    expect_lcp_solution(A, q, r, 1e-9, what);
    Eigen::VectorXd wb;
    ASSERT_TRUE(brute_force_w(A, q, wb)) << what;
    EXPECT_LE((r.w - wb).norm(), 1e-8 * (1.0 + q.norm())) << what;
    const LcpResult lemke = physics::solve_lcp_dense(A, q);
    ASSERT_TRUE(lemke.converged) << what;
    EXPECT_LE((r.w - lemke.w).norm(), 1e-8 * (1.0 + q.norm())) << what;
  }
  EXPECT_GT(exchanges_possible, 30);
}

// Rows that are combinations of others (a dependent row enters while its parts are active: the exchange step)
// and exact duplicates with equal q (the copy must stay out). H rows act on u in R^3, A = H H^T, q = H u_free - g.
TEST(ActiveSetLcp, DependentAndDuplicateRows) {
  Eigen::MatrixXd H(4, 3), Hs(3, 3);
  H << 1, 0, 0,  // h0
      0, 1, 0,   // h1
      1, 1, 0,   // h2 = h0 + h1
      1, 0, 0;   // h3 = h0
  Hs << 1, 0, 0,  //
      0, 1, 0,    //
      0.1, 0.1, 0;  // a small multiple of h0 + h1: h0 and h1 enter first, then it must replace them
  struct Case {
    Eigen::MatrixXd H;
    Eigen::VectorXd g;
  };
  std::vector<Case> cases;
  for (const Eigen::Vector4d& g : {Eigen::Vector4d(0.0, 0.0, 0.5, 0.0), Eigen::Vector4d(-0.5, 0.0, 1.0, -0.5),
                                   Eigen::Vector4d(0.0, -3.0, 0.5, 0.0), Eigen::Vector4d(0.2, 0.1, 0.0, 0.2)})
    cases.push_back({H, g});
  cases.push_back({Hs, Eigen::Vector3d(0.0, 0.0, 0.05)});
  cases.push_back({Hs, Eigen::Vector3d(-0.5, 0.0, 0.05)});
  const Eigen::Vector3d u_free(-1.0, -1.0, 0.0);
  for (const Case& c : cases) {
    const Eigen::MatrixXd A = c.H * c.H.transpose();
    const Eigen::VectorXd q = c.H * u_free - c.g;
    const LcpResult r = physics::solve_lcp_active_set(A, q);
    ASSERT_TRUE(r.converged) << c.g.transpose();
    expect_lcp_solution(A, q, r, 1e-9, "dependent");
    Eigen::VectorXd wb;
    ASSERT_TRUE(brute_force_w(A, q, wb));
    EXPECT_LE((r.w - wb).norm(), 1e-10) << c.g.transpose();
    // The displacement u_free + H^T z is unique and satisfies every row.
    const Eigen::Vector3d u = u_free + c.H.transpose() * r.z;
    const LcpResult lemke = physics::solve_lcp_dense(A, q);
    EXPECT_LE((u - (u_free + c.H.transpose() * lemke.z)).norm(), 1e-10) << c.g.transpose();
    for (int i = 0; i < c.H.rows(); ++i) EXPECT_GE(c.H.row(i).dot(u), c.g[i] - 1e-9);
  }
  // The scaled case's solution pushes with the dependent row alone: u = (0.25, 0.25, 0).
  const Eigen::MatrixXd As = Hs * Hs.transpose();
  const LcpResult rs = physics::solve_lcp_active_set(As, Hs * u_free - Eigen::Vector3d(0.0, 0.0, 0.05));
  EXPECT_LE((u_free + Hs.transpose() * rs.z - Eigen::Vector3d(0.25, 0.25, 0.0)).norm(), 1e-12);
}

// Any warm-start guess (right, wrong, repeated, empty) gives the same solution; the right guess needs no round.
TEST(ActiveSetLcp, WarmStartGivesTheSameSolution) {
  std::mt19937 rng(22);
  std::normal_distribution<double> nd;
  std::uniform_int_distribution<int> coin(0, 1);
  for (int trial = 0; trial < 30; ++trial) {
    const int m = 3 + trial % 12;
    Eigen::MatrixXd B(m, m + 3);
    for (int i = 0; i < B.size(); ++i) B.data()[i] = nd(rng);
    const Eigen::MatrixXd A = B * B.transpose();  // positive definite: z unique
    Eigen::VectorXd q(m);
    for (int i = 0; i < m; ++i) q[i] = nd(rng);
    const LcpResult cold = physics::solve_lcp_active_set(A, q);
    ASSERT_TRUE(cold.converged);
    std::vector<int> right, guess;
    for (int i = 0; i < m; ++i) {
      if (cold.z[i] > 0.0) right.push_back(i);
      if (coin(rng)) guess.push_back(i);
    }
    guess.push_back(guess.empty() ? 0 : guess.front());  // a repeated index
    for (const auto& warm : {right, guess}) {
      const LcpResult r = physics::solve_lcp_active_set(A, q, warm);
      ASSERT_TRUE(r.converged) << "trial " << trial;
      EXPECT_LE((r.z - cold.z).norm(), 1e-10 * (1.0 + cold.z.norm())) << "trial " << trial;
    }
    EXPECT_EQ(physics::solve_lcp_active_set(A, q, right).iterations, 0) << "trial " << trial;
  }
}

TEST(ActiveSetLcp, InfeasibleAndTrivialProblems) {
  // x >= 1 and -x >= 1: the dependent row's null direction is unbounded.
  Eigen::MatrixXd A(2, 2);
  A << 1, -1, -1, 1;
  EXPECT_FALSE(physics::solve_lcp_active_set(A, Eigen::Vector2d(-1.0, -1.0)).converged);
  // A row no force can move (zero column) that is violated.
  Eigen::MatrixXd Z = Eigen::MatrixXd::Zero(2, 2);
  Z(0, 0) = 1.0;
  EXPECT_FALSE(physics::solve_lcp_active_set(Z, Eigen::Vector2d(-1.0, -1.0)).converged);
  // q >= 0: z = 0 without a round.
  const LcpResult r0 = physics::solve_lcp_active_set(Eigen::MatrixXd::Identity(3, 3), Eigen::Vector3d(1, 0, 2));
  EXPECT_TRUE(r0.converged);
  EXPECT_EQ(r0.z.norm(), 0.0);
  EXPECT_EQ(r0.iterations, 0);
  // Empty problem.
  EXPECT_TRUE(physics::solve_lcp_active_set(Eigen::MatrixXd(0, 0), Eigen::VectorXd(0)).converged);
  // Validation at the boundary.
  EXPECT_THROW(physics::solve_lcp_active_set(Eigen::MatrixXd::Identity(2, 2), Eigen::Vector3d::Ones()),
               std::invalid_argument);
  EXPECT_THROW(physics::solve_lcp_active_set(Eigen::MatrixXd::Identity(2, 2), -Eigen::Vector2d::Ones(), {2}),
               std::invalid_argument);
  physics::LcpOptions bad;
  bad.tolerance = -1.0;
  EXPECT_THROW(physics::solve_lcp_active_set(Eigen::MatrixXd::Identity(2, 2), -Eigen::Vector2d::Ones(), {}, bad),
               std::invalid_argument);
}

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
    std::vector<int> fixed = mesh.end_nodes_start;
    fixed.insert(fixed.end(), mesh.end_nodes_stop.begin(), mesh.end_nodes_stop.end());
    solver = std::make_unique<physics::StaticSolver>(physics::assemble_stiffness(mesh, {5000.0, 0.45}), fixed);
    std::vector<char> on(mesh.n_nodes(), 0), is_fixed(mesh.n_nodes(), 0);
    for (int i = 0; i < mesh.inner.size(); ++i) on[mesh.inner.data()[i]] = 1;
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
  r.n = Eigen::Vector3d(nd(rng), nd(rng), nd(rng)).normalized();
  return r;
}

// solve_contacts (active set on columns on demand) equals solve_lcp (all of A, Lemke) on contact rows of a real
// compliance, with duplicated rows and rows reaching off the set: same contact force (unique) and correction,
// every row satisfied (the problems are feasible by construction); the set-only correction equals the whole-mesh one on the set and the rows' nodes.
TEST(SolveContacts, EqualsLemkeOnContactRows) {
  Tube& t = tube();
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> d(-1e-3, 1e-3), force(-0.02, 0.02);
  int pushing = 0;
  for (int trial = 0; trial < 16; ++trial) {
    const int m = 4 + 3 * trial;
    Eigen::VectorXd f(3 * t.mesh.n_nodes());
    for (int i = 0; i < f.size(); ++i) f[i] = force(rng);
    Eigen::VectorXd u_free;
    t.solver->solve(f, u_free);
    std::vector<ContactRow> rows;
    for (int r = 0; r < m; ++r) rows.push_back(random_row(rng, t, r % 2 == 1, trial % 4 == 3 && r % 5 == 0));
    // Feasible by construction: a second displacement u_target (other loads) satisfies every row with slack.
    for (int i = 0; i < f.size(); ++i) f[i] = force(rng);
    Eigen::VectorXd u_target;
    t.solver->solve(f, u_target);
    const Eigen::VectorXd h_target = physics::row_values(rows, u_target);
    for (int r = 0; r < m; ++r) rows[r].g = h_target[r] - 0.2 * std::abs(d(rng));
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

// ---------------------------------------------------------------------------------------------------------------
// contact_row

// The separation vector of a contact from its definition: vf p - ((1-s-t) a + s b + t c); ee the point at s on
// ab minus the point at t on cd.
Eigen::Vector3d separation(const collision::Contact& c, const Points& x) {
  auto p = [&](int k) -> Eigen::Vector3d { return x.row(c.v[k]).transpose(); };
  if (c.kind == collision::FeatureKind::VertexFace) return p(0) - ((1 - c.s - c.t) * p(1) + c.s * p(2) + c.t * p(3));
  return ((1 - c.s) * p(0) + c.s * p(1)) - ((1 - c.t) * p(2) + c.t * p(3));
}

Points at_time(const Points& x0, const Points& x1, double tau) { return (1 - tau) * x0 + tau * x1; }

// The row is the separation along n: H u - g = n . d(rest + u) - gap for every u; n is the unit separation
// direction at the time of contact, and H is the gradient of the separation distance there (central finite
// differences of |d|).
TEST(ContactRow, IsTheSeparationAlongTheNormal) {
  std::mt19937 rng(24);
  std::normal_distribution<double> nd(0.0, 0.01);
  std::uniform_real_distribution<double> u01(0.05, 0.9);
  const double gap = 1e-4;
  for (int trial = 0; trial < 40; ++trial) {
    Points rest(6, 3), x0(6, 3), x1(6, 3);
    for (int i = 0; i < rest.size(); ++i) rest.data()[i] = nd(rng), x0.data()[i] = nd(rng), x1.data()[i] = nd(rng);
    collision::Contact c;
    c.kind = trial % 2 ? collision::FeatureKind::EdgeEdge : collision::FeatureKind::VertexFace;
    c.v[0] = 4, c.v[1] = 0, c.v[2] = 5, c.v[3] = 2;
    c.toi = u01(rng);
    c.s = 0.5 * u01(rng), c.t = 0.5 * u01(rng);
    const ContactRow row = contact_row(c, rest, x0, x1, gap);
    const Eigen::Vector3d d_toi = separation(c, at_time(x0, x1, c.toi));
    EXPECT_NEAR(row.n.norm(), 1.0, 1e-14);
    EXPECT_LE((row.n - d_toi.normalized()).norm(), 1e-12);
    for (int k = 0; k < 3; ++k) {
      Eigen::VectorXd u(18);
      for (int i = 0; i < 18; ++i) u[i] = nd(rng);
      const Points x = rest + Eigen::Map<const Points>(u.data(), 6, 3);
      EXPECT_NEAR(physics::row_values({row}, u)[0] - row.g, row.n.dot(separation(c, x)) - gap, 1e-15);
    }
    // Gradient of |d| at the time of contact along random nodal directions.
    const Points xt = at_time(x0, x1, c.toi);
    Eigen::VectorXd du(18);
    for (int i = 0; i < 18; ++i) du[i] = nd(rng);
    const Points dx = Eigen::Map<const Points>(du.data(), 6, 3);
    const double eps = 1e-6;
    const double fd = (separation(c, xt + eps * dx).norm() - separation(c, xt - eps * dx).norm()) / (2 * eps);
    EXPECT_NEAR(physics::row_values({row}, du)[0], fd, 1e-7 * du.norm());
  }
}

// Touching features (zero separation at the time of contact): n is the face normal (vf) or the edges' common
// normal (ee), pointing to the side the first feature came from; the row is still the separation along n.
TEST(ContactRow, TouchingFeaturesUseTheGeometricNormal) {
  std::mt19937 rng(25);
  std::normal_distribution<double> nd(0.0, 0.01);
  std::uniform_real_distribution<double> u01(0.1, 0.8);
  for (int trial = 0; trial < 20; ++trial) {
    collision::Contact c;
    c.kind = trial % 2 ? collision::FeatureKind::EdgeEdge : collision::FeatureKind::VertexFace;
    c.v[0] = 0, c.v[1] = 1, c.v[2] = 2, c.v[3] = 3;
    c.toi = u01(rng), c.s = 0.4 * u01(rng), c.t = 0.4 * u01(rng);
    // Positions at the time of contact with the features touching, the start anywhere; the end follows.
    Points rest(4, 3), x0(4, 3), xt(4, 3);
    for (int i = 0; i < 12; ++i) rest.data()[i] = nd(rng), x0.data()[i] = nd(rng), xt.data()[i] = nd(rng);
    if (c.kind == collision::FeatureKind::VertexFace) {
      xt.row(0) = (1 - c.s - c.t) * xt.row(1) + c.s * xt.row(2) + c.t * xt.row(3);
    } else {
      // Move the second edge so that its point at t meets the first edge's point at s.
      const Eigen::RowVector3d shift = ((1 - c.s) * xt.row(0) + c.s * xt.row(1)) - ((1 - c.t) * xt.row(2) + c.t * xt.row(3));
      xt.row(2) += shift, xt.row(3) += shift;
    }
    const Points x1 = x0 + (xt - x0) / c.toi;
    ASSERT_LE(separation(c, at_time(x0, x1, c.toi)).norm(), 1e-12);
    const ContactRow row = contact_row(c, rest, x0, x1, 1e-4);
    EXPECT_NEAR(row.n.norm(), 1.0, 1e-12);
    const Points xc = at_time(x0, x1, c.toi);
    const Eigen::Vector3d e1 = c.kind == collision::FeatureKind::VertexFace ? Eigen::Vector3d(xc.row(2) - xc.row(1))
                                                                            : Eigen::Vector3d(xc.row(1) - xc.row(0));
    const Eigen::Vector3d e2 = c.kind == collision::FeatureKind::VertexFace ? Eigen::Vector3d(xc.row(3) - xc.row(1))
                                                                            : Eigen::Vector3d(xc.row(3) - xc.row(2));
    EXPECT_LE(std::abs(row.n.dot(e1)), 1e-9 * e1.norm());
    EXPECT_LE(std::abs(row.n.dot(e2)), 1e-9 * e2.norm());
    EXPECT_GE(row.n.dot(separation(c, x0)), 0.0);
    Eigen::VectorXd u(12);
    for (int i = 0; i < 12; ++i) u[i] = nd(rng);
    const Points x = rest + Eigen::Map<const Points>(u.data(), 4, 3);
    EXPECT_NEAR(physics::row_values({row}, u)[0] - row.g, row.n.dot(separation(c, x)) - 1e-4, 1e-15);
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Whole sessions: a coarse tube squeezed shut by two opposite probes; with either response the inner wall never
// intersects (exact check, independent of the CCD code), and the walls really meet.

Scene squeeze_scene(const std::string& response, int frames) {
  Scene s = load_scene(std::string(LUMEN_SOURCE_DIR) + "/scenes/full-closure.json");
  s.mesh.segments_around = 12;
  s.mesh.segments_along = 8;
  s.mesh.layers = 2;
  s.mesh.length = 0.06;
  for (ProbeSpec& p : s.probes) {
    p.point.z() = 0.03;
    p.track = {TrackKey{0.0, Eigen::Vector3d::Zero()}, TrackKey{0.5, 3.0 * p.track.back().value},
               TrackKey{1.0, 3.0 * p.track.back().value}};
  }
  s.frames = frames;
  s.collision.response = response;
  return s;
}

void expect_session_intersection_free(const std::string& response, int frames) {
  const auto model = compile_model(squeeze_scene(response, frames));
  SessionOptions opt;
  opt.render = false;
  opt.check = true;
  const SessionResult r = run_session(*model, opt);
  long contacts = 0, solved_frames = 0;
  for (const FrameRecord& f : r.frames) {
    EXPECT_EQ(f.intersecting_pairs, 0) << response << " frame " << f.frame;
    EXPECT_FALSE(f.numerical_failure) << response << " frame " << f.frame;
    contacts += f.contacts;
    solved_frames += f.response_iterations > 0 && !f.fallback;
  }
  EXPECT_GT(contacts, 0) << response;
  EXPECT_GT(solved_frames, 0) << response;
}

TEST(CollideAndRespond, ConstraintResponseKeepsTheSqueezedTubeIntersectionFree) {
  expect_session_intersection_free("constraint", 36);
}

// The paper's hold resolves the first contact frames and then needs the safe fallback once the closure spreads
// (every round re-checks by CCD, so a short session keeps the test quick).
TEST(CollideAndRespond, PaperResponseKeepsTheSqueezedTubeIntersectionFree) {
  expect_session_intersection_free("paper", 14);
}

// Without any response the same squeeze makes the walls pass through each other (the scene tests something).
TEST(CollideAndRespond, TheSqueezeIntersectsWithoutResponse) {
  Scene s = squeeze_scene("constraint", 36);
  s.collision.self = false;
  const auto model = compile_model(s);
  SessionOptions opt;
  opt.render = false;
  opt.check = true;
  const SessionResult r = run_session(*model, opt);
  long frames_with = 0;
  for (const FrameRecord& f : r.frames) frames_with += f.intersecting_pairs > 0;
  EXPECT_GT(frames_with, 3);
}

}  // namespace
}  // namespace lumen::engine
