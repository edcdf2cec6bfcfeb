#pragma once
// The client side of `lumen serve`, for simulated devices (tools/device_sim, the tests): an OpenIGTLink client
// that sends TRANSFORM messages and takes every SENSOR reaction back on a reader thread, and a mass-spring "hand"
// that chases a target while feeling that reaction.
#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <thread>

#include <Eigen/Core>

namespace lumen::engine {

// One connection to a server. Not copyable; the reader runs until the server closes the connection.
class DeviceClient {
 public:
  DeviceClient();
  ~DeviceClient();
  DeviceClient(const DeviceClient&) = delete;
  DeviceClient& operator=(const DeviceClient&) = delete;
  bool connect(const std::string& host, int port);
  // A TRANSFORM of `device`: rotation r, position in millimetres.
  bool send_transform(const std::string& device, const Eigen::Matrix3f& r, const Eigen::Vector3f& p_mm);
  // Bytes as they are (a packed message, or a malformed one).
  bool send_bytes(const void* data, int size);
  // Start taking SENSOR messages back (their first three values: the reaction force, newtons).
  void start_reading();
  // Wait for the reader to end (the server closed the connection), then close.
  void finish();
  // Close now (the reader, if any, ends with the connection).
  void close();
  long sensors() const { return sensors_.load(); }
  Eigen::Vector3d force() const { return {fx_.load(), fy_.load(), fz_.load()}; }
  double max_force() const { return max_force_.load(); }

 private:
  struct Socket;
  std::unique_ptr<Socket> socket_;
  std::thread reader_;
  std::atomic<long> sensors_{0};
  std::atomic<double> fx_{0.0}, fy_{0.0}, fz_{0.0}, max_force_{0.0};
};

// The hand: a mass on a spring to a target, damped, pushed by the reaction it feels, moving along the device's y
// axis; integrated at rate_hz by semi-implicit Euler, its position sent as a TRANSFORM at every step.
struct HandSpec {
  std::string device = "Tracker";
  double rate_hz = 1000.0;
  double seconds = 3.0;
  double mass_kg = 0.1;
  double spring_n_per_m = 200.0;
  double damping_n_s_per_m = 9.0;  // about critical for the mass and spring above
  std::function<double(double)> target_y_m;  // the target at time t (seconds), metres
};
struct HandResult {
  long sent = 0;
  double final_y_m = 0.0;
};
HandResult run_hand(DeviceClient& client, const HandSpec& spec);

}  // namespace lumen::engine
