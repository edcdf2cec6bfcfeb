// Backward Euler with lumped mass and Rayleigh damping: linear (prefactorised) and corotational (PCG).
#include "physics/dynamics.hpp"
#include "physics/detail/messages.hpp"

#include "physics/detail/dofs.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace lumen::physics {

namespace {

void validate_params(const DynamicParams& p) {
  const char* where = "DynamicParams";
  if (p.elastic != ElasticModel::kLinear && p.elastic != ElasticModel::kCorotational)
    detail::fail_must(where, "elastic", "be kLinear or kCorotational", static_cast<int>(p.elastic));
  if (!(p.density > 0.0) || !std::isfinite(p.density)) detail::fail_must(where, "density", "be > 0 and finite", p.density);
  if (!(p.alpha >= 0.0) || !std::isfinite(p.alpha)) detail::fail_must(where, "alpha", "be >= 0 and finite", p.alpha);
  if (!(p.beta >= 0.0) || !std::isfinite(p.beta)) detail::fail_must(where, "beta", "be >= 0 and finite", p.beta);
  if (!(p.time_step > 0.0) || !std::isfinite(p.time_step)) detail::fail_must(where, "time_step", "be > 0 and finite", p.time_step);
}

// Lumped mass, 3n, kg: density * V / 4 to each node of each tet (validated parameters).
Eigen::VectorXd lumped_mass(const CorotationalElements& el, double density) {
  Eigen::VectorXd m = Eigen::VectorXd::Zero(el.n_dofs());
  for (int t = 0; t < el.n_tets(); ++t)
    for (int a = 0; a < 4; ++a) m.segment<3>(3 * el.tets()(t, a)).array() += 0.25 * density * el.rest_volume(t);
  return m;
}

}  // namespace

Eigen::SparseMatrix<double> DynamicModel::system_matrix(const Eigen::SparseMatrix<double>& K,
                                                        const Eigen::VectorXd& mass, const DynamicParams& p) {
  // A = (1 + h alpha) M + (h beta + h^2) K.
  const double h = p.time_step;
  Eigen::SparseMatrix<double> M(mass.size(), mass.size());
  M.reserve(Eigen::VectorXi::Constant(mass.size(), 1));
  for (Eigen::Index i = 0; i < mass.size(); ++i) M.insert(i, i) = mass[i];
  return (1.0 + h * p.alpha) * M + (h * p.beta + h * h) * K;
}

DynamicModel::DynamicModel(const TetMesh& mesh, const LinearMaterial& material, const std::vector<int>& fixed_nodes,
                           const DynamicParams& params, const Eigen::VectorXd& support)
    : params_((validate_params(params), params)),
      elements_(mesh, material, support),
      mass_(lumped_mass(elements_, params.density)),
      K_(elements_.with_support(assemble_stiffness(mesh, material))),
      fixed_nodes_(fixed_nodes),
      solver_(system_matrix(K_, mass_, params), fixed_nodes) {}

double kinetic_energy(const DynamicModel& model, const DynamicState& state) {
  detail::check_vector("kinetic_energy", "state.v", state.v, model.n_dofs());
  return 0.5 * state.v.dot(model.mass().cwiseProduct(state.v));
}

double elastic_energy(const DynamicModel& model, const Eigen::VectorXd& u) {
  detail::check_vector("elastic_energy", "u", u, model.n_dofs());
  if (model.params().elastic == ElasticModel::kLinear) return 0.5 * u.dot(model.stiffness() * u);
  std::vector<Eigen::Matrix3d> R;
  model.elements().rotations(u, R);
  return model.elements().elastic_energy(u, R);
}

namespace {

using detail::free_norm;
using detail::reaction_norm;

// The step's residual g = f - f_int(u1) - C v1 - M (v1 - v0) / h on the free DOFs and its size relative to the
// loads, the elastic and inertial forces on the free DOFs and the support reactions (elastic forces on the fixed
// DOFs: they carry a prescribed-displacement problem such as a twisted end at rest).
class StepResidual {
 public:
  StepResidual(const DynamicModel& model, const Eigen::VectorXd& f, const std::vector<char>& fixed,
               const Eigen::VectorXd& v0, double h)
      : model_(model), f_(f), fixed_(fixed), v0_(v0), h_(h), f_norm_(f.norm()), g_(f.size()) {}

  // Relative residual at (u1, v1); the per-tet rotations at u1 (corotational) are kept in rotations().
  double evaluate(const Eigen::VectorXd& u1, const Eigen::VectorXd& v1, StepResult& result) {
    const DynamicParams& p = model_.params();
    const Eigen::VectorXd& M = model_.mass();
    if (p.elastic == ElasticModel::kLinear) {
      f_int_ = model_.stiffness() * u1;
      damp_ = p.beta * (model_.stiffness() * v1);
    } else {
      result.n_inverted = model_.elements().rotations(u1, R_);
      model_.elements().elastic_forces(u1, R_, f_int_);
      model_.elements().warped_product(R_, v1, damp_);
      damp_ *= p.beta;
    }
    damp_.array() += p.alpha * M.array() * v1.array();
    const Eigen::VectorXd inertia = M.cwiseProduct(v1 - v0_) / h_;
    g_ = f_ - f_int_ - damp_ - inertia;
    for (Eigen::Index d = 0; d < g_.size(); ++d)
      if (fixed_[d]) g_[d] = 0.0;
    const double scale = std::max(
        {f_norm_, free_norm(f_int_, fixed_), free_norm(inertia, fixed_), reaction_norm(f_int_, fixed_)});
    const double gnorm = g_.norm();
    return gnorm == 0.0 ? 0.0 : (scale > 0.0 ? gnorm / scale : INFINITY);
  }
  const Eigen::VectorXd& g() const { return g_; }
  const std::vector<Eigen::Matrix3d>& rotations() const { return R_; }

 private:
  const DynamicModel& model_;
  const Eigen::VectorXd& f_;
  const std::vector<char>& fixed_;
  const Eigen::VectorXd& v0_;
  double h_, f_norm_;
  Eigen::VectorXd f_int_, damp_, g_;
  std::vector<Eigen::Matrix3d> R_;
};

// u1 = u0 + h v1 on the free DOFs; fixed DOFs keep u0.
void advance(const Eigen::VectorXd& u0, const Eigen::VectorXd& v1, const std::vector<char>& fixed, double h,
             Eigen::VectorXd& u1) {
  for (Eigen::Index d = 0; d < u0.size(); ++d) u1[d] = fixed[d] ? u0[d] : u0[d] + h * v1[d];
}

// Linear: (M + h C + h^2 K) v1 = M v0 + h (f - K u0), direct at the factorised step, else PCG on that matrix
// (identity rotations: the warped product is K p) preconditioned with the factorisation. A non-finite solve leaves
// the state as it was.
StepResult step_linear(const DynamicModel& model, DynamicState& state, const Eigen::VectorXd& f,
                       const std::vector<char>& fixed, double h, const CorotationalOptions& options) {
  const DynamicParams& p = model.params();
  const Eigen::VectorXd& M = model.mass();
  const Eigen::VectorXd u0 = state.u, v0 = state.v;
  StepResult result;
  Eigen::VectorXd v1 = v0, u1 = u0;
  const Eigen::VectorXd b = M.cwiseProduct(v0) + h * (f - model.stiffness() * u0);
  if (h == p.time_step) {
    model.solver().solve(b, v1);
  } else {
    const CorotationalElements& el = model.elements();
    const std::vector<Eigen::Matrix3d> identity(el.n_tets(), Eigen::Matrix3d::Identity());
    const WarpedSystem system{&el, &identity, &M, 1.0 + h * p.alpha, h * p.beta + h * h};
    const double tol = std::min(0.5, 0.1 * options.tolerance);
    const PcgResult pcg = solve_pcg(system, model.solver(), b, v1, tol, options.max_cg_iterations);
    result.cg_iterations = pcg.iterations;
  }
  result.iterations = 1;
  result.finite = v1.allFinite();
  if (!result.finite) return result;
  advance(u0, v1, fixed, h, u1);
  StepResidual residual(model, f, fixed, v0, h);
  result.residual = residual.evaluate(u1, v1, result);
  result.converged = result.residual <= options.tolerance;
  state.u = u1;
  state.v = v1;
  return result;
}

// Corotational: fixed-point iterations from v1 = v0; each solves A_w dv = h g, A_w = (1 + h alpha) M +
// (h beta + h^2) K_w(R(u1)), by PCG preconditioned with the rest factorisation of A.
StepResult step_corotational(const DynamicModel& model, DynamicState& state, const Eigen::VectorXd& f,
                             const std::vector<char>& fixed, double h, const CorotationalOptions& options) {
  const DynamicParams& p = model.params();
  const CorotationalElements& el = model.elements();
  const Eigen::VectorXd u0 = state.u, v0 = state.v;
  StepResult result;
  StepResidual residual(model, f, fixed, v0, h);
  Eigen::VectorXd v1 = v0, u1 = u0, dv;
  std::vector<Eigen::Matrix3d> node_R;
  for (;;) {
    advance(u0, v1, fixed, h, u1);
    result.residual = residual.evaluate(u1, v1, result);
    result.converged = result.residual <= options.tolerance;
    if (result.converged || result.iterations >= options.max_iterations) break;
    const WarpedSystem system{&el, &residual.rotations(), &model.mass(), 1.0 + h * p.alpha, h * p.beta + h * h};
    if (options.rotate_preconditioner) el.node_rotations(residual.rotations(), node_R);
    // (|h g| relative: the outer tolerance halved, as in solve_corotational)
    const double cg_tol = std::max(options.cg_tolerance, std::min(0.5, 0.5 * options.tolerance / result.residual));
    dv.resize(0);
    const PcgResult pcg = solve_pcg(system, model.solver(), h * residual.g(), dv, cg_tol, options.max_cg_iterations,
                                    options.rotate_preconditioner ? &node_R : nullptr);
    ++result.iterations;
    result.cg_iterations += pcg.iterations;
    if (!dv.allFinite()) break;  // keep the last finite iterate (not converged)
    v1 += dv;
  }
  state.u = u1;
  state.v = v1;
  return result;
}

}  // namespace

StepResult step(const DynamicModel& model, DynamicState& state, const Eigen::VectorXd& f_ext, double h,
                const CorotationalOptions& options) {
  const char* where = "step";
  // Validate the step, the loads and the state.
  validate_options(options);
  if (!(h > 0.0) || !std::isfinite(h)) detail::fail_must(where, "h", "be > 0 and finite", h);
  const int n = model.n_dofs();
  detail::check_vector(where, "f_ext", f_ext, n);
  if (state.u.size() == 0) state.u.setZero(n);
  if (state.v.size() == 0) state.v.setZero(n);
  detail::check_vector(where, "state.u", state.u, n);
  detail::check_vector(where, "state.v", state.v, n);
  // Loads on the free DOFs; fixed DOFs have zero velocity.
  std::vector<char> fixed(n);
  Eigen::VectorXd f = f_ext;
  for (int d = 0; d < n; ++d) {
    fixed[d] = model.is_fixed_dof(d) ? 1 : 0;
    if (fixed[d]) f[d] = 0.0, state.v[d] = 0.0;
  }
  return model.params().elastic == ElasticModel::kLinear ? step_linear(model, state, f, fixed, h, options)
                                                         : step_corotational(model, state, f, fixed, h, options);
}

}  // namespace lumen::physics
