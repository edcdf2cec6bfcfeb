#pragma once
// Scene description (JSON, SI units) and its validating loader.
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "engine/instrument.hpp"
#include "engine/pose_track.hpp"
#include "engine/surface_pair.hpp"
#include "engine/wall_growth.hpp"
#include "physics/mesh.hpp"
#include "physics/swept_tube.hpp"
#include "physics/volume_mesh.hpp"
#include "render/renderer.hpp"

namespace lumen::engine {

// A scene or input file was refused; the message names the file, the key path and the value.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// What a probe prescribes: the force at its point (force-driven), or the displacement of its point from rest
// (displacement-driven, as a position-controlled haptic device: the engine solves for the force and hands it
// back as the reaction, contacts included).
enum class ProbeDrive { Force, Displacement };

// One key of a scripted probe track: the force (newtons) or displacement (metres) reached at time t, linear
// in between.
struct TrackKey {
  double t = 0.0;                                   // seconds
  Eigen::Vector3d value = Eigen::Vector3d::Zero();  // newtons (force) or metres (displacement)
};

// A probe: a point on the organ's surface and where its force comes from.
struct ProbeSpec {
  std::string name;                                 // for reports; defaults to "probe<i>"
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  // metres, snapped to the nearest outer-wall point
  ProbeDrive drive = ProbeDrive::Force;             // what the track keys give
  std::vector<TrackKey> track;                      // scripted key frames (source "track")
  std::string replay;                               // recorded CSV (source "replay"), absolute path
};

// Scene choices, decided once by the parser (no string compares past it). Each has its JSON names, in order.
enum class MaterialModel { kLinear, kCorotational };  // "linear" (prefactorised, the paper's) | "corotational"
enum class ElementType { kTet4, kTet10 };             // "tet4" | "tet10"
enum class SolverType { kQuasiStatic, kDynamic };     // "quasi_static" | "dynamic"
enum class ResponseKind { kPaper, kConstraint };      // "paper" | "constraint"
enum class LcpSolver { kActiveSet, kNncg };           // "active_set" | "nncg"
enum class Recheck { kRestricted, kFull };            // "restricted" | "full"
enum class Detection { kRestricted, kFull };          // "restricted" | "full"
enum class ContactCoupling { kCorrect, kCarried, kSolved };  // "correct" | "carried" | "solved"
enum class EquilibriumHessian { kLagged, kWarpedRest };       // "lagged" | "warped_rest"
enum class Tangent { kWarped, kProjected, kExact };  // "warped" | "projected" | "exact"
enum class SolveMethod { kPcg, kChord };              // "pcg" | "chord"
enum class TwistEnd { kNone, kStart, kStop };         // (no twist) | "start" | "stop"
enum class NodeSetName { kEnds, kStart, kStop };      // "ends" | "start" | "stop"
// "hollow_cylinder" | "swept_tube" | "volume" | "surface_wall" | "surface_pair"
enum class MeshType { kHollowCylinder, kSweptTube, kVolume, kSurfaceWall, kSurfacePair };
// The JSON name of a choice (what the scene file says and report.json repeats).
const char* name_of(MaterialModel v);
const char* name_of(ElementType v);
const char* name_of(SolverType v);
const char* name_of(ResponseKind v);
const char* name_of(LcpSolver v);
const char* name_of(Recheck v);
const char* name_of(Detection v);
const char* name_of(ContactCoupling v);
const char* name_of(Tangent v);
const char* name_of(SolveMethod v);
const char* name_of(EquilibriumHessian v);
const char* name_of(TwistEnd v);
const char* name_of(MeshType v);
const char* name_of(render::CameraPreset v);

// A set of nodes held still (key "fixed"): a named node set ("ends", "start", "stop"), the nodes inside a box
// ({"box": [[x0, y0, z0], [x1, y1, z1]]}, corners in metres, inclusive), the nodes on the normal's side of a
// plane ({"plane": {"point": [...], "normal": [...]}}, inclusive), or (a swept tube only) the outer-wall nodes whose
// nearest centreline point lies in an arc-length interval ({"near_centreline": [s0, s1]}, in mesh.units along the
// whole centreline file, inclusive).
enum class FixedKind { kNamed, kBox, kPlane, kNearCentreline };
struct FixedSpec {
  FixedKind kind = FixedKind::kNamed;
  NodeSetName name = NodeSetName::kEnds;          // kNamed
  Eigen::Vector3d a = Eigen::Vector3d::Zero();    // kBox: the low corner; kPlane: a point on the plane (metres)
  Eigen::Vector3d b = Eigen::Vector3d::Zero();    // kBox: the high corner; kPlane: the unit normal
  double s0 = 0.0, s1 = 0.0;                      // kNearCentreline: the interval, metres of arc length, s0 < s1
  std::string given;                              // the entry as the scene gives it (JSON), for messages
  FixedSpec() = default;
  FixedSpec(NodeSetName n) : name(n) {}  // a named set (implicit, so a list of names reads as before)
};

struct MaterialSpec {
  MaterialModel model = MaterialModel::kLinear;  // prefactorised linear (the paper's) or corotational
  double young_modulus = 5000.0;  // pascals
  double poisson_ratio = 0.45;    // (-1, 0.5)
  double density = 1050.0;        // kg / m^3
};

struct RenderSpec {
  int width = 640, height = 480;   // pixels, even
  render::CameraPreset camera = render::CameraPreset::Diagonal;  // side | diagonal | endoscope
  // render.camera {"endoscope": NAME}: the endoscope rides on that instrument, its eye at the tip looking out of
  // it (along the instrument's -y), the instrument itself not drawn ("": on the lumen axis).
  std::string scope_instrument;
  // render.camera {"centreline": {"from": s0, "to": s1}} (a swept tube only): the endoscope flies along the tube's
  // centreline from arc length s0 to s1 (metres along the whole centreline file, within mesh.range) over the
  // session's frames, looking along the direction of travel (engine/session.hpp, centreline_camera).
  bool centreline_flight = false;
  double flight_from = 0.0, flight_to = 0.0;  // metres of arc length, from != to
  bool video = false;               // write DIR/video.mp4 by default
  double force_scale = 1.0;         // arrow length per newton, metres / N
};

// Default of collision.max_contact_rows: ten times the most contacts any shipped scene holds (378).
inline constexpr int kDefaultMaxContactRows = 4000;

struct CollisionSpec {
  bool self = false;               // inner-wall self-collision on/off
  int kdop = 26;                   // 6, 14, 18, 26
  ResponseKind response = ResponseKind::kConstraint;
  double gap = 1e-4;               // minimum separation, metres
  int max_iterations = 8;          // response/re-check rounds before the safe fallback
  // Most contacts a frame's response holds: past it the frame takes the safe fallback instead of solving (a tool
  // driven deep through the wall in one frame makes thousands, whose dense LCP would take seconds and gigabytes).
  int max_contact_rows = kDefaultMaxContactRows;
  // Walls that take part in self-collision: the inner wall only (the paper's, the default), or also the outer
  // wall ("outer") when a scene folds the organ so that its outside meets itself.
  bool outer_wall = false;         // key "surfaces": ["inner"] | ["inner", "outer"]
  // The constraint response's LCP solver (key "lcp"): "active_set" (exact: active set on columns computed on
  // demand, Lemke's pivoting as its fallback) or "nncg" (iterative, for many contacts: all of the coupling
  // matrix, warm-started from last frame's multipliers, at most lcp_sweeps sweeps; its residual is reported).
  LcpSolver lcp = LcpSolver::kActiveSet;
  int lcp_sweeps = 200;            // "nncg": sweep budget per solve, >= 2
  // The response rounds' re-check of the corrected motion (key "recheck"): "restricted" (the default: only the
  // wall features with a vertex the correction moved, since the first detection, by at least a quarter of the
  // difference of the two gaps, or with a vertex in one of its contacts; the others provably stay clear) or
  // "full" (every feature again: the twin the restricted one is tested against, bit for bit).
  Recheck recheck = Recheck::kRestricted;
  // The frame's first detection of the walls (key "detection"): "restricted" (the default: only the wall features
  // near each other on the last full detection, which ran at a wider gap, or whose vertices moved relative to each
  // other since its sweep by at least the two gaps' difference less a spare; the others stay clear; a full one again
  // once the restricted one does 30 % of its work) or "full" (every feature every frame: the twin the restricted
  // one is tested against, bit for bit).
  Detection detection = Detection::kRestricted;
  // How the contacts meet a corotational quasi-static solve (key "coupling"): "correct" (the contact-free
  // solution is corrected on the rest compliance) or "carried" (the last frame's contacts, re-linearised at the
  // frame's start, enter the nonlinear equilibrium by an augmented Lagrangian; the response then corrects what
  // is left, and the sum of both multipliers is carried to the next frame) or "solved" (the contacts inside the
  // corotational equilibrium: each response round minimises the corotational potential subject to its rows,
  // physics::solve_contact_equilibrium, so the frame ends in equilibrium with its contacts on the model itself).
  ContactCoupling coupling = ContactCoupling::kCorrect;
  // coupling "solved": the most QP steps of one response round (key "equilibrium_steps"), >= 1, and their fixed
  // Hessian (key "equilibrium_hessian"): "lagged" (the warped stiffness factorised at the end of the last contact
  // solve, on the background thread) or "warped_rest" (the rest stiffness turned by each node's rotation).
  int equilibrium_steps = 20;
  EquilibriumHessian equilibrium_hessian = EquilibriumHessian::kLagged;
  // coupling "solved" on the lagged Hessian: the work bound (back-substitutions) of the free prediction of a frame
  // after a contact frame, which only gives the detection its trial motion (the rounds start from the last end);
  // 0 = solver.max_back_substitutions, else >= 2 (key "prediction_back_substitutions").
  int prediction_back_substitutions = 0;
};

// How a frame is solved: quasi-statically (equilibrium with the frame's loads) or by one implicit dynamic step.
struct SolverSpec {
  SolverType type = SolverType::kQuasiStatic;  // or dynamic (backward Euler, lumped mass, step 1 / fps)
  double tolerance = 1e-3;            // corotational nonlinear solve: relative residual, (0, 1)
  int max_iterations = 20;            // its outer iterations, >= 1
  // Corotational: the lagged warped factorisation runs on a second core while the frames go on (true), or inside
  // the solve that asks for it (false: slower frames, but a session gives the same result on every run; with the
  // background thread the iteration where it lands depends on timing).
  bool background_factorisation = true;
  // Corotational quasi-static: past steps the fixed-point iterations mix (Anderson acceleration; 0 = off), 0..20.
  int anderson_depth = 5;
  // Corotational quasi-static: the linear steps' operator (physics::CorotationalTangent).
  Tangent tangent = Tangent::kWarped;
  // Corotational quasi-static: the linear steps (physics::CorotationalMethod): PCG on the operator, or one
  // back-substitution on the lagged factorisation (chord).
  SolveMethod method = SolveMethod::kPcg;
  // Corotational quasi-static: the most back-substitutions one frame's solve may take (its work bound; the frame
  // is then reported unconverged and the next one goes on from its iterate); 0 = no bound.
  int max_back_substitutions = 0;
  double rayleigh_mass = 0.0;         // dynamic: Rayleigh alpha (C = alpha M + beta K), 1/s, >= 0
  double rayleigh_stiffness = 0.0;    // dynamic: Rayleigh beta, s, >= 0
};

// One key of a twist track: the angle reached at time t, linear in between, held after the last key.
struct TwistKey {
  double t = 0.0;        // seconds
  double degrees = 0.0;  // rotation of the end ring about the tube axis (right-handed about the centreline
                         // direction from the start end to the stop end)
};

// Elastic supports (key "support"): the organ held by the tissue around it, springs to rest on its outer wall
// (physics/support.hpp), stiffness per unit area and unit displacement; 0 = none. Key "where" limits them to the
// outer-wall nodes that its entries select (the same entries as "fixed": node-set names, boxes, plane sides, arc
// lengths along the centreline), e.g. a colon held by its mesentery along one side only.
struct SupportSpec {
  double stiffness = 0.0;      // N/m^3 (key stiffness_n_per_m3)
  std::vector<FixedSpec> where;  // the selected nodes; empty: the whole outer wall
  bool enabled() const { return stiffness > 0.0; }
};

// One end ring turned about the tube axis (z for a straight tube; the ring-plane normal for a bent one) through
// the ring's centre: its nodes are prescribed u = R(theta) (X - c) + c - X (held, like a fixed end).
struct TwistSpec {
  TwistEnd end = TwistEnd::kNone;
  std::vector<TwistKey> track;  // non-empty when end is set, times strictly increasing
  bool enabled() const { return end != TwistEnd::kNone; }
};

// Where an instrument's pose comes from: key frames ("track"), a recorded pose CSV ("replay"), or only a device
// ("device_name" without a track or replay: only `lumen serve` runs it; `lumen run` and `bench` refuse it).
enum class InstrumentDrive { kTrack, kReplay, kDevice };

// One key of a grasper's jaw opening (track[k].opening): the opening between the jaws reached at time t, radians;
// linear between keys, held before the first and after the last (the shape's opening_angle without keys).
struct OpeningKey {
  double t = 0.0;      // seconds
  double angle = 0.0;  // radians, [0, kMaxOpeningAngle]
};

// Default of grasp.release_margin: how far past the opening it grasped at the commanded opening must go before the
// jaws let go, radians (about 3 degrees: a jitter of the command does not drop the tissue).
inline constexpr double kDefaultReleaseMargin = 0.05;
// Default of grasp.grip_force_n: the normal force each jaw must press on the tissue for the jaws to hold it,
// newtons (a firm pinch of the 5 kPa tube wall; much less than its closing force).
inline constexpr double kDefaultGripForce = 0.01;

// A grasper that grasps (key "grasp"): when its jaws are closing and each presses the tissue with at least
// grip_force_n, they stop at that opening and hold the organ nodes they touch, rigidly in the instrument frame,
// until the commanded opening exceeds the held one by release_margin; the jaws then follow the command again.
struct GraspSpec {
  bool enabled = false;
  double grip_force_n = kDefaultGripForce;         // newtons, > 0
  double release_margin = kDefaultReleaseMargin;  // radians, > 0
};

// A rigid instrument (key "instruments"): its shape, validated (make_instrument accepts it), and its poses.
struct InstrumentSpec {
  std::string name;                   // for reports; defaults to "instrument<i>", unique in the scene
  ShapeSpec shape;                    // built-in shape with its dimensions, or a mesh file (absolute path)
  InstrumentDrive drive = InstrumentDrive::kTrack;
  std::vector<PoseKey> poses;         // track keys or the replay file's poses (organ frame, rotations unit)
  std::string replay;                 // the replay file, absolute path ("" unless drive is kReplay)
  std::string device_name;            // the bridge's device name ("" for none)
  // Device coordinates (metres, after the wire's millimetres are converted) to the organ frame: applies to the
  // device's poses; track and replay poses are in the organ frame already.
  Eigen::Isometry3d to_organ = Eigen::Isometry3d::Identity();
  std::vector<OpeningKey> openings;   // a grasper's commanded jaw opening over time (track keys' "opening")
  GraspSpec grasp;                    // a grasper's key "grasp"
};

// A tet mesh made elsewhere (mesh.type "volume"): its file read, its walls found and the mesh built at load (so
// that every problem with the file is a load error), in metres.
struct VolumeSourceSpec {
  std::string file;                 // absolute path
  physics::WallTags tags;           // mesh.inner_tag / outer_tag (gmsh physical names resolved), or none
  physics::TetMesh mesh;            // physics::make_volume_mesh of the file
};
// A wall grown from a closed surface file (mesh.type "surface_wall", engine/wall_growth.hpp), grown at load.
struct SurfaceWallSource {
  SurfaceWallSpec spec;
  SurfaceWall wall;
};
// A wall between two closed surface files (mesh.type "surface_pair", engine/surface_pair.hpp), tetrahedralised
// at load.
struct SurfacePairSource {
  SurfacePairSpec spec;
  SurfacePair pair;
};
// Where an instrument starts a session (and, driven by a device, waits for its first reading): its track's or
// replay's first pose, or for a device-only instrument the device origin mapped by to_organ.
Pose home_pose(const InstrumentSpec& spec);

// The haptic loop (key "haptics", engine/haptics.hpp): its rate and the device's limits.
struct HapticsSpec {
  double rate_hz = 1000.0;                // loop rate, Hz, in (0, kMaxHapticRateHz]
  double max_force_n = 8.0;               // force saturation, newtons (> 0)
  double max_stiffness_n_per_m = 3000.0;  // the local model's stiffness is clamped to this, N/m (> 0)
  double damping_n_s_per_m = 1.0;         // c, N s/m (>= 0), only while in contact
  double stale_after_s = 0.1;             // the force fades when no fresh model came for this long, seconds (> 0)
  double fade_s = 0.05;                   // ... to zero over this long, seconds (> 0)
};
// The fastest haptic loop a scene may ask for, Hz.
inline constexpr double kMaxHapticRateHz = 10000.0;

struct Scene {
  std::string path;  // the file it was read from
  std::string name;
  // The volume mesh's source (key mesh.type): the generated hollow cylinder (`mesh`) or a tube swept along a
  // centreline file (`swept_tube`, its centreline read, validated and converted to metres at load), a tet mesh
  // file (`volume`: gmsh .msh, VTK .vtu / .vtk), a wall grown from a closed surface file (`surface_wall`), or the
  // volume between two closed surface files tetrahedralised (`surface_pair`).
  MeshType mesh_type = MeshType::kHollowCylinder;
  physics::HollowCylinderSpec mesh;
  physics::SweptTubeSpec swept_tube;
  // Metres per unit of a swept tube's mesh.units: arc lengths given in other keys (fixed near_centreline,
  // render.camera centreline) are in those units too.
  double swept_tube_unit = 1.0;
  // A swept tube's mesh.radius {"from_surface": FILE}: the surface file (absolute path) its radius profile was
  // sampled from at load (engine/surface_radius.hpp), "" otherwise.
  std::string radius_surface;
  VolumeSourceSpec volume;
  SurfaceWallSource surface_wall;
  SurfacePairSource surface_pair;
  // The mesh source's work at load, milliseconds: a volume file read and built, a surface read and sampled or
  // grown into a wall, a surface pair read, checked and tetrahedralised (0 for the generators, which run when the
  // scene compiles).
  double mesh_load_ms = 0.0;
  // Element of the volume mesh (key mesh.element): "tet4" (linear, the paper's) or "tet10" (quadratic,
  // isoparametric; its walls are drawn and collide as each face split into 4 triangles over the edge nodes).
  ElementType element = ElementType::kTet4;
  MaterialSpec material;
  std::vector<FixedSpec> fixed;  // node sets held still
  std::vector<ProbeSpec> probes;
  int frames = 120;
  double fps = 40.0;  // frames per second of simulated time; the budget is 1 / fps
  RenderSpec render;
  CollisionSpec collision;
  SolverSpec solver;
  TwistSpec twist;
  SupportSpec support;
  std::vector<InstrumentSpec> instruments;
  HapticsSpec haptics;
};

// Refuse a path that is a folder or does not exist, as an InputError "PATH: is a folder, not a WHAT" / "PATH: no
// such WHAT" (a folder would otherwise read as empty input).
void require_file(const std::string& path, const std::string& what);

// Read and validate a scene file; throws InputError with "FILE: KEY.PATH: problem (value V)". Every check that
// involves several keys is made here too, so that compiling a parsed scene fails only on numerical grounds.
Scene load_scene(const std::string& path);
// The same from text (path used in messages and to resolve relative replay files).
Scene parse_scene(const std::string& text, const std::string& path);

}  // namespace lumen::engine
