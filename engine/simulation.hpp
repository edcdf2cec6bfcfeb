#pragma once
// The compiled model (immutable after compile) and the mutable session state; one step per frame.
#include <array>
#include <cstdint>
#include <future>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "collision/surface.hpp"
#include "engine/grasp.hpp"
#include "engine/input.hpp"
#include "engine/instrument_contact.hpp"
#include "engine/report.hpp"
#include "engine/scene.hpp"
#include "physics/compliance.hpp"
#include "physics/fem.hpp"
#include "physics/integrator.hpp"
#include "physics/mesh.hpp"
#include "physics/pair_mesh.hpp"
#include "physics/surface_compliance.hpp"

namespace lumen::engine {

// A point on the organ's surface: up to 3 mesh nodes with barycentric weights, and the triangle it lies on.
using SurfacePoint = physics::LoadPoint;

// Behavioural constants of the frame (named, not bare literals).
// A fixed probe point further than this fraction of the local wall thickness (the distance from its outer-wall
// point to the nearest inner-wall point) from the outer wall is refused.
constexpr double kProbeSnapWallFraction = 0.25;
// Large deformation: a corotational linear solve that takes more PCG iterations than this refactorises the
// warped stiffness (on the second core) for the following solves.
constexpr int kRefactorCgIterations = 5;
// Carried contacts: the augmented Lagrangian's penalty per unit of the walls' mean diagonal stiffness.
constexpr double kCouplingStiffnessScale = 1.0;
// A frame's displacement larger than this many times the organ's rest bounding-box diagonal is not a deformation
// but a failed solve (no organ in a training scene moves ten times its own size): the frame is a numerical failure
// and the last good frame stands. (Collision cannot work on such positions: the CCD's cubic overflows.)
constexpr double kImplausibleDisplacementScale = 10.0;
// A volume mesh's end set spans a plane (and so has an axis to twist about) when the second principal moment of its
// nodes about their centroid is above this fraction of the first (a ring: 1; nodes on a line: 0).
constexpr double kEndPlaneSpread = 1e-6;

// The value at a surface point of a per-node field (positions, or displacements as n x 3): the barycentric sum
// over its nodes.
Eigen::Vector3d point_of(const Eigen::Ref<const Points>& x, const SurfacePoint& sp);
// Nearest point of a surface (positions x, triangles tris) to `p`, brute force over the triangles.
SurfacePoint snap_to_surface(const Points& x, const Tris& tris, const Eigen::Vector3d& p);

// A surface of the mesh drawn every frame: its index in mesh.surfaces and its style.
struct DrawnSurface {
  int surface = -1;
  render::SurfaceStyle style;
};

// Everything fixed for a session: mesh, fixed and prescribed nodes, the integrator (with its factorisations and
// precomputed responses), probe attachment points, collision topology. Immutable after compile_model.
struct Model {
  // What the session reports and runs by (from the scene, decided when it compiled).
  std::string name;                                // the scene's name
  std::string scene_path;                          // the file it came from
  int frames = 120;                                // the scene's frame count
  double fps = 40.0;                               // frames per second of simulated time
  MaterialModel material = MaterialModel::kLinear; // elastic model
  ElementType element = ElementType::kTet4;        // element of the volume mesh
  SolverType solver = SolverType::kQuasiStatic;    // quasi-static or one implicit step per frame
  Tangent tangent = Tangent::kWarped;              // corotational quasi-static: the linear steps' operator
  SolveMethod method = SolveMethod::kPcg;          // corotational quasi-static: PCG or chord steps
  CollisionSpec collision;                         // self-collision and response parameters
  RenderSpec render;                               // image size, camera, force arrows
  TwistSpec twist;                                 // the twisted ring's angle track (prescribed motion below)
  physics::TetMesh mesh;
  std::vector<int> fixed_nodes;                    // node ids held (at rest, or at their prescribed motion)
  std::vector<SurfacePoint> probe_points;          // per probe, where its (fixed) point attaches
  std::vector<bool> probe_held;                    // per probe: displacement-driven (held at its target)
  std::vector<int> held_probes;                    // indices of the displacement-driven probes
  // Prescribed motion (the twisted end ring): u = (cos theta - 1) P + sin theta Q on the ring, basis [P Q]
  // (3n x 2, metres), P = X - c - a (a . (X - c)), Q = a x (X - c); c the ring's centre, a the centreline tangent.
  physics::PrescribedMotion prescribed;
  Eigen::Vector3d twist_center = Eigen::Vector3d::Zero();  // c, metres
  Eigen::Vector3d twist_axis = Eigen::Vector3d::UnitZ();   // a, unit (start -> stop direction)
  int n_elements = 0;                              // volume elements (tets; tet10: the quadratic ones)
  // How the mesh was built: its source, the generator's time, the rings a swept tube's bend clamp reduced, and
  // the end rings (start, stop: centreline frame and wall radii) that twists turn.
  MeshType mesh_type = MeshType::kHollowCylinder;
  double mesh_build_ms = 0.0;
  int clamped_rings = 0;
  int clamped_vertices = 0;    // a surface wall's vertices whose offset is less than the thickness
  int untangled_vertices = 0;  // a surface wall's surface vertices moved to untangle planar fold-overs
  double remesh_target_edge = 0.0;  // a surface wall's or pair's target edge, metres (0: the files' triangles)
  int remesh_file_triangles = 0;    // with a target edge: the file's (a pair's: both files') triangles before
  double remesh_ms = 0.0;           // with a target edge: the remeshing's time, milliseconds
  // The mesh source's file: a volume mesh's, a surface wall's surface, a swept tube's radius surface, a surface
  // pair's inner surface; "" otherwise.
  std::string mesh_file;
  // A surface pair's outer surface file, its mesher, the mesher's time (ms), the nodes it added inside the wall and
  // the time reading and checking both surfaces took (ms).
  std::string mesh_outer_file;
  physics::PairMesher pair_mesher = physics::PairMesher::kGmsh;  // the one that made the mesh
  std::string gmsh_failure;  // mesher "auto": gmsh's failure when Netgen made the mesh instead
  double mesher_ms = 0.0;
  int mesher_added_nodes = 0;
  double surface_check_ms = 0.0;
  std::array<physics::TubeRing, 2> end_rings;
  // The organ's walls as indices into mesh.surfaces, resolved from their names when the scene compiles.
  int inner_surface = -1;                          // the lumen wall: self-collision, framing, surface export
  int outer_surface = -1;                          // the outer wall: where probes attach
  std::vector<DrawnSurface> drawn;                 // what the renderer draws of the mesh, outermost first
  std::unique_ptr<physics::Integrator> integrator;  // chosen once from material.model and solver.type
  std::vector<int> inner_nodes;                    // node ids on the inner wall (sorted)
  Tris collision_tris;                             // walls that self-collide: inner (+ outer), n x 3 node ids
  // Their collision surface (edges, adjacency, BVH topology over the rest positions), shared by every state;
  // null when self-collision is off.
  std::shared_ptr<const collision::CollisionSurface> collision_surface;
  std::vector<int> collision_nodes;                // their node ids (sorted): the contact compliance's nodes
  // Nodes the renderer reads (the drawn surfaces', the probes' and the centreline camera's rings'; sorted): the
  // contact compliance keeps their rows, so that what is drawn is exact before the interior is (State::pending).
  std::vector<int> view_nodes;
  // The contact compliance's budget for whole-mesh columns of its nodes, bytes (tests lower it to take the
  // back-substitution path on small meshes).
  long compliance_mesh_column_bytes = physics::SurfaceCompliance::kMeshColumnBytes;
  // Instruments (scene key "instruments"): their parts, flattened as collision surfaces, and the organ surface they
  // touch: the outer and the inner wall (n x 3 node ids), whose nodes are then all in collision_nodes.
  std::vector<CompiledInstrument> instruments;
  std::vector<ToolPart> tool_parts;
  Tris tool_target_tris;
  std::shared_ptr<const collision::CollisionSurface> tool_target_surface;  // null without instruments
  int scope_instrument = -1;  // index into instruments of the one the endoscope camera rides on (-1: none)
  // render.camera {"centreline": ...} (render.centreline_flight): the swept tube's centreline frames and their arc
  // lengths (the ones its rings are swept with), which the camera flies along, and the narrowest lumen radius of
  // the rings along the flight (metres; the renderer's lumen radius: its near plane and head light).
  std::vector<physics::CentrelineFrame> flight_frames;
  std::vector<double> flight_arc;
  double flight_lumen_radius = 0.0;
  // The tube's rings, which the camera follows as the lumen deforms: each ring's arc length (metres, increasing)
  // and its inner-wall nodes (flight_ring_inner: rings x flight_ring_around node ids, ring-major).
  std::vector<double> flight_ring_s;
  std::vector<int> flight_ring_inner;
  int flight_ring_around = 0;
  // collision.coupling "carried": the augmentation penalty of the contacts carried into the corotational solve,
  // kCouplingStiffnessScale times the mean diagonal of K over the colliding walls' free DOFs, N/m (0 otherwise).
  double coupling_stiffness = 0.0;
  // collision.coupling "solved": each response round solves the contacts inside the integrator's equilibrium
  // (Integrator::solve_with_contacts), to the solve's tolerance (solver.tolerance).
  bool contacts_in_solve = false;
  double equilibrium_tolerance = 0.0;
  double time_step = 0.025;                        // 1 / fps, seconds
  double budget_ms = 25.0;                         // 1000 / fps
  double compile_seconds = 0.0;                    // wall time to build the model
  // kImplausibleDisplacementScale times the rest mesh's bounding-box diagonal, metres: a node displaced further is
  // a numerical failure.
  double max_displacement = 0.0;

  const Tris& inner_wall() const { return mesh.surfaces[inner_surface].tris; }
  const Tris& outer_wall() const { return mesh.surfaces[outer_surface].tris; }
  // The factorisation whose inverse is the contact compliance (the integrator's: K, or the implicit step's).
  const physics::StaticSolver& contact_solver() const { return integrator->contact_solver(); }
};

// Build the model of a scene (mesh, assembly, factorisation, precomputation). Throws InputError for scenes
// whose probe points are off the organ, std::runtime_error for numerical failures.
std::unique_ptr<Model> compile_model(const Scene& scene);

// The twist angle at time t (seconds): linear between the track's keys, held before the first and after the last;
// 0 without a twist. Degrees.
double twist_degrees(const TwistSpec& twist, double t);
// The prescribed motion's coefficients at a twist angle (degrees): (cos theta - 1, sin theta), or none.
Eigen::VectorXd twist_coefficients(const Model& model, double degrees);
// The twisted ring's prescribed displacement at an angle (degrees): R(theta) (X - c) + c - X on its nodes, 0 on
// every other node, 3 n_nodes, metres.
Eigen::VectorXd twist_displacement(const Model& model, double degrees);

// The session's input sources, one per probe in the scene's order (scripted tracks, replays, devices), and one pose
// source per instrument: owned by the session, apart from the model and from the physics state.
struct Inputs {
  std::vector<std::unique_ptr<InputSource>> sources;
  std::vector<std::unique_ptr<PoseSource>> instruments;
};
// Refuses (InputError naming the scene file, the key and the device) an instrument driven only by a device: only
// `lumen serve` (engine/serve.hpp, with make_device_inputs of engine/device.hpp) has a device to feed it.
Inputs make_inputs(const Scene& scene);
// The pose source of instrument i from its track or replay (InputError for a device-only instrument, as above).
std::unique_ptr<PoseSource> make_pose_source(const Scene& scene, size_t i);

// What a frame's commit adds to its record (FrameRecord's fields of the same names). A pipelined frame
// (State::pipeline_interior) commits during the next one: its fields wait in PendingFrame::committed until the
// session files them into the frame's record (file_commits).
struct CommitRecord {
  int frame = 0;                                    // the frame committed (1-based)
  int inverted_elements = 0;
  double kinetic_energy = 0.0;
  double max_displacement = 0.0;                    // metres
  std::vector<Eigen::Vector3d> probe_displacement;  // one per probe, metres
  void apply_to(FrameRecord& rec) const;
};

// A frame whose whole-mesh correction's interior is solving on a second thread
// (SurfaceCompliance::complete_interior): its free motion (3n, metres), what its commit needs, and the solve.
struct InteriorInFlight {
  int frame = 0;                          // 1-based
  Eigen::VectorXd u_free;
  std::vector<SurfacePoint> load_points;  // where its probes attached (the next frame may move them)
  std::future<Eigen::VectorXd> interior;  // valid() until the frame commits
};

// The frame between step_begin() and step_end().
struct PendingFrame {
  bool solved = false;     // the prediction was usable (the frame commits its motion)
  bool open = false;       // between step_begin() and step_end()
  // A deferred interior: the free motion and the whole-mesh correction, exact on the colliding and view nodes only
  // (3n each, metres), as the response leaves them for step_begin() to launch.
  Eigen::VectorXd u_free, du;
  // The launched solve: step_end() commits it, or with State::pipeline_interior the next frame does (settle()).
  InteriorInFlight in_flight;
  std::vector<CommitRecord> committed;  // pipelined frames committed, not yet filed into their records
};

// The walls' proximity reference for the frames' first detections (collision.detection "restricted"): the sweep of
// the last full first detection, which ran at the near gap, and its wall feature pairs found within it. Every other
// wall pair stayed farther apart than near_gap all along that sweep, so a later sweep need test only those pairs and
// the pairs whose vertices moved relative to each other since it by at least near_gap minus the later gap
// (collision::MoveFilter). A fact about positions only: it stays true whatever the frames do after.
struct ProximityReference {
  Points x0, x1;                    // the sweep, n_nodes x 3, metres (empty: none yet)
  double near_gap = 0.0;            // metres
  collision::NearFeatures near;     // the wall feature pairs within near_gap
  long overlaps = 0;                // leaf-box overlaps of that full detection (what a restricted one is weighed against)
  bool valid() const { return x0.rows() > 0; }
};

// The session's mutable state.
struct State {
  int frame = 0;        // frames done
  double t = 0.0;       // simulated time, seconds
  Points x;             // positions at the end of the last good frame, n_nodes x 3, metres
  physics::SimState sim;        // displacement u and velocity v from rest (3 n_nodes each), the one simulation state
  physics::IntegratorWork work; // the integrator's warm starts between frames
  std::vector<ProbeSample> samples;                   // this frame's probe loads, one per probe
  std::vector<SurfacePoint> load_points;              // where each probe attaches this frame (a moving one: snapped)
  std::vector<std::uint8_t> in_contact;               // per node, 1 when part of a contact this frame
  std::unique_ptr<collision::CollisionWorkspace> detector;  // BVH refit workspace (the surface is the model's)
  std::vector<collision::Contact> contacts;           // this frame's contacts (first detection)
  std::vector<std::uint8_t> recheck_flags;            // the restricted re-check's flagged wall nodes (scratch)
  ProximityReference proximity;                       // the first detections' reference (collision.detection)
  std::unique_ptr<physics::SurfaceCompliance> compliance;  // contact compliance on the colliding walls
  std::vector<collision::Contact> active;             // contacts held at the end of the last frame (warm start)
  std::vector<double> active_lambda;                  // their multipliers at the end of the last frame, newtons
  // coupling "carried": each held contact's whole multiplier (the solve's and the response's), newtons; and the
  // force this frame's solve gave each of them (in the order of `active` at the frame's start), newtons.
  std::vector<double> active_total;
  Eigen::VectorXd carried_lambda;
  Eigen::VectorXd last_correction;                    // last frame's contact correction u - u_free, 3n, metres
  // Instruments: each one's pose at the end of the last frame (where it really ended: short of its target when
  // the fallback stopped the frame) and at this frame's target; per tool part, its points at both.
  std::vector<Pose> tool_pose, tool_pose_target;
  std::vector<Points> tool_points, tool_target;
  bool tools_placed = false;                          // tool_pose holds the poses at t = 0 or a frame's end
  std::vector<HeldContact> tool_active;               // tool contacts held at the end of the last frame
  std::vector<double> tool_active_lambda;             // their multipliers, newtons
  std::unique_ptr<collision::CollisionWorkspace> organ_tool_workspace;  // the organ side of detect_pair
  std::vector<std::unique_ptr<collision::CollisionWorkspace>> tool_workspaces;  // per tool part
  std::vector<InstrumentRecord> tool_records;         // this frame's instrument records
  // Graspers: each instrument's jaw opening at the last frame's end and this frame's target (radians; 0 without
  // jaws), its grasp, all holds as one for the contact solve, and their forces on the organ this frame (3d, N).
  std::vector<double> tool_opening, tool_opening_target;
  std::vector<GraspHold> grasps;
  GraspHolds grasp_holds;
  Eigen::VectorXd grasp_force;
  int failures = 0;                                   // frames where the last good state was kept
  // Solve the whole-mesh correction's interior on a second thread between step_begin() and step_end() (a session
  // that renders sets it: the render overlaps the solve), when it would back-substitute and the view rows are kept.
  bool defer_interior = false;
  // With defer_interior, leave the interior solving past step_end() until the next frame's response is done
  // (settle()), so that it overlaps the next frame's physics and collision as well. Only for an integrator that
  // predicts from the loads alone: until it commits, state.x and state.sim are exact only on the colliding and
  // drawn nodes (all that the next frame reads before settle()), and its record's commit fields are filed late (by
  // the caller: file_commits; run_session does).
  bool pipeline_interior = false;
  PendingFrame pending;  // (last: destroyed first, waiting for a solve in flight)
};

State make_state(const Model& model);

// The probes' current forces (state.samples) as a nodal force vector, 3 n_nodes, newtons.
Eigen::VectorXd nodal_loads(const Model& model, const State& state);

// Advance one frame, in named stages: sample inputs; predict (the integrator's free motion with the probes'
// loads and the prescribed motion at the end of the frame); collide and respond (self-collision on the
// integrator's contact compliance); commit (or keep the last good frame on numerical failure); feed back the
// reactions. Fills everything in `rec` but the render and total times.
// `inputs` holds one source per probe of the model.
void step(const Model& model, Inputs& inputs, State& state, FrameRecord& rec);
// step() in two halves around the render: step_begin() runs the stages and leaves state.x exact on every node the
// renderer reads (Model::view_nodes) and state.frame, state.t at the frame's end; with state.defer_interior it may
// leave the whole-mesh correction's interior solving on a second thread. step_end() joins it, commits the frame
// and feeds the reactions back. Between the two, nothing may use the model's solvers; step() is both at once.
void step_begin(const Model& model, Inputs& inputs, State& state, FrameRecord& rec);
void step_end(const Model& model, Inputs& inputs, State& state, FrameRecord& rec);
// Commit a frame whose interior is still solving (State::pipeline_interior), after waiting for the solve; its
// commit's fields go to state.pending.committed. Returns the milliseconds waited (0 when nothing was in flight).
// The frames call it once their response is done; a session calls it before anything reads the whole state.
double settle(const Model& model, State& state);
// Moves the commit fields of state.pending.committed into the records of their frames among frames[0, n) (matched
// by frame number); a commit of a frame not there is a logic_error.
void file_commits(State& state, FrameRecord* frames, size_t n);

}  // namespace lumen::engine
