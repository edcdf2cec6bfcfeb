#pragma once
// Test model of the compliance and contact tests: a coarse tube with both ends fixed, its solver and a dense
// inverse of K as the twin, and random contact rows on it.
#include <Eigen/Dense>
#include <Eigen/SparseCore>
#include <memory>
#include <random>
#include <vector>

#include "physics/contact_rows.hpp"
#include "physics/fem.hpp"
#include "physics/mesh.hpp"

namespace lumen::physics {
namespace {

// A coarse tube with both ends fixed, its solver and a dense inverse of K (0 on fixed DOFs) as the twin.
struct Model {
  TetMesh mesh;
  Eigen::SparseMatrix<double> K;
  std::unique_ptr<StaticSolver> solver;
  Eigen::MatrixXd Kinv;         // 3n x 3n
  std::vector<int> inner;       // inner-wall node ids
  std::vector<int> free_nodes;  // nodes not fixed
  std::vector<int> outer_free;  // free nodes not on the inner wall
  std::vector<int> inner_free;  // free nodes on the inner wall

  Model() {
    HollowCylinderSpec s;
    s.segments_around = 8, s.segments_along = 4, s.layers = 2, s.length = 0.04;
    mesh = make_hollow_cylinder(s);
    K = assemble_stiffness(mesh, LinearMaterial{5000.0, 0.45});
    std::vector<int> fixed = mesh.node_set(kStartEnd);
    fixed.insert(fixed.end(), mesh.node_set(kStopEnd).begin(), mesh.node_set(kStopEnd).end());
    solver = std::make_unique<StaticSolver>(K, fixed);
    const int n = mesh.n_nodes();
    std::vector<char> is_fixed(n, 0), is_inner(n, 0);
    for (int v : fixed) is_fixed[v] = 1;
    for (int i = 0; i < mesh.surface(kInnerWall).size(); ++i) is_inner[mesh.surface(kInnerWall).data()[i]] = 1;
    for (int v = 0; v < n; ++v) {
      if (is_inner[v]) inner.push_back(v);
      if (!is_fixed[v]) free_nodes.push_back(v);
      if (!is_fixed[v] && !is_inner[v]) outer_free.push_back(v);
      if (!is_fixed[v] && is_inner[v]) inner_free.push_back(v);
    }
    // Dense twin.
    std::vector<int> free;
    for (int v : free_nodes)
      for (int c = 0; c < 3; ++c) free.push_back(3 * v + c);
    const Eigen::MatrixXd Kd(K);
    Eigen::MatrixXd Kf(free.size(), free.size());
    for (size_t i = 0; i < free.size(); ++i)
      for (size_t j = 0; j < free.size(); ++j) Kf(i, j) = Kd(free[i], free[j]);
    const Eigen::MatrixXd Kfi = Kf.ldlt().solve(Eigen::MatrixXd::Identity(free.size(), free.size()));
    Kinv = Eigen::MatrixXd::Zero(3 * n, 3 * n);
    for (size_t i = 0; i < free.size(); ++i)
      for (size_t j = 0; j < free.size(); ++j) Kinv(free[i], free[j]) = Kfi(i, j);
  }
  int n() const { return mesh.n_nodes(); }
};

inline const Model& model() {
  static const Model m;
  return m;
}

// H as a dense matrix (rows x 3n), built directly from the row definition.
inline Eigen::MatrixXd dense_H(const std::vector<ContactRow>& rows, int n) {
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(rows.size(), 3 * n);
  for (size_t r = 0; r < rows.size(); ++r)
    for (int k = 0; k < 4; ++k)
      if (rows[r].node[k] >= 0)
        for (int c = 0; c < 3; ++c) H(r, 3 * rows[r].node[k] + c) += rows[r].weight[k] * rows[r].n[c];
  return H;
}

inline Eigen::Vector3d random_unit(std::mt19937& rng) {
  std::normal_distribution<double> d;
  return Eigen::Vector3d(d(rng), d(rng), d(rng)).normalized();
}

// Vertex-face row n . (u_p - sum b_i u_fi) on random nodes: the vertex free, the face nodes anywhere on the
// inner wall (fixed ones included) or, with allow_outer, anywhere in the mesh (outside the compliance set).
inline ContactRow random_vertex_face(std::mt19937& rng, const Model& m, bool allow_outer) {
  const std::vector<int>& vpool = allow_outer ? m.free_nodes : m.inner_free;
  std::vector<int> fpool = m.inner;
  if (allow_outer) fpool.insert(fpool.end(), m.outer_free.begin(), m.outer_free.end());
  std::uniform_int_distribution<size_t> pickv(0, vpool.size() - 1), pickf(0, fpool.size() - 1);
  std::uniform_real_distribution<double> u01(0.05, 1.0);
  ContactRow row;
  row.node[0] = vpool[pickv(rng)];
  for (int k = 1; k < 4; ++k) row.node[k] = fpool[pickf(rng)];
  double b[3] = {u01(rng), u01(rng), u01(rng)};
  const double s = b[0] + b[1] + b[2];
  row.weight[0] = 1.0;
  for (int k = 0; k < 3; ++k) row.weight[k + 1] = -b[k] / s;
  row.n = random_unit(rng);
  return row;
}

}  // namespace
}  // namespace lumen::physics
