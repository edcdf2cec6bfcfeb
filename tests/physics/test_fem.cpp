// Element stiffness vs finite differences of the energy, rigid modes, assembly, and the CHOLMOD solver
// against Eigen's dense Cholesky.
#include <dlfcn.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/SparseCore>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <future>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "physics/fem.hpp"
#include "physics/mesh.hpp"
#include "physics/quadratic.hpp"
#include "support/files.hpp"

namespace lumen::physics {
namespace {

using Mat43 = Eigen::Matrix<double, 4, 3>;
using Mat12 = Eigen::Matrix<double, 12, 12>;

// A random positively oriented tet of size ~1 cm.
Mat43 random_tet(std::mt19937& rng) {
  std::uniform_real_distribution<double> d(-0.01, 0.01);
  for (;;) {
    Mat43 X;
    for (int i = 0; i < 4; ++i)
      for (int c = 0; c < 3; ++c) X(i, c) = d(rng);
    Eigen::Matrix3d Dm;
    for (int a = 0; a < 3; ++a) Dm.col(a) = (X.row(a + 1) - X.row(0)).transpose();
    const double det = Dm.determinant();
    if (std::abs(det) < 1e-7) continue;  // skip slivers
    if (det < 0) X.row(1).swap(X.row(2));
    return X;
  }
}

Mat43 unflatten(const Eigen::Matrix<double, 12, 1>& u) {
  Mat43 m;
  for (int a = 0; a < 4; ++a) m.row(a) = u.segment<3>(3 * a).transpose();
  return m;
}

const LinearMaterial kMaterials[] = {{5000.0, 0.45}, {1e5, 0.0}, {300.0, -0.5}, {5000.0, 0.499}};

TEST(TetStiffness, GradientAndHessianMatchFiniteDifferencesOfEnergy) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> du(-1e-3, 1e-3);
  for (const LinearMaterial& mat : kMaterials)
    for (int trial = 0; trial < 5; ++trial) {
      const Mat43 X = random_tet(rng);
      const Mat12 K = tet_stiffness(X, mat);
      Eigen::Matrix<double, 12, 1> u;
      for (int i = 0; i < 12; ++i) u[i] = du(rng);
      const auto energy = [&](const Eigen::Matrix<double, 12, 1>& v) { return tet_energy(X, unflatten(v), mat); };
      const double h = 1e-5;
      // Gradient: central differences of the energy vs K u.
      const Eigen::Matrix<double, 12, 1> f = K * u;
      for (int i = 0; i < 12; ++i) {
        Eigen::Matrix<double, 12, 1> e = Eigen::Matrix<double, 12, 1>::Unit(i) * h;
        const double fd = (energy(u + e) - energy(u - e)) / (2 * h);
        EXPECT_NEAR(fd, f[i], 1e-6 * f.norm() + 1e-9 * K.norm() * h) << "dof " << i;
      }
      // Hessian: second central differences vs K.
      for (int i = 0; i < 12; ++i)
        for (int j = 0; j < 12; ++j) {
          const Eigen::Matrix<double, 12, 1> ei = Eigen::Matrix<double, 12, 1>::Unit(i) * h;
          const Eigen::Matrix<double, 12, 1> ej = Eigen::Matrix<double, 12, 1>::Unit(j) * h;
          const double fd =
              (energy(u + ei + ej) - energy(u + ei - ej) - energy(u - ei + ej) + energy(u - ei - ej)) / (4 * h * h);
          EXPECT_NEAR(fd, K(i, j), 1e-6 * K.norm()) << "entry " << i << ", " << j;
        }
      // Symmetric, and the energy is the quadratic form.
      EXPECT_LE((K - K.transpose()).norm(), 1e-14 * K.norm());
      EXPECT_NEAR(energy(u), 0.5 * u.dot(K * u), 1e-10 * energy(u));
    }
}

TEST(TetStiffness, RigidMotionsGiveZeroForceAndRankIsSix) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> d(-1.0, 1.0);
  for (const LinearMaterial& mat : kMaterials) {
    const Mat43 X = random_tet(rng);
    const Mat12 K = tet_stiffness(X, mat);
    for (int trial = 0; trial < 5; ++trial) {
      const Eigen::Vector3d t(d(rng), d(rng), d(rng)), w(d(rng), d(rng), d(rng));
      Eigen::Matrix<double, 12, 1> u_t, u_r;
      for (int a = 0; a < 4; ++a) {
        u_t.segment<3>(3 * a) = t;
        u_r.segment<3>(3 * a) = w.cross(X.row(a).transpose());
      }
      EXPECT_LE((K * u_t).norm(), 1e-12 * K.norm() * u_t.norm());
      EXPECT_LE((K * u_r).norm(), 1e-12 * K.norm() * u_r.norm());
    }
    // Six zero eigenvalues (rigid modes) and six positive ones.
    const Eigen::SelfAdjointEigenSolver<Mat12> eig(K);
    const auto ev = eig.eigenvalues();
    for (int i = 0; i < 6; ++i) EXPECT_LE(std::abs(ev[i]), 1e-12 * ev[11]);
    for (int i = 6; i < 12; ++i) EXPECT_GT(ev[i], 1e-6 * ev[11]);
  }
}

TEST(TetStiffness, RejectsInvalidMaterialAndInvertedTets) {
  std::mt19937 rng(3);
  const Mat43 X = random_tet(rng);
  auto expect_msg = [&](const LinearMaterial& m, const std::string& field) {
    try {
      tet_stiffness(X, m);
      ADD_FAILURE() << "accepted " << field;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
    EXPECT_THROW(validate_material(m), std::invalid_argument);
  };
  expect_msg({0.0, 0.3}, "young_modulus");
  expect_msg({-5.0, 0.3}, "young_modulus");
  expect_msg({std::numeric_limits<double>::infinity(), 0.3}, "young_modulus");
  expect_msg({std::nan(""), 0.3}, "young_modulus");
  expect_msg({5000.0, 0.5}, "poisson_ratio");
  expect_msg({5000.0, -1.0}, "poisson_ratio");
  expect_msg({5000.0, std::nan("")}, "poisson_ratio");
  Mat43 inverted = X;
  inverted.row(1).swap(inverted.row(2));
  EXPECT_THROW(tet_stiffness(inverted, LinearMaterial{}), std::invalid_argument);
  EXPECT_THROW(tet_energy(inverted, Mat43::Zero(), LinearMaterial{}), std::invalid_argument);
}

// A small mesh for the global tests.
TetMesh small_mesh() {
  HollowCylinderSpec s;
  s.segments_around = 8, s.segments_along = 4, s.layers = 2, s.length = 0.04;
  return make_hollow_cylinder(s);
}

// Dense K restricted to the DOFs not in `fixed`, and the index map.
Eigen::MatrixXd restrict(const Eigen::MatrixXd& K, const std::vector<char>& fixed, std::vector<int>& free) {
  free.clear();
  for (int d = 0; d < K.rows(); ++d)
    if (!fixed[d]) free.push_back(d);
  Eigen::MatrixXd Kf(free.size(), free.size());
  for (size_t i = 0; i < free.size(); ++i)
    for (size_t j = 0; j < free.size(); ++j) Kf(i, j) = K(free[i], free[j]);
  return Kf;
}

// The fixed mask (3n, 1 = fixed) of whole nodes.
std::vector<char> whole_node_mask(const std::vector<int>& nodes, int n_nodes) {
  std::vector<char> fixed(3 * n_nodes, 0);
  for (int v : nodes)
    for (int c = 0; c < 3; ++c) fixed[3 * v + c] = 1;
  return fixed;
}

// The dense inverse of K on the free DOFs of n nodes with the listed nodes fixed (the independent twin of the
// factorised solves), and those free DOFs (free).
Eigen::MatrixXd free_inverse(const Eigen::SparseMatrix<double>& K, const std::vector<int>& fixed_nodes, int n,
                             std::vector<int>& free) {
  const Eigen::MatrixXd Kf = restrict(Eigen::MatrixXd(K), whole_node_mask(fixed_nodes, n), free);
  return Kf.llt().solve(Eigen::MatrixXd::Identity(Kf.rows(), Kf.cols()));
}

// A load of standard normal entries (n_dofs), and a vector's entries on the free DOFs (in their order).
Eigen::VectorXd random_load(int n_dofs, std::mt19937& rng) {
  std::normal_distribution<double> d;
  Eigen::VectorXd f(n_dofs);
  for (int i = 0; i < n_dofs; ++i) f[i] = d(rng);
  return f;
}
// D K D, D a random positive diagonal (entries in [0.5, 2]): the same stored entries, other values, still positive
// definite.
Eigen::SparseMatrix<double> rescaled(const Eigen::SparseMatrix<double>& K, std::mt19937& rng) {
  std::uniform_real_distribution<double> scale(0.5, 2.0);
  Eigen::VectorXd D(K.rows());
  for (Eigen::Index i = 0; i < K.rows(); ++i) D[i] = scale(rng);
  return D.asDiagonal() * K * D.asDiagonal();
}
Eigen::VectorXd gather(const Eigen::VectorXd& f, const std::vector<int>& free) {
  Eigen::VectorXd ff(free.size());
  for (size_t i = 0; i < free.size(); ++i) ff[i] = f[free[i]];
  return ff;
}

TEST(Assembly, SymmetricRigidModesAndEnergyIsSumOfElements) {
  const TetMesh mesh = small_mesh();
  const LinearMaterial mat{5000.0, 0.45};
  const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, mat);
  ASSERT_EQ(K.rows(), 3 * mesh.n_nodes());
  const Eigen::SparseMatrix<double> Kt = K.transpose();
  EXPECT_EQ((K - Kt).norm(), 0.0);
  // Rigid translation and infinitesimal rotation of the whole mesh: no force.
  const int n = mesh.n_nodes();
  Eigen::VectorXd ut(3 * n), ur(3 * n);
  const Eigen::Vector3d t(0.3, -0.2, 0.7), w(-1.0, 0.5, 2.0);
  for (int v = 0; v < n; ++v) {
    ut.segment<3>(3 * v) = t;
    ur.segment<3>(3 * v) = w.cross(mesh.rest.row(v).transpose());
  }
  const double knorm = Eigen::MatrixXd(K).norm();
  EXPECT_LE((K * ut).norm(), 1e-12 * knorm * ut.norm());
  EXPECT_LE((K * ur).norm(), 1e-12 * knorm * ur.norm());
  // 1/2 u^T K u equals the sum of the element energies.
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> d(-1e-3, 1e-3);
  Eigen::VectorXd u(3 * n);
  for (int i = 0; i < 3 * n; ++i) u[i] = d(rng);
  double e = 0.0;
  for (int tt = 0; tt < mesh.tets.rows(); ++tt) {
    Mat43 X, ue;
    for (int a = 0; a < 4; ++a) {
      X.row(a) = mesh.rest.row(mesh.tets(tt, a));
      ue.row(a) = u.segment<3>(3 * mesh.tets(tt, a)).transpose();
    }
    e += tet_energy(X, ue, mat);
  }
  EXPECT_NEAR(0.5 * u.dot(K * u), e, 1e-10 * e);
}

// ElementAssembly against its brute-force twin, setFromTriplets over scatter_element_matrix's triplets: the same
// pattern and the same values to the bit, for random element matrices on 4-node and 10-node tets (two sums in a
// row, as a matrix reused for new values would not be: each starts from zero_matrix).
template <int K>
void expect_assembly_equals_triplets(const int* nodes, int n_elements, int n_nodes, std::mt19937& rng) {
  const ElementAssembly assembly(nodes, n_elements, K, n_nodes);
  std::uniform_real_distribution<double> d(-1.0, 1.0);
  for (int round = 0; round < 2; ++round) {
    Eigen::SparseMatrix<double> A = assembly.zero_matrix();
    std::vector<Eigen::Triplet<double>> triplets;
    for (int e = 0; e < n_elements; ++e) {
      Eigen::Matrix<double, 3 * K, 3 * K> Ke;
      for (int i = 0; i < Ke.size(); ++i) Ke.data()[i] = d(rng);
      assembly.add(e, Ke, A);
      scatter_element_matrix(Ke, Eigen::Map<const Eigen::Matrix<int, 1, K>>(nodes + e * K), triplets);
    }
    Eigen::SparseMatrix<double> B(3 * n_nodes, 3 * n_nodes);
    B.setFromTriplets(triplets.begin(), triplets.end());
    ASSERT_TRUE(A.isCompressed());
    ASSERT_EQ(A.nonZeros(), B.nonZeros());
    for (int c = 0; c <= A.cols(); ++c) ASSERT_EQ(A.outerIndexPtr()[c], B.outerIndexPtr()[c]) << "column " << c;
    for (int i = 0; i < A.nonZeros(); ++i) {
      ASSERT_EQ(A.innerIndexPtr()[i], B.innerIndexPtr()[i]) << "entry " << i;
      ASSERT_EQ(A.valuePtr()[i], B.valuePtr()[i]) << "entry " << i;  // (exactly: the same sums in the same order)
    }
  }
}

TEST(Assembly, InPlaceEqualsTheTripletSumToTheBitOnLinearAndQuadraticTets) {
  std::mt19937 rng(11);
  const TetMesh mesh = small_mesh();
  expect_assembly_equals_triplets<4>(mesh.tets.data(), static_cast<int>(mesh.tets.rows()), mesh.n_nodes(), rng);
  const QuadraticMesh quadratic = make_quadratic(mesh);
  expect_assembly_equals_triplets<10>(quadratic.tets.data(), static_cast<int>(quadratic.tets.rows()),
                                      quadratic.n_nodes(), rng);
  // The rest stiffness has the assembly's pattern (so a warped stiffness refactorises on K's analysis).
  const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, LinearMaterial{5000.0, 0.45});
  const ElementAssembly assembly(mesh.tets.data(), static_cast<int>(mesh.tets.rows()), 4, mesh.n_nodes());
  const Eigen::SparseMatrix<double> P = assembly.zero_matrix();
  ASSERT_EQ(P.nonZeros(), K.nonZeros());
  EXPECT_TRUE(std::equal(P.innerIndexPtr(), P.innerIndexPtr() + P.nonZeros(), K.innerIndexPtr()));
  // A node id out of range is refused, naming the element.
  Tets bad = mesh.tets;
  bad(2, 3) = mesh.n_nodes();
  try {
    ElementAssembly(bad.data(), static_cast<int>(bad.rows()), 4, mesh.n_nodes());
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("node 3 of element 2 must be a node id"), std::string::npos) << e.what();
  }
}

TEST(StaticSolver, PositiveDefiniteWithEndsFixedAndMatchesDenseCholesky) {
  const TetMesh mesh = small_mesh();
  const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, LinearMaterial{5000.0, 0.45});
  std::vector<int> fixed_nodes = mesh.node_set(kStartEnd);
  fixed_nodes.insert(fixed_nodes.end(), mesh.node_set(kStopEnd).begin(), mesh.node_set(kStopEnd).end());
  const StaticSolver solver(K, fixed_nodes);
  const int n = mesh.n_nodes();
  EXPECT_EQ(solver.n_dofs(), 3 * n);
  EXPECT_EQ(solver.n_free_dofs(), 3 * (n - static_cast<int>(fixed_nodes.size())));
  EXPECT_GT(solver.factor_nonzeros(), 0);

  // Independent twin: Eigen dense Cholesky of K on the free DOFs succeeds; x^T K x > 0 for random x.
  const std::vector<char> fixed = whole_node_mask(fixed_nodes, n);
  for (int d = 0; d < 3 * n; ++d) EXPECT_EQ(solver.is_fixed_dof(d), fixed[d] != 0);
  std::vector<int> free;
  const Eigen::MatrixXd Kf = restrict(Eigen::MatrixXd(K), fixed, free);
  const Eigen::LLT<Eigen::MatrixXd> llt(Kf);
  ASSERT_EQ(llt.info(), Eigen::Success);
  std::mt19937 rng(5);
  std::normal_distribution<double> d;
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::VectorXd x(free.size());
    for (int i = 0; i < x.size(); ++i) x[i] = d(rng);
    EXPECT_GT(x.dot(Kf * x), 0.0);
  }

  // solve() vs the dense solve; fixed DOFs come back 0 whatever f holds there.
  Eigen::VectorXd f(3 * n);
  for (int i = 0; i < 3 * n; ++i) f[i] = d(rng);
  Eigen::VectorXd ff(free.size());
  for (size_t i = 0; i < free.size(); ++i) ff[i] = f[free[i]];
  const Eigen::VectorXd uf = llt.solve(ff);
  Eigen::VectorXd u;
  solver.solve(f, u);
  ASSERT_EQ(u.size(), 3 * n);
  for (size_t i = 0; i < free.size(); ++i) EXPECT_NEAR(u[free[i]], uf[i], 1e-10 * uf.cwiseAbs().maxCoeff());
  for (int dd = 0; dd < 3 * n; ++dd) {
    if (fixed[dd]) {
      EXPECT_EQ(u[dd], 0.0);
    }
  }

  // solve_many == solve column by column.
  Eigen::MatrixXd F(3 * n, 5);
  for (int i = 0; i < F.size(); ++i) F.data()[i] = d(rng);
  const Eigen::MatrixXd U = solver.solve_many(F);
  for (int c = 0; c < 5; ++c) {
    solver.solve(F.col(c), u);
    EXPECT_LE((U.col(c) - u).norm(), 1e-12 * u.norm());
  }
}

// A scaled view shares the factorisation and solves c K: against the dense solve of c K (independent twin), for
// solve and solve_many, and views of views compose; a bad scale is refused.
TEST(StaticSolver, ScaledViewSolvesTheScaledMatrixOnTheSameFactor) {
  const TetMesh mesh = small_mesh();
  const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, LinearMaterial{5000.0, 0.45});
  const StaticSolver solver(K, mesh.node_set(kStartEnd));
  const int n = mesh.n_nodes();
  const std::vector<char> fixed = whole_node_mask(mesh.node_set(kStartEnd), n);
  std::vector<int> free;
  const double c = 1600.0;  // e.g. 1 / h^2 at 40 fps
  const Eigen::LLT<Eigen::MatrixXd> llt(restrict(Eigen::MatrixXd(c * K), fixed, free));
  ASSERT_EQ(llt.info(), Eigen::Success);
  std::mt19937 rng(11);
  const Eigen::VectorXd f = random_load(3 * n, rng);
  const Eigen::VectorXd ff = gather(f, free);
  const Eigen::VectorXd uf = llt.solve(ff);
  const StaticSolver scaled = solver.scaled(c);
  EXPECT_EQ(scaled.factor_nonzeros(), solver.factor_nonzeros());
  Eigen::VectorXd u;
  scaled.solve(f, u);
  for (size_t i = 0; i < free.size(); ++i) EXPECT_NEAR(u[free[i]], uf[i], 1e-10 * uf.cwiseAbs().maxCoeff());
  for (int dd = 0; dd < 3 * n; ++dd) {
    if (fixed[dd]) {
      EXPECT_EQ(u[dd], 0.0);
    }
  }
  const Eigen::MatrixXd U = scaled.solve_many(f);
  EXPECT_LE((U.col(0) - u).norm(), 1e-12 * u.norm());
  Eigen::VectorXd u2;
  scaled.scaled(0.5).solve(f, u2);  // (c/2) K
  EXPECT_LE((u2 - 2.0 * u).norm(), 1e-12 * u.norm());
  EXPECT_THROW(solver.scaled(0.0), std::invalid_argument);
  EXPECT_THROW(solver.scaled(-1.0), std::invalid_argument);
}

// A long thin tube (8 x 24 x 1 cells, 15 cm): nested dissection's elimination tree is balanced on it.
TetMesh long_tube() {
  HollowCylinderSpec spec;
  spec.segments_around = 8, spec.segments_along = 24, spec.layers = 1, spec.length = 0.15;
  return make_hollow_cylinder(spec);
}

// Half columns (sparse forward solves on a nested-dissection factorisation) multiply to K^-1: y_i . y_j against the
// dense inverse (independent twin), through a scaled view too; a fixed DOF has none. On a long tube they are
// sparse, the design's reason: here 14 % of the free DOFs on average, against 31 % with the default ordering (AMD,
// nearly banded on a tube: its elimination tree nearly a chain), which the bound of 20 % refuses.
TEST(StaticSolver, HalfColumnsMultiplyToTheInverseAndAreSparseOnALongTube) {
  const TetMesh mesh = long_tube();
  const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, LinearMaterial{5000.0, 0.45});
  std::vector<int> fixed_nodes = mesh.node_set(kStartEnd);
  fixed_nodes.insert(fixed_nodes.end(), mesh.node_set(kStopEnd).begin(), mesh.node_set(kStopEnd).end());
  const StaticSolver solver(K, fixed_nodes);
  const int n = mesh.n_nodes(), nf = solver.n_free_dofs();
  std::vector<int> free;
  const Eigen::MatrixXd Kinv = free_inverse(K, fixed_nodes, n, free);
  // Half columns of every free DOF, as columns of a sparse matrix over the factor's rows.
  std::vector<Eigen::Triplet<double>> entries;
  std::vector<int> index;
  std::vector<double> value;
  long nonzeros = 0;
  for (int k = 0; k < nf; ++k) {
    solver.half_column(free[k], index, value);
    ASSERT_EQ(index.size(), value.size());
    ASSERT_FALSE(index.empty());
    EXPECT_TRUE(std::is_sorted(index.begin(), index.end()));
    EXPECT_TRUE(std::adjacent_find(index.begin(), index.end()) == index.end());
    for (size_t e = 0; e < index.size(); ++e) {
      ASSERT_GE(index[e], 0);
      ASSERT_LT(index[e], nf);
      entries.emplace_back(index[e], k, value[e]);
    }
    nonzeros += static_cast<long>(index.size());
  }
  Eigen::SparseMatrix<double> Y(nf, nf);
  Y.setFromTriplets(entries.begin(), entries.end());
  const Eigen::MatrixXd YtY = Eigen::MatrixXd(Eigen::SparseMatrix<double>(Y.transpose()) * Y);
  EXPECT_LE((YtY - Kinv).norm(), 1e-10 * Kinv.norm());
  EXPECT_LT(static_cast<double>(nonzeros) / nf, 0.2 * nf) << "mean entries a half column, of " << nf;
  // A scaled view: (c K)^-1 = K^-1 / c, on the same half factor.
  const double c = 40.0;
  const StaticSolver scaled = solver.scaled(c);
  std::vector<int> index2;
  std::vector<double> value2;
  scaled.half_column(free[5], index, value);
  scaled.half_column(free[nf - 7], index2, value2);
  Eigen::VectorXd a = Eigen::VectorXd::Zero(nf), b = Eigen::VectorXd::Zero(nf);
  for (size_t e = 0; e < index.size(); ++e) a[index[e]] = value[e];
  for (size_t e = 0; e < index2.size(); ++e) b[index2[e]] = value2[e];
  EXPECT_NEAR(a.dot(b), Kinv(5, nf - 7) / c, 1e-10 * Kinv.cwiseAbs().maxCoeff() / c);
  // A fixed DOF: no entries; a DOF out of range: refused.
  solver.half_column(3 * fixed_nodes[0] + 1, index, value);
  EXPECT_TRUE(index.empty());
  EXPECT_TRUE(value.empty());
  EXPECT_THROW(solver.half_column(3 * n, index, value), std::invalid_argument);
  EXPECT_THROW(solver.half_column(-1, index, value), std::invalid_argument);
}

// The solve split in halves: half_backward(half_forward(f)) is K^-1 f by the dense inverse (independent twin), a
// DOF's half column dotted with the forward half is that DOF's displacement, and a force added to the forward half
// through its half column gives K^-1 (f + g) from one backward sweep; through scaled views, on half_column's own
// factorisation and on a solver from refactorised_nested (whose halves sweep its supernodal factor); the fixed DOFs
// stay 0; wrong sizes are refused naming the argument.
TEST(StaticSolver, SolveSplitInHalvesReadsAndAddsThroughHalfColumns) {
  const TetMesh mesh = small_mesh();
  const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, LinearMaterial{5000.0, 0.45});
  const std::vector<int>& fixed_nodes = mesh.node_set(kStartEnd);
  const StaticSolver solver(K, fixed_nodes);
  const int n = mesh.n_nodes();
  std::vector<int> free;
  const Eigen::MatrixXd Kinv = free_inverse(K, fixed_nodes, n, free);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Eigen::VectorXd f(3 * n), g = Eigen::VectorXd::Zero(3 * n);
  for (Eigen::Index d = 0; d < f.size(); ++d) f[d] = unit(rng);
  const int loaded = free[7];  // g: a force on one free DOF
  g[loaded] = 0.3;
  // The dense twin on the free DOFs, scattered.
  auto twin = [&](const Eigen::VectorXd& load, double c) {
    Eigen::VectorXd lf(free.size()), u = Eigen::VectorXd::Zero(3 * n);
    for (size_t k = 0; k < free.size(); ++k) lf[static_cast<Eigen::Index>(k)] = load[free[k]];
    const Eigen::VectorXd uf = Kinv * lf / c;
    for (size_t k = 0; k < free.size(); ++k) u[free[k]] = uf[static_cast<Eigen::Index>(k)];
    return u;
  };
  // On half_column's own factorisation, and on a solver from refactorised_nested (the halves sweep its factor).
  solver.prepare_nested_analysis();
  const StaticSolver nested = solver.refactorised_nested(K);
  EXPECT_FALSE(solver.splits_on_its_factor());
  EXPECT_TRUE(nested.splits_on_its_factor());
  for (const double signed_c : {1.0, 40.0, -1.0, -40.0}) {
    SCOPED_TRACE("scale " + std::to_string(signed_c) + " (negative: the nested solver)");
    const double c = std::abs(signed_c);
    const StaticSolver view = signed_c > 0.0 ? solver.scaled(c) : nested.scaled(c);
    const Eigen::VectorXd u_ref = twin(f, c), ufg_ref = twin(f + g, c);
    std::vector<double> z;
    Eigen::VectorXd u;
    view.half_forward(f, z);
    ASSERT_EQ(static_cast<int>(z.size()), solver.n_free_dofs());
    // A DOF's displacement read from z through its half column.
    std::vector<int> index;
    std::vector<double> value;
    for (const int dof : {free[0], free[free.size() / 2], free.back()}) {
      view.half_column(dof, index, value);
      double y_dot_z = 0.0;
      for (size_t e = 0; e < index.size(); ++e) y_dot_z += value[e] * z[index[e]];
      EXPECT_NEAR(y_dot_z, u_ref[dof], 1e-10 * u_ref.cwiseAbs().maxCoeff()) << "dof " << dof;
    }
    std::vector<double> z_copy = z;
    view.half_backward(z_copy, u);
    EXPECT_LE((u - u_ref).norm(), 1e-10 * u_ref.norm());
    for (int v : fixed_nodes) EXPECT_EQ(u.segment<3>(3 * v).norm(), 0.0);
    // g added through its half column, one backward sweep.
    view.half_column(loaded, index, value);
    for (size_t e = 0; e < index.size(); ++e) z[index[e]] += value[e] * g[loaded];
    view.half_backward(z, u);
    EXPECT_LE((u - ufg_ref).norm(), 1e-10 * ufg_ref.norm());
  }
  std::vector<double> z;
  Eigen::VectorXd u;
  using lumen::test::message_of;
  EXPECT_EQ(message_of<std::invalid_argument>([&] { solver.half_forward(Eigen::VectorXd::Zero(3 * n - 1), z); }),
            "StaticSolver::half_forward: f must have " + std::to_string(3 * n) + " entries, got " +
                std::to_string(3 * n - 1));
  EXPECT_EQ(message_of<std::invalid_argument>([&] { solver.half_backward(std::vector<double>(3), u); }),
            "StaticSolver::half_backward: z must have " + std::to_string(solver.n_free_dofs()) +
                " entries (the free DOFs), got 3");
}

// A node's three half columns at once: on a solver from refactorised_nested, one supernodal forward sweep over the
// DOFs' paths in the elimination tree, against CHOLMOD's partial solves of each DOF on the same factor's copy
// (half_column), and their products against the dense inverse; on half_column's own factorisation the per-DOF
// solves merged; a fixed node's columns are 0; a DOF out of range is refused.
TEST(StaticSolver, HalfColumnsOfANodeOnTheSupernodalPathsEqualThePartialSolves) {
  const TetMesh mesh = long_tube();
  const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, LinearMaterial{5000.0, 0.45});
  std::vector<int> fixed_nodes = mesh.node_set(kStartEnd);
  const StaticSolver solver(K, fixed_nodes);
  solver.prepare_nested_analysis();
  const StaticSolver nested = solver.refactorised_nested(K).scaled(3.0);
  const int n = mesh.n_nodes();
  std::vector<int> free;
  const Eigen::MatrixXd Kinv = free_inverse(K, fixed_nodes, n, free);
  std::vector<int> free_index(3 * n, -1);
  for (size_t k = 0; k < free.size(); ++k) free_index[free[k]] = static_cast<int>(k);
  // A node's columns as a dense matrix over the factor's rows (n_free x 3).
  auto dense = [&](const std::vector<int>& index, const std::vector<double>& value) {
    Eigen::MatrixXd Y = Eigen::MatrixXd::Zero(solver.n_free_dofs(), 3);
    EXPECT_EQ(value.size(), 3 * index.size());
    EXPECT_TRUE(std::is_sorted(index.begin(), index.end()));
    for (size_t e = 0; e < index.size(); ++e)
      for (int c = 0; c < 3; ++c) Y(index[e], c) = value[3 * e + c];
    return Y;
  };
  std::vector<int> index, one_index;
  std::vector<double> value, one_value;
  const std::vector<int> nodes = {n / 2, n / 2 + 1, n - 1, 7};
  for (const StaticSolver* s : {&nested, &solver}) {
    const double c = s == &nested ? 3.0 : 1.0;
    std::vector<Eigen::MatrixXd> Ys;
    for (int v : nodes) {
      s->half_columns({3 * v, 3 * v + 1, 3 * v + 2}, index, value);
      const Eigen::MatrixXd Y = dense(index, value);
      // Each column as half_column gives it (CHOLMOD's partial solve).
      for (int d = 0; d < 3; ++d) {
        s->half_column(3 * v + d, one_index, one_value);
        Eigen::VectorXd y = Eigen::VectorXd::Zero(solver.n_free_dofs());
        for (size_t e = 0; e < one_index.size(); ++e) y[one_index[e]] = one_value[e];
        EXPECT_LE((Y.col(d) - y).norm(), 1e-12 * y.norm() + 1e-300) << "node " << v << " dof " << d;
      }
      Ys.push_back(Y);
    }
    // Y_a^T Y_b = (c K)^-1 between the nodes' free DOFs.
    for (size_t a = 0; a < nodes.size(); ++a)
      for (size_t b = 0; b < nodes.size(); ++b) {
        const Eigen::Matrix3d block = Ys[a].transpose() * Ys[b];
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) {
            const int fi = free_index[3 * nodes[a] + i], fj = free_index[3 * nodes[b] + j];
            const double want = fi < 0 || fj < 0 ? 0.0 : Kinv(fi, fj) / c;
            EXPECT_NEAR(block(i, j), want, 1e-10 * Kinv.cwiseAbs().maxCoeff());
          }
      }
  }
  // A fixed node: no entries (its columns are 0).
  nested.half_columns({3 * fixed_nodes[0], 3 * fixed_nodes[0] + 1, 3 * fixed_nodes[0] + 2}, index, value);
  EXPECT_TRUE(index.empty());
  EXPECT_EQ(lumen::test::message_of<std::invalid_argument>([&] { nested.half_columns({0, 3 * n}, index, value); }),
            "StaticSolver::half_columns: dofs[1] must be in [0, " + std::to_string(3 * n) + "), got " +
                std::to_string(3 * n));
}

// A matrix of the same pattern refactorised on the first one's symbolic analysis solves as its own dense Cholesky
// (independent twin) and as a fresh factorisation of it; another pattern, an indefinite or a non-finite matrix is
// refused with its reason.
TEST(StaticSolver, RefactorisedOnTheSameAnalysisEqualsAFreshFactorisation) {
  const TetMesh mesh = small_mesh();
  const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, LinearMaterial{5000.0, 0.45});
  const std::vector<int>& fixed_nodes = mesh.node_set(kStartEnd);
  const StaticSolver solver(K, fixed_nodes);
  const int n = mesh.n_nodes();
  std::mt19937 rng(23);
  const Eigen::SparseMatrix<double> K2 = rescaled(K, rng);
  ASSERT_TRUE(solver.has_pattern(K2));
  const StaticSolver refactorised = solver.refactorised(K2);
  const StaticSolver fresh(K2, fixed_nodes);
  EXPECT_EQ(refactorised.n_free_dofs(), solver.n_free_dofs());
  EXPECT_EQ(refactorised.factor_nonzeros(), solver.factor_nonzeros());
  EXPECT_LE((Eigen::MatrixXd(refactorised.matrix()) - Eigen::MatrixXd(K2)).norm(), 0.0);
  const std::vector<char> fixed = whole_node_mask(fixed_nodes, n);
  std::vector<int> free;
  const Eigen::LLT<Eigen::MatrixXd> llt(restrict(Eigen::MatrixXd(K2), fixed, free));
  ASSERT_EQ(llt.info(), Eigen::Success);
  const Eigen::VectorXd f = random_load(3 * n, rng);
  const Eigen::VectorXd ff = gather(f, free);
  const Eigen::VectorXd uf = llt.solve(ff);
  Eigen::VectorXd u, u_fresh, u_first;
  refactorised.solve(f, u);
  fresh.solve(f, u_fresh);
  for (size_t i = 0; i < free.size(); ++i) EXPECT_NEAR(u[free[i]], uf[i], 1e-10 * uf.cwiseAbs().maxCoeff());
  EXPECT_LE((u - u_fresh).norm(), 1e-10 * u_fresh.norm());
  for (int dd = 0; dd < 3 * n; ++dd) {
    if (fixed[dd]) {
      EXPECT_EQ(u[dd], 0.0);
    }
  }
  // The first solver is untouched: it still solves K.
  solver.solve(f, u_first);
  Eigen::VectorXd residual = K * u_first - f;
  for (int dd = 0; dd < 3 * n; ++dd)
    if (fixed[dd]) residual[dd] = 0.0;
  EXPECT_LE(residual.norm(), 1e-9 * f.norm());

  // Another pattern: one entry more (nodes 0 and n - 1 coupled).
  Eigen::SparseMatrix<double> other = K2;
  other.coeffRef(0, 3 * n - 1) += 1.0;
  other.coeffRef(3 * n - 1, 0) += 1.0;
  EXPECT_FALSE(solver.has_pattern(other));
  const auto message = [&](const Eigen::SparseMatrix<double>& M) {
    return test::message_of<std::invalid_argument>([&] { solver.refactorised(M); });
  };
  const int nnz = static_cast<int>(K.nonZeros());
  EXPECT_EQ(message(other), "StaticSolver::refactorised: K must store the entries of the factorised matrix (" +
                                std::to_string(nnz) + " in a " + std::to_string(3 * n) + " x " +
                                std::to_string(3 * n) + " pattern), got " + std::to_string(nnz + 2) + " in a " +
                                std::to_string(3 * n) + " x " + std::to_string(3 * n));
  // Indefinite, and not finite.
  const Eigen::SparseMatrix<double> negative = -K2;
  EXPECT_NE(message(negative).find("StaticSolver: K on the free DOFs is not positive definite"), std::string::npos)
      << message(negative);
  Eigen::SparseMatrix<double> nan = K2;
  nan.coeffRef(3, 3) = std::nan("");
  EXPECT_EQ(message(nan), "StaticSolver: K(3, 3) must be finite, got nan");
}

// A matrix of the same pattern refactorised on the first one's nested-dissection analysis: its solves equal the
// dense Cholesky of it (independent twin), its half columns multiply to that inverse (Y^T Y = K2^-1 over the free
// DOFs), and a half column taken before a solve leaves the solve right (CHOLMOD turns the partial solves' factor
// simplicial in place, so it is a copy). Without the analysis it is refused.
TEST(StaticSolver, RefactorisedNestedSolvesAndGivesHalfColumnsOfTheNewMatrix) {
  HollowCylinderSpec spec;
  spec.segments_around = 8, spec.segments_along = 12, spec.layers = 1, spec.length = 0.08;
  const TetMesh mesh = make_hollow_cylinder(spec);
  const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, LinearMaterial{5000.0, 0.45});
  const std::vector<int>& fixed_nodes = mesh.node_set(kStartEnd);
  const StaticSolver solver(K, fixed_nodes);
  const int n = mesh.n_nodes();
  std::mt19937 rng(29);
  const Eigen::SparseMatrix<double> K2 = rescaled(K, rng);
  EXPECT_FALSE(solver.has_nested_analysis());
  EXPECT_EQ(test::message_of<std::logic_error>([&] { solver.refactorised_nested(K2); }),
            "StaticSolver::refactorised_nested: prepare_nested_analysis() has not run on this solver");
  solver.prepare_nested_analysis();
  ASSERT_TRUE(solver.has_nested_analysis());
  const StaticSolver nested = solver.refactorised_nested(K2);
  // The twin: K2's dense inverse over the free DOFs.
  const std::vector<char> fixed = whole_node_mask(fixed_nodes, n);
  std::vector<int> free;
  const Eigen::MatrixXd K2f = restrict(Eigen::MatrixXd(K2), fixed, free);
  const Eigen::MatrixXd inverse = K2f.llt().solve(Eigen::MatrixXd::Identity(K2f.rows(), K2f.cols()));
  const int nf = static_cast<int>(free.size());
  ASSERT_EQ(nested.n_free_dofs(), nf);
  // Half columns first (the partial solves' factor goes simplicial), then a solve on the factor they came from.
  Eigen::MatrixXd Y = Eigen::MatrixXd::Zero(nf, nf);
  std::vector<int> index;
  std::vector<double> value;
  for (int k = 0; k < nf; ++k) {
    nested.half_column(free[k], index, value);
    for (size_t e = 0; e < index.size(); ++e) Y(index[e], k) = value[e];
  }
  EXPECT_LE((Y.transpose() * Y - inverse).norm(), 1e-10 * inverse.norm());
  const Eigen::VectorXd f = random_load(3 * n, rng);
  const Eigen::VectorXd uf = inverse * gather(f, free);
  Eigen::VectorXd u;
  nested.solve(f, u);
  for (int k = 0; k < nf; ++k) EXPECT_NEAR(u[free[k]], uf[k], 1e-10 * uf.cwiseAbs().maxCoeff());
  // The first solver still solves K.
  Eigen::VectorXd u_first;
  solver.solve(f, u_first);
  const Eigen::VectorXd u_first_twin = restrict(Eigen::MatrixXd(K), fixed, free).llt().solve(gather(f, free));
  for (int k = 0; k < nf; ++k) EXPECT_NEAR(u_first[free[k]], u_first_twin[k], 1e-10 * u_first_twin.cwiseAbs().maxCoeff());
}

// The single-precision copy of the factor (the corotational solves' preconditioner): K^-1 f to float's precision
// against the dense Cholesky, a symmetric operator to double round-off (its solves are double arithmetic on the
// rounded factor, which CG needs), commuting with scaling K, shared by scaled views, made again by refactorised() and
// refactorised_nested();
// without it, solve_approximately is solve.
TEST(StaticSolver, SinglePrecisionCopySolvesToFloatPrecisionAndSymmetrically) {
  const TetMesh mesh = small_mesh();
  const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, LinearMaterial{5000.0, 0.45});
  const std::vector<int>& fixed_nodes = mesh.node_set(kStartEnd);
  StaticSolver solver(K, fixed_nodes);
  const int n = mesh.n_nodes();
  const std::vector<char> fixed = whole_node_mask(fixed_nodes, n);
  std::vector<int> free;
  const Eigen::LLT<Eigen::MatrixXd> llt(restrict(Eigen::MatrixXd(K), fixed, free));
  ASSERT_EQ(llt.info(), Eigen::Success);
  std::mt19937 rng(31);
  const Eigen::VectorXd f = random_load(3 * n, rng), g = random_load(3 * n, rng);
  Eigen::VectorXd u, u_exact, v;
  // Without the copy: the double solve, bit for bit.
  EXPECT_FALSE(solver.has_single_precision());
  solver.solve_approximately(f, u);
  solver.solve(f, u_exact);
  EXPECT_EQ((u - u_exact).norm(), 0.0);
  // With it: float's precision against the dense twin, 0 on fixed DOFs, symmetric to round-off.
  solver.add_single_precision();
  ASSERT_TRUE(solver.has_single_precision());
  solver.solve_approximately(f, u);
  const Eigen::VectorXd uf = llt.solve(gather(f, free));
  EXPECT_LE((gather(u, free) - uf).norm(), 1e-5 * uf.norm());
  EXPECT_GT((u - u_exact).norm(), 0.0);  // it is the rounded factor's solve, not the double one
  for (int d = 0; d < 3 * n; ++d) {
    if (fixed[d]) {
      EXPECT_EQ(u[d], 0.0);
    }
  }
  solver.solve_approximately(g, v);
  EXPECT_NEAR(g.dot(u), f.dot(v), 1e-12 * std::abs(f.dot(v)));
  // A scaled view shares the copy: exactly 1/c of it.
  Eigen::VectorXd w;
  solver.scaled(4.0).solve_approximately(f, w);
  EXPECT_LE((4.0 * w - u).norm(), 1e-15 * u.norm());
  // It commutes with scaling K (a factorisation of 50 K of its own): the rounding is relative to the factor's
  // largest diagonal entry, so no unit of K enters it.
  StaticSolver fifty(Eigen::SparseMatrix<double>(50.0 * K), fixed_nodes);
  fifty.add_single_precision();
  fifty.solve_approximately(f, w);
  EXPECT_LE((50.0 * w - u).norm(), 1e-12 * u.norm());
  // A refactorisation makes its own copy, of its own matrix.
  const Eigen::SparseMatrix<double> K2 = rescaled(K, rng);
  const StaticSolver refactorised = solver.refactorised(K2);
  ASSERT_TRUE(refactorised.has_single_precision());
  const Eigen::LLT<Eigen::MatrixXd> llt2(restrict(Eigen::MatrixXd(K2), fixed, free));
  refactorised.solve_approximately(f, u);
  const Eigen::VectorXd uf2 = llt2.solve(gather(f, free));
  EXPECT_LE((gather(u, free) - uf2).norm(), 1e-5 * uf2.norm());
  // So does one on the nested-dissection analysis (the contact Hessians, which precondition the predictions too).
  solver.prepare_nested_analysis();
  const StaticSolver nested = solver.refactorised_nested(K2);
  ASSERT_TRUE(nested.has_single_precision());
  nested.solve_approximately(f, u);
  EXPECT_LE((gather(u, free) - uf2).norm(), 1e-5 * uf2.norm());
  nested.solve(f, u_exact);
  EXPECT_GT((u - u_exact).norm(), 0.0);
  nested.solve_approximately(g, v);
  EXPECT_NEAR(g.dot(u), f.dot(v), 1e-12 * std::abs(f.dot(v)));
  EXPECT_THROW(solver.solve_approximately(Eigen::VectorXd::Zero(5), u), std::invalid_argument);
}

TEST(StaticSolver, SingleFixedDofsMatchDenseSolve) {
  const TetMesh mesh = small_mesh();
  const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, LinearMaterial{2000.0, 0.3});
  const int n = mesh.n_nodes();
  // u_z = 0 on the start end, u_x = u_y = 0 on three start nodes (enough to remove rigid motion).
  std::vector<FixedDof> dofs;
  for (int v : mesh.node_set(kStartEnd)) dofs.push_back({v, 2});
  dofs.push_back({mesh.node_set(kStartEnd)[0], 0});
  dofs.push_back({mesh.node_set(kStartEnd)[0], 1});
  dofs.push_back({mesh.node_set(kStartEnd)[3], 0});
  const StaticSolver solver(K, dofs);
  std::vector<char> fixed(3 * n, 0);
  for (const FixedDof& fd : dofs) fixed[3 * fd.node + fd.component] = 1;
  std::vector<int> free;
  const Eigen::MatrixXd Kf = restrict(Eigen::MatrixXd(K), fixed, free);
  EXPECT_EQ(solver.n_free_dofs(), static_cast<int>(free.size()));
  std::mt19937 rng(6);
  const Eigen::VectorXd f = random_load(3 * n, rng);
  const Eigen::VectorXd ff = gather(f, free);
  const Eigen::VectorXd uf = Kf.ldlt().solve(ff);
  Eigen::VectorXd u;
  solver.solve(f, u);
  for (size_t i = 0; i < free.size(); ++i) EXPECT_NEAR(u[free[i]], uf[i], 1e-9 * uf.cwiseAbs().maxCoeff());
  for (const FixedDof& fd : dofs) EXPECT_EQ(u[3 * fd.node + fd.component], 0.0);
}

// Patch test: a linear displacement field prescribed on the surface nodes is reproduced exactly inside.
TEST(StaticSolver, PatchTestReproducesLinearField) {
  HollowCylinderSpec s;
  s.segments_around = 6, s.segments_along = 3, s.layers = 3, s.length = 0.03;
  const TetMesh mesh = make_hollow_cylinder(s);
  const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, LinearMaterial{5000.0, 0.45});
  const int n = mesh.n_nodes();
  std::vector<char> on_surface(n, 0);
  for (const Tris* t : {&mesh.surface(kInnerWall), &mesh.surface(kOuterWall), &mesh.surface(kEndCaps)})
    for (int i = 0; i < t->size(); ++i) on_surface[t->data()[i]] = 1;
  std::vector<int> boundary;
  for (int v = 0; v < n; ++v)
    if (on_surface[v]) boundary.push_back(v);
  ASSERT_LT(static_cast<int>(boundary.size()), n);  // interior nodes exist
  Eigen::Matrix3d G;
  G << 1e-3, 2e-3, -1e-3, 0.5e-3, -2e-3, 3e-3, 1e-3, 0.2e-3, 0.7e-3;
  const Eigen::Vector3d c(1e-4, -2e-4, 3e-4);
  Eigen::VectorXd u_lin(3 * n), u_b = Eigen::VectorXd::Zero(3 * n);
  for (int v = 0; v < n; ++v) u_lin.segment<3>(3 * v) = G * mesh.rest.row(v).transpose() + c;
  for (int v : boundary) u_b.segment<3>(3 * v) = u_lin.segment<3>(3 * v);
  // K_ff u_f = -K_fb u_b.
  const StaticSolver solver(K, boundary);
  Eigen::VectorXd u;
  solver.solve(-(K * u_b), u);
  for (int v = 0; v < n; ++v) {
    if (!on_surface[v]) {
      EXPECT_LE((u.segment<3>(3 * v) - u_lin.segment<3>(3 * v)).norm(), 1e-10 * u_lin.segment<3>(3 * v).norm());
    }
  }
}

// The engine factorises on a second thread while the first solves (the corotational model's lagged factorisation):
// both go through CHOLMOD's supernodal kernels and the system BLAS at once, which must be safe to call from two
// threads (OpenBLAS's serial flavour was not: it corrupted such factorisations). On the paper mesh, a factorisation
// of 2 K made on a second thread while the first keeps solving K x = b gives the solution of 2 y = b to round-off
// (against the assembled matrix itself: |2 K y - b| on the free DOFs), and the first thread's solves stay exact.
TEST(StaticSolver, AFactorisationOnASecondThreadWhileTheFirstSolvesIsExact) {
  HollowCylinderSpec spec;
  spec.segments_around = 20, spec.segments_along = 26, spec.layers = 3;
  const TetMesh mesh = make_hollow_cylinder(spec);
  const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, LinearMaterial{5000.0, 0.45});
  std::vector<int> fixed_nodes = mesh.node_set(kStartEnd);
  fixed_nodes.insert(fixed_nodes.end(), mesh.node_set(kStopEnd).begin(), mesh.node_set(kStopEnd).end());
  const std::vector<char> fixed = whole_node_mask(fixed_nodes, mesh.n_nodes());
  auto free_residual = [&](const Eigen::SparseMatrix<double>& A, const Eigen::VectorXd& x, const Eigen::VectorXd& b) {
    Eigen::VectorXd r = A * x - b;
    double rn = 0.0, bn = 0.0;
    for (Eigen::Index d = 0; d < r.size(); ++d)
      if (!fixed[d]) rn += r[d] * r[d], bn += b[d] * b[d];
    return std::sqrt(rn / bn);
  };
  std::mt19937 rng(11);
  std::normal_distribution<double> normal;
  Eigen::VectorXd b(K.rows());
  for (Eigen::Index d = 0; d < b.size(); ++d) b[d] = fixed[d] ? 0.0 : normal(rng);
  const StaticSolver first(K, fixed_nodes);
  Eigen::VectorXd x0, x;
  first.solve(b, x0);
  ASSERT_LT(free_residual(K, x0, b), 1e-9);
  for (int round = 0; round < 3; ++round) {
    const Eigen::SparseMatrix<double> K2 = 2.0 * K;
    auto second = std::async(std::launch::async, [&] { return std::make_unique<StaticSolver>(K2, fixed_nodes); });
    int solves = 0;
    while (second.wait_for(std::chrono::seconds(0)) != std::future_status::ready) {
      first.solve(b, x);
      ++solves;
      EXPECT_LT((x - x0).norm(), 1e-12 * x0.norm()) << "solve " << solves;
    }
    const std::unique_ptr<StaticSolver> made = second.get();
    Eigen::VectorXd y;
    made->solve(b, y);
    EXPECT_LT(free_residual(K2, y, b), 1e-9) << "round " << round << " (" << solves << " solves during it)";
    EXPECT_LT((2.0 * y - x0).norm(), 1e-9 * x0.norm()) << "round " << round;
  }
}

// CHOLMOD's OpenMP loops run on the thread that factorises, whatever thread that is. libgomp keeps
// max-active-levels per thread: set once on the main thread, it left every background factorisation (a new thread
// each time) with teams of 4 OpenMP threads on 2 cores (36,000 context switches at nice 19 in a 40-frame pinch,
// their wall time twice their CPU time). The OpenMP runtime is CHOLMOD's own, found the way fem.cpp finds it.
TEST(StaticSolver, AFactorisationOnANewThreadRunsOpenMpOnThatThreadAlone) {
  using GetLevels = int (*)();
  const auto max_active_levels = reinterpret_cast<GetLevels>(dlsym(RTLD_DEFAULT, "omp_get_max_active_levels"));
  ASSERT_NE(max_active_levels, nullptr) << "CHOLMOD is linked without an OpenMP runtime";
  const TetMesh mesh = small_mesh();
  const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, LinearMaterial{5000.0, 0.45});
  std::vector<int> fixed_nodes = mesh.node_set(kStartEnd);
  const StaticSolver here(K, fixed_nodes);  // (the first factorisation, on this thread)
  for (int round = 0; round < 2; ++round) {
    auto there = std::async(std::launch::async, [&] {
      const int before = max_active_levels();
      const StaticSolver solver(K, fixed_nodes);
      return std::make_pair(before, max_active_levels());
    });
    const auto [before, after] = there.get();
    EXPECT_GT(before, 0) << "a new thread starts with nested OpenMP teams allowed (else this test shows nothing)";
    EXPECT_EQ(after, 0) << "round " << round;
  }
}

TEST(StaticSolver, RejectsBadInput) {
  const TetMesh mesh = small_mesh();
  const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, LinearMaterial{});
  // Nothing fixed: rigid motion left, not positive definite.
  EXPECT_THROW(StaticSolver(K, std::vector<int>{}), std::invalid_argument);
  // Only one node fixed: rotations about it remain.
  EXPECT_THROW(StaticSolver(K, std::vector<int>{0}), std::invalid_argument);
  EXPECT_THROW(StaticSolver(K, std::vector<int>{mesh.n_nodes()}), std::invalid_argument);
  EXPECT_THROW(StaticSolver(K, std::vector<FixedDof>{{0, 3}}), std::invalid_argument);
  Eigen::SparseMatrix<double> rect(6, 9);
  EXPECT_THROW(StaticSolver(rect, std::vector<int>{}), std::invalid_argument);
  const StaticSolver solver(K, mesh.node_set(kStartEnd));
  Eigen::VectorXd u;
  EXPECT_THROW(solver.solve(Eigen::VectorXd::Zero(5), u), std::invalid_argument);
  EXPECT_THROW(solver.solve_many(Eigen::MatrixXd::Zero(5, 2)), std::invalid_argument);
  EXPECT_THROW(solver.is_fixed_dof(-1), std::invalid_argument);
  // Moved-from and moved-to solvers keep working.
  StaticSolver moved = StaticSolver(K, mesh.node_set(kStartEnd));
  Eigen::VectorXd f = Eigen::VectorXd::Ones(3 * mesh.n_nodes()), u1, u2;
  moved.solve(f, u1);
  solver.solve(f, u2);
  EXPECT_LE((u1 - u2).norm(), 1e-12 * u2.norm());
}

}  // namespace
}  // namespace lumen::physics
