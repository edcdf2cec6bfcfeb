#include "engine/device_client.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>

#include <igtlClientSocket.h>
#include <igtlMessageHeader.h>
#include <igtlSensorMessage.h>
#include <igtlTransformMessage.h>

namespace lumen::engine {
namespace {
constexpr double kMmPerM = 1e3;
}  // namespace

struct DeviceClient::Socket {
  igtl::ClientSocket::Pointer s = igtl::ClientSocket::New();
};

DeviceClient::DeviceClient() : socket_(std::make_unique<Socket>()) {}

DeviceClient::~DeviceClient() {
  close();
  if (reader_.joinable()) reader_.join();
}

bool DeviceClient::connect(const std::string& host, int port) { return socket_->s->ConnectToServer(host.c_str(), port) == 0; }

bool DeviceClient::send_bytes(const void* data, int size) { return socket_->s->Send(data, size) != 0; }

bool DeviceClient::send_transform(const std::string& device, const Eigen::Matrix3f& r, const Eigen::Vector3f& p_mm) {
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
  return send_bytes(m->GetPackPointer(), m->GetPackSize());
}

void DeviceClient::start_reading() {
  reader_ = std::thread([this] {
    // Header, then body; a SENSOR's first three values are the force.
    for (;;) {
      igtl::MessageHeader::Pointer h = igtl::MessageHeader::New();
      h->InitPack();
      if (socket_->s->Receive(h->GetPackPointer(), h->GetPackSize()) != h->GetPackSize()) return;
      h->Unpack();
      igtl::SensorMessage::Pointer m = igtl::SensorMessage::New();
      m->SetMessageHeader(h);
      m->AllocatePack();
      if (socket_->s->Receive(m->GetPackBodyPointer(), m->GetPackBodySize()) != m->GetPackBodySize()) return;
      if (std::strcmp(h->GetDeviceType(), "SENSOR") != 0) continue;
      m->Unpack(1);
      fx_ = m->GetValue(0);
      fy_ = m->GetValue(1);
      fz_ = m->GetValue(2);
      max_force_ = std::max(max_force_.load(), force().norm());
      ++sensors_;
    }
  });
}

void DeviceClient::finish() {
  if (reader_.joinable()) reader_.join();
  close();
}

void DeviceClient::close() { socket_->s->CloseSocket(); }

HandResult run_hand(DeviceClient& client, const HandSpec& spec) {
  HandResult r;
  const double dt = 1.0 / spec.rate_hz;
  const long steps = std::lround(spec.seconds * spec.rate_hz);
  double y = 0.0, v = 0.0;
  auto next = std::chrono::steady_clock::now();
  // Each step: the forces on the hand, its motion, its position to the server.
  for (long i = 0; i < steps; ++i) {
    const double f = spec.spring_n_per_m * (spec.target_y_m(i * dt) - y) - spec.damping_n_s_per_m * v + client.force().y();
    v += dt * f / spec.mass_kg;
    y += dt * v;
    if (!client.send_transform(spec.device, Eigen::Matrix3f::Identity(),
                               Eigen::Vector3f(0.0f, static_cast<float>(kMmPerM * y), 0.0f)))
      break;
    ++r.sent;
    next += std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(dt));
    std::this_thread::sleep_until(next);
  }
  r.final_y_m = y;
  return r;
}

}  // namespace lumen::engine
