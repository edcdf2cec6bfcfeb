#pragma once
// Linear elastic tetrahedral FEM: element stiffness, assembly, prefactorised static solve.
#include <cassert>
#include <memory>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "physics/mesh.hpp"

namespace lumen::physics {

// Isotropic linear elastic material.
struct LinearMaterial {
  double young_modulus = 5000.0;  // pascals, > 0
  double poisson_ratio = 0.45;    // in (-1, 0.5)
};

// 12 x 12 stiffness of a linear (4-node) tet with rest vertices X (4 x 3, metres), N/m.
// DOF order: (x0, y0, z0, x1, ..., z3).
Eigen::Matrix<double, 12, 12> tet_stiffness(const Eigen::Matrix<double, 4, 3>& X, const LinearMaterial& m);

// Elastic energy of a linear tet for displacements u (4 x 3), joules (for finite-difference checks).
double tet_energy(const Eigen::Matrix<double, 4, 3>& X, const Eigen::Matrix<double, 4, 3>& u, const LinearMaterial& m);

// Displacement gradient H = du/dX of a linear tet with rest vertices X and displacements u (4 x 3 each, metres),
// dimensionless; its small strain is sym(H). Throws std::invalid_argument for a degenerate or inverted rest tet.
Eigen::Matrix3d tet_displacement_gradient(const Eigen::Matrix<double, 4, 3>& X, const Eigen::Matrix<double, 4, 3>& u);

// Throws std::invalid_argument unless E > 0 and finite and nu in (-1, 0.5).
void validate_material(const LinearMaterial& m);

// Lame parameters of an isotropic material, pascals.
struct LameParameters {
  double lambda;  // E nu / ((1 + nu) (1 - 2 nu))
  double mu;      // shear modulus E / (2 (1 + nu))
};
// The Lame parameters of a material; throws as validate_material.
LameParameters lame_parameters(const LinearMaterial& m);

// Isotropic linear stress of a small strain eps: lambda tr(eps) I + 2 mu eps, pascals.
Eigen::Matrix3d linear_stress(const Eigen::Matrix3d& eps, const LinearMaterial& m);
// Von Mises equivalent stress of a stress tensor: sqrt(3/2 s:s), s its deviator, pascals.
double von_mises(const Eigen::Matrix3d& sigma);

// Appends the entries of an element matrix Ke (3k x 3k, DOF order (x0, y0, z0, x1, ..., z_{k-1})) of the element
// with mesh nodes nodes(0..k-1) to triplets of the global 3n x 3n matrix: Ke(3a + i, 3b + j) at
// (3 nodes(a) + i, 3 nodes(b) + j), in the order a, b, i, j (setFromTriplets then sums them in that order).
template <class ElementMatrix, class Nodes>
void scatter_element_matrix(const ElementMatrix& Ke, const Nodes& nodes,
                            std::vector<Eigen::Triplet<double>>& triplets) {
  const int k = static_cast<int>(Ke.rows()) / 3;
  for (int a = 0; a < k; ++a)
    for (int b = 0; b < k; ++b)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) triplets.emplace_back(3 * nodes(a) + i, 3 * nodes(b) + j, Ke(3 * a + i, 3 * b + j));
}

// Element matrices summed in place into a fixed global pattern. The pattern is that of the 3n x 3n matrix over a
// mesh's elements (every pair of an element's nodes, full 3 x 3 blocks, rows sorted); per element it keeps where
// each of its block columns starts in the values. A matrix of new element values (a warped stiffness at new
// rotations) is then summed without a triplet list: setFromTriplets' list is 144 triplets a linear tet (22 MB on
// the paper mesh, 900 a 10-node tet) on fresh memory, and its page faults made one lagged warped stiffness cost
// 12-95 ms instead of 3. Each entry is summed in element order, as setFromTriplets sums scatter_element_matrix's
// triplets, so the two give the same matrix to the bit.
class ElementAssembly {
 public:
  ElementAssembly() = default;
  // nodes: n_elements x k node ids, row-major (element e's nodes at nodes[e k .. e k + k - 1]), each in
  // [0, n_nodes); std::invalid_argument otherwise.
  ElementAssembly(const int* nodes, int n_elements, int k, int n_nodes);
  // A 3 n_nodes square matrix of the pattern, its values 0.
  Eigen::SparseMatrix<double> zero_matrix() const { return pattern_; }
  // K (a matrix of this pattern) += Ke, element e's matrix (3k x 3k, DOF order (x0, y0, z0, x1, ..., z_{k-1})).
  template <class ElementMatrix>
  void add(int e, const ElementMatrix& Ke, Eigen::SparseMatrix<double>& K) const {
    assert(K.nonZeros() == pattern_.nonZeros() && Ke.rows() == 3 * k_ && e >= 0 && e < n_elements_);
    const int* start = block_start_.data() + static_cast<size_t>(e) * k_ * k_ * 3;
    double* values = K.valuePtr();
    for (int a = 0; a < k_; ++a)
      for (int b = 0; b < k_; ++b)
        for (int j = 0; j < 3; ++j) {
          double* v = values + start[(a * k_ + b) * 3 + j];
          for (int i = 0; i < 3; ++i) v[i] += Ke(3 * a + i, 3 * b + j);
        }
  }

 private:
  int k_ = 0, n_elements_ = 0;
  Eigen::SparseMatrix<double> pattern_;  // compressed, values 0
  // n_elements x k x k x 3: at ((e k + a) k + b) 3 + j, the value index of row 3 nodes(a) in column 3 nodes(b) + j
  // (rows 3 nodes(a) + 1, + 2 follow it).
  std::vector<int> block_start_;
};

// Global stiffness, 3n x 3n, symmetric, DOF 3*i+c for node i, coordinate c.
Eigen::SparseMatrix<double> assemble_stiffness(const TetMesh& mesh, const LinearMaterial& m);

// One fixed degree of freedom: displacement component `component` (0 = x, 1 = y, 2 = z) of node `node` is 0.
struct FixedDof {
  int node;
  int component;
};

// K u = f with some nodes fixed (u = 0 there), factorised once with CHOLMOD (supernodal LL^T, solved on the
// supernodal factor). All vectors are full length 3n; entries of fixed DOFs in f are ignored and returned as 0 in u.
// K's lower triangle on the free DOFs is copied into CHOLMOD; K itself is kept (matrix(), for InteriorSolver: a copy
// of its nonzeros, small beside the factor's). A solve reuses workspace inside the solver, so one solver must not
// be used from two threads at once: a solve that starts while another runs throws std::logic_error. One thread may
// solve while another does other work (engine: the deferred whole-mesh correction).
class StaticSolver {
 public:
  // Fix whole nodes (all three components).
  StaticSolver(const Eigen::SparseMatrix<double>& K, const std::vector<int>& fixed_nodes);
  // Fix single components (e.g. u_z = 0 on an end face, symmetry planes).
  StaticSolver(const Eigen::SparseMatrix<double>& K, const std::vector<FixedDof>& fixed_dofs);
  ~StaticSolver();
  StaticSolver(const StaticSolver&) = delete;
  StaticSolver& operator=(const StaticSolver&) = delete;
  StaticSolver(StaticSolver&&) noexcept;
  StaticSolver& operator=(StaticSolver&&) noexcept;

  int n_dofs() const;       // 3n
  int n_free_dofs() const;  // 3n minus the fixed DOFs
  // Non-zeros of the Cholesky factor L (a measure of the solve cost).
  long factor_nonzeros() const;
  // u = K^-1 f (full vectors, 3n).
  void solve(const Eigen::VectorXd& f, Eigen::VectorXd& u) const;
  // A single-precision copy of the factor for solve_approximately (half the bytes a back-substitution reads; the
  // solver's memory grows by about half). Solvers made from this one by refactorised() or refactorised_nested() make
  // their own; those made by scaled() share it. Not while a solve runs on another thread.
  void add_single_precision();
  bool has_single_precision() const;
  // u ~ K^-1 f for preconditioning: on the single-precision copy when there is one, in double arithmetic on its
  // rounded values (so the operator is symmetric positive definite, K's Cholesky factor rounded to float, to the
  // last bits of double; relative error about float's epsilon times the factor's condition), else solve().
  void solve_approximately(const Eigen::VectorXd& f, Eigen::VectorXd& u) const;
  // Many right-hand sides at once (3n x m).
  Eigen::MatrixXd solve_many(const Eigen::MatrixXd& F) const;
  // Half of a column of K^-1: y = L^-1 P e_dof for a factorisation P K P^T = L L^T on the free DOFs, times
  // sqrt(inverse scale), so that (K^-1)_ij = y_i . y_j (scaled() included). A sparse forward solve: only the factor
  // columns on dof's path to the root of the elimination tree are read (CHOLMOD's partial solve), where a column of
  // K^-1 needs both whole sweeps. The factorisation is a second one of the same matrix, ordered by nested
  // dissection (METIS), made on first use (or by prepare_half_columns): the default ordering of a long tube (AMD)
  // is nearly banded, its elimination tree nearly a chain, so a path holds a third of the factor's rows; nested
  // dissection's tree is balanced (the whole colon, 24,984 DOFs: 512 entries a column against 8,500). Out: the
  // nonzero entries in that factor's order, ascending; none for a fixed DOF.
  void half_column(int dof, std::vector<int>& index, std::vector<double>& value) const;
  // K^-1 f in two halves on half_column's factorisation: half_forward gives z = L^-1 P f (n_free entries, in that
  // factor's order, times sqrt(inverse scale)), half_backward u = P^T L^-T z (3n, times sqrt(inverse scale), fixed
  // DOFs 0), so that half_backward(half_forward(f)) = K^-1 f, and for a DOF's half column y, y . z = (K^-1 f)_dof.
  // Between the halves the result can be read on a few DOFs, and forces on a few DOFs added (z += y w), from their
  // half columns: K^-1 (f + g) for g on few DOFs in one forward and one backward sweep, where solving f and g apart
  // takes two of each. half_forward throws std::invalid_argument for f of another size, half_backward for z of
  // another size than n_free_dofs().
  void half_forward(const Eigen::VectorXd& f, std::vector<double>& z) const;
  void half_backward(const std::vector<double>& z, Eigen::VectorXd& u) const;
  // Whether half_forward and half_backward sweep solve()'s own supernodal factor (a solver from refactorised_nested:
  // each costs about half a solve()); otherwise they sweep half_column's factorisation, which CHOLMOD's partial
  // solves turn simplicial, at about a whole solve() each.
  bool splits_on_its_factor() const;
  // The half columns of several DOFs (e.g. a node's three) on the union of their patterns: index its rows in the
  // factor's order, ascending; value row-major, index.size() x dofs.size(): value[e * dofs.size() + c] is entry
  // index[e] of dofs[c]'s half column (0 where that column has none; a fixed DOF's column is 0). On a solver whose
  // halves sweep its own supernodal factor (splits_on_its_factor), one forward sweep over the supernodes on the
  // DOFs' paths to the roots of the elimination tree, all the right-hand sides at once; otherwise a partial solve per
  // DOF as half_column. Throws std::invalid_argument for a DOF out of range.
  void half_columns(const std::vector<int>& dofs, std::vector<int>& index, std::vector<double>& value) const;
  // Makes half_column's factorisation and its solve's workspace now (a few hundred ms on the whole colon) rather than
  // on its first call. Throws as the constructor when the factorisation fails.
  void prepare_half_columns() const;
  bool is_fixed_dof(int dof) const;
  // The matrix as given (3n x 3n, both triangles), kept for the solvers made from it (InteriorSolver).
  const Eigen::SparseMatrix<double>& matrix() const;
  // The solver of c K (c > 0, finite) on the same factorisation (shared, not copied): its solves return
  // K^-1 f / c. The two share workspace, so they must not be used from two threads at once either.
  StaticSolver scaled(double c) const;
  // The solver of another matrix with the same stored entries (has_pattern) on the same fixed DOFs, reusing this
  // one's symbolic analysis (fill-reducing ordering, supernodes): only the numeric factorisation is done, which is
  // what a matrix refreshed at new values (the corotational model's warped stiffness) needs. Throws
  // std::invalid_argument for another pattern, and as the constructor for a matrix that is not positive definite
  // or not finite. Reads this solver only, so it may run on another thread while this one solves.
  StaticSolver refactorised(Eigen::SparseMatrix<double> K) const;
  // half_column's nested-dissection ordering and symbolic analysis, made now (under the solve guard) unless made
  // already (by this, prepare_half_columns or a first half_column), for refactorised_nested. About 10 ms on the paper
  // mesh.
  void prepare_nested_analysis() const;
  bool has_nested_analysis() const;
  // The solver of another matrix with the same stored entries, as refactorised(), but factorised on this solver's
  // nested-dissection analysis (prepare_nested_analysis must have run: else std::logic_error) with its half_column
  // factorisation a copy of that factor: one ordering-free factorisation for solve() and half_column() both, where
  // refactorised() then prepare_half_columns() make a second ordering and a second factorisation. No
  // single-precision copy. Reads this solver only, as refactorised().
  StaticSolver refactorised_nested(Eigen::SparseMatrix<double> K) const;
  // Whether K (3n x 3n) stores exactly the entries of the factorised matrix (values aside).
  bool has_pattern(const Eigen::SparseMatrix<double>& K) const;

 private:
  struct Impl;
  StaticSolver(std::shared_ptr<Impl> impl, double inverse_scale);
  std::shared_ptr<Impl> impl_;
  double inverse_scale_ = 1.0;  // solves return inverse_scale_ * (factorised matrix)^-1 f
};

// The solution off a boundary from the solution on it: for K u = f with f = 0 on every free DOF off the boundary
// nodes (the interior), u_I = -K_II^-1 K_IB u_B. K_II, the interior's own factorisation, made once, is much
// smaller than K's when the boundary is a thin wall's both surfaces (the 32 x 41 x 5 tube: 3.7 against 8.0 million
// nonzeros, a solve 3.8 against 8.6 ms). Its solves use their own workspace, apart from the solver it came from.
class InteriorSolver {
 public:
  // The interior: the free DOFs of `solver` on nodes not in `boundary` (node ids; repeats allowed). Throws
  // std::invalid_argument for a node out of range or an empty interior.
  InteriorSolver(const StaticSolver& solver, const std::vector<int>& boundary);
  // u (3n): read on the boundary's free DOFs; written on the interior (fixed DOFs untouched).
  void complete(Eigen::VectorXd& u) const;
  long factor_nonzeros() const { return interior_.factor_nonzeros(); }
  int n_interior_dofs() const { return interior_.n_free_dofs(); }

 private:
  StaticSolver interior_;                 // K with the solver's fixed DOFs and the boundary's fixed: K_II
  Eigen::SparseMatrix<double> coupling_;  // K_IB: 3n x 3n, rows of interior DOFs, columns of boundary free DOFs
};

}  // namespace lumen::physics
