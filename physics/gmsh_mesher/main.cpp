// lumen_gmsh_mesher: fills the volume between two closed surfaces with gmsh's HXT, one request on standard input,
// one reply on standard output (physics/pair_mesh_protocol.hpp). Started by tetrahedralise_pair for each mesh: in a
// process of its own, gmsh's process-wide state (which made each call's mesh differ within one process) starts
// afresh, and a crash inside gmsh becomes an error of the caller's instead of the caller's end.
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <string>
#include <utility>
#include <vector>

#include <gmsh.h>

#include "physics/pair_mesh_protocol.hpp"

namespace {

namespace pp = lumen::physics::pair_protocol;

bool read_all(int fd, void* data, size_t bytes) {
  auto* p = static_cast<char*>(data);
  while (bytes > 0) {
    const ssize_t n = ::read(fd, p, bytes);
    if (n <= 0) return false;
    p += n;
    bytes -= static_cast<size_t>(n);
  }
  return true;
}
bool write_all(int fd, const void* data, size_t bytes) {
  const auto* p = static_cast<const char*>(data);
  while (bytes > 0) {
    const ssize_t n = ::write(fd, p, bytes);
    if (n <= 0) return false;
    p += n;
    bytes -= static_cast<size_t>(n);
  }
  return true;
}

// gmsh's last error, or the last line of its log.
std::string gmsh_said() {
  std::string error;
  gmsh::logger::getLastError(error);
  if (!error.empty()) return error;
  std::vector<std::string> log;
  gmsh::logger::get(log);
  return log.empty() ? "no message" : "its log ends: " + log.back();
}

struct Request {
  std::int32_t vertices = 0, faces = 0, inner_vertices = 0, inner_faces = 0, steps = 0;
  std::vector<double> xyz;          // vertices x 3
  std::vector<std::int32_t> tris;   // faces x 3
};

bool read_request(int fd, Request& r) {
  char magic[sizeof pp::kRequestMagic];
  if (!read_all(fd, magic, sizeof magic) || std::string(magic, sizeof magic) != std::string(pp::kRequestMagic, 8))
    return false;
  std::int32_t head[5];
  if (!read_all(fd, head, sizeof head)) return false;
  r = {head[0], head[1], head[2], head[3], head[4], {}, {}};
  if (r.vertices <= 0 || r.faces <= 0 || r.inner_vertices <= 0 || r.inner_vertices >= r.vertices ||
      r.inner_faces <= 0 || r.inner_faces >= r.faces || r.steps < 0)
    return false;
  r.xyz.resize(3 * static_cast<size_t>(r.vertices));
  r.tris.resize(3 * static_cast<size_t>(r.faces));
  return read_all(fd, r.xyz.data(), r.xyz.size() * sizeof(double)) &&
         read_all(fd, r.tris.data(), r.tris.size() * sizeof(std::int32_t));
}

// Each surface a discrete entity with its vertices (tags 1-based, in the request's order) and triangles; the
// volume between them; HXT on one thread, then gmsh's tet optimiser.
void mesh(const Request& r, std::vector<std::size_t>& tets, std::vector<std::size_t>& node_tags,
          std::vector<double>& coords) {
  auto add_surface = [&](std::int32_t v0, std::int32_t v1, std::int32_t f0, std::int32_t f1) {
    const int entity = gmsh::model::addDiscreteEntity(2);
    std::vector<std::size_t> tags;
    std::vector<double> xyz;
    for (std::int32_t v = v0; v < v1; ++v) {
      tags.push_back(static_cast<std::size_t>(v) + 1);
      for (int c = 0; c < 3; ++c) xyz.push_back(r.xyz[3 * static_cast<size_t>(v) + c]);
    }
    gmsh::model::mesh::addNodes(2, entity, tags, xyz);
    std::vector<std::size_t> tri;
    for (size_t k = 3 * static_cast<size_t>(f0); k < 3 * static_cast<size_t>(f1); ++k)
      tri.push_back(static_cast<std::size_t>(r.tris[k]) + 1);
    gmsh::model::mesh::addElementsByType(entity, pp::kGmshTriangle, {}, tri);
    return gmsh::model::geo::addSurfaceLoop({entity});
  };
  gmsh::model::add("lumen_pair");
  const int inner_loop = add_surface(0, r.inner_vertices, 0, r.inner_faces);
  const int outer_loop = add_surface(r.inner_vertices, r.vertices, r.inner_faces, r.faces);
  gmsh::model::geo::addVolume({outer_loop, inner_loop});
  gmsh::model::geo::synchronize();
  gmsh::option::setNumber("Mesh.Algorithm3D", pp::kGmshHxt);
  gmsh::option::setNumber("Mesh.Optimize", r.steps > 0 ? 1 : 0);
  gmsh::option::setNumber("General.NumThreads", 1);
  gmsh::option::setNumber("Mesh.MaxNumThreads3D", 1);
  gmsh::model::mesh::generate(3);
  if (r.steps > 1) gmsh::model::mesh::optimize("", false, r.steps - 1);
  std::vector<std::size_t> element_tags;
  std::vector<double> parametric;
  gmsh::model::mesh::getElementsByType(pp::kGmshTet, element_tags, tets);
  gmsh::model::mesh::getNodes(node_tags, coords, parametric, -1, -1, false, false);
}

// The reply: the input vertices first (by their tags 1..vertices), the added nodes after in tag order.
bool write_mesh(int fd, const Request& r, const std::vector<std::size_t>& tets,
                const std::vector<std::size_t>& node_tags, const std::vector<double>& coords, std::string& problem) {
  const size_t nv = static_cast<size_t>(r.vertices);
  std::vector<long> position(nv + 1, -1);
  std::vector<std::pair<std::size_t, size_t>> added;  // (tag, position in coords)
  for (size_t k = 0; k < node_tags.size(); ++k) {
    if (node_tags[k] >= 1 && node_tags[k] <= nv)
      position[node_tags[k]] = static_cast<long>(k);
    else
      added.push_back({node_tags[k], k});
  }
  std::sort(added.begin(), added.end());
  std::vector<double> xyz;
  std::vector<std::pair<std::size_t, std::int32_t>> index_of;  // (tag, node index), sorted by tag
  for (size_t v = 0; v < nv; ++v) {
    if (position[v + 1] < 0) {
      problem = "input vertex " + std::to_string(v) + " is missing from its nodes";
      return false;
    }
    for (int c = 0; c < 3; ++c) xyz.push_back(coords[3 * static_cast<size_t>(position[v + 1]) + c]);
    index_of.push_back({v + 1, static_cast<std::int32_t>(v)});
  }
  for (size_t a = 0; a < added.size(); ++a) {
    for (int c = 0; c < 3; ++c) xyz.push_back(coords[3 * added[a].second + c]);
    index_of.push_back({added[a].first, static_cast<std::int32_t>(nv + a)});
  }
  std::sort(index_of.begin(), index_of.end());
  std::vector<std::int32_t> t(tets.size());
  for (size_t k = 0; k < tets.size(); ++k) {
    const auto it = std::lower_bound(index_of.begin(), index_of.end(), std::make_pair(tets[k], std::int32_t{-1}));
    if (it == index_of.end() || it->first != tets[k]) {
      problem = "tet " + std::to_string(k / 4) + " names a node it did not return";
      return false;
    }
    t[k] = it->second;
  }
  const std::int64_t counts[2] = {static_cast<std::int64_t>(xyz.size() / 3), static_cast<std::int64_t>(t.size() / 4)};
  return write_all(fd, pp::kReplyMagic, sizeof pp::kReplyMagic) && write_all(fd, &pp::kReplyOk, sizeof pp::kReplyOk) &&
         write_all(fd, counts, sizeof counts) && write_all(fd, xyz.data(), xyz.size() * sizeof(double)) &&
         write_all(fd, t.data(), t.size() * sizeof(std::int32_t));
}

bool write_failure(int fd, const std::string& what) {
  const std::int64_t length = static_cast<std::int64_t>(what.size());
  return write_all(fd, pp::kReplyMagic, sizeof pp::kReplyMagic) &&
         write_all(fd, &pp::kReplyFailed, sizeof pp::kReplyFailed) && write_all(fd, &length, sizeof length) &&
         write_all(fd, what.data(), what.size());
}

}  // namespace

int main() {
  // The reply keeps standard output to itself: gmsh's own prints (its boundary recovery writes to stdout) go to
  // standard error.
  const int reply = ::dup(STDOUT_FILENO);
  if (reply < 0 || ::dup2(STDERR_FILENO, STDOUT_FILENO) < 0) return pp::kExitBadRequest;
  Request r;
  if (!read_request(STDIN_FILENO, r)) return pp::kExitBadRequest;
  std::vector<std::size_t> tets, node_tags;
  std::vector<double> coords;
  std::string problem;
  bool ok = false;
  try {
    gmsh::initialize(0, nullptr, false);
    gmsh::option::setNumber("General.Terminal", 0);
    gmsh::logger::start();
    mesh(r, tets, node_tags, coords);
    ok = !tets.empty();
    if (!ok) problem = "no tets (" + gmsh_said() + ")";
  } catch (const std::exception& e) {
    problem = std::string(e.what()) + " (" + gmsh_said() + ")";
  } catch (...) {  // gmsh 4.8's API throws its last error's text as a non-std exception
    problem = gmsh_said();
  }
  const bool sent = ok ? write_mesh(reply, r, tets, node_tags, coords, problem) || write_failure(reply, problem)
                       : write_failure(reply, problem);
  ::close(reply);
  // No gmsh::finalize and no exit handlers: the process ends here, its memory with it.
  ::_exit(sent ? 0 : pp::kExitBadRequest);
}
