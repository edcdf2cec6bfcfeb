#include "fuzz/readers.hpp"

#include <fstream>
#include <stdexcept>

#include "collision/ccd_queries.hpp"
#include "engine/input.hpp"
#include "engine/pose_track.hpp"
#include "engine/scene.hpp"
#include "engine/surface_file.hpp"
#include "physics/volume_mesh.hpp"
#include "physics/volume_mesh_files.hpp"

namespace lumen::fuzz {

namespace {

// Metres per unit for the readers that scale (the organ files' millimetres).
constexpr double kFuzzMetresPerUnit = 1e-3;
// How long assimp may take on one input (seconds): the valid inputs here read in milliseconds, and a run must not
// spend the default minute on each endless loop it finds.
constexpr double kFuzzSurfaceTimeoutS = 2.0;

// A swept tube scene naming centreline.json beside it: every other key valid, so the centreline is what is read.
constexpr const char* kCentrelineScene = R"({"name": "centreline",
  "mesh": {"type": "swept_tube", "centreline": "centreline.json", "units": "mm", "radius": 7.0,
           "wall_thickness": 2.5, "segments_around": 8, "segment_length": 5.0, "layers": 1},
  "material": {"model": "linear", "young_modulus": 5000.0, "poisson_ratio": 0.45, "density": 1050.0},
  "fixed": ["ends"], "probes": [], "frames": 1, "fps": 40})";

// The file name an input is written to (or named by, for the readers of text).
std::string file_for(Reader reader, const std::string& folder) {
  if (reader == Reader::kCentreline) return folder + "/centreline.json";
  static constexpr const char* kExtensions[] = {"json", "json", "obj", "stl", "ply", "off",
                                                "msh",  "vtu",  "vtk", "csv", "csv", "csv"};
  return folder + "/input." + kExtensions[static_cast<int>(reader)];
}

void write_file(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::logic_error(path + ": the fuzz harness cannot write its input file");
}

// Read one input; the documented refusals propagate (typed), everything else is the caller's to judge.
void read_as(Reader reader, const std::string& bytes, const std::string& file, const std::string& folder) {
  switch (reader) {
    case Reader::kScene:
      engine::parse_scene(bytes, file);
      return;
    case Reader::kCentreline:
      write_file(file, bytes);
      engine::parse_scene(kCentrelineScene, folder + "/scene.json");
      return;
    case Reader::kObj:
    case Reader::kStl:
    case Reader::kPly:
    case Reader::kOff:
      write_file(file, bytes);
      engine::read_closed_surface(file, kFuzzMetresPerUnit, kFuzzSurfaceTimeoutS);
      return;
    case Reader::kMsh:
    case Reader::kVtu:
    case Reader::kVtk: {
      const std::string format = kReaderNames[static_cast<int>(reader)];
      const physics::VolumeMeshFile f = physics::parse_volume_mesh(bytes, format, file);
      physics::make_volume_mesh(f, kFuzzMetresPerUnit, physics::WallTags{});
      return;
    }
    case Reader::kReplay:
      write_file(file, bytes);
      engine::ReplaySource{file};
      return;
    case Reader::kPose:
      write_file(file, bytes);
      engine::read_pose_csv(file);
      return;
    case Reader::kCcd:
      write_file(file, bytes);
      collision::read_ccd_queries(file);
      return;
    case Reader::kCount:
      break;
  }
  throw std::logic_error("no such reader");
}

// A refusal's text must name the file it refuses (the scene's, or the centreline's through it).
Outcome refused(const std::string& message, const std::string& file, const std::string& folder) {
  const bool names_file = message.find(file) != std::string::npos ||
                          message.find(folder + "/scene.json") != std::string::npos;
  if (!names_file) throw std::logic_error("a refusal that does not name " + file + ": " + message);
  return Outcome{false, message};
}

}  // namespace

Reader reader_named(const std::string& name) {
  for (int i = 0; i < static_cast<int>(Reader::kCount); ++i)
    if (name == kReaderNames[i]) return static_cast<Reader>(i);
  return Reader::kCount;
}

Outcome read_input(Reader reader, const std::string& bytes, const std::string& folder) {
  const std::string file = file_for(reader, folder);
  // The documented error of each reader: InputError (engine), std::invalid_argument (physics' volume meshes),
  // std::runtime_error (the CCD query file; InputError and invalid_argument's siblings are caught first).
  try {
    read_as(reader, bytes, file, folder);
  } catch (const engine::InputError& e) {
    return refused(e.what(), file, folder);
  } catch (const std::invalid_argument& e) {
    if (reader != Reader::kMsh && reader != Reader::kVtu && reader != Reader::kVtk) throw;
    return refused(e.what(), file, folder);
  } catch (const std::runtime_error& e) {
    if (reader != Reader::kCcd) throw;
    return refused(e.what(), file, folder);
  }
  return Outcome{true, ""};
}

}  // namespace lumen::fuzz
