// lumen_device_sim: a simulated haptic device for `lumen serve` (benchmarks, demos): a mass-spring "hand" that
// chases a target pressing down into the tissue and back, sends its position as OpenIGTLink TRANSFORM messages at
// a fixed rate, and feels the SENSOR reaction the server sends back (added to the forces on the hand).
//
// usage: lumen_device_sim [--host 127.0.0.1] [--port 18944] [--device Tracker] [--rate 1000] [--seconds 3]
//                         [--depth-mm 3] [--period-s 2]
// Prints one JSON line at the end: messages sent, SENSOR messages received, the largest force felt.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <thread>

#include <CLI/CLI.hpp>
#include <igtlClientSocket.h>
#include <igtlMessageHeader.h>
#include <igtlSensorMessage.h>
#include <igtlTransformMessage.h>

namespace {

// The hand: mass, its spring to the target and damping (critically damped), newtons and kilograms.
constexpr double kHandMass = 0.1;
constexpr double kHandSpring = 200.0;
constexpr double kHandDamping = 9.0;
constexpr double kMmPerM = 1e3;
constexpr double kTwoPi = 6.283185307179586;

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"simulated OpenIGTLink haptic device (a mass-spring hand) for lumen serve"};
  std::string host = "127.0.0.1", device = "Tracker";
  int port = 18944;
  double rate = 1000.0, seconds = 3.0, depth_mm = 3.0, period_s = 2.0;
  app.add_option("--host", host);
  app.add_option("--port", port);
  app.add_option("--device", device);
  app.add_option("--rate", rate, "TRANSFORM messages per second");
  app.add_option("--seconds", seconds);
  app.add_option("--depth-mm", depth_mm, "how far below the device origin the target goes");
  app.add_option("--period-s", period_s, "the target's press-and-release period");
  CLI11_PARSE(app, argc, argv);

  igtl::ClientSocket::Pointer socket = igtl::ClientSocket::New();
  if (socket->ConnectToServer(host.c_str(), port) != 0) {
    std::fprintf(stderr, "lumen_device_sim: cannot connect to %s:%d\n", host.c_str(), port);
    return 1;
  }
  // Reader: every SENSOR's force, the latest kept for the hand (until the server closes the connection).
  std::atomic<double> fx{0.0}, fy{0.0}, fz{0.0}, max_force{0.0};
  std::atomic<long> sensors{0};
  std::thread reader([&] {
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
      fx = m->GetValue(0);
      fy = m->GetValue(1);
      fz = m->GetValue(2);
      max_force = std::max(max_force.load(), std::sqrt(fx * fx + fy * fy + fz * fz));
      ++sensors;
    }
  });
  // The hand along y (device frame), semi-implicit Euler at the send rate.
  const double dt = 1.0 / rate;
  const long steps = static_cast<long>(seconds * rate);
  double y = 0.0, v = 0.0;
  long sent = 0;
  igtl::TransformMessage::Pointer msg = igtl::TransformMessage::New();
  msg->SetDeviceName(device.c_str());
  auto next = std::chrono::steady_clock::now();
  for (long i = 0; i < steps; ++i) {
    const double target = -0.5 * depth_mm / kMmPerM * (1.0 - std::cos(kTwoPi * i * dt / period_s));
    const double a = (kHandSpring * (target - y) - kHandDamping * v + fy.load()) / kHandMass;
    v += dt * a;
    y += dt * v;
    igtl::Matrix4x4 t;
    igtl::IdentityMatrix(t);
    t[1][3] = static_cast<float>(kMmPerM * y);
    msg->SetMatrix(t);
    msg->Pack();
    if (socket->Send(msg->GetPackPointer(), msg->GetPackSize()) == 0) break;
    ++sent;
    next += std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(dt));
    std::this_thread::sleep_until(next);
  }
  socket->CloseSocket();
  reader.join();
  std::printf("{\"sent\": %ld, \"sensors\": %ld, \"max_force_n\": %.6g}\n", sent, sensors.load(), max_force.load());
  return 0;
}
