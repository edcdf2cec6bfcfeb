#pragma once
// Devices: the input-source interface through which a tracker or haptic device (the OpenIGTLink bridge of
// `lumen serve`, or an SDK such as OpenHaptics or CHAI3D) drives an instrument, without the engine knowing it.
//
// A device runs on its own thread(s). It talks to the simulation only through lock-free single-writer /
// single-reader channels: it writes its latest pose into a PoseChannel (a triple buffer: the newest value wins,
// neither side ever waits), and the simulation writes each frame's local model of the reaction (engine/haptics.hpp)
// back into a channel the haptic loop reads. A DevicePoseSource is the instrument's PoseSource on the simulation
// side: it takes the newest pose at each frame and records every pose it hands to the simulation (the session's
// replay file).
//
// Adding a device SDK: on the SDK's servo callback, write `DeviceSample{pose in the organ frame, ...}` into the
// instrument's PoseChannel (make_device_link gives the pair of ends), and read the force to display from the
// HapticLoop's output (engine/haptics.hpp). Nothing in the engine changes.
#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "engine/input.hpp"
#include "engine/pose_track.hpp"
#include "engine/simulation.hpp"

namespace lumen::engine {

// Latest-value channel between one writer thread and one reader thread (a triple buffer): write() publishes a
// value, read() takes the newest one published since its last call. Wait-free on both sides; no value is ever
// torn; values published between two reads are skipped (only the newest matters).
template <class T>
class TripleBuffer {
 public:
  // Writer side: publish v.
  void write(const T& v) {
    slots_[write_] = v;
    const std::uint8_t prev = middle_.exchange(static_cast<std::uint8_t>(write_ | kFresh), std::memory_order_acq_rel);
    write_ = prev & kIndexMask;
  }
  // Reader side: true (and `out` set) when a value was published since the last read; false leaves `out` alone.
  bool read(T& out) {
    if (!(middle_.load(std::memory_order_acquire) & kFresh)) return false;
    const std::uint8_t prev = middle_.exchange(read_, std::memory_order_acq_rel);
    read_ = prev & kIndexMask;
    out = slots_[read_];
    return true;
  }

 private:
  static constexpr std::uint8_t kIndexMask = 0x3;  // slot index bits of middle_
  static constexpr std::uint8_t kFresh = 0x4;      // middle_ holds a value the reader has not taken
  std::array<T, 3> slots_{};
  std::atomic<std::uint8_t> middle_{1};  // the shared slot (and the fresh bit)
  std::uint8_t write_ = 0;               // writer's own slot
  std::uint8_t read_ = 2;                // reader's own slot
};

// One reading of a device: the instrument's pose in the organ frame and when it was taken.
struct DeviceSample {
  Pose pose;
  double time_s = 0.0;      // the device side's steady clock (seconds since the session's epoch)
  std::uint64_t seq = 0;    // increasing per reading (1 for the first)
  bool connected = true;    // false: the device went away (the instrument stays at its last pose)
};
using PoseChannel = TripleBuffer<DeviceSample>;

// One pose the simulation was handed: at simulation time t (seconds), frame (0 at the start pose, then 1, 2, ...).
struct RecordedPose {
  double t = 0.0;
  int frame = 0;
  Pose pose;
};

// The instrument's pose source on the simulation side of a device: `home` at the session's start (the first
// call), then at each frame the newest pose on its channel (the last one when nothing new came, or home before
// the first reading), never waiting; the tool sweeps from home to the device's pose in the first frame. Records
// every pose it hands out; counts the frames the device was disconnected. The simulation's reaction comes back
// through feedback() and is passed on to `on_feedback` (the haptic loop's model channel), when set.
class DevicePoseSource final : public PoseSource {
 public:
  DevicePoseSource(std::string device_name, std::shared_ptr<PoseChannel> channel, const Pose& home);
  std::string kind() const override { return "device"; }
  Pose pose(double t) override;
  void feedback(double t, const InstrumentRecord& record) override;

  const std::string& device_name() const { return device_name_; }
  const std::vector<RecordedPose>& recorded() const { return recorded_; }
  // The recorded poses as pose-track keys (what write_pose_csv writes and a replay reads back).
  std::vector<PoseKey> recorded_keys() const;
  long disconnected_frames() const { return disconnected_frames_; }
  long readings_taken() const { return readings_; }
  // Called with every frame's record (from the simulation thread; must not block).
  std::function<void(double, const InstrumentRecord&)> on_feedback;

 private:
  std::string device_name_;
  std::shared_ptr<PoseChannel> channel_;
  DeviceSample last_;
  bool connected_ = false;
  long disconnected_frames_ = 0;
  long readings_ = 0;
  std::vector<RecordedPose> recorded_;
};

// The session's inputs with every instrument that has a device_name driven by its device (a DevicePoseSource
// on a fresh channel, at home_pose(spec)); every other source as make_inputs makes it.
struct DeviceInputs {
  Inputs inputs;
  std::vector<int> instrument;                        // per device slot: the instrument's index
  std::vector<std::shared_ptr<PoseChannel>> channels; // per device slot: what the simulation reads
  std::vector<DevicePoseSource*> sources;             // per device slot: owned by inputs
};
DeviceInputs make_device_inputs(const Scene& scene);

}  // namespace lumen::engine
