// The response's restricted re-check against its brute-force twin, the full re-check (collision.recheck "full":
// every wall feature tested again in every round), and the restricted first detection against its twin, the full
// one (collision.detection "full": every wall feature every frame), on the real frames of shipped scenes: the two
// runs must find the same contacts in every round, so every frame's positions, contacts, rounds and forces are
// bit-identical.
#include <gtest/gtest.h>

#include <functional>
#include <string>

#include "engine/simulation.hpp"

using namespace lumen::engine;

namespace {

// Frames whose response took at least one re-check, and at least two (a re-check found something); frames whose
// first detection was restricted, and among them those where it found wall contacts.
struct RoundCounts {
  int rechecked = 0, refound = 0;
  int restricted_first = 0, restricted_found = 0;
};

// Run a shipped scene (the defaults: both restricted) beside its twin (`make_full` turns one restriction off).
RoundCounts expect_twins_equal(const std::string& file, const std::function<void(Scene&)>& make_full) {
  Scene restricted = load_scene(std::string(LUMEN_SOURCE_DIR) + "/scenes/" + file);
  EXPECT_EQ(restricted.collision.recheck, Recheck::kRestricted) << "the default";
  EXPECT_EQ(restricted.collision.detection, Detection::kRestricted) << "the default";
  Scene full = restricted;
  make_full(full);
  const auto model_r = compile_model(restricted);
  const auto model_f = compile_model(full);
  Inputs inputs_r = make_inputs(restricted), inputs_f = make_inputs(full);
  State state_r = make_state(*model_r), state_f = make_state(*model_f);
  RoundCounts counts;
  for (int i = 0; i < restricted.frames; ++i) {
    FrameRecord r, f;
    step(*model_r, inputs_r, state_r, r);
    step(*model_f, inputs_f, state_f, f);
    const std::string where = file + " frame " + std::to_string(i + 1);
    EXPECT_EQ(r.response_iterations, f.response_iterations) << where;
    EXPECT_EQ(r.contacts, f.contacts) << where;
    EXPECT_EQ(r.fallback, f.fallback) << where;
    EXPECT_EQ(r.contact_force, f.contact_force) << where;
    EXPECT_TRUE(state_r.x == state_f.x) << where << ": positions differ";
    EXPECT_EQ(r.instruments.size(), f.instruments.size()) << where;
    if (r.instruments.size() != f.instruments.size()) return counts;
    for (size_t k = 0; k < r.instruments.size(); ++k) {
      EXPECT_EQ(r.instruments[k].contacts, f.instruments[k].contacts) << where;
      EXPECT_TRUE(r.instruments[k].force == f.instruments[k].force) << where << ": instrument force differs";
    }
    counts.rechecked += r.response_iterations >= 1;
    counts.refound += r.response_iterations >= 2;
    counts.restricted_first += !r.full_detection;
    counts.restricted_found += !r.full_detection && r.first_contacts > 0;
    EXPECT_EQ(r.first_contacts, f.first_contacts) << where;
  }
  return counts;
}

RoundCounts expect_restricted_equals_full(const std::string& file) {
  return expect_twins_equal(file, [](Scene& s) { s.collision.recheck = Recheck::kFull; });
}

RoundCounts expect_restricted_first_equals_full(const std::string& file) {
  return expect_twins_equal(file, [](Scene& s) { s.collision.detection = Detection::kFull; });
}

}  // namespace

// Tool contacts only: the probe presses the tube.
TEST(RestrictedRecheck, FindsWhatTheFullRecheckFindsWhenAProbePressesTheTube) {
  const RoundCounts c = expect_restricted_equals_full("instrument-probe-press.json");
  EXPECT_GT(c.rechecked, 60);
}

// Tool contacts and the walls' self-contacts together: two rods pinch the lumen shut.
TEST(RestrictedRecheck, FindsWhatTheFullRecheckFindsWhenTwoToolsPinchTheLumenShut) {
  const RoundCounts c = expect_restricted_equals_full("instrument-two-tools-pinch.json");
  EXPECT_GT(c.rechecked, 60);
  EXPECT_GT(c.refound, 0) << "no re-check found a new contact: the twin proves little";
}

// Self-contacts only: the paper's Fig. 5 squeeze, and the full closure (their re-checks find nothing new: the
// first round's solve holds; the two-tool pinch above is the one where re-checks find contacts).
TEST(RestrictedRecheck, FindsWhatTheFullRecheckFindsWhenTheWallsMeet) {
  for (const char* file : {"fig5-squeeze.json", "full-closure.json"}) {
    const RoundCounts c = expect_restricted_equals_full(file);
    EXPECT_GT(c.rechecked, 10) << file;
  }
}

// The frames' first detections, restricted by the last full one's proximity (collision.detection "restricted"),
// against the full ones. Self-contacts only: the squeeze and the full closure, whose walls come into contact on
// restricted frames, and tool and wall contacts together in the two-tool pinch.
TEST(RestrictedDetection, FindsWhatTheFullDetectionFindsWhenTheWallsMeet) {
  for (const char* file : {"fig5-squeeze.json", "full-closure.json"}) {
    const RoundCounts c = expect_restricted_first_equals_full(file);
    EXPECT_GT(c.restricted_first, 10) << file << ": few restricted first detections, the twin proves little";
    EXPECT_GT(c.restricted_found, 5) << file << ": no restricted first detection found a contact";
  }
}

TEST(RestrictedDetection, FindsWhatTheFullDetectionFindsWhenTwoToolsPinchTheLumenShut) {
  const RoundCounts c = expect_restricted_first_equals_full("instrument-two-tools-pinch.json");
  EXPECT_GT(c.restricted_first, 10);
  EXPECT_GT(c.restricted_found, 5);
}
