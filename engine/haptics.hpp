#pragma once
// The haptic loop: a thread at the device's rate (haptics.rate_hz, 1 kHz by default) that renders, between
// simulation frames, the force from the last frame's local model of each device-driven instrument:
//
//   f = w(age) * sat( f_frame - K (x_device - x_frame) - c v )
//
// f_frame: the contact force on the instrument at the end of the frame; x_frame: where its tip was then;
// K: the tip's stiffness against translation with the frame's pushing contacts held (InstrumentRecord::stiffness,
// K = d(-f)/dx, clamped to haptics.max_stiffness_n_per_m); c v: damping on the device's velocity (its motion
// over each tick, low-pass filtered), in contact only;
// sat: the force clamped to haptics.max_force_n; w: 1 while the model is fresh, fading linearly to 0 over fade_s
// once it is older than stale_after_s, and 0 for a non-finite model. Without contact (f_frame = 0, K = 0) f = 0;
// the spring part never pulls towards the tissue (its component against f_frame is dropped).
//
// The simulation and the loop share no lock: the simulation publishes each frame's model into a TripleBuffer,
// the device's poses reach the loop through another, and the loop hands each force to a sink on its own thread.
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "engine/device.hpp"
#include "engine/scene.hpp"

namespace lumen::engine {

// One instrument's local model, published after each frame.
struct HapticModel {
  double time_s = 0.0;  // when it was published, on the session clock (seconds)
  Eigen::Vector3d x_frame = Eigen::Vector3d::Zero();      // the tip at the frame's end, metres (organ frame)
  Eigen::Vector3d f_frame = Eigen::Vector3d::Zero();      // contact force on the instrument, newtons
  Eigen::Matrix3d stiffness = Eigen::Matrix3d::Zero();    // K, N/m, symmetric positive semi-definite, clamped
  bool valid = false;   // false until the first frame
};
using ModelChannel = TripleBuffer<HapticModel>;

// What the loop renders at one tick for one instrument.
struct HapticForce {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  // on the device (the instrument), newtons, organ frame
  double weight = 0.0;                              // w(age) in [0, 1]
  bool clamped = false;                             // the force limit was hit
  std::uint64_t seq = 0;                            // the device reading it was rendered at (0: none yet)
  double reading_time_s = 0.0;                      // when that reading arrived (session clock)
};

// w(age): 1 up to stale_after_s, then linear down to 0 over fade_s.
double fade_weight(const HapticsSpec& spec, double age_s);
// K symmetrised, its eigenvalues clamped to [0, max_stiffness]; `clamped` set when one was above the limit.
Eigen::Matrix3d clamp_stiffness(const Eigen::Matrix3d& k, double max_stiffness, bool& clamped);
// The force of the coupling formula above for a device at x_device moving at v_device (organ frame) at now_s.
HapticForce render_force(const HapticsSpec& spec, const HapticModel& model, const Eigen::Vector3d& x_device,
                         const Eigen::Vector3d& v_device, double now_s);

// The loop's measurements (report.json "haptics").
struct HapticStats {
  long ticks = 0;
  double seconds = 0.0;         // wall time from the first to the last tick
  double rate_hz = 0.0;         // measured: (ticks - 1) / seconds
  double period_p50_ms = 0.0, period_p99_ms = 0.0, period_max_ms = 0.0;
  long overruns = 0;            // ticks that started a whole period or more late (a missed deadline)
  long force_clamps = 0;        // ticks whose force hit max_force_n
  long stiffness_clamps = 0;    // published models whose stiffness hit max_stiffness_n_per_m
  long faded_ticks = 0;         // ticks with w < 1 (stale or non-finite model)
  bool realtime = false;        // the thread runs under SCHED_FIFO (kHapticPriority); false when not permitted
  nlohmann::json json() const;
};

// The thread. One slot per device-driven instrument: its device's pose channel (the loop's own reader), its
// model channel (written by the simulation through publish()).
class HapticLoop {
 public:
  // Called on the loop's thread with each tick's forces (one per slot) and the tick's time; must not block long.
  using Sink = std::function<void(const std::vector<HapticForce>&, double now_s)>;
  // clock: the session clock (seconds), shared with the device side's time stamps.
  HapticLoop(const HapticsSpec& spec, std::vector<std::shared_ptr<PoseChannel>> device_poses,
             std::function<double()> clock, Sink sink);
  ~HapticLoop();
  HapticLoop(const HapticLoop&) = delete;
  HapticLoop& operator=(const HapticLoop&) = delete;

  // Simulation side: the frame's record of slot i's instrument becomes its model (stiffness clamped here).
  void publish(size_t slot, const InstrumentRecord& record);
  void start();
  // Stops and joins the thread (idempotent); stats() is final after it.
  void stop();
  HapticStats stats() const;

 private:
  void run();
  HapticsSpec spec_;
  std::vector<std::shared_ptr<PoseChannel>> device_poses_;
  std::vector<std::unique_ptr<ModelChannel>> models_;
  std::function<double()> clock_;
  Sink sink_;
  std::atomic<bool> running_{false};
  std::thread thread_;
  std::atomic<long> stiffness_clamps_{0};
  std::vector<double> periods_ms_;  // loop thread only until joined
  HapticStats stats_;               // loop thread only until joined
};

}  // namespace lumen::engine
