#include "engine/simulation.hpp"

#include "collision/distance.hpp"
#include "engine/clock.hpp"
#include "engine/mesh_check.hpp"
#include "engine/response.hpp"
#include "physics/quadratic.hpp"
#include "physics/support.hpp"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <Eigen/Eigenvalues>

namespace lumen::engine {
namespace {

using physics::kPi;

}  // namespace

double twist_degrees(const TwistSpec& twist, double t) {
  if (!twist.enabled() || twist.track.empty()) return 0.0;
  size_t i;
  double w;
  bracket_keys(twist.track, t, i, w);
  return w == 0.0 ? twist.track[i].degrees : (1.0 - w) * twist.track[i].degrees + w * twist.track[i + 1].degrees;
}

Eigen::VectorXd twist_coefficients(const Model& model, double degrees) {
  if (model.prescribed.empty()) return Eigen::VectorXd();
  const double theta = degrees * kPi / 180.0;
  return Eigen::Vector2d(std::cos(theta) - 1.0, std::sin(theta));
}

Eigen::VectorXd twist_displacement(const Model& model, double degrees) {
  if (model.prescribed.empty()) return Eigen::VectorXd::Zero(3 * model.mesh.n_nodes());
  return physics::combine_columns(model.prescribed.basis, twist_coefficients(model, degrees));
}

Eigen::Vector3d point_of(const Eigen::Ref<const Points>& x, const SurfacePoint& sp) {
  Eigen::Vector3d q = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) q += sp.weight[k] * x.row(sp.node[k]).transpose();
  return q;
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

namespace {

// ---------------------------------------------------------------------------------------------------------------
// Compile stages

// The centreline camera's path (render.camera {"centreline"}): the tube's centreline frames and arc lengths, and the
// narrowest lumen radius of the rings along the flight (and of the rings on either side of it).
void set_flight(const Scene& scene, const physics::SweptTube& tube, Model& m) {
  const physics::Centreline& c = scene.swept_tube.centreline;
  m.flight_frames = physics::centreline_frames(c);
  m.flight_arc = physics::arc_lengths(c.points);
  const double lo = std::min(scene.render.flight_from, scene.render.flight_to);
  const double hi = std::max(scene.render.flight_from, scene.render.flight_to);
  const std::vector<double>& s = tube.ring_s;
  // The rings from the last at or before lo to the first at or after hi, and every ring between.
  const size_t first = static_cast<size_t>(std::upper_bound(s.begin(), s.end(), lo) - s.begin());
  const size_t last = static_cast<size_t>(std::lower_bound(s.begin(), s.end(), hi) - s.begin());
  double narrowest = std::numeric_limits<double>::infinity();
  for (size_t j = first > 0 ? first - 1 : 0; j <= std::min(last, s.size() - 1); ++j)
    narrowest = std::min(narrowest, tube.rings[j].inner_radius);
  m.flight_lumen_radius = narrowest;
  // Each ring's inner-wall nodes (layer 0), ring-major.
  const int around = scene.swept_tube.segments_around, layers = scene.swept_tube.layers;
  m.flight_ring_s = s;
  m.flight_ring_around = around;
  m.flight_ring_inner.clear();
  for (int j = 0; j < static_cast<int>(s.size()); ++j)
    for (int i = 0; i < around; ++i)
      m.flight_ring_inner.push_back(physics::structured_tube_node(around, layers, i, j, 0));
}

// The generated linear mesh of the scene's mesh source, with the build facts kept in the model (generator time,
// clamped rings, end rings).
physics::TetMesh generate_mesh(const Scene& scene, Model& m) {
  if (scene.mesh_type == MeshType::kSweptTube) {
    physics::SweptTube tube = physics::make_swept_tube(scene.swept_tube);
    m.clamped_rings = tube.clamped_rings;
    m.mesh_file = scene.radius_surface;
    m.end_rings = {tube.rings.front(), tube.rings.back()};
    if (scene.render.centreline_flight) set_flight(scene, tube, m);
    return std::move(tube.mesh);
  }
  // A volume mesh, a surface wall or a surface pair was built at load (no end rings: it has no twist).
  if (scene.mesh_type == MeshType::kVolume) {
    m.mesh_file = scene.volume.file;
    return scene.volume.mesh;
  }
  if (scene.mesh_type == MeshType::kSurfaceWall) {
    m.mesh_file = scene.surface_wall.spec.file;
    m.clamped_vertices = scene.surface_wall.wall.clamped_vertices;
    m.untangled_vertices = scene.surface_wall.wall.untangled_vertices;
    m.remesh_target_edge = scene.surface_wall.spec.target_edge;
    m.remesh_file_triangles = scene.surface_wall.wall.file_triangles;
    m.remesh_ms = scene.surface_wall.wall.remesh_ms;
    return scene.surface_wall.wall.mesh;
  }
  if (scene.mesh_type == MeshType::kSurfacePair) {
    m.mesh_file = scene.surface_pair.spec.inner_file;
    m.mesh_outer_file = scene.surface_pair.spec.outer_file;
    m.pair_mesher = scene.surface_pair.pair.mesher;
    m.gmsh_failure = scene.surface_pair.pair.gmsh_failure;
    m.mesher_ms = scene.surface_pair.pair.mesher_ms;
    m.mesher_added_nodes = scene.surface_pair.pair.added_nodes;
    m.surface_check_ms = scene.surface_pair.pair.check_ms;
    m.remesh_target_edge = scene.surface_pair.spec.target_edge;
    m.remesh_file_triangles = scene.surface_pair.pair.inner_triangles + scene.surface_pair.pair.outer_triangles;
    m.remesh_ms = scene.surface_pair.pair.remesh_ms;
    return scene.surface_pair.pair.mesh;
  }
  const physics::HollowCylinderSpec& c = scene.mesh;
  m.end_rings = {physics::TubeRing{physics::hollow_cylinder_frame(c, 0.0), c.inner_radius, c.outer_radius},
                 physics::TubeRing{physics::hollow_cylinder_frame(c, c.length), c.inner_radius, c.outer_radius}};
  return physics::make_hollow_cylinder(c);
}

// The volume mesh the engine works on, and (tet10) the quadratic mesh its stiffness comes from: the engine's mesh
// is then the quadratic mesh's linear view (all nodes, each element split into 8 tets, walls split over the edge
// nodes). Sets m.n_elements (the volume elements) and m.mesh_build_ms (generating it, the quality check not
// included). An inverted or zero-volume tet is refused (InputError naming it).
physics::TetMesh build_mesh(const Scene& scene, std::unique_ptr<physics::QuadraticMesh>& quadratic, Model& m) {
  const auto t0 = Clock::now();
  m.mesh_type = scene.mesh_type;
  physics::TetMesh linear = generate_mesh(scene, m);
  m.n_elements = static_cast<int>(linear.tets.rows());
  m.mesh_build_ms = ms_since(t0) + scene.mesh_load_ms;
  require_valid_tets(linear, scene.path);
  if (scene.element != ElementType::kTet10) return linear;
  const auto t1 = Clock::now();
  // Isoparametric on the generated cylinder (edge nodes on its curved walls); straight-sided on every other mesh
  // (edge nodes at edge midpoints: the walls as faceted as the 4-node mesh's).
  quadratic = std::make_unique<physics::QuadraticMesh>(scene.mesh_type == MeshType::kHollowCylinder
                                                           ? physics::make_quadratic_cylinder(linear, scene.mesh)
                                                           : physics::make_quadratic(linear));
  physics::TetMesh view = physics::linear_view(*quadratic);
  m.mesh_build_ms += ms_since(t1);
  require_valid_tets(view, scene.path);
  return view;
}

// Index of the mesh's surface of that name (the generator's names; a missing one is a bug, not a user's mistake).
int surface_index(const physics::TetMesh& mesh, const char* name) {
  const physics::MeshSurface* s = physics::find_named(mesh.surfaces, name);
  if (!s) throw std::logic_error(std::string("compile_model: the mesh has no surface \"") + name + "\"");
  return static_cast<int>(s - mesh.surfaces.data());
}

// The walls by role, and what is drawn of the mesh (outermost first: outer wall, end caps, lumen wall).
void resolve_walls(Model& m) {
  m.inner_surface = surface_index(m.mesh, physics::kInnerWall);
  m.outer_surface = surface_index(m.mesh, physics::kOuterWall);
  m.drawn = {{m.outer_surface, render::SurfaceStyle::outer_wall()},
             {surface_index(m.mesh, physics::kEndCaps), render::SurfaceStyle::wall_ends()},
             {m.inner_surface, render::SurfaceStyle::inner_wall()}};
}

void sort_unique(std::vector<int>& ids) {
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
}

// The mesh nodes a box or plane entry of "fixed" selects (rest positions, inclusive).
std::vector<int> selected_nodes(const FixedSpec& f, const Points& rest) {
  std::vector<int> nodes;
  for (int v = 0; v < rest.rows(); ++v) {
    const Eigen::Vector3d x = rest.row(v).transpose();
    const bool in = f.kind == FixedKind::kBox ? ((x.array() >= f.a.array()).all() && (x.array() <= f.b.array()).all())
                                              : (x - f.a).dot(f.b) >= 0.0;
    if (in) nodes.push_back(v);
  }
  return nodes;
}

// The outer-wall nodes whose nearest point on the swept tube's centreline (the whole file's polyline) lies in the
// entry's arc-length interval [s0, s1] (inclusive).
std::vector<int> near_centreline_nodes(const FixedSpec& f, const physics::Centreline& c, const Model& m) {
  const std::vector<double> arc = physics::arc_lengths(c.points);
  std::vector<int> outer(m.outer_wall().data(), m.outer_wall().data() + m.outer_wall().size());
  sort_unique(outer);
  std::vector<int> nodes;
  for (int v : outer) {
    const double s = physics::nearest_arc_length(c.points, arc, m.mesh.rest.row(v).transpose());
    if (s >= f.s0 && s <= f.s1) nodes.push_back(v);
  }
  return nodes;
}

// The nodes one node selection selects ("ends": both end sets; a box, a plane side or an arc-length interval of the
// centreline: the nodes it selects, at least one, or an InputError naming `key`, e.g. "fixed[2]").
std::vector<int> selection_nodes(const Scene& scene, const Model& m, const FixedSpec& f, const std::string& key) {
  std::vector<int> nodes;
  if (f.kind == FixedKind::kNamed) {
    if (f.name == NodeSetName::kEnds || f.name == NodeSetName::kStart) {
      const std::vector<int>& ids = m.mesh.node_set(physics::kStartEnd);
      nodes.insert(nodes.end(), ids.begin(), ids.end());
    }
    if (f.name == NodeSetName::kEnds || f.name == NodeSetName::kStop) {
      const std::vector<int>& ids = m.mesh.node_set(physics::kStopEnd);
      nodes.insert(nodes.end(), ids.begin(), ids.end());
    }
    return nodes;
  }
  if (f.kind == FixedKind::kNearCentreline) {
    nodes = near_centreline_nodes(f, scene.swept_tube.centreline, m);
    if (nodes.empty())
      throw InputError(scene.path + ": " + key + ": selects no outer-wall node (none has its nearest "
                       "centreline point in the interval) (value " + f.given + ")");
    return nodes;
  }
  nodes = selected_nodes(f, m.mesh.rest);
  if (nodes.empty()) throw InputError(scene.path + ": " + key + ": selects no node of the mesh (value " + f.given + ")");
  return nodes;
}

// Node sets held still (the entries of "fixed").
void add_fixed_sets(const Scene& scene, Model& m) {
  for (size_t i = 0; i < scene.fixed.size(); ++i) {
    const std::vector<int> nodes = selection_nodes(scene, m, scene.fixed[i], "fixed[" + std::to_string(i) + "]");
    m.fixed_nodes.insert(m.fixed_nodes.end(), nodes.begin(), nodes.end());
  }
}

// The elastic supports' diagonal stiffness (3n, N/m; empty without supports): springs on the outer wall's nodes,
// k times each node's lumped area, kept only on the nodes support.where selects when it is given (at least one of
// them on the outer wall, or an InputError).
Eigen::VectorXd support_diagonal(const Scene& scene, const Model& m) {
  if (!scene.support.enabled()) return Eigen::VectorXd();
  Eigen::VectorXd S = physics::support_stiffness(m.mesh.rest, m.outer_wall(), scene.support.stiffness).diagonal();
  if (scene.support.where.empty()) return S;
  std::vector<char> selected(static_cast<size_t>(m.mesh.n_nodes()), 0);
  for (size_t i = 0; i < scene.support.where.size(); ++i)
    for (int v : selection_nodes(scene, m, scene.support.where[i], "support.where[" + std::to_string(i) + "]"))
      selected[static_cast<size_t>(v)] = 1;
  for (int v = 0; v < m.mesh.n_nodes(); ++v)
    if (!selected[static_cast<size_t>(v)]) S.segment<3>(3 * v).setZero();
  if (!(S.maxCoeff() > 0.0)) {
    std::string given;  // the list as the scene gives it (compact JSON, as each entry's)
    for (const FixedSpec& f : scene.support.where) given += (given.empty() ? "[" : ",") + f.given;
    throw InputError(scene.path + ": support.where: selects no node of the outer wall (the springs would hold nothing) "
                     "(value " + given + "])");
  }
  return S;
}

// Refuse held node sets (sorted, unique) that take every node: nothing would be left to solve (e.g. a tube one ring
// of cells long held by its ends).
void require_free_nodes(const Scene& scene, const Model& m) {
  if (static_cast<int>(m.fixed_nodes.size()) == m.mesh.n_nodes())
    throw InputError(scene.path + ": fixed: holds every node of the mesh (" + std::to_string(m.fixed_nodes.size()) +
                     " nodes), nothing is left to move");
}

// The centroid of a node set's rest positions (metres).
Eigen::Vector3d centroid(const Points& rest, const std::vector<int>& nodes) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (int v : nodes) c += rest.row(v).transpose();
  return c / static_cast<double>(nodes.size());
}

// A volume mesh's end (its end node set, a ring of the cut wall): the twist's centre, the set's centroid, and axis,
// the normal of the set's least-squares plane pointing from the start end to the stop end. An end set whose nodes
// do not span a plane (fewer than 3, or on a line) has no axis: InputError naming the file.
void volume_end_axis(const Scene& scene, bool start, Model& m) {
  const std::vector<int>& nodes = m.mesh.node_set(start ? physics::kStartEnd : physics::kStopEnd);
  const Eigen::Vector3d c = centroid(m.mesh.rest, nodes);
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (int v : nodes) {
    const Eigen::Vector3d r = m.mesh.rest.row(v).transpose() - c;
    scatter += r * r.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);  // eigenvalues ascending
  if (nodes.size() < 3 || !(eig.eigenvalues()[1] > kEndPlaneSpread * eig.eigenvalues()[2]))
    throw InputError(scene.path + ": twist: the " + (start ? "start" : "stop") + " end of " + scene.volume.file +
                     " (" + std::to_string(nodes.size()) + " nodes) does not span a plane, so it has no axis to turn about");
  Eigen::Vector3d a = eig.eigenvectors().col(0);
  // (The other end's centroid against this one's: start -> stop.)
  const Eigen::Vector3d other =
      centroid(m.mesh.rest, m.mesh.node_set(start ? physics::kStopEnd : physics::kStartEnd));
  if (a.dot(start ? other - c : c - other) < 0.0) a = -a;
  m.twist_center = c;
  m.twist_axis = a.normalized();
}

// Twisted end ring: turned about the tube's axis at that end through the ring's centre (a generated tube: the
// centreline frame of its end ring; a volume mesh: volume_end_axis). Its nodes are prescribed (and fixed):
// u = (cos theta - 1) P + sin theta Q with the basis [P Q].
void add_twist(const Scene& scene, Model& m) {
  if (!scene.twist.enabled()) return;
  const bool start = scene.twist.end == TwistEnd::kStart;
  physics::PrescribedMotion& pm = m.prescribed;
  pm.nodes = start ? m.mesh.node_set(physics::kStartEnd) : m.mesh.node_set(physics::kStopEnd);
  const bool generated = scene.mesh_type != MeshType::kVolume;  // (the scene refuses twists on closed walls)
  const physics::TubeRing& ring = m.end_rings[start ? 0 : 1];
  if (generated) {
    m.twist_center = ring.frame.point;
    m.twist_axis = ring.frame.tangent;
  } else {
    volume_end_axis(scene, start, m);
  }
  // Rotation basis per ring node: R(theta) r - r = (cos theta - 1) (r - a (a . r)) + sin theta (a x r).
  pm.basis = Eigen::MatrixXd::Zero(3 * m.mesh.n_nodes(), 2);
  const Eigen::Vector3d& a = m.twist_axis;
  for (int node : pm.nodes) {
    const Eigen::Vector3d r = m.mesh.rest.row(node).transpose() - m.twist_center;
    // The generator puts every end node in the ring plane; a node off it is a bug, not a user's mistake. (A volume
    // mesh's end need not be planar: its nodes turn rigidly about the axis all the same.)
    if (generated && std::abs(a.dot(r)) > 1e-9 * ring.outer_radius)
      throw std::logic_error("compile_model: twist: end node " + std::to_string(node) + " is off the ring plane (" +
                             std::to_string(a.dot(r)) + " m)");
    pm.basis.block<3, 1>(3 * node, 0) = r - a * a.dot(r);
    pm.basis.block<3, 1>(3 * node, 1) = a.cross(r);
  }
  m.fixed_nodes.insert(m.fixed_nodes.end(), pm.nodes.begin(), pm.nodes.end());
}

// Probe attachment points on either wall, the nearer one (the outer wall for a probe pressing from outside, the
// inner wall for one pushing from the lumen); a point far from both is refused (the one check that needs the
// mesh, so it is made here, at the boundary, before anything is factorised).
void attach_probes(const Scene& scene, Model& m) {
  for (size_t i = 0; i < scene.probes.size(); ++i) {
    const ProbeSpec& p = scene.probes[i];
    const SurfacePoint outer = snap_to_surface(m.mesh.rest, m.outer_wall(), p.point);
    const SurfacePoint inner = snap_to_surface(m.mesh.rest, m.inner_wall(), p.point);
    const double to_outer = (point_of(m.mesh.rest, outer) - p.point).norm();
    const double to_inner = (point_of(m.mesh.rest, inner) - p.point).norm();
    const bool on_inner = to_inner < to_outer;
    const SurfacePoint& sp = on_inner ? inner : outer;
    const Eigen::Vector3d q = point_of(m.mesh.rest, sp);
    // The wall's own thickness there (the distance to the nearest point of the other wall), not the scene's radii.
    const double thickness =
        (point_of(m.mesh.rest, snap_to_surface(m.mesh.rest, on_inner ? m.outer_wall() : m.inner_wall(), q)) - q).norm();
    const double tolerance = kProbeSnapWallFraction * thickness + 1e-9;
    if ((q - p.point).norm() > tolerance)
      throw InputError(scene.path + ": probes[" + std::to_string(i) + "].point: not on the organ's walls (" +
                       std::to_string(to_outer) + " m from the outer wall, " + std::to_string(to_inner) +
                       " m from the inner; value [" + std::to_string(p.point.x()) + ", " +
                       std::to_string(p.point.y()) + ", " + std::to_string(p.point.z()) + "])");
    m.probe_points.push_back(sp);
    m.probe_held.push_back(p.drive == ProbeDrive::Displacement);
    if (m.probe_held.back()) m.held_probes.push_back(static_cast<int>(i));
  }
}

// The colliding walls: the inner wall, and the outer wall when the scene asks; their nodes.
void build_collision_topology(const Scene& scene, Model& m) {
  const Tris& inner = m.inner_wall();
  const Tris& outer = m.outer_wall();
  m.inner_nodes.assign(inner.data(), inner.data() + inner.size());
  sort_unique(m.inner_nodes);
  m.collision_tris = inner;
  if (scene.collision.outer_wall) {
    m.collision_tris.conservativeResize(inner.rows() + outer.rows(), 3);
    m.collision_tris.bottomRows(outer.rows()) = outer;
  }
  m.collision_nodes.assign(m.collision_tris.data(), m.collision_tris.data() + m.collision_tris.size());
  // Instruments touch the outer wall: its nodes join the contact compliance's set, so that the response's
  // correction the re-check sees there is exact.
  if (!scene.instruments.empty()) m.collision_nodes.insert(m.collision_nodes.end(), outer.data(), outer.data() + outer.size());
  sort_unique(m.collision_nodes);
  if (scene.collision.self)
    m.collision_surface = std::make_shared<const collision::CollisionSurface>(m.collision_tris, m.mesh.rest);
}

// The corotational solve's options from the scene: warm start extrapolated from the last two frames, the Anderson
// history carried from frame to frame (but for a twist); a twist rotates the tube far from rest, so there the rest
// factorisation is rotated per node (several times fewer CG iterations; slower for the small rotations of a
// press); the lagged warped factorisation on the second core.
physics::CorotationalOptions corotational_options(const Scene& scene) {
  physics::CorotationalOptions o;
  o.tolerance = scene.solver.tolerance;
  o.max_iterations = scene.solver.max_iterations;
  o.extrapolate = true;
  o.rotate_preconditioner = scene.twist.enabled();
  o.refactor_cg_iterations = kRefactorCgIterations;
  o.anderson_depth = scene.solver.anderson_depth;
  // (Not with the per-node rotated preconditioner: its map changes with the rotations from solve to solve, and a
  // carried history made the twist's median frame 34 % slower, docs/bench_anderson_carry.csv.)
  o.carry_anderson_history = !o.rotate_preconditioner;
  o.max_back_substitutions = scene.solver.max_back_substitutions;
  o.contact_back_substitutions = scene.collision.prediction_back_substitutions;
  constexpr physics::CorotationalTangent kTangents[] = {physics::CorotationalTangent::warped,
                                                        physics::CorotationalTangent::projected,
                                                        physics::CorotationalTangent::exact};
  o.tangent = kTangents[static_cast<int>(scene.solver.tangent)];
  o.refactor_in_background = scene.solver.background_factorisation;
  o.method = scene.solver.method == SolveMethod::kChord ? physics::CorotationalMethod::chord
                                                         : physics::CorotationalMethod::pcg;
  return o;
}

// The integrator of the scene, chosen once: backward Euler (solver.type dynamic, elasticity from material.model),
// corotational quasi-static or linear quasi-static (both on the quadratic mesh for tet10).
std::unique_ptr<physics::Integrator> make_integrator(const Scene& scene, const Model& m,
                                                     const physics::QuadraticMesh* quadratic) {
  physics::LinearMaterial material;
  material.young_modulus = scene.material.young_modulus;
  material.poisson_ratio = scene.material.poisson_ratio;
  // The surrounding tissue's springs to rest on the outer wall (their diagonal stiffness, N/m per DOF).
  const Eigen::VectorXd support = support_diagonal(scene, m);
  if (scene.solver.type == SolverType::kDynamic) {
    physics::DynamicParams params;
    params.elastic = scene.material.model == MaterialModel::kCorotational ? physics::ElasticModel::kCorotational
                                                                          : physics::ElasticModel::kLinear;
    params.density = scene.material.density;
    params.alpha = scene.solver.rayleigh_mass;
    params.beta = scene.solver.rayleigh_stiffness;
    params.time_step = m.time_step;
    return std::make_unique<physics::BackwardEuler>(m.mesh, material, m.fixed_nodes, params,
                                                    corotational_options(scene), m.prescribed, support);
  }
  if (scene.material.model == MaterialModel::kCorotational && quadratic)
    return std::make_unique<physics::CorotationalQuasiStatic>(*quadratic, material, m.fixed_nodes,
                                                              corotational_options(scene), m.prescribed, support);
  if (scene.material.model == MaterialModel::kCorotational)
    return std::make_unique<physics::CorotationalQuasiStatic>(m.mesh, material, m.fixed_nodes,
                                                              corotational_options(scene), m.prescribed, support);
  Eigen::SparseMatrix<double> K = quadratic ? physics::assemble_stiffness(*quadratic, material)
                                            : physics::assemble_stiffness(m.mesh, material);
  if (support.size()) K += Eigen::SparseMatrix<double>(Eigen::VectorXd(support).asDiagonal());
  return std::make_unique<physics::LinearQuasiStatic>(K, m.fixed_nodes, m.probe_points, m.probe_held, m.prescribed);
}

// The carried contacts' penalty: kCouplingStiffnessScale times the mean diagonal of the rest stiffness over the
// colliding walls' free DOFs (the scene's checks allow "carried" with the corotational quasi-static model only).
double coupling_stiffness(const Model& m) {
  const auto* corotational = dynamic_cast<const physics::CorotationalQuasiStatic*>(m.integrator.get());
  assert(corotational);
  const Eigen::SparseMatrix<double>& K = corotational->model().stiffness();
  double sum = 0.0;
  int count = 0;
  for (int v : m.collision_nodes)
    for (int axis = 0; axis < 3; ++axis) {
      const int d = 3 * v + axis;
      if (corotational->is_fixed_dof(d)) continue;
      sum += K.coeff(d, d);
      ++count;
    }
  return count > 0 ? kCouplingStiffnessScale * sum / count : 0.0;
}

// The nodes the renderer reads: the drawn surfaces', the probes' attachment nodes, the centreline camera's rings.
void collect_view_nodes(Model& m) {
  std::vector<int>& v = m.view_nodes;
  for (const DrawnSurface& d : m.drawn) {
    const Tris& tris = m.mesh.surfaces[d.surface].tris;
    v.insert(v.end(), tris.data(), tris.data() + tris.size());
  }
  for (const SurfacePoint& sp : m.probe_points) v.insert(v.end(), sp.node, sp.node + 3);
  v.insert(v.end(), m.flight_ring_inner.begin(), m.flight_ring_inner.end());
  sort_unique(v);
}

}  // namespace

std::unique_ptr<Model> compile_model(const Scene& scene) {
  const auto t0 = Clock::now();
  auto m = std::make_unique<Model>();
  m->name = scene.name;
  m->scene_path = scene.path;
  m->frames = scene.frames;
  m->fps = scene.fps;
  m->material = scene.material.model;
  m->element = scene.element;
  m->solver = scene.solver.type;
  m->tangent = scene.solver.tangent;
  m->method = scene.solver.method;
  m->collision = scene.collision;
  m->render = scene.render;
  m->twist = scene.twist;
  m->budget_ms = 1000.0 / scene.fps;
  m->time_step = 1.0 / scene.fps;
  std::unique_ptr<physics::QuadraticMesh> quadratic;
  m->mesh = build_mesh(scene, quadratic, *m);
  resolve_walls(*m);
  add_fixed_sets(scene, *m);
  add_twist(scene, *m);
  sort_unique(m->fixed_nodes);
  require_free_nodes(scene, *m);
  attach_probes(scene, *m);
  build_collision_topology(scene, *m);
  compile_instruments(scene, *m);
  collect_view_nodes(*m);
  m->integrator = make_integrator(scene, *m, quadratic.get());
  if (m->collision_surface && scene.collision.coupling == ContactCoupling::kCarried)
    m->coupling_stiffness = coupling_stiffness(*m);
  // (The scene checks "solved" names a corotational quasi-static solve, whose integrator solves its contacts.)
  m->contacts_in_solve = m->collision_surface && scene.collision.coupling == ContactCoupling::kSolved &&
                         m->integrator->solves_contacts();
  m->equilibrium_tolerance = scene.solver.tolerance;
  const Points& rest = m->mesh.rest;
  m->max_displacement = kImplausibleDisplacementScale * (rest.colwise().maxCoeff() - rest.colwise().minCoeff()).norm();
  m->compile_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  return m;
}

std::unique_ptr<PoseSource> make_pose_source(const Scene& scene, size_t i) {
  const InstrumentSpec& spec = scene.instruments[i];
  if (spec.drive == InstrumentDrive::kDevice)
    throw InputError(scene.path + ": instruments[" + std::to_string(i) + "].device_name: poses from a device need "
                     "the OpenIGTLink bridge: run it with `lumen serve`, or give the instrument a \"track\" "
                     "or a \"replay\" (value \"" + spec.device_name + "\")");
  const bool replay = spec.drive == InstrumentDrive::kReplay;
  return std::make_unique<PoseTrackSource>(PoseTrack(spec.poses, replay ? spec.replay : scene.path),
                                           replay ? "replay" : "track");
}

Inputs make_inputs(const Scene& scene) {
  Inputs in;
  for (const ProbeSpec& p : scene.probes) in.sources.push_back(make_source(p));
  for (size_t i = 0; i < scene.instruments.size(); ++i) in.instruments.push_back(make_pose_source(scene, i));
  return in;
}

namespace {

// Contacts to come in the equilibrium on lagged Hessians: the integrator keeps one factorised ahead of them (from the
// session's start, so that the first, slower factorisations are done before the walls meet).
void anticipate_contacts(const Model& model, State& state) {
  if (model.contacts_in_solve && state.compliance && model.collision.equilibrium_hessian == EquilibriumHessian::kLagged)
    model.integrator->anticipate_contacts(state.compliance->nodes(), state.work);
}

}  // namespace

State make_state(const Model& model) {
  State s;
  const int n = model.mesh.n_nodes();
  s.x = model.mesh.rest;
  s.sim.u = Eigen::VectorXd::Zero(3 * n);
  s.sim.v = Eigen::VectorXd::Zero(3 * n);
  s.samples.resize(model.probe_points.size());
  s.load_points = model.probe_points;
  s.in_contact.assign(n, 0);
  if (model.collision_surface) s.detector = std::make_unique<collision::CollisionWorkspace>(model.collision.kdop);
  // Instruments: a workspace for the organ side of their pair detection, one per part.
  if (model.tool_target_surface) {
    s.organ_tool_workspace = std::make_unique<collision::CollisionWorkspace>(model.collision.kdop);
    for (size_t p = 0; p < model.tool_parts.size(); ++p)
      s.tool_workspaces.push_back(std::make_unique<collision::CollisionWorkspace>(model.collision.kdop));
    s.tool_pose.resize(model.instruments.size());
    s.tool_points.resize(model.tool_parts.size());
    for (const CompiledInstrument& ci : model.instruments) s.tool_opening.push_back(ci.instrument.rest_opening);
    s.tool_opening_target = s.tool_opening;
    s.grasps.resize(model.instruments.size());
  }
  if (model.collision_surface || model.tool_target_surface) {
    using physics::SurfaceCompliance;
    s.compliance = std::make_unique<SurfaceCompliance>(model.contact_solver(), model.collision_nodes,
                                                       SurfaceCompliance::kBlockColumns,
                                                       model.compliance_mesh_column_bytes,
                                                       SurfaceCompliance::kSetMatrixBytes, model.view_nodes);
    // Whole-mesh columns of the probe nodes too, so a contact correction that changes probe forces stays cheap.
    std::vector<int> probe_nodes;
    for (const SurfacePoint& sp : model.probe_points) probe_nodes.insert(probe_nodes.end(), sp.node, sp.node + 3);
    sort_unique(probe_nodes);
    s.compliance->ensure_columns(probe_nodes);
  }
  prime_proximity(model, s);
  anticipate_contacts(model, s);
  return s;
}

namespace {

// ---------------------------------------------------------------------------------------------------------------
// Frame stages

// What sampling the inputs found.
struct InputHealth {
  bool all_fixed = true;   // every probe point is where it was compiled
  bool bad_input = false;  // a source gave a non-finite value (its last good sample stands)
};

// Sample every probe source at the end-of-frame time, and attach each probe: a fixed point where it was
// compiled, a moving one at the outer-wall point nearest to where it is this frame. A source that yields a
// non-finite value (a faulty device) is not believed: its last good sample stands.
InputHealth sample_inputs(const Model& model, Inputs& inputs, State& state, double t1) {
  assert(inputs.sources.size() == model.probe_points.size());
  InputHealth h;
  for (size_t i = 0; i < inputs.sources.size(); ++i) {
    InputSource& source = *inputs.sources[i];
    const ProbeSample s = source.sample(t1);
    if (s.point.allFinite() && s.force.allFinite() && s.displacement.allFinite())
      state.samples[i] = s;
    else
      h.bad_input = true;
    const bool fixed = source.point_is_fixed();
    state.load_points[i] = fixed ? model.probe_points[i]
                                 : snap_to_surface(model.mesh.rest, model.outer_wall(), state.samples[i].point);
    h.all_fixed = h.all_fixed && fixed;
  }
  return h;
}

// Each instrument's points at a pose, into its parts' slots of `parts` (one array per tool part).
void place_instrument(const Model& model, size_t i, const Pose& pose, double opening, std::vector<Points>& parts) {
  const CompiledInstrument& ci = model.instruments[i];
  std::vector<Points> posed = posed_parts(ci.instrument, pose, opening);
  for (size_t j = 0; j < posed.size(); ++j) parts[static_cast<size_t>(ci.first_part) + j] = std::move(posed[j]);
}

// The instruments' target poses at the end-of-frame time t1 (at the first frame, their start at t = 0 too). A
// source that yields a non-finite pose is not believed: the instrument stays where it is (bad input).
void sample_instruments(const Model& model, Inputs& inputs, State& state, double t1, InputHealth& h) {
  if (model.instruments.empty()) return;
  assert(inputs.instruments.size() == model.instruments.size());
  if (!state.tools_placed)
    for (size_t i = 0; i < model.instruments.size(); ++i) {
      const CompiledInstrument& ci = model.instruments[i];
      state.tool_pose[i] = inputs.instruments[i]->pose(state.t);
      state.tool_opening[i] = commanded_opening(ci.openings, ci.instrument.rest_opening, state.t);
      place_instrument(model, i, state.tool_pose[i], state.tool_opening[i], state.tool_points);
    }
  // Graspers: the jaws' opening at t1 (held at a grasp), and holds that begin or end.
  update_grasps(model, state, t1);
  state.tools_placed = true;
  state.tool_pose_target = state.tool_pose;
  state.tool_target = state.tool_points;
  for (size_t i = 0; i < model.instruments.size(); ++i) {
    const Pose target = inputs.instruments[i]->pose(t1);
    if (!target.position.allFinite() || !target.rotation.coeffs().allFinite()) {
      h.bad_input = true;
      continue;
    }
    state.tool_pose_target[i] = target;
    place_instrument(model, i, target, state.tool_opening_target[i], state.tool_target);
  }
}

// The frame's point loads at the probes' attachment points.
physics::FrameLoads frame_loads(const Model& model, const State& state, bool all_fixed) {
  physics::FrameLoads loads;
  loads.at_compiled_points = all_fixed;
  loads.points.resize(state.samples.size());
  for (size_t i = 0; i < state.samples.size(); ++i) {
    physics::PointLoad& p = loads.points[i];
    p.at = state.load_points[i];
    p.force = state.samples[i].force;
    p.held = model.probe_held[i];
    p.target = state.samples[i].displacement;
  }
  return loads;
}

Points positions_of(const Model& model, const Eigen::VectorXd& u) {
  return model.mesh.rest + Eigen::Map<const Points>(u.data(), model.mesh.n_nodes(), 3);
}

// Tets with non-positive volume at x.
int count_inverted(const Points& x, const Tets& tets) {
  int inverted = 0;
  for (int e = 0; e < tets.rows(); ++e)
    if (physics::tet_volume(x, tets, e) <= 0.0) ++inverted;
  return inverted;
}

// Whether the prediction u can be collided and committed: solved, finite, no node displaced beyond
// model.max_displacement.
bool usable(const Model& model, const physics::Prediction& pred, const Eigen::VectorXd& u) {
  if (!pred.finite || pred.diverged || !u.allFinite()) return false;
  const Eigen::Map<const Points> d(u.data(), u.size() / 3, 3);
  return d.size() == 0 || d.rowwise().norm().maxCoeff() <= model.max_displacement;
}

// Commit the frame's end displacement u (solved: usable()), or keep the last good state; what the commit adds to
// the frame's record (its probe points' displacements at load_points, where they attached in that frame).
CommitRecord commit_frame(const Model& model, State& state, int frame, const Eigen::VectorXd& u, bool solved,
                          const std::vector<SurfacePoint>& load_points) {
  CommitRecord c;
  c.frame = frame;
  if (solved) {
    Points x1 = positions_of(model, u);
    c.inverted_elements = count_inverted(x1, model.mesh.tets);
    model.integrator->commit(u, state.sim);
    state.x = std::move(x1);
  }
  c.kinetic_energy = model.integrator->kinetic_energy(state.sim);
  for (int i = 0; i < model.mesh.n_nodes(); ++i)
    c.max_displacement = std::max(c.max_displacement, state.sim.u.segment<3>(3 * i).norm());
  const Eigen::Map<const Points> uu(state.sim.u.data(), state.sim.u.size() / 3, 3);
  for (const SurfacePoint& p : load_points) c.probe_displacement.push_back(point_of(uu, p));
  return c;
}

// The contacts held at the end of the last frame as rows at the frame's start positions, with their whole
// multipliers: the loads the corotational solve carries (collision.coupling "carried").
physics::AugmentedContacts carry_contacts(const Model& model, const State& state) {
  physics::AugmentedContacts c;
  for (const collision::Contact& contact : state.active)
    c.rows.push_back(contact_row(contact, model.mesh.rest, state.x, state.x, model.collision.gap));
  c.lambda = Eigen::Map<const Eigen::VectorXd>(state.active_total.data(), static_cast<Eigen::Index>(state.active_total.size()));
  c.stiffness = model.coupling_stiffness;
  return c;
}

// The prediction's solver statistics into the frame's record.
void record_prediction(const physics::Prediction& pred, FrameRecord& rec) {
  rec.physics_iterations = pred.iterations;
  rec.physics_converged = pred.converged;
  rec.physics_diverged = pred.diverged;
  rec.refactorisations = pred.refactorisations;
  rec.tangent_fallbacks = pred.tangent_fallbacks;
  rec.cg_iterations = pred.cg_iterations;
  rec.truncated_steps = pred.truncated_steps;
  rec.preconditioner_failures = pred.preconditioner_failures;
}

// Reaction at each probe point (a probe in equilibrium: equal and opposite to its force), handed back.
void feed_back(Inputs& inputs, const State& state, double t1, FrameRecord& rec) {
  rec.reactions.clear();
  for (size_t i = 0; i < inputs.sources.size(); ++i) {
    const Eigen::Vector3d reaction = -state.samples[i].force;
    rec.reactions.push_back(reaction);
    inputs.sources[i]->feedback(t1, reaction);
  }
}

// Each instrument's record (where it ended, the contacts' force and torque on it), handed back to its source. A
// frame whose response did not run (a failed prediction) leaves the instruments where they were, without force.
void feed_back_instruments(const Model& model, Inputs& inputs, State& state, double t1, FrameRecord& rec) {
  if (model.instruments.empty()) return;
  if (state.tool_records.empty()) state.tool_records = instrument_records(model, state, {}, {}, Eigen::VectorXd());
  rec.instruments = state.tool_records;
  for (size_t i = 0; i < rec.instruments.size(); ++i)
    inputs.instruments[i]->feedback(t1, rec.instruments[i]);
}

}  // namespace

// The probes' forces as a nodal force vector (3n) at their attachment points of the last frame.
Eigen::VectorXd nodal_loads(const Model& model, const State& state) {
  return physics::nodal_forces(frame_loads(model, state, true), 3 * model.mesh.n_nodes());
}

void step(const Model& model, Inputs& inputs, State& state, FrameRecord& rec) {
  step_begin(model, inputs, state, rec);
  step_end(model, inputs, state, rec);
}

void step_begin(const Model& model, Inputs& inputs, State& state, FrameRecord& rec) {
  if (state.pending.open) throw std::logic_error("step_begin: the last frame's step_end() has not run");
  // Every field of the record is this frame's (callers may reuse one record across frames).
  rec = FrameRecord{};
  const double t1 = (state.frame + 1) / model.fps;
  rec.frame = state.frame + 1;
  rec.t = t1;

  // Sample inputs.
  auto clock = Clock::now();
  InputHealth input = sample_inputs(model, inputs, state, t1);
  sample_instruments(model, inputs, state, t1, input);
  rec.ms[kInput] = ms_since(clock);

  // Predict: the integrator's free motion with the probes' loads, the twisted ring at its end-of-frame angle;
  // displacement-driven probes get the forces that hold their points at the targets.
  clock = Clock::now();
  rec.twist_degrees = twist_degrees(model.twist, t1);
  physics::FrameLoads loads = frame_loads(model, state, input.all_fixed);
  physics::AugmentedContacts carried;
  if (model.coupling_stiffness > 0.0 && !state.active.empty()) {
    carried = carry_contacts(model, state);
    loads.contacts = &carried;
  }
  Eigen::VectorXd u;
  const physics::Prediction pred =
      model.integrator->predict(loads, twist_coefficients(model, rec.twist_degrees), state.sim, state.work, u);
  for (int p : model.held_probes) state.samples[p].force = loads.points[p].force;
  record_prediction(pred, rec);
  state.carried_lambda = loads.contacts ? pred.contact_lambda : Eigen::VectorXd();
  // Grasped nodes follow their graspers (prescribed displacements of the free motion).
  const bool solved = usable(model, pred, u);
  if (solved) hold_grasped_nodes(model, state, u);
  rec.ms[kPhysics] = ms_since(clock);

  // Collide and respond: contacts constrain the solve on the contact compliance, CCD re-checks (and settle a
  // pipelined last frame once the response is done).
  std::fill(state.in_contact.begin(), state.in_contact.end(), 0);
  state.contacts.clear();
  state.tool_records.clear();
  if (state.compliance && solved) collide_and_respond(model, state, u, rec);
  wait_for_last_frame(model, state, rec);
  anticipate_contacts(model, state);

  // Commit (or keep the last good frame), or, with the interior deferred, start its solve on a second thread and
  // place the nodes the renderer and the next frame's collision read (exact already).
  rec.numerical_failure = !solved || input.bad_input;
  rec.bad_input = input.bad_input;
  if (rec.numerical_failure) ++state.failures;
  PendingFrame& p = state.pending;
  p.open = true;
  p.solved = solved;
  if (!rec.interior_deferred) {
    commit_frame(model, state, rec.frame, u, solved, state.load_points).apply_to(rec);
  } else {
    const physics::SurfaceCompliance* compliance = state.compliance.get();
    InteriorInFlight& f = p.in_flight;
    f.frame = rec.frame;
    f.u_free = std::move(p.u_free);
    f.load_points = state.load_points;
    f.interior = std::async(std::launch::async, [compliance, du = std::move(p.du)]() mutable {
      compliance->complete_interior(du);
      return du;
    });
    for (const std::vector<int>* nodes : {&model.view_nodes, &compliance->nodes()})
      for (int v : *nodes) state.x.row(v) = model.mesh.rest.row(v) + u.segment<3>(3 * v).transpose();
  }
  state.frame += 1;
  state.t = t1;
}

void step_end(const Model& model, Inputs& inputs, State& state, FrameRecord& rec) {
  PendingFrame& p = state.pending;
  if (!p.open) throw std::logic_error("step_end: no frame was begun (step_begin)");
  p.open = false;
  // A deferred interior: wait for its solve (which writes the interior only: what was drawn stays) and commit;
  // pipelined, the next frame does.
  if (!state.pipeline_interior) {
    wait_for_last_frame(model, state, rec);
    file_commits(state, &rec, 1);
  }
  // Carried contacts: the next solve starts where this frame ended (its loads include the contacts). A failed
  // solve's warm start goes back to the last good frame too, never to what failed.
  // Contacts solved in the equilibrium: likewise (the frame's end is the equilibrium with its contacts).
  const bool in_equilibrium = model.coupling_stiffness > 0.0 || model.contacts_in_solve;
  const bool restart = (in_equilibrium && !rec.numerical_failure) || !p.solved;
  if (restart && state.work.corotational.u.size() == state.sim.u.size()) state.work.corotational.u = state.sim.u;
  feed_back(inputs, state, state.t, rec);
  feed_back_instruments(model, inputs, state, state.t, rec);
}

void wait_for_last_frame(const Model& model, State& state, FrameRecord& rec) {
  const double waited = settle(model, state);
  rec.interior_wait_ms += waited;
  rec.ms[kResponse] += waited;
}

double settle(const Model& model, State& state) {
  InteriorInFlight& f = state.pending.in_flight;
  if (!f.interior.valid()) return 0.0;
  const auto clock = Clock::now();
  const Eigen::VectorXd u = f.u_free + f.interior.get();
  const double waited = ms_since(clock);
  state.last_correction = u - f.u_free;  // (as keep_for_next_frame has it, to the last bit)
  state.pending.committed.push_back(commit_frame(model, state, f.frame, u, true, f.load_points));
  f = InteriorInFlight{};
  return waited;
}

void file_commits(State& state, FrameRecord* frames, size_t n) {
  for (const CommitRecord& c : state.pending.committed) {
    FrameRecord* rec = std::find_if(frames, frames + n, [&](const FrameRecord& r) { return r.frame == c.frame; });
    if (rec == frames + n)
      throw std::logic_error("file_commits: frame " + std::to_string(c.frame) + " is not among the records given");
    c.apply_to(*rec);
  }
  state.pending.committed.clear();
}

void CommitRecord::apply_to(FrameRecord& rec) const {
  rec.inverted_elements = inverted_elements;
  rec.kinetic_energy = kinetic_energy;
  rec.max_displacement = max_displacement;
  rec.probe_displacement = probe_displacement;
}

}  // namespace lumen::engine
