#include "engine/simulation.hpp"

#include "collision/distance.hpp"
#include "engine/response.hpp"
#include "physics/quadratic.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace lumen::engine {
namespace {

using Clock = std::chrono::steady_clock;
constexpr double kPi = 3.14159265358979323846;
double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

}  // namespace

// The probes' forces as a nodal force vector (3n); a moving point is attached where it is this frame.
Eigen::VectorXd nodal_loads(const Model& model, const State& state) {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * model.mesh.n_nodes());
  for (size_t i = 0; i < state.samples.size(); ++i) {
    const SurfacePoint sp = state.sources[i]->point_is_fixed()
                                ? model.probe_points[i]
                                : snap_to_surface(model.mesh.rest, model.mesh.outer, state.samples[i].point);
    add_point_load(sp, state.samples[i].force, f);
  }
  return f;
}

void add_point_load(const SurfacePoint& sp, const Eigen::Vector3d& force, Eigen::VectorXd& f) {
  for (int k = 0; k < 3; ++k) f.segment<3>(3 * sp.node[k]) += sp.weight[k] * force;
}

double twist_degrees(const TwistSpec& twist, double t) {
  if (!twist.enabled() || twist.track.empty()) return 0.0;
  const std::vector<TwistKey>& k = twist.track;
  // Held before the first key and after the last; linear in between.
  if (t <= k.front().t) return k.front().degrees;
  if (t >= k.back().t) return k.back().degrees;
  const auto next = std::upper_bound(k.begin(), k.end(), t, [](double v, const TwistKey& key) { return v < key.t; });
  const TwistKey& a = *(next - 1);
  const TwistKey& b = *next;
  const double w = (t - a.t) / (b.t - a.t);
  return (1.0 - w) * a.degrees + w * b.degrees;
}

Eigen::VectorXd twist_displacement(const Model& model, double degrees) {
  if (model.twist_nodes.empty()) return Eigen::VectorXd::Zero(3 * model.mesh.n_nodes());
  const double theta = degrees * kPi / 180.0;
  return (std::cos(theta) - 1.0) * model.twist_basis.col(0) + std::sin(theta) * model.twist_basis.col(1);
}

SurfacePoint snap_to_surface(const Points& x, const Tris& tris, const Eigen::Vector3d& p) {
  SurfacePoint best;
  double best_d2 = std::numeric_limits<double>::infinity();
  // Brute force over the surface triangles (done once per probe for fixed points).
  for (int t = 0; t < tris.rows(); ++t) {
    const Eigen::Vector3d a = x.row(tris(t, 0)), b = x.row(tris(t, 1)), c = x.row(tris(t, 2));
    const Eigen::Vector3d w = collision::closest_on_triangle(p, a, b, c);
    const double d2 = (w[0] * a + w[1] * b + w[2] * c - p).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best.triangle = t;
      for (int k = 0; k < 3; ++k) {
        best.node[k] = tris(t, k);
        best.weight[k] = w[k];
      }
    }
  }
  return best;
}

std::unique_ptr<Model> compile_model(const Scene& scene) {
  const auto t0 = Clock::now();
  auto m = std::make_unique<Model>();
  m->scene = scene;
  m->budget_ms = 1000.0 / scene.fps;

  // Mesh and material. Quadratic elements: the engine's mesh is their linear view (all nodes, walls split over
  // the edge nodes), and the stiffness comes from the 10-node tets.
  m->material.young_modulus = scene.material.young_modulus;
  m->material.poisson_ratio = scene.material.poisson_ratio;
  const physics::TetMesh linear = physics::make_hollow_cylinder(scene.mesh);
  std::unique_ptr<physics::QuadraticMesh> quadratic;
  if (scene.element == "tet10") {
    quadratic = std::make_unique<physics::QuadraticMesh>(physics::make_quadratic_cylinder(linear, scene.mesh));
    m->mesh = physics::surface_view(*quadratic, linear);
  } else {
    m->mesh = linear;
  }

  // Named fixed node sets.
  for (const std::string& name : scene.fixed) {
    if (name == "ends" || name == "start")
      m->fixed_nodes.insert(m->fixed_nodes.end(), m->mesh.end_nodes_start.begin(), m->mesh.end_nodes_start.end());
    if (name == "ends" || name == "stop")
      m->fixed_nodes.insert(m->fixed_nodes.end(), m->mesh.end_nodes_stop.begin(), m->mesh.end_nodes_stop.end());
  }
  // Twisted end ring: turned about the centreline tangent through its centre (the generator's geometry: the arc
  // c(s) = (R - R cos(s/R), 0, R sin(s/R)) with tangent (sin(s/R), 0, cos(s/R)), or the z axis when straight).
  if (scene.twist.enabled()) {
    const bool start = scene.twist.end == "start";
    m->twist_nodes = start ? m->mesh.end_nodes_start : m->mesh.end_nodes_stop;
    const double s_end = start ? 0.0 : scene.mesh.length, bend = scene.mesh.bend_radius;
    if (bend == 0.0) {
      m->twist_center = Eigen::Vector3d(0.0, 0.0, s_end);
      m->twist_axis = Eigen::Vector3d::UnitZ();
    } else {
      const double phi = s_end / bend;
      m->twist_center = Eigen::Vector3d(bend - bend * std::cos(phi), 0.0, bend * std::sin(phi));
      m->twist_axis = Eigen::Vector3d(std::sin(phi), 0.0, std::cos(phi));
    }
    // Rotation basis per ring node: R(theta) r - r = (cos theta - 1) (r - a (a . r)) + sin theta (a x r).
    m->twist_basis = Eigen::MatrixXd::Zero(3 * m->mesh.n_nodes(), 2);
    const Eigen::Vector3d& a = m->twist_axis;
    for (int node : m->twist_nodes) {
      const Eigen::Vector3d r = m->mesh.rest.row(node).transpose() - m->twist_center;
      if (std::abs(a.dot(r)) > 1e-9 * scene.mesh.outer_radius)
        throw std::runtime_error("compile_model: twist: end node " + std::to_string(node) +
                                 " is off the ring plane (" + std::to_string(a.dot(r)) + " m)");
      m->twist_basis.block<3, 1>(3 * node, 0) = r - a * a.dot(r);
      m->twist_basis.block<3, 1>(3 * node, 1) = a.cross(r);
    }
    m->fixed_nodes.insert(m->fixed_nodes.end(), m->twist_nodes.begin(), m->twist_nodes.end());
  }
  std::sort(m->fixed_nodes.begin(), m->fixed_nodes.end());
  m->fixed_nodes.erase(std::unique(m->fixed_nodes.begin(), m->fixed_nodes.end()), m->fixed_nodes.end());

  // Assemble K and factorise it once.
  const Eigen::SparseMatrix<double> K = quadratic ? physics::assemble_stiffness(*quadratic, m->material)
                                                  : physics::assemble_stiffness(m->mesh, m->material);
  m->solver = std::make_unique<physics::StaticSolver>(K, m->fixed_nodes);
  m->time_step = 1.0 / scene.fps;
  m->corotational_options.tolerance = scene.solver.tolerance;
  m->corotational_options.max_iterations = scene.solver.max_iterations;
  m->corotational_options.extrapolate = true;
  // A twist rotates the tube far from rest: precondition with the rest factorisation rotated per node (several
  // times fewer CG iterations there; slower for the small rotations of a press, so only then).
  m->corotational_options.rotate_preconditioner = scene.twist.enabled();
  // Large deformation: once a linear solve takes more than 5 PCG iterations, K_w is factorised at the rotations of
  // that moment on the second core and preconditions the following solves (quasi-static only).
  m->corotational_options.refactor_cg_iterations = 5;
  m->corotational_options.refactor_in_background = true;

  // Linear quasi-static twist: the whole mesh's response to each basis column held on the ring (no load), so a
  // frame's twist costs two vector updates: u = P - K_ff^-1 (K P) on the free DOFs (the solve ignores fixed DOFs).
  if (scene.twist.enabled() && scene.material.model == "linear" && scene.solver.type == "quasi_static") {
    const Eigen::MatrixXd KP = K * m->twist_basis;
    m->twist_response = m->twist_basis - m->solver->solve_many(KP);
  }

  // Probe attachment points on the outer wall; a point far from the wall is refused.
  const double tolerance = 0.25 * (scene.mesh.outer_radius - scene.mesh.inner_radius) + 1e-9;
  std::vector<physics::LoadPoint> load_points;
  for (size_t i = 0; i < scene.probes.size(); ++i) {
    const ProbeSpec& p = scene.probes[i];
    SurfacePoint sp = snap_to_surface(m->mesh.rest, m->mesh.outer, p.point);
    Eigen::Vector3d q = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) q += sp.weight[k] * m->mesh.rest.row(sp.node[k]).transpose();
    if ((q - p.point).norm() > tolerance)
      throw InputError(scene.path + ": probes[" + std::to_string(i) + "].point: not on the organ's outer wall (" +
                       std::to_string((q - p.point).norm()) + " m away; value [" + std::to_string(p.point.x()) + ", " +
                       std::to_string(p.point.y()) + ", " + std::to_string(p.point.z()) + "])");
    m->probe_points.push_back(sp);
    physics::LoadPoint lp;
    for (int k = 0; k < 3; ++k) {
      lp.node[k] = sp.node[k];
      lp.weight[k] = sp.weight[k];
    }
    load_points.push_back(lp);
  }
  // Unit-load responses at the probe points: a frame's physics is then a small dense product.
  m->probe_response = std::make_unique<physics::LoadResponse>(*m->solver, load_points);

  // Displacement-driven probes: the stiffness that maps their points' displacements to their forces.
  for (size_t i = 0; i < scene.probes.size(); ++i)
    if (scene.probes[i].drive == ProbeDrive::Displacement) m->held_probes.push_back(static_cast<int>(i));
  for (size_t i = 0; i < scene.probes.size() && !m->held_probes.empty(); ++i)
    if (!scene.probes[i].replay.empty())
      throw InputError(scene.path + ": probes[" + std::to_string(i) +
                       "].replay: replayed probes cannot be combined with displacement-driven probes (value \"" +
                       scene.probes[i].replay + "\")");
  if (!m->held_probes.empty()) {
    const Eigen::MatrixXd& P = m->probe_response->point_compliance();
    const int d = static_cast<int>(m->held_probes.size());
    Eigen::MatrixXd Pdd(3 * d, 3 * d);
    m->hold_coupling.resize(3 * d, P.cols());
    for (int a = 0; a < d; ++a) {
      m->hold_coupling.middleRows(3 * a, 3) = P.middleRows(3 * m->held_probes[a], 3);
      for (int b = 0; b < d; ++b) Pdd.block(3 * a, 3 * b, 3, 3) = P.block(3 * m->held_probes[a], 3 * m->held_probes[b], 3, 3);
    }
    m->hold_stiffness = Pdd.ldlt().solve(Eigen::MatrixXd::Identity(3 * d, 3 * d));
    // The same points for the contact solve: contacts must not move them (the device holds them).
    m->held.U.resize(3 * m->mesh.n_nodes(), 3 * d);
    for (int a = 0; a < d; ++a) {
      m->held.points.push_back(load_points[m->held_probes[a]]);
      m->held.U.middleCols(3 * a, 3) = m->probe_response->response().middleCols(3 * m->held_probes[a], 3);
    }
    m->held.S = m->hold_stiffness;
  }

  // Inner-wall nodes (for the collision surface's bookkeeping).
  for (int t = 0; t < m->mesh.inner.rows(); ++t)
    for (int k = 0; k < 3; ++k) m->inner_nodes.push_back(m->mesh.inner(t, k));
  std::sort(m->inner_nodes.begin(), m->inner_nodes.end());
  m->inner_nodes.erase(std::unique(m->inner_nodes.begin(), m->inner_nodes.end()), m->inner_nodes.end());

  // The colliding walls: the inner wall, and the outer wall when the scene asks; their nodes.
  m->collision_tris = m->mesh.inner;
  if (scene.collision.outer_wall) {
    m->collision_tris.conservativeResize(m->mesh.inner.rows() + m->mesh.outer.rows(), 3);
    m->collision_tris.bottomRows(m->mesh.outer.rows()) = m->mesh.outer;
  }
  m->collision_nodes.assign(m->collision_tris.data(), m->collision_tris.data() + m->collision_tris.size());
  std::sort(m->collision_nodes.begin(), m->collision_nodes.end());
  m->collision_nodes.erase(std::unique(m->collision_nodes.begin(), m->collision_nodes.end()), m->collision_nodes.end());

  // Implicit dynamics: backward Euler at h = 1 / fps, and the compliance of one step for the contact solves,
  // A_u = A / h^2 with A = (1 + h alpha) M + (h beta + h^2) K the matrix the dynamic model factorises.
  if (scene.solver.type == "dynamic") {
    if (!m->held_probes.empty())
      throw InputError(scene.path + ": probes[" + std::to_string(m->held_probes[0]) +
                       "].track: displacement-driven probes need solver.type \"quasi_static\" (value \"dynamic\")");
    physics::DynamicParams params;
    params.elastic = scene.material.model == "corotational" ? physics::ElasticModel::kCorotational
                                                            : physics::ElasticModel::kLinear;
    params.density = scene.material.density;
    params.alpha = scene.solver.rayleigh_mass;
    params.beta = scene.solver.rayleigh_stiffness;
    params.time_step = m->time_step;
    m->dynamic = std::make_unique<physics::DynamicModel>(m->mesh, m->material, m->fixed_nodes, params);
    const double h = params.time_step;
    const Eigen::VectorXd& mass = m->dynamic->mass();
    Eigen::SparseMatrix<double> M(mass.size(), mass.size());
    M.reserve(Eigen::VectorXi::Constant(mass.size(), 1));
    for (Eigen::Index i = 0; i < mass.size(); ++i) M.insert(i, i) = mass[i];
    const Eigen::SparseMatrix<double> A_u =
        (1.0 + params.beta / h) * m->dynamic->stiffness() + ((1.0 + h * params.alpha) / (h * h)) * M;
    m->step_solver = std::make_unique<physics::StaticSolver>(A_u, m->fixed_nodes);
  } else if (scene.material.model == "corotational") {
    // Corotational material, quasi-static: stiffness warped per element each frame, PCG preconditioned by the
    // rest factorisation.
    if (!m->held_probes.empty())
      throw InputError(scene.path + ": probes[" + std::to_string(m->held_probes[0]) +
                       "].track: displacement-driven probes need material.model \"linear\" (value \"corotational\")");
    m->corotational = std::make_unique<physics::CorotationalModel>(m->mesh, m->material, m->fixed_nodes);
  }

  m->compile_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  return m;
}

State make_state(const Model& model) {
  State s;
  s.x = model.mesh.rest;
  s.u = Eigen::VectorXd::Zero(3 * model.mesh.n_nodes());
  for (const ProbeSpec& p : model.scene.probes) s.sources.push_back(make_source(p));
  s.samples.resize(model.scene.probes.size());
  s.in_contact.assign(model.mesh.n_nodes(), 0);
  if (model.dynamic) {
    s.dynamic.u = Eigen::VectorXd::Zero(3 * model.mesh.n_nodes());
    s.dynamic.v = Eigen::VectorXd::Zero(3 * model.mesh.n_nodes());
  }
  if (model.scene.collision.self) {
    s.detector = std::make_unique<collision::SelfCollision>(model.collision_tris, model.mesh.n_nodes(), model.scene.collision.kdop);
    s.compliance = std::make_unique<physics::SurfaceCompliance>(model.contact_solver(), model.collision_nodes);
    // Whole-mesh columns of the probe nodes too, so a contact correction that changes probe forces stays cheap.
    std::vector<int> probe_nodes;
    for (const SurfacePoint& sp : model.probe_points) probe_nodes.insert(probe_nodes.end(), sp.node, sp.node + 3);
    std::sort(probe_nodes.begin(), probe_nodes.end());
    probe_nodes.erase(std::unique(probe_nodes.begin(), probe_nodes.end()), probe_nodes.end());
    s.compliance->ensure_columns(probe_nodes);
  }
  return s;
}

void step(const Model& model, State& state, FrameRecord& rec) {
  // Every field of the record is this frame's (callers may reuse one record across frames).
  rec = FrameRecord{};
  const int n = model.mesh.n_nodes();
  const double t1 = (state.frame + 1) / model.scene.fps;
  rec.frame = state.frame + 1;
  rec.t = t1;

  // Input: sample every probe source at the end-of-frame time.
  auto clock = Clock::now();
  bool all_fixed = true;
  bool bad_input = false;
  for (size_t i = 0; i < state.sources.size(); ++i) {
    // A source that yields a non-finite value (a faulty device) is not believed: its last good sample stands.
    const ProbeSample s = state.sources[i]->sample(t1);
    if (s.point.allFinite() && s.force.allFinite() && s.displacement.allFinite())
      state.samples[i] = s;
    else
      bad_input = true;
    all_fixed = all_fixed && state.sources[i]->point_is_fixed();
  }
  rec.ms[kInput] = ms_since(clock);

  // Twist: the turned ring's angle at the end of the frame.
  rec.twist_degrees = twist_degrees(model.scene.twist, t1);
  const double theta = rec.twist_degrees * kPi / 180.0;
  const double twist_c = std::cos(theta) - 1.0, twist_s = std::sin(theta);

  // Physics: one implicit step (dynamic), or quasi-static equilibrium: corotational, or linear FEM u = K^-1 f
  // (precomputed unit responses when probe points are fixed); the twisted ring is held at its angle.
  clock = Clock::now();
  Eigen::VectorXd u(3 * n);
  Eigen::VectorXd v_before;  // dynamic: the velocity restored when the frame fails
  bool solved = true;        // false: the solver reported a failed (non-finite) solve
  if (model.dynamic) {
    v_before = state.dynamic.v;
    // Backward Euler with the probes' loads; fixed nodes keep the displacement the state gives them (the ring's
    // at the end of the frame, 0 for the others).
    const Eigen::VectorXd f = nodal_loads(model, state);
    if (!model.twist_nodes.empty()) {
      const Eigen::VectorXd u_ring = twist_displacement(model, rec.twist_degrees);
      for (int node : model.twist_nodes) state.dynamic.u.segment<3>(3 * node) = u_ring.segment<3>(3 * node);
    }
    const physics::StepResult r =
        physics::step(*model.dynamic, state.dynamic, f, model.time_step, model.corotational_options);
    rec.physics_iterations = r.iterations;
    rec.physics_converged = r.converged;
    solved = r.finite;
    u = state.dynamic.u;
  } else if (model.corotational) {
    // Corotational: nonlinear equilibrium from the nodal loads, warm-started from the last frame.
    const Eigen::VectorXd f = nodal_loads(model, state);
    const Eigen::VectorXd u_fixed =
        model.twist_nodes.empty() ? Eigen::VectorXd() : twist_displacement(model, rec.twist_degrees);
    const physics::CorotationalResult r =
        physics::solve_corotational(*model.corotational, f, state.corotational, model.corotational_options, u_fixed);
    rec.physics_iterations = r.iterations;
    rec.physics_converged = r.converged;
    u = state.corotational.u;
  } else if (all_fixed) {
    // Displacement-driven probes get the forces that move their points to the targets, given the others' and the
    // twist's: P_dd f_d = d - d_twist - P_df f_f (P: compliance between probe points).
    Points forces(state.samples.size(), 3);
    for (size_t i = 0; i < state.samples.size(); ++i)
      forces.row(i) = state.samples[i].displacement_driven ? Eigen::RowVector3d(0, 0, 0)
                                                           : Eigen::RowVector3d(state.samples[i].force.transpose());
    if (!model.held_probes.empty()) {
      const int d = static_cast<int>(model.held_probes.size());
      Eigen::VectorXd target(3 * d);
      for (int a = 0; a < d; ++a) {
        const int p = model.held_probes[a];
        target.segment<3>(3 * a) = state.samples[p].displacement;
        if (model.twist_response.size() == 0) continue;
        for (int k = 0; k < 3; ++k) {
          const int node = model.probe_points[p].node[k];
          target.segment<3>(3 * a) -= model.probe_points[p].weight[k] *
                                      (twist_c * model.twist_response.col(0).segment<3>(3 * node) +
                                       twist_s * model.twist_response.col(1).segment<3>(3 * node));
        }
      }
      const Eigen::VectorXd f_all = Eigen::Map<const Eigen::VectorXd>(forces.data(), forces.size());
      const Eigen::VectorXd f_held = model.hold_stiffness * (target - model.hold_coupling * f_all);
      for (int a = 0; a < d; ++a) {
        forces.row(model.held_probes[a]) = f_held.segment<3>(3 * a).transpose();
        state.samples[model.held_probes[a]].force = f_held.segment<3>(3 * a);
      }
    }
    model.probe_response->displacement(forces, u);
  } else {
    const Eigen::VectorXd f = nodal_loads(model, state);
    model.solver->solve(f, u);
  }
  // Linear quasi-static twist: add the precomputed response of the held ring.
  if (model.twist_response.size() > 0)
    u += twist_c * model.twist_response.col(0) + twist_s * model.twist_response.col(1);
  Points x1 = model.mesh.rest + Eigen::Map<const Points>(u.data(), n, 3);
  rec.ms[kPhysics] = ms_since(clock);

  // Collision and response (self-collision of the inner wall): contacts constrain the solve, CCD re-checks.
  std::fill(state.in_contact.begin(), state.in_contact.end(), 0);
  state.contacts.clear();
  rec.ms[kCollision] = 0.0;
  rec.ms[kResponse] = 0.0;
  if (state.detector && solved && u.allFinite()) {
    collide_and_respond(model, state, u, rec);
    x1 = model.mesh.rest + Eigen::Map<const Points>(u.data(), n, 3);
  }

  // Numerical health: finite values and element orientation; a bad frame keeps the last good state.
  bool finite = solved && u.allFinite();
  int inverted = 0;
  if (finite)
    for (int e = 0; e < model.mesh.tets.rows(); ++e)
      if (physics::tet_volume(x1, model.mesh.tets, e) <= 0.0) ++inverted;
  rec.inverted_elements = inverted;
  rec.numerical_failure = !finite || bad_input;
  rec.bad_input = bad_input;
  if (bad_input) ++state.failures;
  if (model.dynamic) {
    // The committed velocity is the committed motion over the step, v1 = (u1 - u0) / h (contacts included);
    // fixed nodes have none. A failed frame restores the last good state.
    if (finite) {
      for (int dof = 0; dof < 3 * n; ++dof)
        state.dynamic.v[dof] = model.dynamic->is_fixed_dof(dof) ? 0.0 : (u[dof] - state.u[dof]) / model.time_step;
      state.dynamic.u = u;
    } else {
      state.dynamic.u = state.u;
      state.dynamic.v = v_before;
    }
    rec.kinetic_energy = physics::kinetic_energy(*model.dynamic, state.dynamic);
  }
  if (finite) {
    state.x = std::move(x1);
    state.u = std::move(u);
  } else {
    ++state.failures;
  }
  rec.max_displacement = 0.0;
  for (int i = 0; i < n; ++i) rec.max_displacement = std::max(rec.max_displacement, state.u.segment<3>(3 * i).norm());

  // Reaction at each probe point (force-controlled probe in equilibrium: equal and opposite), handed back.
  rec.reactions.clear();
  for (size_t i = 0; i < state.sources.size(); ++i) {
    const Eigen::Vector3d reaction = -state.samples[i].force;
    rec.reactions.push_back(reaction);
    state.sources[i]->feedback(t1, reaction);
  }
  state.frame += 1;
  state.t = t1;
}

}  // namespace lumen::engine
