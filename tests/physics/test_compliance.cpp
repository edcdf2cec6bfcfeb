// LoadResponse, SurfaceCompliance and the contact solves against a dense twin (Eigen LDLT of K on the free DOFs)
// and brute-force active-set enumeration.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>
#include <stdexcept>
#include <vector>

#include "physics/compliance.hpp"
#include "physics/mesh.hpp"
#include "support/lcp.hpp"

namespace lumen::physics {
namespace {

// A coarse tube with both ends fixed, its solver and a dense inverse of K (0 on fixed DOFs) as the twin.
struct Model {
  TetMesh mesh;
  Eigen::SparseMatrix<double> K;
  std::unique_ptr<StaticSolver> solver;
  Eigen::MatrixXd Kinv;         // 3n x 3n
  std::vector<int> inner;       // inner-wall node ids
  std::vector<int> free_nodes;  // nodes not fixed
  std::vector<int> outer_free;  // free nodes not on the inner wall
  std::vector<int> inner_free;  // free nodes on the inner wall

  Model() {
    HollowCylinderSpec s;
    s.segments_around = 8, s.segments_along = 4, s.layers = 2, s.length = 0.04;
    mesh = make_hollow_cylinder(s);
    K = assemble_stiffness(mesh, LinearMaterial{5000.0, 0.45});
    std::vector<int> fixed = mesh.end_nodes_start;
    fixed.insert(fixed.end(), mesh.end_nodes_stop.begin(), mesh.end_nodes_stop.end());
    solver = std::make_unique<StaticSolver>(K, fixed);
    const int n = mesh.n_nodes();
    std::vector<char> is_fixed(n, 0), is_inner(n, 0);
    for (int v : fixed) is_fixed[v] = 1;
    for (int i = 0; i < mesh.inner.size(); ++i) is_inner[mesh.inner.data()[i]] = 1;
    for (int v = 0; v < n; ++v) {
      if (is_inner[v]) inner.push_back(v);
      if (!is_fixed[v]) free_nodes.push_back(v);
      if (!is_fixed[v] && !is_inner[v]) outer_free.push_back(v);
      if (!is_fixed[v] && is_inner[v]) inner_free.push_back(v);
    }
    // Dense twin.
    std::vector<int> free;
    for (int v : free_nodes)
      for (int c = 0; c < 3; ++c) free.push_back(3 * v + c);
    const Eigen::MatrixXd Kd(K);
    Eigen::MatrixXd Kf(free.size(), free.size());
    for (size_t i = 0; i < free.size(); ++i)
      for (size_t j = 0; j < free.size(); ++j) Kf(i, j) = Kd(free[i], free[j]);
    const Eigen::MatrixXd Kfi = Kf.ldlt().solve(Eigen::MatrixXd::Identity(free.size(), free.size()));
    Kinv = Eigen::MatrixXd::Zero(3 * n, 3 * n);
    for (size_t i = 0; i < free.size(); ++i)
      for (size_t j = 0; j < free.size(); ++j) Kinv(free[i], free[j]) = Kfi(i, j);
  }
  int n() const { return mesh.n_nodes(); }
};

const Model& model() {
  static const Model m;
  return m;
}

// H as a dense matrix (rows x 3n), built directly from the row definition.
Eigen::MatrixXd dense_H(const std::vector<ContactRow>& rows, int n) {
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(rows.size(), 3 * n);
  for (size_t r = 0; r < rows.size(); ++r)
    for (int k = 0; k < 4; ++k)
      if (rows[r].node[k] >= 0)
        for (int c = 0; c < 3; ++c) H(r, 3 * rows[r].node[k] + c) += rows[r].weight[k] * rows[r].n[c];
  return H;
}

Eigen::Vector3d random_unit(std::mt19937& rng) {
  std::normal_distribution<double> d;
  return Eigen::Vector3d(d(rng), d(rng), d(rng)).normalized();
}

// Vertex-face row n . (u_p - sum b_i u_fi) on random nodes: the vertex free, the face nodes anywhere on the
// inner wall (fixed ones included) or, with allow_outer, anywhere in the mesh (outside the compliance set).
ContactRow random_vertex_face(std::mt19937& rng, const Model& m, bool allow_outer) {
  const std::vector<int>& vpool = allow_outer ? m.free_nodes : m.inner_free;
  std::vector<int> fpool = m.inner;
  if (allow_outer) fpool.insert(fpool.end(), m.outer_free.begin(), m.outer_free.end());
  std::uniform_int_distribution<size_t> pickv(0, vpool.size() - 1), pickf(0, fpool.size() - 1);
  std::uniform_real_distribution<double> u01(0.05, 1.0);
  ContactRow row;
  row.node[0] = vpool[pickv(rng)];
  for (int k = 1; k < 4; ++k) row.node[k] = fpool[pickf(rng)];
  double b[3] = {u01(rng), u01(rng), u01(rng)};
  const double s = b[0] + b[1] + b[2];
  row.weight[0] = 1.0;
  for (int k = 0; k < 3; ++k) row.weight[k + 1] = -b[k] / s;
  row.n = random_unit(rng);
  return row;
}

TEST(LoadResponse, EqualsDirectSolve) {
  const Model& m = model();
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> tri(0, static_cast<int>(m.mesh.inner.rows()) - 1);
  std::uniform_real_distribution<double> u01(0.0, 1.0), force(-0.05, 0.05);
  std::vector<LoadPoint> points(3);
  for (LoadPoint& p : points) {
    const int t = tri(rng);
    double b0 = u01(rng), b1 = u01(rng) * (1 - b0);
    const double b[3] = {b0, b1, 1 - b0 - b1};
    for (int k = 0; k < 3; ++k) p.node[k] = m.mesh.inner(t, k), p.weight[k] = b[k];
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

// The coupling matrix column by column equals the dense twin H K^-1 H^T, rows inside and outside the set.
TEST(CouplingMatrix, ColumnsEqualDenseTwin) {
  const Model& m = model();
  SurfaceCompliance sc(*m.solver, m.inner);
  std::mt19937 rng(16);
  std::vector<ContactRow> rows;
  for (int r = 0; r < 30; ++r) rows.push_back(random_vertex_face(rng, m, r % 4 == 0));
  ContactRow held;  // a one-node unit row (the paper's hold) on a node outside the set
  held.node[0] = m.outer_free[3], held.weight[0] = 1.0, held.n = Eigen::Vector3d::UnitY();
  rows.push_back(held);
  const Eigen::MatrixXd H = dense_H(rows, m.n());
  const Eigen::MatrixXd twin = H * m.Kinv * H.transpose();
  CouplingMatrix A(sc, rows);
  ASSERT_EQ(A.size(), 31);
  EXPECT_EQ(A.columns_computed(), 0);
  for (int s : {30, 4, 0}) EXPECT_LE((A.column(s) - twin.col(s)).norm(), 1e-9 * twin.norm()) << "column " << s;
  EXPECT_EQ(A.columns_computed(), 3);
  const Eigen::MatrixXd dense = A.dense();
  EXPECT_LE((dense - twin).norm(), 1e-9 * twin.norm());
  EXPECT_EQ((dense - dense.transpose()).norm(), 0.0);
  EXPECT_LE((coupling_matrix(sc, rows) - dense).norm(), 1e-15 * twin.norm());
  EXPECT_THROW(A.column(31), std::invalid_argument);
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
