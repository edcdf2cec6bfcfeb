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
  std::unique_ptr<physics::CorotationalModel> corotational;  // material.model "corotational" (else null)
  std::vector<int> inner_nodes;                       // node ids on the inner wall (sorted)
  double budget_ms = 25.0;                            // 1000 / fps
  double compile_seconds = 0.0;                       // wall time to build the model
};

// Build the model of a scene (mesh, assembly, factorisation, precomputation). Throws InputError for scenes
// whose probe points are off the organ, std::runtime_error for numerical failures.
std::unique_ptr<Model> compile_model(const Scene& scene);

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
  int failures = 0;                                   // frames where the last good state was kept
};

State make_state(const Model& model);

// The probes' current forces (state.samples) as a nodal force vector, 3 n_nodes, newtons.
Eigen::VectorXd nodal_loads(const Model& model, const State& state);

// Advance one frame: sample inputs, solve, detect and resolve self-collision, commit (or keep the last good
// frame on numerical failure). Fills everything in `rec` but the render and total times.
void step(const Model& model, State& state, FrameRecord& rec);

}  // namespace lumen::engine
