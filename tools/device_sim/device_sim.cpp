// lumen_device_sim: a simulated haptic device for `lumen serve` (benchmarks, demos): a mass-spring "hand"
// (engine/device_client.hpp) that chases a target pressing down into the tissue and back, sends its position as
// OpenIGTLink TRANSFORM messages at a fixed rate, and feels the SENSOR reaction the server sends back.
//
// usage: lumen_device_sim [--host 127.0.0.1] [--port 18944] [--device Tracker] [--rate 1000] [--seconds 3]
//                         [--depth-mm 3] [--period-s 2]
// Prints one JSON line at the end: messages sent, SENSOR messages received, the largest force felt.
#include <cmath>
#include <cstdio>
#include <string>

#include <CLI/CLI.hpp>

#include "engine/device_client.hpp"

namespace {
constexpr double kMmPerM = 1e3;
constexpr double kTwoPi = 6.283185307179586;
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"simulated OpenIGTLink haptic device (a mass-spring hand) for lumen serve"};
  std::string host = "127.0.0.1";
  int port = 18944;
  double depth_mm = 3.0, period_s = 2.0;
  lumen::engine::HandSpec hand;
  app.add_option("--host", host);
  app.add_option("--port", port);
  app.add_option("--device", hand.device);
  app.add_option("--rate", hand.rate_hz, "TRANSFORM messages per second");
  app.add_option("--seconds", hand.seconds);
  app.add_option("--depth-mm", depth_mm, "how far below the device origin the target goes");
  app.add_option("--period-s", period_s, "the target's press-and-release period");
  CLI11_PARSE(app, argc, argv);

  lumen::engine::DeviceClient client;
  if (!client.connect(host, port)) {
    std::fprintf(stderr, "lumen_device_sim: cannot connect to %s:%d\n", host.c_str(), port);
    return 1;
  }
  client.start_reading();
  // Press and release: the target goes down depth_mm and back once per period.
  hand.target_y_m = [&](double t) { return -0.5 * depth_mm / kMmPerM * (1.0 - std::cos(kTwoPi * t / period_s)); };
  const lumen::engine::HandResult r = lumen::engine::run_hand(client, hand);
  client.close();
  std::printf("{\"sent\": %ld, \"sensors\": %ld, \"max_force_n\": %.6g}\n", r.sent, client.sensors(), client.max_force());
  return 0;
}
