#include "engine/serve.hpp"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>

#include <igtlMessageHeader.h>
#include <igtlPositionMessage.h>
#include <igtlSensorMessage.h>
#include <igtlTransformMessage.h>
#include <igtl_header.h>

namespace lumen::engine {
namespace fs = std::filesystem;
namespace {

// Wire facts of OpenIGTLink version 1/2 messages.
constexpr std::uint32_t kHeaderBytes = IGTL_HEADER_SIZE;  // 58
constexpr std::uint32_t kTransformBodyBytes = 48;         // 12 float32: rotation columns and translation
constexpr std::uint32_t kPositionOnlyBytes = 12;          // 3 float32
constexpr std::uint32_t kPositionQuaternion3Bytes = 24;   // 3 + 3 float32
constexpr std::uint32_t kPositionAllBytes = 28;           // 3 + 4 float32
// The largest body the bridge reads (a longer one closes the connection: the stream cannot be trusted).
constexpr std::uint64_t kMaxBodyBytes = 1u << 24;
// A SENSOR's values: the reaction force's three components.
constexpr unsigned kSensorValues = 3;
// How long the network thread waits for events before it checks whether to stop, milliseconds.
constexpr int kPollMs = 1;
// The listen backlog.
constexpr int kBacklog = 4;
// Bytes read from a socket at a time.
constexpr size_t kReadChunk = 1 << 16;
// Closing a client waits for the haptic thread to finish this many send rounds (none then uses its socket),
// at most kCloseWaitMs.
constexpr long kCloseGraceRounds = 2;
constexpr int kCloseWaitMs = 100;

}  // namespace

Listener::Listener(const std::string& host, int port) {
  const std::string where = "--host " + (host.empty() ? std::string("(any)") : host) + " --port " + std::to_string(port);
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE;
  addrinfo* found = nullptr;
  const std::string service = std::to_string(port);
  if (const int rc = getaddrinfo(host.empty() ? nullptr : host.c_str(), service.c_str(), &hints, &found); rc != 0)
    throw InputError(where + ": cannot resolve the host: " + gai_strerror(rc));
  fd_ = socket(found->ai_family, found->ai_socktype, found->ai_protocol);
  if (fd_ < 0) {
    freeaddrinfo(found);
    throw InputError(where + ": cannot open a socket: " + std::strerror(errno));
  }
  const int yes = 1;
  setsockopt(fd_, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  const int bound = bind(fd_, found->ai_addr, found->ai_addrlen);
  const int bind_errno = errno;
  freeaddrinfo(found);
  if (bound != 0 || listen(fd_, kBacklog) != 0) {
    const std::string reason = std::strerror(bound != 0 ? bind_errno : errno);
    close(fd_);
    fd_ = -1;
    throw InputError(where + ": cannot listen: " + reason);
  }
  sockaddr_in addr{};
  socklen_t len = sizeof addr;
  getsockname(fd_, reinterpret_cast<sockaddr*>(&addr), &len);
  port_ = ntohs(addr.sin_port);
}

Listener::~Listener() {
  if (fd_ >= 0) close(fd_);
}

// A connected client: its socket and the bytes read but not yet parsed.
struct Bridge::Client {
  int fd = -1;
  std::vector<std::uint8_t> buffer;
  std::vector<size_t> slots;  // the slots whose poses it sent
};

Bridge::Bridge(Listener listener, std::vector<BridgeSlot> slots, std::function<double()> clock)
    : listener_(std::move(listener)), slots_(std::move(slots)), clock_(std::move(clock)) {
  for (size_t i = 0; i < slots_.size(); ++i) slot_fd_.push_back(std::make_unique<std::atomic<int>>(-1));
  seq_.assign(slots_.size(), 0);
  answered_seq_.assign(slots_.size(), 0);
  for (size_t i = 0; i < slots_.size(); ++i) pending_.push_back(std::make_unique<PendingSensor>());
  send_ = [](int fd, const void* data, size_t size) { return send(fd, data, size, MSG_DONTWAIT | MSG_NOSIGNAL); };
}

Bridge::~Bridge() { stop(); }

void Bridge::start() {
  if (running_.exchange(true)) return;
  thread_ = std::thread([this] { run(); });
}

void Bridge::stop() {
  running_.store(false);
  if (thread_.joinable()) thread_.join();
  for (auto& c : clients_)
    if (c->fd >= 0) close_client(*c);
  clients_.clear();
}

void Bridge::run() {
  // Wait for a new client or bytes from one; parse every complete message.
  while (running_.load(std::memory_order_relaxed)) {
    std::vector<pollfd> fds{{listener_.fd(), POLLIN, 0}};
    for (const auto& c : clients_) fds.push_back({c->fd, POLLIN, 0});
    if (poll(fds.data(), fds.size(), kPollMs) <= 0) continue;
    if (fds[0].revents & POLLIN) {
      const int fd = accept(listener_.fd(), nullptr, nullptr);
      if (fd >= 0) {
        const int yes = 1;
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &yes, sizeof yes);
        auto c = std::make_unique<Client>();
        c->fd = fd;
        clients_.push_back(std::move(c));
        ++connections_;
      }
    }
    for (size_t k = 1; k < fds.size(); ++k)
      if (fds[k].revents & (POLLIN | POLLHUP | POLLERR)) read_client(*clients_[k - 1]);
    clients_.erase(std::remove_if(clients_.begin(), clients_.end(), [](const auto& c) { return c->fd < 0; }),
                   clients_.end());
  }
}

void Bridge::read_client(Client& c) {
  std::uint8_t chunk[kReadChunk];
  const ssize_t n = recv(c.fd, chunk, sizeof chunk, 0);
  if (n <= 0) {
    close_client(c);
    return;
  }
  c.buffer.insert(c.buffer.end(), chunk, chunk + n);
  // Every complete message in the buffer: header, then its body.
  size_t at = 0;
  while (c.buffer.size() - at >= kHeaderBytes) {
    igtl::MessageHeader::Pointer header = igtl::MessageHeader::New();
    header->InitPack();
    std::memcpy(header->GetPackPointer(), c.buffer.data() + at, kHeaderBytes);
    header->Unpack();
    const std::uint64_t body = header->GetBodySizeToRead();
    if (body > kMaxBodyBytes) {
      ++rejected_["oversized_body"];
      close_client(c);
      return;
    }
    if (c.buffer.size() - at - kHeaderBytes < body) break;
    handle_message(c, header->GetDeviceType(), header->GetDeviceName(), header.GetPointer(),
                   c.buffer.data() + at + kHeaderBytes, static_cast<std::uint32_t>(body));
    at += kHeaderBytes + body;
  }
  c.buffer.erase(c.buffer.begin(), c.buffer.begin() + static_cast<long>(at));
}

void Bridge::handle_message(Client& c, const std::string& type, const std::string& device, const void* header,
                            const std::uint8_t* body, std::uint32_t body_size) {
  ++received_[type.empty() ? "(none)" : type];
  const bool transform = type == "TRANSFORM", position = type == "POSITION";
  if (!transform && !position) {
    ++rejected_["unknown_type"];
    return;
  }
  const auto slot_it = std::find_if(slots_.begin(), slots_.end(), [&](const BridgeSlot& s) { return s.device_name == device; });
  if (slot_it == slots_.end()) {
    ++rejected_["unknown_device"];
    return;
  }
  // The body's size must be one the type has (TRANSFORM: 48 bytes; POSITION: 12, 24 or 28).
  const bool size_ok = transform ? body_size == kTransformBodyBytes
                                 : (body_size == kPositionOnlyBytes || body_size == kPositionQuaternion3Bytes ||
                                    body_size == kPositionAllBytes);
  if (!size_ok) {
    const std::uint32_t largest = transform ? kTransformBodyBytes : kPositionAllBytes;
    ++rejected_[body_size < largest ? "short_body" : "bad_body_size"];
    return;
  }
  // Unpack with the CRC check; the pose in millimetres and its rotation.
  igtl::MessageBase::Pointer msg;
  if (transform)
    msg = igtl::TransformMessage::New();
  else
    msg = igtl::PositionMessage::New();
  msg->SetMessageHeader(static_cast<const igtl::MessageHeader*>(header));
  if (position) static_cast<igtl::PositionMessage*>(msg.GetPointer())->SetPackTypeByBodySize(static_cast<int>(body_size));
  msg->AllocatePack();
  std::memcpy(msg->GetPackBodyPointer(), body, body_size);
  if (!(msg->Unpack(1) & igtl::MessageHeader::UNPACK_BODY)) {
    ++rejected_["bad_crc"];
    return;
  }
  std::array<double, 16> m{};
  m[15] = 1.0;
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  Eigen::Vector3d p_mm;
  bool finite = true;
  if (transform) {
    igtl::Matrix4x4 t;
    static_cast<igtl::TransformMessage*>(msg.GetPointer())->GetMatrix(t);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 4; ++j) m[static_cast<size_t>(4 * i + j)] = t[i][j];
    for (double v : m) finite = finite && std::isfinite(v);
  } else {
    auto* pm = static_cast<igtl::PositionMessage*>(msg.GetPointer());
    float pos[3], quat[4] = {0.0f, 0.0f, 0.0f, 1.0f};
    pm->GetPosition(pos);
    if (body_size != kPositionOnlyBytes) pm->GetQuaternion(quat);
    for (float v : pos) finite = finite && std::isfinite(v);
    for (float v : quat) finite = finite && std::isfinite(v);
    q = Eigen::Quaterniond(quat[3], quat[0], quat[1], quat[2]);
    for (int i = 0; i < 3; ++i) m[static_cast<size_t>(4 * i + 3)] = pos[i];
    if (finite && std::abs(q.norm() - 1.0) <= kQuaternionNormTolerance) {
      const Eigen::Matrix3d r = q.normalized().toRotationMatrix();
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) m[static_cast<size_t>(4 * i + j)] = r(i, j);
    } else if (finite) {
      ++rejected_["non_unit_quaternion"];
      return;
    }
  }
  if (!finite) {
    ++rejected_["non_finite_pose"];
    return;
  }
  // The rotation must be orthonormal (rigid_to_organ's test, in millimetres).
  Eigen::Isometry3d wire;
  try {
    wire = rigid_to_organ(m, "wire");
  } catch (const InputError&) {
    ++rejected_["non_orthonormal_rotation"];
    return;
  }
  // Into the organ frame; to the simulation and the haptic loop.
  const size_t slot = static_cast<size_t>(slot_it - slots_.begin());
  DeviceSample s;
  s.pose = device_to_organ(slot_it->to_organ, wire.translation(), Eigen::Quaterniond(wire.linear()));
  s.time_s = clock_();
  s.seq = ++seq_[slot];
  slot_it->to_simulation->write(s);
  slot_it->to_haptics->write(s);
  if (std::find(c.slots.begin(), c.slots.end(), slot) == c.slots.end()) c.slots.push_back(slot);
  slot_fd_[slot]->store(c.fd);
}

void Bridge::close_client(Client& c) {
  // Its devices are disconnected: the instruments stay at their last poses.
  for (size_t slot : c.slots) {
    int expected = c.fd;
    slot_fd_[slot]->compare_exchange_strong(expected, -1);
    DeviceSample s;
    s.time_s = clock_();
    s.seq = ++seq_[slot];
    s.connected = false;
    slots_[slot].to_simulation->write(s);
    slots_[slot].to_haptics->write(s);
  }
  // Grace period: the haptic thread may hold the socket number for the round in progress.
  const long round = send_rounds_.load();
  const auto t0 = std::chrono::steady_clock::now();
  while (send_rounds_.load() < round + kCloseGraceRounds &&
         std::chrono::steady_clock::now() - t0 < std::chrono::milliseconds(kCloseWaitMs))
    std::this_thread::yield();
  close(c.fd);
  c.fd = -1;
  ++disconnects_;
}

// A SENSOR message being written to a socket: its bytes, how many are out, and the reading it answers.
struct Bridge::PendingSensor {
  int fd = -1;
  std::vector<std::uint8_t> bytes;
  size_t sent = 0;
  std::uint64_t seq = 0;
  double reading_time_s = 0.0;
};

void Bridge::set_sender(Sender sender) { send_ = std::move(sender); }

bool Bridge::flush_sensor(size_t slot) {
  PendingSensor& p = *pending_[slot];
  // Write what the socket takes now (nothing more when it is full).
  while (p.sent < p.bytes.size()) {
    const ssize_t n = send_(p.fd, p.bytes.data() + p.sent, p.bytes.size() - p.sent);
    if (n <= 0) return false;
    p.sent += static_cast<size_t>(n);
  }
  sensors_sent_.fetch_add(1, std::memory_order_relaxed);
  // The first SENSOR rendered at a new reading answers it.
  if (p.seq != answered_seq_[slot] && p.seq > 0) {
    answered_seq_[slot] = p.seq;
    latency_ms_.push_back(1e3 * (clock_() - p.reading_time_s));
  }
  p.bytes.clear();
  p.sent = 0;
  return true;
}

void Bridge::send_reactions(const std::vector<HapticForce>& forces, double now_s) {
  // One SENSOR per slot with a client: the force in newtons.
  for (size_t i = 0; i < forces.size() && i < slots_.size(); ++i) {
    const int fd = slot_fd_[i]->load();
    PendingSensor& pending = *pending_[i];
    // A message left half-written belongs to its connection: gone with it, or finished first (until then this
    // round's message is dropped whole, so the stream never holds a torn message).
    if (pending.fd != fd) {
      pending = PendingSensor{};
      pending.fd = fd;
    }
    if (fd < 0) continue;
    if (!pending.bytes.empty() && !flush_sensor(i)) {
      sensors_dropped_.fetch_add(1, std::memory_order_relaxed);
      continue;
    }
    igtl::SensorMessage::Pointer msg = igtl::SensorMessage::New();
    msg->SetDeviceName(slots_[i].device_name.c_str());
    msg->SetLength(kSensorValues);
    igtl::Unit::Pointer unit = igtl::Unit::New();
    unit->Append(igtl::Unit::SI_DERIVED_NEWTON, 1);
    msg->SetUnit(unit);
    // In the device's frame (to_organ's rotation undone), as its poses came.
    const Eigen::Vector3d f = slots_[i].to_organ.linear().transpose() * forces[i].force;
    for (unsigned k = 0; k < kSensorValues; ++k) msg->SetValue(k, f[static_cast<int>(k)]);
    msg->Pack();
    const auto* packed = static_cast<const std::uint8_t*>(msg->GetPackPointer());
    pending.bytes.assign(packed, packed + msg->GetPackSize());
    pending.seq = forces[i].seq;
    pending.reading_time_s = forces[i].reading_time_s;
    // Sent whole, dropped whole (the socket took none of it), or partly: the rest goes out first next round.
    if (flush_sensor(i)) continue;
    if (pending.sent == 0) {
      pending.bytes.clear();
      sensors_dropped_.fetch_add(1, std::memory_order_relaxed);
    } else {
      sensors_partial_.fetch_add(1, std::memory_order_relaxed);
    }
  }
  (void)now_s;
  send_rounds_.fetch_add(1);
}

nlohmann::json Bridge::report() const {
  nlohmann::json j;
  j["port"] = listener_.port();
  j["received"] = received_;
  j["rejected"] = rejected_;
  long rejected = 0;
  for (const auto& [reason, n] : rejected_) rejected += n;
  j["rejected_total"] = rejected;
  j["sensors_sent"] = sensors_sent_.load();
  j["sensors_dropped"] = sensors_dropped_.load();
  j["sensors_partial"] = sensors_partial_.load();
  j["connections"] = connections_;
  j["disconnects"] = disconnects_;
  j["latency_ms"] = {{"answered", static_cast<long>(latency_ms_.size())}, {"median", summarize(latency_ms_).median_ms}};
  return j;
}

namespace {

using Clock = std::chrono::steady_clock;

// The bridge's slots, the haptic loop's channels, of the scene's device-driven instruments.
std::vector<BridgeSlot> bridge_slots(const Scene& scene, const DeviceInputs& d,
                                     std::vector<std::shared_ptr<PoseChannel>>& haptic_channels) {
  std::vector<BridgeSlot> slots;
  for (size_t k = 0; k < d.instrument.size(); ++k) {
    const InstrumentSpec& spec = scene.instruments[static_cast<size_t>(d.instrument[k])];
    BridgeSlot s;
    s.device_name = spec.device_name;
    s.to_organ = spec.to_organ;
    s.to_simulation = d.channels[k];
    s.to_haptics = std::make_shared<PoseChannel>();
    haptic_channels.push_back(s.to_haptics);
    slots.push_back(std::move(s));
  }
  return slots;
}

}  // namespace

ServeResult serve_session(const Scene& scene, const Model& model, Listener listener, const ServeOptions& options) {
  DeviceInputs d = make_device_inputs(scene);
  const auto epoch = Clock::now();
  auto clock = [epoch] { return std::chrono::duration<double>(Clock::now() - epoch).count(); };
  std::vector<std::shared_ptr<PoseChannel>> haptic_channels;
  Bridge bridge(std::move(listener), bridge_slots(scene, d, haptic_channels), clock);
  HapticLoop haptics(scene.haptics, haptic_channels, clock,
                     [&bridge](const std::vector<HapticForce>& f, double now) { bridge.send_reactions(f, now); });
  // Each frame's record of a device-driven instrument becomes the haptic loop's model.
  for (size_t k = 0; k < d.sources.size(); ++k)
    d.sources[k]->on_feedback = [&haptics, k](double, const InstrumentRecord& r) { haptics.publish(k, r); };
  // Frames in real time until the count or an interrupt.
  SessionOptions opt = options.session;
  const double dt = 1.0 / model.fps;
  Clock::time_point first_frame;  // frame i is due at first_frame + i / fps (set when frame 0 starts)
  opt.before_frame = [&](int i) {
    if (options.interrupted && options.interrupted->load()) return false;
    if (i == 0) first_frame = Clock::now();
    if (options.real_time)
      std::this_thread::sleep_until(first_frame +
                                    std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(i * dt)));
    return !(options.interrupted && options.interrupted->load());
  };
  bridge.start();
  haptics.start();
  ServeResult result;
  result.session = run_session_on(model, d.inputs, opt);
  haptics.stop();
  bridge.stop();
  // The report: run's, the bridge's counts, the haptic loop's measurements, the devices' disconnected frames.
  nlohmann::json& r = result.session.report;
  r["serve"] = bridge.report();
  r["haptics"] = haptics.stats().json();
  r["haptics"]["rate_hz_target"] = scene.haptics.rate_hz;
  nlohmann::json devices = nlohmann::json::array();
  for (size_t k = 0; k < d.sources.size(); ++k) {
    const DevicePoseSource& s = *d.sources[k];
    devices.push_back({{"instrument", scene.instruments[static_cast<size_t>(d.instrument[k])].name},
                       {"device_name", s.device_name()}, {"readings_taken", s.readings_taken()},
                       {"disconnected_frames", s.disconnected_frames()}});
    result.recorded.push_back(s.recorded_keys());
  }
  r["serve"]["devices"] = devices;
  r["serve"]["interrupted"] = options.interrupted && options.interrupted->load();
  result.device_instruments = d.instrument;
  return result;
}

std::string replay_file(const std::string& dir, size_t instrument) {
  return (fs::path(dir) / "replay" / ("instrument_" + std::to_string(instrument) + ".csv")).string();
}

void write_replay(const std::string& dir, const ServeResult& result) {
  fs::create_directories(fs::path(dir) / "replay");
  for (size_t k = 0; k < result.recorded.size(); ++k)
    write_pose_csv(replay_file(dir, static_cast<size_t>(result.device_instruments[k])), result.recorded[k]);
}

Inputs make_replay_inputs(const Scene& scene, const std::string& dir, int& frames) {
  Inputs in;
  for (const ProbeSpec& p : scene.probes) in.sources.push_back(make_source(p));
  frames = -1;
  for (size_t i = 0; i < scene.instruments.size(); ++i) {
    if (scene.instruments[i].device_name.empty()) {
      in.instruments.push_back(make_pose_source(scene, i));
      continue;
    }
    const std::string file = replay_file(dir, i);
    require_file(file, "served session's replay file");
    PoseTrack track = read_pose_csv(file);
    frames = static_cast<int>(track.keys().size()) - 1;  // the start pose, then one per frame
    in.instruments.push_back(std::make_unique<PoseTrackSource>(std::move(track), "replay"));
  }
  if (frames < 0) throw InputError(scene.path + ": instruments: no instrument has a device_name, nothing to replay");
  if (frames < 1) throw InputError(dir + ": the served session has no frames to replay");
  return in;
}

}  // namespace lumen::engine
