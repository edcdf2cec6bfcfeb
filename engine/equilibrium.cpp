#include "engine/equilibrium.hpp"

#include <cmath>
#include <vector>

#include "engine/response.hpp"
#include "physics/contact_rows.hpp"
#include "physics/corotational.hpp"
#include "physics/integrator.hpp"
#include "physics/lcp.hpp"

namespace lumen::engine {

ContactEquilibrium contact_equilibrium(const Model& model, const State& state) {
  ContactEquilibrium out;
  const auto* corot = dynamic_cast<const physics::CorotationalQuasiStatic*>(model.integrator.get());
  if (corot == nullptr) return out;
  out.available = true;
  const physics::CorotationalModel& elastic = corot->model();

  // r = f_int(u) - f_probes, 3n, newtons, 0 on the fixed DOFs (their reactions balance anything).
  std::vector<Eigen::Matrix3d> R;
  elastic.elements().rotations(state.sim.u, R);
  Eigen::VectorXd r;
  elastic.elements().elastic_forces(state.sim.u, R, r);
  const Eigen::VectorXd f_probes = nodal_loads(model, state);
  r -= f_probes;
  const int n = static_cast<int>(r.size());
  auto free_only = [&](Eigen::VectorXd& v) {
    for (int d = 0; d < n; ++d)
      if (elastic.is_fixed_dof(d)) v[d] = 0.0;
  };
  free_only(r);
  const double scale = f_probes.norm();

  // G: 3n x k, column j the nodal forces of active row j at a unit multiplier (free DOFs only).
  std::vector<physics::ContactRow> rows;
  for (const auto& c : state.active) rows.push_back(contact_row(c, model.mesh.rest, state.x, state.x, model.collision.gap));
  const int k = static_cast<int>(rows.size());
  out.rows = k;
  Eigen::MatrixXd G(n, k);
  for (int j = 0; j < k; ++j) {
    Eigen::VectorXd unit = Eigen::VectorXd::Zero(k);
    unit[j] = 1.0;
    Eigen::VectorXd column = physics::contact_force(rows, unit, n);
    free_only(column);
    G.col(j) = column;
  }

  // The committed multipliers (none when the state carries no active rows).
  Eigen::VectorXd reported = Eigen::VectorXd::Zero(k);
  if (k == static_cast<int>(state.active_total.size()))
    reported = Eigen::Map<const Eigen::VectorXd>(state.active_total.data(), k);
  out.reported_residual = (r - G * reported).norm() / scale;
  if (k == 0) {
    out.fitted_residual = out.reported_residual;
    return out;
  }
  // Non-negative least squares as an LCP: w = G^T G lambda - G^T r >= 0, lambda >= 0, w . lambda = 0.
  const physics::LcpResult fit = physics::solve_lcp_dense(G.transpose() * G, -G.transpose() * r);
  out.fitted_residual = (r - G * fit.z).norm() / scale;
  out.fitted_force = fit.converged ? fit.z.sum() : std::nan("");
  return out;
}

}  // namespace lumen::engine
