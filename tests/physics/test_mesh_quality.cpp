// Tet shape quality against analytic values (regular and right-corner tets), a brute-force recomputation on the
// paper's tube, degenerate and inverted tets; the stress helpers against a uniaxial stretch.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "physics/fem.hpp"
#include "physics/mesh.hpp"
#include "physics/mesh_quality.hpp"

namespace lumen::physics {
namespace {

using Mat43 = Eigen::Matrix<double, 4, 3>;
constexpr double kPi = 3.14159265358979323846;

// The regular tet of edge sqrt(8) (alternate corners of a cube), positively oriented.
Mat43 regular_tet() {
  Mat43 X;
  X << 1, 1, 1, 1, -1, -1, -1, 1, -1, -1, -1, 1;
  if (tet_shape(X).volume < 0) X.row(2).swap(X.row(3));
  return X;
}
// The unit right-corner tet: origin and the three unit points.
Mat43 corner_tet() {
  Mat43 X;
  X << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  return X;
}

// Brute force: the dihedral angle at edge (i, j) is the angle between the other two corners' offsets from the
// edge line, projected onto the plane normal to the edge; degrees. The smallest over the six edges.
double brute_min_dihedral(const Mat43& X) {
  double best = 180.0;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) {
      int other[2], m = 0;
      for (int k = 0; k < 4; ++k)
        if (k != i && k != j) other[m++] = k;
      const Eigen::Vector3d e = (X.row(j) - X.row(i)).normalized().transpose();
      Eigen::Vector3d p[2];
      for (int q = 0; q < 2; ++q) {
        const Eigen::Vector3d d = (X.row(other[q]) - X.row(i)).transpose();
        p[q] = d - d.dot(e) * e;
      }
      best = std::min(best, std::atan2(p[0].cross(p[1]).norm(), p[0].dot(p[1])) * 180.0 / kPi);
    }
  return best;
}
// Brute force: the circumcentre solves 2 (X_k - X_0) . c = |X_k|^2 - |X_0|^2, the inradius is 3 V / area.
double brute_radius_ratio(const Mat43& X) {
  Eigen::Matrix3d A;
  Eigen::Vector3d b;
  for (int k = 1; k < 4; ++k) {
    A.row(k - 1) = 2.0 * (X.row(k) - X.row(0));
    b(k - 1) = X.row(k).squaredNorm() - X.row(0).squaredNorm();
  }
  const Eigen::Vector3d c = A.fullPivLu().solve(b);
  const double R = (X.row(0).transpose() - c).norm();
  const double V = std::abs((X.row(1) - X.row(0)).dot((X.row(2) - X.row(0)).cross(X.row(3) - X.row(0)))) / 6.0;
  double area = 0.0;
  const int faces[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
  for (const auto& f : faces) area += 0.5 * (X.row(f[1]) - X.row(f[0])).cross(X.row(f[2]) - X.row(f[0])).norm();
  return 3.0 * (3.0 * V / area) / R;
}

TEST(MeshQuality, RegularTetHasDihedralAcosOneThirdAndRatioOne) {
  const TetShape s = tet_shape(regular_tet());
  EXPECT_NEAR(s.min_dihedral_deg, std::acos(1.0 / 3.0) * 180.0 / kPi, 1e-10);
  EXPECT_NEAR(s.min_dihedral_deg, 70.528779, 1e-6);
  EXPECT_NEAR(s.radius_ratio, 1.0, 1e-12);
  EXPECT_FALSE(s.degenerate);
}

TEST(MeshQuality, RightCornerTetMatchesAnalyticValues) {
  // Dihedral angles: 90 degrees at the three edges through the corner, acos(1/sqrt 3) = 54.74 at the slanted face;
  // inradius 1 / (3 + sqrt 3), circumradius sqrt(3) / 2, so the ratio is sqrt(3) - 1.
  const TetShape s = tet_shape(corner_tet());
  EXPECT_NEAR(s.min_dihedral_deg, std::acos(1.0 / std::sqrt(3.0)) * 180.0 / kPi, 1e-10);
  EXPECT_NEAR(s.radius_ratio, std::sqrt(3.0) - 1.0, 1e-12);
  EXPECT_NEAR(s.volume, 1.0 / 6.0, 1e-15);
}

TEST(MeshQuality, InvertedAndFlatTetsAreDegenerate) {
  Mat43 inverted = corner_tet();
  inverted.row(1).swap(inverted.row(2));
  EXPECT_TRUE(tet_shape(inverted).degenerate);
  EXPECT_LT(tet_shape(inverted).volume, 0.0);
  Mat43 flat = corner_tet();
  flat(3, 2) = 0.0;  // the fourth corner in the plane of the others
  flat(3, 0) = 0.3;
  EXPECT_TRUE(tet_shape(flat).degenerate);
  EXPECT_EQ(tet_shape(flat).radius_ratio, 0.0);
}

TEST(MeshQuality, PaperTubeMatchesBruteForceAndCountsBadTets) {
  TetMesh mesh = make_hollow_cylinder(HollowCylinderSpec{});
  std::vector<double> angles, ratios;
  for (int t = 0; t < mesh.tets.rows(); ++t) {
    Mat43 X;
    for (int k = 0; k < 4; ++k) X.row(k) = mesh.rest.row(mesh.tets(t, k));
    const TetShape s = tet_shape(X);
    ASSERT_NEAR(s.min_dihedral_deg, brute_min_dihedral(X), 1e-9) << "tet " << t;
    ASSERT_NEAR(s.radius_ratio, brute_radius_ratio(X), 1e-9) << "tet " << t;
    angles.push_back(brute_min_dihedral(X));
    ratios.push_back(brute_radius_ratio(X));
  }
  const MeshQuality q = mesh_quality(mesh.rest, mesh.tets);
  EXPECT_EQ(q.tets, 9360);
  EXPECT_EQ(q.degenerate_tets, 0);
  EXPECT_EQ(q.first_degenerate, -1);
  EXPECT_NEAR(q.min_dihedral_deg.min, *std::min_element(angles.begin(), angles.end()), 1e-9);
  EXPECT_NEAR(q.radius_ratio.min, *std::min_element(ratios.begin(), ratios.end()), 1e-9);
  // The median by counting: half the tets at or below it.
  std::sort(ratios.begin(), ratios.end());
  EXPECT_NEAR(q.radius_ratio.p50, 0.5 * (ratios[4679] + ratios[4680]), 1e-12);
  EXPECT_LE(q.min_dihedral_deg.min, q.min_dihedral_deg.p1);
  EXPECT_LE(q.min_dihedral_deg.p1, q.min_dihedral_deg.p50);
  // Flip tets 7 and 20: both counted, the first named.
  mesh.tets.row(7).tail<2>().reverseInPlace();
  mesh.tets.row(20).tail<2>().reverseInPlace();
  const MeshQuality bad = mesh_quality(mesh.rest, mesh.tets);
  EXPECT_EQ(bad.degenerate_tets, 2);
  EXPECT_EQ(bad.first_degenerate, 7);
}

TEST(MeshQuality, SortedPercentileInterpolates) {
  Eigen::VectorXd v(5);
  v << 0.0, 1.0, 2.0, 3.0, 10.0;
  EXPECT_DOUBLE_EQ(sorted_percentile(v, 0.0), 0.0);
  EXPECT_DOUBLE_EQ(sorted_percentile(v, 50.0), 2.0);
  EXPECT_DOUBLE_EQ(sorted_percentile(v, 1.0), 0.04);
  EXPECT_DOUBLE_EQ(sorted_percentile(v, 100.0), 10.0);
}

TEST(Stress, UniaxialStretchHasVonMisesEqualToTheAxialStress) {
  // u = eps X with eps = diag(e, -nu e, -nu e): the uniaxial stress state sigma = diag(E e, 0, 0), von Mises E e.
  const LinearMaterial m{5000.0, 0.45};
  const double e = 1e-3;
  const Eigen::Vector3d strain(e, -m.poisson_ratio * e, -m.poisson_ratio * e);
  const Mat43 X = regular_tet();
  const Mat43 u = X * strain.asDiagonal();
  const Eigen::Matrix3d H = tet_displacement_gradient(X, u);
  EXPECT_LT((H - Eigen::Matrix3d(strain.asDiagonal())).norm(), 1e-15);
  const Eigen::Matrix3d sigma = linear_stress(H, m);
  EXPECT_NEAR(sigma(0, 0), m.young_modulus * e, 1e-9);
  EXPECT_NEAR(sigma(1, 1), 0.0, 1e-9);
  EXPECT_NEAR(von_mises(sigma), m.young_modulus * e, 1e-9);
  // A pure pressure has no von Mises stress; a pure shear tau has sqrt(3) tau.
  EXPECT_NEAR(von_mises(Eigen::Matrix3d::Identity() * 7.0), 0.0, 1e-12);
  Eigen::Matrix3d shear = Eigen::Matrix3d::Zero();
  shear(0, 1) = shear(1, 0) = 2.0;
  EXPECT_NEAR(von_mises(shear), 2.0 * std::sqrt(3.0), 1e-12);
}

}  // namespace
}  // namespace lumen::physics
