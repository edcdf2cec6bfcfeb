// The lumen program end to end: bad input exits 2 with a message naming file, key and value, and leaves the
// output folder empty; a short run writes frames, video and a report whose numbers agree with each other.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "render/writers.hpp"
#include "support/files.hpp"

namespace fs = std::filesystem;

namespace {

using CliRun = lumen::test::CommandRun;  // output: stdout + stderr

// Runs build/lumen; output is stdout and, when merge_stderr, stderr too.
CliRun run_lumen(const std::string& args, bool merge_stderr = true) {
  return lumen::test::run_command(std::string(LUMEN_BINARY) + " " + args + (merge_stderr ? " 2>&1" : " 2>/dev/null"));
}

std::string small_scene(const std::string& name, const std::string& extra_render = "") {
  return R"({"name": ")" + name + R"(",
    "mesh": {"type": "hollow_cylinder", "inner_radius": 0.01, "outer_radius": 0.013, "length": 0.1,
             "segments_around": 12, "segments_along": 10, "layers": 2},
    "material": {"model": "linear", "young_modulus": 5000.0, "poisson_ratio": 0.45},
    "fixed": ["ends"],
    "probes": [{"point": [0.0, 0.013, 0.05], "track": [{"t": 0.0, "force": [0, 0, 0]}, {"t": 0.2, "force": [0, -0.3, 0]}]}],
    "frames": 6, "fps": 40,
    "render": {"width": 160, "height": 120, "camera": "side", "video": true)" + extra_render + R"(}})";
}

bool is_empty_dir(const fs::path& d) { return !fs::exists(d) || fs::is_empty(d); }

}  // namespace

TEST(Cli, BadSceneExitsTwoNamingFileKeyValueAndWritesNothing) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_cli_", "bad");
  std::string text = small_scene("bad");
  text.replace(text.find("0.45"), 4, "0.7");
  std::ofstream(d / "bad.json") << text;
  const fs::path out = d / "out";
  CliRun r = run_lumen("run " + (d / "bad.json").string() + " --out " + out.string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find((d / "bad.json").string() + ": material.poisson_ratio: out of range (-1, 0.5) (value 0.7)"),
            std::string::npos)
      << r.output;
  EXPECT_TRUE(is_empty_dir(out));
}

TEST(Cli, MissingSceneAndUnwritableOutput) {
  CliRun r = run_lumen("run /nonexistent/scene.json --no-render");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("/nonexistent/scene.json: no such scene file"), std::string::npos) << r.output;

  const fs::path d = lumen::test::fresh_temp_dir("lumen_cli_", "unwritable");
  std::ofstream(d / "s.json") << small_scene("s");
  std::ofstream(d / "file") << "x";  // a file where the output folder should be
  r = run_lumen("run " + (d / "s.json").string() + " --out " + (d / "file" / "out").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find((d / "file" / "out").string() + ": cannot create output folder"), std::string::npos) << r.output;
}

// The command line's own errors read like the scene loader's: what, the problem, the value; exit 2.
TEST(Cli, CommandLineErrorsNameTheArgumentAndTheValue) {
  CliRun r = run_lumen("frobnicate");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("lumen: error: unknown command \"frobnicate\": must be one of run, serve, bench, ccd"),
            std::string::npos) << r.output;
  r = run_lumen("");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("lumen: error: a command is required: one of run, serve, bench, ccd"), std::string::npos) << r.output;

  const fs::path d = lumen::test::fresh_temp_dir("lumen_cli_", "cli_args");
  std::ofstream(d / "s.json") << small_scene("s");
  r = run_lumen("run " + (d / "s.json").string() + " --frames 0 --out " + (d / "out").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("--frames: out of range [1, 10000000] (value 0)"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("1797693"), std::string::npos) << r.output;
  r = run_lumen("run " + (d / "s.json").string() + " --frames abc --out " + (d / "out").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("--frames: must be a whole number of frames (value \"abc\")"), std::string::npos) << r.output;
  r = run_lumen("bench " + (d / "s.json").string() + " --kdop 7");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("--kdop: must be one of 6, 14, 18, 26 (value 7)"), std::string::npos) << r.output;
  // A folder where a file is expected.
  r = run_lumen("run " + d.string() + " --out " + (d / "out").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find(d.string() + ": is a folder, not a scene file"), std::string::npos) << r.output;
  r = run_lumen("ccd " + d.string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find(d.string() + ": is a folder, not a CCD query file"), std::string::npos) << r.output;
  EXPECT_TRUE(is_empty_dir(d / "out"));
}

TEST(Cli, BadReplayFileExitsTwoBeforeWriting) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_cli_", "replay");
  std::ofstream(d / "r.csv") << "0,0,0.013,0.05,0,0,0\n0.1,0,0.013,0.05,0,oops,0\n";
  std::string text = small_scene("replay");
  const std::string track = R"("track": [{"t": 0.0, "force": [0, 0, 0]}, {"t": 0.2, "force": [0, -0.3, 0]}])";
  text.replace(text.find(track), track.size(), R"("replay": "r.csv")");
  std::ofstream(d / "s.json") << text;
  CliRun r = run_lumen("run " + (d / "s.json").string() + " --out " + (d / "out").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find((d / "r.csv").string() + ": line 2: field fy: not a number (value \"oops\")"), std::string::npos)
      << r.output;
  EXPECT_TRUE(is_empty_dir(d / "out"));
}

TEST(Cli, RunWritesFramesVideoReportAndSurface) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_cli_", "run");
  std::ofstream(d / "s.json") << small_scene("small");
  const fs::path out = d / "out";
  CliRun r = run_lumen("run " + (d / "s.json").string() + " --out " + out.string() + " --export-surface --check");
  ASSERT_EQ(r.code, 0) << r.output;
  for (int i = 1; i <= 6; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06d.png", i);
    EXPECT_TRUE(fs::exists(out / "frames" / name)) << name;
    std::snprintf(name, sizeof name, "inner_%06d.obj", i);
    EXPECT_TRUE(fs::exists(out / "surface" / name)) << name;
  }
  EXPECT_FALSE(fs::exists(out / "frames" / "frame_000007.png"));
  // No temporary file is left behind anywhere.
  for (const auto& e : fs::recursive_directory_iterator(out))
    EXPECT_EQ(e.path().string().find(".tmp"), std::string::npos) << e.path();
  // The video decodes to one frame per simulated frame.
  auto info = lumen::render::probe_video((out / "video.mp4").string());
  EXPECT_EQ(info.frames, 6);
  EXPECT_EQ(info.width, 160);
  EXPECT_EQ(info.height, 120);
  // Report: counts agree with the mesh formula, one per_frame entry per frame, stage stats ordered.
  std::ifstream in(out / "report.json");
  auto rep = nlohmann::json::parse(in);
  EXPECT_EQ(rep["scene"], "small");
  EXPECT_EQ(rep["frames"], 6);
  EXPECT_DOUBLE_EQ(rep["budget_ms"].get<double>(), 25.0);
  EXPECT_EQ(rep["mesh"]["nodes"], 12 * 11 * 3);
  EXPECT_EQ(rep["mesh"]["tets"], 6 * 12 * 10 * 2);
  EXPECT_EQ(rep["mesh"]["inner_triangles"], 2 * 12 * 10);
  ASSERT_EQ(rep["per_frame"].size(), 6u);
  for (const char* s : {"input", "physics", "collision", "response", "render", "total"}) {
    const auto& st = rep["stages"][s];
    EXPECT_LE(st["median_ms"].get<double>(), st["p95_ms"].get<double>()) << s;
    EXPECT_LE(st["p95_ms"].get<double>(), st["p99_ms"].get<double>()) << s;
    EXPECT_LE(st["p99_ms"].get<double>(), st["max_ms"].get<double>()) << s;
  }
  long over = 0;
  for (const auto& f : rep["per_frame"]) {
    over += f["over_budget"].get<bool>();
    EXPECT_EQ(f["intersecting_pairs"], 0);
    EXPECT_EQ(f["over_budget"].get<bool>(), f["total_ms"].get<double>() > 25.0);
  }
  EXPECT_EQ(rep["over_budget_frames"].get<long>(), over);
  // The probe pushes -y: the last frame moved the wall, the first (zero force) hardly.
  EXPECT_GT(rep["per_frame"][5]["max_displacement_m"].get<double>(), 1e-4);
}

TEST(Cli, BenchPrintsStageTableAsJson) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_cli_", "bench");
  std::ofstream(d / "s.json") << small_scene("small");
  CliRun r = run_lumen("bench " + (d / "s.json").string() + " --frames 4 --json", false);
  ASSERT_EQ(r.code, 0) << r.output;
  auto j = nlohmann::json::parse(r.output);
  EXPECT_EQ(j["frames"], 4);
  EXPECT_TRUE(j["stages"].contains("total"));
  EXPECT_FALSE(fs::exists(fs::path("out") / "small" / "frames"));
}

// An instrument driven only by a device (the bridge is not built) and a bad instrument key: exit 2 from run and
// bench, naming the scene file, the key and the value, and nothing written.
TEST(Cli, InstrumentErrorsExitTwoBeforeWriting) {
  const fs::path d = lumen::test::fresh_temp_dir("lumen_cli_", "instrument");
  nlohmann::json scene = nlohmann::json::parse(small_scene("instrument"));
  scene["instruments"] = {{{"name", "probe"},
                           {"shape", {{"type", "sphere_probe"}, {"tip_radius", 0.003}, {"shaft_radius", 0.002},
                                      {"shaft_length", 0.08}}},
                           {"device_name", "Tracker"}}};
  std::ofstream(d / "device.json") << scene.dump();
  for (const std::string& command : {"run " + (d / "device.json").string() + " --out " + (d / "out").string(),
                                     "bench " + (d / "device.json").string()}) {
    CliRun r = run_lumen(command);
    EXPECT_EQ(r.code, 2) << command;
    EXPECT_NE(r.output.find((d / "device.json").string() + ": instruments[0].device_name: poses from a device need "
                            "the OpenIGTLink bridge: run it with `lumen serve`"),
              std::string::npos)
        << command << ": " << r.output;
  }
  scene["instruments"][0]["shape"]["tip_radius"] = 0.0;
  std::ofstream(d / "zero.json") << scene.dump();
  CliRun r = run_lumen("run " + (d / "zero.json").string() + " --out " + (d / "out").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find((d / "zero.json").string() + ": instruments[0].shape.tip_radius: must be > 0 (value 0)"),
            std::string::npos)
      << r.output;
  EXPECT_TRUE(is_empty_dir(d / "out"));
}
