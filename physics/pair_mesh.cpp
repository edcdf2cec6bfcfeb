// The volume between two closed surfaces tetrahedralised by gmsh or Netgen's nglib (physics/pair_mesh.hpp).
#include "physics/pair_mesh.hpp"

#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cassert>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <mutex>
#include <ostream>
#include <set>
#include <sstream>
#include <vector>

#include "physics/detail/messages.hpp"
#include "physics/mesh_quality.hpp"
#include "physics/pair_mesh_protocol.hpp"
#include "physics/volume_mesh.hpp"

// nglib declares its interface in namespace nglib when included inside it (its own examples do so).
namespace nglib {
#include <nglib.h>
}

// Netgen's log streams (libmesh), which nglib's Ng_Init points at std::cout and std::cerr.
namespace netgen {
extern std::ostream* mycout;
extern std::ostream* myerr;
}  // namespace netgen

namespace lumen::physics {
namespace {

using Clock = std::chrono::steady_clock;
using Face = std::array<int, 3>;

// The last lines of a mesher's log kept in a failure message.
constexpr int kLogLinesInMessage = 2;
// The input vertices must come back within this distance (in the meshers' frame) of where they went in.
constexpr double kMovedVertexTolerance = 1e-9 * kPairMesherFrameDiagonal;

// What a mesher returns, in its frame: every node (the input vertices first, in their order) and the tets
// (#tets x 4 node indices, any orientation).
struct RawMesh {
  Points nodes;
  Tets tets;
};

// The surfaces as the meshers take them, in their frame.
struct PairInput {
  Points x;                 // #vertices x 3: inner vertices, then outer ones, in the meshers' frame
  std::vector<Face> faces;  // triangles facing out of the volume, indices into x: the inner ones, then the outer
  int inner_vertices = 0;   // x's first rows that are the inner surface's
  size_t inner_faces = 0;   // faces' first entries that are the inner surface's
};

// Netgen keeps global state: one initialisation, one mesh at a time.
std::mutex& netgen_mutex() {
  static std::mutex m;
  return m;
}

// Ng_Result's names, for messages.
std::string result_name(nglib::Ng_Result r) {
  switch (r) {
    case nglib::NG_ERROR: return "NG_ERROR";
    case nglib::NG_OK: return "NG_OK";
    case nglib::NG_SURFACE_INPUT_ERROR: return "NG_SURFACE_INPUT_ERROR";
    case nglib::NG_VOLUME_FAILURE: return "NG_VOLUME_FAILURE";
    case nglib::NG_STL_INPUT_ERROR: return "NG_STL_INPUT_ERROR";
    case nglib::NG_SURFACE_FAILURE: return "NG_SURFACE_FAILURE";
    case nglib::NG_FILE_NOT_FOUND: return "NG_FILE_NOT_FOUND";
  }
  return "result " + std::to_string(static_cast<int>(r));
}

// The last non-empty lines of a log, joined by " / ".
std::string last_lines(const std::string& log, int count) {
  std::vector<std::string> lines;
  std::istringstream in(log);
  for (std::string line; std::getline(in, line);) {
    const size_t a = line.find_first_not_of(" \t\r");
    if (a != std::string::npos) lines.push_back(line.substr(a, line.find_last_not_of(" \t\r") - a + 1));
  }
  std::string out;
  for (size_t i = lines.size() > static_cast<size_t>(count) ? lines.size() - count : 0; i < lines.size(); ++i)
    out += (out.empty() ? "" : " / ") + lines[i];
  return out;
}

Face sorted(Face f) {
  std::sort(f.begin(), f.end());
  return f;
}

// An nglib mesh, deleted on every path; Netgen's log goes to a buffer meanwhile (restored after).
class NetgenSession {
 public:
  NetgenSession() : lock_(netgen_mutex()) {
    static std::once_flag once;
    std::call_once(once, [] { nglib::Ng_Init(); });
    saved_out_ = netgen::mycout;
    saved_err_ = netgen::myerr;
    netgen::mycout = &log_;
    netgen::myerr = &log_;
    mesh_ = nglib::Ng_NewMesh();
  }
  ~NetgenSession() {
    nglib::Ng_DeleteMesh(mesh_);
    netgen::mycout = saved_out_;
    netgen::myerr = saved_err_;
  }
  NetgenSession(const NetgenSession&) = delete;
  NetgenSession& operator=(const NetgenSession&) = delete;
  nglib::Ng_Mesh* mesh() const { return mesh_; }
  std::string log() const { return log_.str(); }

 private:
  std::lock_guard<std::mutex> lock_;
  std::ostringstream log_;
  std::ostream* saved_out_ = nullptr;
  std::ostream* saved_err_ = nullptr;
  nglib::Ng_Mesh* mesh_ = nullptr;
};

// A mesher's name at the head of its messages.
const char* said_by(PairMesher mesher) { return mesher == PairMesher::kGmsh ? "gmsh" : "Netgen"; }

[[noreturn]] void not_kept(PairMesher mesher, const std::string& what) {
  throw PairMesherError(std::string(said_by(mesher)) + " did not keep the input surface: " + what);
}

// Refuses a mesher's tets unless their boundary faces are exactly the input triangles (as sets of node ids).
void require_kept_surface(PairMesher mesher, const Tets& tets, const std::vector<Face>& input) {
  const Tris boundary = boundary_faces(tets);
  std::set<Face> in;
  for (const Face& f : input) in.insert(sorted(f));
  std::set<Face> out;
  for (Eigen::Index t = 0; t < boundary.rows(); ++t) {
    const Face f = sorted({boundary(t, 0), boundary(t, 1), boundary(t, 2)});
    if (!in.count(f))
      not_kept(mesher, "boundary face (nodes " + std::to_string(f[0]) + ", " + std::to_string(f[1]) + ", " +
               std::to_string(f[2]) + ") of its tets is not an input triangle");
    out.insert(f);
  }
  for (const Face& f : in)
    if (!out.count(f))
      not_kept(mesher, "input triangle (nodes " + std::to_string(f[0]) + ", " + std::to_string(f[1]) + ", " +
               std::to_string(f[2]) + ") is not a boundary face of its tets");
}

[[noreturn]] void mesher_failed(PairMesher mesher, const std::string& what) {
  throw PairMesherError(std::string(said_by(mesher)) + " failed: " + what);
}

// Netgen's advancing front and optimisation passes.
RawMesh run_netgen(const PairInput& in, double maxh, int steps) {
  NetgenSession ng;
  // Input: the points (1-based in Netgen), the triangles with normals out of the volume (Netgen's convention).
  for (Eigen::Index v = 0; v < in.x.rows(); ++v) {
    Eigen::RowVector3d p = in.x.row(v);
    nglib::Ng_AddPoint(ng.mesh(), p.data());
  }
  for (const Face& f : in.faces) {
    int v[3] = {f[0] + 1, f[1] + 1, f[2] + 1};
    nglib::Ng_AddSurfaceElement(ng.mesh(), nglib::NG_TRIG, v);
  }
  nglib::Ng_Meshing_Parameters mp;
  // nglib's volume mesher takes its size from its local size tree: maxh alone, or its global h, leave it unchanged
  // (measured), so the size is restricted over the whole bounding box.
  if (maxh > 0.0) {
    mp.maxh = maxh;
    Eigen::RowVector3d lo = in.x.colwise().minCoeff(), hi = in.x.colwise().maxCoeff();
    nglib::Ng_RestrictMeshSizeBox(ng.mesh(), lo.data(), hi.data(), mp.maxh);
  }
  mp.optsteps_3d = steps;
  nglib::Ng_Result result = nglib::NG_ERROR;
  try {
    result = nglib::Ng_GenerateVolumeMesh(ng.mesh(), &mp);
  } catch (const std::exception& e) {
    mesher_failed(PairMesher::kNetgen, e.what());
  } catch (...) {
    mesher_failed(PairMesher::kNetgen, "it threw an exception of an unknown type (its log ends: " +
                                           last_lines(ng.log(), kLogLinesInMessage) + ")");
  }
  const int np = nglib::Ng_GetNP(ng.mesh()), ne = nglib::Ng_GetNE(ng.mesh());
  if (result != nglib::NG_OK || ne == 0)
    mesher_failed(PairMesher::kNetgen, result_name(result) + " with " + std::to_string(ne) +
                                           " tets (its log ends: " + last_lines(ng.log(), kLogLinesInMessage) + ")");
  RawMesh out{Points(np, 3), Tets(ne, 4)};
  for (int v = 0; v < np; ++v) {
    Eigen::RowVector3d p;
    nglib::Ng_GetPoint(ng.mesh(), v + 1, p.data());
    out.nodes.row(v) = p;
  }
  for (int e = 0; e < ne; ++e) {
    int v[10];
    if (nglib::Ng_GetVolumeElement(ng.mesh(), e + 1, v) != nglib::NG_TET)
      mesher_failed(PairMesher::kNetgen, "element " + std::to_string(e) + " is not a tetrahedron");
    for (int k = 0; k < 4; ++k) out.tets(e, k) = v[k] - 1;
  }
  return out;
}

// The gmsh process's executable: LUMEN_GMSH_MESHER when set (tests point it elsewhere), else the one built beside
// Lumen.
std::string gmsh_mesher_path() {
  const char* env = std::getenv("LUMEN_GMSH_MESHER");
  return env && *env ? std::string(env) : std::string(LUMEN_GMSH_MESHER_PATH);
}

bool send_all(int fd, const void* data, size_t bytes) {
  const auto* p = static_cast<const char*>(data);
  while (bytes > 0) {
    const ssize_t n = ::send(fd, p, bytes, MSG_NOSIGNAL);  // a process that died is an error, not our SIGPIPE
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    p += n;
    bytes -= static_cast<size_t>(n);
  }
  return true;
}
bool receive_all(int fd, void* data, size_t bytes) {
  auto* p = static_cast<char*>(data);
  while (bytes > 0) {
    const ssize_t n = ::recv(fd, p, bytes, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    p += n;
    bytes -= static_cast<size_t>(n);
  }
  return true;
}

// The gmsh process: started with one end of a socket pair as its standard input and output, sent the request,
// its reply read, waited for. Every way it can fail is a PairMesherError naming it.
class GmshProcess {
 public:
  explicit GmshProcess(const std::string& path) : path_(path) {
    int ends[2];
    if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, ends) != 0)
      mesher_failed(PairMesher::kGmsh, "no socket pair for its process (" + std::string(std::strerror(errno)) + ")");
    fd_ = ends[0];
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, ends[1], STDIN_FILENO);
    posix_spawn_file_actions_adddup2(&actions, ends[1], STDOUT_FILENO);
    char* argv[] = {const_cast<char*>(path_.c_str()), nullptr};
    const int err = ::posix_spawn(&pid_, path_.c_str(), &actions, nullptr, argv, environ);
    posix_spawn_file_actions_destroy(&actions);
    ::close(ends[1]);
    if (err != 0) {
      ::close(fd_);
      mesher_failed(PairMesher::kGmsh, "cannot start its process " + path_ + " (" + std::strerror(err) + ")");
    }
  }
  ~GmshProcess() {
    if (fd_ >= 0) ::close(fd_);
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  GmshProcess(const GmshProcess&) = delete;
  GmshProcess& operator=(const GmshProcess&) = delete;
  int fd() const { return fd_; }
  // Closes the socket and waits: "" when it exited 0, else how it ended.
  std::string finish() {
    ::close(fd_);
    fd_ = -1;
    int status = 0;
    while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
    }
    pid_ = -1;
    if (WIFSIGNALED(status))
      return "its process " + path_ + " died of signal " + std::to_string(WTERMSIG(status)) + " (" +
             strsignal(WTERMSIG(status)) + ")";
    if (WIFEXITED(status) && WEXITSTATUS(status) != 0)
      return "its process " + path_ + " exited with status " + std::to_string(WEXITSTATUS(status));
    return "";
  }

 private:
  std::string path_;
  int fd_ = -1;
  pid_t pid_ = -1;
};

// gmsh's HXT and its optimiser in a process of its own (physics/gmsh_mesher/main.cpp): each mesh a first call of a
// fresh gmsh, so the same input gives the same mesh, and a crash inside gmsh is reported, not shared.
RawMesh run_gmsh(const PairInput& in, int steps) {
  namespace pp = pair_protocol;
  GmshProcess process(gmsh_mesher_path());
  const std::int32_t head[5] = {static_cast<std::int32_t>(in.x.rows()), static_cast<std::int32_t>(in.faces.size()),
                                in.inner_vertices, static_cast<std::int32_t>(in.inner_faces), steps};
  std::vector<double> xyz(3 * static_cast<size_t>(in.x.rows()));
  for (Eigen::Index v = 0; v < in.x.rows(); ++v)
    for (int c = 0; c < 3; ++c) xyz[3 * static_cast<size_t>(v) + c] = in.x(v, c);
  std::vector<std::int32_t> tris;
  tris.reserve(3 * in.faces.size());
  for (const Face& f : in.faces) tris.insert(tris.end(), f.begin(), f.end());
  const bool sent = send_all(process.fd(), pp::kRequestMagic, sizeof pp::kRequestMagic) &&
                    send_all(process.fd(), head, sizeof head) &&
                    send_all(process.fd(), xyz.data(), xyz.size() * sizeof(double)) &&
                    send_all(process.fd(), tris.data(), tris.size() * sizeof(std::int32_t));
  // Its reply: the mesh, or what gmsh said.
  char magic[sizeof pp::kReplyMagic] = {};
  std::int32_t status = -1;
  bool replied = sent && receive_all(process.fd(), magic, sizeof magic) &&
                 std::equal(magic, magic + sizeof magic, pp::kReplyMagic) &&
                 receive_all(process.fd(), &status, sizeof status);
  RawMesh out;
  std::string said;
  if (replied && status == pp::kReplyOk) {
    std::int64_t counts[2] = {0, 0};
    replied = receive_all(process.fd(), counts, sizeof counts) && counts[0] >= in.x.rows() && counts[1] > 0;
    if (replied) {
      std::vector<double> nodes(3 * static_cast<size_t>(counts[0]));
      std::vector<std::int32_t> tets(4 * static_cast<size_t>(counts[1]));
      replied = receive_all(process.fd(), nodes.data(), nodes.size() * sizeof(double)) &&
                receive_all(process.fd(), tets.data(), tets.size() * sizeof(std::int32_t));
      using NodeRows = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
      using TetRows = Eigen::Matrix<std::int32_t, Eigen::Dynamic, 4, Eigen::RowMajor>;
      out.nodes = Eigen::Map<const NodeRows>(nodes.data(), counts[0], 3);
      out.tets = Eigen::Map<const TetRows>(tets.data(), counts[1], 4).cast<int>();
      if (replied && (out.tets.minCoeff() < 0 || out.tets.maxCoeff() >= counts[0]))
        mesher_failed(PairMesher::kGmsh, "its process returned a tet naming a node it did not return");
    }
  } else if (replied && status == pp::kReplyFailed) {
    std::int64_t length = 0;
    replied = receive_all(process.fd(), &length, sizeof length) && length >= 0 && length < (1 << 20);
    said.resize(replied ? static_cast<size_t>(length) : 0);
    replied = replied && receive_all(process.fd(), said.data(), said.size());
  }
  const std::string ended = process.finish();
  if (!ended.empty()) mesher_failed(PairMesher::kGmsh, ended);
  if (!replied) mesher_failed(PairMesher::kGmsh, "its process's reply was cut short or malformed");
  if (status == pp::kReplyFailed) mesher_failed(PairMesher::kGmsh, said);
  return out;
}

// One mesher on the prepared input: its tets checked and mapped back to the caller's frame and surfaces.
PairMesh mesh_with(PairMesher mesher, const PairInput& in, const Points& x, const Tris& inner_tris,
                   const Tris& outer_tris, const Eigen::RowVector3d& centre, double scale,
                   const PairMeshOptions& options) {
  const Eigen::Index ni = in.inner_vertices, nv = x.rows();
  const int steps = options.optimise_steps >= 0
                        ? options.optimise_steps
                        : (mesher == PairMesher::kGmsh ? kGmshOptimiseSteps : kNetgenOptimiseSteps);
  PairMesh out;
  out.mesher = mesher;
  const auto t0 = Clock::now();
  RawMesh raw = mesher == PairMesher::kGmsh ? run_gmsh(in, steps) : run_netgen(in, options.max_edge * scale, steps);
  const Eigen::Index np = raw.nodes.rows();
  if (np < nv)
    not_kept(mesher, "it returned " + std::to_string(np) + " points for " + std::to_string(nv) + " input vertices");
  // The nodes: the input vertices exactly where they were (checked), the added ones mapped back.
  out.mesh.rest.resize(np, 3);
  out.mesh.rest.topRows(nv) = x;
  for (Eigen::Index v = 0; v < np; ++v) {
    if (v >= nv)
      out.mesh.rest.row(v) = raw.nodes.row(v) / scale + centre;
    else if (!((raw.nodes.row(v) - in.x.row(v)).norm() <= kMovedVertexTolerance))
      not_kept(mesher, "input vertex " + std::to_string(v) + " moved");
  }
  // The tets, each made positive.
  out.mesh.tets = std::move(raw.tets);
  for (Eigen::Index e = 0; e < out.mesh.tets.rows(); ++e)
    if (tet_volume(out.mesh.rest, out.mesh.tets, static_cast<int>(e)) < 0.0)
      std::swap(out.mesh.tets(e, 0), out.mesh.tets(e, 1));
  out.mesher_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  // Its result checked: no inverted or flat tet, the boundary exactly the input triangles.
  const MeshQuality q = mesh_quality(out.mesh.rest, out.mesh.tets);
  if (q.first_degenerate >= 0)
    not_kept(mesher, "tet " + std::to_string(q.first_degenerate) + " is inverted or has zero volume (" +
                         std::to_string(q.degenerate_tets) + " such tets)");
  require_kept_surface(mesher, out.mesh.tets, in.faces);
  // The walls: the inner triangles reversed (facing the lumen, out of the volume), the outer ones as given.
  out.added_nodes = static_cast<int>(np - nv);
  Tris in_tris = inner_tris;
  in_tris.col(1).swap(in_tris.col(2));
  out.mesh.surfaces = {{kInnerWall, in_tris}, {kOuterWall, outer_tris.array() + static_cast<int>(ni)},
                       {kEndCaps, Tris(0, 3)}};
  return out;
}

}  // namespace

const char* pair_mesher_name(PairMesher mesher) {
  switch (mesher) {
    case PairMesher::kAuto: return "auto";
    case PairMesher::kGmsh: return kGmshMesherName;
    case PairMesher::kNetgen: return kNetgenMesherName;
  }
  return "?";
}

PairMesh tetrahedralise_pair(const Points& inner, const Tris& inner_tris, const Points& outer, const Tris& outer_tris,
                             const PairMeshOptions& options) {
  const int ni = static_cast<int>(inner.rows()), no = static_cast<int>(outer.rows());
  // An empty surface would reach the mesher with nothing to mesh (Netgen crashed there, measured with both empty).
  if (inner_tris.rows() == 0 || outer_tris.rows() == 0)
    detail::fail("tetrahedralise_pair: the " + std::string(inner_tris.rows() == 0 ? "inner" : "outer") +
                 " surface has no triangles");
  if (inner_tris.minCoeff() < 0 || inner_tris.maxCoeff() >= ni || outer_tris.minCoeff() < 0 ||
      outer_tris.maxCoeff() >= no)
    detail::fail("tetrahedralise_pair: a triangle names a vertex outside its surface");
  if (options.mesher == PairMesher::kGmsh && options.max_edge > 0.0) detail::fail(kGmshMaxEdgeRefused);
  assert(options.max_edge >= 0.0 && options.optimise_steps >= -1 &&
         options.optimise_steps <= kPairMesherMaxOptimiseSteps);
  // Both surfaces as one point array (inner, then outer) and their triangles facing out of the volume.
  Points x(ni + no, 3);
  x << inner, outer;
  PairInput in;
  in.inner_vertices = ni;
  in.inner_faces = static_cast<size_t>(inner_tris.rows());
  for (Eigen::Index t = 0; t < inner_tris.rows(); ++t)
    in.faces.push_back({inner_tris(t, 0), inner_tris(t, 2), inner_tris(t, 1)});
  for (Eigen::Index t = 0; t < outer_tris.rows(); ++t)
    in.faces.push_back({ni + outer_tris(t, 0), ni + outer_tris(t, 1), ni + outer_tris(t, 2)});
  // The meshers' frame: centred on the bounding box, scaled to kPairMesherFrameDiagonal.
  const Eigen::RowVector3d lo = x.colwise().minCoeff(), hi = x.colwise().maxCoeff();
  const Eigen::RowVector3d centre = 0.5 * (lo + hi);
  const double scale = kPairMesherFrameDiagonal / (hi - lo).norm();
  in.x = (x.rowwise() - centre) * scale;
  auto with = [&](PairMesher m) { return mesh_with(m, in, x, inner_tris, outer_tris, centre, scale, options); };
  // Automatic: gmsh, and Netgen where gmsh fails (or for a maximum edge, which only Netgen takes).
  if (options.mesher != PairMesher::kAuto) return with(options.mesher);
  if (options.max_edge > 0.0) return with(PairMesher::kNetgen);
  try {
    return with(PairMesher::kGmsh);
  } catch (const PairMesherError& gmsh_failed) {
    try {
      PairMesh out = with(PairMesher::kNetgen);
      out.gmsh_failure = gmsh_failed.what();
      return out;
    } catch (const PairMesherError& netgen_failed) {
      throw PairMesherError(std::string(gmsh_failed.what()) + "; then " + netgen_failed.what());
    }
  }
}

}  // namespace lumen::physics
