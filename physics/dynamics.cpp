// Backward Euler with lumped mass and Rayleigh damping: linear (prefactorised) and corotational (PCG).
#include "physics/dynamics.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace lumen::physics {

namespace {

// Throws std::invalid_argument "<where>: <what> must <rule>, got <value>".
template <typename T>
[[noreturn]] void fail(const char* where, const std::string& what, const char* rule, T value) {
  std::ostringstream msg;
  msg.precision(17);
  msg << where << ": " << what << " must " << rule << ", got " << value;
  throw std::invalid_argument(msg.str());
}

// Checks a 3n vector: the given size and finite entries.
void check_vector(const char* where, const char* name, const Eigen::VectorXd& v, int n) {
  if (v.size() != n) fail(where, std::string(name) + ".size()", ("be " + std::to_string(n)).c_str(), v.size());
  for (int i = 0; i < n; ++i)
    if (!std::isfinite(v[i])) fail(where, std::string(name) + "[" + std::to_string(i) + "]", "be finite", v[i]);
}

void validate_params(const DynamicParams& p) {
  const char* where = "DynamicParams";
  if (p.elastic != ElasticModel::kLinear && p.elastic != ElasticModel::kCorotational)
    fail(where, "elastic", "be kLinear or kCorotational", static_cast<int>(p.elastic));
  if (!(p.density > 0.0) || !std::isfinite(p.density)) fail(where, "density", "be > 0 and finite", p.density);
  if (!(p.alpha >= 0.0) || !std::isfinite(p.alpha)) fail(where, "alpha", "be >= 0 and finite", p.alpha);
  if (!(p.beta >= 0.0) || !std::isfinite(p.beta)) fail(where, "beta", "be >= 0 and finite", p.beta);
  if (!(p.time_step > 0.0) || !std::isfinite(p.time_step)) fail(where, "time_step", "be > 0 and finite", p.time_step);
}

// Lumped mass, 3n, kg: density * V / 4 to each node of each tet (validated parameters).
Eigen::VectorXd lumped_mass(const CorotationalElements& el, double density) {
  Eigen::VectorXd m = Eigen::VectorXd::Zero(el.n_dofs());
  for (int t = 0; t < el.n_tets(); ++t)
    for (int a = 0; a < 4; ++a) m.segment<3>(3 * el.tets()(t, a)).array() += 0.25 * density * el.rest_volume(t);
  return m;
}

// Norm of v over the free DOFs.
double free_norm(const Eigen::VectorXd& v, const std::vector<char>& fixed) {
  double s = 0.0;
  for (Eigen::Index i = 0; i < v.size(); ++i)
    if (!fixed[i]) s += v[i] * v[i];
  return std::sqrt(s);
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
                           const DynamicParams& params)
    : params_((validate_params(params), params)),
      elements_(mesh, material),
      mass_(lumped_mass(elements_, params.density)),
      K_(assemble_stiffness(mesh, material)),
      fixed_nodes_(fixed_nodes),
      solver_(system_matrix(K_, mass_, params), fixed_nodes) {}

double kinetic_energy(const DynamicModel& model, const DynamicState& state) {
  check_vector("kinetic_energy", "state.v", state.v, model.n_dofs());
  return 0.5 * state.v.dot(model.mass().cwiseProduct(state.v));
}

double elastic_energy(const DynamicModel& model, const Eigen::VectorXd& u) {
  check_vector("elastic_energy", "u", u, model.n_dofs());
  if (model.params().elastic == ElasticModel::kLinear) return 0.5 * u.dot(model.stiffness() * u);
  std::vector<Eigen::Matrix3d> R;
  model.elements().rotations(u, R);
  return model.elements().elastic_energy(u, R);
}

StepResult step(const DynamicModel& model, DynamicState& state, const Eigen::VectorXd& f_ext, double h,
                const CorotationalOptions& options) {
  const char* where = "step";
  // Validate the step, the loads and the state.
  validate_options(options);
  if (!(h > 0.0) || !std::isfinite(h)) fail(where, "h", "be > 0 and finite", h);
  const int n = model.n_dofs();
  const CorotationalElements& el = model.elements();
  const DynamicParams& p = model.params();
  const Eigen::VectorXd& M = model.mass();
  check_vector(where, "f_ext", f_ext, n);
  if (state.u.size() == 0) state.u.setZero(n);
  if (state.v.size() == 0) state.v.setZero(n);
  check_vector(where, "state.u", state.u, n);
  check_vector(where, "state.v", state.v, n);

  // Loads on the free DOFs; fixed DOFs have zero velocity.
  std::vector<char> fixed(n);
  Eigen::VectorXd f = f_ext;
  for (int d = 0; d < n; ++d) {
    fixed[d] = model.is_fixed_dof(d) ? 1 : 0;
    if (fixed[d]) f[d] = 0.0, state.v[d] = 0.0;
  }
  const Eigen::VectorXd u0 = state.u, v0 = state.v;
  const double c_mass = 1.0 + h * p.alpha, c_stiff = h * p.beta + h * h;
  const double f_norm = f.norm();

  // Residual g = f - f_int(u1) - C v1 - M (v1 - v0) / h (free DOFs) and its relative size.
  StepResult result;
  Eigen::VectorXd f_int, damp, g(n);
  std::vector<Eigen::Matrix3d> R;
  auto residual = [&](const Eigen::VectorXd& u1, const Eigen::VectorXd& v1) {
    if (p.elastic == ElasticModel::kLinear) {
      f_int = model.stiffness() * u1;
      damp = p.beta * (model.stiffness() * v1);
    } else {
      result.n_inverted = el.rotations(u1, R);
      el.elastic_forces(u1, R, f_int);
      el.warped_product(R, v1, damp);
      damp *= p.beta;
    }
    damp.array() += p.alpha * M.array() * v1.array();
    const Eigen::VectorXd inertia = M.cwiseProduct(v1 - v0) / h;
    g = f - f_int - damp - inertia;
    for (int d = 0; d < n; ++d)
      if (fixed[d]) g[d] = 0.0;
    // Scale: the loads, the elastic and inertial forces on the free DOFs, and the support reactions (elastic forces
    // on the fixed DOFs: they carry a prescribed-displacement problem such as a twisted end at rest).
    double reaction2 = 0.0;
    for (int d = 0; d < n; ++d)
      if (fixed[d]) reaction2 += f_int[d] * f_int[d];
    const double scale =
        std::max({f_norm, free_norm(f_int, fixed), free_norm(inertia, fixed), std::sqrt(reaction2)});
    const double gnorm = g.norm();
    return gnorm == 0.0 ? 0.0 : (scale > 0.0 ? gnorm / scale : INFINITY);
  };

  Eigen::VectorXd v1 = v0, u1 = u0, dv;
  if (p.elastic == ElasticModel::kLinear) {
    // (M + h C + h^2 K) v1 = M v0 + h (f - K u0): direct at the factorised step, else PCG on that matrix
    // (identity rotations: the warped product is K p) preconditioned with the factorisation.
    const Eigen::VectorXd b = M.cwiseProduct(v0) + h * (f - model.stiffness() * u0);
    if (h == p.time_step) {
      model.solver().solve(b, v1);
    } else {
      const std::vector<Eigen::Matrix3d> identity(el.n_tets(), Eigen::Matrix3d::Identity());
      const WarpedSystem system{&el, &identity, &M, c_mass, c_stiff};
      const double tol = std::min(0.5, 0.1 * options.tolerance);
      const PcgResult pcg = solve_pcg(system, model.solver(), b, v1, tol, options.max_cg_iterations);
      result.cg_iterations = pcg.iterations;
    }
    result.iterations = 1;
    result.finite = v1.allFinite();
    if (result.finite) {
      for (int d = 0; d < n; ++d) u1[d] = fixed[d] ? u0[d] : u0[d] + h * v1[d];
      result.residual = residual(u1, v1);
      result.converged = result.residual <= options.tolerance;
      state.u = u1;
      state.v = v1;
    }
    return result;
  }

  // Corotational: fixed-point iterations from v1 = v0; each solves A_w dv = h g, A_w = (1 + h alpha) M +
  // (h beta + h^2) K_w(R(u1)), by PCG preconditioned with the rest factorisation of A.
  std::vector<Eigen::Matrix3d> node_R;
  for (;;) {
    for (int d = 0; d < n; ++d) u1[d] = fixed[d] ? u0[d] : u0[d] + h * v1[d];
    result.residual = residual(u1, v1);
    result.converged = result.residual <= options.tolerance;
    if (result.converged || result.iterations >= options.max_iterations) break;
    const WarpedSystem system{&el, &R, &M, c_mass, c_stiff};
    if (options.rotate_preconditioner) el.node_rotations(R, node_R);
    // (|h g| relative: the outer tolerance halved, as in solve_corotational)
    const double cg_tol = std::max(options.cg_tolerance, std::min(0.5, 0.5 * options.tolerance / result.residual));
    dv.resize(0);
    const PcgResult pcg = solve_pcg(system, model.solver(), h * g, dv, cg_tol, options.max_cg_iterations,
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

}  // namespace lumen::physics
