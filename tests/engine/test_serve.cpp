// lumen serve in-process: a simulated device (a mass-spring "hand" chasing a target) on loopback drives an
// instrument through the real OpenIGTLink client library and feels the SENSOR reaction; the served session's
// replay plays back to the same frames and reactions bit for bit; malformed messages are counted by reason and
// ignored while the session goes on.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iterator>
#include <thread>
#include <vector>

#include <igtlClientSocket.h>
#include <igtlMessageHeader.h>
#include <igtlPositionMessage.h>
#include <igtlSensorMessage.h>
#include <igtlStatusMessage.h>
#include <igtlTransformMessage.h>
#include <nlohmann/json.hpp>

#include "engine/device_client.hpp"
#include "engine/serve.hpp"
#include "support/files.hpp"
#include "support/instruments.hpp"
#include "support/tube.hpp"

using namespace lumen::engine;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

using lumen::test::kPaperOuterRadius;

// The small tube with a device-driven 3 mm probe: device origin 0.5 mm above the outer wall's top.
json device_scene(int frames) {
  const json probe = {{"type", "sphere_probe"}, {"tip_radius", 0.003}, {"shaft_radius", 0.002}, {"shaft_length", 0.04}};
  return lumen::test::device_tube_scene("probe", frames, probe, "Hand", Eigen::Vector3d(0.0, kPaperOuterRadius + 0.0005, 0.05));
}

// An OpenIGTLink client on loopback (the real client library, engine/device_client.hpp).
struct Client : DeviceClient {
  bool connect(int port) { return DeviceClient::connect("127.0.0.1", port); }
  void send(igtl::MessageBase* m) { send_bytes(m->GetPackPointer(), m->GetPackSize()); }
};

// The device scene compiled, and session options without rendering.
struct Served {
  explicit Served(int frames)
      : scene(parse_scene(device_scene(frames).dump(), "serve.json")), model(compile_model(scene)) {
    session.render = false;
  }
  Scene scene;
  std::unique_ptr<Model> model;
  SessionOptions session;
};

// A served session on a free port with `device` run on its own thread once the bridge listens.
template <class Device>
ServeResult serve_with(const Scene& scene, const Model& model, const SessionOptions& session, Device device) {
  Listener listener("127.0.0.1", 0);
  const int port = listener.port();
  ServeOptions opt;
  opt.session = session;
  std::thread client([&] { device(port); });
  ServeResult r = serve_session(scene, model, std::move(listener), opt);
  client.join();
  return r;
}

// Every field of two frames' records that the simulation decides (timings left out), equal bit for bit.
void expect_same_frames(const std::vector<FrameRecord>& a, const std::vector<FrameRecord>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a[i].instruments.size(), b[i].instruments.size());
    EXPECT_EQ(a[i].max_displacement, b[i].max_displacement) << "frame " << a[i].frame;
    EXPECT_EQ(a[i].contacts, b[i].contacts) << "frame " << a[i].frame;
    for (size_t k = 0; k < a[i].instruments.size(); ++k) {
      const InstrumentRecord &p = a[i].instruments[k], &q = b[i].instruments[k];
      EXPECT_EQ(p.position, q.position) << "frame " << a[i].frame;
      EXPECT_EQ(p.rotation.coeffs(), q.rotation.coeffs()) << "frame " << a[i].frame;
      EXPECT_EQ(p.force, q.force) << "frame " << a[i].frame;
      EXPECT_EQ(p.torque, q.torque) << "frame " << a[i].frame;
      EXPECT_EQ(p.stiffness, q.stiffness) << "frame " << a[i].frame;
      EXPECT_EQ(p.contacts, q.contacts) << "frame " << a[i].frame;
    }
  }
}

}  // namespace

TEST(Serve, ASimulatedHandDrivesTheProbeFeelsTheTissueAndTheReplayIsBitIdentical) {
  constexpr int kFrames = 48;
  Served f(kFrames);
  const Scene& scene = f.scene;
  SessionOptions& session = f.session;
  session.check = true;
  lumen::Points served_x, replayed_x;
  session.on_frame = [&](const Model&, const State& s, const FrameRecord&) { served_x = s.x; };
  // The hand (0.1 kg on a 200 N/m spring, damped, pushed by the reaction it feels, at 1 kHz) chases a target that
  // goes from 0 to 3.5 mm into the tissue in 0.6 s, past the session's 1.2 s end (the server closes the connection).
  Client hand;
  double max_up = 0.0;
  const ServeResult served = serve_with(scene, *f.model, session, [&](int port) {
    ASSERT_TRUE(hand.connect(port));
    hand.start_reading();
    HandSpec spec;
    spec.device = "Hand";
    spec.seconds = 1.1;
    constexpr double kDepth = 0.0035, kRamp = 0.6;
    spec.target_y_m = [](double t) { return -kDepth * std::min(1.0, t / kRamp); };
    run_hand(hand, spec);
    max_up = hand.max_force();
    hand.finish();
  });
  const json& r = served.session.report;
  ASSERT_EQ(served.session.frames.size(), static_cast<size_t>(kFrames));
  EXPECT_GT(r["serve"]["received"]["TRANSFORM"].get<long>(), kFrames);
  EXPECT_EQ(r["serve"]["rejected_total"].get<long>(), 0);
  EXPECT_GT(r["serve"]["sensors_sent"].get<long>(), 0);
  EXPECT_GT(r["serve"]["latency_ms"]["answered"].get<long>(), 0);
  EXPECT_GT(r["haptics"]["ticks"].get<long>(), 0);
  EXPECT_EQ(r["frames_with_instrument_intersections"].get<long>(), 0);
  // The hand got the probe into the tissue and felt it push back over SENSOR.
  int touching = 0;
  for (const FrameRecord& f : served.session.frames) touching += f.instruments[0].contacts > 0;
  EXPECT_GT(touching, 0);
  EXPECT_GT(hand.sensors(), 0);
  EXPECT_GT(max_up, 0.0);
  // The probe was where the hand sent it: the last frame's tip below the device's start.
  EXPECT_LT(served.session.frames.back().instruments[0].position.y(), kPaperOuterRadius + 0.0005);

  // Replay: the recorded poses played back give the same frames and reactions, bit for bit.
  const fs::path dir = fs::temp_directory_path() / "lumen_serve_replay";
  fs::remove_all(dir);
  write_replay(dir.string(), served);
  int frames = 0;
  Inputs replay = make_replay_inputs(scene, dir.string(), frames);
  EXPECT_EQ(frames, kFrames);
  SessionOptions again;
  again.render = false;
  again.frames = frames;
  again.on_frame = [&](const Model&, const State& s, const FrameRecord&) { replayed_x = s.x; };
  const SessionResult replayed = run_session(*f.model, std::move(replay), again);
  expect_same_frames(served.session.frames, replayed.frames);
  EXPECT_EQ(served_x, replayed_x);
}

TEST(Serve, MalformedMessagesAreCountedByReasonAndIgnored) {
  constexpr int kFrames = 16;
  Served f(kFrames);
  const Scene& scene = f.scene;
  SessionOptions& session = f.session;
  Client c;
  const Eigen::Vector3f good_mm(1.0f, 2.0f, 0.0f);
  const ServeResult served = serve_with(scene, *f.model, session, [&](int port) {
    ASSERT_TRUE(c.connect(port));
    c.start_reading();
    const Eigen::Matrix3f id = Eigen::Matrix3f::Identity();
    // Bad CRC: a packed TRANSFORM with one body byte changed.
    {
      igtl::TransformMessage::Pointer m = igtl::TransformMessage::New();
      m->SetDeviceName("Hand");
      igtl::Matrix4x4 t;
      igtl::IdentityMatrix(t);
      m->SetMatrix(t);
      m->Pack();
      static_cast<unsigned char*>(m->GetPackBodyPointer())[5] ^= 0x5a;
      c.send(m);
    }
    // Short body: a TRANSFORM header announcing 12 body bytes (a TRANSFORM has 48), and 12 bytes.
    {
      igtl::TransformMessage::Pointer m = igtl::TransformMessage::New();
      m->SetDeviceName("Hand");
      m->Pack();
      constexpr int kHeader = 58, kBodySizeOffset = 42, kShort = 12;  // header: body size, big-endian uint64
      std::vector<unsigned char> bytes(static_cast<unsigned char*>(m->GetPackPointer()),
                                       static_cast<unsigned char*>(m->GetPackPointer()) + kHeader + kShort);
      for (int k = 0; k < 8; ++k) bytes[kBodySizeOffset + k] = k == 7 ? kShort : 0;
      c.send_bytes(bytes.data(), static_cast<int>(bytes.size()));
    }
    // Unknown type, unknown device, non-finite pose, non-orthonormal rotation.
    {
      igtl::StatusMessage::Pointer m = igtl::StatusMessage::New();
      m->SetDeviceName("Hand");
      m->SetCode(igtl::StatusMessage::STATUS_OK);
      m->Pack();
      c.send(m);
    }
    c.send_transform("Nobody", id, good_mm);
    c.send_transform("Hand", id, Eigen::Vector3f(std::nanf(""), 0.0f, 0.0f));
    c.send_transform("Hand", 2.0f * id, good_mm);
    // Then a good one, as a POSITION (quaternion x, y, z, w).
    {
      igtl::PositionMessage::Pointer m = igtl::PositionMessage::New();
      m->SetDeviceName("Hand");
      m->SetPosition(good_mm.x(), good_mm.y(), good_mm.z());
      m->SetQuaternion(0.0f, 0.0f, 0.0f, 1.0f);
      m->Pack();
      c.send(m);
    }
    c.finish();
  });
  const json& s = served.session.report["serve"];
  ASSERT_EQ(served.session.frames.size(), static_cast<size_t>(kFrames));
  for (const char* reason : {"bad_crc", "short_body", "unknown_type", "unknown_device", "non_finite_pose",
                             "non_orthonormal_rotation"})
    EXPECT_EQ(s["rejected"].value(reason, 0L), 1L) << reason << "\n" << s.dump(1);
  EXPECT_EQ(s["rejected_total"].get<long>(), 6);
  EXPECT_EQ(s["received"]["TRANSFORM"].get<long>(), 5);
  EXPECT_EQ(s["received"]["POSITION"].get<long>(), 1);
  EXPECT_EQ(s["received"]["STATUS"].get<long>(), 1);
  // Only the good pose moved the probe: 1 mm along x, 2 mm up from the device origin.
  const Eigen::Vector3d expected(0.001, kPaperOuterRadius + 0.0005 + 0.002, 0.05);
  EXPECT_LE((served.session.frames.back().instruments[0].position - expected).norm(), 1e-9);
}

TEST(Serve, APortInUseIsAClearError) {
  Listener taken("127.0.0.1", 0);
  const std::string msg = lumen::test::message_of<InputError>([&] { Listener again("127.0.0.1", taken.port()); });
  EXPECT_NE(msg.find("--port " + std::to_string(taken.port()) + ": cannot listen: Address already in use"),
            std::string::npos)
      << msg;
}

TEST(Serve, ADeviceThatDisconnectsLeavesTheInstrumentAtItsLastPoseAndMayReconnect) {
  constexpr int kFrames = 40;
  Served f(kFrames);
  const Scene& scene = f.scene;
  SessionOptions& session = f.session;
  std::atomic<int> frames_done{0};
  session.on_frame = [&](const Model&, const State&, const FrameRecord&) { ++frames_done; };
  auto wait_frames = [&](int n) {
    while (frames_done.load() < n) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  };
  const Eigen::Vector3f a_mm(2.0f, 1.0f, 0.0f), b_mm(-1.0f, 3.0f, 0.0f);
  std::vector<Eigen::Vector3d> positions;
  const ServeResult served = serve_with(scene, *f.model, session, [&](int port) {
    // First client: one pose, then it goes away after a few frames; a second client comes later with another.
    Client first;
    ASSERT_TRUE(first.connect(port));
    first.send_transform("Hand", Eigen::Matrix3f::Identity(), a_mm);
    wait_frames(5);
    first.close();
    wait_frames(20);
    Client second;
    ASSERT_TRUE(second.connect(port));
    second.start_reading();
    second.send_transform("Hand", Eigen::Matrix3f::Identity(), b_mm);
    second.finish();
  });
  const json& s = served.session.report["serve"];
  EXPECT_EQ(s["connections"].get<long>(), 2);
  EXPECT_GT(s["devices"][0]["disconnected_frames"].get<long>(), 0);
  // While disconnected the probe stayed at the first pose; at the end it is at the second.
  const Eigen::Vector3d origin(0.0, kPaperOuterRadius + 0.0005, 0.05);
  const Eigen::Vector3d a = origin + 1e-3 * a_mm.cast<double>(), b = origin + 1e-3 * b_mm.cast<double>();
  EXPECT_LE((served.session.frames[19].instruments[0].position - a).norm(), 1e-9);
  EXPECT_LE((served.session.frames.back().instruments[0].position - b).norm(), 1e-9);
}

TEST(Serve, TheSensorReactionIsInTheDevicesFrame) {
  // to_organ turns the device frame 90 degrees about z (device x -> organ y) and shifts it.
  auto to_sim = std::make_shared<PoseChannel>(), to_haptics = std::make_shared<PoseChannel>();
  BridgeSlot slot;
  slot.device_name = "Hand";
  slot.to_organ = Eigen::Translation3d(0.0, 0.1, 0.0) * Eigen::AngleAxisd(0.5 * EIGEN_PI, Eigen::Vector3d::UnitZ());
  slot.to_simulation = to_sim;
  slot.to_haptics = to_haptics;
  Listener listener("127.0.0.1", 0);
  const int port = listener.port();
  Bridge bridge(std::move(listener), {slot}, [] { return 0.0; });
  bridge.start();
  Client c;
  ASSERT_TRUE(c.connect(port));
  c.start_reading();
  // A pose 10 mm along device x arrives 10 mm along organ y (plus the shift).
  ASSERT_TRUE(c.send_transform("Hand", Eigen::Matrix3f::Identity(), Eigen::Vector3f(10.0f, 0.0f, 0.0f)));
  DeviceSample s;
  while (!to_sim->read(s)) std::this_thread::yield();
  EXPECT_LE((s.pose.position - Eigen::Vector3d(0.0, 0.11, 0.0)).norm(), 1e-9);
  // A force along organ y goes back along device x; sent until the client has one (the bridge records its socket
  // after the pose).
  HapticForce f;
  f.force = Eigen::Vector3d(0.0, 0.25, 0.0);
  while (c.sensors() == 0) {
    bridge.send_reactions({f}, 0.0);
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  bridge.stop();
  c.finish();
  EXPECT_LE((c.force() - Eigen::Vector3d(0.25, 0.0, 0.0)).norm(), 1e-12);
}

namespace {

// Every SENSOR in a byte stream, parsed with the OpenIGTLink library: header, then body with its CRC checked;
// false at the first message that is torn, of another type or fails its CRC.
bool parse_sensors(const std::vector<std::uint8_t>& stream, std::vector<double>& first_values) {
  size_t at = 0;
  while (at < stream.size()) {
    igtl::MessageHeader::Pointer h = igtl::MessageHeader::New();
    h->InitPack();
    if (stream.size() - at < static_cast<size_t>(h->GetPackSize())) return false;
    std::memcpy(h->GetPackPointer(), stream.data() + at, static_cast<size_t>(h->GetPackSize()));
    h->Unpack();
    if (std::strcmp(h->GetDeviceType(), "SENSOR") != 0) return false;
    igtl::SensorMessage::Pointer m = igtl::SensorMessage::New();
    m->SetMessageHeader(h);
    m->AllocatePack();
    const size_t body = static_cast<size_t>(m->GetPackBodySize());
    at += static_cast<size_t>(h->GetPackSize());
    if (stream.size() - at < body) return false;
    std::memcpy(m->GetPackBodyPointer(), stream.data() + at, body);
    at += body;
    if (!(m->Unpack(1) & igtl::MessageHeader::UNPACK_BODY)) return false;
    first_values.push_back(m->GetValue(0));
  }
  return true;
}

}  // namespace

// A socket that takes the SENSOR messages in pieces (as a full send buffer does: some bytes, or none): the rest
// of a partly sent message goes out first on the next round and no torn message reaches the client. Every
// message the client parses is whole and CRC-checked, in order, and sent + dropped accounts for every round.
TEST(Serve, ASensorPartlySentToAFullSocketIsFinishedOnTheNextRound) {
  auto to_sim = std::make_shared<PoseChannel>(), to_haptics = std::make_shared<PoseChannel>();
  BridgeSlot slot;
  slot.device_name = "Hand";
  slot.to_simulation = to_sim;
  slot.to_haptics = to_haptics;
  Listener listener("127.0.0.1", 0);
  const int port = listener.port();
  Bridge bridge(std::move(listener), {slot}, [] { return 0.0; });
  // The socket takes at most these many bytes per write, in turn (0: full).
  constexpr size_t kTakes[] = {0, 7, 58, 0, 0, 31, 1000, 90, 3, 0, 1000, 1000};
  std::atomic<size_t> call{0};
  bridge.set_sender([&](int fd, const void* data, size_t size) -> ssize_t {
    const size_t take = std::min(size, kTakes[call.fetch_add(1) % std::size(kTakes)]);
    return take == 0 ? -1 : send(fd, data, take, MSG_NOSIGNAL);
  });
  bridge.start();
  // A raw client: one TRANSFORM to claim the device, then it reads nothing until the end (a slow reader).
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  igtl::TransformMessage::Pointer t = igtl::TransformMessage::New();
  t->SetDeviceName("Hand");
  t->Pack();
  ASSERT_EQ(send(fd, t->GetPackPointer(), static_cast<size_t>(t->GetPackSize()), 0), t->GetPackSize());
  DeviceSample s;
  while (!to_sim->read(s)) std::this_thread::yield();
  // Rounds with force 0 until the bridge writes to the client's socket (the first write takes nothing: dropped),
  // then rounds with force k along x.
  HapticForce f;
  while (call.load() == 0) {
    bridge.send_reactions({f}, 0.0);
    std::this_thread::yield();
  }
  constexpr int kRounds = 200;
  for (int k = 1; k <= kRounds; ++k) {
    f.force = Eigen::Vector3d(k, 0.0, 0.0);
    bridge.send_reactions({f}, 0.0);
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  bridge.stop();
  std::vector<std::uint8_t> stream;
  std::uint8_t chunk[4096];
  for (ssize_t n; (n = recv(fd, chunk, sizeof chunk, 0)) > 0;) stream.insert(stream.end(), chunk, chunk + n);
  close(fd);
  std::vector<double> values;
  ASSERT_TRUE(parse_sensors(stream, values)) << "a torn or corrupt message in " << stream.size() << " bytes";
  const json r = bridge.report();
  EXPECT_EQ(static_cast<long>(values.size()), r["sensors_sent"].get<long>());
  EXPECT_GT(r["sensors_partial"].get<long>(), 10);
  EXPECT_GT(r["sensors_dropped"].get<long>(), 10);
  // Every message (the first one and one per round) was sent whole, dropped whole, or is the last left in pieces.
  const long accounted = r["sensors_sent"].get<long>() + r["sensors_dropped"].get<long>();
  EXPECT_GE(accounted, kRounds);
  EXPECT_LE(accounted, kRounds + 1);
  // In order, each the force of its own round.
  for (size_t i = 0; i < values.size(); ++i) {
    EXPECT_EQ(values[i], std::round(values[i]));
    EXPECT_GE(values[i], 1.0);
    EXPECT_LE(values[i], kRounds);
    if (i > 0) {
      EXPECT_GT(values[i], values[i - 1]);
    }
  }
}

// A violent device: the probe's pose jumps every 25 ms between 0.5 mm above the tube and 20 mm down through its top
// wall into the lumen, 15 mm to either side, against a contact cap of 60 rows. Every frame stays finite and free of
// intersections (exact check, walls and instrument), frames over the cap among them.
TEST(Serve, AViolentDeviceAgainstTheContactCapStaysFiniteAndIntersectionFree) {
  constexpr int kFrames = 40;
  constexpr int kMaxContactRows = 60;
  json s = device_scene(kFrames);
  s["collision"]["max_contact_rows"] = kMaxContactRows;
  const Scene scene = parse_scene(s.dump(), "violent.json");
  const auto model = compile_model(scene);
  SessionOptions session;
  session.render = false;
  session.check = true;
  Client hand;
  const ServeResult served = serve_with(scene, *model, session, [&](int port) {
    ASSERT_TRUE(hand.connect(port));
    hand.start_reading();
    // Device millimetres (device origin 0.5 mm above the outer wall's top).
    const Eigen::Vector3f poses[] = {{0.0f, -20.0f, 0.0f}, {15.0f, 0.0f, 0.0f}, {0.0f, -20.0f, 0.0f},
                                     {-15.0f, -18.0f, 5.0f}, {0.0f, 0.0f, 0.0f}};
    constexpr int kJumps = 36;
    for (int k = 0; k < kJumps; ++k) {
      if (!hand.send_transform("Hand", Eigen::Matrix3f::Identity(), poses[k % std::size(poses)])) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(25));
    }
    hand.finish();
  });
  ASSERT_EQ(served.session.frames.size(), static_cast<size_t>(kFrames));
  int capped = 0, stopped = 0;
  for (const FrameRecord& f : served.session.frames) {
    EXPECT_EQ(f.intersecting_pairs, 0) << "frame " << f.frame;
    EXPECT_EQ(f.instrument_intersecting_pairs, 0) << "frame " << f.frame;
    EXPECT_FALSE(f.numerical_failure) << "frame " << f.frame;
    EXPECT_TRUE(std::isfinite(f.max_displacement)) << "frame " << f.frame;
    EXPECT_TRUE(f.instruments[0].force.allFinite()) << "frame " << f.frame;
    EXPECT_TRUE(f.instruments[0].position.allFinite()) << "frame " << f.frame;
    capped += f.contact_rows_capped;
    stopped += f.fallback;
  }
  // The jumps were violent: frames went over the cap and had to stop short of the device's pose. (A capped frame
  // whose sweep holds no true contact, only pairs within the gap, runs its whole motion: not a fallback frame.)
  EXPECT_GT(capped, 0);
  EXPECT_GT(stopped, 0);
  std::printf("violent device: %d of %d frames capped, %d took the fallback\n", capped, kFrames, stopped);
}
