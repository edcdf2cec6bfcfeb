// `lumen serve` as a program: the OpenIGTLink project's own example TrackerClient (Debian openigtlink-examples,
// built from its shipped source) drives an instrument, `lumen run --replay` plays the served session back to the
// same frames and reactions bit for bit, a port in use exits 2 with nothing written, and SIGINT ends a session
// cleanly with its report written.
#include <gtest/gtest.h>

#include <signal.h>
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "engine/serve.hpp"
#include "support/instruments.hpp"

extern char** environ;

using namespace lumen::engine;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

// Where TrackerClient's device origin sits in the organ frame: far above the tube (its path is a 50 mm circle).
constexpr double kOriginY = 0.2;
constexpr double kOriginZ = 0.05;
constexpr double kTrackerRadiusMm = 50.0;  // TrackerClient: x = 50 cos(phi), y = 50 sin(phi), z = 50 cos(phi)

fs::path fresh_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// The small tube with a rod driven by device "Tracker" (TrackerClient's name).
fs::path write_scene(const fs::path& dir) {
  const json rod = {{"type", "rod"}, {"radius", 0.002}, {"length", 0.02}};
  const json s = lumen::test::device_tube_scene("rod", 40, rod, "Tracker", Eigen::Vector3d(0.0, kOriginY, kOriginZ));
  const fs::path p = dir / "tracker.json";
  std::ofstream(p) << s.dump(1);
  return p;
}

// Start a program with stdout and stderr to `log`; its pid.
pid_t spawn(const std::vector<std::string>& args, const fs::path& log) {
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, STDOUT_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&fa, STDOUT_FILENO, STDERR_FILENO);
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = -1;
  if (posix_spawn(&pid, argv[0], &fa, nullptr, argv.data(), environ) != 0) pid = -1;
  posix_spawn_file_actions_destroy(&fa);
  return pid;
}

std::string text_of(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Wait (bounded: 60 s, not a timing requirement) until the log says the server listens.
bool wait_for_serving(const fs::path& log) {
  for (int i = 0; i < 6000; ++i) {
    if (text_of(log).find("serving ") != std::string::npos) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

int exit_code(pid_t pid) {
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// A free port: bound by the kernel's choice, then released.
int free_port() { return Listener("127.0.0.1", 0).port(); }

json report_of(const fs::path& dir) { return json::parse(text_of(dir / "report.json")); }

}  // namespace

TEST(ServeCli, TheOpenIGTLinkTrackerClientDrivesAnInstrumentAndRunReplaysItBitForBit) {
#ifndef LUMEN_TRACKER_CLIENT
  GTEST_SKIP() << "openigtlink-examples is not installed (no TrackerClient source to build)";
#else
  const fs::path d = fresh_dir("lumen_serve_tracker");
  const fs::path scene = write_scene(d);
  const int port = free_port();
  const pid_t serve = spawn({LUMEN_BINARY, "serve", scene.string(), "--host", "127.0.0.1", "--port",
                             std::to_string(port), "--out", (d / "served").string(), "--no-render"},
                            d / "serve.log");
  ASSERT_GT(serve, 0);
  ASSERT_TRUE(wait_for_serving(d / "serve.log")) << text_of(d / "serve.log");
  const pid_t tracker = spawn({LUMEN_TRACKER_CLIENT, "127.0.0.1", std::to_string(port), "100"}, d / "tracker.log");
  ASSERT_GT(tracker, 0);
  EXPECT_EQ(exit_code(serve), 0) << text_of(d / "serve.log");
  kill(tracker, SIGTERM);
  exit_code(tracker);

  const json served = report_of(d / "served");
  const json& s = served["serve"];
  EXPECT_GT(s["received"]["TRANSFORM"].get<long>(), 0) << s.dump(1);
  EXPECT_EQ(s["rejected_total"].get<long>(), 0) << s.dump(1);
  EXPECT_GT(s["devices"][0]["readings_taken"].get<long>(), 0);
  // Once TrackerClient's poses came, the rod is on its path: x = z and x^2 + y^2 = 50 mm squared (device frame).
  int on_path = 0;
  for (const json& f : served["per_frame"]) {
    const json& p = f["instruments"][0]["position"];
    const double x = p[0].get<double>(), y = p[1].get<double>() - kOriginY, z = p[2].get<double>() - kOriginZ;
    if (x == 0.0 && y == 0.0 && z == 0.0) continue;  // home, before the first reading
    ++on_path;
    constexpr double kFloatMm = 1e-4;  // float32 millimetres on the wire
    EXPECT_NEAR(1e3 * x, 1e3 * z, kFloatMm);
    EXPECT_NEAR(1e3 * std::hypot(x, y), kTrackerRadiusMm, kFloatMm);
  }
  EXPECT_GT(on_path, 10);

  // lumen run --replay plays it back: the same frames and reactions, bit for bit (JSON doubles round-trip).
  const pid_t run = spawn({LUMEN_BINARY, "run", scene.string(), "--replay", (d / "served").string(), "--out",
                           (d / "replayed").string(), "--no-render"},
                          d / "run.log");
  ASSERT_EQ(exit_code(run), 0) << text_of(d / "run.log");
  const json replayed = report_of(d / "replayed");
  ASSERT_EQ(replayed["per_frame"].size(), served["per_frame"].size());
  for (size_t i = 0; i < served["per_frame"].size(); ++i) {
    const json &a = served["per_frame"][i], &b = replayed["per_frame"][i];
    EXPECT_EQ(a.at("instruments"), b.at("instruments")) << "frame " << i;
    EXPECT_EQ(a.at("max_displacement_m"), b.at("max_displacement_m")) << "frame " << i;
    EXPECT_EQ(a.at("contacts"), b.at("contacts")) << "frame " << i;
  }
#endif
}

TEST(ServeCli, APortInUseExitsTwoWithNothingWritten) {
  const fs::path d = fresh_dir("lumen_serve_port");
  const fs::path scene = write_scene(d);
  Listener taken("127.0.0.1", 0);
  const pid_t serve = spawn({LUMEN_BINARY, "serve", scene.string(), "--host", "127.0.0.1", "--port",
                             std::to_string(taken.port()), "--out", (d / "out").string()},
                            d / "serve.log");
  EXPECT_EQ(exit_code(serve), 2);
  EXPECT_NE(text_of(d / "serve.log").find("lumen: error: --host 127.0.0.1 --port " + std::to_string(taken.port()) +
                                          ": cannot listen: Address already in use"),
            std::string::npos)
      << text_of(d / "serve.log");
  EXPECT_FALSE(fs::exists(d / "out"));
}

TEST(ServeCli, AnInterruptEndsTheSessionCleanlyWithItsReport) {
  const fs::path d = fresh_dir("lumen_serve_interrupt");
  const fs::path scene = write_scene(d);
  const pid_t serve = spawn({LUMEN_BINARY, "serve", scene.string(), "--host", "127.0.0.1", "--port",
                             std::to_string(free_port()), "--out", (d / "out").string(), "--frames", "100000",
                             "--no-render"},
                            d / "serve.log");
  ASSERT_TRUE(wait_for_serving(d / "serve.log")) << text_of(d / "serve.log");
  kill(serve, SIGINT);
  EXPECT_EQ(exit_code(serve), 0) << text_of(d / "serve.log");
  const json r = report_of(d / "out");
  EXPECT_TRUE(r["serve"]["interrupted"].get<bool>());
  EXPECT_LT(r["frames"].get<long>(), 100000);
  EXPECT_TRUE(fs::exists(d / "out" / "replay" / "instrument_0.csv"));
}

TEST(ServeCli, ABadPortOrASceneWithoutADeviceExitsTwoWithNothingWritten) {
  const fs::path d = fresh_dir("lumen_serve_bad");
  const fs::path scene = write_scene(d);
  const pid_t bad_port = spawn({LUMEN_BINARY, "serve", scene.string(), "--port", "70000", "--out", (d / "out").string()},
                               d / "port.log");
  EXPECT_EQ(exit_code(bad_port), 2);
  EXPECT_NE(text_of(d / "port.log").find("lumen: error: --port: out of range [0, 65535] (value 70000)"), std::string::npos)
      << text_of(d / "port.log");
  // The same scene with its instrument on a track instead of a device: nothing to serve.
  json s = json::parse(text_of(scene));
  s["instruments"][0].erase("device_name");
  s["instruments"][0]["track"] = {{{"t", 0.0}, {"position", {0.0, kOriginY, kOriginZ}}}};
  const fs::path no_device = d / "no_device.json";
  std::ofstream(no_device) << s.dump();
  const pid_t none = spawn({LUMEN_BINARY, "serve", no_device.string(), "--out", (d / "out").string()}, d / "none.log");
  EXPECT_EQ(exit_code(none), 2);
  EXPECT_NE(text_of(d / "none.log").find(no_device.string() + ": instruments: no instrument has a \"device_name\": "
                                         "nothing to serve"),
            std::string::npos)
      << text_of(d / "none.log");
  EXPECT_FALSE(fs::exists(d / "out"));
}
