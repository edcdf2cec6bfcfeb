// Surface files through assimp, and the closed-surface checks (engine/surface_file.hpp).
#include "engine/surface_file.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <cctype>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <tuple>
#include <utility>
#include <vector>

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include "engine/input.hpp"
#include "engine/isolated.hpp"
#include "engine/scene.hpp"
#include "physics/surface_remesh.hpp"

namespace lumen::engine {
namespace {

// File extensions (lower case) of the organ surface formats: Wavefront OBJ, STL, PLY, OFF.
constexpr const char* kSurfaceExtensions[] = {".obj", ".stl", ".ply", ".off"};

// The text in lower case (ASCII).
std::string lower_case(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

// A file's extension in lower case (".ply").
std::string lower_extension(const std::string& file) { return lower_case(std::filesystem::path(file).extension().string()); }

// "vertex 3 at [x, y, z]", for messages.
std::string vertex_text(const SurfaceMesh& m, int v) {
  return "vertex " + std::to_string(v) + " at " + values_text(m.points.row(v).data(), 3);
}

// Refuse a triangle with a repeated vertex or (near) zero area.
void require_nondegenerate(const SurfaceMesh& m, const std::string& where) {
  const Eigen::RowVector3d extent = m.points.colwise().maxCoeff() - m.points.colwise().minCoeff();
  const double min_area = kDegenerateAreaRatio * extent.squaredNorm();
  for (int t = 0; t < m.tris.rows(); ++t) {
    const int a = m.tris(t, 0), b = m.tris(t, 1), c = m.tris(t, 2);
    const Eigen::Vector3d pa = m.points.row(a), pb = m.points.row(b), pc = m.points.row(c);
    const double area = 0.5 * (pb - pa).cross(pc - pa).norm();
    if (a == b || b == c || c == a || !(area > min_area))
      throw InputError(where + ": triangle " + std::to_string(t) + " is degenerate (area " + value_text(area) +
                       " m^2): " + vertex_text(m, a) + ", " + vertex_text(m, b) + ", " + vertex_text(m, c));
  }
}

// Refuse an edge not shared by exactly two triangles that run it in opposite directions.
void require_paired_edges(const SurfaceMesh& m, const std::string& where) {
  // Every triangle side as (low id, high id, triangle, runs low -> high), sorted so each edge's sides are adjacent.
  std::vector<std::tuple<int, int, int, bool>> sides;
  for (int t = 0; t < m.tris.rows(); ++t)
    for (int j = 0; j < 3; ++j) {
      const int a = m.tris(t, j), b = m.tris(t, (j + 1) % 3);
      sides.emplace_back(std::min(a, b), std::max(a, b), t, a < b);
    }
  std::sort(sides.begin(), sides.end());
  for (size_t i = 0; i < sides.size();) {
    const int lo = std::get<0>(sides[i]), hi = std::get<1>(sides[i]);
    const bool up0 = std::get<3>(sides[i]);
    size_t j = i;
    std::string tris;
    for (; j < sides.size() && std::get<0>(sides[j]) == lo && std::get<1>(sides[j]) == hi; ++j)
      tris += (j > i ? ", " : "") + std::to_string(std::get<2>(sides[j]));
    const std::string edge = "edge between " + vertex_text(m, lo) + " and " + vertex_text(m, hi);
    if (j - i == 1) throw InputError(where + ": not closed: " + edge + " belongs to triangle " + tris + " only");
    if (j - i > 2)
      throw InputError(where + ": non-manifold " + edge + ": shared by " + std::to_string(j - i) + " triangles (" +
                       tris + ")");
    if (std::get<3>(sides[i + 1]) == up0)
      throw InputError(where + ": inconsistent orientation: triangles " + tris + " run the " + edge +
                       " the same way");
    i = j;
  }
}

// Every triangle of the assimp scene below `node` (positions through the node transforms), vertices at identical
// positions merged in order of first use.
void collect_triangles(const aiScene& scene, const aiNode& node, const aiMatrix4x4& parent, const std::string& file,
                       std::map<std::array<double, 3>, int>& ids, std::vector<std::array<double, 3>>& points,
                       std::vector<std::array<int, 3>>& tris) {
  const aiMatrix4x4 to_root = parent * node.mTransformation;
  for (unsigned k = 0; k < node.mNumMeshes; ++k) {
    const aiMesh& mesh = *scene.mMeshes[node.mMeshes[k]];
    for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
      const aiFace& face = mesh.mFaces[f];
      if (face.mNumIndices != 3)
        throw InputError(file + ": mesh " + std::to_string(node.mMeshes[k]) + " face " + std::to_string(f) + " has " +
                         std::to_string(face.mNumIndices) + " vertices: not a triangle (points and lines enclose nothing)");
      std::array<int, 3> tri;
      for (int c = 0; c < 3; ++c) {
        if (face.mIndices[c] >= mesh.mNumVertices)
          throw InputError(file + ": mesh " + std::to_string(node.mMeshes[k]) + " face " + std::to_string(f) +
                           " names vertex " + std::to_string(face.mIndices[c]) + " of " +
                           std::to_string(mesh.mNumVertices));
        const aiVector3D p = to_root * mesh.mVertices[face.mIndices[c]];
        const std::array<double, 3> key = {p.x, p.y, p.z};
        const auto [it, added] = ids.emplace(key, static_cast<int>(points.size()));
        if (added) points.push_back(key);
        tri[static_cast<size_t>(c)] = it->second;
      }
      tris.push_back(tri);
    }
  }
  for (unsigned c = 0; c < node.mNumChildren; ++c)
    collect_triangles(scene, *node.mChildren[c], to_root, file, ids, points, tris);
}

// The surface as assimp reads it (read_surface_file's work, run in the child process).
SurfaceMesh import_surface(const std::string& file, double metres_per_unit, const std::string& what) {
  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile(file, aiProcess_Triangulate);
  if (!scene || !scene->mRootNode)
    throw InputError(file + ": cannot read " + what + " (" + importer.GetErrorString() + ")");
  std::map<std::array<double, 3>, int> ids;
  std::vector<std::array<double, 3>> points;
  std::vector<std::array<int, 3>> tris;
  collect_triangles(*scene, *scene->mRootNode, aiMatrix4x4(), file, ids, points, tris);
  if (tris.empty()) throw InputError(file + ": no triangles in " + what);
  SurfaceMesh m;
  m.points.resize(static_cast<Eigen::Index>(points.size()), 3);
  m.tris.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (size_t i = 0; i < points.size(); ++i)
    for (int j = 0; j < 3; ++j)
      m.points(static_cast<Eigen::Index>(i), j) = metres_per_unit * points[i][static_cast<size_t>(j)];
  for (size_t t = 0; t < tris.size(); ++t)
    for (int j = 0; j < 3; ++j) m.tris(static_cast<Eigen::Index>(t), j) = tris[t][static_cast<size_t>(j)];
  return m;
}

// A surface as bytes across the pipe: the row counts (int64), then the points' and the triangles' raw arrays.
std::string encode(const SurfaceMesh& m) {
  const std::int64_t rows[2] = {m.points.rows(), m.tris.rows()};
  std::string bytes(reinterpret_cast<const char*>(rows), sizeof rows);
  bytes.append(reinterpret_cast<const char*>(m.points.data()), sizeof(double) * static_cast<size_t>(m.points.size()));
  bytes.append(reinterpret_cast<const char*>(m.tris.data()), sizeof(int) * static_cast<size_t>(m.tris.size()));
  return bytes;
}

SurfaceMesh decode(const std::string& bytes) {
  std::int64_t rows[2];
  assert(bytes.size() >= sizeof rows);
  std::memcpy(rows, bytes.data(), sizeof rows);
  SurfaceMesh m;
  m.points.resize(rows[0], 3);
  m.tris.resize(rows[1], 3);
  const size_t point_bytes = sizeof(double) * static_cast<size_t>(m.points.size());
  assert(bytes.size() == sizeof rows + point_bytes + sizeof(int) * static_cast<size_t>(m.tris.size()));
  std::memcpy(m.points.data(), bytes.data() + sizeof rows, point_bytes);
  std::memcpy(m.tris.data(), bytes.data() + sizeof rows + point_bytes, sizeof(int) * static_cast<size_t>(m.tris.size()));
  return m;
}

// Bytes of a PLY scalar type, or 0 for a name that is none; integer: whether it is an integer type.
int ply_type_bytes(const std::string& type, bool* integer = nullptr) {
  static const std::map<std::string, std::pair<int, bool>> kTypes = {
      {"char", {1, true}},    {"uchar", {1, true}},   {"int8", {1, true}},    {"uint8", {1, true}},
      {"short", {2, true}},   {"ushort", {2, true}},  {"int16", {2, true}},   {"uint16", {2, true}},
      {"int", {4, true}},     {"uint", {4, true}},    {"int32", {4, true}},   {"uint32", {4, true}},
      {"float", {4, false}},  {"float32", {4, false}}, {"double", {8, false}}, {"float64", {8, false}}};
  const auto it = kTypes.find(type);
  if (it == kTypes.end()) return 0;
  if (integer) *integer = it->second.second;
  return it->second.first;
}

// The whitespace-separated words of a line.
std::vector<std::string> words_of(const std::string& line) {
  std::vector<std::string> words;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    const size_t start = i;
    while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

// A PLY element of the header: its name, declared count, line, and the least bytes one of it takes in the body.
struct PlyElement {
  std::string name;
  long long count = 0;
  int line = 0;
  std::string text;         // the header line
  long long min_bytes = 0;  // binary: fixed properties and list counts; ascii: 2 a property
};

}  // namespace

void require_ply_header(const std::string& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file + ": PLY header: cannot open the file");
  std::string head(static_cast<size_t>(kPlyHeaderMaxBytes), '\0');
  in.read(head.data(), kPlyHeaderMaxBytes);
  head.resize(static_cast<size_t>(in.gcount()));
  in.clear();
  in.seekg(0, std::ios::end);
  const long long file_bytes = static_cast<long long>(in.tellg());
  // A header line as the messages quote it: at most kQuoted characters, unprintable ones as '?'.
  constexpr size_t kQuoted = 80;
  auto quoted = [](const std::string& text) {
    std::string q = text.substr(0, kQuoted);
    for (char& c : q)
      if (!std::isprint(static_cast<unsigned char>(c))) c = '?';
    return "(\"" + q + (text.size() > kQuoted ? "...\")" : "\")");
  };
  auto fail_line = [&](int line, const std::string& text, const std::string& problem) {
    throw InputError(file + ": PLY header line " + std::to_string(line) + ": " + problem + " " + quoted(text));
  };
  bool ascii = false, have_format = false;
  std::vector<PlyElement> elements;
  size_t pos = 0;
  for (int line = 1;; ++line) {
    const size_t end = head.find('\n', pos);
    if (end == std::string::npos)
      throw InputError(file + ": PLY header: no \"end_header\" line within its first " +
                       std::to_string(kPlyHeaderMaxBytes) + " bytes");
    std::string text = head.substr(pos, end - pos);
    pos = end + 1;
    if (!text.empty() && text.back() == '\r') text.pop_back();
    const std::vector<std::string> w = words_of(text);
    const std::string key = w.empty() ? std::string() : w[0];
    // The magic line (as assimp takes it, in either case), then the keywords of the header; blank lines skipped.
    if (line == 1) {
      if (w.size() != 1 || lower_case(key) != "ply") fail_line(line, text, "must be \"ply\"");
      continue;
    }
    if (w.empty() || key == "comment" || key == "obj_info") continue;
    if (key == "end_header") {
      if (w.size() != 1) fail_line(line, text, "\"end_header\" takes nothing after it");
      break;
    }
    if (key == "format") {
      const bool known = w.size() == 3 && w[2] == "1.0" &&
                         (w[1] == "ascii" || w[1] == "binary_little_endian" || w[1] == "binary_big_endian");
      if (!known) fail_line(line, text, "must be \"format ascii|binary_little_endian|binary_big_endian 1.0\"");
      if (have_format || !elements.empty()) fail_line(line, text, "one format line, before the first element");
      have_format = true;
      ascii = w[1] == "ascii";
      continue;
    }
    if (key == "element") {
      if (!have_format) fail_line(line, text, "an element before the format line");
      char* stop = nullptr;
      const long long count = w.size() == 3 ? std::strtoll(w[2].c_str(), &stop, 10) : -1;
      if (w.size() != 3 || *stop != '\0' || count < 0 || count > std::numeric_limits<int>::max())
        fail_line(line, text, "must be \"element NAME COUNT\" with COUNT an integer in [0, 2147483647]");
      elements.push_back({w[1], count, line, text, 0});
      continue;
    }
    if (key == "property") {
      if (elements.empty()) fail_line(line, text, "a property before any element");
      bool integer = false;
      const bool list = w.size() > 1 && w[1] == "list";
      if (list) {
        const bool ok = w.size() == 5 && ply_type_bytes(w[2], &integer) > 0 && integer && ply_type_bytes(w[3]) > 0;
        if (!ok) fail_line(line, text, "must be \"property list COUNT_TYPE TYPE NAME\" (COUNT_TYPE an integer type)");
      } else if (w.size() != 3 || ply_type_bytes(w[1]) == 0) {
        fail_line(line, text, "must be \"property TYPE NAME\" with TYPE one of PLY's scalar types");
      }
      elements.back().min_bytes += ascii ? 2 : ply_type_bytes(list ? w[2] : w[1]);
      continue;
    }
    fail_line(line, text, "not a PLY header keyword");
  }
  // Each element's declared count against the bytes after the header (ascii: the last value needs no separator).
  const long long body = file_bytes - static_cast<long long>(pos);
  long long needed = 0;
  for (const PlyElement& e : elements) {
    needed += e.count * e.min_bytes;  // (each term < 2^48, and the sum stops once past the body: no overflow)
    if (needed > body + (ascii ? 1 : 0))
      fail_line(e.line, e.text, "element " + e.name + " declares " + std::to_string(e.count) +
                " of them, more than the file's " + std::to_string(body) + " bytes after the header can hold");
  }
}

SurfaceMesh read_surface_file(const std::string& file, double metres_per_unit, const std::string& what,
                              double timeout_s) {
  // A PLY header checked first; assimp in a child process: its crash or endless loop on a malformed file becomes
  // this file's refusal.
  if (lower_extension(file) == ".ply") require_ply_header(file);
  const IsolatedRun run = run_isolated([&] { return encode(import_surface(file, metres_per_unit, what)); }, timeout_s);
  switch (run.end) {
    case IsolatedRun::End::kDone:
      return decode(run.text);
    case IsolatedRun::End::kThrew:
      throw InputError(run.text);
    case IsolatedRun::End::kCrashed:
      throw InputError(file + ": cannot read " + what + ": the reader (assimp) crashed on it (" + run.text + ")");
    case IsolatedRun::End::kTimedOut:
      break;
  }
  throw InputError(file + ": cannot read " + what + ": the reader (assimp) did not finish within " +
                   value_text(timeout_s) + " s");
}

void require_surface_format(const std::string& file) {
  const std::string ext = lower_extension(file);
  for (const char* ok : kSurfaceExtensions)
    if (ext == ok) return;
  throw InputError(file + ": unsupported surface format \"" + ext + "\" (OBJ, STL, PLY or OFF)");
}

void require_closed_surface(const SurfaceMesh& mesh, const std::string& where) {
  // Triangles with area, then every edge paired the opposite way.
  if (mesh.tris.rows() == 0) throw InputError(where + ": no triangles");
  assert(mesh.tris.minCoeff() >= 0 && mesh.tris.maxCoeff() < mesh.points.rows());
  require_nondegenerate(mesh, where);
  require_paired_edges(mesh, where);
}

void require_closed_manifold(const SurfaceMesh& mesh, const std::string& where) {
  // Triangles with area, every edge paired the opposite way, then a positive enclosed volume.
  require_closed_surface(mesh, where);
  const double volume = enclosed_volume(mesh);
  if (!(volume > 0.0))
    throw InputError(where + ": triangles face inwards: enclosed volume " + value_text(volume) +
                     " m^3 (must be > 0, triangles counter-clockwise seen from outside)");
}

double enclosed_volume(const SurfaceMesh& mesh) {
  // Sum of the signed tetrahedra from the origin to each triangle.
  double six_v = 0.0;
  for (int t = 0; t < mesh.tris.rows(); ++t) {
    const Eigen::Vector3d a = mesh.points.row(mesh.tris(t, 0)), b = mesh.points.row(mesh.tris(t, 1)),
                          c = mesh.points.row(mesh.tris(t, 2));
    six_v += a.dot(b.cross(c));
  }
  return six_v / 6.0;
}

SurfaceMesh read_closed_surface(const std::string& file, double metres_per_unit, double timeout_s) {
  require_file(file, "surface file");
  require_surface_format(file);
  SurfaceMesh m = read_surface_file(file, metres_per_unit, "surface", timeout_s);
  require_closed_surface(m, file);
  return enclosed_volume(m) < 0.0 ? reversed(m) : m;
}

SurfaceMesh reversed(const SurfaceMesh& mesh) {
  SurfaceMesh r = mesh;
  r.tris.col(1).swap(r.tris.col(2));
  return r;
}

std::string length_in_units(double metres, double metres_per_unit) {
  const bool millimetres = metres_per_unit == kMetresPerMillimetre;
  return value_text(metres / metres_per_unit) + (millimetres ? " mm" : " m");
}

SurfaceMesh remesh_surface(const SurfaceMesh& mesh, double target_edge, const std::string& file,
                           const std::string& target_text) {
  const double estimate = physics::remesh_triangle_estimate(mesh.points, mesh.tris, target_edge);
  if (!(estimate <= physics::kRemeshMaxTriangles))
    throw InputError(file + ": mesh.target_edge " + target_text + " would remesh the surface into about " +
                     value_text(estimate) + " triangles (at most " + value_text(physics::kRemeshMaxTriangles) + ")");
  physics::RemeshedSurface r;
  try {
    r = physics::remesh_isotropic(mesh.points, mesh.tris, target_edge);
  } catch (const std::exception& e) {
    throw InputError(file + ": mesh.target_edge: " + e.what());
  }
  return SurfaceMesh{std::move(r.points), std::move(r.tris)};
}

}  // namespace lumen::engine
