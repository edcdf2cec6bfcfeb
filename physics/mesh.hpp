#pragma once
// Tetrahedral mesh with tagged surfaces, and the hollow-cylinder generator.
#include <vector>

#include "physics/types.hpp"

namespace lumen::physics {

// A tetrahedral volume mesh with its boundary surfaces as index maps onto its vertices.
struct TetMesh {
  Points rest;               // rest positions, n_nodes x 3, metres
  Tets tets;                 // elements, n_tets x 4, positive volume
  Tris inner;                // inner (lumen) wall, n_inner x 3, normals point into the lumen (toward the axis)
  Tris outer;                // outer wall, n_outer x 3, normals point away from the axis
  Tris ends;                 // end caps, n_end x 3, normals point out of the volume
  std::vector<int> end_nodes_start;  // node ids on the end z = 0 (or centreline start)
  std::vector<int> end_nodes_stop;   // node ids on the end z = length (or centreline end)
  int n_nodes() const { return static_cast<int>(rest.rows()); }
};

// Parameters of a hollow cylinder along +z from z = 0 to z = length, axis through the origin.
struct HollowCylinderSpec {
  double inner_radius = 0.01;   // metres
  double outer_radius = 0.013;  // metres
  double length = 0.1;          // metres
  int segments_around = 20;     // cells around the circumference
  int segments_along = 26;      // cells along the axis
  int layers = 3;               // cells through the wall
  // Optional bend: the centreline is an arc of this radius in the x-z plane (0 = straight), metres.
  double bend_radius = 0.0;
};

// Structured hex grid (around x along x layers), 6 tets per hex (consistent diagonals, conforming).
// Nodes: around * (along + 1) * (layers + 1); tets: 6 * around * along * layers;
// inner triangles: 2 * around * along.
// Node id of ring j (0..along), layer k (0 = inner wall .. layers = outer wall), angle step i (0..around-1):
// (j * (layers + 1) + k) * around + i, at angle 2 pi i / around from the local x axis. End node lists are the
// rings j = 0 and j = along in that order (inner layer first).
// Bent tube: the centreline is the arc c(s) = (R - R cos(s/R), 0, R sin(s/R)), R = bend_radius, starting at the
// origin along +z and curving toward +x (centre of curvature at (R, 0, 0)); each ring lies in the plane normal
// to the arc, with local axes (cos(s/R), 0, -sin(s/R)) and y. Straight: rings at z = s in the x-y plane.
// Throws std::invalid_argument naming the field and value when the spec is invalid (also when a bend would
// close the tube on itself: length / bend_radius must be < 2 pi).
TetMesh make_hollow_cylinder(const HollowCylinderSpec& spec);

// Frame of the hollow cylinder's centreline at arc length s (metres). Bent (bend_radius R > 0): the arc point
// c(s) = (R - R cos(s/R), 0, R sin(s/R)), tangent (sin(s/R), 0, cos(s/R)), normal (cos(s/R), 0, -sin(s/R))
// toward the centre of curvature (the rings' local x axis) and binormal y (the local y axis). Straight
// (R <= 0): (0, 0, s), z, x and y. Any s is accepted (no validation of spec).
struct CentrelineFrame {
  Eigen::Vector3d point;     // metres
  Eigen::Vector3d tangent;   // unit
  Eigen::Vector3d normal;    // unit, local x axis of the ring at s
  Eigen::Vector3d binormal;  // unit, local y axis of the ring at s (tangent x normal)
};
CentrelineFrame hollow_cylinder_frame(const HollowCylinderSpec& spec, double s);

// Point of the hollow cylinder of `spec` at arc length s along the centreline (metres), distance r from it
// (metres) and angle theta (radians) from the local x axis of the ring at s: the map make_hollow_cylinder places
// its nodes with (s = length j / along, r = inner + (outer - inner) k / layers, theta = 2 pi i / around). Any
// (s, r, theta) is accepted (no validation of spec), so callers can evaluate between grid points.
Eigen::Vector3d hollow_cylinder_point(const HollowCylinderSpec& spec, double s, double r, double theta);

// Signed volume of tet t at the given positions (positive when not inverted), cubic metres.
double tet_volume(const Points& x, const Tets& tets, int t);

}  // namespace lumen::physics
