#pragma once
// Elastic supports: an organ held by the tissue around it, as springs to rest on a wall (a Winkler foundation).
// Each node of the wall gets an isotropic spring of stiffness k times its lumped area (a third of the area of every
// wall triangle it belongs to), so the springs push back k per unit area and unit displacement.
#include <Eigen/SparseCore>

#include "physics/types.hpp"

namespace lumen::physics {

// Lumped area per node of a triangle surface over `rest` (n_nodes x 3, metres): a third of each triangle's area
// to each of its corners, n_nodes entries (0 off the surface), m^2.
Eigen::VectorXd lumped_areas(const Points& rest, const Tris& surface);

// The supports' stiffness, 3n x 3n diagonal: k (N/m^3, pressure per metre of displacement) times each node's lumped
// area on all three of its DOFs, N/m. Add it to K.
Eigen::SparseMatrix<double> support_stiffness(const Points& rest, const Tris& surface, double k);

}  // namespace lumen::physics
