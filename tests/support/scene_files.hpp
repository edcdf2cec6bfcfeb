// Test support for scene files: a scene written to a folder, the message its loading refuses it with, and
// `lumen run` on it (the engine tests' LUMEN_BINARY).
#pragma once

#include <filesystem>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "engine/scene.hpp"
#include "engine/session.hpp"
#include "engine/simulation.hpp"
#include "support/files.hpp"

namespace lumen::test {

// The message of the InputError that parsing a scene's JSON throws ("" when it parses), as from "dir/s.json".
inline std::string scene_parse_error(const nlohmann::json& scene) {
  return message_of<engine::InputError>([&] { engine::parse_scene(scene.dump(), "dir/s.json"); });
}

// Writes the scene as d/s.json; its path.
inline std::string write_scene(const std::filesystem::path& d, const nlohmann::json& scene) {
  std::ofstream(d / "s.json") << scene.dump();
  return (d / "s.json").string();
}

// The InputError message load_scene refuses the scene file with ("" when it loads).
inline std::string load_error(const std::string& scene) {
  return message_of<engine::InputError>([&] { engine::load_scene(scene); });
}

// The scene's session, headless, with the exact intersection check on every frame.
inline engine::SessionResult run_checked_session(const engine::Scene& scene) {
  const auto model = engine::compile_model(scene);
  engine::SessionOptions opt;
  opt.render = false;
  opt.check = true;
  return engine::run_session(*model, engine::make_inputs(scene), opt);
}

#ifdef LUMEN_BINARY
// lumen run on a scene (with `options`) into `out`: the exit code; what it printed (both streams) in `text`.
inline int run_lumen(const std::string& scene, const std::filesystem::path& out, std::string& text,
                     const std::string& options = "") {
  const CommandRun r =
      run_command(std::string(LUMEN_BINARY) + " run " + scene + options + " --out " + out.string() + " 2>&1");
  text += r.output;
  return r.code;
}
#endif

}  // namespace lumen::test
