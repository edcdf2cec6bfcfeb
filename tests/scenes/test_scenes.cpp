// Whole sessions of the shipped scenes, with the exact intersection check (independent of the CCD code) on
// every frame: zero intersecting inner-wall pairs with collision processing, and demonstrably some without it.
#include <gtest/gtest.h>

#include <string>

#include "engine/session.hpp"
#include "engine/simulation.hpp"

using namespace lumen::engine;

namespace {

SessionResult run_checked(const std::string& scene_file) {
  Scene scene = load_scene(std::string(LUMEN_SOURCE_DIR) + "/scenes/" + scene_file);
  auto model = compile_model(scene);
  SessionOptions opt;
  opt.render = false;
  opt.check = true;
  return run_session(*model, make_inputs(scene), opt);
}

void expect_never_intersects(const std::string& scene_file) {
  SessionResult r = run_checked(scene_file);
  long contacts = 0;
  for (const auto& f : r.frames) {
    EXPECT_EQ(f.intersecting_pairs, 0) << scene_file << " frame " << f.frame;
    EXPECT_FALSE(f.numerical_failure) << scene_file << " frame " << f.frame;
    contacts += f.contacts;
  }
  // The scene really makes the walls meet (otherwise the check proves nothing).
  EXPECT_GT(contacts, 0) << scene_file;
}

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
