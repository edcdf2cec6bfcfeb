#pragma once
// Implicit dynamics: backward Euler with lumped mass and Rayleigh damping, linear or corotational elasticity.
//
//   M (v1 - v0) / h = f_ext - f_int(u1) - C v1,   u1 = u0 + h v1,   C = alpha M + beta K
//
// Linear (f_int = K u): (M + h C + h^2 K) v1 = M v0 + h (f_ext - K u0), with that matrix factorised once by
// CHOLMOD for the model's time step. Corotational (f_int and K warped per tet, see corotational.hpp): a few
// fixed-point iterations on the warped system, each solved by CG preconditioned with the same factorisation.
// Fixed nodes keep the displacement they have in the state and have zero velocity.
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "physics/corotational.hpp"
#include "physics/fem.hpp"
#include "physics/mesh.hpp"

namespace lumen::physics {

// Elastic force model of a dynamic simulation.
enum class ElasticModel { kLinear, kCorotational };

// Parameters of a dynamic model (validated by its constructor).
struct DynamicParams {
  ElasticModel elastic = ElasticModel::kLinear;
  double density = 1000.0;   // mass density, kg/m^3, > 0
  double alpha = 0.0;        // Rayleigh mass-proportional damping, 1/s, >= 0
  double beta = 0.0;         // Rayleigh stiffness-proportional damping, s, >= 0
  double time_step = 0.025;  // step h of the prefactorised system, seconds, > 0
};

// Immutable dynamic model: element data, lumped mass, rest stiffness and the CHOLMOD factorisation of
// A = (1 + h alpha) M + (h beta + h^2) K on the free DOFs at h = params.time_step.
class DynamicModel {
 public:
  // fixed_nodes: nodes held at their state displacement; the others must be in at least one tet. support: the
  // elastic supports' diagonal stiffness (CorotationalElements; 3n, N/m; empty: none), in the elements and in K.
  DynamicModel(const TetMesh& mesh, const LinearMaterial& material, const std::vector<int>& fixed_nodes,
               const DynamicParams& params, const Eigen::VectorXd& support = Eigen::VectorXd());

  const DynamicParams& params() const { return params_; }
  const CorotationalElements& elements() const { return elements_; }
  // Lumped mass, 3n (the same for the three DOFs of a node), kg: density x rest volume / 4 per tet and node.
  const Eigen::VectorXd& mass() const { return mass_; }
  // Rest stiffness K (with the supports), 3n x 3n, N/m.
  const Eigen::SparseMatrix<double>& stiffness() const { return K_; }
  // Factorisation of A at h = params().time_step.
  const StaticSolver& solver() const { return solver_; }
  const std::vector<int>& fixed_nodes() const { return fixed_nodes_; }
  int n_dofs() const { return elements_.n_dofs(); }
  bool is_fixed_dof(int dof) const { return solver_.is_fixed_dof(dof); }

 private:
  static Eigen::SparseMatrix<double> system_matrix(const Eigen::SparseMatrix<double>& K, const Eigen::VectorXd& mass,
                                                   const DynamicParams& params);
  DynamicParams params_;
  CorotationalElements elements_;
  Eigen::VectorXd mass_;                     // 3n, kg
  Eigen::SparseMatrix<double> K_;            // 3n x 3n, N/m
  std::vector<int> fixed_nodes_;
  StaticSolver solver_;                      // A at h = time_step
};

// Mutable state of a dynamic simulation.
struct DynamicState {
  Eigen::VectorXd u;  // displacements, 3n, metres (empty = 0)
  Eigen::VectorXd v;  // velocities, 3n, metres per second (empty = 0)
};

// Result of one step.
struct StepResult {
  int iterations = 0;      // outer iterations (linear solves): 1 for the linear model
  int cg_iterations = 0;   // PCG iterations (0 for the linear model's direct solve)
  // |f_ext - f_int(u1) - C v1 - M (v1 - v0) / h| on the free DOFs, relative to the largest of |f_ext|,
  // |f_int(u1)| and |M (v1 - v0) / h| there and the support reactions |f_int(u1)| on the fixed DOFs (0 when all
  // are 0).
  double residual = 0.0;
  bool converged = false;  // residual <= options.tolerance
  int n_inverted = 0;      // tets with det F <= 0 at u1 (corotational; 0 for linear)
  bool finite = true;      // false: the linear solve gave NaN/Inf and the state was left as it was (a failed step)
};

// One backward Euler step of length h (seconds, > 0) under the loads f_ext (3n, newtons; entries of fixed DOFs
// ignored). Linear model: a direct solve when h equals params().time_step, else PCG preconditioned with the
// factorisation. Corotational: options bound the outer and PCG iterations (as in solve_corotational).
// state is updated even when not converged (never NaN).
StepResult step(const DynamicModel& model, DynamicState& state, const Eigen::VectorXd& f_ext, double h,
                const CorotationalOptions& options = {});

// Kinetic energy 1/2 v^T M v, joules.
double kinetic_energy(const DynamicModel& model, const DynamicState& state);
// Elastic energy at u (3n, metres), joules: 1/2 u^T K u (linear) or the corotational energy.
double elastic_energy(const DynamicModel& model, const Eigen::VectorXd& u);

}  // namespace lumen::physics
