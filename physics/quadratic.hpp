#pragma once
// Quadratic (10-node) tetrahedra for the linear elastic model: the mesh built on a linear TetMesh (straight-sided
// or isoparametric on the hollow cylinder), shape functions, quadrature, element stiffness, assembly, and the
// consistent load of a pressure on a curved 6-node face.
#include <array>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "physics/fem.hpp"
#include "physics/mesh.hpp"

namespace lumen::physics {

// Element order of the elastic model: 4-node tets (linear) or 10-node tets (quadratic).
enum class ElementOrder { kLinear, kQuadratic };

// Local corners of the six edges of a 10-node tet, in the order of its edge nodes 4..9 (VTK quadratic tetra):
// 4 = (0,1), 5 = (1,2), 6 = (0,2), 7 = (0,3), 8 = (1,3), 9 = (2,3).
inline constexpr int kTet10Edges[6][2] = {{0, 1}, {1, 2}, {0, 2}, {0, 3}, {1, 3}, {2, 3}};
// Local corners of the three edges of a 6-node triangle, in the order of its edge nodes 3..5:
// 3 = (0,1), 4 = (1,2), 5 = (2,0).
inline constexpr int kTri6Edges[3][2] = {{0, 1}, {1, 2}, {2, 0}};

// Row-major n x 6 quadratic triangles: corners 0..2 (as the linear triangle) then edge nodes (kTri6Edges order).
using Tris6 = Eigen::Matrix<int, Eigen::Dynamic, 6, Eigen::RowMajor>;

// 10-node tets built on a linear TetMesh: the corner nodes keep their ids 0..n-1, one node per edge follows.
struct QuadraticMesh {
  Points rest;  // all nodes, (n_corners + n_edges) x 3, metres; rows 0..n_corners-1 = the linear mesh's
  Eigen::Matrix<int, Eigen::Dynamic, 10, Eigen::RowMajor> tets;  // corners 0..3 then edge nodes (kTet10Edges order)
  Eigen::Matrix<int, Eigen::Dynamic, 2, Eigen::RowMajor> edges;  // per edge node (index e -> node n_corners + e):
                                                                 // its two corners, smaller id first
  int n_corners = 0;
  // The linear mesh's surfaces as 6-node triangles, by the same names (same rows, same orientation).
  std::vector<NamedFaces<Tris6>> surfaces;
  // The linear mesh's node sets by the same names, with corner AND edge nodes: its corners in their order, then
  // the edge nodes whose two corners are both in the set, ascending.
  std::vector<NodeSet> node_sets;
  int n_nodes() const { return static_cast<int>(rest.rows()); }
  // The surface / node set of that name; throws std::invalid_argument naming it when the mesh has none.
  const Tris6& surface(std::string_view name) const {
    return require_named(surfaces, name, "QuadraticMesh", "surface").tris;
  }
  const std::vector<int>& node_set(std::string_view name) const {
    return require_named(node_sets, name, "QuadraticMesh", "node set").nodes;
  }
};

// Straight-sided (mid-edge nodes at edge midpoints). Edge nodes are numbered in order of first appearance over
// the tets (tet 0 edges in kTet10Edges order, then tet 1, ...). Throws std::invalid_argument when a tet refers to
// a missing node or a surface triangle edge is not a tet edge.
QuadraticMesh make_quadratic(const TetMesh& mesh);

// Isoparametric on the hollow cylinder of `spec` (straight or bent): mid-edge nodes placed at the image of the
// parametric midpoint of the generator's (radius, angle, arc length) map, so the curved walls are represented to
// second order. The TetMesh must be make_hollow_cylinder(spec) (checked: throws std::invalid_argument otherwise).
QuadraticMesh make_quadratic_cylinder(const TetMesh& mesh, const HollowCylinderSpec& spec);

// Shape functions of the 10-node tet at reference point xi = (L1, L2, L3) (L0 = 1 - L1 - L2 - L3; corners at the
// origin and the unit points): corner a: L_a (2 L_a - 1), edge (a,b): 4 L_a L_b. Dimensionless, 10 values.
Eigen::Matrix<double, 10, 1> tet10_shape(const Eigen::Vector3d& xi);
// Their derivatives dN_a / dxi_k, 10 x 3.
Eigen::Matrix<double, 10, 3> tet10_shape_gradients(const Eigen::Vector3d& xi);
// Shape functions of the 6-node triangle at xi = (L1, L2) (L0 = 1 - L1 - L2), 6 values, and dN / dxi, 6 x 2.
Eigen::Matrix<double, 6, 1> tri6_shape(const Eigen::Vector2d& xi);
Eigen::Matrix<double, 6, 2> tri6_shape_gradients(const Eigen::Vector2d& xi);

// A quadrature point on the reference tet (weights sum to its volume 1/6) or triangle (weights sum to 1/2).
struct TetQuadraturePoint {
  Eigen::Vector3d xi;
  double weight;
};
struct TriQuadraturePoint {
  Eigen::Vector2d xi;
  double weight;
};
// Degree-5 rules with positive weights: Walkington's 14-point tet rule, Radon's 7-point triangle rule.
const std::array<TetQuadraturePoint, 14>& tet_quadrature();
const std::array<TriQuadraturePoint, 7>& triangle_quadrature();

// Stiffness of one (possibly curved) 10-node tet with rest nodes X (10 x 3, metres), 30 x 30, DOF order
// (x0, y0, z0, x1, ...), N/m, by the degree-5 rule (exact for straight elements). Throws std::invalid_argument
// if the Jacobian determinant is not positive at a quadrature point.
Eigen::Matrix<double, 30, 30> tet10_stiffness(const Eigen::Matrix<double, 10, 3>& X, const LinearMaterial& m);
// Elastic energy of a 10-node tet for displacements u (10 x 3, metres), joules, by the same rule.
double tet10_energy(const Eigen::Matrix<double, 10, 3>& X, const Eigen::Matrix<double, 10, 3>& u,
                    const LinearMaterial& m);
// Rest volume of a (possibly curved) 10-node tet, cubic metres (same rule and Jacobian check).
double tet10_volume(const Eigen::Matrix<double, 10, 3>& X);
// Shape-function gradients averaged over a (possibly curved) 10-node tet, G_a = (1 / V) integral of grad N_a dV,
// 10 x 3 (row a: G_a), 1/metres, by the same rule and Jacobian check: the volume-averaged deformation gradient
// of a displacement u (10 x 3) is I + u^T G. They sum to zero (the N_a sum to one); for a straight element and an
// affine displacement u^T G is the displacement gradient itself.
Eigen::Matrix<double, 10, 3> tet10_mean_gradients(const Eigen::Matrix<double, 10, 3>& X);

// Global stiffness, 3N x 3N (N = mesh.n_nodes()), symmetric, DOF 3*i+c for node i, coordinate c.
// Throws std::invalid_argument naming the tet when a node id is out of range or a Jacobian is not positive.
Eigen::SparseMatrix<double> assemble_stiffness(const QuadraticMesh& mesh, const LinearMaterial& m);

// Consistent nodal forces (6 x 3, newtons) of a uniform pressure p (pascals) on a curved 6-node face with nodes X
// (6 x 3, metres): f_a = -p * integral of N_a n dA, n the unit normal of the node order (right-hand rule), i.e. the
// pressure pushes against a face whose normal points out of the body. Exact for quadratic geometry (degree 5 rule).
Eigen::Matrix<double, 6, 3> tri6_pressure_load(const Eigen::Matrix<double, 6, 3>& X, double pressure);

// Each 6-node triangle split into 4 linear triangles over its corner and edge nodes, same orientation:
// (c0, e01, e20), (e01, c1, e12), (e20, e12, c2), (e01, e12, e20). n x 6 -> 4n x 3.
Tris split_tri6(const Tris6& tris);

// Each 10-node tet split into 8 linear tets over its corner and edge nodes, positive volume at the given rest
// positions: the four corner tets and the inner octahedron cut along its (0,2)-(1,3) edge-node diagonal.
// n x 10 -> 8n x 4. Throws std::logic_error if a sub-tet has no positive volume (a degenerate element).
Tets split_tet10(const Points& rest, const Eigen::Matrix<int, Eigen::Dynamic, 10, Eigen::RowMajor>& tets);

// The linear view of a quadratic mesh that rendering, collision and inversion counts use: all its nodes (corners
// and edge nodes, so positions and displacements index alike), its tets split by split_tet10 (every node belongs
// to a tet), its surfaces split by split_tri6 (twice the linear mesh's resolution along each edge, index maps
// onto the volume's nodes) and its node sets (corners and edge nodes).
TetMesh linear_view(const QuadraticMesh& q);

}  // namespace lumen::physics
