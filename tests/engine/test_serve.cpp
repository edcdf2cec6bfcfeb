// lumen serve in-process: a simulated device (a mass-spring "hand" chasing a target) on loopback drives an
// instrument through the real OpenIGTLink client library and feels the SENSOR reaction; the served session's
// replay plays back to the same frames and reactions bit for bit; malformed messages are counted by reason and
// ignored while the session goes on.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <thread>

#include <igtlClientSocket.h>
#include <igtlMessageHeader.h>
#include <igtlPositionMessage.h>
#include <igtlSensorMessage.h>
#include <igtlStatusMessage.h>
#include <igtlTransformMessage.h>
#include <nlohmann/json.hpp>

#include "engine/serve.hpp"
#include "support/files.hpp"
#include "support/instruments.hpp"

using namespace lumen::engine;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

constexpr double kOuterRadius = 0.013;
constexpr double kMmPerM = 1e3;

// The small tube with a device-driven 3 mm probe: device origin 0.5 mm above the outer wall's top.
json device_scene(int frames) {
  json s = lumen::test::small_tube_scene("serve");
  s["frames"] = frames;
  s["collision"] = {{"self", true}, {"gap", 1e-4}};
  s["instruments"] = {{{"name", "probe"},
                       {"shape", {{"type", "sphere_probe"}, {"tip_radius", 0.003}, {"shaft_radius", 0.002},
                                  {"shaft_length", 0.04}}},
                       {"device_name", "Hand"},
                       {"to_organ", {1, 0, 0, 0, 0, 1, 0, kOuterRadius + 0.0005, 0, 0, 1, 0.05, 0, 0, 0, 1}}}};
  return s;
}

// An OpenIGTLink client on loopback: igtl::ClientSocket sends; a reader thread takes every SENSOR back until the
// server closes the connection.
struct Client {
  igtl::ClientSocket::Pointer socket = igtl::ClientSocket::New();
  std::thread reader;
  std::atomic<long> sensors{0};
  std::atomic<double> fy{0.0}, max_fy{0.0};

  bool connect(int port) { return socket->ConnectToServer("127.0.0.1", port) == 0; }
  void start_reading() {
    reader = std::thread([this] {
      for (;;) {
        igtl::MessageHeader::Pointer h = igtl::MessageHeader::New();
        h->InitPack();
        if (socket->Receive(h->GetPackPointer(), h->GetPackSize()) != h->GetPackSize()) return;
        h->Unpack();
        igtl::SensorMessage::Pointer m = igtl::SensorMessage::New();
        m->SetMessageHeader(h);
        m->AllocatePack();
        if (socket->Receive(m->GetPackBodyPointer(), m->GetPackBodySize()) != m->GetPackBodySize()) return;
        if (std::strcmp(h->GetDeviceType(), "SENSOR") != 0) continue;
        m->Unpack(1);
        ++sensors;
        fy = m->GetValue(1);
        if (fy > max_fy) max_fy = fy.load();
      }
    });
  }
  void send(igtl::MessageBase* m) { socket->Send(m->GetPackPointer(), m->GetPackSize()); }
  void send_transform(const std::string& device, const Eigen::Matrix3f& r, const Eigen::Vector3f& p_mm) {
    igtl::TransformMessage::Pointer m = igtl::TransformMessage::New();
    m->SetDeviceName(device.c_str());
    igtl::Matrix4x4 t;
    igtl::IdentityMatrix(t);
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) t[i][j] = r(i, j);
      t[i][3] = p_mm[i];
    }
    m->SetMatrix(t);
    m->Pack();
    send(m);
  }
  void finish() {
    if (reader.joinable()) reader.join();
    socket->CloseSocket();
  }
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
  const Scene scene = parse_scene(device_scene(kFrames).dump(), "serve.json");
  const auto model = compile_model(scene);
  SessionOptions session;
  session.render = false;
  session.check = true;
  lumen::Points served_x, replayed_x;
  session.on_frame = [&](const Model&, const State& s, const FrameRecord&) { served_x = s.x; };
  // The hand: 0.1 kg on a 200 N/m spring to a target that goes from 0 to 3 mm into the tissue in 0.6 s, damped,
  // pushed by the reaction it feels; integrated at 1 kHz, its position sent as a TRANSFORM each step.
  Client hand;
  const ServeResult served = serve_with(scene, *model, session, [&](int port) {
    ASSERT_TRUE(hand.connect(port));
    hand.start_reading();
    constexpr double kMass = 0.1, kSpring = 200.0, kDamping = 9.0, kDt = 1e-3, kDepth = 0.0035, kRamp = 0.6;
    constexpr int kSteps = 1100;  // past the session's 1.2 s end: the server closes the connection
    double y = 0.0, v = 0.0;
    auto next = std::chrono::steady_clock::now();
    for (int i = 0; i < kSteps; ++i) {
      const double target = -kDepth * std::min(1.0, i * kDt / kRamp);
      const double a = (kSpring * (target - y) - kDamping * v + hand.fy.load()) / kMass;
      v += kDt * a;
      y += kDt * v;
      hand.send_transform("Hand", Eigen::Matrix3f::Identity(), Eigen::Vector3f(0.0f, static_cast<float>(kMmPerM * y), 0.0f));
      next += std::chrono::microseconds(1000);
      std::this_thread::sleep_until(next);
    }
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
  // The hand got the probe into the tissue and felt it push back (up, +y) over SENSOR.
  int touching = 0;
  for (const FrameRecord& f : served.session.frames) touching += f.instruments[0].contacts > 0;
  EXPECT_GT(touching, 0);
  EXPECT_GT(hand.sensors.load(), 0);
  EXPECT_GT(hand.max_fy.load(), 0.0);
  // The probe was where the hand sent it: the last frame's tip below the device's start.
  EXPECT_LT(served.session.frames.back().instruments[0].position.y(), kOuterRadius + 0.0005);

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
  const SessionResult replayed = run_session(*model, std::move(replay), again);
  expect_same_frames(served.session.frames, replayed.frames);
  EXPECT_EQ(served_x, replayed_x);
}

TEST(Serve, MalformedMessagesAreCountedByReasonAndIgnored) {
  constexpr int kFrames = 16;
  const Scene scene = parse_scene(device_scene(kFrames).dump(), "serve.json");
  const auto model = compile_model(scene);
  SessionOptions session;
  session.render = false;
  Client c;
  const Eigen::Vector3f good_mm(1.0f, 2.0f, 0.0f);
  const ServeResult served = serve_with(scene, *model, session, [&](int port) {
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
      c.socket->Send(bytes.data(), static_cast<int>(bytes.size()));
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
  const Eigen::Vector3d expected(0.001, kOuterRadius + 0.0005 + 0.002, 0.05);
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
  const Scene scene = parse_scene(device_scene(kFrames).dump(), "serve.json");
  const auto model = compile_model(scene);
  SessionOptions session;
  session.render = false;
  std::atomic<int> frames_done{0};
  session.on_frame = [&](const Model&, const State&, const FrameRecord&) { ++frames_done; };
  auto wait_frames = [&](int n) {
    while (frames_done.load() < n) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  };
  const Eigen::Vector3f a_mm(2.0f, 1.0f, 0.0f), b_mm(-1.0f, 3.0f, 0.0f);
  std::vector<Eigen::Vector3d> positions;
  const ServeResult served = serve_with(scene, *model, session, [&](int port) {
    // First client: one pose, then it goes away after a few frames; a second client comes later with another.
    Client first;
    ASSERT_TRUE(first.connect(port));
    first.send_transform("Hand", Eigen::Matrix3f::Identity(), a_mm);
    wait_frames(5);
    first.socket->CloseSocket();
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
  const Eigen::Vector3d origin(0.0, kOuterRadius + 0.0005, 0.05);
  const Eigen::Vector3d a = origin + 1e-3 * a_mm.cast<double>(), b = origin + 1e-3 * b_mm.cast<double>();
  EXPECT_LE((served.session.frames[19].instruments[0].position - a).norm(), 1e-9);
  EXPECT_LE((served.session.frames.back().instruments[0].position - b).norm(), 1e-9);
}
