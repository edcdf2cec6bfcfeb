#include "engine/wall_field.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <limits>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "physics/types.hpp"

namespace lumen::engine {

namespace {

using physics::kPi;

constexpr double kTwoPi = 2.0 * kPi;
// Grid coordinates closer than this fraction of their range are the same grid line (the CSV prints 7 significant
// digits: one z printed twice differs by up to 1e-8 m on a 0.1 m tube, the angles of one node's printed x, y by about
// 1e-7 rad; the reference's finest cells are about 1e-4 of the range).
constexpr double kSameLine = 1e-6;
// A node further than this from the mean radius (relative) is not on the wall.
constexpr double kRadiusTolerance = 1e-4;
// A barycentric coordinate at least this negative puts a grid node outside a triangle (round-off on its edges).
constexpr double kOnTriangle = -1e-9;
// The columns of the file, in order.
const char* const kColumns[6] = {"x_m", "y_m", "z_m", "ux_m", "uy_m", "uz_m"};

// The angle of (x, y) about the z axis in [-pi, pi), a point on the seam (within kSameLine of a turn) at -pi.
double angle_of(double x, double y) {
  const double a = std::atan2(y, x);
  return a >= kPi - kSameLine * kTwoPi ? a - kTwoPi : a;
}

// The distinct values of v (sorted), those closer than tol merged into the first.
std::vector<double> grid_lines(std::vector<double> v, double tol) {
  std::sort(v.begin(), v.end());
  std::vector<double> lines;
  for (double x : v)
    if (lines.empty() || x - lines.back() > tol) lines.push_back(x);
  return lines;
}

// The index of the grid line within tol of x, or -1.
int line_of(const std::vector<double>& lines, double x, double tol) {
  const auto it = std::lower_bound(lines.begin(), lines.end(), x - tol);
  return it != lines.end() && *it <= x + tol ? static_cast<int>(it - lines.begin()) : -1;
}

// Trapezoid weights of a grid: half the neighbouring spacings; periodic over `period` when it is positive.
std::vector<double> trapezoid(const std::vector<double>& x, double period) {
  const size_t n = x.size();
  std::vector<double> w(n, 0.0);
  for (size_t i = 0; i < n; ++i) {
    const double before = i > 0 ? x[i] - x[i - 1] : (period > 0.0 ? x[0] + period - x[n - 1] : 0.0);
    const double after = i + 1 < n ? x[i + 1] - x[i] : (period > 0.0 ? x[0] + period - x[n - 1] : 0.0);
    w[i] = 0.5 * (before + after);
  }
  return w;
}

// The wall's triangles in (angle, z), each unwrapped across the seam at +-pi (its angles within pi of its first
// node's), in buckets of a uniform grid over [-pi, pi) x [z0, z1] holding (triangle, shift of 2 pi) pairs.
class WallLocator {
 public:
  WallLocator(const Points& rest, const Tris& wall) : uv_(wall.rows()) {
    const int m = static_cast<int>(wall.rows());
    z0_ = rest(wall(0, 0), 2);
    z1_ = z0_;
    for (int t = 0; t < m; ++t) {
      for (int k = 0; k < 3; ++k) {
        const int v = wall(t, k);
        double a = angle_of(rest(v, 0), rest(v, 1));
        if (k > 0) a += a - uv_[t][0][0] > kPi ? -kTwoPi : (uv_[t][0][0] - a > kPi ? kTwoPi : 0.0);
        uv_[t][k] = {a, rest(v, 2)};
        z0_ = std::min(z0_, rest(v, 2));
        z1_ = std::max(z1_, rest(v, 2));
      }
    }
    n_ = std::max(1, static_cast<int>(std::sqrt(static_cast<double>(m))));
    buckets_.assign(static_cast<size_t>(n_) * n_, {});
    for (int t = 0; t < m; ++t) {
      double a0 = uv_[t][0][0], a1 = a0, zlo = uv_[t][0][1], zhi = zlo;
      for (int k = 1; k < 3; ++k) {
        a0 = std::min(a0, uv_[t][k][0]);
        a1 = std::max(a1, uv_[t][k][0]);
        zlo = std::min(zlo, uv_[t][k][1]);
        zhi = std::max(zhi, uv_[t][k][1]);
      }
      for (const double shift : {-kTwoPi, 0.0, kTwoPi}) {
        const double lo = std::max(a0 + shift, -kPi), hi = std::min(a1 + shift, kPi);
        if (lo > hi) continue;
        for (int i = bin_angle(lo); i <= bin_angle(hi); ++i)
          for (int j = bin_z(zlo); j <= bin_z(zhi); ++j) buckets_[j * n_ + i].push_back({t, shift});
      }
    }
  }

  // The triangle holding (a, z) and its barycentric coordinates; false when none does.
  bool locate(double a, double z, int& tri, Eigen::Vector3d& bary) const {
    double best = -std::numeric_limits<double>::infinity();
    for (const auto& [t, shift] : buckets_[bin_z(z) * n_ + bin_angle(a)]) {
      const Eigen::Vector3d b = barycentric(t, a - shift, z);
      if (b.minCoeff() > best) {
        best = b.minCoeff();
        tri = t;
        bary = b;
      }
    }
    return best >= kOnTriangle;
  }

 private:
  int bin_angle(double a) const { return std::clamp(static_cast<int>((a + kPi) / kTwoPi * n_), 0, n_ - 1); }
  int bin_z(double z) const {
    return z1_ > z0_ ? std::clamp(static_cast<int>((z - z0_) / (z1_ - z0_) * n_), 0, n_ - 1) : 0;
  }
  Eigen::Vector3d barycentric(int t, double a, double z) const {
    const auto& p = uv_[t];
    const double d = (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]);
    const double l1 = ((a - p[0][0]) * (p[2][1] - p[0][1]) - (p[2][0] - p[0][0]) * (z - p[0][1])) / d;
    const double l2 = ((p[1][0] - p[0][0]) * (z - p[0][1]) - (a - p[0][0]) * (p[1][1] - p[0][1])) / d;
    return {1.0 - l1 - l2, l1, l2};
  }

  std::vector<std::array<std::array<double, 2>, 3>> uv_;  // per triangle, per corner: (angle, z)
  double z0_ = 0.0, z1_ = 0.0;
  int n_ = 1;                                             // buckets along each axis
  std::vector<std::vector<std::pair<int, double>>> buckets_;  // [n_ * n_]: (triangle, angle shift)
};

}  // namespace

WallField read_wall_field(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot be read");
  WallField f;
  f.path = path;
  bool have_force = false, have_header = false;
  std::vector<Eigen::Matrix<double, 6, 1>> rows;
  std::vector<int> line_numbers;
  const std::regex force_pattern(R"(F = ([-+0-9.eE]+) N)");
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    if (line.empty()) continue;
    if (line[0] == '#') {
      std::smatch m;
      if (!have_force && std::regex_search(line, m, force_pattern)) {
        f.force_n = std::strtod(m[1].str().c_str(), nullptr);
        have_force = true;
      }
      continue;
    }
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) cells.push_back(cell);
    if (!have_header) {
      for (int c = 0; c < 6; ++c)
        if (c >= static_cast<int>(cells.size()) || cells[c] != kColumns[c])
          throw std::runtime_error(path + ":" + std::to_string(number) +
                                   ": the header must be x_m,y_m,z_m,ux_m,uy_m,uz_m (column " + std::to_string(c + 1) +
                                   " is \"" + (c < static_cast<int>(cells.size()) ? cells[c] : "") + "\")");
      have_header = true;
      continue;
    }
    Eigen::Matrix<double, 6, 1> row;
    for (int c = 0; c < 6; ++c) {
      const std::string cell = c < static_cast<int>(cells.size()) ? cells[c] : "";
      char* end = nullptr;
      row[c] = std::strtod(cell.c_str(), &end);
      if (cell.empty() || *end != '\0' || !std::isfinite(row[c]))
        throw std::runtime_error(path + ":" + std::to_string(number) + ": " + kColumns[c] + " is not a number (\"" +
                                 cell + "\")");
    }
    rows.push_back(row);
    line_numbers.push_back(number);
  }
  if (!have_header) throw std::runtime_error(path + ": no header line x_m,y_m,z_m,ux_m,uy_m,uz_m");
  if (!have_force || !(f.force_n > 0.0))
    throw std::runtime_error(path + ": no force in its comment lines (\"F = <newtons> N\", positive)");
  if (rows.size() < 4) throw std::runtime_error(path + ": " + std::to_string(rows.size()) + " nodes (at least 4)");
  // The wall's radius (the nodes' median distance from the axis, which one node off the wall does not move), each
  // node on it.
  std::vector<double> radii;
  for (const auto& r : rows) radii.push_back(std::hypot(r[0], r[1]));
  std::nth_element(radii.begin(), radii.begin() + radii.size() / 2, radii.end());
  f.radius = radii[radii.size() / 2];
  for (size_t i = 0; i < rows.size(); ++i)
    if (std::abs(std::hypot(rows[i][0], rows[i][1]) - f.radius) > kRadiusTolerance * f.radius)
      throw std::runtime_error(path + ":" + std::to_string(line_numbers[i]) + ": x_m, y_m at radius " +
                               std::to_string(std::hypot(rows[i][0], rows[i][1])) + " m, off the wall's " +
                               std::to_string(f.radius) + " m");
  // The grid: every (angle, z) pair once.
  std::vector<double> angles, zs;
  for (const auto& r : rows) {
    angles.push_back(angle_of(r[0], r[1]));
    zs.push_back(r[2]);
  }
  const auto [z_lo, z_hi] = std::minmax_element(zs.begin(), zs.end());
  const double same_angle = kSameLine * kTwoPi, same_z = kSameLine * (*z_hi - *z_lo);
  f.angle = grid_lines(angles, same_angle);
  f.z = grid_lines(zs, same_z);
  const size_t na = f.angle.size(), nz = f.z.size();
  if (na * nz != rows.size() || na < 3 || nz < 2)
    throw std::runtime_error(path + ": " + std::to_string(rows.size()) + " nodes are not a full grid of " +
                             std::to_string(na) + " angles x " + std::to_string(nz) + " positions along z");
  f.u.setConstant(static_cast<Eigen::Index>(na * nz), 3, std::nan(""));
  for (size_t k = 0; k < rows.size(); ++k) {
    const int i = line_of(f.angle, angles[k], same_angle), j = line_of(f.z, zs[k], same_z);
    const Eigen::Index row = static_cast<Eigen::Index>(j) * static_cast<Eigen::Index>(na) + i;
    if (!std::isnan(f.u(row, 0)))
      throw std::runtime_error(path + ":" + std::to_string(line_numbers[k]) + ": x_m, y_m, z_m repeat a node's");
    f.u.row(row) = rows[k].tail<3>().transpose();
  }
  return f;
}

WallFieldError wall_field_error(const Points& rest, const Tris& wall, const Eigen::VectorXd& u,
                                const WallField& reference, double scale) {
  if (wall.rows() == 0) throw std::invalid_argument("wall_field_error: the wall has no triangles");
  const WallLocator locator(rest, wall);
  const std::vector<double> wa = trapezoid(reference.angle, kTwoPi), wz = trapezoid(reference.z, 0.0);
  const int na = static_cast<int>(reference.angle.size());
  double err2 = 0.0, ref2 = 0.0;
  WallFieldError e;
  for (int j = 0; j < static_cast<int>(reference.z.size()); ++j)
    for (int i = 0; i < na; ++i) {
      int t = 0;
      Eigen::Vector3d b = Eigen::Vector3d::Zero();
      if (!locator.locate(reference.angle[i], reference.z[j], t, b))
        throw std::invalid_argument("wall_field_error: the mesh's wall does not cover " + reference.path +
                                    "'s node at angle " + std::to_string(reference.angle[i]) + " rad, z " +
                                    std::to_string(reference.z[j]) + " m");
      Eigen::Vector3d mesh_u = Eigen::Vector3d::Zero();
      for (int k = 0; k < 3; ++k) mesh_u += b[k] * u.segment<3>(3 * wall(t, k));
      const Eigen::Vector3d ref_u = scale * reference.u.row(static_cast<Eigen::Index>(j) * na + i).transpose();
      const double w = reference.radius * wa[i] * wz[j];
      err2 += w * (mesh_u - ref_u).squaredNorm();
      ref2 += w * ref_u.squaredNorm();
      ++e.samples;
    }
  e.reference_l2 = std::sqrt(ref2);
  e.relative_l2 = ref2 > 0.0 ? std::sqrt(err2 / ref2) : std::nan("");
  return e;
}

}  // namespace lumen::engine
