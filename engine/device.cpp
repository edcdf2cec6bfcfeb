#include "engine/device.hpp"

#include <utility>

namespace lumen::engine {

DevicePoseSource::DevicePoseSource(std::string device_name, std::shared_ptr<PoseChannel> channel, const Pose& home)
    : device_name_(std::move(device_name)), channel_(std::move(channel)) {
  last_.pose = home;
  last_.connected = false;
}

Pose DevicePoseSource::pose(double t) {
  // The session starts at home (checked clear of the organ when the model compiled); from the first frame on,
  // the newest reading, if any came since the last frame; else the last one stands (a disconnected device
  // leaves the instrument where it was).
  DeviceSample s;
  if (!recorded_.empty() && channel_->read(s)) {
    ++readings_;
    if (s.connected) last_.pose = s.pose;
    last_.time_s = s.time_s;
    last_.seq = s.seq;
    last_.connected = s.connected;
    connected_ = connected_ || s.connected;
  }
  if (connected_ && !last_.connected) ++disconnected_frames_;
  recorded_.push_back(RecordedPose{t, static_cast<int>(recorded_.size()), last_.pose});
  return last_.pose;
}

void DevicePoseSource::feedback(double t, const InstrumentRecord& record) {
  if (on_feedback) on_feedback(t, record);
}

std::vector<PoseKey> DevicePoseSource::recorded_keys() const {
  std::vector<PoseKey> keys;
  keys.reserve(recorded_.size());
  for (const RecordedPose& r : recorded_) keys.push_back(PoseKey{r.t, r.pose});
  return keys;
}

DeviceInputs make_device_inputs(const Scene& scene) {
  DeviceInputs d;
  for (const ProbeSpec& p : scene.probes) d.inputs.sources.push_back(make_source(p));
  for (size_t i = 0; i < scene.instruments.size(); ++i) {
    const InstrumentSpec& spec = scene.instruments[i];
    if (spec.device_name.empty()) {
      d.inputs.instruments.push_back(make_pose_source(scene, i));
      continue;
    }
    auto channel = std::make_shared<PoseChannel>();
    auto source = std::make_unique<DevicePoseSource>(spec.device_name, channel, home_pose(spec));
    d.instrument.push_back(static_cast<int>(i));
    d.channels.push_back(channel);
    d.sources.push_back(source.get());
    d.inputs.instruments.push_back(std::move(source));
  }
  return d;
}

}  // namespace lumen::engine
