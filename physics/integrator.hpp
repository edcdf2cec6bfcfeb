#pragma once
// The integrator seam: one interface between the frame loop and the ways a frame's elasticity is solved.
//
// A frame asks its integrator for the free motion (no contacts) under the frame's point loads and prescribed
// displacements (predict), solves the contacts on the integrator's contact compliance (contact_solver: its
// inverse maps nodal forces to the change of the frame's end displacement), and hands back the corrected end
// displacement (commit), or gives the frame up (reject). One implementation per model and solve:
//   LinearQuasiStatic      K u = f, prefactorised; probe responses precomputed (a frame is a dense product)
//   CorotationalQuasiStatic f_int(u) = f, warped stiffness, PCG on a lagged factorisation
//   BackwardEuler          one implicit step of h (linear or corotational elasticity, Rayleigh damping)
// Chosen once when the scene compiles; nothing in a frame switches on the model.
#include <memory>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "physics/compliance.hpp"
#include "physics/corotational.hpp"
#include "physics/corotational_contact.hpp"
#include "physics/dynamics.hpp"
#include "physics/fem.hpp"

namespace lumen::physics {

// The simulation state every integrator advances: displacement and velocity from rest.
struct SimState {
  Eigen::VectorXd u;  // displacements, 3n, metres
  Eigen::VectorXd v;  // velocities, 3n, metres per second (0 for quasi-static integrators)
};

// A load at a surface point this frame.
struct PointLoad {
  LoadPoint at;                                     // where it acts (barycentric over up to 3 nodes)
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  // newtons; for a held point, the solved force (output)
  bool held = false;                                // displacement-driven: the point is moved to `target`
  Eigen::Vector3d target = Eigen::Vector3d::Zero(); // held only: displacement of the point from rest, metres
};

// The frame's loads: one per load point, in the order the integrator was built with (its `load_points`).
struct FrameLoads {
  std::vector<PointLoad> points;
  bool at_compiled_points = true;  // every point is where it was at compile time (precomputed responses apply)
  // Contacts carried into the solve as loads of its equilibrium (the corotational quasi-static solve reads them;
  // the other integrators ignore them), or null.
  const AugmentedContacts* contacts = nullptr;
};

// Displacements prescribed on some nodes (e.g. a turned end ring): basis * c on them, c given per frame.
// The prescribed nodes are also among the integrator's fixed nodes.
struct PrescribedMotion {
  std::vector<int> nodes;  // node ids
  Eigen::MatrixXd basis;   // 3n x k, metres: column j is the displacement per unit c_j (0 off the nodes)
  bool empty() const { return basis.cols() == 0; }
};
// sum_j c_j basis.col(j), 3n, metres (c has basis.cols() entries).
Eigen::VectorXd combine_columns(const Eigen::MatrixXd& basis, const Eigen::VectorXd& c);

// What a prediction reports.
struct Prediction {
  int iterations = 0;     // nonlinear (outer) iterations; 0 for a direct linear solve
  bool converged = true;  // the solve reached its tolerance
  bool finite = true;     // false: the solve failed (non-finite values); the frame must be rejected
  bool diverged = false;  // the nonlinear solve diverged and went back to its start; the frame must be rejected
  int refactorisations = 0;         // lagged factorisations started (corotational quasi-static)
  int tangent_fallbacks = 0;        // exact-tangent steps redone with K_w (corotational quasi-static)
  int cg_iterations = 0;            // PCG iterations over the frame's linear solves (corotational quasi-static)
  int truncated_steps = 0;          // exact-tangent steps whose CG stopped at negative curvature
  int preconditioner_failures = 0;  // lagged factorisations that failed (the solve kept the previous one)
  Eigen::VectorXd contact_lambda;   // with FrameLoads::contacts: each carried row's force in the solve, newtons
};

// A factorised contact Hessian and its compliance over the contact nodes (lazy: half columns per node), which
// refers to the factorisation.
struct ContactHessianFactor {
  std::shared_ptr<const StaticSolver> factor;
  std::shared_ptr<SurfaceCompliance> compliance;
  int taken_at = 0;  // IntegratorWork::predictions when the rotations it is factorised at were taken
};

// Mutable data an integrator keeps between frames besides SimState (warm starts, lagged preconditioners).
struct IntegratorWork {
  CorotationalState corotational;  // corotational quasi-static: the nonlinear solve's warm start and caches
  Eigen::VectorXd frame_forces;    // corotational quasi-static: the last prediction's nodal loads, 3n, newtons
  // corotational quasi-static, contacts solved on a lagged factorisation (ContactHessian::as_given): K_w at the end
  // of the last contact solve, or at a solve's start where it was factorised at once, with its compliance over the
  // contact nodes (half columns cached per node until the next one is adopted), and the next one, in progress on a
  // background thread (valid() from its start until adopted or let go, which may be after it has finished), which
  // also solves for the half columns of the last solve's row nodes and the kept gram among them.
  ContactHessianFactor contact_hessian;
  std::future<ContactHessianFactor> contact_pending;
  // corotational quasi-static: contact_pending was waited for as long as walls meeting on a stale Hessian wait, and
  // did not come (its thread starved): where the walls meet again before it comes, they do not wait for it again.
  bool contact_pending_outwaited = false;
  // corotational quasi-static: the predictions counted when contact_pending was started.
  int contact_pending_since = 0;
  // corotational quasi-static: the last frame solved its contacts on the lagged Hessian (solve_with_contacts); its
  // prediction then has the contact work bound and, while a contact Hessian's factor preconditions it (the one the
  // walls met on: share_with_prediction), starts no factorisation of its own (the second core factorises the next
  // Hessian). Read and cleared by predict.
  bool after_contact_solve = false;
  // corotational quasi-static, contacts solved in the equilibrium: the last contact solve's end with its evaluation
  // (taken only when evaluated at that end; the prediction between two contact solves evaluates the solve's state
  // elsewhere).
  CachedEvaluation contact_end;
  int predictions = 0;             // corotational quasi-static: predictions made (frames; a contact Hessian's age)
  int last_contact_solve = -1;     // corotational quasi-static: `predictions` at the last contact solve
  DynamicState step;               // backward Euler: the step's trial state (u, v)
};

class Integrator {
 public:
  virtual ~Integrator() = default;
  // Free motion of the frame: u1 (3n, metres) under the loads, the prescribed nodes at combine(basis, c).
  // Held points' solved forces are written into loads.points[i].force.
  virtual Prediction predict(FrameLoads& loads, const Eigen::VectorXd& prescribed_c, const SimState& state,
                             IntegratorWork& work, Eigen::VectorXd& u1) const = 0;
  // The factorisation whose inverse is the contact compliance (K, or the implicit step's matrix).
  virtual const StaticSolver& contact_solver() const = 0;
  // Held points for the contact solve (their forces change so that contacts do not move them), or null.
  virtual const HeldPoints* held_points() const { return nullptr; }
  // Accept u1 (contacts included) as the end of the frame.
  virtual void commit(const Eigen::VectorXd& u1, SimState& state) const;
  // Kinetic energy of a state, joules (0 for quasi-static integrators).
  virtual double kinetic_energy(const SimState&) const { return 0.0; }
  // Whether a DOF is fixed (prescribed or held at rest).
  virtual bool is_fixed_dof(int dof) const { return contact_solver().is_fixed_dof(dof); }
  // Whether predict() reads the committed state (SimState: a warm start, a velocity). One that does not lets a
  // rendering session commit a frame's whole-mesh interior during the next frame (engine: State::pipeline_interior).
  virtual bool predicts_from_state() const { return true; }
  // Whether solve_with_contacts is available: the contacts inside the integrator's own equilibrium.
  virtual bool solves_contacts() const { return false; }
  // The frame's end with contact rows H u >= g inside the equilibrium of the last prediction's loads, from u (in:
  // the start, e.g. the prediction; out: the end), warm-started from lambda_warm (per row, or empty);
  // compliance: over contact_solver(). Throws std::logic_error unless solves_contacts().
  virtual ContactEquilibriumResult solve_with_contacts(const std::vector<ContactRow>& rows,
                                                       SurfaceCompliance& compliance,
                                                       const ContactEquilibriumOptions& options, IntegratorWork& work,
                                                       Eigen::VectorXd& u, const Eigen::VectorXd& lambda_warm) const;
  // Called after a frame without a contact solve when later frames' contacts will be solved by solve_with_contacts
  // on lagged Hessians (ContactHessian::as_given) with their compliance over nodes: an integrator that factorises
  // those Hessians keeps one ready from now (so that the first contact frame adopts one instead of factorising).
  virtual void anticipate_contacts(const std::vector<int>& /*nodes*/, IntegratorWork& /*work*/) const {}
};

// Nodal force vector of the loads (3n, newtons): each point's force spread over its nodes by its weights.
Eigen::VectorXd nodal_forces(const FrameLoads& loads, int n_dofs);

// Linear elasticity, quasi-static: u = K^-1 f. The load points' unit responses are precomputed (LoadResponse),
// so a frame at the compiled points is a dense 3n x 3m product; held (displacement-driven) points get the forces
// that move them to their targets from the point compliance (a Schur complement); the prescribed basis's
// responses are precomputed too (u = P - K^-1 K P with the basis held, no load).
class LinearQuasiStatic final : public Integrator {
 public:
  // K: stiffness (3n x 3n, N/m); held: per load point, whether it is displacement-driven.
  LinearQuasiStatic(const Eigen::SparseMatrix<double>& K, const std::vector<int>& fixed_nodes,
                    const std::vector<LoadPoint>& load_points, const std::vector<bool>& held,
                    const PrescribedMotion& prescribed);
  Prediction predict(FrameLoads& loads, const Eigen::VectorXd& prescribed_c, const SimState& state,
                     IntegratorWork& work, Eigen::VectorXd& u1) const override;
  const StaticSolver& contact_solver() const override { return solver_; }
  const HeldPoints* held_points() const override { return held_.points.empty() ? nullptr : &held_; }
  bool predicts_from_state() const override { return false; }  // (u = K^-1 f: the loads alone)
  const LoadResponse& load_response() const { return response_; }

 private:
  void solve_held_forces(FrameLoads& loads, const Eigen::VectorXd& prescribed_u, Points& forces) const;
  StaticSolver solver_;                // K on the free DOFs
  LoadResponse response_;              // K^-1 of unit loads at the load points
  std::vector<int> held_index_;        // load point ids of the held points (d)
  Eigen::MatrixXd hold_stiffness_;     // (P_dd)^-1, 3d x 3d, N/m: forces that move the held points
  Eigen::MatrixXd hold_coupling_;      // P_df, 3d x 3m, m/N: held points' motion per load point force
  HeldPoints held_;                    // the held points for the contact solve
  Eigen::MatrixXd prescribed_response_;  // 3n x k, metres: mesh displacement with basis column j held
};

// Corotational elasticity, quasi-static: f_int(u) = f solved from the last frame's free solution.
class CorotationalQuasiStatic final : public Integrator {
 public:
  // support: the elastic supports' diagonal stiffness (CorotationalElements; 3n, N/m; empty: none).
  CorotationalQuasiStatic(const TetMesh& mesh, const LinearMaterial& material, const std::vector<int>& fixed_nodes,
                          const CorotationalOptions& options, const PrescribedMotion& prescribed,
                          const Eigen::VectorXd& support = Eigen::VectorXd());
  // On 10-node tets (the warped tangent only: std::invalid_argument for another options.tangent); support as above
  // (3n over the quadratic mesh's nodes, corners and edge nodes).
  CorotationalQuasiStatic(const QuadraticMesh& mesh, const LinearMaterial& material,
                          const std::vector<int>& fixed_nodes, const CorotationalOptions& options,
                          const PrescribedMotion& prescribed, const Eigen::VectorXd& support = Eigen::VectorXd());
  Prediction predict(FrameLoads& loads, const Eigen::VectorXd& prescribed_c, const SimState& state,
                     IntegratorWork& work, Eigen::VectorXd& u1) const override;
  const StaticSolver& contact_solver() const override { return model_.solver(); }
  const CorotationalModel& model() const { return model_; }
  // physics::solve_contact_equilibrium on the model, with the last prediction's loads; work.corotational ends at u
  // (the next prediction's warm start unless the caller sets another). Hessian as_given: K_w factorised at the end
  // of the last contact solve (at the first one's start, at once), refreshed after each solve at its end, on a
  // background thread with options' refactor_in_background (adopted when ready) or at once; its compliance over
  // compliance.nodes(). node_rotations: the rest K (compliance) turned per node.
  bool solves_contacts() const override { return true; }
  ContactEquilibriumResult solve_with_contacts(const std::vector<ContactRow>& rows, SurfaceCompliance& compliance,
                                               const ContactEquilibriumOptions& options, IntegratorWork& work,
                                               Eigen::VectorXd& u, const Eigen::VectorXd& lambda_warm) const override;
  // With options' refactor_in_background (and the factor shared with the prediction): at the session's start (no
  // prediction yet) K factorised at once; then K_w at the last evaluated rotations on the background thread, once the
  // Hessian in use is a few frames old and none is under way; a finished one adopted as the contact Hessian and the
  // prediction's preconditioner (whose own factorisations then stop, as after a contact solve). Measured on the 8x
  // pinch: the first contact frame had factorised at once (170-225 ms).
  void anticipate_contacts(const std::vector<int>& nodes, IntegratorWork& work) const override;

 private:
  void share_with_prediction(IntegratorWork& work) const;
  bool adopt_contact_hessian(IntegratorWork& work, int& failures) const;  // whether the background one replaced it
  bool shares_contact_hessian() const { return !options_.rotate_preconditioner; }
  CorotationalModel model_;
  CorotationalOptions options_;
  PrescribedMotion prescribed_;
};

// One backward Euler step of h per frame (DynamicModel). Its contact compliance is that of the step,
// A_u = A / h^2 (A the factorised step matrix): the same factorisation, scaled. After the contacts the committed
// velocity is the committed motion over the step, v1 = (u1 - u0) / h (0 on fixed DOFs).
class BackwardEuler final : public Integrator {
 public:
  // support: the elastic supports' diagonal stiffness (DynamicModel; empty: none).
  BackwardEuler(const TetMesh& mesh, const LinearMaterial& material, const std::vector<int>& fixed_nodes,
                const DynamicParams& params, const CorotationalOptions& options, const PrescribedMotion& prescribed,
                const Eigen::VectorXd& support = Eigen::VectorXd());
  Prediction predict(FrameLoads& loads, const Eigen::VectorXd& prescribed_c, const SimState& state,
                     IntegratorWork& work, Eigen::VectorXd& u1) const override;
  const StaticSolver& contact_solver() const override { return step_solver_; }
  void commit(const Eigen::VectorXd& u1, SimState& state) const override;
  double kinetic_energy(const SimState& state) const override;
  const DynamicModel& model() const { return model_; }

 private:
  DynamicModel model_;
  StaticSolver step_solver_;  // A_u = A / h^2: a view of model_.solver()'s factorisation, scaled by h^2
  CorotationalOptions options_;
  PrescribedMotion prescribed_;
};

}  // namespace lumen::physics
