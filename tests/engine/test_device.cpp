// The device side: the triple buffer's semantics (newest value wins, nothing torn, across threads), the device
// pose source (home before the first reading, the newest pose at each frame, the last pose kept when the device
// disconnects, every handed-out pose recorded) and the session inputs that give device-driven instruments one.
#include <gtest/gtest.h>

#include <thread>

#include <nlohmann/json.hpp>

#include "engine/device.hpp"
#include "engine/scene.hpp"
#include "support/instruments.hpp"

using namespace lumen::engine;
using nlohmann::json;

namespace {

// A value whose halves must agree (a torn read would mix two writes).
struct Pair {
  long a = 0, b = 0;
};

Pose pose_at(double x, double y, double z) {
  Pose p;
  p.position = Eigen::Vector3d(x, y, z);
  return p;
}

DeviceSample reading(const Pose& p, std::uint64_t seq, bool connected = true) {
  DeviceSample s;
  s.pose = p;
  s.seq = seq;
  s.connected = connected;
  return s;
}

}  // namespace

TEST(TripleBuffer, ReadGivesTheNewestValueOnceAndNothingBeforeTheFirstWrite) {
  TripleBuffer<int> b;
  int v = -1;
  EXPECT_FALSE(b.read(v));
  EXPECT_EQ(v, -1);
  b.write(1);
  b.write(2);
  b.write(3);
  ASSERT_TRUE(b.read(v));
  EXPECT_EQ(v, 3);
  v = -1;
  EXPECT_FALSE(b.read(v));  // nothing new
  EXPECT_EQ(v, -1);
  b.write(4);
  ASSERT_TRUE(b.read(v));
  EXPECT_EQ(v, 4);
}

TEST(TripleBuffer, AcrossThreadsValuesAreNeverTornAndNeverGoBack) {
  TripleBuffer<Pair> b;
  constexpr long kWrites = 200000;
  std::thread writer([&] {
    for (long i = 1; i <= kWrites; ++i) b.write(Pair{i, -i});
  });
  long last = 0, reads = 0;
  Pair p;
  // Read until the last value has come through.
  while (last < kWrites) {
    if (!b.read(p)) continue;
    ++reads;
    ASSERT_EQ(p.b, -p.a);   // not torn
    ASSERT_GT(p.a, last);   // a fresh read is newer than the one before
    last = p.a;
  }
  writer.join();
  EXPECT_EQ(last, kWrites);
  EXPECT_GT(reads, 0);
  EXPECT_FALSE(b.read(p));
}

TEST(DevicePoseSource, HomeFirstThenTheNewestReadingAndTheLastPoseWhenDisconnected) {
  auto channel = std::make_shared<PoseChannel>();
  const Pose home = pose_at(0.0, 0.03, 0.05);
  DevicePoseSource src("Tracker", channel, home);
  EXPECT_EQ(src.kind(), "device");
  // The session's start is home, even when a reading came before it; the reading counts from the first frame.
  channel->write(reading(pose_at(0.005, 0.02, 0.05), 1));
  EXPECT_EQ(src.pose(0.0).position, home.position);
  // Two readings between frames: the newer is taken.
  channel->write(reading(pose_at(0.001, 0.02, 0.05), 2));
  channel->write(reading(pose_at(0.002, 0.02, 0.05), 3));
  EXPECT_EQ(src.pose(0.025).position, Eigen::Vector3d(0.002, 0.02, 0.05));
  // Nothing new: the same pose.
  EXPECT_EQ(src.pose(0.05).position, Eigen::Vector3d(0.002, 0.02, 0.05));
  EXPECT_EQ(src.disconnected_frames(), 0);
  // Disconnected: the last pose stays (the reading's pose is not believed), counted per frame until it returns.
  channel->write(reading(pose_at(9.0, 9.0, 9.0), 4, false));
  EXPECT_EQ(src.pose(0.075).position, Eigen::Vector3d(0.002, 0.02, 0.05));
  EXPECT_EQ(src.pose(0.1).position, Eigen::Vector3d(0.002, 0.02, 0.05));
  EXPECT_EQ(src.disconnected_frames(), 2);
  channel->write(reading(pose_at(0.003, 0.02, 0.05), 5));
  EXPECT_EQ(src.pose(0.125).position, Eigen::Vector3d(0.003, 0.02, 0.05));
  EXPECT_EQ(src.disconnected_frames(), 2);
  // Every pose handed out is recorded with its time and frame.
  const std::vector<RecordedPose>& r = src.recorded();
  ASSERT_EQ(r.size(), 6u);
  const double times[] = {0.0, 0.025, 0.05, 0.075, 0.1, 0.125};
  const double xs[] = {0.0, 0.002, 0.002, 0.002, 0.002, 0.003};
  for (size_t i = 0; i < r.size(); ++i) {
    EXPECT_EQ(r[i].t, times[i]);
    EXPECT_EQ(r[i].frame, static_cast<int>(i));
    EXPECT_EQ(r[i].pose.position.x(), xs[i]);
  }
  EXPECT_EQ(src.recorded_keys().size(), r.size());
}

TEST(DevicePoseSource, FeedbackIsPassedOn) {
  DevicePoseSource src("Tracker", std::make_shared<PoseChannel>(), Pose{});
  InstrumentRecord seen;
  double seen_t = -1.0;
  src.on_feedback = [&](double t, const InstrumentRecord& r) {
    seen_t = t;
    seen = r;
  };
  InstrumentRecord rec;
  rec.force = Eigen::Vector3d(0.0, 0.5, 0.0);
  rec.stiffness = 300.0 * Eigen::Matrix3d::Identity();
  src.feedback(0.25, rec);
  EXPECT_EQ(seen_t, 0.25);
  EXPECT_EQ(seen.force, rec.force);
  EXPECT_EQ(seen.stiffness, rec.stiffness);
}

TEST(DeviceInputs, InstrumentsWithADeviceNameGetADeviceSourceAtHome) {
  json s = lumen::test::small_tube_scene("device");
  s["frames"] = 10;
  s["instruments"] = json::parse(R"([
    {"name": "scripted", "shape": {"type": "rod", "radius": 0.002, "length": 0.04},
     "track": [{"t": 0.0, "position": [0.0, 0.03, 0.02]}]},
    {"name": "tracked", "shape": {"type": "rod", "radius": 0.002, "length": 0.04}, "device_name": "Tracker",
     "track": [{"t": 0.0, "position": [0.0, 0.03, 0.05]}]},
    {"name": "device only", "shape": {"type": "rod", "radius": 0.002, "length": 0.04}, "device_name": "Stylus",
     "to_organ": [1, 0, 0, 0.01,  0, 1, 0, 0.04,  0, 0, 1, 0.08,  0, 0, 0, 1]}])");
  const Scene scene = parse_scene(s.dump(), "dir/s.json");
  DeviceInputs d = make_device_inputs(scene);
  ASSERT_EQ(d.inputs.instruments.size(), 3u);
  EXPECT_EQ(d.inputs.instruments[0]->kind(), "track");
  ASSERT_EQ(d.instrument, (std::vector<int>{1, 2}));
  EXPECT_EQ(d.sources[0]->device_name(), "Tracker");
  EXPECT_EQ(d.sources[1]->device_name(), "Stylus");
  // Homes: the track's start; the device origin mapped by to_organ.
  EXPECT_EQ(d.inputs.instruments[1]->pose(0.0).position, Eigen::Vector3d(0.0, 0.03, 0.05));
  EXPECT_EQ(d.inputs.instruments[2]->pose(0.0).position, Eigen::Vector3d(0.01, 0.04, 0.08));
  // The channel the slot's source reads (from the first frame on).
  d.channels[0]->write(reading(pose_at(0.0, 0.02, 0.05), 1));
  EXPECT_EQ(d.inputs.instruments[1]->pose(0.025).position, Eigen::Vector3d(0.0, 0.02, 0.05));
}
