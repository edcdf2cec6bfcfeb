#pragma once
// Lame thick-walled cylinder under internal pressure (plane strain): an analytic check of the FEM, reusable by
// studies that sweep the mesh resolution.
#include "physics/fem.hpp"
#include "physics/quadratic.hpp"

namespace lumen::physics {

// A hollow-cylinder section under internal pressure with u_z = 0 on both end faces (plane strain) and the three
// rigid in-plane motions removed by single DOFs at the start end's inner ring: u_y = 0 at angles 0 and pi,
// u_x = 0 at angle pi/2 (the load is self-equilibrated, so these carry no reaction).
struct LameSetup {
  int segments_around = 20;     // cells around, a multiple of 4
  int segments_along = 1;       // cells along
  int layers = 3;               // cells through the wall
  double inner_radius = 0.01;   // a, metres
  double outer_radius = 0.013;  // b, metres
  // Section length, metres; 0 = segments_along x the circumferential cell size at mid-wall (near-cubic cells).
  double length = 0.0;
  LinearMaterial material{5000.0, 0.45};
  double pressure = 100.0;  // internal pressure p, pascals
  // 4-node tets, or 10-node isoparametric tets (make_quadratic_cylinder) with u_z = 0 on every end node (corner
  // and edge) and the same three in-plane pins (at corner nodes).
  ElementOrder element = ElementOrder::kLinear;
};

struct LameResult {
  double rel_l2_error = 0.0;    // sqrt(sum (u_r - u_r*)^2 / sum u_r*^2) over all nodes (corners and edge nodes)
  double max_rel_error = 0.0;   // max |u_r - u_r*| / max |u_r*|
  double max_tangential = 0.0;  // max |u_theta| / max |u_r*| (exact: 0)
  double max_axial = 0.0;       // max |u_z| / max |u_r*| (exact: 0)
  int n_nodes = 0;  // all nodes (3 DOFs each)
  int n_tets = 0;
};

// Exact radial displacement u_r(r) = (1+nu)/E p a^2/(b^2-a^2) ((1-2nu) r + b^2/r), metres.
double lame_radial_displacement(double r, double a, double b, const LinearMaterial& m, double pressure);

// Builds the mesh, applies the pressure as consistent nodal forces pointing out of the lumen (linear: p * area / 3
// per vertex of each inner triangle; quadratic: tri6_pressure_load on each curved 6-node inner face), solves, and
// compares u_r with the exact solution at every node.
LameResult lame_error(const LameSetup& setup);
// Shorthand with the default radii: E pascals, nu, p pascals.
LameResult lame_error(int around, int along, int layers, double E, double nu, double p,
                      ElementOrder element = ElementOrder::kLinear);

}  // namespace lumen::physics
