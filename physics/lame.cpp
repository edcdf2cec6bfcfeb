// Lame thick-walled cylinder check of the tetrahedral FEM (linear and quadratic tets).
#include "physics/lame.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "physics/mesh.hpp"

namespace lumen::physics {

namespace {

// Node of `ring` (node ids) closest to point p.
int closest(const Points& x, const std::vector<int>& ring, const Eigen::Vector3d& p) {
  int best = ring.front();
  for (int v : ring)
    if ((x.row(v).transpose() - p).squaredNorm() < (x.row(best).transpose() - p).squaredNorm()) best = v;
  return best;
}

}  // namespace

double lame_radial_displacement(double r, double a, double b, const LinearMaterial& m, double pressure) {
  const double E = m.young_modulus, nu = m.poisson_ratio;
  return (1.0 + nu) / E * pressure * a * a / (b * b - a * a) * ((1.0 - 2.0 * nu) * r + b * b / r);
}

LameResult lame_error(const LameSetup& setup) {
  validate_material(setup.material);
  if (setup.segments_around < 4 || setup.segments_around % 4 != 0) {
    throw std::invalid_argument("LameSetup.segments_around must be a positive multiple of 4, got " +
                                std::to_string(setup.segments_around));
  }
  if (!std::isfinite(setup.pressure) || setup.pressure == 0.0) {
    std::ostringstream msg;
    msg << "LameSetup.pressure must be finite and non-zero, got " << setup.pressure;
    throw std::invalid_argument(msg.str());
  }
  if (setup.element != ElementOrder::kLinear && setup.element != ElementOrder::kQuadratic) {
    throw std::invalid_argument("LameSetup.element must be kLinear or kQuadratic, got " +
                                std::to_string(static_cast<int>(setup.element)));
  }
  if (!(setup.length >= 0.0)) {
    std::ostringstream msg;
    msg << "LameSetup.length must be >= 0 (0 = automatic), got " << setup.length;
    throw std::invalid_argument(msg.str());
  }
  // Mesh (the generator validates radii and counts).
  HollowCylinderSpec spec;
  spec.inner_radius = setup.inner_radius;
  spec.outer_radius = setup.outer_radius;
  spec.segments_around = setup.segments_around;
  spec.segments_along = setup.segments_along;
  spec.layers = setup.layers;
  spec.length = setup.length > 0.0
                    ? setup.length
                    : setup.segments_along * kPi *
                          (setup.inner_radius + setup.outer_radius) / setup.segments_around;
  const TetMesh mesh = make_hollow_cylinder(spec);
  const double a = spec.inner_radius, b = spec.outer_radius;
  const bool quadratic = setup.element == ElementOrder::kQuadratic;
  const QuadraticMesh qmesh = quadratic ? make_quadratic_cylinder(mesh, spec) : QuadraticMesh{};
  const Points& x = quadratic ? qmesh.rest : mesh.rest;  // all nodes, n x 3, metres
  const int n = static_cast<int>(x.rows());

  // Constraints: u_z = 0 on both ends (every end node); u_y = 0 at angles 0 and pi, u_x = 0 at pi/2 on the start
  // inner ring (corner nodes, the same ids for both element orders).
  std::vector<FixedDof> fixed;
  for (int v : quadratic ? qmesh.node_set(kStartEnd) : mesh.node_set(kStartEnd)) fixed.push_back({v, 2});
  for (int v : quadratic ? qmesh.node_set(kStopEnd) : mesh.node_set(kStopEnd)) fixed.push_back({v, 2});
  fixed.push_back({closest(mesh.rest, mesh.node_set(kStartEnd), {a, 0.0, 0.0}), 1});
  fixed.push_back({closest(mesh.rest, mesh.node_set(kStartEnd), {-a, 0.0, 0.0}), 1});
  fixed.push_back({closest(mesh.rest, mesh.node_set(kStartEnd), {0.0, a, 0.0}), 0});

  // Pressure as consistent nodal forces out of the lumen (the inner triangles' normals point into it).
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * n);
  if (quadratic) {
    // Curved 6-node faces: quadrature of p N_a n dA over each face's quadratic map.
    for (int t = 0; t < qmesh.surface(kInnerWall).rows(); ++t) {
      Eigen::Matrix<double, 6, 3> X6;
      for (int c = 0; c < 6; ++c) X6.row(c) = x.row(qmesh.surface(kInnerWall)(t, c));
      const Eigen::Matrix<double, 6, 3> f6 = tri6_pressure_load(X6, setup.pressure);
      for (int c = 0; c < 6; ++c) f.segment<3>(3 * qmesh.surface(kInnerWall)(t, c)) += f6.row(c).transpose();
    }
  } else {
    // Flat triangles: p * area / 3 per vertex, along -(inner normal).
    for (int t = 0; t < mesh.surface(kInnerWall).rows(); ++t) {
      const Eigen::Vector3d x0 = mesh.rest.row(mesh.surface(kInnerWall)(t, 0)).transpose();
      const Eigen::Vector3d x1 = mesh.rest.row(mesh.surface(kInnerWall)(t, 1)).transpose();
      const Eigen::Vector3d x2 = mesh.rest.row(mesh.surface(kInnerWall)(t, 2)).transpose();
      const Eigen::Vector3d area_normal = 0.5 * (x1 - x0).cross(x2 - x0);  // into the lumen, |.| = area
      for (int c = 0; c < 3; ++c) f.segment<3>(3 * mesh.surface(kInnerWall)(t, c)) -= setup.pressure / 3.0 * area_normal;
    }
  }

  // Solve and compare the radial displacement at every node.
  const StaticSolver solver(quadratic ? assemble_stiffness(qmesh, setup.material)
                                      : assemble_stiffness(mesh, setup.material),
                            fixed);
  Eigen::VectorXd u;
  solver.solve(f, u);
  double err2 = 0.0, ref2 = 0.0, max_err = 0.0, max_ref = 0.0, max_t = 0.0, max_z = 0.0;
  for (int v = 0; v < n; ++v) {
    const double px = x(v, 0), py = x(v, 1), r = std::hypot(px, py);
    const double ur = (u[3 * v] * px + u[3 * v + 1] * py) / r;
    const double ut = (-u[3 * v] * py + u[3 * v + 1] * px) / r;
    const double exact = lame_radial_displacement(r, a, b, setup.material, setup.pressure);
    err2 += (ur - exact) * (ur - exact);
    ref2 += exact * exact;
    max_err = std::max(max_err, std::abs(ur - exact));
    max_ref = std::max(max_ref, std::abs(exact));
    max_t = std::max(max_t, std::abs(ut));
    max_z = std::max(max_z, std::abs(u[3 * v + 2]));
  }
  LameResult res;
  res.rel_l2_error = std::sqrt(err2 / ref2);
  res.max_rel_error = max_err / max_ref;
  res.max_tangential = max_t / max_ref;
  res.max_axial = max_z / max_ref;
  res.n_nodes = n;
  res.n_tets = static_cast<int>(mesh.tets.rows());
  return res;
}

LameResult lame_error(int around, int along, int layers, double E, double nu, double p, ElementOrder element) {
  LameSetup s;
  s.segments_around = around;
  s.segments_along = along;
  s.layers = layers;
  s.material = {E, nu};
  s.pressure = p;
  s.element = element;
  return lame_error(s);
}

}  // namespace lumen::physics
