#pragma once
// The compiled model (immutable after compile) and the mutable session state; one step per frame.
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "collision/self_collision.hpp"
#include "engine/input.hpp"
#include "engine/report.hpp"
#include "engine/scene.hpp"
#include "physics/compliance.hpp"
#include "physics/corotational.hpp"
#include "physics/dynamics.hpp"
#include "physics/fem.hpp"
#include "physics/mesh.hpp"

namespace lumen::engine {

// A point on the outer wall: the triangle it lies on and its barycentric weights over that triangle's nodes.
struct SurfacePoint {
  int triangle = -1;                    // row of mesh.outer
  int node[3] = {-1, -1, -1};           // mesh node ids
  double weight[3] = {0.0, 0.0, 0.0};   // barycentric, sum 1
};

// Nearest point of the outer wall (rest positions) to `p`.
SurfacePoint snap_to_surface(const Points& x, const Tris& tris, const Eigen::Vector3d& p);
// Spread a force at a surface point over its triangle's nodes with the barycentric weights: f (3n) += ...
void add_point_load(const SurfacePoint& sp, const Eigen::Vector3d& force, Eigen::VectorXd& f);

// Everything fixed for a session: mesh, material, factorisation, precomputed responses, collision topology.
struct Model {
  Scene scene;
  physics::TetMesh mesh;
  physics::LinearMaterial material;
  std::vector<int> fixed_nodes;                       // node ids held at rest
  std::unique_ptr<physics::StaticSolver> solver;      // K prefactorised (CHOLMOD) on the free DOFs
  std::vector<SurfacePoint> probe_points;             // per probe, where its (fixed) point attaches
  std::unique_ptr<physics::LoadResponse> probe_response;  // K^-1 for unit loads at the fixed probe points
  std::vector<int> held_probes;                       // displacement-driven probes (indices into scene.probes)
  Eigen::MatrixXd hold_stiffness;                     // (P_dd)^-1, 3d x 3d, N/m: forces that move held points
  Eigen::MatrixXd hold_coupling;                      // P_df, 3d x 3m, m/N: held points' motion per probe force
  physics::HeldPoints held;                           // the held probes for the contact solve (empty: none)
  std::unique_ptr<physics::CorotationalModel> corotational;  // material.model "corotational", quasi-static (else null)
  physics::CorotationalOptions corotational_options;  // scene.solver's tolerance and max_iterations (extrapolating)
  // Implicit dynamics (solver.type "dynamic", else null): backward Euler at h = time_step, elastic model from
  // material.model, density from material.density, Rayleigh damping from the solver keys.
  std::unique_ptr<physics::DynamicModel> dynamic;
  // Dynamic: the compliance of one implicit step, A_u = (1 + beta / h) K + (1 + h alpha) M / h^2 (the change of
  // u1 per unit force, K rest stiffness, M lumped mass), prefactorised (CHOLMOD) on the free DOFs: contacts use it.
  std::unique_ptr<physics::StaticSolver> step_solver;
  double time_step = 0.025;                           // 1 / fps, seconds
  // Twist of one end ring (scene.twist): its nodes (also in fixed_nodes) are prescribed
  // u = R(theta) (X - c) + c - X = (cos theta - 1) P + sin theta Q, the columns of twist_basis.
  std::vector<int> twist_nodes;                       // node ids of the turned ring
  Eigen::Vector3d twist_center = Eigen::Vector3d::Zero();  // c, the ring's centre on the centreline, metres
  Eigen::Vector3d twist_axis = Eigen::Vector3d::UnitZ();   // a, unit centreline tangent (start -> stop direction)
  Eigen::MatrixXd twist_basis;     // 3n x 2, metres: P = X - c - a (a . (X - c)), Q = a x (X - c) on the ring, else 0
  Eigen::MatrixXd twist_response;  // linear quasi-static: 3n x 2, metres: the whole mesh's displacement with the
                                   // ring held at each basis column, no load (u = P - K_ff^-1 K_fc P)
  std::vector<int> inner_nodes;                       // node ids on the inner wall (sorted)
  Tris collision_tris;                                // walls that self-collide: inner (+ outer), n x 3 node ids
  std::vector<int> collision_nodes;                   // their node ids (sorted): the contact compliance's nodes
  double budget_ms = 25.0;                            // 1000 / fps
  double compile_seconds = 0.0;                       // wall time to build the model

  // The solver whose inverse is the contact compliance: the implicit step's (dynamic) or K's (quasi-static).
  const physics::StaticSolver& contact_solver() const { return dynamic ? *step_solver : *solver; }
};

// Build the model of a scene (mesh, assembly, factorisation, precomputation). Throws InputError for scenes
// whose probe points are off the organ, std::runtime_error for numerical failures.
std::unique_ptr<Model> compile_model(const Scene& scene);

// The twist angle at time t (seconds): linear between the track's keys, held before the first and after the last;
// 0 without a twist. Degrees.
double twist_degrees(const TwistSpec& twist, double t);
// The twisted ring's prescribed displacement at an angle (degrees): R(theta) (X - c) + c - X on its nodes, 0 on
// every other node, 3 n_nodes, metres.
Eigen::VectorXd twist_displacement(const Model& model, double degrees);

// The session's mutable state.
struct State {
  int frame = 0;        // frames done
  double t = 0.0;       // simulated time, seconds
  Points x;             // positions at the end of the last good frame, n_nodes x 3, metres
  Eigen::VectorXd u;    // displacement from rest, 3 n_nodes, metres
  std::vector<std::unique_ptr<InputSource>> sources;  // one per probe
  std::vector<ProbeSample> samples;                   // this frame's probe loads, one per probe
  std::vector<std::uint8_t> in_contact;               // per node, 1 when part of a contact this frame
  std::unique_ptr<collision::SelfCollision> detector; // refit workspace (topology from the model)
  std::vector<collision::Contact> contacts;           // this frame's contacts (first detection)
  std::unique_ptr<physics::SurfaceCompliance> compliance;  // K^-1 on the inner wall, for the contact solves
  std::vector<collision::Contact> active;             // contacts held at the end of the last frame (warm start)
  Eigen::VectorXd last_correction;                    // last frame's contact correction u - u_free, 3n, metres
  physics::CorotationalState corotational;            // warm start of the corotational solve
  physics::DynamicState dynamic;                      // dynamic: u (= u above) and v, 3 n_nodes each, m and m/s
  int failures = 0;                                   // frames where the last good state was kept
};

State make_state(const Model& model);

// The probes' current forces (state.samples) as a nodal force vector, 3 n_nodes, newtons.
Eigen::VectorXd nodal_loads(const Model& model, const State& state);

// Advance one frame: sample inputs, solve (quasi-static equilibrium, or one backward Euler step of 1 / fps with the
// probes' loads, the twisted ring at its angle at the end of the frame), detect and resolve self-collision (on the
// implicit step's compliance when dynamic, after which v1 = (u1 - u0) / h on the free DOFs), commit (or keep the
// last good frame on numerical failure). Fills everything in `rec` but the render and total times.
void step(const Model& model, State& state, FrameRecord& rec);

}  // namespace lumen::engine
