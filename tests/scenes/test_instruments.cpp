// The shipped instrument scenes, every frame: no instrument-organ and no inner-wall intersection by the exact
// check, every tool vertex outside the organ and no organ node inside a tool (brute force, independent of the
// contact code), and the force on the instruments balanced by the organ's elastic response K u.
#include <gtest/gtest.h>

#include <string>

#include "engine/session.hpp"
#include "support/instruments.hpp"

using namespace lumen::engine;

namespace {

lumen::test::CheckedRun run_instrument_scene(const std::string& file) {
  return lumen::test::run_checked(load_scene(std::string(LUMEN_SOURCE_DIR) + "/scenes/" + file));
}

// The common checks; returns the number of frames on which some instrument touched the organ.
int expect_tools_never_penetrate(const std::string& file, const lumen::test::CheckedRun& run) {
  constexpr double kClearanceGapFraction = 0.25;  // the re-check clears half the gap
  const double gap = run.model->collision.gap;
  int touching = 0;
  for (size_t i = 0; i < run.result.frames.size(); ++i) {
    const FrameRecord& f = run.result.frames[i];
    EXPECT_EQ(f.instrument_intersecting_pairs, 0) << file << " frame " << f.frame;
    EXPECT_EQ(f.intersecting_pairs, 0) << file << " frame " << f.frame;
    EXPECT_FALSE(f.numerical_failure) << file << " frame " << f.frame;
    EXPECT_GE(run.clearance[i].min_tool_vertex, kClearanceGapFraction * gap) << file << " frame " << f.frame;
    EXPECT_EQ(run.clearance[i].organ_nodes_inside_tool, 0) << file << " frame " << f.frame;
    // Linear quasi-static, no probe: the forces on the instruments and the organ's elastic forces cancel.
    Eigen::Vector3d on_tools = Eigen::Vector3d::Zero();
    int contacts = 0;
    for (const InstrumentRecord& in : f.instruments) {
      on_tools += in.force;
      contacts += in.contacts;
    }
    if (!f.fallback) {
      EXPECT_LE((on_tools + run.elastic[i].force).norm(), 1e-6 * run.elastic[i].force.norm() + 1e-12)
          << file << " frame " << f.frame;
    }
    touching += contacts > 0;
  }
  return touching;
}

}  // namespace

// The paper's Fig. 4 done with a tool: a 3 mm sphere-tipped probe presses the tube 3.5 mm in.
TEST(InstrumentScenes, ProbePressNeverPenetratesAndTheOrganPushesBack) {
  const std::string file = "instrument-probe-press.json";
  const lumen::test::CheckedRun run = run_instrument_scene(file);
  EXPECT_GT(expect_tools_never_penetrate(file, run), 60);
  // The organ pushes the probe back, more the deeper it goes.
  const FrameRecord& mid = run.result.frames[run.result.frames.size() / 2];
  const FrameRecord& last = run.result.frames.back();
  EXPECT_GT(mid.instruments[0].force.y(), 0.0);
  EXPECT_GT(last.instruments[0].force.y(), mid.instruments[0].force.y());
}

// Two rods pinch the tube shut: tool contacts and the walls' self-contacts together.
TEST(InstrumentScenes, TwoToolsPinchTheLumenShutWithoutIntersection) {
  const std::string file = "instrument-two-tools-pinch.json";
  const lumen::test::CheckedRun run = run_instrument_scene(file);
  EXPECT_GT(expect_tools_never_penetrate(file, run), 60);
  // The lumen really shut: on the last frame the walls hold self-contacts besides the tools' contacts.
  const FrameRecord& last = run.result.frames.back();
  EXPECT_GT(last.contacts, last.instruments[0].contacts + last.instruments[1].contacts);
  // Opposite tools, opposite forces (the organ is held at its ends, so they need not cancel exactly).
  EXPECT_GT(last.instruments[0].force.y(), 0.0);
  EXPECT_LT(last.instruments[1].force.y(), 0.0);
}
