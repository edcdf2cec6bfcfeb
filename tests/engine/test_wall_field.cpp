// The full-field error over the inner wall (engine/wall_field): a reference_inner_wall CSV read back, its trapezoid
// integral against the cylinder's analytic area, a field the mesh holds exactly against itself (no error; a scaled
// one: its exact relative error), the interpolation error of a smooth field falling at second order with the mesh,
// and the reader's and the comparison's errors naming the file, the line and the field.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "engine/wall_field.hpp"
#include "physics/mesh.hpp"
#include "support/files.hpp"

using namespace lumen;

namespace {

constexpr double kRadius = 0.01, kLength = 0.1;  // metres: the paper tube's inner wall
using Field = std::function<Eigen::Vector3d(double angle, double z)>;

// A reference CSV on na angles (uniform from -pi + offset) x nz positions along z (uniform over the length), the
// displacement from `field`; its path.
std::string write_field(const std::string& name, int na, int nz, const Field& field, const std::string& header =
                        "# case test, F = 0.002 N per tip; inner wall of the full tube\n") {
  std::ostringstream s;
  s.precision(9);
  s << header << "x_m,y_m,z_m,ux_m,uy_m,uz_m\n";
  for (int j = 0; j < nz; ++j)
    for (int i = 0; i < na; ++i) {
      const double a = -EIGEN_PI + 2.0 * EIGEN_PI * (i + 0.3) / na, z = kLength * j / (nz - 1);
      const Eigen::Vector3d u = field(a, z);
      s << kRadius * std::cos(a) << "," << kRadius * std::sin(a) << "," << z << "," << u.x() << "," << u.y() << ","
        << u.z() << "\n";
    }
  return test::write_temp(name, s.str());
}

// The inner wall of a hollow cylinder (one layer) and the field at its nodes' rest positions.
struct Wall {
  physics::TetMesh mesh;
  Eigen::VectorXd u;
  Wall(int around, int along, const Field& field) {
    physics::HollowCylinderSpec spec;
    spec.segments_around = around;
    spec.segments_along = along;
    spec.layers = 1;
    mesh = physics::make_hollow_cylinder(spec);
    u.resize(3 * mesh.n_nodes());
    for (int v = 0; v < mesh.n_nodes(); ++v)
      u.segment<3>(3 * v) = field(std::atan2(mesh.rest(v, 1), mesh.rest(v, 0)), mesh.rest(v, 2));
  }
  engine::WallFieldError error(const engine::WallField& f, double scale = 1.0) const {
    return engine::wall_field_error(mesh.rest, mesh.surface(physics::kInnerWall), u, f, scale);
  }
};

// A bulge: radial, largest at mid-length, zero at the ends.
Eigen::Vector3d bulge(double a, double z) {
  return 1e-3 * std::sin(EIGEN_PI * z / kLength) * Eigen::Vector3d(std::cos(a), std::sin(a), 0.0);
}

}  // namespace

TEST(WallField, ReadsTheGridAndIntegratesOverTheCylindersArea) {
  const Eigen::Vector3d c(1e-3, -2e-3, 5e-4);
  const engine::WallField f = engine::read_wall_field(write_field("wf_const.csv", 48, 21, [&](double, double) {
    return c;
  }));
  EXPECT_DOUBLE_EQ(f.force_n, 0.002);
  EXPECT_NEAR(f.radius, kRadius, 1e-12);
  ASSERT_EQ(f.angle.size(), 48u);
  ASSERT_EQ(f.z.size(), 21u);
  EXPECT_NEAR(f.angle[0], -EIGEN_PI + 2.0 * EIGEN_PI * 0.3 / 48, 1e-7);
  // A constant field: its L2 norm is |c| times the square root of the wall's area, 2 pi r L.
  const Wall w(12, 6, [&](double, double) { return c; });
  const engine::WallFieldError e = w.error(f);
  EXPECT_EQ(e.samples, 48 * 21);
  EXPECT_NEAR(e.reference_l2, c.norm() * std::sqrt(2.0 * EIGEN_PI * kRadius * kLength), 1e-9 * e.reference_l2);
  EXPECT_LT(e.relative_l2, 1e-9);
}

TEST(WallField, AFieldTheMeshHoldsExactlyHasNoErrorAndAScaledOneItsExactError) {
  // Linear along z and constant around: the mesh's piecewise-linear field is exact at every grid node.
  const Field linear = [](double, double z) { return Eigen::Vector3d(2e-4, -1e-4 + 3e-3 * z, 1e-2 * z); };
  const engine::WallField f = engine::read_wall_field(write_field("wf_linear.csv", 64, 33, linear));
  const Wall w(20, 26, linear);
  EXPECT_LT(w.error(f).relative_l2, 1e-7);  // (the CSV's 9 digits)
  // Against twice the field: |u - 2u| / |2u| = 1/2, whatever the weights.
  EXPECT_NEAR(w.error(f, 2.0).relative_l2, 0.5, 1e-7);
  // A mesh displaced by the reference plus a constant offset d: |d| sqrt(area) / |u_ref|.
  Wall shifted(20, 26, linear);
  const Eigen::Vector3d d(1e-5, 0.0, 0.0);
  for (int v = 0; v < shifted.mesh.n_nodes(); ++v) shifted.u.segment<3>(3 * v) += d;
  const engine::WallFieldError e = shifted.error(f);
  EXPECT_NEAR(e.relative_l2, d.norm() * std::sqrt(2.0 * EIGEN_PI * kRadius * kLength) / e.reference_l2, 1e-3 * e.relative_l2);
}

TEST(WallField, ASmoothFieldsInterpolationErrorFallsAtSecondOrder) {
  const engine::WallField f = engine::read_wall_field(write_field("wf_bulge.csv", 400, 201, bulge));
  double previous = 0.0;
  for (const int n : {8, 16, 32}) {
    SCOPED_TRACE(n);
    const double e = Wall(n, n, bulge).error(f).relative_l2;
    EXPECT_GT(e, 0.0);
    if (previous > 0.0) {
      const double order = std::log2(previous / e);
      EXPECT_GT(order, 1.8);
      EXPECT_LT(order, 2.2);
    }
    previous = e;
  }
}

TEST(WallField, BadFilesAndUncoveredWallsAreNamed) {
  const auto read_error = [](const std::string& path) {
    return test::message_of<std::runtime_error>([&] { engine::read_wall_field(path); });
  };
  const Field zero = [](double, double) { return Eigen::Vector3d::Zero(); };
  const std::string good = write_field("wf_good.csv", 8, 3, zero);
  std::string text;
  {
    std::ifstream in(good);
    std::stringstream s;
    s << in.rdbuf();
    text = s.str();
  }
  // A cell that is not a number: the file, its line (two comment/header lines, then the nodes) and the column.
  std::string bad = text;
  const size_t third_node = bad.find('\n', bad.find('\n', bad.find('\n', bad.find('\n') + 1) + 1) + 1);
  const size_t last_comma = bad.rfind(',', bad.find('\n', third_node + 1));
  bad.replace(last_comma + 1, bad.find('\n', third_node + 1) - last_comma - 1, "abc");
  const std::string bad_path = test::write_temp("wf_bad_cell.csv", bad);
  EXPECT_EQ(read_error(bad_path), bad_path + ":5: uz_m is not a number (\"abc\")");
  // No force in the comments.
  const std::string no_force = write_field("wf_no_force.csv", 8, 3, zero, "# inner wall\n");
  EXPECT_NE(read_error(no_force).find(no_force + ": no force"), std::string::npos) << read_error(no_force);
  // A node missing from the grid.
  const std::string missing = test::write_temp("wf_missing.csv", text.substr(0, text.rfind('\n', text.size() - 2) + 1));
  EXPECT_NE(read_error(missing).find("23 nodes are not a full grid of 8 angles x 3 positions"), std::string::npos)
      << read_error(missing);
  // A node off the wall's radius, first or last (the wall's radius is the nodes' median: the good ones are not blamed).
  std::string off = text;
  off.insert(off.find("x_m,y_m,z_m,ux_m,uy_m,uz_m\n") + 27, "0.02,0,0,0,0,0\n");
  const std::string off_path = test::write_temp("wf_off.csv", off);
  EXPECT_NE(read_error(off_path).find(off_path + ":3: x_m, y_m at radius"), std::string::npos) << read_error(off_path);
  const std::string off_last = test::write_temp("wf_off_last.csv", text + "0.2,0,0,0,0,0\n");
  EXPECT_NE(read_error(off_last).find(off_last + ":27: x_m, y_m at radius 0.2"), std::string::npos)
      << read_error(off_last);
  // A node twice (in place of another: the grid's size is right, one of its nodes is missing).
  std::vector<std::string> lines;
  {
    std::stringstream ss(text);
    for (std::string l; std::getline(ss, l);) lines.push_back(l);
  }
  lines[6] = lines[5];  // (line 7 repeats line 6)
  std::string twice;
  for (const std::string& l : lines) twice += l + "\n";
  const std::string twice_path = test::write_temp("wf_twice.csv", twice);
  EXPECT_EQ(read_error(twice_path), twice_path + ":7: x_m, y_m, z_m repeat a node's");
  // The wrong header; a missing file.
  const std::string header = test::write_temp("wf_header.csv", "# F = 0.002 N\nx,y,z,ux,uy,uz\n");
  EXPECT_EQ(read_error(header), header + ":2: the header must be x_m,y_m,z_m,ux_m,uy_m,uz_m (column 1 is \"x\")");
  EXPECT_EQ(read_error("/nonexistent/wall.csv"), "/nonexistent/wall.csv: cannot be read");
  // A mesh whose wall covers half the tube's length.
  const engine::WallField f = engine::read_wall_field(good);
  Wall half(8, 4, zero);
  physics::HollowCylinderSpec spec;
  spec.length = 0.05;
  half.mesh = physics::make_hollow_cylinder(spec);
  half.u.setZero(3 * half.mesh.n_nodes());
  const std::string uncovered = test::message_of<std::invalid_argument>([&] { half.error(f); });
  EXPECT_NE(uncovered.find("does not cover " + good + "'s node at angle"), std::string::npos) << uncovered;
}
