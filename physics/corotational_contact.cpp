// Contacts inside the corotational quasi-static equilibrium: SQP with a fixed Hessian, line-searched on the potential.
#include "physics/corotational_contact.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "physics/detail/dofs.hpp"
#include "physics/detail/messages.hpp"
#include "physics/lcp.hpp"
#include "physics/lcp_iterative.hpp"

namespace lumen::physics {
namespace {

constexpr double kSufficientDecrease = 1e-4;  // sufficient decrease of Pi, a fraction of the step's slope
constexpr int kMaxHalvings = 12;               // line-search halvings before a step is given up
constexpr double kLcpToleranceShare = 0.1;     // the LCP's tolerance, a share of the feasibility tolerance
// Off the rows, the exact penalty's weight: this many times the largest multiplier (above 1: the QP step descends).
constexpr double kMeritMultiplierFactor = 2.0;
// A change of Pi this small relative to its size is round-off (near the solution Pi changes by about r . du / 2):
// there the whole step is taken, as a converging SQP's is.
constexpr double kPotentialRoundOff = 1e-11;

void validate(const ContactEquilibriumOptions& o) {
  const char* where = "solve_contact_equilibrium";
  if (!(o.tolerance > 0.0) || !std::isfinite(o.tolerance))
    detail::fail_must(where, "options.tolerance", "be > 0", o.tolerance);
  if (o.max_steps < 1) detail::fail_must(where, "options.max_steps", "be >= 1", o.max_steps);
  if (!(o.feasibility_tolerance > 0.0) || !std::isfinite(o.feasibility_tolerance))
    detail::fail_must(where, "options.feasibility_tolerance", "be > 0", o.feasibility_tolerance);
  if (o.lcp_sweeps < 0) detail::fail_must(where, "options.lcp_sweeps", "be >= 0", o.lcp_sweeps);
  if (!(o.split_entry_share >= 0.0) || !std::isfinite(o.split_entry_share))
    detail::fail_must(where, "options.split_entry_share", "be >= 0", o.split_entry_share);
}

// v (3n) turned node by node: v_a <- R_a v_a, or R_a^T v_a (no frames: unchanged).
void turn(const std::vector<Eigen::Matrix3d>& Rn, bool transpose, Eigen::VectorXd& v) {
  for (size_t a = 0; a < Rn.size(); ++a) {
    auto block = v.segment<3>(3 * static_cast<Eigen::Index>(a));
    const Eigen::Vector3d x = block;
    block = transpose ? Eigen::Vector3d(Rn[a].transpose() * x) : Eigen::Vector3d(Rn[a] * x);
  }
}

// The potential, residual and force scale at state.u (rotations and forces evaluated unless cached).
struct Evaluation {
  const CorotationalElements& el;
  const Eigen::VectorXd& f;          // loads, 0 on the fixed DOFs
  const std::vector<char>& fixed;
  Eigen::VectorXd r;                 // f - f_int on the free DOFs, 0 on the fixed
  double potential = 0.0;            // Pi(u), joules
  double scale = 0.0;                // max(|f|, reactions), newtons

  void at(CorotationalState& s) {
    const int n = static_cast<int>(f.size());
    evaluate_at_u(el, s);
    r.resize(n);
    for (int d = 0; d < n; ++d) r[d] = fixed[d] ? 0.0 : f[d] - s.f_int[d];
    potential = s.energy - f.dot(s.u);  // (evaluate_at_u's, at u)
    scale = std::max(f.norm(), detail::reaction_norm(s.f_int, fixed));
  }
};

// One QP at u: lambda from the LCP on W, and the step du = B^-1 (r + H^T lambda) with B^-1 = Rn A^-1 Rn^T (A the
// given factorisation; Rn empty: B = A). On a lazy compliance whose set holds every row node, over a solver whose
// halves sweep its own supernodal factor, and with few enough half-column rows (options.split_entry_share), the
// step is split (StaticSolver::half_forward / half_backward): z = L^-1 P Rn^T r, the LCP's free motion of the row
// nodes read from z through their half columns, H^T lambda added to z the same way, and one backward sweep: one
// solve a step. Otherwise two: B^-1 r, then B^-1 H^T lambda.
class WarpedQp {
 public:
  WarpedQp(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows, const Eigen::MatrixXd& W,
           const std::vector<Eigen::Matrix3d>& Rn, const ContactEquilibriumOptions& options)
      : C_(compliance), rows_(rows), W_(W), Rn_(Rn), options_(options), g_(row_targets(rows)),
        nodes_(row_nodes(rows)) {
    split_ = compliance.lazy() && compliance.solver().splits_on_its_factor() && !rows.empty() &&
             std::all_of(nodes_.begin(), nodes_.end(), [&](int v) { return compliance.index_of(v) >= 0; });
    if (split_) {
      // (The rows' half columns are at hand: W was formed from them.)
      long entries = 0;
      for (int v : nodes_) entries += compliance.half_entries(v);
      split_ = static_cast<double>(entries) <=
               options.split_entry_share * static_cast<double>(compliance.solver().factor_nonzeros());
    }
  }
  // B^-1 v (3n).
  void compliance(Eigen::VectorXd v, Eigen::VectorXd& out) const {
    turn(Rn_, true, v);
    C_.solver().solve(v, out);
    turn(Rn_, false, out);
  }
  // The step at u with residual r; lambda: in the warm start, out the QP's multipliers; fc: H^T lambda.
  void step(const Eigen::VectorXd& u, const Eigen::VectorXd& r, Eigen::VectorXd& lambda, Eigen::VectorXd& fc,
            Eigen::VectorXd& du, ContactEquilibriumResult& result) {
    const int n = static_cast<int>(u.size());
    if (rows_.empty()) {
      compliance(r, du);
      lambda.resize(0);
      fc.setZero(n);
      return;
    }
    // The free motion B^-1 r: whole, or on the row nodes only (all the LCP reads) from the forward half.
    if (split_) {
      ++result.split_steps;
      Eigen::VectorXd v = r;
      turn(Rn_, true, v);
      C_.solver().half_forward(v, z_);
      du.setZero(n);
      for (int a : nodes_) du.segment<3>(3 * a) = frame(a) * C_.half_displacement(a, z_);
    } else {
      compliance(r, du);
    }
    const Eigen::VectorXd q = row_values(rows_, u + du) - g_;
    lambda = solve_lcp(q, lambda, result);
    fc = contact_force(rows_, lambda, n);
    // du = B^-1 (r + fc): the contact forces added to the forward half and one backward sweep, or a second solve.
    if (split_) {
      for (int a : nodes_) C_.add_half_force(a, frame(a).transpose() * fc.segment<3>(3 * a), z_);
      C_.solver().half_backward(z_, du);
      turn(Rn_, false, du);
    } else {
      Eigen::VectorXd dc;
      compliance(fc, dc);
      du += dc;
    }
  }
  // Largest g - H u, metres.
  double violation(const Eigen::VectorXd& u) const {
    return rows_.empty() ? 0.0 : (g_ - row_values(rows_, u)).maxCoeff();
  }
  // Sum of max(0, g - H u) over the rows, metres.
  double total_violation(const Eigen::VectorXd& u) const {
    return rows_.empty() ? 0.0 : (g_ - row_values(rows_, u)).cwiseMax(0.0).sum();
  }

 private:
  // Node a's frame R_a (identity without frames).
  Eigen::Matrix3d frame(int a) const { return Rn_.empty() ? Eigen::Matrix3d::Identity() : Rn_[a]; }
  // The multipliers of the LCP on W with free motion q, warm-started from lambda.
  Eigen::VectorXd solve_lcp(const Eigen::VectorXd& q, const Eigen::VectorXd& lambda,
                            ContactEquilibriumResult& result) const {
    LcpResult z;
    const double tol = kLcpToleranceShare * options_.feasibility_tolerance;
    if (options_.lcp_sweeps > 0) {
      IterativeLcpOptions o;
      o.max_sweeps = options_.lcp_sweeps;
      o.tolerance = tol;
      o.warm = lambda.size() == q.size() ? lambda : Eigen::VectorXd();
      z = solve_lcp_nncg(W_, q, o);
    } else {
      std::vector<int> warm;
      for (Eigen::Index i = 0; i < lambda.size() && lambda.size() == q.size(); ++i)
        if (lambda[i] > 0.0) warm.push_back(static_cast<int>(i));
      LcpOptions o;
      o.tolerance = tol;
      z = solve_lcp_active_set(W_, q, warm, o);
      if (!z.converged) z = solve_lcp_dense(W_, q, o);
    }
    result.lcp_iterations += z.iterations;
    result.lcp_converged = result.lcp_converged && z.converged;
    return z.z;
  }
  SurfaceCompliance& C_;
  const std::vector<ContactRow>& rows_;
  const Eigen::MatrixXd& W_;
  const std::vector<Eigen::Matrix3d>& Rn_;
  const ContactEquilibriumOptions& options_;
  Eigen::VectorXd g_;
  std::vector<int> nodes_;  // the rows' distinct nodes
  bool split_ = false;      // whether the steps are split (see above)
  std::vector<double> z_;   // the split step's forward half (n_free, the factor's order)
};

}  // namespace

ContactEquilibriumResult solve_contact_equilibrium(const CorotationalModel& model, const Eigen::VectorXd& f_ext,
                                                   const std::vector<ContactRow>& rows, SurfaceCompliance& compliance,
                                                   const ContactEquilibriumOptions& options, CorotationalState& state,
                                                   const Eigen::VectorXd& lambda_warm) {
  const char* where = "solve_contact_equilibrium";
  validate(options);
  const CorotationalElements& el = model.elements();
  const int n = model.n_dofs();
  detail::check_vector(where, "f", f_ext, n);
  detail::check_vector(where, "state.u", state.u, n);
  if (compliance.solver().n_dofs() != n)
    detail::fail_must(where, "compliance.solver().n_dofs()", "be the model's " + std::to_string(n),
                      compliance.solver().n_dofs());
  if (lambda_warm.size() != 0 && lambda_warm.size() != static_cast<Eigen::Index>(rows.size()))
    detail::fail_must(where, "lambda_warm.size()", "be 0 or rows = " + std::to_string(rows.size()), lambda_warm.size());

  // The free loads and the fixed mask (whole nodes: a node turned by Rn keeps its fixed components fixed).
  std::vector<char> fixed(static_cast<size_t>(n));
  Eigen::VectorXd f = f_ext;
  for (int d = 0; d < n; ++d) {
    fixed[d] = model.is_fixed_dof(d) ? 1 : 0;
    if (fixed[d]) f[d] = 0.0;
  }
  Evaluation eval{el, f, fixed, {}, 0.0, 0.0};
  eval.at(state);

  // The fixed Hessian's frames (each node's rotation at the start, or none) and the rows' coupling on it.
  std::vector<Eigen::Matrix3d> Rn;
  if (options.hessian == ContactHessian::node_rotations) el.node_rotations(state.rotations, Rn);
  const Eigen::MatrixXd W =
      rows.empty() ? Eigen::MatrixXd() : coupling_matrix(compliance, rows, Rn.empty() ? nullptr : &Rn);
  WarpedQp qp(compliance, rows, W, Rn, options);

  ContactEquilibriumResult result;
  Eigen::VectorXd lambda = lambda_warm, fc, du;
  result.finite = std::isfinite(eval.potential) && eval.r.allFinite();
  for (;;) {
    if (!result.finite) break;  // (only a start that is not finite: every accepted iterate is)
    // The QP at u, and the KKT residual with its multipliers. At the step bound no QP is solved (its step would
    // not be taken): the residual is the last QP's multipliers' at u, the pair (u, lambda) returned.
    const bool at_bound = result.steps >= options.max_steps;
    if (!at_bound) qp.step(state.u, eval.r, lambda, fc, du, result);
    const double scale = std::max(eval.scale, fc.norm());
    const Eigen::VectorXd stationarity = eval.r + fc;
    result.residual = scale > 0.0 ? detail::free_norm(stationarity, fixed) / scale : 0.0;
    result.violation = qp.violation(state.u);
    result.converged = result.residual <= options.tolerance && result.violation <= options.feasibility_tolerance;
    if (at_bound || result.converged || !du.allFinite()) break;
    ++result.steps;
    const Eigen::VectorXd u0 = state.u;
    // The merit the step backtracks on: off the rows the exact penalty phi = Pi + mu sum max(0, g - H u), mu above
    // every multiplier, along which du descends (its slope -r . du - mu V(u)); on the rows Pi itself (Armijo).
    const bool off_rows = result.violation > options.feasibility_tolerance;
    const double mu =
        off_rows ? kMeritMultiplierFactor * (lambda.size() > 0 ? std::max(lambda.maxCoeff(), 0.0) : 0.0) : 0.0;
    const auto merit = [&](const Eigen::VectorXd& u) {
      return off_rows ? eval.potential + mu * qp.total_violation(u) : eval.potential;
    };
    const double penalty = off_rows ? mu * qp.total_violation(u0) : 0.0;
    const double start = eval.potential + penalty, slope = eval.r.dot(du) + penalty;  // slope: -(phi's slope)
    if (!off_rows && !(slope > 0.0)) break;  // on the rows, no descent left at round-off: the iterate stays
    bool accepted = false;
    double alpha = 1.0;
    for (int k = 0; k <= kMaxHalvings && slope > 0.0; ++k, alpha *= 0.5) {
      state.u = u0 + alpha * du;
      eval.at(state);
      const double phi = merit(state.u);
      const bool decrease = phi <= start - kSufficientDecrease * alpha * slope;
      const bool round_off =
          !off_rows && alpha == 1.0 && std::abs(phi - start) <= kPotentialRoundOff * std::abs(start);
      if (std::isfinite(phi) && eval.r.allFinite() && (decrease || round_off)) {
        accepted = true;
        break;
      }
      ++result.backtracks;
    }
    if (accepted) continue;
    // No decrease found: off the rows the whole step is taken (it ends on the rows); on the rows, or where the whole
    // step is not finite, the iterate goes back to its start and the iteration stops (not converged).
    if (off_rows) {
      state.u = u0 + du;
      eval.at(state);
      if (std::isfinite(eval.potential) && eval.r.allFinite()) continue;
    }
    state.u = u0;
    eval.at(state);
    break;
  }
  result.lambda = lambda;
  result.n_inverted = state.n_inverted;
  return result;
}

}  // namespace lumen::physics
