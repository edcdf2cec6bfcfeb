#pragma once
// `lumen serve`: an OpenIGTLink server (the protocol of 3D Slicer and the PLUS toolkit) that drives instruments.
//
// TRANSFORM and POSITION messages whose device name matches an instrument's device_name set its pose (millimetres
// on the wire, mapped into the organ frame by the instrument's to_organ); every haptic tick the instrument's
// reaction goes back to the client that drives it as a SENSOR message (3 float64, newtons, in the device's frame:
// to_organ's rotation undone). The
// session runs in real time; the network thread, the haptic loop and the simulation share no lock (device.hpp's
// channels). A bad message (bad CRC, short body, unknown type, unknown device name, non-finite pose, rotation
// not orthonormal) is counted by reason and ignored; a client that goes away leaves its instruments at their last
// poses, and may reconnect.
#include <sys/types.h>

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "engine/device.hpp"
#include "engine/haptics.hpp"
#include "engine/session.hpp"

namespace lumen::engine {

// The OpenIGTLink default port (3D Slicer's).
inline constexpr int kDefaultIgtlPort = 18944;

// A listening TCP socket, bound before anything else happens (so a port in use is a clear error, exit 2).
class Listener {
 public:
  // Throws InputError naming --host / --port and the reason ("Address already in use") when it cannot listen.
  // host "" listens on every interface.
  Listener(const std::string& host, int port);
  ~Listener();
  Listener(Listener&& o) noexcept : fd_(o.fd_), port_(o.port_) { o.fd_ = -1; }
  Listener(const Listener&) = delete;
  Listener& operator=(const Listener&) = delete;
  int fd() const { return fd_; }
  int port() const { return port_; }  // the bound port (the kernel's choice when asked for 0)

 private:
  int fd_ = -1;
  int port_ = 0;
};

// One device-driven instrument as the bridge sees it.
struct BridgeSlot {
  std::string device_name;
  Eigen::Isometry3d to_organ = Eigen::Isometry3d::Identity();
  std::shared_ptr<PoseChannel> to_simulation;  // the DevicePoseSource's channel
  std::shared_ptr<PoseChannel> to_haptics;     // the haptic loop's channel
};

// The network thread: accepts clients, reads their messages, feeds the channels; sends the haptic loop's forces.
class Bridge {
 public:
  Bridge(Listener listener, std::vector<BridgeSlot> slots, std::function<double()> clock);
  ~Bridge();
  Bridge(const Bridge&) = delete;
  Bridge& operator=(const Bridge&) = delete;
  void start();
  void stop();  // joins the thread, closes every socket (idempotent)
  // Haptic thread: one SENSOR per slot whose device has a client. Never blocks: a message the socket takes only
  // part of keeps its remainder, written first on the next call (the socket's next writable opportunity at the
  // haptic rate), and until it is out the new messages of that slot are dropped whole; a message the full socket
  // takes none of is dropped. The client's stream never holds a torn message.
  void send_reactions(const std::vector<HapticForce>& forces, double now_s);
  // After stop(): messages received by type, rejected by reason, SENSOR messages sent (whole), dropped and partly
  // sent at first, connections, and the TRANSFORM/POSITION -> SENSOR latency (from the pose's arrival to the send
  // of the first SENSOR rendered at it).
  nlohmann::json report() const;
  // The socket write send_reactions uses: returns the bytes taken, or <= 0 when none (default: send() with
  // MSG_DONTWAIT | MSG_NOSIGNAL). Set before start(); tests replace it to take messages in pieces.
  using Sender = std::function<ssize_t(int fd, const void* data, size_t size)>;
  void set_sender(Sender sender);

 private:
  struct Client;
  struct PendingSensor;
  // Write slot's pending SENSOR bytes; true (and counted as sent) when the whole message is out.
  bool flush_sensor(size_t slot);
  void run();
  void read_client(Client& c);
  void handle_message(Client& c, const std::string& type, const std::string& device, const void* header,
                      const std::uint8_t* body, std::uint32_t body_size);
  void close_client(Client& c);
  Listener listener_;
  std::vector<BridgeSlot> slots_;
  std::function<double()> clock_;
  std::atomic<bool> running_{false};
  std::thread thread_;
  std::vector<std::unique_ptr<Client>> clients_;            // network thread only
  std::vector<std::unique_ptr<std::atomic<int>>> slot_fd_;  // per slot: the socket of its client, or -1
  std::atomic<long> send_rounds_{0};                        // send_reactions calls completed
  std::vector<std::uint64_t> seq_;                          // network thread: readings per slot
  // Counts (network thread until joined), and the haptic thread's.
  std::map<std::string, long> received_, rejected_;
  long connections_ = 0, disconnects_ = 0;
  std::atomic<long> sensors_sent_{0}, sensors_dropped_{0}, sensors_partial_{0};
  std::vector<std::unique_ptr<PendingSensor>> pending_;  // haptic thread: per slot, a SENSOR not yet all out
  Sender send_;
  std::vector<std::uint64_t> answered_seq_;  // haptic thread: per slot, the last reading a SENSOR answered
  std::vector<double> latency_ms_;           // haptic thread
};

// What `lumen serve` runs by.
struct ServeOptions {
  SessionOptions session;            // outputs, frames (> 0 overrides the scene's), rendering
  const std::atomic<bool>* interrupted = nullptr;  // set (SIGINT) to end the session cleanly after the frame
  bool real_time = true;             // pace the frames at the scene's fps
};

// The session's report (report.json: run's, plus "serve" and "haptics") and the poses to replay.
struct ServeResult {
  SessionResult session;
  std::vector<int> device_instruments;             // per device slot: the instrument's index
  std::vector<std::vector<PoseKey>> recorded;      // per device slot: every pose handed to the simulation
};

// Run a served session: the bridge on `listener`, the haptic loop, the frames in real time until the frame
// count or an interrupt.
ServeResult serve_session(const Scene& scene, const Model& model, Listener listener, const ServeOptions& options);

// The replay file of instrument i of a served session in folder dir (DIR/replay/instrument_<i>.csv).
std::string replay_file(const std::string& dir, size_t instrument);
// Write every device slot's recorded poses there (write_pose_csv: 17 digits, bit for bit).
void write_replay(const std::string& dir, const ServeResult& result);
// The inputs of a run that plays a served session back: every instrument with a device_name from its replay
// file under dir; the rest as make_inputs. `frames` is set to the recorded frame count.
Inputs make_replay_inputs(const Scene& scene, const std::string& dir, int& frames);

}  // namespace lumen::engine
