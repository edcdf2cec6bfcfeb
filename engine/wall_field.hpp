#pragma once
// The full-field error of issue 9: a mesh's displacement over the tube's inner wall against the converged CalculiX
// reference's (tools/reference/ccx_reference.py writes it as reference_inner_wall_<case>.csv: the wall's nodes, on
// a tensor grid of angle about the tube's axis z and position along it, with their displacement).
#include <string>
#include <vector>

#include <Eigen/Core>

#include "physics/types.hpp"

namespace lumen::engine {

// A displacement field sampled on the inner wall's (angle, z) grid.
struct WallField {
  std::string path;            // the file it was read from
  double force_n = 0.0;        // newtons per tip, from the header's "F = <value> N"
  double radius = 0.0;         // metres: the nodes' distance from the axis (their median)
  std::vector<double> angle;   // radians in [-pi, pi), ascending  [n_angle]
  std::vector<double> z;       // metres, ascending                [n_z]
  Eigen::MatrixX3d u;          // metres: the displacement at (angle[i], z[j]) in row j * n_angle + i  [n_angle * n_z]
};

// Reads a reference_inner_wall_<case>.csv: comment lines ('#', one of them with "F = <value> N"), the header
// x_m,y_m,z_m,ux_m,uy_m,uz_m, then one node a line. Throws std::runtime_error naming the file, and the line and the
// field where one is at fault (a cell that is not a number, a missing cell, a node off the wall's radius), or what
// the whole file lacks (the header, the force, a full grid of angle x z).
WallField read_wall_field(const std::string& path);

struct WallFieldError {
  double relative_l2 = 0.0;   // |u_mesh - u_ref|_L2 / |u_ref|_L2 over the wall
  double reference_l2 = 0.0;  // |u_ref|_L2, metres^2: the square root of the integral of |u_ref|^2 over the wall
  int samples = 0;            // the grid nodes compared (all of them)
};

// The mesh's displacement u (3 n_nodes) over its wall triangles (rows of node ids), sampled at the reference's grid
// nodes by linear interpolation over the triangle that holds each in the (angle, z) coordinates of its rest nodes
// (so the interpolant is the mesh's own piecewise-linear field over that surface; a quadratic mesh's wall is its 4
// sub-triangles a face), against reference.u times `scale` (a linear reference taken at another force), integrated
// by the trapezoid rule on the reference's grid: dA = radius d(angle) dz, periodic in angle. The rest nodes must lie
// around the z axis. Throws std::invalid_argument when a grid node is on no triangle (the mesh's wall does not cover
// the reference's), naming the node.
WallFieldError wall_field_error(const Points& rest, const Tris& wall, const Eigen::VectorXd& u,
                                const WallField& reference, double scale = 1.0);

}  // namespace lumen::engine
