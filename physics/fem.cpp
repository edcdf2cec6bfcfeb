// Linear tetrahedral FEM: element kernels, assembly, CHOLMOD prefactorised static solver.
#include "physics/fem.hpp"

#include <cholmod.h>
#include <dlfcn.h>

#include <Eigen/LU>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include "physics/detail/supernodal_single.hpp"

namespace lumen::physics {

// A supernodal factor's elimination tree: each column's supernode, each supernode's parent (the supernode of its
// first row below its own columns; -1: a root). (Outside the anonymous namespace: StaticSolver::Impl keeps one.)
struct SupernodeTree {
  std::vector<int> of_column, parent;
};

namespace {

using Mat43 = Eigen::Matrix<double, 4, 3>;

// The elimination tree of a supernodal factor (SupernodeTree).
SupernodeTree supernode_tree(const detail::SupernodalView& L) {
  SupernodeTree t;
  t.of_column.resize(L.n);
  t.parent.assign(L.nsuper, -1);
  for (int k = 0; k < L.nsuper; ++k)
    for (int c = L.super[k]; c < L.super[k + 1]; ++c) t.of_column[c] = k;
  for (int k = 0; k < L.nsuper; ++k) {
    const int ncol = L.super[k + 1] - L.super[k], nrow = L.pi[k + 1] - L.pi[k];
    if (nrow > ncol) t.parent[k] = t.of_column[L.s[L.pi[k] + ncol]];
  }
  return t;
}

// Y (n x r) <- L^-1 Y, where Y is 0 outside the listed supernodes' columns and those are every supernode on the
// paths from its nonzero rows to the roots, ascending (a child before its parent): a forward sweep over them only,
// with the r right-hand sides together (a supernode's diagonal block solved, then its rows below subtracted).
void forward_on_paths(const detail::SupernodalView& L, const std::vector<int>& supernodes, Eigen::MatrixXd& Y) {
  using Block = Eigen::Map<const Eigen::MatrixXd, 0, Eigen::OuterStride<>>;
  Eigen::MatrixXd below;
  for (int k : supernodes) {
    const int c0 = L.super[k], ncol = L.super[k + 1] - c0, nrow = L.pi[k + 1] - L.pi[k], m = nrow - ncol;
    const Block V(L.x + L.px[k], nrow, ncol, Eigen::OuterStride<>(nrow));
    auto own = Y.middleRows(c0, ncol);
    V.topRows(ncol).triangularView<Eigen::Lower>().solveInPlace(own);
    if (m == 0) continue;
    below.noalias() = V.bottomRows(m) * own;
    const int* rows = L.s + L.pi[k] + ncol;
    for (int i = 0; i < m; ++i) Y.row(rows[i]) -= below.row(i);
  }
}

// CHOLMOD's supernodal factorisations and solves call the system BLAS, OpenBLAS's threaded flavour from
// tools/setup.sh (libopenblas0-pthread, the one that is safe to call from two threads at once: the engine solves
// on one while it factorises on the other; a single-threaded OpenBLAS is only with USE_LOCKING, which Debian's
// serial flavour lacks, and with it the lagged factorisations went bad). Its
// own threads would compete with the engine's second thread on a 2-core machine, so it runs one thread per call:
// openblas_set_num_threads(1) when the BLAS loaded is OpenBLAS (looked up at run time: no link to it), once.
// CHOLMOD itself (Debian's SuiteSparse 5.12) runs loops of its supernodal factorisation on 4 OpenMP threads, a
// number compiled in (CHOLMOD_OMP_NUM_THREADS) that OMP_NUM_THREADS does not change: on 2 cores those threads
// wait on each other and on the engine's. omp_set_max_active_levels(0) makes the OpenMP regions of the thread that
// calls it run on that thread alone (nothing else in Lumen uses OpenMP). libgomp keeps that setting per thread, so
// it is set on every call, by whichever thread factorises: set once, on the first thread, it left every background
// factorisation (a new thread each time) with teams of 4. Measured on the paper mesh (lumen_benchmarks
// BM_PhysicsFactorise, 3 repetitions, twice each way alternating): 60-65 ms wall for 40 ms of the calling thread's
// CPU, against 28-34 ms on one thread.
void use_one_blas_thread() {
  static std::once_flag once;
  std::call_once(once, [] {
    using SetThreads = void (*)(int);
    if (void* f = dlsym(RTLD_DEFAULT, "openblas_set_num_threads")) reinterpret_cast<SetThreads>(f)(1);
  });
  using SetLevels = void (*)(int);
  static const SetLevels set_levels = reinterpret_cast<SetLevels>(dlsym(RTLD_DEFAULT, "omp_set_max_active_levels"));
  if (set_levels) set_levels(0);
}

// Shape-function gradients of a linear tet (4 x 3, 1/metres) and its rest volume (cubic metres).
// Rejects a degenerate or inverted rest element.
Mat43 shape_gradients(const Mat43& X, double& volume) {
  Eigen::Matrix3d Dm;  // edge vectors X_a - X_0 as columns, metres
  for (int a = 0; a < 3; ++a) Dm.col(a) = (X.row(a + 1) - X.row(0)).transpose();
  volume = Dm.determinant() / 6.0;
  if (!(volume > 0.0) || !std::isfinite(volume)) {
    std::ostringstream msg;
    msg << "tet element: rest volume must be > 0 (positively oriented, non-degenerate), got " << volume;
    throw std::invalid_argument(msg.str());
  }
  // grad N_a (a = 1..3) is row a-1 of Dm^-1; grad N_0 = -(sum of the others).
  const Eigen::Matrix3d G = Dm.inverse();
  Mat43 g;
  g.bottomRows<3>() = G;
  g.row(0) = -G.colwise().sum();
  return g;
}

}  // namespace

void validate_material(const LinearMaterial& m) {
  if (!(m.young_modulus > 0.0) || !std::isfinite(m.young_modulus)) {
    std::ostringstream msg;
    msg << "LinearMaterial.young_modulus must be > 0 and finite, got " << m.young_modulus;
    throw std::invalid_argument(msg.str());
  }
  if (!(m.poisson_ratio > -1.0 && m.poisson_ratio < 0.5)) {
    std::ostringstream msg;
    msg << "LinearMaterial.poisson_ratio must be in (-1, 0.5), got " << m.poisson_ratio;
    throw std::invalid_argument(msg.str());
  }
}

LameParameters lame_parameters(const LinearMaterial& m) {
  validate_material(m);
  const double E = m.young_modulus, nu = m.poisson_ratio;
  return {E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))};
}

Eigen::Matrix<double, 12, 12> tet_stiffness(const Mat43& X, const LinearMaterial& m) {
  const LameParameters lame = lame_parameters(m);
  const double lambda = lame.lambda, mu = lame.mu;
  double volume;
  const Mat43 g = shape_gradients(X, volume);

  // Strain-displacement matrix B (6 x 12): Voigt strain (xx, yy, zz, 2yz, 2xz, 2xy) from nodal displacements.
  Eigen::Matrix<double, 6, 12> B = Eigen::Matrix<double, 6, 12>::Zero();
  for (int a = 0; a < 4; ++a) {
    const double gx = g(a, 0), gy = g(a, 1), gz = g(a, 2);
    const int c = 3 * a;
    B(0, c) = gx;
    B(1, c + 1) = gy;
    B(2, c + 2) = gz;
    B(3, c + 1) = gz, B(3, c + 2) = gy;
    B(4, c) = gz, B(4, c + 2) = gx;
    B(5, c) = gy, B(5, c + 1) = gx;
  }

  // Isotropic elasticity D (6 x 6, pascals) in the same Voigt order.
  Eigen::Matrix<double, 6, 6> D = Eigen::Matrix<double, 6, 6>::Zero();
  D.topLeftCorner<3, 3>().setConstant(lambda);
  D.topLeftCorner<3, 3>().diagonal().array() += 2.0 * mu;
  D.bottomRightCorner<3, 3>().diagonal().setConstant(mu);

  // K_e = V B^T D B, symmetrised so that assembly gives an exactly symmetric K.
  Eigen::Matrix<double, 12, 12> K = volume * (B.transpose() * D * B);
  return 0.5 * (K + K.transpose());
}

Eigen::Matrix3d tet_displacement_gradient(const Mat43& X, const Mat43& u) {
  double volume;
  const Mat43 g = shape_gradients(X, volume);
  // H = sum_a u_a (x) grad N_a.
  return u.transpose() * g;
}

Eigen::Matrix3d linear_stress(const Eigen::Matrix3d& eps, const LinearMaterial& m) {
  const LameParameters lame = lame_parameters(m);
  return lame.lambda * eps.trace() * Eigen::Matrix3d::Identity() + 2.0 * lame.mu * eps;
}

double von_mises(const Eigen::Matrix3d& sigma) {
  // Deviator s = sigma - tr(sigma)/3 I; sigma_vm = sqrt(3/2 s:s).
  const Eigen::Matrix3d s = sigma - sigma.trace() / 3.0 * Eigen::Matrix3d::Identity();
  return std::sqrt(1.5 * s.squaredNorm());
}

double tet_energy(const Mat43& X, const Mat43& u, const LinearMaterial& m) {
  const LameParameters lame = lame_parameters(m);
  const double lambda = lame.lambda, mu = lame.mu;
  double volume;
  shape_gradients(X, volume);
  // Small strain eps = sym(H) of the displacement gradient.
  const Eigen::Matrix3d H = tet_displacement_gradient(X, u);
  const Eigen::Matrix3d eps = 0.5 * (H + H.transpose());
  // Energy density mu eps:eps + lambda/2 tr(eps)^2, times the volume.
  const double tr = eps.trace();
  return volume * (mu * eps.squaredNorm() + 0.5 * lambda * tr * tr);
}

ElementAssembly::ElementAssembly(const int* nodes, int n_elements, int k, int n_nodes)
    : k_(k), n_elements_(n_elements) {
  if (k < 1 || n_elements < 0 || n_nodes < 0)
    throw std::invalid_argument("ElementAssembly: needs k >= 1 nodes an element and counts >= 0, got k = " +
                                std::to_string(k) + ", " + std::to_string(n_elements) + " elements, " +
                                std::to_string(n_nodes) + " nodes");
  const size_t per_element = static_cast<size_t>(k);
  for (size_t i = 0; i < per_element * static_cast<size_t>(n_elements); ++i)
    if (nodes[i] < 0 || nodes[i] >= n_nodes)
      throw std::invalid_argument("ElementAssembly: node " + std::to_string(i % per_element) + " of element " +
                                  std::to_string(i / per_element) + " must be a node id in [0, " +
                                  std::to_string(n_nodes) + "), got " + std::to_string(nodes[i]));
  // Each node's neighbours (the nodes it shares an element with, itself included), sorted.
  std::vector<std::vector<int>> neighbours(n_nodes);
  for (int e = 0; e < n_elements; ++e)
    for (int a = 0; a < k; ++a)
      for (int b = 0; b < k; ++b) neighbours[nodes[e * k + a]].push_back(nodes[e * k + b]);
  for (std::vector<int>& list : neighbours) {
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
  }
  // The pattern: column 3 v + j holds rows 3 w + i for every neighbour w of v (the matrix is structurally symmetric).
  const int n = 3 * n_nodes;
  std::vector<int> column_start(n + 1, 0);
  for (int v = 0; v < n_nodes; ++v)
    for (int j = 0; j < 3; ++j)
      column_start[3 * v + j + 1] = column_start[3 * v + j] + 3 * static_cast<int>(neighbours[v].size());
  pattern_.resize(n, n);
  pattern_.resizeNonZeros(column_start[n]);
  std::copy(column_start.begin(), column_start.end(), pattern_.outerIndexPtr());
  int* rows = pattern_.innerIndexPtr();
  for (int v = 0; v < n_nodes; ++v)
    for (int j = 0; j < 3; ++j) {
      int p = column_start[3 * v + j];
      for (int w : neighbours[v])
        for (int i = 0; i < 3; ++i) rows[p++] = 3 * w + i;
    }
  std::fill(pattern_.valuePtr(), pattern_.valuePtr() + pattern_.nonZeros(), 0.0);
  // Per element block column (a, b, j): where row 3 nodes(a) sits in column 3 nodes(b) + j.
  block_start_.resize(static_cast<size_t>(n_elements) * k * k * 3);
  size_t out = 0;
  for (int e = 0; e < n_elements; ++e)
    for (int a = 0; a < k; ++a)
      for (int b = 0; b < k; ++b) {
        const int wa = nodes[e * k + a], vb = nodes[e * k + b];
        const std::vector<int>& list = neighbours[vb];
        const int at = static_cast<int>(std::lower_bound(list.begin(), list.end(), wa) - list.begin());
        for (int j = 0; j < 3; ++j) block_start_[out++] = column_start[3 * vb + j] + 3 * at;
      }
}

Eigen::SparseMatrix<double> assemble_stiffness(const TetMesh& mesh, const LinearMaterial& m) {
  validate_material(m);
  const int n = mesh.n_nodes();
  // Element matrices scattered as triplets (144 per tet), summed by setFromTriplets.
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<size_t>(mesh.tets.rows()) * 144);
  for (int t = 0; t < mesh.tets.rows(); ++t) {
    Mat43 X;
    for (int a = 0; a < 4; ++a) {
      const int v = mesh.tets(t, a);
      if (v < 0 || v >= n) {
        throw std::invalid_argument("assemble_stiffness: mesh.tets(" + std::to_string(t) + ", " + std::to_string(a) +
                                    ") must be a node id in [0, " + std::to_string(n) + "), got " + std::to_string(v));
      }
      X.row(a) = mesh.rest.row(v);
    }
    scatter_element_matrix(tet_stiffness(X, m), mesh.tets.row(t), triplets);
  }
  Eigen::SparseMatrix<double> K(3 * n, 3 * n);
  K.setFromTriplets(triplets.begin(), triplets.end());
  return K;
}

// ---------------------------------------------------------------------------------------------------------------
// StaticSolver

struct StaticSolver::Impl {
  cholmod_common common;
  cholmod_factor* L = nullptr;
  int n = 0;                 // all DOFs, 3 * nodes
  std::vector<int> free_of;  // DOF -> free index, or -1 when fixed, length n
  std::vector<int> dof_of;   // free index -> DOF, length n_free
  long lnz = 0;              // nonzeros of L (the symbolic analysis' count)
  Eigen::SparseMatrix<double> K;  // the matrix as given (3n x 3n), compressed
  // The lower triangle on the free DOFs as CHOLMOD takes it (n_free + 1 column pointers, rows), and each stored
  // entry of K's place in its values (nnz(K); -1: not in it).
  std::vector<int> lower_p, lower_i, place_of;
  // The factor's single-precision copy (add_single_precision, or refactorise / refactorise_nested from a solver that
  // has one; null: none).
  std::unique_ptr<detail::SupernodalSingle> single;
  // Reused solve workspace (single right-hand side).
  mutable std::vector<double> rhs;
  mutable cholmod_dense* X = nullptr;
  mutable cholmod_dense* Y = nullptr;
  mutable cholmod_dense* E = nullptr;
  // Partial solves (half_column): a second factorisation of the matrix, ordered by nested dissection, the free
  // index of each of its columns inverted (position), the one-entry right-hand side (dense and its pattern), and
  // CHOLMOD's outputs and workspace. Made on first use, under the solve guard.
  mutable cholmod_factor* half_L = nullptr;
  bool half_copies_L = false;  // half_L was made as a copy of L (refactorised_nested): the same order and values
  // half_columns' sweeps on L (when half_copies_L): its elimination tree (made on first use), each supernode's mark
  // and a workspace (n_free x r), 0 between uses.
  mutable SupernodeTree tree;
  mutable std::vector<char> marked;
  mutable Eigen::MatrixXd paths;
  mutable std::vector<int> position;
  mutable cholmod_dense* half_b = nullptr;
  mutable cholmod_sparse* half_bset = nullptr;
  mutable cholmod_sparse* half_xset = nullptr;
  mutable cholmod_dense* half_x = nullptr;
  mutable cholmod_dense* half_y = nullptr;
  mutable cholmod_dense* half_e = nullptr;
  // half_forward / half_backward's outputs and workspace (whole sweeps on half_L).
  mutable cholmod_dense* sweep_x = nullptr;
  mutable cholmod_dense* sweep_y = nullptr;
  mutable cholmod_dense* sweep_e = nullptr;
  // The nested-dissection ordering's symbolic analysis (supernodal), kept for refactorised_nested (null: not made),
  // and its factor's nonzeros.
  mutable cholmod_factor* nested = nullptr;
  long nested_lnz = 0;
  // Whether a solve is running (the workspace and the CHOLMOD common above are one per factorisation).
  mutable std::atomic<bool> busy{false};

  Impl() { cholmod_start(&common); }
  ~Impl() {
    cholmod_free_dense(&X, &common);
    cholmod_free_dense(&Y, &common);
    cholmod_free_dense(&E, &common);
    cholmod_free_factor(&half_L, &common);
    cholmod_free_factor(&nested, &common);
    cholmod_free_dense(&half_b, &common);
    cholmod_free_sparse(&half_bset, &common);
    cholmod_free_sparse(&half_xset, &common);
    cholmod_free_dense(&half_x, &common);
    cholmod_free_dense(&half_y, &common);
    cholmod_free_dense(&half_e, &common);
    cholmod_free_dense(&sweep_x, &common);
    cholmod_free_dense(&sweep_y, &common);
    cholmod_free_dense(&sweep_e, &common);
    cholmod_free_factor(&L, &common);
    cholmod_finish(&common);
  }
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  int n_free() const { return static_cast<int>(dof_of.size()); }

  // b (n_free) = f on the free DOFs; f must have n entries (`where` names the caller in the error).
  void gather(const char* where, const Eigen::VectorXd& f, double* b) const {
    if (f.size() != n)
      throw std::invalid_argument(std::string(where) + ": f must have " + std::to_string(n) + " entries, got " +
                                  std::to_string(f.size()));
    for (int k = 0; k < n_free(); ++k) b[k] = f[dof_of[k]];
  }
  // u (n) = scale x on the free DOFs, 0 on the fixed ones.
  void scatter(const double* x, double scale, Eigen::VectorXd& u) const {
    u.setZero(n);
    for (int k = 0; k < n_free(); ++k) u[dof_of[k]] = scale * x[k];
  }

  // L's supernodes as SupernodalSingle reads them (L is supernodal: factorise asks CHOLMOD for it).
  detail::SupernodalView supernodes() const {
    if (!L || !L->is_super || L->itype != CHOLMOD_INT)
      throw std::logic_error("StaticSolver: the factor must be supernodal with int indices");
    detail::SupernodalView v;
    v.n = static_cast<int>(L->n);
    v.nsuper = static_cast<int>(L->nsuper);
    v.super = static_cast<const int*>(L->super);
    v.pi = static_cast<const int*>(L->pi);
    v.px = static_cast<const int*>(L->px);
    v.s = static_cast<const int*>(L->s);
    v.x = static_cast<const double*>(L->x);
    v.perm = static_cast<const int*>(L->Perm);
    return v;
  }

  // A cholmod_dense header over caller-owned column-major memory (nrow x ncol).
  static cholmod_dense wrap(double* data, int nrow, int ncol) {
    cholmod_dense d{};
    d.nrow = static_cast<size_t>(nrow);
    d.ncol = static_cast<size_t>(ncol);
    d.nzmax = d.nrow * d.ncol;
    d.d = d.nrow;
    d.x = data;
    d.z = nullptr;
    d.xtype = CHOLMOD_REAL;
    d.dtype = CHOLMOD_DOUBLE;
    return d;
  }

  // The free DOFs of the fixed mask (per DOF, 1 = fixed).
  void set_free(const std::vector<char>& fixed) {
    free_of.assign(n, -1);
    dof_of.clear();
    for (int d = 0; d < n; ++d)
      if (!fixed[d]) {
        free_of[d] = static_cast<int>(dof_of.size());
        dof_of.push_back(d);
      }
    if (n_free() == 0) throw std::invalid_argument("StaticSolver: every DOF is fixed, nothing to solve");
  }

  // The pattern of K's lower triangle on the free DOFs (CHOLMOD's A: column pointers lower_p, rows lower_i) and,
  // per stored entry of K in column order, its place in A's values (or -1: upper triangle or a fixed DOF).
  // (The free numbering keeps the DOFs' order, so each column's rows stay sorted.)
  void set_lower_pattern() {
    const int nf = n_free();
    lower_p.assign(nf + 1, 0);
    lower_i.clear();
    place_of.clear();
    place_of.reserve(K.nonZeros());
    for (int j = 0; j < K.outerSize(); ++j) {
      const int jf = free_of[j];
      for (Eigen::SparseMatrix<double>::InnerIterator it(K, j); it; ++it) {
        const int fi = free_of[it.row()];
        const bool lower = jf >= 0 && fi >= jf;
        place_of.push_back(lower ? static_cast<int>(lower_i.size()) : -1);
        if (lower) lower_i.push_back(fi);
      }
      if (jf >= 0) lower_p[jf + 1] = static_cast<int>(lower_i.size());
    }
  }

  // CHOLMOD's A (the caller frees it) with the values of K (whose pattern set_lower_pattern read).
  cholmod_sparse* lower_matrix() {
    const int nf = n_free();
    cholmod_sparse* A = cholmod_allocate_sparse(nf, nf, lower_i.size(), 1, 1, -1, CHOLMOD_REAL, &common);
    if (!A) throw std::runtime_error("StaticSolver: CHOLMOD could not allocate the matrix");
    std::copy(lower_p.begin(), lower_p.end(), static_cast<int*>(A->p));
    std::copy(lower_i.begin(), lower_i.end(), static_cast<int*>(A->i));
    double* Ax = static_cast<double*>(A->x);
    size_t k = 0;
    for (int j = 0; j < K.outerSize(); ++j)
      for (Eigen::SparseMatrix<double>::InnerIterator it(K, j); it; ++it, ++k) {
        if (!std::isfinite(it.value())) {
          cholmod_free_sparse(&A, &common);
          std::ostringstream msg;
          msg << "StaticSolver: K(" << it.row() << ", " << j << ") must be finite, got " << it.value();
          throw std::invalid_argument(msg.str());
        }
        if (place_of[k] >= 0) Ax[place_of[k]] = it.value();
      }
    return A;
  }

  // Numeric factorisation of A into F (L or half_L; symbolic or numeric already: then refactorised on its analysis),
  // and the checks: CHOLMOD's status, positive definiteness, singularity up to round-off. Frees A.
  void factorise_numeric(cholmod_sparse* A, cholmod_factor* F) {
    use_one_blas_thread();
    const bool ok = F && cholmod_factorize(A, F, &common);
    cholmod_free_sparse(&A, &common);
    if (!ok || common.status == CHOLMOD_OUT_OF_MEMORY) {
      throw std::runtime_error("StaticSolver: CHOLMOD factorisation failed (status " + std::to_string(common.status) +
                               ")");
    }
    // Not positive definite, or singular up to round-off (rigid motion left free).
    const double rcond = cholmod_rcond(F, &common);
    if (common.status == CHOLMOD_NOT_POSDEF || static_cast<int>(F->minor) < n_free() || !(rcond > 1e-12)) {
      std::ostringstream msg;
      msg << "StaticSolver: K on the free DOFs is not positive definite (reciprocal condition estimate " << rcond
          << "); the fixed DOFs must remove all rigid motion";
      throw std::invalid_argument(msg.str());
    }
  }

  // half_column's factorisation (nested dissection, supernodal LL^T) and workspace, unless made already (half_L,
  // set last, says they are).
  void prepare_half() {
    if (half_L) return;
    prepare_half_workspace();
    analyse_nested();
    cholmod_factor* F = copy_factor(nested);
    try {
      factorise_numeric(lower_matrix(), F);
    } catch (...) {
      cholmod_free_factor(&F, &common);
      throw;
    }
    set_half(F);
  }

  // The nested-dissection ordering (METIS) and its supernodal symbolic analysis, unless made already.
  void analyse_nested() {
    if (nested) return;
    cholmod_sparse* A = lower_matrix();
    const int nmethods = common.nmethods, ordering = common.method[0].ordering;
    common.nmethods = 1;
    common.method[0].ordering = CHOLMOD_METIS;
    common.supernodal = CHOLMOD_SUPERNODAL;
    cholmod_factor* F = cholmod_analyze(A, &common);
    common.nmethods = nmethods;
    common.method[0].ordering = ordering;
    cholmod_free_sparse(&A, &common);
    if (!F)
      throw std::runtime_error("StaticSolver: CHOLMOD's nested-dissection analysis failed (status " +
                               std::to_string(common.status) + ")");
    nested = F;
    nested_lnz = static_cast<long>(common.lnz);
  }

  // A copy of F (CHOLMOD's), or std::runtime_error.
  cholmod_factor* copy_factor(const cholmod_factor* F) {
    cholmod_factor* C = cholmod_copy_factor(const_cast<cholmod_factor*>(F), &common);
    if (!C) throw std::runtime_error("StaticSolver: CHOLMOD factor copy failed (status " + std::to_string(common.status) + ")");
    return C;
  }

  // The partial solves' one-entry right-hand side (dense and its pattern).
  void prepare_half_workspace() {
    const int nf = n_free();
    if (!half_b) half_b = cholmod_zeros(nf, 1, CHOLMOD_REAL, &common);
    if (!half_bset) half_bset = cholmod_allocate_sparse(nf, 1, 1, 1, 1, 0, CHOLMOD_PATTERN, &common);
    if (!half_b || !half_bset)
      throw std::runtime_error("StaticSolver::half_column: CHOLMOD allocation failed (status " +
                               std::to_string(common.status) + ")");
    static_cast<int*>(half_bset->p)[0] = 0;
    static_cast<int*>(half_bset->p)[1] = 1;
  }

  // F (numeric, nested dissection) becomes half_L, with each free index's column in it (position).
  void set_half(cholmod_factor* F) {
    const int nf = n_free();
    position.resize(nf);
    const int* perm = static_cast<const int*>(F->Perm);
    for (int j = 0; j < nf; ++j) position[perm[j]] = j;
    half_L = F;
  }

  // y = L^-1 e_j on half_L (j in its order), on the reach of j only: half_xset holds the pattern, half_x the values.
  void half_solve(int j) {
    static_cast<double*>(half_b->x)[j] = 1.0;
    static_cast<int*>(half_bset->i)[0] = j;
    const int ok = cholmod_solve2(CHOLMOD_L, half_L, half_b, half_bset, &half_x, &half_xset, &half_y, &half_e, &common);
    static_cast<double*>(half_b->x)[j] = 0.0;
    if (!ok)
      throw std::runtime_error("StaticSolver::half_column: CHOLMOD partial solve failed (status " +
                               std::to_string(common.status) + ")");
  }

  // half_columns on half_L: one partial solve per DOF, onto the union of their patterns, times scale.
  void half_columns_partial(const std::vector<int>& dofs, double scale, std::vector<int>& index,
                            std::vector<double>& value) {
    const int r = static_cast<int>(dofs.size());
    std::vector<std::vector<std::pair<int, double>>> columns(r);
    for (int c = 0; c < r; ++c) {
      const int k = free_of[dofs[c]];
      if (k < 0) continue;
      half_solve(position[k]);
      const int* xp = static_cast<const int*>(half_xset->p);
      const int* xi = static_cast<const int*>(half_xset->i);
      const double* x = static_cast<const double*>(half_x->x);
      for (int e = xp[0]; e < xp[1]; ++e) {
        columns[c].emplace_back(xi[e], x[xi[e]]);
        index.push_back(xi[e]);
      }
    }
    std::sort(index.begin(), index.end());
    index.erase(std::unique(index.begin(), index.end()), index.end());
    value.assign(index.size() * static_cast<size_t>(r), 0.0);
    for (int c = 0; c < r; ++c)
      for (const auto& [i, x] : columns[c]) {
        const size_t e = static_cast<size_t>(std::lower_bound(index.begin(), index.end(), i) - index.begin());
        value[e * r + c] = scale * x;
      }
  }

  // half_columns on L (supernodal, half_L's order): the supernodes on the DOFs' paths to the roots, ascending, one
  // forward sweep over them, times scale; the workspace (paths) left 0.
  void half_columns_on_paths(const std::vector<int>& dofs, double scale, std::vector<int>& index,
                             std::vector<double>& value) {
    const int r = static_cast<int>(dofs.size());
    const detail::SupernodalView view = supernodes();
    if (tree.parent.empty()) {
      tree = supernode_tree(view);
      marked.assign(tree.parent.size(), 0);
    }
    if (paths.rows() != n_free() || paths.cols() != r) paths = Eigen::MatrixXd::Zero(n_free(), r);
    std::vector<int> on_paths;
    for (int c = 0; c < r; ++c) {
      const int k = free_of[dofs[c]];
      if (k < 0) continue;
      const int j = position[k];
      paths(j, c) = 1.0;
      for (int s = tree.of_column[j]; s >= 0 && !marked[s]; s = tree.parent[s]) {
        marked[s] = 1;
        on_paths.push_back(s);
      }
    }
    std::sort(on_paths.begin(), on_paths.end());
    forward_on_paths(view, on_paths, paths);
    // The rows with an entry in any column (a supernode's first columns may have none), each row cleared after.
    for (int s : on_paths) {
      for (int i = view.super[s]; i < view.super[s + 1]; ++i) {
        if (paths.row(i).cwiseAbs().maxCoeff() == 0.0) continue;
        index.push_back(i);
        for (int c = 0; c < r; ++c) value.push_back(scale * paths(i, c));
        paths.row(i).setZero();
      }
      marked[s] = 0;
    }
  }

  // b (n_free, half_L's order) <- L^-1 b (sys CHOLMOD_L) or L^-T b (CHOLMOD_Lt), a whole sweep on half_L's values:
  // on L itself when half_L is its copy (L stays supernodal; CHOLMOD's partial solves turn half_L simplicial).
  void half_sweep(int sys, std::vector<double>& b, const char* where) {
    cholmod_dense B = wrap(b.data(), n_free(), 1);
    if (!cholmod_solve2(sys, half_copies_L ? L : half_L, &B, nullptr, &sweep_x, nullptr, &sweep_y, &sweep_e, &common))
      throw std::runtime_error(std::string(where) + ": CHOLMOD solve failed (status " + std::to_string(common.status) +
                               ")");
    const double* x = static_cast<const double*>(sweep_x->x);
    std::copy(x, x + n_free(), b.begin());
  }

  // Copies the lower triangle of K on the free DOFs into CHOLMOD, analyses and factorises it (supernodal LL^T).
  void factorise(const Eigen::SparseMatrix<double>& K_in, const std::vector<char>& fixed) {
    K = K_in;
    K.makeCompressed();
    n = static_cast<int>(K.rows());
    set_free(fixed);
    set_lower_pattern();
    cholmod_sparse* A = lower_matrix();
    // Symbolic analysis (fill-reducing ordering and supernodes), then the numeric factorisation.
    common.supernodal = CHOLMOD_SUPERNODAL;
    common.print = 0;
    L = cholmod_analyze(A, &common);
    factorise_numeric(A, L);
    lnz = static_cast<long>(common.lnz);
    // Solves run on the supernodal factor itself (BLAS-2 / BLAS-3 per supernode, OpenBLAS: use_one_blas_thread).
    // Measured on the paper mesh (lumen_benchmarks, 3 alternating runs, 2026-12-05): one solve 0.58-0.64 ms
    // against 1.6-2.2 ms on the simplicial form, 64 right-hand sides 17-21 ms against 63-77 ms. (With Debian's
    // reference BLAS it was the other way round, which is why the factor used to be converted to simplicial.)
  }

  // The same for K_in with the pattern of from.K, on from's fixed DOFs and symbolic analysis (its factor copied,
  // then refactorised with K_in's values): no ordering, no supernode analysis.
  void refactorise(const Impl& from, Eigen::SparseMatrix<double> K_in) {
    cholmod_sparse* A = take_pattern(from, std::move(K_in));
    L = cholmod_copy_factor(from.L, &common);
    factorise_numeric(A, L);
    lnz = from.lnz;
    if (from.single) single = std::make_unique<detail::SupernodalSingle>(supernodes());
  }

  // The same on from's nested-dissection analysis (from.nested made): L is factorised once on it, and half_L is a
  // copy of it (the first partial solve turns half_L simplicial, in place, which would slow L's solves).
  void refactorise_nested(const Impl& from, Eigen::SparseMatrix<double> K_in) {
    cholmod_sparse* A = take_pattern(from, std::move(K_in));
    L = copy_factor(from.nested);
    factorise_numeric(A, L);
    lnz = from.nested_lnz;
    prepare_half_workspace();
    set_half(copy_factor(L));
    half_copies_L = true;
    // (The contact Hessians precondition the corotational predictions too: without the copy those solves ran in
    // double, 8 % of a rendered 8x pinch's main thread in the profile.)
    if (from.single) single = std::make_unique<detail::SupernodalSingle>(supernodes());
  }

  // K_in (the pattern of from.K) as this matrix, with from's free DOFs and lower-triangle pattern; returns its lower
  // triangle for CHOLMOD (factorise_numeric frees it).
  cholmod_sparse* take_pattern(const Impl& from, Eigen::SparseMatrix<double> K_in) {
    K = std::move(K_in);
    K.makeCompressed();
    n = from.n;
    free_of = from.free_of;
    dof_of = from.dof_of;
    lower_p = from.lower_p;
    lower_i = from.lower_i;
    place_of = from.place_of;
    common.supernodal = CHOLMOD_SUPERNODAL;
    common.print = 0;
    return lower_matrix();
  }
};

namespace {

// Whether a and b (both compressed) store the same entries.
bool same_pattern(const Eigen::SparseMatrix<double>& a, const Eigen::SparseMatrix<double>& b) {
  if (a.rows() != b.rows() || a.cols() != b.cols() || a.nonZeros() != b.nonZeros()) return false;
  return std::equal(a.outerIndexPtr(), a.outerIndexPtr() + a.outerSize() + 1, b.outerIndexPtr()) &&
         std::equal(a.innerIndexPtr(), a.innerIndexPtr() + a.nonZeros(), b.innerIndexPtr());
}

// Marks DOFs to fix, validating node ids and components; n_dofs must be a multiple of 3.
std::vector<char> fixed_mask(const Eigen::SparseMatrix<double>& K, const std::vector<FixedDof>& dofs) {
  if (K.rows() != K.cols() || K.rows() % 3 != 0 || K.rows() == 0) {
    throw std::invalid_argument("StaticSolver: K must be square with 3n rows, got " + std::to_string(K.rows()) + " x " +
                                std::to_string(K.cols()));
  }
  const int n_nodes = static_cast<int>(K.rows() / 3);
  std::vector<char> fixed(K.rows(), 0);
  for (size_t k = 0; k < dofs.size(); ++k) {
    if (dofs[k].node < 0 || dofs[k].node >= n_nodes) {
      throw std::invalid_argument("StaticSolver: fixed node [" + std::to_string(k) + "] must be in [0, " +
                                  std::to_string(n_nodes) + "), got " + std::to_string(dofs[k].node));
    }
    if (dofs[k].component < 0 || dofs[k].component > 2) {
      throw std::invalid_argument("StaticSolver: fixed component [" + std::to_string(k) + "] must be 0, 1 or 2, got " +
                                  std::to_string(dofs[k].component));
    }
    fixed[3 * dofs[k].node + dofs[k].component] = 1;
  }
  return fixed;
}

std::vector<FixedDof> whole_nodes(const std::vector<int>& nodes) {
  std::vector<FixedDof> dofs;
  dofs.reserve(3 * nodes.size());
  for (int v : nodes)
    for (int c = 0; c < 3; ++c) dofs.push_back({v, c});
  return dofs;
}

}  // namespace

StaticSolver::StaticSolver(const Eigen::SparseMatrix<double>& K, const std::vector<int>& fixed_nodes)
    : StaticSolver(K, whole_nodes(fixed_nodes)) {}

StaticSolver::StaticSolver(const Eigen::SparseMatrix<double>& K, const std::vector<FixedDof>& fixed_dofs)
    : impl_(std::make_shared<Impl>()) {
  impl_->factorise(K, fixed_mask(K, fixed_dofs));
}

StaticSolver::StaticSolver(std::shared_ptr<Impl> impl, double inverse_scale)
    : impl_(std::move(impl)), inverse_scale_(inverse_scale) {}

namespace {

// Throws std::invalid_argument naming `where` unless K (compressed) stores the solver's entries.
void require_pattern(const char* where, const StaticSolver& solver, const Eigen::SparseMatrix<double>& K) {
  if (solver.has_pattern(K)) return;
  throw std::invalid_argument(std::string(where) + ": K must store the entries of the factorised matrix (" +
                              std::to_string(solver.matrix().nonZeros()) + " in a " + std::to_string(solver.n_dofs()) +
                              " x " + std::to_string(solver.n_dofs()) + " pattern), got " +
                              std::to_string(K.nonZeros()) + " in a " + std::to_string(K.rows()) + " x " +
                              std::to_string(K.cols()));
}

}  // namespace

StaticSolver StaticSolver::refactorised(Eigen::SparseMatrix<double> K) const {
  K.makeCompressed();
  require_pattern("StaticSolver::refactorised", *this, K);
  auto impl = std::make_shared<Impl>();
  impl->refactorise(*impl_, std::move(K));
  return StaticSolver(std::move(impl), 1.0);
}

bool StaticSolver::has_nested_analysis() const { return impl_->nested != nullptr; }

StaticSolver StaticSolver::refactorised_nested(Eigen::SparseMatrix<double> K) const {
  K.makeCompressed();
  require_pattern("StaticSolver::refactorised_nested", *this, K);
  if (!impl_->nested)
    throw std::logic_error("StaticSolver::refactorised_nested: prepare_nested_analysis() has not run on this solver");
  auto impl = std::make_shared<Impl>();
  impl->refactorise_nested(*impl_, std::move(K));
  return StaticSolver(std::move(impl), 1.0);
}

bool StaticSolver::has_pattern(const Eigen::SparseMatrix<double>& K) const {
  if (K.isCompressed()) return same_pattern(K, impl_->K);
  Eigen::SparseMatrix<double> compressed = K;
  compressed.makeCompressed();
  return same_pattern(compressed, impl_->K);
}

StaticSolver StaticSolver::scaled(double c) const {
  if (!(c > 0.0) || !std::isfinite(c))
    throw std::invalid_argument("StaticSolver::scaled: c must be > 0 and finite, got " + std::to_string(c));
  return StaticSolver(impl_, inverse_scale_ / c);
}

StaticSolver::~StaticSolver() = default;
StaticSolver::StaticSolver(StaticSolver&&) noexcept = default;
StaticSolver& StaticSolver::operator=(StaticSolver&&) noexcept = default;

int StaticSolver::n_dofs() const { return impl_->n; }
int StaticSolver::n_free_dofs() const { return impl_->n_free(); }
long StaticSolver::factor_nonzeros() const {
  return impl_->lnz;
}

bool StaticSolver::is_fixed_dof(int dof) const {
  if (dof < 0 || dof >= impl_->n) {
    throw std::invalid_argument("StaticSolver::is_fixed_dof: dof must be in [0, " + std::to_string(impl_->n) +
                                "), got " + std::to_string(dof));
  }
  return impl_->free_of[dof] < 0;
}

const Eigen::SparseMatrix<double>& StaticSolver::matrix() const { return impl_->K; }

namespace {

// The solver's fixed DOFs and every DOF of the boundary nodes (validated), as FixedDofs.
std::vector<FixedDof> interior_fixed(const StaticSolver& solver, const std::vector<int>& boundary) {
  const int n = solver.n_dofs();
  std::vector<FixedDof> dofs;
  for (int d = 0; d < n; ++d)
    if (solver.is_fixed_dof(d)) dofs.push_back({d / 3, d % 3});
  for (size_t k = 0; k < boundary.size(); ++k) {
    if (boundary[k] < 0 || boundary[k] >= n / 3)
      throw std::invalid_argument("InteriorSolver: boundary[" + std::to_string(k) + "] must be in [0, " +
                                  std::to_string(n / 3) + "), got " + std::to_string(boundary[k]));
    for (int c = 0; c < 3; ++c) dofs.push_back({boundary[k], c});
  }
  return dofs;
}

}  // namespace

InteriorSolver::InteriorSolver(const StaticSolver& solver, const std::vector<int>& boundary)
    : interior_(solver.matrix(), interior_fixed(solver, boundary)) {
  // K_IB: the entries of K in an interior row and a free boundary column.
  const Eigen::SparseMatrix<double>& K = solver.matrix();
  std::vector<Eigen::Triplet<double>> entries;
  for (int j = 0; j < K.outerSize(); ++j) {
    if (solver.is_fixed_dof(j) || !interior_.is_fixed_dof(j)) continue;  // (boundary: fixed here only)
    for (Eigen::SparseMatrix<double>::InnerIterator it(K, j); it; ++it)
      if (!interior_.is_fixed_dof(static_cast<int>(it.row()))) entries.emplace_back(it.row(), j, it.value());
  }
  coupling_.resize(K.rows(), K.cols());
  coupling_.setFromTriplets(entries.begin(), entries.end());
}

void InteriorSolver::complete(Eigen::VectorXd& u) const {
  if (u.size() != interior_.n_dofs())
    throw std::invalid_argument("InteriorSolver::complete: u must have " + std::to_string(interior_.n_dofs()) +
                                " entries, got " + std::to_string(u.size()));
  // u_I = K_II^-1 (-K_IB u_B); the interior solver returns 0 off the interior, so only its entries are taken.
  const Eigen::VectorXd r = -(coupling_ * u);
  Eigen::VectorXd u_interior;
  interior_.solve(r, u_interior);
  for (int d = 0; d < u.size(); ++d)
    if (!interior_.is_fixed_dof(d)) u[d] = u_interior[d];
}

namespace {

// One solve at a time on a factorisation: a second caller while one runs (another thread) is a programming error,
// refused instead of corrupting the shared workspace.
class SolveGuard {
 public:
  SolveGuard(std::atomic<bool>& busy, const char* what) : busy_(busy) {
    if (busy_.exchange(true))
      throw std::logic_error(std::string(what) + ": the solver is already solving on another thread (one at a time)");
  }
  ~SolveGuard() { busy_.store(false); }
  SolveGuard(const SolveGuard&) = delete;
  SolveGuard& operator=(const SolveGuard&) = delete;

 private:
  std::atomic<bool>& busy_;
};

}  // namespace

void StaticSolver::add_single_precision() {
  if (!impl_->single) impl_->single = std::make_unique<detail::SupernodalSingle>(impl_->supernodes());
}

bool StaticSolver::has_single_precision() const { return impl_->single != nullptr; }

void StaticSolver::solve_approximately(const Eigen::VectorXd& f, Eigen::VectorXd& u) const {
  Impl& m = *impl_;
  if (!m.single) {
    solve(f, u);
    return;
  }
  const SolveGuard guard(m.busy, "StaticSolver::solve_approximately");
  // Gather the free DOFs, the two triangular solves on the rounded factor, scatter (fixed DOFs are 0).
  const int nf = m.n_free();
  m.rhs.resize(2 * static_cast<size_t>(nf));
  double* b = m.rhs.data();
  double* x = b + nf;
  m.gather("StaticSolver::solve_approximately", f, b);
  m.single->solve(b, x);
  m.scatter(x, inverse_scale_, u);
}

void StaticSolver::solve(const Eigen::VectorXd& f, Eigen::VectorXd& u) const {
  Impl& m = *impl_;
  const SolveGuard guard(m.busy, "StaticSolver::solve");
  // Gather the free DOFs, back-substitute with reused workspace, scatter (fixed DOFs are 0).
  const int nf = m.n_free();
  m.rhs.resize(nf);
  m.gather("StaticSolver::solve", f, m.rhs.data());
  cholmod_dense B = Impl::wrap(m.rhs.data(), nf, 1);
  if (!cholmod_solve2(CHOLMOD_A, m.L, &B, nullptr, &m.X, nullptr, &m.Y, &m.E, &m.common)) {
    throw std::runtime_error("StaticSolver::solve: CHOLMOD solve failed (status " + std::to_string(m.common.status) +
                             ")");
  }
  m.scatter(static_cast<const double*>(m.X->x), inverse_scale_, u);
}

void StaticSolver::prepare_nested_analysis() const {
  const SolveGuard guard(impl_->busy, "StaticSolver::prepare_nested_analysis");
  impl_->analyse_nested();
}

void StaticSolver::prepare_half_columns() const {
  Impl& m = *impl_;
  const SolveGuard guard(m.busy, "StaticSolver::prepare_half_columns");
  m.prepare_half();
  if (m.n_free() > 0) m.half_solve(0);  // (CHOLMOD's first partial solve sets up its workspace)
}

void StaticSolver::half_column(int dof, std::vector<int>& index, std::vector<double>& value) const {
  Impl& m = *impl_;
  const SolveGuard guard(m.busy, "StaticSolver::half_column");
  if (dof < 0 || dof >= m.n)
    throw std::invalid_argument("StaticSolver::half_column: dof must be in [0, " + std::to_string(m.n) + "), got " +
                                std::to_string(dof));
  index.clear();
  value.clear();
  // L y = e_k in the factor's order (a partial solve on half_L), its reach's entries ascending, scaled by
  // sqrt(inverse scale) (L L^T is the factorised matrix, whose inverse this solver returns times inverse_scale_).
  m.prepare_half();
  m.half_columns_partial({dof}, std::sqrt(inverse_scale_), index, value);
}

void StaticSolver::half_forward(const Eigen::VectorXd& f, std::vector<double>& z) const {
  Impl& m = *impl_;
  const char* where = "StaticSolver::half_forward";
  const SolveGuard guard(m.busy, where);
  // P f on the free DOFs (free index k sits at position[k] in half_L's order), then the forward sweep.
  std::vector<double>& b = m.rhs;
  b.resize(m.n_free());
  m.gather(where, f, b.data());
  m.prepare_half();
  z.resize(b.size());
  for (int k = 0; k < m.n_free(); ++k) z[m.position[k]] = b[k];
  m.half_sweep(CHOLMOD_L, z, where);
  const double scale = std::sqrt(inverse_scale_);
  for (double& v : z) v *= scale;
}

bool StaticSolver::splits_on_its_factor() const { return impl_->half_copies_L; }

void StaticSolver::half_columns(const std::vector<int>& dofs, std::vector<int>& index,
                                std::vector<double>& value) const {
  Impl& m = *impl_;
  const SolveGuard guard(m.busy, "StaticSolver::half_columns");
  for (size_t c = 0; c < dofs.size(); ++c)
    if (dofs[c] < 0 || dofs[c] >= m.n)
      throw std::invalid_argument("StaticSolver::half_columns: dofs[" + std::to_string(c) + "] must be in [0, " +
                                  std::to_string(m.n) + "), got " + std::to_string(dofs[c]));
  m.prepare_half();
  index.clear();
  value.clear();
  if (m.half_copies_L) m.half_columns_on_paths(dofs, std::sqrt(inverse_scale_), index, value);
  else m.half_columns_partial(dofs, std::sqrt(inverse_scale_), index, value);
}


void StaticSolver::half_backward(const std::vector<double>& z, Eigen::VectorXd& u) const {
  Impl& m = *impl_;
  const char* where = "StaticSolver::half_backward";
  const SolveGuard guard(m.busy, where);
  if (static_cast<int>(z.size()) != m.n_free())
    throw std::invalid_argument(std::string(where) + ": z must have " + std::to_string(m.n_free()) +
                                " entries (the free DOFs), got " + std::to_string(z.size()));
  m.prepare_half();
  std::vector<double>& x = m.rhs;
  x = z;
  m.half_sweep(CHOLMOD_Lt, x, where);
  // Back to the free DOFs' order (P^T), scattered.
  const double scale = std::sqrt(inverse_scale_);
  u.setZero(m.n);
  for (int k = 0; k < m.n_free(); ++k) u[m.dof_of[k]] = scale * x[m.position[k]];
}

Eigen::MatrixXd StaticSolver::solve_many(const Eigen::MatrixXd& F) const {
  Impl& m = *impl_;
  const SolveGuard guard(m.busy, "StaticSolver::solve_many");
  if (F.rows() != m.n) {
    throw std::invalid_argument("StaticSolver::solve_many: F must have " + std::to_string(m.n) + " rows, got " +
                                std::to_string(F.rows()));
  }
  const int nf = m.n_free(), nc = static_cast<int>(F.cols());
  Eigen::MatrixXd U = Eigen::MatrixXd::Zero(m.n, nc);
  if (nc == 0) return U;
  // Gather the free rows, one multi-column CHOLMOD solve, scatter.
  Eigen::MatrixXd Bf(nf, nc);
  for (int k = 0; k < nf; ++k) Bf.row(k) = F.row(m.dof_of[k]);
  cholmod_dense B = Impl::wrap(Bf.data(), nf, nc);
  cholmod_dense* X = cholmod_solve(CHOLMOD_A, m.L, &B, &m.common);
  if (!X) {
    throw std::runtime_error("StaticSolver::solve_many: CHOLMOD solve failed (status " +
                             std::to_string(m.common.status) + ")");
  }
  const Eigen::Map<const Eigen::MatrixXd, 0, Eigen::OuterStride<>> Xf(static_cast<const double*>(X->x), nf, nc,
                                                                      Eigen::OuterStride<>(X->d));
  for (int k = 0; k < nf; ++k) U.row(m.dof_of[k]) = Xf.row(k);
  if (inverse_scale_ != 1.0) U *= inverse_scale_;
  cholmod_free_dense(&X, &m.common);
  return U;
}

}  // namespace lumen::physics
