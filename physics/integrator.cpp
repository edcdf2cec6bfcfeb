// The integrators behind the seam: linear and corotational quasi-static, backward Euler.
#include "physics/integrator.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <chrono>
#include <future>
#include <stdexcept>
#include <string>

namespace lumen::physics {

Eigen::VectorXd combine_columns(const Eigen::MatrixXd& basis, const Eigen::VectorXd& c) {
  if (c.size() != basis.cols())
    throw std::invalid_argument("combine_columns: " + std::to_string(basis.cols()) + " coefficients expected, got " +
                                std::to_string(c.size()));
  if (basis.cols() == 0) return Eigen::VectorXd::Zero(basis.rows());
  Eigen::VectorXd u = c[0] * basis.col(0);
  for (Eigen::Index j = 1; j < basis.cols(); ++j) u += c[j] * basis.col(j);
  return u;
}

Eigen::VectorXd nodal_forces(const FrameLoads& loads, int n_dofs) {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(n_dofs);
  for (const PointLoad& p : loads.points) add_point_force(p.at, p.force, f);
  return f;
}

void Integrator::commit(const Eigen::VectorXd& u1, SimState& state) const { state.u = u1; }

ContactEquilibriumResult Integrator::solve_with_contacts(const std::vector<ContactRow>&, SurfaceCompliance&,
                                                         const ContactEquilibriumOptions&, IntegratorWork&,
                                                         Eigen::VectorXd&, const Eigen::VectorXd&) const {
  throw std::logic_error(
      "Integrator::solve_with_contacts: this integrator does not solve its contacts (solves_contacts())");
}

// ---------------------------------------------------------------------------------------------------------------
// LinearQuasiStatic

LinearQuasiStatic::LinearQuasiStatic(const Eigen::SparseMatrix<double>& K, const std::vector<int>& fixed_nodes,
                                     const std::vector<LoadPoint>& load_points, const std::vector<bool>& held,
                                     const PrescribedMotion& prescribed)
    : solver_(K, fixed_nodes), response_(solver_, load_points) {
  if (held.size() != load_points.size())
    throw std::invalid_argument("LinearQuasiStatic: one held flag per load point expected (" +
                                std::to_string(load_points.size()) + "), got " + std::to_string(held.size()));
  // The prescribed basis's responses: u = P - K_ff^-1 (K P) on the free DOFs (the solve ignores fixed DOFs).
  if (!prescribed.empty()) prescribed_response_ = prescribed.basis - solver_.solve_many(K * prescribed.basis);

  // Held points: the stiffness that maps their displacements to their forces, (P_dd)^-1, and their motion per
  // force at every load point, P_d*.
  for (size_t i = 0; i < held.size(); ++i)
    if (held[i]) held_index_.push_back(static_cast<int>(i));
  if (held_index_.empty()) return;
  const Eigen::MatrixXd& P = response_.point_compliance();
  const int d = static_cast<int>(held_index_.size());
  Eigen::MatrixXd Pdd(3 * d, 3 * d);
  hold_coupling_.resize(3 * d, P.cols());
  for (int a = 0; a < d; ++a) {
    hold_coupling_.middleRows(3 * a, 3) = P.middleRows(3 * held_index_[a], 3);
    for (int b = 0; b < d; ++b) Pdd.block(3 * a, 3 * b, 3, 3) = P.block(3 * held_index_[a], 3 * held_index_[b], 3, 3);
  }
  hold_stiffness_ = Pdd.ldlt().solve(Eigen::MatrixXd::Identity(3 * d, 3 * d));
  // The same points for the contact solve: contacts must not move them (the device holds them).
  held_.U.resize(response_.response().rows(), 3 * d);
  for (int a = 0; a < d; ++a) {
    held_.points.push_back(load_points[held_index_[a]]);
    held_.U.middleCols(3 * a, 3) = response_.response().middleCols(3 * held_index_[a], 3);
  }
  held_.S = hold_stiffness_;
}

// Held points get the forces that move them to their targets given the other points' forces and the prescribed
// motion: P_dd f_d = d - d_prescribed - P_df f_f (P: compliance between load points).
void LinearQuasiStatic::solve_held_forces(FrameLoads& loads, const Eigen::VectorXd& prescribed_u,
                                          Points& forces) const {
  const int d = static_cast<int>(held_index_.size());
  Eigen::VectorXd target(3 * d);
  for (int a = 0; a < d; ++a) {
    const PointLoad& p = loads.points[held_index_[a]];
    target.segment<3>(3 * a) = p.target;
    if (prescribed_u.size() == 0) continue;
    for (int k = 0; k < 3; ++k)
      target.segment<3>(3 * a) -= p.at.weight[k] * prescribed_u.segment<3>(3 * p.at.node[k]);
  }
  const Eigen::VectorXd f_all = Eigen::Map<const Eigen::VectorXd>(forces.data(), forces.size());
  const Eigen::VectorXd f_held = hold_stiffness_ * (target - hold_coupling_ * f_all);
  for (int a = 0; a < d; ++a) {
    forces.row(held_index_[a]) = f_held.segment<3>(3 * a).transpose();
    loads.points[held_index_[a]].force = f_held.segment<3>(3 * a);
  }
}

Prediction LinearQuasiStatic::predict(FrameLoads& loads, const Eigen::VectorXd& prescribed_c, const SimState&,
                                      IntegratorWork&, Eigen::VectorXd& u1) const {
  // The prescribed nodes' effect on the whole mesh: a sum of precomputed columns.
  const Eigen::VectorXd prescribed_u =
      prescribed_response_.cols() > 0 ? combine_columns(prescribed_response_, prescribed_c) : Eigen::VectorXd();
  if (loads.at_compiled_points) {
    // u = U forces: precomputed unit responses at the load points (held points' forces solved first).
    Points forces(loads.points.size(), 3);
    for (size_t i = 0; i < loads.points.size(); ++i)
      forces.row(i) = loads.points[i].held ? Eigen::RowVector3d(0, 0, 0)
                                           : Eigen::RowVector3d(loads.points[i].force.transpose());
    if (!held_index_.empty()) solve_held_forces(loads, prescribed_u, forces);
    response_.displacement(forces, u1);
  } else {
    // A point moved: one back-substitution with the nodal loads.
    solver_.solve(nodal_forces(loads, solver_.n_dofs()), u1);
  }
  if (prescribed_u.size() > 0) u1 += prescribed_u;
  return Prediction{};
}

// ---------------------------------------------------------------------------------------------------------------
// CorotationalQuasiStatic

CorotationalQuasiStatic::CorotationalQuasiStatic(const TetMesh& mesh, const LinearMaterial& material,
                                                 const std::vector<int>& fixed_nodes,
                                                 const CorotationalOptions& options, const PrescribedMotion& prescribed,
                                                 const Eigen::VectorXd& support)
    : model_(mesh, material, fixed_nodes, support), options_(options), prescribed_(prescribed) {
  validate_options(options_);
}

CorotationalQuasiStatic::CorotationalQuasiStatic(const QuadraticMesh& mesh, const LinearMaterial& material,
                                                 const std::vector<int>& fixed_nodes,
                                                 const CorotationalOptions& options, const PrescribedMotion& prescribed,
                                                 const Eigen::VectorXd& support)
    : model_(mesh, material, fixed_nodes, support), options_(options), prescribed_(prescribed) {
  validate_options(options_);
  if (options_.tangent != CorotationalTangent::warped) model_.elements().require_linear("CorotationalQuasiStatic");
}

Prediction CorotationalQuasiStatic::predict(FrameLoads& loads, const Eigen::VectorXd& prescribed_c, const SimState&,
                                            IntegratorWork& work, Eigen::VectorXd& u1) const {
  // Nonlinear equilibrium from the nodal loads, warm-started from the last frame's free solution.
  work.frame_forces = nodal_forces(loads, model_.n_dofs());
  const Eigen::VectorXd& f = work.frame_forces;
  const Eigen::VectorXd u_fixed = prescribed_.empty() ? Eigen::VectorXd() : combine_columns(prescribed_.basis, prescribed_c);
  // After a contact frame: no factorisation of its own where a contact Hessian's factor preconditions it (the one
  // the walls met on, share_with_prediction; measured on the 8x pinch: its factorisations beside the Hessian's left
  // that 2-6 contact frames old, and its bounded QP steps short, docs/bench_contact_prediction.csv; when it only
  // waited for the shared factor to be its preconditioner, its own last one replaced it, and its factorisations came
  // back: halvings 187 against 42-49 in one run), and the contact work bound.
  // (So too before and between contacts while the background thread keeps a contact Hessian factorised,
  // anticipate_contacts.)
  CorotationalOptions options = options_;
  const bool anticipated = options_.refactor_in_background && (work.contact_hessian.factor || work.contact_pending.valid());
  if ((work.after_contact_solve || anticipated) && shares_contact_hessian()) options.refactor_cg_iterations = 0;
  if (work.after_contact_solve && options.contact_back_substitutions > 0)
    options.max_back_substitutions = options.contact_back_substitutions;
  work.after_contact_solve = false;
  ++work.predictions;
  const CorotationalResult r = solve_corotational(model_, f, work.corotational, options, u_fixed, loads.contacts);
  u1 = work.corotational.u;
  Prediction p;
  p.iterations = r.iterations;
  p.converged = r.converged;
  p.diverged = r.diverged;
  p.refactorisations = r.refactorisations;
  p.tangent_fallbacks = r.tangent_fallbacks;
  p.cg_iterations = r.cg_iterations;
  p.truncated_steps = r.truncated_steps;
  p.preconditioner_failures = r.refactor_failures;
  p.contact_lambda = r.contact_lambda;
  return p;
}

namespace {

// A contact solve's start this near the last one's end (relative to its largest entry) is taken as that end.
constexpr double kSameStartRoundOff = 1e-12;
// When the walls meet (a contact solve after a frame without one), a contact Hessian factorised at rotations more
// than this many frames old is not used: the solve takes the one under way, if any, and if that is as old factorises
// K_w at its start at once. (Measured on the 8x pinch, rendered with the exact check: in contact the background
// Hessians the solves use are 0-12 frames old; when the walls met on one anticipated about 25 frames before, the
// next 9 frames' steps took 7-9 line-search halvings each. Anticipated every kAnticipatedHessianFrames, with jobs of
// 3-8 frames, the walls met on one 13-15 frames old in 4 of 6 rendered runs, which at 12 waited 3-12 ms for the next:
// the first contact frame 24-34 ms. At 20, 8 alternating rendered runs: worst frame 28.5 -> 25.4 ms, and with the
// exact check, 3 runs each, the same tip, residual and halvings within the runs' spread:
// docs/bench_stale_hessian_frames*.csv.)
constexpr int kStaleHessianFrames = 20;
// ... and waits at most this long for the one under way; past it the frame factorises K_w at its start at once, as
// when no job is under way. (The background thread runs at nice 19: on a machine busy with other work it can get no
// core for seconds: 2.8-9.4 s for one frame of the 8x pinch while a build or two busy loops ran. Solving on the stale
// Hessian instead, until the job came, ended that session's tip at -10.9 mm against -18.0. Unloaded, the whole
// first-contact frame, wait included, took at most 88 ms, docs/bench_stale_waits.csv.)
constexpr auto kStaleHessianWait = std::chrono::milliseconds(100);
// While the walls stay in contact, a contact Hessian more than kOverdueHessianFrames old whose successor has been under
// way for more than kOverdueJobFrames is replaced at once (K_w at the solve's start, factorised on this thread; the
// late job, older, is let go when it comes). On a machine busy with other work (two busy loops at nice 0) the nice-19
// job never came and every contact frame solved on the one the walls met on, up to 89 frames old: the tip ended at
// -13.4 mm against about -17.5 idle. Idle, rendered (8x pinch, instrumented), the Hessians the contact solves used
// were 3-19 frames old in 3 runs, but the Hessian's age alone (over 24 frames) replaced one at once in some of 8
// runs, a 37 ms frame: the job's age tells a starved job from a slow one.
constexpr int kOverdueHessianFrames = 24;
// (The jobs' own wall times, idle and rendered, warmed: 43-116 ms, 3-8 frames; before the warm-up the slowest took
// 200-300 ms, about 20 frames. Instrumented, 8x pinch.)
constexpr int kOverdueJobFrames = 20;
// Before the walls meet, a new contact Hessian is started once the last one is this many frames old (not whenever
// the background thread is free: its factorisations slowed the contact-free frames' solves on the main thread,
// measured on the 8x pinch, pcr median 8 against 15 ms with one after another).
constexpr int kAnticipatedHessianFrames = 6;
// Contact Hessians factorised at the session's start with all alive, one kept, so that the memory of that many is
// touched before the frames (see anticipate_contacts). In contact three are alive at once (the one in use, the
// prediction's older preconditioner, the next under way), and the main thread's allocations between them split the
// heap's free blocks. Measured on the 8x pinch, rendered (page faults and CPU time of each background factorisation,
// instrumented): with two, the first job took 85-89 ms (4,900 faults) against 27-30 ms warm and the first after the
// walls met 120-135 ms (8,000 faults), in every run; with three, the first 34-36 ms and still one of 113-125 ms after
// the walls met; with four, at most one of 62-65 ms (3,000 faults) a session.
constexpr int kWarmContactHessians = 4;

// K_w at the rotations R factorised, with its compliance over the nodes (lazy: half columns per node) readied for
// couplings on the prefetched nodes (their half columns and the kept gram among them: 3-5 ms of the frame that adopts
// it otherwise, on the 8x pinch).
ContactHessianFactor contact_hessian(const CorotationalModel& model, const std::vector<Eigen::Matrix3d>& R,
                                     const std::vector<int>& nodes, const std::vector<int>& prefetch, int taken_at) {
  ContactHessianFactor h;
  h.taken_at = taken_at;
  h.factor = factorise_warped(model, R, true);
  h.compliance = std::make_shared<SurfaceCompliance>(*h.factor, nodes, SurfaceCompliance::kBlockColumns, 0L, 0L);
  h.compliance->prepare_couplings(prefetch);
  return h;
}

// The same started now on a new thread at the background factorisations' priority, as the work's job under way (its
// start and outwait reset).
void start_contact_hessian(const CorotationalModel& model, std::vector<Eigen::Matrix3d> R, std::vector<int> nodes,
                           std::vector<int> prefetch, IntegratorWork& work) {
  const int taken_at = work.predictions;
  work.contact_pending = std::async(
      std::launch::async,
      [&model, taken_at](std::vector<Eigen::Matrix3d> rotations, std::vector<int> set, std::vector<int> ahead) {
        at_background_priority();
        return contact_hessian(model, rotations, set, ahead, taken_at);
      },
      std::move(R), std::move(nodes), std::move(prefetch));
  work.contact_pending_since = taken_at;
  work.contact_pending_outwaited = false;
}

}  // namespace

// A new contact Hessian's factor (K_w at recent rotations) also preconditions the free predictions, which start no
// factorisation of their own after a contact solve; not with per-node rotated preconditioning, whose factor must
// come with the rotations it was made at.
void CorotationalQuasiStatic::share_with_prediction(IntegratorWork& work) const {
  if (!shares_contact_hessian() || !work.contact_hessian.factor) return;
  work.corotational.preconditioner = work.contact_hessian.factor;
  work.corotational.chord_steps_since_refresh = 0;
}

ContactEquilibriumResult CorotationalQuasiStatic::solve_with_contacts(const std::vector<ContactRow>& rows,
                                                                      SurfaceCompliance& compliance,
                                                                      const ContactEquilibriumOptions& options,
                                                                      IntegratorWork& work, Eigen::VectorXd& u,
                                                                      const Eigen::VectorXd& lambda_warm) const {
  if (work.frame_forces.size() != model_.n_dofs())
    throw std::logic_error(
        "CorotationalQuasiStatic::solve_with_contacts: no prediction before it (its loads are the frame's)");
  const bool lagged = options.hessian == ContactHessian::as_given;
  // A finished background factorisation becomes the Hessian; the first contact solve, or one where the walls meet on
  // a stale Hessian, waits for one under way (anticipate_contacts started it before the walls met) rather than
  // factorising another beside it (its thread then has a core; rendered, the walls met on a stale Hessian with one
  // under way in about 1 run of 4, and the factorisation beside it took 140-150 ms); on a stale one, for at most
  // kStaleHessianWait (outwaited: this frame factorises at once below; where the walls meet again on a stale Hessian
  // before that job has come, they do not wait for it again).
  // The prediction takes it as its preconditioner where the walls meet, not while they stay in contact: the frame's
  // trial motion is its prediction plus the last frame's correction, measured from a prediction on the old
  // preconditioner, and a bounded prediction on a new one ends elsewhere (on the 8x pinch the frame after each
  // adoption held 2-3 times the rows, 400-500 instead of 160, and its solve took 20-30 ms).
  int failures = 0;
  const bool walls_meet = work.predictions - work.last_contact_solve > 1;
  const auto stale = [&work, walls_meet] {
    return walls_meet && work.contact_hessian.compliance &&
           work.predictions - work.contact_hessian.taken_at > kStaleHessianFrames;
  };
  const auto wait = work.contact_pending_outwaited ? std::chrono::milliseconds(0) : kStaleHessianWait;
  const bool outwaited = lagged && work.contact_pending.valid() && stale() &&
                         work.contact_pending.wait_for(wait) != std::future_status::ready;
  work.contact_pending_outwaited = work.contact_pending_outwaited || outwaited;
  if (lagged && work.contact_pending.valid() && !outwaited &&
      (!work.contact_hessian.compliance || stale() ||
       work.contact_pending.wait_for(std::chrono::seconds(0)) == std::future_status::ready) &&
      adopt_contact_hessian(work, failures) && walls_meet)
    share_with_prediction(work);
  // A start at the last contact solve's end to round-off (the committed state is the prediction plus the
  // correction) starts at that end exactly, with its evaluation.
  const CachedEvaluation& end = work.contact_end;
  if (end.u.size() == u.size() &&
      (u - end.u).lpNorm<Eigen::Infinity>() <= kSameStartRoundOff * end.u.lpNorm<Eigen::Infinity>()) {
    end.restore(work.corotational);
    u = end.u;
  }
  work.corotational.u = u;
  // The rest solver's nested-dissection analysis, once, on this thread: the contact Hessians are factorised on it.
  if (lagged && !model_.solver().has_nested_analysis()) model_.solver().prepare_nested_analysis();
  // The first contact solve without an anticipated Hessian, or where the walls meet on a stale one (the one under
  // way, taken above, as stale, or outwaited), or one in contact on an overdue one (its successor starved: taken above
  // when it had come), factorises K_w at its start, at once (the rest K is far from the tangent of a tube deflected
  // several wall thicknesses: its steps needed four line-search halvings each and did not converge).
  const bool overdue = lagged && !walls_meet && work.contact_hessian.compliance &&
                      work.predictions - work.contact_hessian.taken_at > kOverdueHessianFrames &&
                      work.contact_pending.valid() && work.predictions - work.contact_pending_since > kOverdueJobFrames;
  const bool at_once =
      lagged && ((!work.contact_hessian.compliance && !work.contact_pending.valid()) || stale() || overdue);
  work.last_contact_solve = work.predictions;
  if (at_once) {
    // (The stale one let go first, the prediction's too: one more factorisation alive would touch fresh memory; an
    // overdue job under way holds one more until it comes.)
    if (work.corotational.preconditioner == work.contact_hessian.factor) work.corotational.preconditioner.reset();
    work.contact_hessian = ContactHessianFactor{};
    try {
      std::vector<Eigen::Matrix3d> R;
      model_.elements().rotations(u, R);
      work.contact_hessian = contact_hessian(model_, R, compliance.nodes(), {}, work.predictions);
      share_with_prediction(work);
    } catch (const std::exception&) {
      ++failures;  // (the rest K then)
    }
  }
  // The Hessian's compliance: the lagged factorisation's, or the rest one.
  SurfaceCompliance& B = lagged && work.contact_hessian.compliance ? *work.contact_hessian.compliance : compliance;
  ContactEquilibriumResult r =
      solve_contact_equilibrium(model_, work.frame_forces, rows, B, options, work.corotational, lambda_warm);
  u = work.corotational.u;
  const CorotationalState& s = work.corotational;
  if (s.u_eval.size() == s.u.size() && s.u_eval == s.u) work.contact_end.take(s);
  // The next Hessian: K_w at this end (its rotations are the state's cached evaluation at u), with the half columns
  // of these rows' nodes (the next frame's rows are mostly on them).
  if (lagged && !work.contact_pending.valid()) {
    if (options_.refactor_in_background) {
      start_contact_hessian(model_, work.corotational.rotations, compliance.nodes(), row_nodes(rows), work);
    } else {
      try {
        work.contact_hessian =
            contact_hessian(model_, work.corotational.rotations, compliance.nodes(), row_nodes(rows), work.predictions);
        share_with_prediction(work);
      } catch (const std::exception&) {
        ++failures;
      }
    }
  }
  work.after_contact_solve = lagged;
  r.refactor_failures = failures;
  return r;
}

// The background job's Hessian adopted (waiting for it if under way) unless it is older than the one in use; one that
// failed (not positive definite, out of memory) is counted and dropped, and the last one stays.
bool CorotationalQuasiStatic::adopt_contact_hessian(IntegratorWork& work, int& failures) const {
  try {
    ContactHessianFactor h = work.contact_pending.get();  // (get() leaves contact_pending invalid, failed or not)
    if (work.contact_hessian.compliance && h.taken_at < work.contact_hessian.taken_at) return false;
    work.contact_hessian = std::move(h);
    return true;
  } catch (const std::exception&) {
    ++failures;
    return false;
  }
}

void CorotationalQuasiStatic::anticipate_contacts(const std::vector<int>& nodes, IntegratorWork& work) const {
  if (!options_.refactor_in_background || !shares_contact_hessian() || work.after_contact_solve) return;
  // (A failure here is the next contact solve's to meet: it factorises at once when no Hessian is left.)
  int failures = 0;
  if (work.contact_pending.valid() &&
      work.contact_pending.wait_for(std::chrono::seconds(0)) == std::future_status::ready &&
      adopt_contact_hessian(work, failures))
    share_with_prediction(work);
  if (work.contact_pending.valid()) return;
  if (!model_.solver().has_nested_analysis()) model_.solver().prepare_nested_analysis();
  // Before the first prediction (the session's start): K, at once, kWarmContactHessians times with all alive, one
  // kept. A factorisation whose memory is touched for the first time costs several later ones (120-170 against 26-30
  // ms on the paper mesh, measured, page faults); the process keeps the memory it has touched (the lumen binary's
  // malloc settings), so the background thread's factorisations reuse these ones', out of the frames.
  const std::vector<Eigen::Matrix3d>& R = work.corotational.rotations;
  if (static_cast<int>(R.size()) != model_.elements().n_tets()) {
    try {
      const std::vector<Eigen::Matrix3d> rest(model_.elements().n_tets(), Eigen::Matrix3d::Identity());
      work.contact_hessian = contact_hessian(model_, rest, nodes, {}, work.predictions);
      share_with_prediction(work);
      // (The others beside it, then let go: one that fails leaves the first in use, its memory only less warmed.)
      std::vector<ContactHessianFactor> warm;
      for (int i = 1; i < kWarmContactHessians; ++i)
        warm.push_back(contact_hessian(model_, rest, nodes, {}, work.predictions));
    } catch (const std::exception&) {
      // (as a failed background one: the first contact solve factorises at once)
    }
    return;
  }
  if (work.contact_hessian.compliance && work.predictions - work.contact_hessian.taken_at < kAnticipatedHessianFrames)
    return;
  start_contact_hessian(model_, R, nodes, {}, work);
}

// ---------------------------------------------------------------------------------------------------------------
// BackwardEuler

BackwardEuler::BackwardEuler(const TetMesh& mesh, const LinearMaterial& material, const std::vector<int>& fixed_nodes,
                             const DynamicParams& params, const CorotationalOptions& options,
                             const PrescribedMotion& prescribed, const Eigen::VectorXd& support)
    : model_(mesh, material, fixed_nodes, params, support),
      step_solver_(model_.solver().scaled(1.0 / (params.time_step * params.time_step))),
      options_(options),
      prescribed_(prescribed) {
  validate_options(options_);
}

Prediction BackwardEuler::predict(FrameLoads& loads, const Eigen::VectorXd& prescribed_c, const SimState& state,
                                  IntegratorWork& work, Eigen::VectorXd& u1) const {
  // The trial step starts from the committed state; prescribed nodes take their end-of-step displacement.
  DynamicState& trial = work.step;
  trial.u = state.u;
  trial.v = state.v;
  if (!prescribed_.empty()) {
    const Eigen::VectorXd u_p = combine_columns(prescribed_.basis, prescribed_c);
    for (int node : prescribed_.nodes) trial.u.segment<3>(3 * node) = u_p.segment<3>(3 * node);
  }
  const StepResult r = step(model_, trial, nodal_forces(loads, model_.n_dofs()), model_.params().time_step, options_);
  u1 = trial.u;
  Prediction p;
  p.iterations = r.iterations;
  p.converged = r.converged;
  p.finite = r.finite;
  return p;
}

void BackwardEuler::commit(const Eigen::VectorXd& u1, SimState& state) const {
  // The committed velocity is the committed motion over the step (contacts included); fixed nodes have none.
  const double h = model_.params().time_step;
  for (Eigen::Index dof = 0; dof < u1.size(); ++dof)
    state.v[dof] = model_.is_fixed_dof(static_cast<int>(dof)) ? 0.0 : (u1[dof] - state.u[dof]) / h;
  state.u = u1;
}

double BackwardEuler::kinetic_energy(const SimState& state) const {
  return 0.5 * state.v.dot(model_.mass().cwiseProduct(state.v));
}

}  // namespace lumen::physics
