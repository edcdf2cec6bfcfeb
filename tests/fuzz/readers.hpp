#pragma once
// Every file reader Lumen has, fed one input at a time: the libFuzzer target (tests/fuzz/fuzz_main.cpp,
// tools/fuzz.sh) and the regression test of the inputs kept under tests/fuzz/inputs/ (tests/engine) call the same
// function, so what the fuzzer found is replayed in both of CI's builds.
#include <string>

namespace lumen::fuzz {

// The readers, each with its folder name under tests/fuzz/inputs/ (kReaderNames, same order).
enum class Reader {
  kScene,       // scene JSON (engine::parse_scene)
  kCentreline,  // a swept tube's centreline JSON, read through a scene that names it
  kObj,         // closed organ surfaces through assimp (engine::read_closed_surface), one per format
  kStl,
  kPly,
  kOff,
  kMsh,         // volume meshes (physics::parse_volume_mesh, then physics::make_volume_mesh)
  kVtu,
  kVtk,
  kReplay,      // a probe's replay CSV (engine::ReplaySource)
  kPose,        // an instrument's pose track CSV (engine::read_pose_csv)
  kCcd,         // CCD query CSV (collision::read_ccd_queries)
  kCount
};
inline constexpr const char* kReaderNames[] = {"scene", "centreline", "obj", "stl", "ply", "off",
                                               "msh",   "vtu",        "vtk", "replay", "pose", "ccd"};
static_assert(sizeof(kReaderNames) / sizeof(kReaderNames[0]) == static_cast<int>(Reader::kCount));

// The reader named `name`, or Reader::kCount when there is none.
Reader reader_named(const std::string& name);

// What one input came to: read, or refused with the reader's documented error.
struct Outcome {
  bool read = false;
  std::string message;  // the refusal's text (empty when read)
};

// Feed `bytes` to `reader` as the file `folder`/input.<ext> (written there for the readers that take a path).
// A refusal must be the reader's documented error type and name the file: another exception propagates as it is, a
// refusal that does not name the file throws std::logic_error; the fuzz target lets either escape (a finding).
// Crashes, sanitizer reports and exhausted memory end the process, as they would a session.
Outcome read_input(Reader reader, const std::string& bytes, const std::string& folder);

}  // namespace lumen::fuzz
