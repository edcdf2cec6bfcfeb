// Quadratic (10-node) tetrahedra: mesh construction, shape functions, quadrature, stiffness, pressure load.
#include "physics/quadratic.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

namespace lumen::physics {

namespace {

using Mat10x3 = Eigen::Matrix<double, 10, 3>;

// Key of the undirected edge (a, b) for the edge map.
std::int64_t edge_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<std::int64_t>(a) << 32) | static_cast<std::uint32_t>(b);
}

// Physical shape-function gradients (10 x 3, 1/metres) and Jacobian determinant (dimension m^3 per reference
// volume) at reference point xi. `element` names the element in the error (-1: unnamed).
Mat10x3 physical_gradients(const Mat10x3& X, const Eigen::Vector3d& xi, int q, int element, double& det) {
  const Mat10x3 dN = tet10_shape_gradients(xi);
  const Eigen::Matrix3d J = X.transpose() * dN;  // J(c, k) = d x_c / d xi_k
  det = J.determinant();
  if (!(det > 0.0) || !std::isfinite(det)) {
    std::ostringstream msg;
    msg << "tet10 element";
    if (element >= 0) msg << " " << element;
    msg << ": Jacobian determinant must be > 0 at quadrature point " << q << " (xi = " << xi.transpose()
        << "), got " << det;
    throw std::invalid_argument(msg.str());
  }
  return dN * J.inverse();  // dN_a/dx_c = sum_k dN_a/dxi_k dxi_k/dx_c
}

Eigen::Matrix<double, 30, 30> stiffness(const Mat10x3& X, const LinearMaterial& m, int element) {
  const LameParameters lame = lame_parameters(m);
  const double lambda = lame.lambda, mu = lame.mu;
  // K = sum_q w_q det J_q B_q^T D B_q for isotropic D, written per node pair (a, b) and components (i, j):
  // K_ab(i, j) = lambda g_a,i g_b,j + mu g_a,j g_b,i + mu (g_a . g_b) delta_ij, g = physical gradients.
  // Only blocks b >= a are accumulated; the upper triangle is mirrored at the end (exactly symmetric K).
  // Plain arrays in the inner loops (also keeps unoptimised builds fast).
  double k[30][30] = {};
  const auto& rule = tet_quadrature();
  for (int q = 0; q < static_cast<int>(rule.size()); ++q) {
    double det;
    const Mat10x3 grad = physical_gradients(X, rule[q].xi, q, element, det);
    double g[10][3];
    for (int a = 0; a < 10; ++a)
      for (int c = 0; c < 3; ++c) g[a][c] = grad(a, c);
    const double w = rule[q].weight * det, wl = w * lambda, wm = w * mu;
    for (int a = 0; a < 10; ++a)
      for (int b = a; b < 10; ++b) {
        const double dot = wm * (g[a][0] * g[b][0] + g[a][1] * g[b][1] + g[a][2] * g[b][2]);
        for (int i = 0; i < 3; ++i) {
          double* row = &k[3 * a + i][3 * b];
          for (int j = 0; j < 3; ++j) row[j] += wl * g[a][i] * g[b][j] + wm * g[a][j] * g[b][i];
          row[i] += dot;
        }
      }
  }
  Eigen::Matrix<double, 30, 30> K;
  for (int r = 0; r < 30; ++r)
    for (int c = r; c < 30; ++c) K(r, c) = K(c, r) = k[r][c];
  return K;
}

// Parametric grid coordinates (i around, j along, k layer) of a node of make_hollow_cylinder(spec).
void grid_of(const HollowCylinderSpec& spec, int node, int& i, int& j, int& k) {
  const int na = spec.segments_around, nr = spec.layers;
  i = node % na;
  k = (node / na) % (nr + 1);
  j = node / (na * (nr + 1));
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------------
// Shape functions and quadrature

Eigen::Matrix<double, 10, 1> tet10_shape(const Eigen::Vector3d& xi) {
  const double L[4] = {1.0 - xi[0] - xi[1] - xi[2], xi[0], xi[1], xi[2]};
  Eigen::Matrix<double, 10, 1> N;
  for (int a = 0; a < 4; ++a) N[a] = L[a] * (2.0 * L[a] - 1.0);
  for (int e = 0; e < 6; ++e) N[4 + e] = 4.0 * L[kTet10Edges[e][0]] * L[kTet10Edges[e][1]];
  return N;
}

Eigen::Matrix<double, 10, 3> tet10_shape_gradients(const Eigen::Vector3d& xi) {
  const double L[4] = {1.0 - xi[0] - xi[1] - xi[2], xi[0], xi[1], xi[2]};
  // dL_a / dxi_k: L0 = 1 - sum, L_a = xi_{a-1}.
  Eigen::Matrix<double, 4, 3> dL;
  dL << -1, -1, -1, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  Mat10x3 dN;
  for (int a = 0; a < 4; ++a) dN.row(a) = (4.0 * L[a] - 1.0) * dL.row(a);
  for (int e = 0; e < 6; ++e) {
    const int a = kTet10Edges[e][0], b = kTet10Edges[e][1];
    dN.row(4 + e) = 4.0 * (L[a] * dL.row(b) + L[b] * dL.row(a));
  }
  return dN;
}

Eigen::Matrix<double, 6, 1> tri6_shape(const Eigen::Vector2d& xi) {
  const double L[3] = {1.0 - xi[0] - xi[1], xi[0], xi[1]};
  Eigen::Matrix<double, 6, 1> N;
  for (int a = 0; a < 3; ++a) N[a] = L[a] * (2.0 * L[a] - 1.0);
  for (int e = 0; e < 3; ++e) N[3 + e] = 4.0 * L[kTri6Edges[e][0]] * L[kTri6Edges[e][1]];
  return N;
}

Eigen::Matrix<double, 6, 2> tri6_shape_gradients(const Eigen::Vector2d& xi) {
  const double L[3] = {1.0 - xi[0] - xi[1], xi[0], xi[1]};
  Eigen::Matrix<double, 3, 2> dL;
  dL << -1, -1, 1, 0, 0, 1;
  Eigen::Matrix<double, 6, 2> dN;
  for (int a = 0; a < 3; ++a) dN.row(a) = (4.0 * L[a] - 1.0) * dL.row(a);
  for (int e = 0; e < 3; ++e) {
    const int a = kTri6Edges[e][0], b = kTri6Edges[e][1];
    dN.row(3 + e) = 4.0 * (L[a] * dL.row(b) + L[b] * dL.row(a));
  }
  return dN;
}

const std::array<TetQuadraturePoint, 14>& tet_quadrature() {
  // Walkington's degree-5 rule: orbits (a,a,a,1-3a) x 4 for two values of a, and (c,c,1/2-c,1/2-c) x 6.
  static const std::array<TetQuadraturePoint, 14> rule = [] {
    std::array<TetQuadraturePoint, 14> r{};
    const double a[2] = {0.31088591926330060980, 0.092735250310891226402};
    const double wa[2] = {0.018781320953002641800, 0.012248840519393658257};
    const double c = 0.045503704125649649492, wc = 0.0070910034628469110730;
    int n = 0;
    for (int o = 0; o < 2; ++o) {
      // Barycentric (L0..L3) with 1-3a at position p; xi = (L1, L2, L3).
      for (int p = 0; p < 4; ++p) {
        double L[4] = {a[o], a[o], a[o], a[o]};
        L[p] = 1.0 - 3.0 * a[o];
        r[n++] = {Eigen::Vector3d(L[1], L[2], L[3]), wa[o]};
      }
    }
    // The six ways to put c on two of the four barycentric slots.
    for (int e = 0; e < 6; ++e) {
      double L[4] = {0.5 - c, 0.5 - c, 0.5 - c, 0.5 - c};
      L[kTet10Edges[e][0]] = c;
      L[kTet10Edges[e][1]] = c;
      r[n++] = {Eigen::Vector3d(L[1], L[2], L[3]), wc};
    }
    return r;
  }();
  return rule;
}

const std::array<TriQuadraturePoint, 7>& triangle_quadrature() {
  // Radon's degree-5 rule: centroid, and two orbits (a, a, 1-2a) with a = (6 -+ sqrt 15) / 21.
  static const std::array<TriQuadraturePoint, 7> rule = [] {
    std::array<TriQuadraturePoint, 7> r{};
    const double s15 = std::sqrt(15.0);
    r[0] = {Eigen::Vector2d(1.0 / 3.0, 1.0 / 3.0), 9.0 / 80.0};
    const double a[2] = {(6.0 - s15) / 21.0, (6.0 + s15) / 21.0};
    const double w[2] = {(155.0 - s15) / 2400.0, (155.0 + s15) / 2400.0};
    int n = 1;
    for (int o = 0; o < 2; ++o) {
      const double b = 1.0 - 2.0 * a[o];
      r[n++] = {Eigen::Vector2d(a[o], a[o]), w[o]};
      r[n++] = {Eigen::Vector2d(b, a[o]), w[o]};
      r[n++] = {Eigen::Vector2d(a[o], b), w[o]};
    }
    return r;
  }();
  return rule;
}

// ---------------------------------------------------------------------------------------------------------------
// Element kernels

Eigen::Matrix<double, 30, 30> tet10_stiffness(const Mat10x3& X, const LinearMaterial& m) {
  return stiffness(X, m, -1);
}

double tet10_energy(const Mat10x3& X, const Mat10x3& u, const LinearMaterial& m) {
  const LameParameters lame = lame_parameters(m);
  const double lambda = lame.lambda, mu = lame.mu;
  const auto& rule = tet_quadrature();
  double energy = 0.0;
  for (int q = 0; q < static_cast<int>(rule.size()); ++q) {
    double det;
    const Mat10x3 g = physical_gradients(X, rule[q].xi, q, -1, det);
    // Displacement gradient H = sum_a u_a (x) grad N_a, small strain eps = sym(H), density mu eps:eps + lambda/2 tr^2.
    const Eigen::Matrix3d H = u.transpose() * g;
    const Eigen::Matrix3d eps = 0.5 * (H + H.transpose());
    const double tr = eps.trace();
    energy += rule[q].weight * det * (mu * eps.squaredNorm() + 0.5 * lambda * tr * tr);
  }
  return energy;
}

double tet10_volume(const Mat10x3& X) {
  const auto& rule = tet_quadrature();
  double volume = 0.0;
  for (int q = 0; q < static_cast<int>(rule.size()); ++q) {
    double det;
    physical_gradients(X, rule[q].xi, q, -1, det);
    volume += rule[q].weight * det;
  }
  return volume;
}

Mat10x3 tet10_mean_gradients(const Mat10x3& X) {
  const auto& rule = tet_quadrature();
  Mat10x3 sum = Mat10x3::Zero();
  double volume = 0.0;
  for (int q = 0; q < static_cast<int>(rule.size()); ++q) {
    double det;
    const Mat10x3 g = physical_gradients(X, rule[q].xi, q, -1, det);
    sum += (rule[q].weight * det) * g;
    volume += rule[q].weight * det;
  }
  return sum / volume;
}

Eigen::SparseMatrix<double> assemble_stiffness(const QuadraticMesh& mesh, const LinearMaterial& m) {
  validate_material(m);
  const int n = mesh.n_nodes();
  // Element matrices scattered as triplets (900 per tet), summed by setFromTriplets.
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<size_t>(mesh.tets.rows()) * 900);
  for (int t = 0; t < mesh.tets.rows(); ++t) {
    Mat10x3 X;
    for (int a = 0; a < 10; ++a) {
      const int v = mesh.tets(t, a);
      if (v < 0 || v >= n) {
        throw std::invalid_argument("assemble_stiffness: mesh.tets(" + std::to_string(t) + ", " + std::to_string(a) +
                                    ") must be a node id in [0, " + std::to_string(n) + "), got " + std::to_string(v));
      }
      X.row(a) = mesh.rest.row(v);
    }
    scatter_element_matrix(stiffness(X, m, t), mesh.tets.row(t), triplets);
  }
  Eigen::SparseMatrix<double> K(3 * n, 3 * n);
  K.setFromTriplets(triplets.begin(), triplets.end());
  return K;
}

Eigen::Matrix<double, 6, 3> tri6_pressure_load(const Eigen::Matrix<double, 6, 3>& X, double pressure) {
  if (!std::isfinite(pressure)) {
    std::ostringstream msg;
    msg << "tri6_pressure_load: pressure must be finite, got " << pressure;
    throw std::invalid_argument(msg.str());
  }
  // f_a = -p sum_q w_q N_a(xi_q) (x_xi x x_eta)(xi_q): the area-weighted normal of the node order.
  Eigen::Matrix<double, 6, 3> f = Eigen::Matrix<double, 6, 3>::Zero();
  for (const TriQuadraturePoint& qp : triangle_quadrature()) {
    const Eigen::Matrix<double, 3, 2> J = X.transpose() * tri6_shape_gradients(qp.xi);  // d x / d xi, 3 x 2
    const Eigen::Vector3d area_normal = J.col(0).cross(J.col(1));
    f.noalias() -= (pressure * qp.weight) * tri6_shape(qp.xi) * area_normal.transpose();
  }
  return f;
}

// ---------------------------------------------------------------------------------------------------------------
// Meshes

QuadraticMesh make_quadratic(const TetMesh& mesh) {
  const int n = mesh.n_nodes();
  const int n_tets = static_cast<int>(mesh.tets.rows());
  QuadraticMesh q;
  q.n_corners = n;

  // Unique edges in order of first appearance; tets get their corner ids then edge node ids.
  std::unordered_map<std::int64_t, int> edge_of;
  edge_of.reserve(static_cast<size_t>(n_tets) * 2);
  std::vector<std::array<int, 2>> edges;
  q.tets.resize(n_tets, 10);
  for (int t = 0; t < n_tets; ++t) {
    for (int a = 0; a < 4; ++a) {
      const int v = mesh.tets(t, a);
      if (v < 0 || v >= n) {
        throw std::invalid_argument("make_quadratic: mesh.tets(" + std::to_string(t) + ", " + std::to_string(a) +
                                    ") must be a node id in [0, " + std::to_string(n) + "), got " + std::to_string(v));
      }
      q.tets(t, a) = v;
    }
    for (int e = 0; e < 6; ++e) {
      const int a = mesh.tets(t, kTet10Edges[e][0]), b = mesh.tets(t, kTet10Edges[e][1]);
      const auto [it, inserted] = edge_of.emplace(edge_key(a, b), static_cast<int>(edges.size()));
      if (inserted) edges.push_back({std::min(a, b), std::max(a, b)});
      q.tets(t, 4 + e) = n + it->second;
    }
  }

  // Nodes: the corners, then each edge's midpoint.
  const int n_edges = static_cast<int>(edges.size());
  q.rest.resize(n + n_edges, 3);
  q.rest.topRows(n) = mesh.rest;
  q.edges.resize(n_edges, 2);
  for (int e = 0; e < n_edges; ++e) {
    q.edges(e, 0) = edges[e][0];
    q.edges(e, 1) = edges[e][1];
    q.rest.row(n + e) = 0.5 * (mesh.rest.row(edges[e][0]) + mesh.rest.row(edges[e][1]));
  }

  // Surfaces: each triangle's edges must be tet edges.
  auto lift = [&](const Tris& tris, const std::string& name) {
    Tris6 out(tris.rows(), 6);
    for (int f = 0; f < tris.rows(); ++f) {
      for (int c = 0; c < 3; ++c) out(f, c) = tris(f, c);
      for (int e = 0; e < 3; ++e) {
        const int a = tris(f, kTri6Edges[e][0]), b = tris(f, kTri6Edges[e][1]);
        const auto it = edge_of.find(edge_key(a, b));
        if (it == edge_of.end()) {
          throw std::invalid_argument("make_quadratic: surface " + name + " triangle " + std::to_string(f) +
                                      " has edge (" + std::to_string(a) + ", " + std::to_string(b) +
                                      ") that is not an edge of any tet");
        }
        out(f, 3 + e) = n + it->second;
      }
    }
    return out;
  };
  for (const MeshSurface& surface : mesh.surfaces) q.surfaces.push_back({surface.name, lift(surface.tris, surface.name)});

  // Node sets: the linear sets, then the edge nodes joining two nodes of the same set.
  auto lift_set = [&](const std::vector<int>& corners) {
    std::vector<char> on(n, 0);
    for (int v : corners) {
      if (v < 0 || v >= n) {
        throw std::invalid_argument("make_quadratic: node set ids must be in [0, " + std::to_string(n) + "), got " +
                                    std::to_string(v));
      }
      on[v] = 1;
    }
    std::vector<int> out = corners;
    for (int e = 0; e < n_edges; ++e)
      if (on[edges[e][0]] && on[edges[e][1]]) out.push_back(n + e);
    return out;
  };
  for (const NodeSet& set : mesh.node_sets) q.node_sets.push_back({set.name, lift_set(set.nodes)});
  return q;
}

QuadraticMesh make_quadratic_cylinder(const TetMesh& mesh, const HollowCylinderSpec& spec) {
  // The mesh must be the generator's for this spec (same nodes and tets), so grid coordinates follow from node ids.
  const TetMesh reference = make_hollow_cylinder(spec);
  if (reference.n_nodes() != mesh.n_nodes() || reference.tets.rows() != mesh.tets.rows() ||
      reference.tets != mesh.tets || reference.rest != mesh.rest) {
    throw std::invalid_argument("make_quadratic_cylinder: mesh must be make_hollow_cylinder(spec) (got " +
                                std::to_string(mesh.n_nodes()) + " nodes and " + std::to_string(mesh.tets.rows()) +
                                " tets, or other positions)");
  }
  QuadraticMesh q = make_quadratic(mesh);
  const int na = spec.segments_around;
  const bool graded_around = spec.grading_around.ratio != 1.0, graded_along = spec.grading_along.ratio != 1.0;
  const CylinderGrid grid = hollow_cylinder_grid(spec);
  // Edge nodes: image of the parametric midpoint (of the graded grid's coordinates when graded); the angle step
  // is taken the short way round the seam.
  for (int e = 0; e < q.edges.rows(); ++e) {
    int i0, j0, k0, i1, j1, k1;
    grid_of(spec, q.edges(e, 0), i0, j0, k0);
    grid_of(spec, q.edges(e, 1), i1, j1, k1);
    int di = i1 - i0;
    if (2 * di > na) di -= na;
    if (2 * di < -na) di += na;
    const double s = graded_along ? 0.5 * (grid.arc[j0] + grid.arc[j1])
                                  : spec.length * 0.5 * (j0 + j1) / spec.segments_along;
    const double r = spec.inner_radius + (spec.outer_radius - spec.inner_radius) * 0.5 * (k0 + k1) / spec.layers;
    // Graded angle of the step's far end, unwrapped across the seam (index -1 or na).
    const int i_far = i0 + di;
    const double far = i_far < 0 ? grid.angle[na + i_far] - kTwoPi : grid.angle[i_far];
    const double theta = graded_around ? 0.5 * (grid.angle[i0] + far)
                                       : kTwoPi * (i0 + 0.5 * di) / na;
    q.rest.row(q.n_corners + e) = hollow_cylinder_point(spec, s, r, theta).transpose();
  }
  return q;
}

Tris split_tri6(const Tris6& tris) {
  Tris out(4 * tris.rows(), 3);
  for (int t = 0; t < tris.rows(); ++t) {
    // Corners c0..c2 and edge nodes e01, e12, e20 (kTri6Edges order).
    const int c0 = tris(t, 0), c1 = tris(t, 1), c2 = tris(t, 2), e01 = tris(t, 3), e12 = tris(t, 4), e20 = tris(t, 5);
    out.row(4 * t + 0) << c0, e01, e20;
    out.row(4 * t + 1) << e01, c1, e12;
    out.row(4 * t + 2) << e20, e12, c2;
    out.row(4 * t + 3) << e01, e12, e20;
  }
  return out;
}

Tets split_tet10(const Points& rest, const Eigen::Matrix<int, Eigen::Dynamic, 10, Eigen::RowMajor>& tets) {
  // Local nodes of the 8 sub-tets (kTet10Edges order: 4 = (0,1), 5 = (1,2), 6 = (0,2), 7 = (0,3), 8 = (1,3),
  // 9 = (2,3)): four corner tets, then the octahedron 4..9 around its 6-8 diagonal (the cycle 4, 5, 9, 7).
  static constexpr int kSub[8][4] = {{0, 4, 6, 7}, {4, 1, 5, 8}, {6, 5, 2, 9}, {7, 8, 9, 3},
                                     {6, 8, 4, 5}, {6, 8, 5, 9}, {6, 8, 9, 7}, {6, 8, 7, 4}};
  Tets out(8 * tets.rows(), 4);
  for (int t = 0; t < tets.rows(); ++t)
    for (int s = 0; s < 8; ++s) {
      const int row = 8 * t + s;
      for (int k = 0; k < 4; ++k) out(row, k) = tets(t, kSub[s][k]);
      // Orientation: positive volume (swap two nodes otherwise).
      if (tet_volume(rest, out, row) < 0.0) std::swap(out(row, 2), out(row, 3));
      if (!(tet_volume(rest, out, row) > 0.0))
        throw std::logic_error("split_tet10: sub-tet " + std::to_string(s) + " of tet " + std::to_string(t) +
                               " has no positive volume");
    }
  return out;
}

TetMesh linear_view(const QuadraticMesh& q) {
  TetMesh m;
  m.rest = q.rest;
  m.tets = split_tet10(q.rest, q.tets);
  for (const auto& surface : q.surfaces) m.surfaces.push_back({surface.name, split_tri6(surface.tris)});
  m.node_sets = q.node_sets;
  return m;
}

}  // namespace lumen::physics
