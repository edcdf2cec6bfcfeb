// Tet shape quality: dihedral angles, radius ratio, degenerate and inverted tets.
#include "physics/mesh_quality.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include <Eigen/Geometry>

namespace lumen::physics {

namespace {

// Local corners of the face opposite each corner, ordered so the normal (b - a) x (c - a) points out of a
// positively oriented tet.
constexpr int kOppositeFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
// Percentiles reported for each quality measure.
constexpr double kLowPercentile = 1.0;
constexpr double kMedianPercentile = 50.0;
constexpr double kRadiansToDegrees = 180.0 / 3.14159265358979323846;

// The three percentiles of a measure (values in any order; sorted here).
QualityPercentiles percentiles_of(Eigen::VectorXd values) {
  std::sort(values.data(), values.data() + values.size());
  QualityPercentiles q;
  q.min = values.size() > 0 ? values(0) : 0.0;
  q.p1 = sorted_percentile(values, kLowPercentile);
  q.p50 = sorted_percentile(values, kMedianPercentile);
  return q;
}

}  // namespace

TetShape tet_shape(const Eigen::Matrix<double, 4, 3>& X) {
  TetShape s;
  // Edge vectors from corner 0 (metres) and the signed volume.
  const Eigen::Vector3d a = (X.row(1) - X.row(0)).transpose();
  const Eigen::Vector3d b = (X.row(2) - X.row(0)).transpose();
  const Eigen::Vector3d c = (X.row(3) - X.row(0)).transpose();
  s.volume = a.dot(b.cross(c)) / 6.0;
  // Longest edge, for the scale-free degeneracy test.
  double longest = 0.0;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) longest = std::max(longest, (X.row(i) - X.row(j)).norm());
  s.degenerate = !(s.volume > kDegenerateVolumeFraction * longest * longest * longest);
  if (s.degenerate) return s;
  // Outward face normals (length = twice the face area), face f opposite corner f.
  Eigen::Matrix<double, 4, 3> n;
  double area_sum = 0.0;
  for (int f = 0; f < 4; ++f) {
    const auto& k = kOppositeFace[f];
    n.row(f) = (X.row(k[1]) - X.row(k[0])).cross(X.row(k[2]) - X.row(k[0]));
    area_sum += 0.5 * n.row(f).norm();
  }
  // The dihedral angle at the edge shared by faces f and g is pi minus the angle between their outward normals.
  // The smallest angle has the largest cosine -n_f . n_g.
  double largest_cos = -1.0;
  for (int f = 0; f < 4; ++f)
    for (int g = f + 1; g < 4; ++g)
      largest_cos = std::max(largest_cos, -n.row(f).normalized().dot(n.row(g).normalized()));
  s.min_dihedral_deg = std::acos(std::clamp(largest_cos, -1.0, 1.0)) * kRadiansToDegrees;
  // Inradius 3 V / area; circumradius |a^2 (b x c) + b^2 (c x a) + c^2 (a x b)| / (12 V).
  const double inradius = 3.0 * s.volume / area_sum;
  const Eigen::Vector3d w = a.squaredNorm() * b.cross(c) + b.squaredNorm() * c.cross(a) + c.squaredNorm() * a.cross(b);
  const double circumradius = w.norm() / (12.0 * s.volume);
  s.radius_ratio = 3.0 * inradius / circumradius;
  return s;
}

double sorted_percentile(const Eigen::Ref<const Eigen::VectorXd>& sorted, double q) {
  const Eigen::Index n = sorted.size();
  if (n == 0) return 0.0;
  const double pos = q / 100.0 * static_cast<double>(n - 1);
  const Eigen::Index lo = static_cast<Eigen::Index>(std::floor(pos));
  const Eigen::Index hi = std::min(lo + 1, n - 1);
  return sorted(lo) + (pos - static_cast<double>(lo)) * (sorted(hi) - sorted(lo));
}

MeshQuality mesh_quality(const Points& x, const Tets& tets) {
  MeshQuality q;
  q.tets = static_cast<int>(tets.rows());
  // Per-tet measures; a degenerate tet counts with angle 0 and ratio 0.
  Eigen::VectorXd dihedral(tets.rows()), ratio(tets.rows());
  for (int t = 0; t < tets.rows(); ++t) {
    Eigen::Matrix<double, 4, 3> X;
    for (int k = 0; k < 4; ++k) X.row(k) = x.row(tets(t, k));
    const TetShape s = tet_shape(X);
    dihedral(t) = s.min_dihedral_deg;
    ratio(t) = s.radius_ratio;
    if (s.degenerate && q.degenerate_tets++ == 0) q.first_degenerate = t;
  }
  q.min_dihedral_deg = percentiles_of(std::move(dihedral));
  q.radius_ratio = percentiles_of(std::move(ratio));
  return q;
}

}  // namespace lumen::physics
