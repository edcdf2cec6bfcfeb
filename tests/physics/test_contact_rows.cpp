// The coupling matrix against the dense twin H K^-1 H^T.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <random>
#include <vector>

#include "physics/contact_rows.hpp"
#include "compliance_model.hpp"

namespace lumen::physics {
namespace {

// A random rotation per node into frames (n), and Rn, the block-diagonal matrix of them (3n x 3n).
Eigen::MatrixXd random_node_frames(std::mt19937& rng, int n, std::vector<Eigen::Matrix3d>& frames) {
  std::normal_distribution<double> normal(0.0, 1.0);
  frames.resize(static_cast<size_t>(n));
  Eigen::MatrixXd Rn = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  for (int v = 0; v < n; ++v) {
    const Eigen::Vector4d q(normal(rng), normal(rng), normal(rng), normal(rng));
    frames[v] = Eigen::Quaterniond(q.normalized()).toRotationMatrix();
    Rn.block<3, 3>(3 * v, 3 * v) = frames[v];
  }
  return Rn;
}

// The coupling matrix column by column equals the dense twin H K^-1 H^T, rows inside and outside the set.
// Once with the set's matrix solved at construction, once with its columns solved per node on first use (lazy).
TEST(CouplingMatrix, ColumnsEqualDenseTwin) {
  for (const long set_matrix_bytes : {256L << 20, 0L}) {
    const Model& m = model();
    SurfaceCompliance sc(*m.solver, m.inner, 64, 256L << 20, set_matrix_bytes);
    ASSERT_EQ(sc.lazy(), set_matrix_bytes == 0);
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
}

// With per-node frames the coupling is that of the warped compliance, against the dense twin H Rn K^-1 Rn^T H^T
// (Rn block-diagonal: a random rotation per node), set matrix solved or lazy; a frame list of the wrong size throws.
TEST(CouplingMatrix, NodeFramesEqualTheWarpedDenseTwin) {
  for (const long set_matrix_bytes : {256L << 20, 0L}) {
    const Model& m = model();
    SurfaceCompliance sc(*m.solver, m.inner, 64, 256L << 20, set_matrix_bytes);
    std::mt19937 rng(23);
    std::vector<ContactRow> rows;
    for (int r = 0; r < 20; ++r) rows.push_back(random_vertex_face(rng, m, r % 3 == 0));
    std::vector<Eigen::Matrix3d> frames;
    const Eigen::MatrixXd Rn = random_node_frames(rng, m.n(), frames);
    const Eigen::MatrixXd H = dense_H(rows, m.n());
    const Eigen::MatrixXd twin = H * Rn * m.Kinv * Rn.transpose() * H.transpose();
    EXPECT_LE((coupling_matrix(sc, rows, &frames) - twin).norm(), 1e-9 * twin.norm());
    // (Not the unwarped coupling: the frames matter.)
    EXPECT_GT((coupling_matrix(sc, rows) - twin).norm(), 1e-3 * twin.norm());
    frames.pop_back();
    EXPECT_THROW(CouplingMatrix(sc, rows, &frames), std::invalid_argument);
  }
}

// Every row on the lazy set's nodes: dense() forms A from one product of the touched nodes' half columns. It equals
// the dense twin and the column-by-column coupling (the path the active-set solvers take), with and without per-node
// frames, and leaves every column at hand.
TEST(CouplingMatrix, DenseFromHalfColumnsEqualsColumnsAndTwin) {
  const Model& m = model();
  SurfaceCompliance sc(*m.solver, m.inner, 64, 256L << 20, 0L);
  ASSERT_TRUE(sc.lazy());
  std::mt19937 rng(31);
  std::vector<ContactRow> rows;
  for (int r = 0; r < 40; ++r) rows.push_back(random_vertex_face(rng, m, false));
  std::vector<Eigen::Matrix3d> frames;
  const Eigen::MatrixXd Rn = random_node_frames(rng, m.n(), frames);
  const Eigen::MatrixXd H = dense_H(rows, m.n());
  for (const bool warped : {false, true}) {
    const std::vector<Eigen::Matrix3d>* f = warped ? &frames : nullptr;
    const Eigen::MatrixXd C = warped ? Eigen::MatrixXd(Rn * m.Kinv * Rn.transpose()) : m.Kinv;
    const Eigen::MatrixXd twin = H * C * H.transpose();
    CouplingMatrix by_product(sc, rows, f), by_columns(sc, rows, f);
    const Eigen::MatrixXd A = by_product.dense();
    EXPECT_EQ(by_product.columns_computed(), 40);
    EXPECT_LE((A - twin).norm(), 1e-9 * twin.norm()) << "warped " << warped;
    Eigen::MatrixXd columns(40, 40);
    for (int s = 0; s < 40; ++s) columns.col(s) = by_columns.column(s);
    EXPECT_LE((A - columns).norm(), 1e-12 * twin.norm()) << "warped " << warped;
    for (int s : {0, 17, 39}) EXPECT_LE((by_product.column(s) - columns.col(s)).norm(), 1e-12 * twin.norm());
  }
}

// A lazy set keeps the blocks of its recent couplings and computes only those of new nodes: a sequence of overlapping row sets each equals the dense twin and the column-by-column coupling (which
// uses no kept block), with the default bound and with one so small that the kept blocks are dropped on the way.
TEST(CouplingMatrix, DenseOnKeptBlocksOfEarlierCouplingsEqualsTheTwin) {
  const Model& m = model();
  for (const int bound : {SurfaceCompliance::kGramNodes, 24}) {
    SurfaceCompliance sc(*m.solver, m.inner, 64, 256L << 20, 0L, {}, 0L, bound);
    ASSERT_TRUE(sc.lazy());
    std::mt19937 rng(47);
    std::vector<ContactRow> rows;
    for (int r = 0; r < 12; ++r) rows.push_back(random_vertex_face(rng, m, false));
    for (int k = 0; k < 5; ++k) {
      // Each set keeps most of the last one's rows and adds new ones.
      rows.erase(rows.begin(), rows.begin() + 3);
      for (int r = 0; r < 3 + 2 * k; ++r) rows.push_back(random_vertex_face(rng, m, false));
      const Eigen::MatrixXd H = dense_H(rows, m.n());
      const Eigen::MatrixXd twin = H * m.Kinv * H.transpose();
      CouplingMatrix by_product(sc, rows), by_columns(sc, rows);
      const Eigen::MatrixXd A = by_product.dense();
      const int size = static_cast<int>(rows.size());
      Eigen::MatrixXd columns(size, size);
      for (int s = 0; s < size; ++s) columns.col(s) = by_columns.column(s);
      EXPECT_LE((A - twin).norm(), 1e-9 * twin.norm()) << "bound " << bound << ", set " << k;
      EXPECT_LE((A - columns).norm(), 1e-12 * twin.norm()) << "bound " << bound << ", set " << k;
    }
  }
  EXPECT_THROW(SurfaceCompliance(*m.solver, m.inner, 64, 256L << 20, 0L, {}, 0L, 0), std::invalid_argument);
}

// A lazy set readied for couplings on some nodes (prepare_couplings, as a contact Hessian made on the background thread
// is, here on more nodes than the rows touch) solves no half column for a coupling on them, and that coupling, from
// the kept gram's blocks, equals the dense twin and the coupling of a set not readied.
TEST(CouplingMatrix, ReadiedForItsNodesSolvesNothingMoreAndEqualsTheTwin) {
  const Model& m = model();
  SurfaceCompliance readied(*m.solver, m.inner, 64, 256L << 20, 0L), plain(*m.solver, m.inner, 64, 256L << 20, 0L);
  ASSERT_TRUE(readied.lazy());
  std::mt19937 rng(53);
  std::vector<ContactRow> rows;
  for (int r = 0; r < 20; ++r) rows.push_back(random_vertex_face(rng, m, false));
  std::vector<int> nodes = row_nodes(rows);
  const size_t touched = nodes.size();
  for (int k = 0; k < 6; ++k) nodes.push_back(m.inner[static_cast<size_t>(k) * m.inner.size() / 6]);
  readied.prepare_couplings(nodes);
  const int solved = readied.n_set_columns();
  EXPECT_GE(solved, static_cast<int>(touched));
  const Eigen::MatrixXd H = dense_H(rows, m.n());
  const Eigen::MatrixXd twin = H * m.Kinv * H.transpose();
  const Eigen::MatrixXd A = CouplingMatrix(readied, rows).dense(), B = CouplingMatrix(plain, rows).dense();
  EXPECT_EQ(readied.n_set_columns(), solved);
  EXPECT_LE((A - twin).norm(), 1e-9 * twin.norm());
  EXPECT_LE((A - B).norm(), 1e-12 * twin.norm());
}

}  // namespace
}  // namespace lumen::physics
