// Framing from rest geometry: bounding box of the points, lumen axis and radius from the lumen triangles' nodes.
#include "render/renderer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>

namespace lumen::render {

Framing frame_organ(const double* points, int n_points, const int* lumen_triangles, int n_lumen_triangles,
                    double cutaway_degrees) {
  if (n_points <= 0) throw std::invalid_argument("frame_organ: n_points must be > 0 (value " + std::to_string(n_points) + ")");
  if (points == nullptr) throw std::invalid_argument("frame_organ: points is null");
  if (n_lumen_triangles < 0)
    throw std::invalid_argument("frame_organ: n_lumen_triangles must be >= 0 (value " + std::to_string(n_lumen_triangles) + ")");
  if (n_lumen_triangles > 0 && lumen_triangles == nullptr) throw std::invalid_argument("frame_organ: lumen_triangles is null");
  using Vec3 = Eigen::Vector3d;
  auto point = [&](int i) { return Vec3(points[3 * i], points[3 * i + 1], points[3 * i + 2]); };

  // Bounding box of all points: the orbit cameras' centre and bounding sphere.
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (int i = 0; i < n_points; ++i) {
    const Vec3 p = point(i);
    if (!std::isfinite(p.x()) || !std::isfinite(p.y()) || !std::isfinite(p.z()))
      throw std::invalid_argument("frame_organ: point " + std::to_string(i) + " is not finite");
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  Framing f;
  f.center = 0.5 * (lo + hi);
  f.radius = 0.5 * (hi - lo).norm();
  f.cutaway_degrees = cutaway_degrees;

  // Lumen nodes: every point used by a lumen triangle, once; all points when there is no lumen.
  std::vector<int> nodes;
  if (n_lumen_triangles > 0) {
    std::vector<char> used(n_points, 0);
    for (int k = 0; k < 3 * n_lumen_triangles; ++k) {
      const int v = lumen_triangles[k];
      if (v < 0 || v >= n_points)
        throw std::invalid_argument("frame_organ: lumen_triangles[" + std::to_string(k) + "] out of range [0, " +
                                    std::to_string(n_points) + ") (value " + std::to_string(v) + ")");
      if (!used[v]) {
        used[v] = 1;
        nodes.push_back(v);
      }
    }
  } else {
    nodes.resize(n_points);
    for (int i = 0; i < n_points; ++i) nodes[i] = i;
  }

  // Principal axis: eigenvector of the largest eigenvalue of the nodes' covariance about their mean.
  Vec3 mean = Vec3::Zero();
  for (int v : nodes) mean += point(v);
  mean /= static_cast<double>(nodes.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (int v : nodes) {
    const Vec3 d = point(v) - mean;
    cov += d * d.transpose();
  }
  Vec3 axis = Vec3::UnitZ();
  if (cov.norm() > 0) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    axis = eig.eigenvectors().col(2).normalized();  // eigenvalues ascending
    int big = 0;
    axis.cwiseAbs().maxCoeff(&big);
    if (axis[big] < 0) axis = -axis;
  }
  f.axis = axis;

  // Extent along the axis, and mean distance from it.
  double s_lo = std::numeric_limits<double>::infinity(), s_hi = -s_lo, dist = 0;
  for (int v : nodes) {
    const Vec3 d = point(v) - mean;
    const double s = d.dot(axis);
    s_lo = std::min(s_lo, s);
    s_hi = std::max(s_hi, s);
    dist += (d - s * axis).norm();
  }
  dist /= static_cast<double>(nodes.size());
  if (n_lumen_triangles > 0) {
    f.lumen_center = mean + 0.5 * (s_lo + s_hi) * axis;
    f.half_length = 0.5 * (s_hi - s_lo);
    f.lumen_radius = dist;
  } else {
    f.lumen_center = f.center;
    f.half_length = 0.0;
    f.lumen_radius = 0.1 * f.radius;
  }
  // The renderer needs 0 < lumen_radius < radius (degenerate lumens: a point, a line).
  if (!(f.radius > 0)) f.radius = 1e-3;
  if (!(f.lumen_radius > 0) || !(f.lumen_radius < f.radius)) f.lumen_radius = 0.1 * f.radius;
  return f;
}

}  // namespace lumen::render
