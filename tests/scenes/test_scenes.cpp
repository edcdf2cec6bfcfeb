// Whole sessions of the shipped scenes, with the exact intersection check (independent of the CCD code) on
// every frame: zero intersecting inner-wall pairs with collision processing, and demonstrably some without it.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "collision/intersect.hpp"
#include "engine/session.hpp"
#include "engine/simulation.hpp"
#include "engine/surface_pair.hpp"
#include "physics/mesh_quality.hpp"
#include "physics/volume_mesh.hpp"
#include "support/scene_files.hpp"

using namespace lumen::engine;

namespace {

Scene shipped_scene(const std::string& scene_file) { return load_scene(std::string(LUMEN_SOURCE_DIR) + "/scenes/" + scene_file); }

SessionResult run_checked(const std::string& scene_file) { return lumen::test::run_checked_session(shipped_scene(scene_file)); }

// Every frame of the scene's session intersection-free and without numerical failure, and the walls meet; the
// contacts summed over the frames.
long expect_never_intersects(const Scene& scene, const std::string& what) {
  const SessionResult r = lumen::test::run_checked_session(scene);
  long contacts = 0;
  for (const auto& f : r.frames) {
    EXPECT_EQ(f.intersecting_pairs, 0) << what << " frame " << f.frame;
    EXPECT_FALSE(f.numerical_failure) << what << " frame " << f.frame;
    contacts += f.contacts;
  }
  // The scene really makes the walls meet (otherwise the check proves nothing).
  EXPECT_GT(contacts, 0) << what;
  return contacts;
}
void expect_never_intersects(const std::string& scene_file) { expect_never_intersects(shipped_scene(scene_file), scene_file); }

}  // namespace

TEST(Scenes, Fig5WithoutCollisionProcessingTheWallsPassThrough) {
  SessionResult r = run_checked("fig5-squeeze-no-collision.json");
  long frames_with = 0;
  for (const auto& f : r.frames) frames_with += f.intersecting_pairs > 0;
  EXPECT_GT(frames_with, 10);
}

TEST(Scenes, Fig5WithCollisionProcessingNeverIntersects) { expect_never_intersects("fig5-squeeze.json"); }
TEST(Scenes, Fig7aEndAndMiddleNeverIntersects) { expect_never_intersects("fig7a-end-and-middle.json"); }
TEST(Scenes, Fig7bTwoAreasAtOneEndNeverIntersects) { expect_never_intersects("fig7b-two-areas-end.json"); }
TEST(Scenes, FullClosureNeverIntersects) { expect_never_intersects("full-closure.json"); }

TEST(Scenes, PaperSceneLoadsWithThePaperMeshCounts) {
  Scene scene = load_scene(std::string(LUMEN_SOURCE_DIR) + "/scenes/paper-press.json");
  auto model = compile_model(scene);
  EXPECT_EQ(model->mesh.n_nodes(), 2160);
  EXPECT_EQ(model->mesh.tets.rows(), 9360);
  EXPECT_EQ(model->mesh.surface(lumen::physics::kInnerWall).rows(), 1040);
}

// 20 cm of the real colon's sigmoid (swept along its CT centreline, with haustra) pinched shut by two probes.
TEST(Scenes, ColonSigmoidPinchNeverIntersects) { expect_never_intersects("colon-sigmoid-pinch.json"); }
// The whole real colon (1.39 m, 25,056 tets) on elastic supports, pressed at the transverse colon: the supports
// hold it (the free colon, fixed only at its ends, moves tens of centimetres under such a press), the point moves along the force,
// and no frame holds an inner-wall intersection (the walls do not meet here: this checks the bends stay clear).
TEST(Scenes, WholeColonOnSupportsMovesWhereItIsPressedWithoutIntersection) {
  const Scene scene = load_scene(std::string(LUMEN_SOURCE_DIR) + "/scenes/colon-whole-press.json");
  const SessionResult r = run_checked("colon-whole-press.json");
  for (const auto& f : r.frames) {
    EXPECT_EQ(f.intersecting_pairs, 0) << "frame " << f.frame;
    EXPECT_FALSE(f.numerical_failure) << "frame " << f.frame;
    EXPECT_LT(f.max_displacement, 0.01) << "frame " << f.frame;
  }
  const Eigen::Vector3d force = scene.probes[0].track.back().value;
  const Eigen::Vector3d moved = r.frames.back().probe_displacement[0];
  EXPECT_GT(moved.dot(force.normalized()), 0.9 * moved.norm());
  EXPECT_GT(moved.norm(), 1e-4);
}

// The whole real colon on its supports pinched shut in the sigmoid by two displacement-driven probes (the sigmoid
// segment's pinch): the walls meet (contacts from frame 63) and no frame holds an inner-wall intersection.
TEST(Scenes, WholeColonPinchedShutNeverIntersects) { expect_never_intersects("colon-whole-pinch.json"); }

// A tube read from a gmsh file (data/volume-tube.msh, mesh.type "volume") pinched by two probes.
TEST(Scenes, VolumeTubePinchNeverIntersects) { expect_never_intersects("volume-tube-pinch.json"); }

// Quadratic elements at the paper's wall resolution (10 x 13 x 1 tet10: 1040 split inner triangles).
TEST(Scenes, FullClosureTet10NeverIntersects) { expect_never_intersects("full-closure-tet10.json"); }

// The outer wall in the collision surface too: the exact check then covers both walls.
TEST(Scenes, FullClosureWithTheOuterWallCollidingNeverIntersects) {
  Scene scene = load_scene(std::string(LUMEN_SOURCE_DIR) + "/scenes/full-closure.json");
  scene.collision.outer_wall = true;
  auto model = compile_model(scene);
  ASSERT_EQ(model->collision_tris.rows(), model->mesh.surface(lumen::physics::kInnerWall).rows() + model->mesh.surface(lumen::physics::kOuterWall).rows());
  SessionOptions opt;
  opt.render = false;
  opt.check = true;
  const SessionResult r = run_session(*model, make_inputs(scene), opt);
  long contacts = 0;
  for (const auto& f : r.frames) {
    EXPECT_EQ(f.intersecting_pairs, 0) << "frame " << f.frame;
    contacts += f.contacts;
  }
  EXPECT_GT(contacts, 0);
}

namespace {

// The finest finished CalculiX tip displacement (metres) of a material at a force, from the committed reference
// CSV (tools/reference/ccx_reference.py; columns force_N, material, dofs, tip_displacement_m, status).
double calculix_tip(const std::string& material, double force) {
  std::ifstream in(std::string(LUMEN_SOURCE_DIR) + "/docs/reference_convergence_tip3mm.csv");
  std::string line;
  std::vector<std::string> header;
  double tip = 0.0;
  long best_dofs = 0;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) cells.push_back(c);
    if (header.empty()) {
      header = cells;
      continue;
    }
    auto cell = [&](const std::string& name) {
      for (size_t i = 0; i < header.size(); ++i)
        if (header[i] == name) return i < cells.size() ? cells[i] : std::string();
      return std::string();
    };
    if (cell("material") != material || cell("status") != "ok" || std::abs(std::stod(cell("force_N")) - force) > 1e-12) continue;
    if (std::stol(cell("dofs")) > best_dofs) best_dofs = std::stol(cell("dofs")), tip = std::stod(cell("tip_displacement_m"));
  }
  return tip;
}

// Mean pinch-direction displacement of the top tip's 7 probe points at the last frame, metres (positive inward).
double top_tip_displacement(const SessionResult& r) {
  const auto& p = r.frames.back().probe_displacement;
  double sum = 0.0;
  for (int k = 0; k < 7; ++k) sum -= p[k].y();
  return sum / 7.0;
}

}  // namespace

// The corotational tet10 pinch (two 3 mm tips at 0.01 N, below first contact) against the converged Neo-Hookean
// NLGEOM CalculiX reference: every frame converged and intersection-free, the tip within 35 % of the reference
// (measured -28.5 %; the corotational tet4 paper mesh is at -69 %, docs/study_reference.csv), and nearer to it than
// the linear model on the same quadratic mesh, which misses the geometric softening.
TEST(Scenes, CorotationalTet10PinchApproachesTheCalculixReference) {
  const double reference = calculix_tip("neohooke", 0.01);
  ASSERT_GT(reference, 0.004);  // the committed reference row exists (4.78 mm)
  const SessionResult r = run_checked("pinch-corotational-tet10.json");
  for (const auto& f : r.frames) {
    EXPECT_EQ(f.intersecting_pairs, 0) << "frame " << f.frame;
    EXPECT_TRUE(f.physics_converged) << "frame " << f.frame;
  }
  const double corotational = top_tip_displacement(r);
  EXPECT_LT(std::abs(corotational - reference), 0.35 * reference) << corotational;
  // The same pinch with the linear model.
  Scene scene = load_scene(std::string(LUMEN_SOURCE_DIR) + "/scenes/pinch-corotational-tet10.json");
  scene.material.model = MaterialModel::kLinear;
  auto model = compile_model(scene);
  SessionOptions opt;
  opt.render = false;
  const double linear = top_tip_displacement(run_session(*model, make_inputs(scene), opt));
  EXPECT_LT(std::abs(corotational - reference), std::abs(linear - reference) - 0.1 * reference) << linear;
}

// The same sigmoid segment with its lumen radius sampled from the real CT surface (mesh.radius from_surface)
// instead of a constant with synthetic haustra, pinched shut by the same two probes.
TEST(Scenes, ColonSigmoidSurfacePinchNeverIntersects) { expect_never_intersects("colon-sigmoid-surface-pinch.json"); }
// A 0.5 mm wall grown outward from the real aneurysm's lumen surface (mesh.type surface_wall), one probe pressing
// the vessel 5 mm along -z (its lumen is 4.4 mm deep there) onto a plane that holds its underside, self-collision
// on. On the coarse surface (scenes/aneurysm-wall-press-coarse.json: SOFA's aneurysm decimated to 900 vertices by
// tools/organs/decimate_surface.py), since the full scene's dense contact compliance over its 7,095 inner-wall
// nodes takes minutes to build (the full surface's growth is tested in tests/engine). The wall grows with both
// walls together free of intersections by the exact check and no inverted tet; every frame has 0 intersecting
// inner-wall pairs by the exact check and no numerical failure, and the walls meet (contacts); the wall moves
// where pressed: the probe's point follows its track to the end (5 mm along -z), the organ pushes back along the
// press, and no node moves more than twice the press.
// The full-resolution scene loads and compiles with the documented mesh: 14,190 nodes, 42,558 tets, the file's
// 14,186 triangles as the inner wall, one vertex untangled, no offset clamped, and its probe on the outer wall.
TEST(Scenes, AneurysmFullSceneCompilesWithTheDocumentedMesh) {
  const Scene scene = load_scene(std::string(LUMEN_SOURCE_DIR) + "/scenes/aneurysm-wall-press.json");
  const auto model = compile_model(scene);
  EXPECT_EQ(model->mesh.n_nodes(), 14190);
  EXPECT_EQ(model->mesh.tets.rows(), 42558);
  EXPECT_EQ(model->inner_wall().rows(), 14186);
  EXPECT_EQ(model->untangled_vertices, 1);
  EXPECT_EQ(model->clamped_vertices, 0);
  EXPECT_EQ(model->probe_points.size(), 1u);
}

// And its whole session (120 frames; its wall's contact compliance, 3.6 GB as a matrix, is solved per node on first
// contact): every frame intersection-free by the exact check, without numerical failure, and the walls meet.
TEST(Scenes, AneurysmFullSceneNeverIntersects) { expect_never_intersects("aneurysm-wall-press.json"); }

TEST(Scenes, AneurysmWallGrowsIntersectionFreeAndMovesWhereItIsPressed) {
  const std::string file = "aneurysm-wall-press-coarse.json";
  const Scene scene = load_scene(std::string(LUMEN_SOURCE_DIR) + "/scenes/" + file);
  const lumen::engine::SurfaceWall& wall = scene.surface_wall.wall;
  lumen::Tris both(2 * wall.triangles, 3);
  both.topRows(wall.triangles) = wall.mesh.surface(lumen::physics::kInnerWall);
  both.bottomRows(wall.triangles) = wall.mesh.surface(lumen::physics::kOuterWall);
  EXPECT_EQ(lumen::collision::count_intersecting_pairs(wall.mesh.rest, both), 0);
  EXPECT_EQ(lumen::physics::mesh_quality(wall.mesh.rest, wall.mesh.tets).degenerate_tets, 0);

  const SessionResult r = run_checked(file);
  long contacts = 0;
  double max_displacement = 0.0;
  for (const auto& f : r.frames) {
    EXPECT_EQ(f.intersecting_pairs, 0) << "frame " << f.frame;
    EXPECT_FALSE(f.numerical_failure) << "frame " << f.frame;
    contacts += f.contacts;
    max_displacement = std::max(max_displacement, f.max_displacement);
  }
  EXPECT_GT(contacts, 0);
  const Eigen::Vector3d press = scene.probes[0].track.back().value;
  ASSERT_GT(press.norm(), 0.0);
  EXPECT_LT((r.frames.back().probe_displacement[0] - press).norm(), 1e-3 * press.norm());
  EXPECT_GT(-r.frames.back().reactions[0].dot(press), 0.0);
  EXPECT_LT(max_displacement, 2.0 * press.norm());
  std::printf("%s: %zu frames, %ld contacts, max displacement %.2f mm, force along the press %.4f N\n", file.c_str(),
              r.frames.size(), contacts, 1e3 * max_displacement,
              -r.frames.back().reactions[0].dot(press.normalized()));
}

// The aneurysm's wall as a surface pair (mesh.type surface_pair): the coarse lumen surface and the outer surface
// grown 0.5 mm from it by lumen_grow_surface (data/organs), tetrahedralised by Netgen at load. The tets fill exactly
// the volume between the two files' surfaces (divergence theorem over their triangles), all positive, and their
// boundary faces are exactly the files' triangles (node ids: inner vertices first, then outer), the inner wall the
// inner file's; the same press as aneurysm-wall-press-coarse (shortened to 90 frames: the walls meet from frame 74 on
// the prism wall) has 0 intersecting inner-wall pairs by the exact check, no numerical failure, and contacts.
TEST(Scenes, AneurysmPairTetrahedralisedAtLoadKeepsItsSurfacesAndNeverIntersects) {
  const std::string file = "aneurysm-pair-press.json";
  Scene scene = shipped_scene(file);
  const lumen::engine::SurfacePair& pair = scene.surface_pair.pair;
  const lumen::engine::SurfaceMesh in = read_closed_surface(scene.surface_pair.spec.inner_file, 1e-3);
  const lumen::engine::SurfaceMesh out = read_closed_surface(scene.surface_pair.spec.outer_file, 1e-3);
  double volume = 0.0;
  for (int e = 0; e < pair.mesh.tets.rows(); ++e) {
    ASSERT_GT(lumen::physics::tet_volume(pair.mesh.rest, pair.mesh.tets, e), 0.0) << "tet " << e;
    volume += lumen::physics::tet_volume(pair.mesh.rest, pair.mesh.tets, e);
  }
  const double between = enclosed_volume(out) - enclosed_volume(in);
  EXPECT_NEAR(volume, between, 1e-12 * between);
  const lumen::Tris boundary = lumen::physics::boundary_faces(pair.mesh.tets);
  std::set<std::array<int, 3>> faces, inputs;
  for (Eigen::Index t = 0; t < boundary.rows(); ++t) {
    std::array<int, 3> f = {boundary(t, 0), boundary(t, 1), boundary(t, 2)};
    std::sort(f.begin(), f.end());
    faces.insert(f);
  }
  const int ni = static_cast<int>(in.points.rows());
  for (int s = 0; s < 2; ++s) {
    const lumen::engine::SurfaceMesh& m = s == 0 ? in : out;
    for (Eigen::Index t = 0; t < m.tris.rows(); ++t) {
      std::array<int, 3> f = {m.tris(t, 0) + s * ni, m.tris(t, 1) + s * ni, m.tris(t, 2) + s * ni};
      std::sort(f.begin(), f.end());
      inputs.insert(f);
    }
  }
  EXPECT_EQ(faces, inputs);
  EXPECT_EQ(pair.mesh.rest.topRows(ni), in.points);
  EXPECT_EQ(pair.mesh.surface(lumen::physics::kInnerWall).rows(), in.tris.rows());
  EXPECT_LT(pair.mesh.surface(lumen::physics::kInnerWall).maxCoeff(), ni);

  constexpr int kFrames = 90;
  scene.frames = kFrames;
  const long contacts = expect_never_intersects(scene, file);
  std::printf("%s: %ld tets, %d nodes added, Netgen %.0f ms; %d frames, %ld contacts\n", file.c_str(),
              static_cast<long>(pair.mesh.tets.rows()), pair.added_nodes, pair.mesher_ms, kFrames, contacts);
}
