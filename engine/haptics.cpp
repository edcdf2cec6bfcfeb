#include "engine/haptics.hpp"

#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <chrono>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "engine/report.hpp"

namespace lumen::engine {
namespace {

// The haptic thread's SCHED_FIFO priority (1-99): above ordinary threads, below the kernel's own real-time work.
constexpr int kHapticPriority = 40;
// Time constant of the device velocity's low-pass filter, seconds.
constexpr double kVelocityFilterS = 0.01;
// Periods kept for the statistics: an hour at 1 kHz at most (the rest are counted, not kept).
constexpr size_t kMaxKeptPeriods = 3600000;

}  // namespace

double fade_weight(const HapticsSpec& spec, double age_s) {
  if (!(age_s > spec.stale_after_s)) return 1.0;
  if (age_s >= spec.stale_after_s + spec.fade_s) return 0.0;
  return std::max(0.0, 1.0 - (age_s - spec.stale_after_s) / spec.fade_s);
}

Eigen::Matrix3d clamp_stiffness(const Eigen::Matrix3d& k, double max_stiffness, bool& clamped) {
  // Symmetric part, eigenvalues into [0, max].
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(0.5 * (k + k.transpose()));
  Eigen::Vector3d lambda = eig.eigenvalues();
  clamped = lambda.maxCoeff() > max_stiffness;
  lambda = lambda.cwiseMax(0.0).cwiseMin(max_stiffness);
  return eig.eigenvectors() * lambda.asDiagonal() * eig.eigenvectors().transpose();
}

HapticForce render_force(const HapticsSpec& spec, const HapticModel& model, const Eigen::Vector3d& x_device,
                         const Eigen::Vector3d& v_device, double now_s) {
  HapticForce out;
  const bool finite = model.x_frame.allFinite() && model.f_frame.allFinite() && model.stiffness.allFinite() &&
                      x_device.allFinite() && v_device.allFinite();
  const bool in_contact = model.f_frame.squaredNorm() > 0.0 || model.stiffness.squaredNorm() > 0.0;
  if (!model.valid || !finite) return out;
  out.weight = fade_weight(spec, now_s - model.time_s);
  if (!in_contact) return out;
  // Spring part of the local model; never towards the tissue (against the frame's force).
  Eigen::Vector3d f = model.f_frame - model.stiffness * (x_device - model.x_frame);
  const double f_norm = model.f_frame.norm();
  if (f_norm > 0.0) {
    const Eigen::Vector3d n = model.f_frame / f_norm;
    f -= std::min(0.0, f.dot(n)) * n;
  }
  f -= spec.damping_n_s_per_m * v_device;
  // Saturate, then fade with the model's age.
  const double norm = f.norm();
  out.clamped = norm > spec.max_force_n;
  if (out.clamped) f *= spec.max_force_n / norm;
  out.force = out.weight * f;
  return out;
}

nlohmann::json HapticStats::json() const {
  return {{"ticks", ticks}, {"seconds", seconds}, {"rate_hz", rate_hz}, {"period_p50_ms", period_p50_ms},
          {"period_p99_ms", period_p99_ms}, {"period_max_ms", period_max_ms}, {"overruns", overruns},
          {"force_clamps", force_clamps}, {"stiffness_clamps", stiffness_clamps}, {"faded_ticks", faded_ticks},
          {"realtime", realtime}};
}

HapticLoop::HapticLoop(const HapticsSpec& spec, std::vector<std::shared_ptr<PoseChannel>> device_poses,
                       std::function<double()> clock, Sink sink)
    : spec_(spec), device_poses_(std::move(device_poses)), clock_(std::move(clock)), sink_(std::move(sink)) {
  for (size_t i = 0; i < device_poses_.size(); ++i) models_.push_back(std::make_unique<ModelChannel>());
}

HapticLoop::~HapticLoop() { stop(); }

void HapticLoop::publish(size_t slot, const InstrumentRecord& record) {
  HapticModel m;
  bool clamped = false;
  m.time_s = clock_();
  m.x_frame = record.position;
  m.f_frame = record.force;
  m.stiffness = clamp_stiffness(record.stiffness, spec_.max_stiffness_n_per_m, clamped);
  m.valid = true;
  if (clamped) stiffness_clamps_.fetch_add(1, std::memory_order_relaxed);
  models_[slot]->write(m);
}

void HapticLoop::start() {
  if (running_.exchange(true)) return;
  thread_ = std::thread([this] { run(); });
}

void HapticLoop::stop() {
  running_.store(false);
  if (thread_.joinable()) thread_.join();
}

HapticStats HapticLoop::stats() const {
  HapticStats s = stats_;
  s.stiffness_clamps = stiffness_clamps_.load();
  return s;
}

void HapticLoop::run() {
  using Clock = std::chrono::steady_clock;
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / spec_.rate_hz));
  const size_t n = device_poses_.size();
  std::vector<HapticModel> model(n);
  std::vector<DeviceSample> pose(n);
  std::vector<Eigen::Vector3d> previous_x(n, Eigen::Vector3d::Zero());
  std::vector<bool> had_pose(n, false);
  std::vector<Eigen::Vector3d> velocity(n, Eigen::Vector3d::Zero());
  std::vector<HapticForce> forces(n);
  periods_ms_.clear();
  // Real-time priority where the system allows it (a haptic device's loop must not wait behind the simulation's
  // threads on a busy machine); otherwise an ordinary thread, reported.
  sched_param priority{};
  priority.sched_priority = kHapticPriority;
  stats_.realtime = pthread_setschedparam(pthread_self(), SCHED_FIFO, &priority) == 0;
  auto next = Clock::now();
  Clock::time_point first, last;
  // Each tick: the newest model and pose of every slot, the velocity between the last two readings, the force.
  while (running_.load(std::memory_order_relaxed)) {
    const auto now = Clock::now();
    const double tick_s = stats_.ticks > 0 ? std::chrono::duration<double>(now - last).count() : 0.0;
    if (stats_.ticks > 0) {
      const double dt_ms = std::chrono::duration<double, std::milli>(now - last).count();
      if (periods_ms_.size() < kMaxKeptPeriods) periods_ms_.push_back(dt_ms);
      if (now - next >= period) ++stats_.overruns;
    } else {
      first = now;
    }
    last = now;
    ++stats_.ticks;
    const double t = clock_();
    for (size_t i = 0; i < n; ++i) {
      models_[i]->read(model[i]);
      DeviceSample s;
      if (device_poses_[i]->read(s) && s.connected) pose[i] = s;
      const Eigen::Vector3d x = pose[i].seq > 0 ? pose[i].pose.position : model[i].x_frame;
      // Velocity: the device's motion over the tick, low-pass filtered (readings arrive in bursts on a busy
      // network; their arrival times would make spikes).
      if (pose[i].seq > 0 && had_pose[i] && tick_s > 0.0)
        velocity[i] += (tick_s / (kVelocityFilterS + tick_s)) * ((x - previous_x[i]) / tick_s - velocity[i]);
      previous_x[i] = x;
      had_pose[i] = pose[i].seq > 0;
      forces[i] = render_force(spec_, model[i], x, velocity[i], t);
      forces[i].seq = pose[i].seq;
      forces[i].reading_time_s = pose[i].time_s;
      stats_.force_clamps += forces[i].clamped;
      stats_.faded_ticks += model[i].valid && forces[i].weight < 1.0;
    }
    if (sink_) sink_(forces, t);
    // Sleep to the next deadline; after an overrun, restart the schedule from now (no burst of catch-up ticks).
    next += period;
    if (Clock::now() > next) next = Clock::now();
    std::this_thread::sleep_until(next);
  }
  stats_.seconds = stats_.ticks > 1 ? std::chrono::duration<double>(last - first).count() : 0.0;
  stats_.rate_hz = stats_.seconds > 0.0 ? static_cast<double>(stats_.ticks - 1) / stats_.seconds : 0.0;
  // The periods' percentiles as the report's stage times have them (report.hpp summarize).
  const StageSummary periods = summarize(periods_ms_);
  stats_.period_p50_ms = periods.median_ms;
  stats_.period_p99_ms = periods.p99_ms;
  stats_.period_max_ms = periods.max_ms;
}

}  // namespace lumen::engine
