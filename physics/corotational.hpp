#pragma once
// Corotational linear elasticity (stiffness warping, Mueller & Gross 2004) and its quasi-static solve.
//
// Each tet carries the rotation R_e of its deformation gradient F_e (polar decomposition, kept proper when the
// element inverts, Irving et al. 2004). Its elastic force is f_e = R_e K_e (R_e^T x_e - X_e) and its warped
// stiffness R_e K_e R_e^T, so rigid rotations cost no energy while small deformations match the linear model.
// The nonlinear equilibrium f_int(u) = f_ext is solved by fixed-point iterations on the warped system; each
// linear solve is CG preconditioned with a CHOLMOD factorisation (StaticSolver): the rest state's, or, once the
// rotations have made it a poor match (a solve needing many CG iterations), a lagged one of K_w itself at the
// rotations of that moment, refreshed on a background thread while the solves go on; warm-started from the
// previous frame's displacement.
#include <future>
#include <memory>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "physics/contact_rows.hpp"
#include "physics/fem.hpp"
#include "physics/mesh.hpp"
#include "physics/polar.hpp"
#include "physics/quadratic.hpp"

namespace lumen::physics {

// The part of the exact corotational tangent that the warped stiffness K_w leaves out (the derivative of the
// rotations), for one tet: sum_k stiffness[k] b_k b_k^T, 12 x 12. In the signed singular frame F = U Sigma V^T
// (U = R Q, V = Q, Q the eigenvectors of the symmetric R^T F) the energy's Hessian is K_w's except on the three
// twist modes T_k = U (e_i e_j^T - e_j e_i^T) V^T / sqrt 2, pairs (i, j) = (1, 2), (0, 2), (0, 1), where K_w has 0
// and the energy psi(Sigma) = mu sum (s_i - 1)^2 + lambda/2 (sum s_i - 3)^2 has (psi_i + psi_j) / (s_i + s_j)
// (Smith et al. 2019, "Analytic eigensystems for isotropic distortion energies").
struct TwistModes {
  Eigen::Matrix<double, 12, 3> b;  // column k: the nodal gradient of dF : T_k (nodes of the tet, x y z each), 1/m
  Eigen::Vector3d stiffness;       // rest volume times the twist eigenvalue, N m; >= 0 when projected
};

// Element data of a tet mesh for corotational kernels. Keeps no reference to the mesh.
// - 4-node tets: per tet the rest shape-function gradients and volume; matrix-free (K_e p = V B^T D B p is
//   evaluated from the gradients, the same element as tet_stiffness).
// - 10-node tets: one rotation per element, that of the volume-averaged deformation gradient
//   F_e = I + sum_a u_a (x) G_a (G_a = tet10_mean_gradients; F_e is the deformation gradient itself for a
//   straight element deformed affinely), and the stored quadratic K_e (tet10_stiffness, 30 x 30):
//   f_e = R_e K_e (R_e^T x_e - X_e), K_w = R_e K_e R_e^T (element-wise corotation, as for higher-order elements in
//   Nesme et al. 2005). Rigid motions cost nothing and small deformations match the linear tet10, but the
//   rotations' derivative is left out of the tangent entirely (no twist modes: warped steps only).
class CorotationalElements {
 public:
  // Throws std::invalid_argument for an invalid material, node index or a non-positive rest volume. support: the
  // elastic supports' springs to rest (the organ held by the tissue around it, physics/support.hpp), a diagonal
  // stiffness per DOF (3n, N/m, >= 0; empty: none); they are part of every kernel below: the forces gain S u, the
  // products S p, the stiffness matrices diag(S), the energy u^T S u / 2.
  CorotationalElements(const TetMesh& mesh, const LinearMaterial& material,
                       const Eigen::VectorXd& support = Eigen::VectorXd());
  // The same for 10-node tets (and a Jacobian that is not positive at a quadrature point).
  CorotationalElements(const QuadraticMesh& mesh, const LinearMaterial& material,
                       const Eigen::VectorXd& support = Eigen::VectorXd());

  int n_nodes() const { return n_nodes_; }
  int n_dofs() const { return 3 * n_nodes_; }
  int n_tets() const { return static_cast<int>(tets_.rows()); }
  ElementOrder order() const { return order_; }
  // Corner nodes of each element (n_tets x 4; the whole element for 4-node tets).
  const Tets& tets() const { return tets_; }
  const LinearMaterial& material() const { return material_; }
  // Rest volume of tet t, cubic metres.
  double rest_volume(int t) const { return volume_[t]; }

  // Deformation gradient of tet t for displacements u (3n, metres): F = I + sum_a u_a (x) grad N_a (10-node
  // tets: its volume average, as above).
  Eigen::Matrix3d deformation_gradient(const Eigen::VectorXd& u, int t) const;
  // Per-tet rotations R (n_tets, proper) of the deformation gradients at u; returns the number of inverted tets
  // (det F <= 0).
  int rotations(const Eigen::VectorXd& u, std::vector<Eigen::Matrix3d>& R) const;
  // Elastic forces f_int = sum_e R_e K_e (R_e^T x_e - X_e), 3n, newtons (x = X + u). With R_e = I this is K u.
  // With energy: also elastic_energy(u, R), summed in the same element loop (joules).
  void elastic_forces(const Eigen::VectorXd& u, const std::vector<Eigen::Matrix3d>& R, Eigen::VectorXd& f,
                      double* energy = nullptr) const;
  // rotations(u, R), then elastic_forces(u, R, f, energy), in one pass over the tets (each tet's nodes read once);
  // returns the number of inverted tets.
  int rotations_and_forces(const Eigen::VectorXd& u, std::vector<Eigen::Matrix3d>& R, Eigen::VectorXd& f,
                           double* energy = nullptr) const;
  // y = K_w p with the warped stiffness K_w = sum_e R_e K_e R_e^T (p, y: 3n).
  void warped_product(const std::vector<Eigen::Matrix3d>& R, const Eigen::VectorXd& p, Eigen::VectorXd& y) const;
  // The same K_w assembled, 3n x 3n, N/m (the sparsity of the rest stiffness K; with R = identity it is K).
  Eigen::SparseMatrix<double> warped_stiffness(const std::vector<Eigen::Matrix3d>& R) const;
  // Per-tet twist modes (n_tets) of the tangent at u with rotations R (as from rotations(u)); 4-node tets only
  // (std::invalid_argument for 10-node tets, as the two functions after it). project: each
  // negative twist eigenvalue (a tet compressed across the pair) is clamped to 0, so that the tangent
  // K_w + sum_e twist_e is positive semi-definite per element; otherwise the exact Hessian of elastic_energy.
  void twist_modes(const Eigen::VectorXd& u, const std::vector<Eigen::Matrix3d>& R, bool project,
                   std::vector<TwistModes>& modes) const;
  // y = K_t p = K_w p + sum_e b_e diag(stiffness_e) b_e^T p_e (p, y: 3n).
  void tangent_product(const std::vector<Eigen::Matrix3d>& R, const std::vector<TwistModes>& modes,
                       const Eigen::VectorXd& p, Eigen::VectorXd& y) const;
  // The same K_t assembled, 3n x 3n, N/m (the sparsity of K).
  Eigen::SparseMatrix<double> tangent_stiffness(const std::vector<Eigen::Matrix3d>& R,
                                                const std::vector<TwistModes>& modes) const;
  // Elastic energy sum_e 1/2 (R_e^T x_e - X_e)^T K_e (R_e^T x_e - X_e), joules.
  double elastic_energy(const Eigen::VectorXd& u, const std::vector<Eigen::Matrix3d>& R) const;
  // Per-node rotations (n_nodes): the proper rotation of the sum of the rotations of the tets around each node
  // (identity for a node in no tet).
  void node_rotations(const std::vector<Eigen::Matrix3d>& R, std::vector<Eigen::Matrix3d>& node_R) const;
  // Throws std::invalid_argument naming `where` unless the elements are 4-node tets (what the twist modes need).
  void require_linear(const char* where) const;
  // The supports' diagonal stiffness (3n, N/m; empty: none), and K + diag(support).
  const Eigen::VectorXd& support() const { return support_; }
  Eigen::SparseMatrix<double> with_support(Eigen::SparseMatrix<double> K) const;

 private:
  Eigen::Matrix3d gradient(const Eigen::VectorXd& u, int t) const;  // deformation_gradient without checks
  void build_node_elements();  // node_tet_start_ / node_tet_ from the element nodes
  void set_support(const Eigen::VectorXd& support);               // validated (std::invalid_argument)
  void add_support(const Eigen::VectorXd& v, Eigen::VectorXd& y) const;  // y += support .* v
  double support_energy(const Eigen::VectorXd& u) const;                  // the supports' springs, joules
  // The kernels of 10-node tets (same contracts as the public functions; quadratic_forces returns the elements'
  // energy).
  double quadratic_forces(const Eigen::VectorXd& u, const std::vector<Eigen::Matrix3d>& R, Eigen::VectorXd& f) const;
  void quadratic_product(const std::vector<Eigen::Matrix3d>& R, const Eigen::VectorXd& p, Eigen::VectorXd& y) const;
  Eigen::SparseMatrix<double> quadratic_stiffness(const std::vector<Eigen::Matrix3d>& R) const;
  double quadratic_energy(const Eigen::VectorXd& u, const std::vector<Eigen::Matrix3d>& R) const;
  // Element t's unrotated displacement R^T x_e - X_e up to a translation (30, metres) and its K_e (30 x 30, N/m),
  // 10-node tets.
  Eigen::Matrix<double, 30, 1> unrotated_displacement(const Eigen::VectorXd& u, const Eigen::Matrix3d& R, int t) const;
  Eigen::Map<const Eigen::Matrix<double, 30, 30>> element_stiffness(int t) const {
    return Eigen::Map<const Eigen::Matrix<double, 30, 30>>(stiffness10_.data() + kTet10Dofs * kTet10Dofs * t);
  }
  static constexpr int kTet10Dofs = 30;
  // Shape-function gradients g_a of tet t (g_0 = -(g_1 + g_2 + g_3)), 1/metres.
  void shape_gradients(int t, Eigen::Vector3d (&g)[4]) const;
  Eigen::Matrix<double, 12, 12> warped_element(const Eigen::Matrix3d& R, int t) const;  // R K_e R^T of tet t, N/m
  void check_rotations(const char* where, const std::vector<Eigen::Matrix3d>& R) const;  // one per tet
  void check_modes(const char* where, const std::vector<TwistModes>& modes) const;        // one per tet
  int n_nodes_ = 0;
  ElementOrder order_ = ElementOrder::kLinear;
  Tets tets_;                              // n_tets x 4 node ids (corners)
  std::vector<Eigen::Matrix3d> grad_;      // per tet: rows a = 0..2 are grad N_{a+1} (= Dm^-1), 1/metres
  std::vector<double> volume_;             // per tet rest volume, cubic metres
  std::vector<int> node_tet_start_;        // CSR node -> incident tets, n_nodes + 1
  std::vector<int> node_tet_;              // incident tet ids
  // 10-node tets only:
  Eigen::Matrix<int, Eigen::Dynamic, 10, Eigen::RowMajor> nodes10_;  // n_tets x 10 node ids
  std::vector<double> stiffness10_;        // n_tets x 30 x 30 (column-major per tet): K_e, N/m
  std::vector<Eigen::Matrix<double, 10, 3>> mean_grad10_;  // per tet: rows G_a, 1/metres
  Points rest10_;                          // n_nodes x 3 rest positions, metres
  LinearMaterial material_;
  double lambda_ = 0.0, mu_ = 0.0;         // Lame parameters, pascals
  Eigen::VectorXd support_;                // the supports' springs to rest, 3n, N/m (empty: none)
  ElementAssembly assembly_;               // the stiffness matrices' pattern over the elements (corners or 10 nodes)
};

// Contacts carried into the nonlinear equilibrium by an augmented Lagrangian (the method of multipliers): rows
// (H u)_r >= g_r with multiplier estimates lambda_r. The solve adds the contact force H^T lambda_eff, with
// lambda_eff_r = max(0, lambda_r + stiffness (g_r - (H u)_r)), and the stiffness h_r h_r^T of each row that pushes
// (lambda_eff_r > 0) to its tangent. With lambda_r the converged multipliers the rows hold exactly; otherwise a
// row is off by (lambda_eff_r - lambda_r) / stiffness.
struct AugmentedContacts {
  std::vector<ContactRow> rows;
  Eigen::VectorXd lambda;  // rows, newtons, >= 0
  double stiffness = 0.0;  // augmentation penalty, N/m, > 0
};

// A symmetric positive definite system A = c_mass diag(mass) + c_stiffness K_w(R) + P (with twist modes:
// c_stiffness K_t(R, twist) for K_w; projected modes keep it positive definite) on the free DOFs of a
// preconditioner's factorisation, P = stiffness sum h_r h_r^T over the contact rows that push (none when
// contacts is null). R = identity rotations gives the linear stiffness K.
struct WarpedSystem {
  const CorotationalElements* elements = nullptr;
  const std::vector<Eigen::Matrix3d>* rotations = nullptr;  // per tet, n_tets
  const Eigen::VectorXd* mass = nullptr;                     // lumped mass, 3n, kg; nullptr when c_mass = 0
  double c_mass = 0.0;                                       // >= 0
  double c_stiffness = 1.0;                                  // > 0
  const AugmentedContacts* contacts = nullptr;               // rows and penalty of P, or null
  const std::vector<char>* pushing = nullptr;                // per row of contacts: 1 when in P
  const std::vector<TwistModes>* twist = nullptr;            // per tet: K_w becomes the tangent K_t, or null
};

// Result of one preconditioned CG solve.
struct PcgResult {
  int iterations = 0;     // preconditioner applications (one CHOLMOD back-substitution each)
  double residual = 0.0;  // |b - A x| / |b| on the free DOFs (0 when b = 0)
  bool converged = false;
  bool negative_curvature = false;  // solve_truncated_pcg: stopped at a direction with p . A p <= 0
};

// Solves A x = b on the free DOFs of `preconditioner` by Eigen's ConjugateGradient, preconditioned with the
// CHOLMOD factorisation (applied as z = Rn solve(Rn^T r) with per-node rotations Rn when node_rotations is
// given; this needs whole fixed nodes). x: in the initial guess (empty = 0), out the solution; fixed DOFs of
// x are 0. b: 3n, entries of fixed DOFs ignored. Stops when |b - A x| <= tolerance |b| or at max_iterations.
PcgResult solve_pcg(const WarpedSystem& system, const StaticSolver& preconditioner, const Eigen::VectorXd& b,
                    Eigen::VectorXd& x, double tolerance, int max_iterations,
                    const std::vector<Eigen::Matrix3d>* node_rotations = nullptr);

// The same system, possibly indefinite (the exact tangent), solved by CG from x = 0 up to the first direction of
// non-positive curvature (truncated CG, Steihaug 1983): x is then a descent direction for the quadratic model
// (b . x > 0), M^-1 b when the first direction already has non-positive curvature. x: out, 3n (fixed DOFs 0);
// node_rotations as for solve_pcg.
PcgResult solve_truncated_pcg(const WarpedSystem& system, const StaticSolver& preconditioner,
                              const Eigen::VectorXd& b, Eigen::VectorXd& x, double tolerance, int max_iterations,
                              const std::vector<Eigen::Matrix3d>* node_rotations = nullptr);

// A corotational model: element data, fixed nodes and the rest-state factorisation used as preconditioner.
// Built once; a solve reads it and writes a CorotationalState.
class CorotationalModel {
 public:
  // fixed_nodes: nodes whose displacement is prescribed (0 unless a solve is given u_fixed); must remove all
  // rigid motion (or the supports must). Factorises K once (StaticSolver). support: as for CorotationalElements
  // (K includes it).
  CorotationalModel(const TetMesh& mesh, const LinearMaterial& material, const std::vector<int>& fixed_nodes,
                    const Eigen::VectorXd& support = Eigen::VectorXd());
  // The same on 10-node tets (K: the elements' warped stiffness at rest, that of assemble_stiffness(mesh)).
  CorotationalModel(const QuadraticMesh& mesh, const LinearMaterial& material, const std::vector<int>& fixed_nodes,
                    const Eigen::VectorXd& support = Eigen::VectorXd());

  const CorotationalElements& elements() const { return elements_; }
  // Rest-state stiffness K, 3n x 3n, N/m, and its CHOLMOD factorisation on the free DOFs.
  const Eigen::SparseMatrix<double>& stiffness() const { return K_; }
  const StaticSolver& solver() const { return solver_; }
  const std::vector<int>& fixed_nodes() const { return fixed_nodes_; }
  int n_dofs() const { return elements_.n_dofs(); }
  bool is_fixed_dof(int dof) const { return solver_.is_fixed_dof(dof); }

 private:
  CorotationalElements elements_;
  Eigen::SparseMatrix<double> K_;
  std::vector<int> fixed_nodes_;
  StaticSolver solver_;
};

// The operator of the corotational solves' linear steps: the warped stiffness K_w (stiffness warping; the
// rotations' derivative left out, so the iterations are quasi-Newton and converge linearly), or the exact
// tangent K_t = K_w + twist modes with each tet's negative twist eigenvalues clamped to 0 (Newton's method on a
// positive semi-definite projection of the Hessian, as in projected Newton, Teran et al. 2005), or the exact one.
// The exact tangent (indefinite where tets are compressed) is Newton's method itself: its linear steps by CG
// truncated at negative curvature (solve_truncated_pcg, a descent direction), line-searched on the potential; a
// step that finds no decrease is replaced by the warped step from the same start.
enum class CorotationalTangent { warped, projected, exact };

// How each linear step is taken. pcg: PCG on the step's operator (K_w or the tangent), preconditioned by the
// lagged factorisation, to a relative tolerance (several back-substitutions and operator products per step).
// chord: the lagged factorisation itself is the operator (du = A^-1 r, one back-substitution, no CG): a chord /
// quasi-Newton iteration whose operator is K_w at the rotations of the last refresh, accelerated by Anderson
// mixing (the multisecant update Liu, Bouaziz and Kavan 2017 get from L-BFGS over a constant prefactored matrix),
// with the factorisation refreshed at the current rotations every refactor_cg_iterations steps, counted over solves
// so that solves of one or two steps (a frame budget) still refresh it (on the background thread with
// refactor_in_background; warped tangent only).
enum class CorotationalMethod { pcg, chord };

// Iteration bounds and tolerances of the corotational solves (validated by each solve).
struct CorotationalOptions {
  // Outer (fixed-point) convergence: |f_ext - f_int(u)| on the free DOFs <= tolerance * force scale, where the
  // force scale is max(|f_ext| on the free DOFs, |f_int(u)| on the fixed DOFs) (the reactions, which carry a
  // prescribed-displacement problem); > 0.
  double tolerance = 1e-3;
  int max_iterations = 20;      // outer iterations (re-linearisations), >= 1
  // Each linear solve stops at |r_cg| <= max(cg_tolerance |r|, tolerance * force scale / 2); in (0, 1).
  double cg_tolerance = 0.1;
  int max_cg_iterations = 100;  // per linear solve, >= 1
  // Work bound of one solve (one frame): the most back-substitutions on the factorisation (cg_iterations) over
  // all its linear steps; the solve stops before a step that could pass it, not converged, and the next solve
  // goes on from its iterate. 0 = no bound, else >= 2 (a PCG step takes at least two); PCG steps only.
  int max_back_substitutions = 0;
  // The work bound of a free prediction that follows a contact solve on the lagged Hessian
  // (CorotationalQuasiStatic::solve_with_contacts), whose contacts are solved in the equilibrium from the last end:
  // the prediction only gives the detection its trial motion. 0 = max_back_substitutions, else >= 2; PCG only.
  int contact_back_substitutions = 0;
  // Precondition with Rn K^-1 Rn^T (per-node average rotations) instead of K^-1; for a lagged factorisation,
  // Rn the nodes' rotations since it was factorised.
  bool rotate_preconditioner = false;
  // Start from the secant prediction u + (u - u_previous) (the last two solutions of a frame sequence) instead
  // of u, when that lowers the residual (one extra evaluation of the rotations and forces); after a refusal the
  // next few solves do not try it (CorotationalState::secant_skips).
  bool extrapolate = false;
  // Lagged warped preconditioner (quasi-static solve only): when a linear solve takes more than this many PCG
  // iterations, K_w at the current rotations is factorised and preconditions the following solves (of this and
  // later frames) until the next refresh; 0 = always the rest factorisation. >= 0.
  int refactor_cg_iterations = 0;
  // Anderson acceleration of the fixed-point iterations: the number of past steps mixed (0 = off), >= 0. A mixed
  // step is kept only when it lowers the residual (otherwise the plain step, and the history restarts).
  int anderson_depth = 0;
  // The PCG solves' Anderson history (differences of iterates and of steps, which describe the fixed-point map's
  // Jacobian, not the loads) goes on from one solve to the next (CorotationalState), so that a frame's first step
  // is already mixed. As within a solve, a mixed step that does not lower the residual restarts it, and so does a
  // diverged solve. Off: each solve starts its history afresh (chord steps always do).
  bool carry_anderson_history = false;
  CorotationalTangent tangent = CorotationalTangent::warped;  // the linear steps' operator (and lagged factor)
  // Factorise on a background thread (the solves go on with the previous preconditioner until it is ready)
  // rather than at once inside the solve.
  bool refactor_in_background = false;
  CorotationalMethod method = CorotationalMethod::pcg;  // the linear steps (chord: warped tangent only)
};

// Throws std::invalid_argument naming the field and its value unless every option is in range.
void validate_options(const CorotationalOptions& options);

// Mutable state of a quasi-static corotational simulation: the displacement (warm start of the next solve) and
// the rotations and elastic forces evaluated at u_eval, reused while u == u_eval.
struct CorotationalState {
  Eigen::VectorXd u;                          // displacements, 3n, metres (empty = 0)
  std::vector<Eigen::Matrix3d> rotations;     // per tet at u_eval
  std::vector<TwistModes> twist;              // per tet at the last linear step (projected tangent only)
  Eigen::VectorXd f_int;                      // elastic forces at u_eval, 3n, newtons
  Eigen::VectorXd u_eval;                     // displacement of the cached evaluation, 3n, metres
  double energy = 0.0;                        // elastic energy at u_eval, joules
  int n_inverted = 0;                         // inverted tets at u_eval
  Eigen::VectorXd u_previous;                 // u before the last solve (for extrapolate), 3n, metres
  int chord_steps_since_refresh = 0;          // chord steps (over solves) since a factorisation was last asked for
  int secant_skips = 0;                       // solves left that start without trying the secant start
  // The PCG solves' Anderson history left by the last solve (options.carry_anderson_history): per kept pair, the
  // differences of iterates and of steps, 3n each, oldest first.
  std::vector<Eigen::VectorXd> anderson_dX, anderson_dF;
  // Lagged warped preconditioner: K_w factorised at earlier rotations (null: the model's rest factorisation),
  // and a factorisation in progress on a background thread (valid() while one runs).
  std::shared_ptr<const StaticSolver> preconditioner;
  std::future<std::shared_ptr<const StaticSolver>> pending;
  // With options.rotate_preconditioner: the per-node rotations at which `preconditioner` and `pending` were
  // factorised (n_nodes each; empty: identity, the rest factorisation), so that the solves precondition with
  // the factor turned by each node's rotation since then.
  std::vector<Eigen::Matrix3d> preconditioner_node_rotations, pending_node_rotations;
};

// A state's displacement and its cached evaluation (rotations, elastic forces), to go back to it without evaluating
// again: a step's start, or the last contact solve's end (IntegratorWork::contact_end).
struct CachedEvaluation {
  Eigen::VectorXd u, u_eval, f_int;        // 3n each (u empty: none taken)
  std::vector<Eigen::Matrix3d> rotations;  // per tet, at u_eval
  double energy = 0.0;                     // elastic energy at u_eval, joules
  int n_inverted = 0;                      // tets with det F <= 0 at u_eval
  void take(const CorotationalState& s) {
    u = s.u, u_eval = s.u_eval, f_int = s.f_int, rotations = s.rotations, energy = s.energy, n_inverted = s.n_inverted;
  }
  void restore(CorotationalState& s) const {
    s.u = u, s.u_eval = u_eval, s.f_int = f_int, s.rotations = rotations, s.energy = energy, s.n_inverted = n_inverted;
  }
  // The evaluation (not u) exchanged with the state's, without copies: twice around a trial evaluation, the state's
  // back as it was.
  void swap_evaluation(CorotationalState& s) {
    std::swap(u_eval, s.u_eval), std::swap(f_int, s.f_int), std::swap(rotations, s.rotations);
    std::swap(energy, s.energy), std::swap(n_inverted, s.n_inverted);
  }
};

// The rotations, elastic forces and energy at state.u into the state's cached evaluation (rotations, f_int, energy,
// u_eval, n_inverted), unless it is already at state.u.
void evaluate_at_u(const CorotationalElements& el, CorotationalState& state);

// K_w at the rotations R (per tet) factorised on the rest factorisation's symbolic analysis, with its half
// columns' factorisation made too when half_columns (for a contact compliance over it). With half columns, once the
// rest solver has its nested-dissection analysis (StaticSolver::prepare_nested_analysis), K_w is factorised once on
// that analysis for both (refactorised_nested; 26 against 62-72 ms on the paper mesh, measured inside the 8x pinch);
// without it, a METIS ordering and a second factorisation each time. Reads the model only, so it may run on another
// thread; the background one must end before the model does (a background thread's future's destructor waits).
// Throws as StaticSolver's constructor.
std::shared_ptr<const StaticSolver> factorise_warped(const CorotationalModel& model,
                                                     const std::vector<Eigen::Matrix3d>& R, bool half_columns);
// Lowers the calling thread's priority to the background factorisations' (a scheduling hint: if refused, the thread
// runs at the default).
void at_background_priority();

// Result of a quasi-static solve.
struct CorotationalResult {
  int iterations = 0;      // outer iterations (linear solves)
  int cg_iterations = 0;   // back-substitutions (preconditioner applications) over all linear solves
  double residual = 0.0;   // final |f_ext - f_int(u)| on the free DOFs / force scale (see CorotationalOptions)
  bool converged = false;  // residual <= tolerance
  bool diverged = false;   // |r| grew past 1e4 x its start or became non-finite: state went back to the solve's
                           // start (the returned u is the start's; a factorisation at its rotations was asked for)
  int n_inverted = 0;      // tets with det F <= 0 at the returned u
  int refactorisations = 0;  // warped preconditioner factorisations this solve started
  int tangent_fallbacks = 0; // exact tangent: steps taken with K_w instead (no descent or no decrease)
  int truncated_steps = 0;   // exact tangent: Newton steps whose CG stopped at a direction of negative curvature
  int refactor_failures = 0; // factorisations that failed (not positive definite, out of memory): the solve went
                             // on with the previous preconditioner
  Eigen::VectorXd contact_lambda;  // with carried contacts: lambda_eff per row at the returned u, newtons
};

// Quasi-static equilibrium f_int(u) = f_ext (+ H^T lambda_eff(u) with carried contacts; f_ext: 3n newtons,
// entries of fixed DOFs ignored), starting from state.u. Fixed DOFs take u_fixed (3n, metres; empty = 0).
// state.u holds the last iterate even when not converged (never NaN). Throws std::invalid_argument for contacts
// with a non-positive stiffness, a negative or non-finite multiplier, or a row node out of range.
CorotationalResult solve_corotational(const CorotationalModel& model, const Eigen::VectorXd& f_ext,
                                      CorotationalState& state, const CorotationalOptions& options = {},
                                      const Eigen::VectorXd& u_fixed = Eigen::VectorXd(),
                                      const AugmentedContacts* contacts = nullptr);

}  // namespace lumen::physics
