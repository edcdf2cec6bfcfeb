// lumen: the command line. run a scene to frames/video/report, bench it, or run CCD query files.
#include <malloc.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <utility>

#include <CLI/CLI.hpp>

#include "collision/ccd_queries.hpp"
#include "collision/self_collision.hpp"
#include "engine/mesh_check.hpp"
#include "engine/scene.hpp"
#include "engine/serve.hpp"
#include "engine/session.hpp"
#include "engine/simulation.hpp"

namespace fs = std::filesystem;
using namespace lumen;

namespace {

// Exit codes: 0 done; 1 a failure while running (I/O, numerics that could not be survived); 2 bad input (the
// message names the file or option, the key and the value); 3 an internal error (a bug in Lumen).
constexpr int kExitFailure = 1;
constexpr int kExitBadInput = 2;
constexpr int kExitInternalError = 3;
constexpr const char* kCommands[] = {"run", "serve", "bench", "ccd"};
constexpr int kMaxFrames = 10000000;
constexpr int kMaxPort = 65535;  // --port 0: any free port (printed)

// --frames N: a whole number of frames, 1 to kMaxFrames; the message reads like the scene loader's.
std::string check_frames(const std::string& text) {
  size_t used = 0;
  long long v = 0;
  try {
    v = std::stoll(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != text.size() || used == 0) return "must be a whole number of frames (value \"" + text + "\")";
  if (v < 1 || v > kMaxFrames)
    return "out of range [1, " + std::to_string(kMaxFrames) + "] (value " + text + ")";
  return "";
}

// The first argument must name a command; CLI11 alone would report an unknown one as "A subcommand is required".
std::string check_command(int argc, char** argv) {
  std::string list;
  for (const char* c : kCommands) list += (list.empty() ? "" : ", ") + std::string(c);
  if (argc < 2) return "a command is required: one of " + list + " (lumen --help for more)";
  const std::string first = argv[1];
  if (first.rfind("-", 0) == 0) return "";
  for (const char* c : kCommands)
    if (first == c) return "";
  return "unknown command \"" + first + "\": must be one of " + list + " (lumen --help for more)";
}


// Create the output folder and prove it is writable before any work; InputError otherwise.
void prepare_output_dir(const std::string& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) throw engine::InputError(dir + ": cannot create output folder" + (ec ? ": " + ec.message() : ""));
  const fs::path probe = fs::path(dir) / ".lumen_write_test";
  {
    std::ofstream f(probe);
    if (!f) throw engine::InputError(dir + ": output folder is not writable");
  }
  fs::remove(probe, ec);
}

// Where a contact frame's whole-mesh interior is solved, to compare: before the render (--serial-correction), or
// while it renders only (--in-frame-correction); by default on into the next frame (SessionOptions).
struct CorrectionFlags {
  bool serial = false, in_frame = false;
  void apply_to(engine::SessionOptions& opt) const {
    opt.overlap_interior = !serial;
    opt.pipeline_interior = !in_frame;
  }
};

int cmd_run(const std::string& scene_path, std::string out_dir, int frames, bool no_render, std::string video,
            bool export_surface, bool export_volume, bool check, const std::string& positions_path,
            const std::string& replay_dir, const CorrectionFlags& correction) {
  // Load and validate everything before touching the output folder.
  engine::Scene scene = engine::load_scene(scene_path);
  if (out_dir.empty()) out_dir = (fs::path("out") / scene.name).string();
  if (!video.empty() && fs::path(video).extension() != ".mp4")
    throw engine::InputError("--video: must name an .mp4 file (value \"" + video + "\")");
  if (video.empty() && scene.render.video && !no_render) video = (fs::path(out_dir) / "video.mp4").string();
  // Reads (and refuses a bad) replay file now; a served session's replay sets the frame count it recorded.
  int replay_frames = -1;
  engine::Inputs inputs =
      replay_dir.empty() ? engine::make_inputs(scene) : engine::make_replay_inputs(scene, replay_dir, replay_frames);
  if (frames < 0) frames = replay_frames;
  auto model = engine::compile_model(scene);
  std::printf("%s\n", engine::mesh_quality_line(*model, physics::mesh_quality(model->mesh.rest, model->mesh.tets)).c_str());
  engine::SessionOptions opt;
  opt.frames = frames;
  prepare_output_dir(out_dir);
  if (!video.empty()) prepare_output_dir(fs::path(video).parent_path().empty() ? "." : fs::path(video).parent_path().string());
  opt.out_dir = out_dir;
  opt.render = !no_render;
  correction.apply_to(opt);
  opt.write_frames = !no_render;
  opt.video_path = no_render ? std::string() : video;
  opt.export_surface = export_surface;
  opt.export_volume = export_volume;
  opt.volume_material.young_modulus = scene.material.young_modulus;
  opt.volume_material.poisson_ratio = scene.material.poisson_ratio;
  opt.check = check;
  opt.progress = true;
  // Final node positions (for comparing runs to a baseline): the committed state after the last frame.
  Points final_positions;
  if (!positions_path.empty())
    opt.on_end = [&](const engine::Model&, const engine::State& state, const engine::FrameRecord&) {
      final_positions = state.x;
    };

  engine::SessionResult result = engine::run_session(*model, std::move(inputs), opt);
  engine::write_json_file((fs::path(out_dir) / "report.json").string(), result.report);
  if (!positions_path.empty()) engine::write_text_file(positions_path, engine::positions_csv(final_positions));
  std::cout << engine::format_stage_table(result.frames, model->budget_ms);
  if (result.writer.frames > 0)
    std::printf("writer: %ld frames, %.1f frames/s on its thread\n", result.writer.frames, result.writer.frames_per_second());
  if (check) std::printf("frames with intersecting inner-wall pairs: %ld\n", result.report["frames_with_intersections"].get<long>());
  if (check && !model->instruments.empty())
    std::printf("frames with intersecting instrument-organ pairs: %ld\n",
                result.report["frames_with_instrument_intersections"].get<long>());
  std::printf("outputs in %s\n", out_dir.c_str());
  return 0;
}

// SIGINT ends a served session cleanly (after the frame in progress; the report is written).
std::atomic<bool> g_interrupted{false};
extern "C" void on_interrupt(int) { g_interrupted.store(true); }

int cmd_serve(const std::string& scene_path, std::string out_dir, int frames, bool no_render, const std::string& host,
              int port) {
  // Scene, port and model before anything is written.
  const engine::Scene scene = engine::load_scene(scene_path);
  const bool any_device = std::any_of(scene.instruments.begin(), scene.instruments.end(),
                                      [](const engine::InstrumentSpec& i) { return !i.device_name.empty(); });
  if (!any_device)
    throw engine::InputError(scene_path + ": instruments: no instrument has a \"device_name\": nothing to serve");
  if (port < 0 || port > kMaxPort)
    throw engine::InputError("--port: out of range [0, " + std::to_string(kMaxPort) + "] (value " + std::to_string(port) + ")");
  if (out_dir.empty()) out_dir = (fs::path("out") / scene.name).string();
  engine::Listener listener(host, port);
  auto model = engine::compile_model(scene);
  prepare_output_dir(out_dir);
  engine::ServeOptions opt;
  opt.session.frames = frames;
  opt.session.out_dir = out_dir;
  opt.session.render = !no_render;
  opt.session.write_frames = !no_render;
  if (scene.render.video && !no_render) opt.session.video_path = (fs::path(out_dir) / "video.mp4").string();
  opt.interrupted = &g_interrupted;
  std::signal(SIGINT, on_interrupt);
  std::printf("serving %s on port %d (OpenIGTLink)\n", scene.name.c_str(), listener.port());
  std::fflush(stdout);
  engine::ServeResult result = engine::serve_session(scene, *model, std::move(listener), opt);
  std::signal(SIGINT, SIG_DFL);
  engine::write_replay(out_dir, result);
  engine::write_json_file((fs::path(out_dir) / "report.json").string(), result.session.report);
  std::cout << engine::format_stage_table(result.session.frames, model->budget_ms);
  const nlohmann::json& h = result.session.report["haptics"];
  std::printf("haptics: %.1f Hz, period p99 %.3f ms, overruns %ld, force clamps %ld\n", h["rate_hz"].get<double>(),
              h["period_p99_ms"].get<double>(), h["overruns"].get<long>(), h["force_clamps"].get<long>());
  std::printf("replay: lumen run %s --replay %s\n", scene_path.c_str(), out_dir.c_str());
  std::printf("outputs in %s\n", out_dir.c_str());
  return 0;
}

int cmd_bench(const std::string& scene_path, int frames, bool json, bool no_render, int kdop, bool classify,
              const CorrectionFlags& correction) {
  engine::Scene scene = engine::load_scene(scene_path);
  if (kdop > 0 && kdop != 6 && kdop != 14 && kdop != 18 && kdop != 26)
    throw engine::InputError("--kdop: must be one of 6, 14, 18, 26 (value " + std::to_string(kdop) + ")");
  if (kdop > 0) scene.collision.kdop = kdop;
  engine::Inputs inputs = engine::make_inputs(scene);  // refuses a bad replay or a device-only instrument now
  auto model = engine::compile_model(scene);
  engine::SessionOptions opt;
  opt.frames = frames;
  opt.classify_overlaps = classify;
  opt.render = !no_render;
  correction.apply_to(opt);
  opt.write_frames = false;
  engine::SessionResult result = engine::run_session(*model, std::move(inputs), opt);
  if (json) {
    nlohmann::json j = result.report;
    j.erase("per_frame");
    std::cout << j.dump(1) << "\n";
  } else {
    std::printf("scene %s: %d nodes, %ld tets, %ld inner triangles, compile %.3f s\n", scene.name.c_str(),
                model->mesh.n_nodes(), static_cast<long>(model->n_elements), static_cast<long>(model->inner_wall().rows()),
                model->compile_seconds);
    std::cout << engine::format_stage_table(result.frames, model->budget_ms);
  }
  return 0;
}

int cmd_ccd(const std::string& file, bool json) {
  engine::require_file(file, "CCD query file");
  collision::CcdFileStats r;
  try {
    r = collision::run_ccd_file(file);
  } catch (const std::runtime_error& e) {
    throw engine::InputError(e.what());
  }
  std::cout << (json ? collision::format_ccd_json(r) : collision::format_ccd_table(r)) << "\n";
  return 0;
}

// The process keeps the memory it has touched (glibc's malloc): one arena for all threads, blocks up to 32 MB from
// it rather than mapped afresh, and no trimming. Otherwise each new factorisation on the background thread (a new
// thread each time, a new arena, mapped blocks unmapped when freed) touches fresh pages: in a VM at about 6 us a
// page fault, the contact Hessians took 120-170 ms each for the first two on the background thread against 26 ms
// after (paper mesh, 8x pinch; with these settings every one after the session's start took 26-30 ms, measured).
void keep_touched_memory() {
  constexpr int kMmapThresholdBytes = 32 << 20;  // (glibc's largest: HEAP_MAX_SIZE / 2 on 64-bit)
  mallopt(M_ARENA_MAX, 1);
  mallopt(M_MMAP_THRESHOLD, kMmapThresholdBytes);
  mallopt(M_TRIM_THRESHOLD, -1);  // (-1: never trim)
}

}  // namespace

int main(int argc, char** argv) {
  keep_touched_memory();
  CLI::App app{"Lumen: real-time hollow-organ deformation with inner-wall self-collision"};
  app.require_subcommand(1);
  const CLI::Validator frames_check(check_frames, "FRAMES");

  std::string scene_path, out_dir, video, ccd_file, positions_path, replay_dir, host;
  int frames = -1, kdop = 0, port = engine::kDefaultIgtlPort;
  bool classify = false;
  bool no_render = false, export_surface = false, export_volume = false, json = false, check = false;
  CorrectionFlags correction;
  const char* serial_help = "solve a contact frame's whole-mesh correction before rendering instead of on the second "
                            "core while it renders (to compare)";
  const char* in_frame_help = "wait for a contact frame's whole-mesh correction after its render instead of letting "
                              "it solve on into the next frame (to compare)";

  CLI::App* run = app.add_subcommand("run", "run a scene: PNG frames, optional MP4, report.json");
  run->add_option("scene", scene_path, "scene file (JSON)")->required();
  run->add_option("--out", out_dir, "output folder (default out/<scene name>)");
  run->add_option("--frames", frames, "number of frames (overrides the scene)")->check(frames_check);
  run->add_flag("--no-render", no_render, "simulate only (no images, no video)");
  run->add_option("--video", video, "write an MP4 (H.264) to this file");
  run->add_flag("--export-surface", export_surface, "write the deformed inner wall per frame as OBJ (assimp)");
  run->add_flag("--export-volume", export_volume,
                "write the volume mesh per frame as VTK XML (DIR/volume/volume_000001.vtu ..., DIR/volume.pvd)");
  run->add_option("--positions", positions_path, "write the final node positions as CSV (x, y, z per node, metres)");
  run->add_flag("--check", check, "count intersecting inner-wall triangle pairs, and instrument-organ pairs, on every frame (exact predicates)");

  run->add_flag("--serial-correction", correction.serial, serial_help);
  run->add_flag("--in-frame-correction", correction.in_frame, in_frame_help);
  run->add_option("--replay", replay_dir, "play back a served session (its --out folder): its poses and frame count");

  CLI::App* serve = app.add_subcommand("serve", "serve a scene over OpenIGTLink: devices drive its instruments, "
                                                "reactions go back as SENSOR messages; frames, report.json, replay");
  serve->add_option("scene", scene_path, "scene file (JSON)")->required();
  serve->add_option("--port", port, "TCP port to listen on (default 18944)");
  serve->add_option("--host", host, "address to listen on (default: every interface)");
  serve->add_option("--out", out_dir, "output folder (default out/<scene name>)");
  serve->add_option("--frames", frames, "number of frames (overrides the scene)")->check(frames_check);
  serve->add_flag("--no-render", no_render, "simulate only (no images)");

  CLI::App* bench = app.add_subcommand("bench", "run a scene without writing images; print per-stage frame times");
  bench->add_option("scene", scene_path, "scene file (JSON)")->required();
  bench->add_option("--frames", frames, "number of frames (overrides the scene)")->check(frames_check);
  bench->add_flag("--json", json, "print one JSON object");
  bench->add_flag("--no-render", no_render, "leave rendering out");
  bench->add_option("--kdop", kdop, "override the scene's k-DOP (6, 14, 18, 26)");
  bench->add_flag("--classify-overlaps", classify, "count bounding-volume overlaps with and without contact");
  bench->add_flag("--serial-correction", correction.serial, serial_help);
  bench->add_flag("--in-frame-correction", correction.in_frame, in_frame_help);

  CLI::App* ccd = app.add_subcommand("ccd", "run every CCD query of a file; print positives, misses, timings");
  ccd->add_option("file", ccd_file, "query file (CSV, see tests/data/ccd/README.md)")->required();
  ccd->add_flag("--json", json, "print one JSON object");

  // Command-line errors read like the scene loader's: "lumen: error: what: problem (value V)".
  if (const std::string bad = check_command(argc, argv); !bad.empty()) {
    std::fprintf(stderr, "lumen: error: %s\n", bad.c_str());
    return kExitBadInput;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "lumen: error: %s (lumen %s --help for more)\n", e.what(), argv[1]);
    return kExitBadInput;
  }

  try {
    if (*run) return cmd_run(scene_path, out_dir, frames, no_render, video, export_surface, export_volume, check,
                               positions_path, replay_dir, correction);
    if (*serve) return cmd_serve(scene_path, out_dir, frames, no_render, host, port);
    if (*bench) return cmd_bench(scene_path, frames, json, no_render, kdop, classify, correction);
    if (*ccd) return cmd_ccd(ccd_file, json);
  } catch (const engine::InputError& e) {
    std::fprintf(stderr, "lumen: error: %s\n", e.what());
    return kExitBadInput;
  } catch (const std::logic_error& e) {
    // A caller's bug inside Lumen (every user input was validated at the boundary): not the user's fault.
    std::fprintf(stderr, "lumen: internal error: %s\n", e.what());
    return kExitInternalError;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lumen: failed: %s\n", e.what());
    return kExitFailure;
  }
  return 0;
}
