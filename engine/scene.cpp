#include "engine/scene.hpp"

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>
#include <tuple>

#include <nlohmann/json.hpp>

#include "engine/clock.hpp"
#include "engine/surface_radius.hpp"

namespace lumen::engine {
namespace {

using nlohmann::json;

// JSON names of the scene's choices, indexed by the enum's value.
constexpr const char* kMaterialModelNames[] = {"linear", "corotational"};
constexpr const char* kElementNames[] = {"tet4", "tet10"};
constexpr const char* kSolverNames[] = {"quasi_static", "dynamic"};
constexpr const char* kResponseNames[] = {"paper", "constraint"};
constexpr const char* kLcpSolverNames[] = {"active_set", "nncg"};
constexpr const char* kRecheckNames[] = {"restricted", "full"};
constexpr const char* kDetectionNames[] = {"restricted", "full"};
constexpr const char* kCouplingNames[] = {"correct", "carried", "solved"};
constexpr const char* kEquilibriumHessianNames[] = {"lagged", "warped_rest"};
constexpr const char* kTangentNames[] = {"warped", "projected", "exact"};
constexpr const char* kMethodNames[] = {"pcg", "chord"};
constexpr const char* kTwistEndNames[] = {"", "start", "stop"};
constexpr const char* kNodeSetNames[] = {"ends", "start", "stop"};
constexpr const char* kCameraNames[] = {"side", "diagonal", "endoscope"};
constexpr const char* kMeshTypeNames[] = {"hollow_cylinder", "swept_tube", "volume", "surface_wall", "surface_pair"};
// Names of physics::PairMesher (mesh.mesher of a surface pair).
constexpr const char* kPairMesherNames[] = {"auto", "gmsh", "netgen"};
// Names of MeshUnits (mesh.units of a swept tube, an instrument mesh's units).
constexpr const char* kLengthUnitNames[] = {"m", "mm"};
// A range end within this fraction of the centreline's arc length past it is its end (decimal rounding).
constexpr double kRangeEndTolerance = 1e-9;
constexpr const char* kRodEndNames[] = {"flat", "rounded"};
// Entries of a row-major 4 x 4 transform, and of a quaternion [w, x, y, z].
constexpr size_t kMatrixEntries = 16;
constexpr size_t kQuaternionEntries = 4;

// Reads one JSON object, checking keys, types and ranges; every error names file, key path and value.
class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const std::string& key, const std::string& problem, const json* value) const {
    std::string msg = file_ + ": " + (key.empty() ? "(top level)" : key) + ": " + problem;
    if (value) msg += " (value " + value->dump() + ")";
    throw InputError(msg);
  }

  // Refuse keys that are not in `allowed`.
  void only_keys(const json& obj, const std::string& path, std::initializer_list<const char*> allowed) const {
    if (!obj.is_object()) fail(path, "must be an object", &obj);
    std::set<std::string> ok(allowed.begin(), allowed.end());
    for (auto it = obj.begin(); it != obj.end(); ++it)
      if (!ok.count(it.key())) fail(join(path, it.key()), "unknown key", nullptr);
  }

  const json& require(const json& obj, const std::string& path, const char* key) const {
    if (!obj.contains(key)) fail(join(path, key), "missing key", nullptr);
    return obj.at(key);
  }

  double number(const json& v, const std::string& path) const {
    if (!v.is_number()) fail(path, "must be a number", &v);
    double d = v.get<double>();
    if (!std::isfinite(d)) fail(path, "must be finite", &v);
    return d;
  }
  // Number in the open/closed range given; messages say the range.
  double number_in(const json& v, const std::string& path, double lo, double hi, bool lo_open, bool hi_open) const {
    double d = number(v, path);
    bool bad = (lo_open ? d <= lo : d < lo) || (hi_open ? d >= hi : d > hi);
    if (bad) {
      std::ostringstream r;
      r << "out of range " << (lo_open ? "(" : "[") << lo << ", " << hi << (hi_open ? ")" : "]");
      fail(path, r.str(), &v);
    }
    return d;
  }
  double positive(const json& v, const std::string& path) const {
    double d = number(v, path);
    if (!(d > 0)) fail(path, "must be > 0", &v);
    return d;
  }
  int integer_in(const json& v, const std::string& path, int lo, int hi) const {
    if (!v.is_number_integer()) fail(path, "must be an integer", &v);
    long long i = v.get<long long>();
    if (i < lo || i > hi)
      fail(path, "out of range [" + std::to_string(lo) + ", " + std::to_string(hi) + "]", &v);
    return static_cast<int>(i);
  }
  bool boolean(const json& v, const std::string& path) const {
    if (!v.is_boolean()) fail(path, "must be true or false", &v);
    return v.get<bool>();
  }
  std::string string(const json& v, const std::string& path) const {
    if (!v.is_string()) fail(path, "must be a string", &v);
    return v.get<std::string>();
  }
  std::string one_of(const json& v, const std::string& path, std::initializer_list<const char*> names) const {
    std::string s = string(v, path);
    std::string list;
    for (const char* n : names) {
      if (s == n) return s;
      list += (list.empty() ? "" : ", ") + std::string(n);
    }
    fail(path, "must be one of " + list, &v);
  }
  // One of the names of an enum (names[i] is value i); `first` skips leading values that have no JSON name.
  template <class E, size_t N>
  E choice(const json& v, const std::string& path, const char* const (&names)[N], size_t first = 0) const {
    const std::string s = string(v, path);
    std::string list;
    for (size_t i = first; i < N; ++i) {
      if (s == names[i]) return static_cast<E>(i);
      list += (list.empty() ? "" : ", ") + std::string(names[i]);
    }
    fail(path, "must be one of " + list, &v);
  }
  Eigen::Vector3d vec3(const json& v, const std::string& path) const {
    if (!v.is_array() || v.size() != 3) fail(path, "must be an array of 3 numbers", &v);
    Eigen::Vector3d r;
    for (int i = 0; i < 3; ++i) r[i] = number(v[i], path + "[" + std::to_string(i) + "]");
    return r;
  }

  static std::string join(const std::string& path, const std::string& key) {
    return path.empty() ? key : path + "." + key;
  }
  static std::string index(const std::string& path, size_t i) { return path + "[" + std::to_string(i) + "]"; }
  // "FILE: PATH", the prefix of messages made by the validators outside the reader (instrument, pose_track).
  std::string where(const std::string& path) const { return file_ + ": " + path; }

 private:
  std::string file_;
};

// One graded direction of mesh.grading: {"at" | "at_deg": [foci...], "ratio": r}; angles in degrees.
physics::CellGrading read_grading(const Reader& r, const json& g, const std::string& path, const char* at_key,
                                  double to_model_units, double lo, double hi) {
  r.only_keys(g, path, {at_key, "ratio"});
  physics::CellGrading grading;
  grading.ratio = r.number_in(r.require(g, path, "ratio"), Reader::join(path, "ratio"), 1.0,
                              physics::kMaxGradingRatio, false, false);
  const json& at = r.require(g, path, at_key);
  const std::string at_path = Reader::join(path, at_key);
  if (!at.is_array() || at.empty()) r.fail(at_path, "must be a non-empty array of numbers", &at);
  for (size_t i = 0; i < at.size(); ++i)
    grading.focus.push_back(to_model_units * r.number_in(at[i], Reader::index(at_path, i), lo, hi, false, false));
  return grading;
}

// mesh.grading: {"around": {"at_deg": [...], "ratio"}, "along": {"at": [...] (metres along the axis), "ratio"}},
// each optional: cells shrink toward those angles and arc lengths (physics::CellGrading).
void read_cylinder_grading(const Reader& r, const json& g, physics::HollowCylinderSpec& spec) {
  r.only_keys(g, "mesh.grading", {"around", "along"});
  constexpr double kRadiansPerDegree = static_cast<double>(EIGEN_PI) / 180.0;
  if (g.contains("around"))
    spec.grading_around = read_grading(r, g.at("around"), "mesh.grading.around", "at_deg", kRadiansPerDegree,
                                       -360.0, 360.0);
  if (g.contains("along"))
    spec.grading_along = read_grading(r, g.at("along"), "mesh.grading.along", "at", 1.0, 0.0, spec.length);
}

void read_hollow_cylinder(const Reader& r, const json& m, physics::HollowCylinderSpec& spec) {
  r.only_keys(m, "mesh", {"type", "inner_radius", "outer_radius", "length", "segments_around", "segments_along",
                          "layers", "bend_radius", "element", "grading"});
  spec.inner_radius = r.positive(r.require(m, "mesh", "inner_radius"), "mesh.inner_radius");
  spec.outer_radius = r.positive(r.require(m, "mesh", "outer_radius"), "mesh.outer_radius");
  if (spec.inner_radius >= spec.outer_radius)
    r.fail("mesh.inner_radius", "must be < mesh.outer_radius (" + std::to_string(spec.outer_radius) + ")",
           &m.at("inner_radius"));
  spec.length = r.positive(r.require(m, "mesh", "length"), "mesh.length");
  spec.segments_around = r.integer_in(r.require(m, "mesh", "segments_around"), "mesh.segments_around", 3, 4096);
  spec.segments_along = r.integer_in(r.require(m, "mesh", "segments_along"), "mesh.segments_along", 1, 4096);
  spec.layers = r.integer_in(r.require(m, "mesh", "layers"), "mesh.layers", 1, 256);
  if (m.contains("bend_radius")) {
    spec.bend_radius = r.number(m.at("bend_radius"), "mesh.bend_radius");
    if (spec.bend_radius != 0.0 && !(spec.bend_radius > spec.outer_radius))
      r.fail("mesh.bend_radius", "must be 0 (straight) or > mesh.outer_radius", &m.at("bend_radius"));
  }
  if (m.contains("grading")) read_cylinder_grading(r, m.at("grading"), spec);
}

// Rows of 3 numbers (a centreline file's points, tangents or normals), n of them, times `scale`.
Points read_rows(const Reader& r, const json& v, const char* key, size_t n, double scale) {
  if (!v.is_array() || v.size() != n)
    r.fail(key, "must be an array of " + std::to_string(n) + " [x, y, z] rows (one per point)", nullptr);
  Points rows(static_cast<Eigen::Index>(n), 3);
  for (size_t i = 0; i < n; ++i) rows.row(static_cast<Eigen::Index>(i)) = scale * r.vec3(v[i], Reader::index(key, i)).transpose();
  return rows;
}

// A centreline file {"n", "points", "tangents", "normals"} (tangents and normals optional), points scaled to
// metres; its geometry validated (physics::validate_centreline), every error naming the file, field and sample.
physics::Centreline read_centreline(const std::string& file, double metres_per_unit) {
  require_file(file, "centreline file");
  std::ifstream in(file, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  if (!in) throw InputError(file + ": cannot read centreline file");
  json root;
  try {
    root = json::parse(text.str());
  } catch (const json::exception& e) {
    throw InputError(file + ": malformed JSON: " + e.what());
  }
  const Reader r(file);
  r.only_keys(root, "", {"n", "points", "tangents", "normals"});
  const json& points = r.require(root, "", "points");
  if (!points.is_array() || points.empty()) r.fail("points", "must be a non-empty array of [x, y, z] rows", nullptr);
  const size_t n = points.size();
  if (root.contains("n") && r.integer_in(root.at("n"), "n", 0, std::numeric_limits<int>::max()) != static_cast<int>(n))
    r.fail("n", "must equal the number of points (" + std::to_string(n) + ")", &root.at("n"));
  physics::Centreline c;
  c.points = read_rows(r, points, "points", n, metres_per_unit);
  if (root.contains("tangents")) c.tangents = read_rows(r, root.at("tangents"), "tangents", n, 1.0);
  if (root.contains("normals")) c.normals = read_rows(r, root.at("normals"), "normals", n, 1.0);
  try {
    physics::validate_centreline(c, file);
  } catch (const std::invalid_argument& e) {
    throw InputError(e.what());
  }
  return c;
}

// A file named by a scene key, relative to the scene file's folder: its absolute, normalised path.
std::string scene_relative(const Reader& r, const json& v, const std::string& path, const std::filesystem::path& dir) {
  std::filesystem::path file = r.string(v, path);
  if (file.is_relative()) file = dir / file;
  return file.lexically_normal().string();
}

// mesh.radius of a swept tube: a number, a profile [[s, r], ...] along the arc length (file units), or
// {"from_surface": FILE} (the file's path returned; the profile is sampled once the other keys are read).
std::string read_radius(const Reader& r, const json& v, double unit, const std::filesystem::path& dir,
                        physics::SweptTubeSpec& spec) {
  if (v.is_object()) {
    r.only_keys(v, "mesh.radius", {"from_surface"});
    return scene_relative(r, r.require(v, "mesh.radius", "from_surface"), "mesh.radius.from_surface", dir);
  }
  if (!v.is_array()) {
    spec.radius = unit * r.positive(v, "mesh.radius");
    return "";
  }
  if (v.size() < 2) r.fail("mesh.radius", "a profile needs at least 2 [s, r] pairs", &v);
  for (size_t k = 0; k < v.size(); ++k) {
    const std::string at = Reader::index("mesh.radius", k);
    if (!v[k].is_array() || v[k].size() != 2) r.fail(at, "must be a pair [s, r]", &v[k]);
    physics::RadiusKnot knot{unit * r.number(v[k][0], at + "[0]"), unit * r.positive(v[k][1], at + "[1]")};
    if (!spec.radius_profile.empty() && !(knot.s > spec.radius_profile.back().s))
      r.fail(at + "[0]", "arc lengths must be strictly increasing", &v[k][0]);
    spec.radius_profile.push_back(knot);
  }
  return "";
}

// mesh.range: [s0, s1] within the centreline's arc length (file units); the whole centreline when absent.
void read_range(const Reader& r, const json& m, double unit, physics::SweptTubeSpec& spec) {
  const double length = physics::arc_lengths(spec.centreline.points).back();
  spec.range_start = 0.0;
  spec.range_stop = length;
  if (!m.contains("range")) return;
  const json& v = m.at("range");
  if (!v.is_array() || v.size() != 2) r.fail("mesh.range", "must be [start, stop] (arc lengths)", &v);
  spec.range_start = unit * r.number(v[0], "mesh.range[0]");
  spec.range_stop = unit * r.number(v[1], "mesh.range[1]");
  std::ostringstream within;
  within << "must lie within the centreline's arc length [0, " << length / unit << "] of " << spec.source
         << ", start < stop";
  if (spec.range_stop > length && spec.range_stop <= length * (1.0 + kRangeEndTolerance)) spec.range_stop = length;
  if (!(spec.range_start >= 0.0 && spec.range_start < spec.range_stop && spec.range_stop <= length))
    r.fail("mesh.range", within.str(), &v);
}

// Cross-checks of a swept tube's keys: the profile covers the range, haustra resolved, rings bounded.
void check_swept_tube(const Reader& r, const json& m, const physics::SweptTubeSpec& spec) {
  if (!spec.radius_profile.empty() &&
      (spec.radius_profile.front().s > spec.range_start || spec.radius_profile.back().s < spec.range_stop))
    r.fail("mesh.radius", "the profile must cover mesh.range (first s <= range start, last s >= range stop)",
           &m.at("radius"));
  if (spec.haustra.enabled() && spec.haustra.pitch < physics::kMinRingsPerHaustrum * spec.segment_length)
    r.fail("mesh.haustra.pitch",
           "must be at least " + std::to_string(physics::kMinRingsPerHaustrum) + " mesh.segment_length",
           &m.at("haustra").at("pitch"));
  if (!((spec.range_stop - spec.range_start) / spec.segment_length < physics::kMaxSweptRings))
    r.fail("mesh.segment_length", "gives more than " + std::to_string(physics::kMaxSweptRings) + " rings over the range",
           &m.at("segment_length"));
}

// mesh.units: metres per unit of the mesh's files and lengths ("m", the default, or "mm").
double read_metres_per_unit(const Reader& r, const json& m) {
  const MeshUnits units = m.contains("units") ? r.choice<MeshUnits>(m.at("units"), "mesh.units", kLengthUnitNames)
                                              : MeshUnits::kMetres;
  return kMetresPerUnit[static_cast<int>(units)];
}

void read_swept_tube(const Reader& r, const json& m, const std::filesystem::path& dir, Scene& scene) {
  physics::SweptTubeSpec& spec = scene.swept_tube;
  r.only_keys(m, "mesh", {"type", "element", "centreline", "units", "range", "radius", "wall_thickness",
                          "segments_around", "segment_length", "layers", "haustra"});
  const double unit = read_metres_per_unit(r, m);
  scene.swept_tube_unit = unit;
  // The centreline file, relative to the scene file.
  spec.source = scene_relative(r, r.require(m, "mesh", "centreline"), "mesh.centreline", dir);
  spec.centreline = read_centreline(spec.source, unit);
  read_range(r, m, unit, spec);
  scene.radius_surface = read_radius(r, r.require(m, "mesh", "radius"), unit, dir, spec);
  spec.wall_thickness = unit * r.positive(r.require(m, "mesh", "wall_thickness"), "mesh.wall_thickness");
  spec.segments_around = r.integer_in(r.require(m, "mesh", "segments_around"), "mesh.segments_around", 3, 4096);
  spec.segment_length = unit * r.positive(r.require(m, "mesh", "segment_length"), "mesh.segment_length");
  spec.layers = r.integer_in(r.require(m, "mesh", "layers"), "mesh.layers", 1, 256);
  if (m.contains("haustra")) {
    const json& h = m.at("haustra");
    r.only_keys(h, "mesh.haustra", {"depth", "pitch"});
    spec.haustra.depth = unit * r.positive(r.require(h, "mesh.haustra", "depth"), "mesh.haustra.depth");
    spec.haustra.pitch = unit * r.positive(r.require(h, "mesh.haustra", "pitch"), "mesh.haustra.pitch");
  }
  check_swept_tube(r, m, spec);
  // The radius sampled from the organ's surface at the rings (now that the range and ring spacing are known).
  if (scene.radius_surface.empty()) return;
  const auto t0 = Clock::now();
  spec.radius_profile = sample_lumen_radius(spec, read_closed_surface(scene.radius_surface, unit), scene.radius_surface);
  scene.mesh_load_ms = ms_since(t0);
}

// A wall grown from a closed surface file (mesh.type "surface_wall"), relative to the scene file, grown at load.
void read_surface_wall(const Reader& r, const json& m, const std::filesystem::path& dir, Scene& scene) {
  r.only_keys(m, "mesh", {"type", "element", "surface", "units", "thickness", "direction", "layers", "target_edge"});
  SurfaceWallSpec& spec = scene.surface_wall.spec;
  spec.metres_per_unit = read_metres_per_unit(r, m);
  spec.file = scene_relative(r, r.require(m, "mesh", "surface"), "mesh.surface", dir);
  spec.thickness = spec.metres_per_unit * r.positive(r.require(m, "mesh", "thickness"), "mesh.thickness");
  spec.direction = r.choice<WallDirection>(r.require(m, "mesh", "direction"), "mesh.direction", kWallDirectionNames);
  if (m.contains("layers")) spec.layers = r.integer_in(m.at("layers"), "mesh.layers", 1, 256);
  if (m.contains("target_edge"))
    spec.target_edge = spec.metres_per_unit * r.positive(m.at("target_edge"), "mesh.target_edge");
  const auto t0 = Clock::now();
  scene.surface_wall.wall = grow_surface_wall(spec);
  scene.mesh_load_ms = ms_since(t0);
}

// The wall between two closed surface files (mesh.type "surface_pair"), relative to the scene file, tetrahedralised
// at load.
void read_surface_pair(const Reader& r, const json& m, const std::filesystem::path& dir, Scene& scene) {
  r.only_keys(m, "mesh",
              {"type", "element", "inner", "outer", "units", "mesher", "max_edge", "optimise_steps", "target_edge"});
  SurfacePairSpec& spec = scene.surface_pair.spec;
  spec.metres_per_unit = read_metres_per_unit(r, m);
  spec.inner_file = scene_relative(r, r.require(m, "mesh", "inner"), "mesh.inner", dir);
  spec.outer_file = scene_relative(r, r.require(m, "mesh", "outer"), "mesh.outer", dir);
  if (m.contains("mesher"))
    spec.options.mesher = r.choice<physics::PairMesher>(m.at("mesher"), "mesh.mesher", kPairMesherNames);
  if (m.contains("max_edge"))
    spec.options.max_edge = spec.metres_per_unit * r.positive(m.at("max_edge"), "mesh.max_edge");
  if (m.contains("target_edge"))
    spec.target_edge = spec.metres_per_unit * r.positive(m.at("target_edge"), "mesh.target_edge");
  if (m.contains("max_edge") && spec.options.mesher == physics::PairMesher::kGmsh)
    r.fail("mesh.max_edge", physics::kGmshMaxEdgeRefused, &m.at("max_edge"));
  if (m.contains("optimise_steps"))
    spec.options.optimise_steps =
        r.integer_in(m.at("optimise_steps"), "mesh.optimise_steps", 0, physics::kPairMesherMaxOptimiseSteps);
  const auto t0 = Clock::now();
  scene.surface_pair.pair = mesh_surface_pair(spec);
  scene.mesh_load_ms = ms_since(t0);
}

// mesh.inner_tag / outer_tag of a volume mesh: a tag number, or (gmsh) a physical surface's name.
int read_wall_tag(const Reader& r, const json& v, const std::string& path, const physics::VolumeMeshFile& f) {
  if (v.is_number_integer()) return r.integer_in(v, path, INT_MIN + 1, INT_MAX);
  const std::string name = r.string(v, path);
  std::string names;
  for (const physics::TagName& t : f.tag_names) {
    if (t.name == name) return t.tag;
    names += (names.empty() ? "" : ", ") + ("\"" + t.name + "\"");
  }
  r.fail(path, "no physical surface of that name in " + f.file + " (it has: " + (names.empty() ? "none" : names) + ")",
         &v);
}

// A volume mesh file (mesh.type "volume"), relative to the scene file: read, its walls found and built at load.
void read_volume(const Reader& r, const json& m, const std::filesystem::path& dir, Scene& scene) {
  VolumeSourceSpec& spec = scene.volume;
  r.only_keys(m, "mesh", {"type", "element", "file", "units", "inner_tag", "outer_tag"});
  const auto t0 = Clock::now();
  const double unit = read_metres_per_unit(r, m);
  spec.file = scene_relative(r, r.require(m, "mesh", "file"), "mesh.file", dir);
  if (m.contains("inner_tag") != m.contains("outer_tag"))
    r.fail(m.contains("inner_tag") ? "mesh.inner_tag" : "mesh.outer_tag",
           "give both mesh.inner_tag and mesh.outer_tag, or neither (the walls are then found on the boundary)", nullptr);
  try {
    const physics::VolumeMeshFile f = physics::read_volume_mesh_file(spec.file);
    if (m.contains("inner_tag")) {
      spec.tags = {true, read_wall_tag(r, m.at("inner_tag"), "mesh.inner_tag", f),
                   read_wall_tag(r, m.at("outer_tag"), "mesh.outer_tag", f)};
      if (spec.tags.inner == spec.tags.outer)
        r.fail("mesh.outer_tag", "must differ from mesh.inner_tag", &m.at("outer_tag"));
    }
    spec.mesh = physics::make_volume_mesh(f, unit, spec.tags);
  } catch (const std::invalid_argument& e) {
    throw InputError(e.what());
  }
  scene.mesh_load_ms = ms_since(t0);
}

void read_mesh(const Reader& r, const json& m, const std::filesystem::path& dir, Scene& s) {
  if (!m.is_object()) r.fail("mesh", "must be an object", &m);
  s.mesh_type = r.choice<MeshType>(r.require(m, "mesh", "type"), "mesh.type", kMeshTypeNames);
  if (m.contains("element")) s.element = r.choice<ElementType>(m.at("element"), "mesh.element", kElementNames);
  if (s.mesh_type == MeshType::kSweptTube)
    read_swept_tube(r, m, dir, s);
  else if (s.mesh_type == MeshType::kVolume)
    read_volume(r, m, dir, s);
  else if (s.mesh_type == MeshType::kSurfaceWall)
    read_surface_wall(r, m, dir, s);
  else if (s.mesh_type == MeshType::kSurfacePair)
    read_surface_pair(r, m, dir, s);
  else
    read_hollow_cylinder(r, m, s.mesh);
}

// A swept tube's arc length given in a key (mesh.units): within [lo, hi] (metres, the centreline's or the range's),
// refused naming the key, the interval (in mesh.units) and what it is of; metres.
double arc_length_within(const Reader& r, const json& v, const std::string& path, const Scene& s, double lo, double hi,
                         const char* of) {
  const double unit = s.swept_tube_unit;
  const double x = unit * r.number(v, path);
  // A value within kRangeEndTolerance of an end past it is that end (decimal rounding of the file's units).
  const double slack = kRangeEndTolerance * hi;
  if (!(x >= lo - slack && x <= hi + slack)) {
    std::ostringstream within;
    within << "must lie within " << of << " [" << lo / unit << ", " << hi / unit << "]";
    r.fail(path, within.str(), &v);
  }
  return std::clamp(x, lo, hi);
}

// {"near_centreline": [s0, s1]} of "fixed" (a swept tube only): an arc-length interval in mesh.units along the whole
// centreline file, s0 < s1, within its arc length.
FixedSpec read_near_centreline(const Reader& r, const json& v, const std::string& path, const Scene& s) {
  if (s.mesh_type != MeshType::kSweptTube)
    r.fail(path, std::string("needs mesh.type \"swept_tube\" (got \"") + name_of(s.mesh_type) + "\")", &v);
  if (!v.is_array() || v.size() != 2) r.fail(path, "must be [s0, s1] (arc lengths along the centreline)", &v);
  const double length = physics::arc_lengths(s.swept_tube.centreline.points).back();
  const std::string of = "the centreline's arc length of " + s.swept_tube.source;
  FixedSpec f;
  f.kind = FixedKind::kNearCentreline;
  f.s0 = arc_length_within(r, v[0], Reader::index(path, 0), s, 0.0, length, of.c_str());
  f.s1 = arc_length_within(r, v[1], Reader::index(path, 1), s, 0.0, length, of.c_str());
  if (!(f.s0 < f.s1)) r.fail(path, "must be [s0, s1] with s0 < s1", &v);
  return f;
}

// One entry of "fixed": a node-set name, {"box": [low, high]}, {"plane": {"point", "normal"}} or (a swept tube)
// {"near_centreline": [s0, s1]}.
FixedSpec read_fixed_entry(const Reader& r, const json& v, const std::string& path, const Scene& s) {
  if (v.is_string()) return r.choice<NodeSetName>(v, path, kNodeSetNames);
  if (!v.is_object() || v.size() != 1 || !(v.contains("box") || v.contains("plane") || v.contains("near_centreline")))
    r.fail(path, "must be a node-set name (ends, start, stop), {\"box\": [[x0, y0, z0], [x1, y1, z1]]}, "
                 "{\"plane\": {\"point\": [x, y, z], \"normal\": [x, y, z]}} or {\"near_centreline\": [s0, s1]}", &v);
  if (v.contains("near_centreline"))
    return read_near_centreline(r, v.at("near_centreline"), Reader::join(path, "near_centreline"), s);
  FixedSpec f;
  if (v.contains("box")) {
    const json& box = v.at("box");
    const std::string at = Reader::join(path, "box");
    if (!box.is_array() || box.size() != 2) r.fail(at, "must be [[x0, y0, z0], [x1, y1, z1]]", &box);
    f.kind = FixedKind::kBox;
    f.a = r.vec3(box[0], Reader::index(at, 0));
    f.b = r.vec3(box[1], Reader::index(at, 1));
    if (!(f.a.array() <= f.b.array()).all()) r.fail(at, "the first corner must be the low one (x0 <= x1, y0 <= y1, z0 <= z1)", &box);
    return f;
  }
  const json& plane = v.at("plane");
  const std::string at = Reader::join(path, "plane");
  r.only_keys(plane, at, {"point", "normal"});
  f.kind = FixedKind::kPlane;
  f.a = r.vec3(r.require(plane, at, "point"), Reader::join(at, "point"));
  f.b = r.vec3(r.require(plane, at, "normal"), Reader::join(at, "normal"));
  if (!(f.b.norm() > 0.0)) r.fail(Reader::join(at, "normal"), "must not be zero", &plane.at("normal"));
  f.b.normalize();
  return f;
}

// An entry of "fixed" (or of support.where) with the entry as the scene gives it, for the messages that name it.
FixedSpec read_fixed(const Reader& r, const json& v, const std::string& path, const Scene& s) {
  FixedSpec f = read_fixed_entry(r, v, path, s);
  f.given = v.dump();
  return f;
}

void read_material(const Reader& r, const json& m, MaterialSpec& mat) {
  r.only_keys(m, "material", {"model", "young_modulus", "poisson_ratio", "density"});
  mat.model = r.choice<MaterialModel>(r.require(m, "material", "model"), "material.model", kMaterialModelNames);
  mat.young_modulus = r.positive(r.require(m, "material", "young_modulus"), "material.young_modulus");
  mat.poisson_ratio = r.number_in(r.require(m, "material", "poisson_ratio"), "material.poisson_ratio", -1.0, 0.5,
                                  true, true);
  if (m.contains("density")) mat.density = r.positive(m.at("density"), "material.density");
}

ProbeSpec read_probe(const Reader& r, const json& p, const std::string& path, size_t i,
                     const std::filesystem::path& scene_dir) {
  r.only_keys(p, path, {"name", "point", "track", "replay"});
  ProbeSpec probe;
  probe.name = p.contains("name") ? r.string(p.at("name"), Reader::join(path, "name")) : "probe" + std::to_string(i);
  probe.point = r.vec3(r.require(p, path, "point"), Reader::join(path, "point"));
  bool has_track = p.contains("track"), has_replay = p.contains("replay");
  if (has_track == has_replay) r.fail(path, "needs exactly one of \"track\" or \"replay\"", nullptr);
  if (has_replay) {
    std::filesystem::path f = r.string(p.at("replay"), Reader::join(path, "replay"));
    if (f.is_relative()) f = scene_dir / f;
    probe.replay = f.lexically_normal().string();
    return probe;
  }
  // Scripted key frames: times strictly increasing, forces finite.
  const std::string tpath = Reader::join(path, "track");
  const json& track = p.at("track");
  if (!track.is_array()) r.fail(tpath, "must be an array of {\"t\", \"force\" | \"displacement\"} keys", &track);
  if (track.empty()) r.fail(tpath, "must not be empty", &track);
  // The first key decides whether the probe is force- or displacement-driven; every key must agree.
  const bool by_displacement = track[0].is_object() && track[0].contains("displacement");
  probe.drive = by_displacement ? ProbeDrive::Displacement : ProbeDrive::Force;
  const char* value_key = by_displacement ? "displacement" : "force";
  for (size_t k = 0; k < track.size(); ++k) {
    const std::string kpath = Reader::index(tpath, k);
    r.only_keys(track[k], kpath, {"t", value_key});
    TrackKey key;
    key.t = r.number(r.require(track[k], kpath, "t"), kpath + ".t");
    if (key.t < 0) r.fail(kpath + ".t", "must be >= 0", &track[k].at("t"));
    key.value = r.vec3(r.require(track[k], kpath, value_key), kpath + "." + value_key);
    if (by_displacement && key.value.norm() > 0.5)
      r.fail(kpath + ".displacement", "must be at most 0.5 m long", &track[k].at("displacement"));
    if (!probe.track.empty() && !(key.t > probe.track.back().t))
      r.fail(kpath + ".t", "track times must be strictly increasing", &track[k].at("t"));
    probe.track.push_back(key);
  }
  return probe;
}

// render.camera {"centreline": {"from": s0, "to": s1}} (a swept tube only): the flight's arc lengths in mesh.units,
// both within mesh.range (where the lumen is), s0 != s1.
void read_centreline_flight(const Reader& r, const json& c, const Scene& s, RenderSpec& spec) {
  const std::string path = "render.camera.centreline";
  if (s.mesh_type != MeshType::kSweptTube)
    r.fail(path, std::string("needs mesh.type \"swept_tube\" (got \"") + name_of(s.mesh_type) + "\")", &c);
  if (!c.is_object()) r.fail(path, "must be an object {\"from\", \"to\"}", &c);
  r.only_keys(c, path, {"from", "to"});
  const physics::SweptTubeSpec& tube = s.swept_tube;
  spec.centreline_flight = true;
  spec.flight_from = arc_length_within(r, r.require(c, path, "from"), Reader::join(path, "from"), s, tube.range_start,
                                       tube.range_stop, "mesh.range");
  spec.flight_to = arc_length_within(r, r.require(c, path, "to"), Reader::join(path, "to"), s, tube.range_start,
                                     tube.range_stop, "mesh.range");
  if (spec.flight_to == spec.flight_from)
    r.fail(Reader::join(path, "to"), "must differ from render.camera.centreline.from", &c.at("to"));
}

void read_render(const Reader& r, const json& m, const Scene& s, RenderSpec& spec) {
  r.only_keys(m, "render", {"width", "height", "camera", "video", "force_scale"});
  if (m.contains("width")) spec.width = r.integer_in(m.at("width"), "render.width", 16, 8192);
  if (m.contains("height")) spec.height = r.integer_in(m.at("height"), "render.height", 16, 8192);
  if (spec.width % 2) r.fail("render.width", "must be even (video encoding)", &m.at("width"));
  if (spec.height % 2) r.fail("render.height", "must be even (video encoding)", &m.at("height"));
  // A preset by name, {"endoscope": NAME}: the endoscope on an instrument (the name is checked with them), or
  // {"centreline": {"from", "to"}}: the endoscope flying along a swept tube's centreline.
  if (m.contains("camera") && m.at("camera").is_object()) {
    const json& c = m.at("camera");
    r.only_keys(c, "render.camera", {"endoscope", "centreline"});
    if (c.size() != 1) r.fail("render.camera", "needs exactly one of \"endoscope\" or \"centreline\"", &c);
    spec.camera = render::CameraPreset::Endoscope;
    if (c.contains("centreline"))
      read_centreline_flight(r, c.at("centreline"), s, spec);
    else
      spec.scope_instrument = r.string(c.at("endoscope"), "render.camera.endoscope");
  } else if (m.contains("camera")) {
    spec.camera = r.choice<render::CameraPreset>(m.at("camera"), "render.camera", kCameraNames);
  }
  if (m.contains("video")) spec.video = r.boolean(m.at("video"), "render.video");
  if (m.contains("force_scale")) spec.force_scale = r.positive(m.at("force_scale"), "render.force_scale");
}

void read_collision(const Reader& r, const json& m, CollisionSpec& spec) {
  r.only_keys(m, "collision", {"self", "kdop", "response", "gap", "max_iterations", "max_contact_rows", "surfaces", "lcp", "lcp_sweeps",
                               "coupling", "recheck", "detection", "equilibrium_steps",
                               "equilibrium_hessian", "prediction_back_substitutions"});
  if (m.contains("surfaces")) {
    const json& list = m.at("surfaces");
    if (!list.is_array() || list.empty()) r.fail("collision.surfaces", "must be a non-empty array of wall names", &list);
    bool inner = false;
    for (size_t i = 0; i < list.size(); ++i) {
      const std::string wall = r.one_of(list[i], Reader::index("collision.surfaces", i), {"inner", "outer"});
      inner = inner || wall == "inner";
      spec.outer_wall = spec.outer_wall || wall == "outer";
    }
    if (!inner) r.fail("collision.surfaces", "must include \"inner\" (the lumen's walls always collide)", &list);
  }
  if (m.contains("self")) spec.self = r.boolean(m.at("self"), "collision.self");
  if (m.contains("kdop")) {
    spec.kdop = r.integer_in(m.at("kdop"), "collision.kdop", 6, 26);
    if (spec.kdop != 6 && spec.kdop != 14 && spec.kdop != 18 && spec.kdop != 26)
      r.fail("collision.kdop", "must be one of 6, 14, 18, 26", &m.at("kdop"));
  }
  if (m.contains("response")) spec.response = r.choice<ResponseKind>(m.at("response"), "collision.response", kResponseNames);
  if (m.contains("lcp")) spec.lcp = r.choice<LcpSolver>(m.at("lcp"), "collision.lcp", kLcpSolverNames);
  if (m.contains("recheck")) spec.recheck = r.choice<Recheck>(m.at("recheck"), "collision.recheck", kRecheckNames);
  if (m.contains("detection"))
    spec.detection = r.choice<Detection>(m.at("detection"), "collision.detection", kDetectionNames);
  if (m.contains("gap")) spec.gap = r.number_in(m.at("gap"), "collision.gap", 0.0, 0.01, false, false);
  if (m.contains("max_iterations"))
    spec.max_iterations = r.integer_in(m.at("max_iterations"), "collision.max_iterations", 1, 100);
  if (m.contains("max_contact_rows"))
    spec.max_contact_rows = r.integer_in(m.at("max_contact_rows"), "collision.max_contact_rows", 1, 1000000);
  if (m.contains("coupling"))
    spec.coupling = r.choice<ContactCoupling>(m.at("coupling"), "collision.coupling", kCouplingNames);
  if (m.contains("lcp_sweeps")) spec.lcp_sweeps = r.integer_in(m.at("lcp_sweeps"), "collision.lcp_sweeps", 2, 100000);
  if (m.contains("equilibrium_steps"))
    spec.equilibrium_steps = r.integer_in(m.at("equilibrium_steps"), "collision.equilibrium_steps", 1, 1000);
  if (m.contains("equilibrium_hessian"))
    spec.equilibrium_hessian =
        r.choice<EquilibriumHessian>(m.at("equilibrium_hessian"), "collision.equilibrium_hessian", kEquilibriumHessianNames);
  if (m.contains("prediction_back_substitutions")) {
    spec.prediction_back_substitutions =
        r.integer_in(m.at("prediction_back_substitutions"), "collision.prediction_back_substitutions", 0, 1000000);
    if (spec.prediction_back_substitutions == 1)
      r.fail("collision.prediction_back_substitutions",
             "must be 0 (solver.max_back_substitutions) or >= 2 (a PCG step takes two)",
             &m.at("prediction_back_substitutions"));
  }
}

void read_solver(const Reader& r, const json& m, SolverSpec& spec) {
  r.only_keys(m, "solver", {"type", "tolerance", "max_iterations", "rayleigh_mass", "rayleigh_stiffness",
                            "background_factorisation", "anderson_depth", "tangent", "method",
                            "max_back_substitutions"});
  if (m.contains("tangent")) spec.tangent = r.choice<Tangent>(m.at("tangent"), "solver.tangent", kTangentNames);
  if (m.contains("method")) spec.method = r.choice<SolveMethod>(m.at("method"), "solver.method", kMethodNames);
  if (m.contains("max_back_substitutions")) {
    spec.max_back_substitutions =
        r.integer_in(m.at("max_back_substitutions"), "solver.max_back_substitutions", 0, 1000000);
    if (spec.max_back_substitutions == 1)
      r.fail("solver.max_back_substitutions", "must be 0 (no bound) or >= 2 (a PCG step takes two)",
             &m.at("max_back_substitutions"));
  }
  if (m.contains("anderson_depth"))
    spec.anderson_depth = r.integer_in(m.at("anderson_depth"), "solver.anderson_depth", 0, 20);
  if (m.contains("background_factorisation"))
    spec.background_factorisation = r.boolean(m.at("background_factorisation"), "solver.background_factorisation");
  if (m.contains("type")) spec.type = r.choice<SolverType>(m.at("type"), "solver.type", kSolverNames);
  if (m.contains("tolerance"))
    spec.tolerance = r.number_in(m.at("tolerance"), "solver.tolerance", 0.0, 1.0, true, true);
  if (m.contains("max_iterations"))
    spec.max_iterations = r.integer_in(m.at("max_iterations"), "solver.max_iterations", 1, 10000);
  // Rayleigh damping: only a dynamic solve has velocities to damp (refused otherwise, as a likely mistake).
  auto damping = [&](const char* key, double& out) {
    if (!m.contains(key)) return;
    const std::string path = std::string("solver.") + key;
    if (spec.type != SolverType::kDynamic) r.fail(path, "needs solver.type \"dynamic\"", &m.at(key));
    out = r.number(m.at(key), path);
    if (!(out >= 0.0)) r.fail(path, "must be >= 0", &m.at(key));
  };
  damping("rayleigh_mass", spec.rayleigh_mass);
  damping("rayleigh_stiffness", spec.rayleigh_stiffness);
}

void read_twist(const Reader& r, const json& m, TwistSpec& spec) {
  r.only_keys(m, "twist", {"end", "track"});
  spec.end = r.choice<TwistEnd>(r.require(m, "twist", "end"), "twist.end", kTwistEndNames, 1);
  // Key frames of the angle: times >= 0 and strictly increasing, angles within two turns either way.
  const json& track = r.require(m, "twist", "track");
  if (!track.is_array()) r.fail("twist.track", "must be an array of {\"t\", \"degrees\"} keys", &track);
  if (track.empty()) r.fail("twist.track", "must not be empty", &track);
  for (size_t k = 0; k < track.size(); ++k) {
    const std::string kpath = Reader::index("twist.track", k);
    r.only_keys(track[k], kpath, {"t", "degrees"});
    TwistKey key;
    key.t = r.number(r.require(track[k], kpath, "t"), kpath + ".t");
    if (key.t < 0) r.fail(kpath + ".t", "must be >= 0", &track[k].at("t"));
    if (!spec.track.empty() && !(key.t > spec.track.back().t))
      r.fail(kpath + ".t", "track times must be strictly increasing", &track[k].at("t"));
    key.degrees = r.number_in(r.require(track[k], kpath, "degrees"), kpath + ".degrees", -720.0, 720.0, false, false);
    spec.track.push_back(key);
  }
}

// A built-in shape's optional dimension or resolution: type-checked here; its range is make_instrument's check.
void read_dimension(const Reader& r, const json& m, const std::string& path, const char* key, double& out) {
  if (m.contains(key)) out = r.number(m.at(key), Reader::join(path, key));
}
void read_resolution(const Reader& r, const json& m, const std::string& path, const char* key, int& out) {
  if (m.contains(key))
    out = r.integer_in(m.at(key), Reader::join(path, key), std::numeric_limits<int>::min(),
                       std::numeric_limits<int>::max());
}
// The resolutions of a round shape (the sphere-tipped probe's, the rod's).
void read_round_resolutions(const Reader& r, const json& m, const std::string& path, int& segments_around, int& rings,
                            int& shaft_segments) {
  read_resolution(r, m, path, "segments_around", segments_around);
  read_resolution(r, m, path, "rings", rings);
  read_resolution(r, m, path, "shaft_segments", shaft_segments);
}
// The same for a dimension the shape needs.
double required_dimension(const Reader& r, const json& m, const std::string& path, const char* key) {
  return r.number(r.require(m, path, key), Reader::join(path, key));
}

// An instrument's shape: its type's keys only, then built once (make_instrument) so that every range, and a mesh
// file's closedness, is refused here with the scene file and key path.
ShapeSpec read_shape(const Reader& r, const json& m, const std::string& path, const std::filesystem::path& dir) {
  if (!m.is_object()) r.fail(path, "must be an object", &m);
  const std::string type =
      r.one_of(r.require(m, path, "type"), Reader::join(path, "type"), {"sphere_probe", "rod", "grasper", "mesh"});
  ShapeSpec shape;
  if (type == "sphere_probe") {
    r.only_keys(m, path, {"type", "tip_radius", "shaft_radius", "shaft_length", "segments_around", "rings",
                          "shaft_segments"});
    SphereProbeSpec s;
    s.tip_radius = required_dimension(r, m, path, "tip_radius");
    s.shaft_radius = required_dimension(r, m, path, "shaft_radius");
    s.shaft_length = required_dimension(r, m, path, "shaft_length");
    read_round_resolutions(r, m, path, s.segments_around, s.rings, s.shaft_segments);
    shape = s;
  } else if (type == "rod") {
    r.only_keys(m, path, {"type", "radius", "length", "end", "segments_around", "rings", "shaft_segments"});
    RodSpec s;
    s.radius = required_dimension(r, m, path, "radius");
    s.length = required_dimension(r, m, path, "length");
    if (m.contains("end")) s.end = r.choice<RodEnd>(m.at("end"), Reader::join(path, "end"), kRodEndNames);
    read_round_resolutions(r, m, path, s.segments_around, s.rings, s.shaft_segments);
    shape = s;
  } else if (type == "grasper") {
    r.only_keys(m, path, {"type", "jaw_length", "jaw_width", "jaw_thickness", "opening_angle", "shaft_radius",
                          "shaft_length", "segments_around", "shaft_segments"});
    GrasperSpec s;
    s.jaw_length = required_dimension(r, m, path, "jaw_length");
    s.jaw_width = required_dimension(r, m, path, "jaw_width");
    s.jaw_thickness = required_dimension(r, m, path, "jaw_thickness");
    s.shaft_radius = required_dimension(r, m, path, "shaft_radius");
    s.shaft_length = required_dimension(r, m, path, "shaft_length");
    read_dimension(r, m, path, "opening_angle", s.opening_angle);
    read_resolution(r, m, path, "segments_around", s.segments_around);
    read_resolution(r, m, path, "shaft_segments", s.shaft_segments);
    shape = s;
  } else {
    r.only_keys(m, path, {"type", "file", "units"});
    MeshFileSpec s;
    std::filesystem::path f = r.string(r.require(m, path, "file"), Reader::join(path, "file"));
    if (f.is_relative()) f = dir / f;
    s.file = f.lexically_normal().string();
    if (m.contains("units")) s.units = r.choice<MeshUnits>(m.at("units"), Reader::join(path, "units"), kLengthUnitNames);
    // The mesh file's own message (it names the file and the triangle or edge) under the scene's key.
    try {
      make_instrument(s, r.where(path));
    } catch (const InputError& e) {
      r.fail(Reader::join(path, "file"), e.what(), &m.at("file"));
    }
    return s;
  }
  make_instrument(shape, r.where(path));
  return shape;
}

// A pose key's rotation: a unit quaternion [w, x, y, z] or {"axis": [x, y, z], "angle": radians}.
Eigen::Quaterniond read_rotation(const Reader& r, const json& v, const std::string& path) {
  if (v.is_object()) {
    r.only_keys(v, path, {"axis", "angle"});
    const Eigen::Vector3d axis = r.vec3(r.require(v, path, "axis"), Reader::join(path, "axis"));
    const double angle = r.number(r.require(v, path, "angle"), Reader::join(path, "angle"));
    return axis_angle_rotation(axis, angle, r.where(path));
  }
  if (!v.is_array() || v.size() != kQuaternionEntries)
    r.fail(path, "must be a quaternion [w, x, y, z] or {\"axis\", \"angle\"}", &v);
  double q[kQuaternionEntries];
  for (size_t i = 0; i < kQuaternionEntries; ++i) q[i] = r.number(v[i], Reader::index(path, i));
  return Eigen::Quaterniond(q[0], q[1], q[2], q[3]);  // unit norm: checked by PoseTrack
}

// Key frames {t, position, rotation[, opening]}: times >= 0, then PoseTrack's checks (increasing, unit rotations);
// a grasper's keys may give its jaws' opening (radians), collected into `openings`.
std::vector<PoseKey> read_pose_track(const Reader& r, const json& track, const std::string& path, bool grasper,
                                     std::vector<OpeningKey>& openings) {
  if (!track.is_array()) r.fail(path, "must be an array of {\"t\", \"position\", \"rotation\"} keys", &track);
  if (track.empty()) r.fail(path, "must not be empty", &track);
  std::vector<PoseKey> keys;
  for (size_t k = 0; k < track.size(); ++k) {
    const std::string kpath = Reader::index(path, k);
    if (grasper)
      r.only_keys(track[k], kpath, {"t", "position", "rotation", "opening"});
    else
      r.only_keys(track[k], kpath, {"t", "position", "rotation"});
    PoseKey key;
    key.t = r.number(r.require(track[k], kpath, "t"), kpath + ".t");
    if (key.t < 0) r.fail(kpath + ".t", "must be >= 0", &track[k].at("t"));
    key.pose.position = r.vec3(r.require(track[k], kpath, "position"), kpath + ".position");
    if (track[k].contains("rotation")) key.pose.rotation = read_rotation(r, track[k].at("rotation"), kpath + ".rotation");
    if (track[k].contains("opening"))
      openings.push_back({key.t, r.number_in(track[k].at("opening"), kpath + ".opening", 0.0, kMaxOpeningAngle, false, false)});
    keys.push_back(key);
  }
  return PoseTrack(std::move(keys), r.where(path)).keys();
}

// A grasper's "grasp": {grip_force_n (> 0), release_margin (radians, in (0, kMaxOpeningAngle])}, both optional.
GraspSpec read_grasp(const Reader& r, const json& g, const std::string& path) {
  if (!g.is_object()) r.fail(path, "must be an object {\"grip_force_n\", \"release_margin\"}", &g);
  r.only_keys(g, path, {"grip_force_n", "release_margin"});
  GraspSpec spec;
  spec.enabled = true;
  if (g.contains("grip_force_n")) spec.grip_force_n = r.positive(g.at("grip_force_n"), Reader::join(path, "grip_force_n"));
  if (g.contains("release_margin"))
    spec.release_margin = r.number_in(g.at("release_margin"), Reader::join(path, "release_margin"), 0.0,
                                      kMaxOpeningAngle, true, false);
  return spec;
}

// One instrument: name, shape, exactly one of track or replay (or a device_name alone), optional to_organ.
InstrumentSpec read_instrument(const Reader& r, const json& p, const std::string& path, size_t i,
                               const std::filesystem::path& dir) {
  r.only_keys(p, path, {"name", "shape", "track", "replay", "device_name", "to_organ", "grasp"});
  InstrumentSpec spec;
  spec.name = p.contains("name") ? r.string(p.at("name"), Reader::join(path, "name")) : "instrument" + std::to_string(i);
  if (spec.name.empty()) r.fail(Reader::join(path, "name"), "must not be empty", &p.at("name"));
  spec.shape = read_shape(r, r.require(p, path, "shape"), Reader::join(path, "shape"), dir);
  if (p.contains("device_name")) {
    spec.device_name = r.string(p.at("device_name"), Reader::join(path, "device_name"));
    if (spec.device_name.empty()) r.fail(Reader::join(path, "device_name"), "must not be empty", &p.at("device_name"));
  }
  const bool has_track = p.contains("track"), has_replay = p.contains("replay");
  if (has_track && has_replay) r.fail(path, "needs at most one of \"track\" or \"replay\"", nullptr);
  if (!has_track && !has_replay && spec.device_name.empty())
    r.fail(path, "needs one of \"track\", \"replay\" or \"device_name\"", nullptr);
  const bool grasper = std::holds_alternative<GrasperSpec>(spec.shape);
  if (p.contains("grasp") && !grasper)
    r.fail(Reader::join(path, "grasp"), "needs shape.type \"grasper\"", &p.at("grasp"));
  if (p.contains("grasp")) spec.grasp = read_grasp(r, p.at("grasp"), Reader::join(path, "grasp"));
  if (has_track) {
    spec.poses = read_pose_track(r, p.at("track"), Reader::join(path, "track"), grasper, spec.openings);
  } else if (has_replay) {
    spec.drive = InstrumentDrive::kReplay;
    std::filesystem::path f = r.string(p.at("replay"), Reader::join(path, "replay"));
    if (f.is_relative()) f = dir / f;
    spec.replay = f.lexically_normal().string();
    require_file(spec.replay, "pose replay file");
    spec.poses = read_pose_csv(spec.replay).keys();
  } else {
    spec.drive = InstrumentDrive::kDevice;
  }
  if (p.contains("to_organ")) {
    const std::string mpath = Reader::join(path, "to_organ");
    const json& v = p.at("to_organ");
    if (!v.is_array() || v.size() != kMatrixEntries) r.fail(mpath, "must be an array of 16 numbers (row-major 4 x 4)", &v);
    std::array<double, kMatrixEntries> rows{};
    for (size_t k = 0; k < kMatrixEntries; ++k) rows[k] = r.number(v[k], Reader::index(mpath, k));
    spec.to_organ = rigid_to_organ(rows, r.where(mpath));
  }
  return spec;
}

// The haptic loop's rate and limits: every value finite and positive (the damping may be 0).
void read_haptics(const Reader& r, const json& h, HapticsSpec& spec) {
  r.only_keys(h, "haptics", {"rate_hz", "max_force_n", "max_stiffness_n_per_m", "damping_n_s_per_m", "stale_after_s",
                             "fade_s"});
  if (h.contains("rate_hz"))
    spec.rate_hz = r.number_in(h.at("rate_hz"), "haptics.rate_hz", 0.0, kMaxHapticRateHz, true, false);
  if (h.contains("max_force_n")) spec.max_force_n = r.positive(h.at("max_force_n"), "haptics.max_force_n");
  if (h.contains("max_stiffness_n_per_m"))
    spec.max_stiffness_n_per_m = r.positive(h.at("max_stiffness_n_per_m"), "haptics.max_stiffness_n_per_m");
  if (h.contains("damping_n_s_per_m")) {
    spec.damping_n_s_per_m = r.number(h.at("damping_n_s_per_m"), "haptics.damping_n_s_per_m");
    if (spec.damping_n_s_per_m < 0.0) r.fail("haptics.damping_n_s_per_m", "must be >= 0", &h.at("damping_n_s_per_m"));
  }
  if (h.contains("stale_after_s")) spec.stale_after_s = r.positive(h.at("stale_after_s"), "haptics.stale_after_s");
  if (h.contains("fade_s")) spec.fade_s = r.positive(h.at("fade_s"), "haptics.fade_s");
}

void read_instruments(const Reader& r, const json& list, const std::filesystem::path& dir, Scene& s) {
  if (!list.is_array()) r.fail("instruments", "must be an array", &list);
  std::set<std::string> names;
  for (size_t i = 0; i < list.size(); ++i) {
    const std::string path = Reader::index("instruments", i);
    s.instruments.push_back(read_instrument(r, list[i], path, i, dir));
    if (!names.insert(s.instruments.back().name).second)
      r.fail(Reader::join(path, "name"), "must be unique among the instruments", &list[i].at("name"));
  }
}

// Checks across keys: what the compiled model cannot combine is refused here, naming the first key involved.
void check_combinations(const Reader& r, const json& root, const Scene& s) {
  // The node selections that may name end sets: "fixed" and the supports' "where" (key, entries, their JSON).
  const json none = json::array();
  const std::array<std::tuple<std::string, const std::vector<FixedSpec>*, const json*>, 2> selections{{
      {"fixed", &s.fixed, root.contains("fixed") ? &root.at("fixed") : &none},
      {"support.where", &s.support.where,
       root.contains("support") && root.at("support").contains("where") ? &root.at("support").at("where") : &none}}};
  // A volume mesh has no generated centreline: no twist; its end sets exist when its end caps are two pieces.
  if (s.mesh_type == MeshType::kVolume) {
    if (s.twist.enabled() && !s.volume.mesh.has_node_set(physics::kStartEnd))
      r.fail("twist", "the volume mesh " + s.volume.file + " has no end node sets (its end caps are not two separate "
             "pieces), so it has no end to turn", nullptr);
    for (const auto& [key, list, at] : selections)
      for (size_t i = 0; i < list->size(); ++i)
        if ((*list)[i].kind == FixedKind::kNamed && !s.volume.mesh.has_node_set(physics::kStartEnd))
          r.fail(Reader::index(key, i), "the volume mesh " + s.volume.file + " has no end node sets (its end caps "
                 "are not two separate pieces): hold nodes by {\"box\": ...} or {\"plane\": ...}", &(*at)[i]);
  }
  // A wall grown from a closed surface, or between two, has no ends: no twist, no end sets.
  if (s.mesh_type == MeshType::kSurfaceWall || s.mesh_type == MeshType::kSurfacePair) {
    const std::string from = s.mesh_type == MeshType::kSurfaceWall
                                 ? "the wall grown from " + s.surface_wall.spec.file
                                 : "the wall between " + s.surface_pair.spec.inner_file + " and " +
                                       s.surface_pair.spec.outer_file;
    if (s.twist.enabled())
      r.fail("twist", std::string("needs a generated tube (mesh.type \"hollow_cylinder\" or \"swept_tube\"; got \"") +
                          name_of(s.mesh_type) + "\")", nullptr);
    for (const auto& [key, list, at] : selections)
      for (size_t i = 0; i < list->size(); ++i)
        if ((*list)[i].kind == FixedKind::kNamed)
          r.fail(Reader::index(key, i), from + " is closed and has no end node sets: hold nodes by {\"box\": ...} "
                 "or {\"plane\": ...}", &(*at)[i]);
  }
  // Quadratic elements come with the quasi-static models only (linear prefactorised, or corotational).
  if (s.element == ElementType::kTet10 && s.solver.type != SolverType::kQuasiStatic)
    r.fail("mesh.element", std::string("\"tet10\" needs solver.type \"quasi_static\" (got \"") + name_of(s.solver.type) + "\")",
           &root.at("mesh").at("element"));
  // The iterative LCP solves the constraint response's non-penetration problem (the paper's response is equalities).
  if (s.collision.lcp == LcpSolver::kNncg && s.collision.response != ResponseKind::kConstraint)
    r.fail("collision.lcp", "\"nncg\" needs collision.response \"constraint\" (got \"paper\")",
           &root.at("collision").at("lcp"));
  // Keys of the corotational quasi-static solve only: the message after the key's own words.
  const bool corotational_quasi_static =
      s.material.model == MaterialModel::kCorotational && s.solver.type == SolverType::kQuasiStatic;
  const std::string needs_corotational = std::string("needs material.model \"corotational\" and solver.type "
      "\"quasi_static\" (got \"") + name_of(s.material.model) + "\", \"" + name_of(s.solver.type) + "\")";
  // The prediction's bound after a contact frame is the solved coupling's, on the lagged Hessian, with PCG steps.
  if (s.collision.prediction_back_substitutions != 0) {
    const json* at = &root.at("collision").at("prediction_back_substitutions");
    if (s.collision.coupling != ContactCoupling::kSolved || s.collision.equilibrium_hessian != EquilibriumHessian::kLagged)
      r.fail("collision.prediction_back_substitutions",
             std::string("needs collision.coupling \"solved\" with equilibrium_hessian \"lagged\" (got \"") +
                 name_of(s.collision.coupling) + "\", \"" + name_of(s.collision.equilibrium_hessian) + "\")",
             at);
    if (s.solver.method != SolveMethod::kPcg)
      r.fail("collision.prediction_back_substitutions",
             std::string("needs solver.method \"pcg\" (got \"") + name_of(s.solver.method) + "\")", at);
  }
  // Carried or solved contacts enter the corotational quasi-static solve's equilibrium, with the constraint response.
  if (s.collision.coupling != ContactCoupling::kCorrect) {
    const json* at = &root.at("collision").at("coupling");
    const std::string quoted = std::string("\"") + name_of(s.collision.coupling) + "\" ";
    if (!corotational_quasi_static) r.fail("collision.coupling", quoted + needs_corotational, at);
    if (s.collision.response != ResponseKind::kConstraint)
      r.fail("collision.coupling", quoted + "needs collision.response \"constraint\" (got \"paper\")", at);
  }
  // The tangent is the corotational quasi-static solve's (the other integrators have no choice of operator).
  if (s.solver.tangent != Tangent::kWarped && !corotational_quasi_static)
    r.fail("solver.tangent", needs_corotational, &root.at("solver").at("tangent"));
  // The work bound is the corotational quasi-static solve's (the dynamic one's steps are not carried over).
  if (s.solver.max_back_substitutions != 0) {
    const json* at = &root.at("solver").at("max_back_substitutions");
    if (!corotational_quasi_static) r.fail("solver.max_back_substitutions", needs_corotational, at);
    if (s.solver.method != SolveMethod::kPcg)
      r.fail("solver.max_back_substitutions",
             std::string("needs solver.method \"pcg\" (got \"") + name_of(s.solver.method) + "\")", at);
  }
  // The chord steps' operator is the lagged factorisation of K_w (the corotational quasi-static solve's).
  if (s.solver.method != SolveMethod::kPcg) {
    const json* at = &root.at("solver").at("method");
    if (!corotational_quasi_static) r.fail("solver.method", needs_corotational, at);
    if (s.solver.tangent != Tangent::kWarped)
      r.fail("solver.method", std::string("\"chord\" needs solver.tangent \"warped\" (got \"") + name_of(s.solver.tangent) + "\")", at);
  }
  // The 10-node corotational element has no twist modes: warped steps only.
  if (s.solver.tangent != Tangent::kWarped && s.element == ElementType::kTet10)
    r.fail("solver.tangent", std::string("\"") + name_of(s.solver.tangent) + "\" needs mesh.element \"tet4\" (got \"tet10\")",
           &root.at("solver").at("tangent"));
  // The endoscope rides on one of the scene's instruments.
  const std::string& scope = s.render.scope_instrument;
  if (!scope.empty() && std::none_of(s.instruments.begin(), s.instruments.end(),
                                     [&](const InstrumentSpec& in) { return in.name == scope; }))
    r.fail("render.camera.endoscope", "names no instrument of the scene", &root.at("render").at("camera").at("endoscope"));
  // Tool contacts are rows of the constraint response (the paper's response holds vertices, not tools), solved
  // after the nonlinear solve (not carried into it).
  if (!s.instruments.empty() && s.collision.response != ResponseKind::kConstraint)
    r.fail("collision.response", "instruments need \"constraint\"", &root.at("collision").at("response"));
  if (!s.instruments.empty() && s.collision.coupling != ContactCoupling::kCorrect)
    r.fail("collision.coupling", "instruments need \"correct\"", &root.at("collision").at("coupling"));
  // Displacement-driven probes (held points) are solved on the linear quasi-static model's probe compliance.
  int held = -1;
  for (size_t i = 0; i < s.probes.size() && held < 0; ++i)
    if (s.probes[i].drive == ProbeDrive::Displacement) held = static_cast<int>(i);
  // (Supports are springs on the outer wall's nodes, part of every model's stiffness: linear and corotational,
  // quasi-static and dynamic, 4- and 10-node tets.)
  // Grasped nodes are held the same way, on the rest stiffness, as the only held points of the session.
  for (size_t i = 0; i < s.instruments.size(); ++i) {
    if (!s.instruments[i].grasp.enabled) continue;
    const std::string gpath = Reader::join(Reader::index("instruments", i), "grasp");
    const json* at = &root.at("instruments")[i].at("grasp");
    if (s.material.model != MaterialModel::kLinear || s.solver.type != SolverType::kQuasiStatic)
      r.fail(gpath, "needs material.model \"linear\" and solver.type \"quasi_static\"", at);
    if (held >= 0) r.fail(gpath, "cannot be combined with displacement-driven probes (probes[" + std::to_string(held) + "])", at);
  }
  if (held < 0) return;
  const std::string held_path = Reader::index("probes", held);
  for (size_t i = 0; i < s.probes.size(); ++i)
    if (!s.probes[i].replay.empty())
      r.fail(Reader::index("probes", i) + ".replay",
             "replayed probes cannot be combined with displacement-driven probes", &root.at("probes")[i].at("replay"));
  if (s.solver.type == SolverType::kDynamic)
    r.fail(held_path + ".track", "displacement-driven probes need solver.type \"quasi_static\" (value \"dynamic\")",
           nullptr);
  if (s.material.model == MaterialModel::kCorotational)
    r.fail(held_path + ".track",
           "displacement-driven probes need material.model \"linear\" (value \"corotational\")", nullptr);
}

}  // namespace

const char* name_of(MaterialModel v) { return kMaterialModelNames[static_cast<int>(v)]; }
const char* name_of(ElementType v) { return kElementNames[static_cast<int>(v)]; }
const char* name_of(SolverType v) { return kSolverNames[static_cast<int>(v)]; }
const char* name_of(ResponseKind v) { return kResponseNames[static_cast<int>(v)]; }
const char* name_of(LcpSolver v) { return kLcpSolverNames[static_cast<int>(v)]; }
const char* name_of(Recheck v) { return kRecheckNames[static_cast<int>(v)]; }
const char* name_of(Detection v) { return kDetectionNames[static_cast<int>(v)]; }
const char* name_of(ContactCoupling v) { return kCouplingNames[static_cast<int>(v)]; }
const char* name_of(Tangent v) { return kTangentNames[static_cast<int>(v)]; }
const char* name_of(SolveMethod v) { return kMethodNames[static_cast<int>(v)]; }
const char* name_of(EquilibriumHessian v) { return kEquilibriumHessianNames[static_cast<int>(v)]; }
const char* name_of(TwistEnd v) { return kTwistEndNames[static_cast<int>(v)]; }
const char* name_of(MeshType v) { return kMeshTypeNames[static_cast<int>(v)]; }
const char* name_of(render::CameraPreset v) { return kCameraNames[static_cast<int>(v)]; }

Scene parse_scene(const std::string& text, const std::string& path) {
  Reader r(path);
  // Parse the JSON text; syntax errors name the byte position.
  json root;
  try {
    root = json::parse(text);
  } catch (const json::exception& e) {
    // Syntax errors, and numbers that overflow a double (1e999): name the file and the parser's reason.
    throw InputError(path + ": malformed JSON: " + e.what());
  }
  r.only_keys(root, "", {"name", "mesh", "material", "fixed", "probes", "frames", "fps", "render", "collision",
                          "solver", "twist", "support", "instruments", "haptics"});

  Scene s;
  s.path = path;
  const std::filesystem::path dir = std::filesystem::path(path).parent_path();
  s.name = r.string(r.require(root, "", "name"), "name");
  if (s.name.empty() || s.name.find_first_of("/\\") != std::string::npos || s.name == "." || s.name == "..")
    r.fail("name", "must be a non-empty name without path separators", &root.at("name"));
  read_mesh(r, r.require(root, "", "mesh"), dir, s);
  read_material(r, r.require(root, "", "material"), s.material);

  // Node sets held still: names, boxes, plane sides.
  const json& fixed = r.require(root, "", "fixed");
  if (!fixed.is_array() || fixed.empty()) r.fail("fixed", "must be a non-empty array of node sets", &fixed);
  for (size_t i = 0; i < fixed.size(); ++i) s.fixed.push_back(read_fixed(r, fixed[i], Reader::index("fixed", i), s));

  const json& probes = r.require(root, "", "probes");
  if (!probes.is_array()) r.fail("probes", "must be an array", &probes);
  for (size_t i = 0; i < probes.size(); ++i) s.probes.push_back(read_probe(r, probes[i], Reader::index("probes", i), i, dir));

  s.frames = r.integer_in(r.require(root, "", "frames"), "frames", 1, 10000000);
  s.fps = r.number(r.require(root, "", "fps"), "fps");
  if (!(s.fps > 0) || s.fps > 10000) r.fail("fps", "out of range (0, 10000]", &root.at("fps"));
  if (root.contains("render")) read_render(r, root.at("render"), s, s.render);
  if (root.contains("collision")) read_collision(r, root.at("collision"), s.collision);
  if (root.contains("solver")) read_solver(r, root.at("solver"), s.solver);
  if (root.contains("twist")) read_twist(r, root.at("twist"), s.twist);
  if (root.contains("support")) {
    const json& sp = root.at("support");
    if (!sp.is_object()) r.fail("support", "must be an object {\"stiffness_n_per_m3\", \"where\"}", &sp);
    r.only_keys(sp, "support", {"stiffness_n_per_m3", "where"});
    s.support.stiffness = r.positive(r.require(sp, "support", "stiffness_n_per_m3"), "support.stiffness_n_per_m3");
    if (sp.contains("where")) {
      const json& where = sp.at("where");
      if (!where.is_array() || where.empty())
        r.fail("support.where", "must be a non-empty list of node selections (as \"fixed\")", &where);
      for (size_t i = 0; i < where.size(); ++i)
        s.support.where.push_back(read_fixed(r, where[i], Reader::index("support.where", i), s));
    }
  }
  if (root.contains("instruments")) read_instruments(r, root.at("instruments"), dir, s);
  if (root.contains("haptics")) read_haptics(r, root.at("haptics"), s.haptics);
  check_combinations(r, root, s);
  return s;
}

Pose home_pose(const InstrumentSpec& spec) {
  if (!spec.poses.empty()) return spec.poses.front().pose;
  return device_to_organ(spec.to_organ, Eigen::Vector3d::Zero(), Eigen::Quaterniond::Identity());
}

void require_file(const std::string& path, const std::string& what) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw InputError(path + ": is a folder, not a " + what);
  if (!std::filesystem::exists(path, ec)) throw InputError(path + ": no such " + what);
}

Scene load_scene(const std::string& path) {
  require_file(path, "scene file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot read scene file");
  std::stringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw InputError(path + ": cannot read scene file");
  return parse_scene(ss.str(), path);
}

}  // namespace lumen::engine
