#pragma once
// Tetrahedral mesh with tagged surfaces, and the hollow-cylinder generator.
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "physics/types.hpp"

namespace lumen::physics {

// A boundary surface of a volume mesh, by name: faces whose node ids index the mesh's nodes (an index map onto
// the volume), normals out of the volume. Faces: Tris (n x 3) or, on a quadratic mesh, Tris6 (n x 6).
template <class Faces>
struct NamedFaces {
  std::string name;
  Faces tris;
};
using MeshSurface = NamedFaces<Tris>;

// A named set of node ids (e.g. the nodes of one end, held by a scene's "fixed").
struct NodeSet {
  std::string name;
  std::vector<int> nodes;
};

// The names the hollow-cylinder generator gives its surfaces and node sets (the names scenes use).
inline constexpr char kInnerWall[] = "inner";  // surface: the lumen wall, normals into the lumen
inline constexpr char kOuterWall[] = "outer";  // surface: the outer wall, normals away from the axis
inline constexpr char kEndCaps[] = "ends";     // surface: both end caps
inline constexpr char kStartEnd[] = "start";   // node set: every node of the end ring at the centreline's start
inline constexpr char kStopEnd[] = "stop";     // node set: every node of the end ring at its end

// The item of that name in a list of named items (surfaces, node sets), or null.
template <class Item>
const Item* find_named(const std::vector<Item>& items, std::string_view name) {
  for (const Item& item : items)
    if (item.name == name) return &item;
  return nullptr;
}
// The same, throwing std::invalid_argument "<owner> has no <kind> "<name>" (it has: a, b)" when it is missing.
template <class Item>
const Item& require_named(const std::vector<Item>& items, std::string_view name, const char* owner, const char* kind) {
  if (const Item* item = find_named(items, name)) return *item;
  std::string have;
  for (const Item& item : items) have += (have.empty() ? "" : ", ") + item.name;
  throw std::invalid_argument(std::string(owner) + " has no " + kind + " \"" + std::string(name) + "\" (it has: " +
                              (have.empty() ? "none" : have) + ")");
}

// A tetrahedral volume mesh with its boundary surfaces and node sets by name.
struct TetMesh {
  Points rest;                         // rest positions, n_nodes x 3, metres
  Tets tets;                           // elements, n_tets x 4, positive volume
  std::vector<MeshSurface> surfaces;   // boundary surfaces (index maps onto the nodes)
  std::vector<NodeSet> node_sets;      // named node sets
  int n_nodes() const { return static_cast<int>(rest.rows()); }
  bool has_surface(std::string_view name) const { return find_named(surfaces, name) != nullptr; }
  bool has_node_set(std::string_view name) const { return find_named(node_sets, name) != nullptr; }
  // The surface / node set of that name; throws std::invalid_argument naming it when the mesh has none.
  const Tris& surface(std::string_view name) const { return require_named(surfaces, name, "TetMesh", "surface").tris; }
  const std::vector<int>& node_set(std::string_view name) const {
    return require_named(node_sets, name, "TetMesh", "node set").nodes;
  }
};

// A frame of a tube's centreline: the point and its right-handed orthonormal axes (tangent, normal, binormal).
struct CentrelineFrame {
  Eigen::Vector3d point;     // metres
  Eigen::Vector3d tangent;   // unit
  Eigen::Vector3d normal;    // unit, local x axis of the ring at s
  Eigen::Vector3d binormal;  // unit, local y axis of the ring at s (tangent x normal)
};

// Point of a ring with frame f at distance r (metres) from its centre and angle theta (radians) from its
// local x axis (the normal): f.point + r cos(theta) f.normal + r sin(theta) f.binormal.
Eigen::Vector3d ring_point(const CentrelineFrame& f, double r, double theta);

// One ring of nodes of a structured tube: its centreline frame and the radii of its inner and outer wall.
struct TubeRing {
  CentrelineFrame frame;
  double inner_radius = 0.0;  // metres
  double outer_radius = 0.0;  // metres, > inner_radius
};

// The structured double-wall tet mesh over rings (at least 2, in order along the centreline): the hollow
// cylinder's grid, numbering, tets, surfaces and node sets (make_hollow_cylinder below), ring j's nodes at
// ring_point(rings[j].frame, r_k, theta_i) with r_k from its inner to its outer radius in `layers` equal steps and
// theta_i = 2 pi i / segments_around, or angles[i] when `angles` is given (segments_around increasing angles in
// [0, 2 pi), radians). Every generated tube (hollow cylinder, swept tube) is built by it. Throws
// std::invalid_argument when there are fewer than 2 rings, segments_around < 3, layers < 1, or angles of another
// size or not increasing in [0, 2 pi).
TetMesh make_structured_tube(const std::vector<TubeRing>& rings, int segments_around, int layers,
                             const std::vector<double>& angles = {});
// Node id in make_structured_tube's numbering of angle step i (0 .. around - 1), ring j, layer k (0 = inner wall ..
// layers = outer wall).
inline int structured_tube_node(int around, int layers, int i, int j, int k) {
  return (j * (layers + 1) + k) * around + i;
}

// Grading of a structured tube's cells in one direction (around or along): cells shrink toward the foci, their
// size growing geometrically with the distance d to the nearest focus, h(d) ~ ratio^(d / d_max) (d_max: the
// largest such distance in the interval), so the largest cell is about `ratio` times the smallest. ratio 1 is
// uniform (and then the foci are ignored).
struct CellGrading {
  std::vector<double> focus;  // around: angles from the rings' local x axis, radians; along: arc lengths, metres
  double ratio = 1.0;         // largest / smallest cell, in [1, kMaxGradingRatio]
};
constexpr double kMaxGradingRatio = 100.0;
constexpr double kTwoPi = 2.0 * kPi;  // a full turn around a ring, radians

// The cells + 1 grid coordinates of [0, extent] under `grading` (first 0, last extent, increasing): uniform
// extent * i / cells when grading.ratio is 1; otherwise the equidistribution of the density 1 / h(d) (above),
// integrated on kGradingSamples points per cell. `periodic`: distances wrap around extent (the angle around a
// ring). Throws std::invalid_argument (naming `what`) when cells < 1, extent is not > 0, the ratio is out of
// range, a graded direction has no focus, or a focus is not finite (or, not periodic, outside [0, extent]).
std::vector<double> graded_grid(const CellGrading& grading, double extent, int cells, bool periodic,
                                const char* what);
constexpr int kGradingSamples = 64;

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
  // Optional grading toward where the tools work (uniform by default): around, by angle from the local x axis
  // toward +y (radians); along, by arc length (metres).
  CellGrading grading_around, grading_along;
};

// Structured hex grid (around x along x layers), 6 tets per hex (consistent diagonals, conforming).
// Nodes: around * (along + 1) * (layers + 1); tets: 6 * around * along * layers;
// inner triangles: 2 * around * along.
// Node id of ring j (0..along), layer k (0 = inner wall .. layers = outer wall), angle step i (0..around-1):
// (j * (layers + 1) + k) * around + i, at angle 2 pi i / around from the local x axis (ring j at arc length
// length j / along), or at hollow_cylinder_grid's graded angles and arc lengths. Surfaces kInnerWall,
// kOuterWall, kEndCaps; node sets kStartEnd and kStopEnd: the rings j = 0 and j = along in that order (inner
// layer first).
// Bent tube: the centreline is the arc c(s) = (R - R cos(s/R), 0, R sin(s/R)), R = bend_radius, starting at the
// origin along +z and curving toward +x (centre of curvature at (R, 0, 0)); each ring lies in the plane normal
// to the arc, with local axes (cos(s/R), 0, -sin(s/R)) and y. Straight: rings at z = s in the x-y plane.
// Throws std::invalid_argument naming the field and value when the spec is invalid (also when a bend would
// close the tube on itself: length / bend_radius must be < 2 pi).
TetMesh make_hollow_cylinder(const HollowCylinderSpec& spec);

// The hollow cylinder's grid coordinates: angles (segments_around + 1, from 0 to 2 pi, radians) and arc lengths
// (segments_along + 1, from 0 to length, metres), graded by spec.grading_around / grading_along (graded_grid).
// Does not validate the rest of the spec.
struct CylinderGrid {
  std::vector<double> angle, arc;
};
CylinderGrid hollow_cylinder_grid(const HollowCylinderSpec& spec);

// Frame of the hollow cylinder's centreline at arc length s (metres). Bent (bend_radius R > 0): the arc point
// c(s) = (R - R cos(s/R), 0, R sin(s/R)), tangent (sin(s/R), 0, cos(s/R)), normal (cos(s/R), 0, -sin(s/R))
// toward the centre of curvature (the rings' local x axis) and binormal y (the local y axis). Straight
// (R <= 0): (0, 0, s), z, x and y. Any s is accepted (no validation of spec).
CentrelineFrame hollow_cylinder_frame(const HollowCylinderSpec& spec, double s);

// Point of the hollow cylinder of `spec` at arc length s along the centreline (metres), distance r from it
// (metres) and angle theta (radians) from the local x axis of the ring at s: the map make_hollow_cylinder places
// its nodes with (s = length j / along, r = inner + (outer - inner) k / layers, theta = 2 pi i / around). Any
// (s, r, theta) is accepted (no validation of spec), so callers can evaluate between grid points.
Eigen::Vector3d hollow_cylinder_point(const HollowCylinderSpec& spec, double s, double r, double theta);

// Signed volume of tet t at the given positions (positive when not inverted), cubic metres.
double tet_volume(const Points& x, const Tets& tets, int t);

}  // namespace lumen::physics
