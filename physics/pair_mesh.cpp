// The volume between two closed surfaces tetrahedralised by Netgen's nglib (physics/pair_mesh.hpp).
#include "physics/pair_mesh.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <chrono>
#include <exception>
#include <mutex>
#include <ostream>
#include <set>
#include <sstream>
#include <vector>

#include "physics/detail/messages.hpp"
#include "physics/mesh_quality.hpp"
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

// The last lines of Netgen's log kept in a failure message.
constexpr int kLogLinesInMessage = 2;
// Netgen's input vertices must come back within this distance (in its frame) of where they went in.
constexpr double kMovedVertexTolerance = 1e-9 * kPairMesherFrameDiagonal;

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

[[noreturn]] void not_kept(const std::string& what) {
  throw PairMesherError("Netgen did not keep the input surface: " + what);
}

// Refuses Netgen's tets unless their boundary faces are exactly the input triangles (as sets of node ids).
void require_kept_surface(const Tets& tets, const std::vector<Face>& input) {
  const Tris boundary = boundary_faces(tets);
  std::set<Face> in;
  for (const Face& f : input) in.insert(sorted(f));
  std::set<Face> out;
  for (Eigen::Index t = 0; t < boundary.rows(); ++t) {
    const Face f = sorted({boundary(t, 0), boundary(t, 1), boundary(t, 2)});
    if (!in.count(f))
      not_kept("boundary face (nodes " + std::to_string(f[0]) + ", " + std::to_string(f[1]) + ", " +
               std::to_string(f[2]) + ") of its tets is not an input triangle");
    out.insert(f);
  }
  for (const Face& f : in)
    if (!out.count(f))
      not_kept("input triangle (nodes " + std::to_string(f[0]) + ", " + std::to_string(f[1]) + ", " +
               std::to_string(f[2]) + ") is not a boundary face of its tets");
}

}  // namespace

PairMesh tetrahedralise_pair(const Points& inner, const Tris& inner_tris, const Points& outer, const Tris& outer_tris,
                             const PairMeshSize& size) {
  const int ni = static_cast<int>(inner.rows()), no = static_cast<int>(outer.rows());
  // An empty surface would reach Netgen with nothing to mesh (it crashed there, measured with both empty).
  if (inner_tris.rows() == 0 || outer_tris.rows() == 0)
    detail::fail("tetrahedralise_pair: the " + std::string(inner_tris.rows() == 0 ? "inner" : "outer") +
                 " surface has no triangles");
  if (inner_tris.minCoeff() < 0 || inner_tris.maxCoeff() >= ni || outer_tris.minCoeff() < 0 ||
      outer_tris.maxCoeff() >= no)
    detail::fail("tetrahedralise_pair: a triangle names a vertex outside its surface");
  assert(size.max_edge >= 0.0 && size.optimise_steps >= 0 && size.optimise_steps <= kPairMesherMaxOptimiseSteps);
  // Both surfaces as one point array (inner, then outer) and their triangles facing out of the volume.
  Points x(ni + no, 3);
  x << inner, outer;
  std::vector<Face> faces;
  for (Eigen::Index t = 0; t < inner_tris.rows(); ++t)
    faces.push_back({inner_tris(t, 0), inner_tris(t, 2), inner_tris(t, 1)});
  for (Eigen::Index t = 0; t < outer_tris.rows(); ++t)
    faces.push_back({ni + outer_tris(t, 0), ni + outer_tris(t, 1), ni + outer_tris(t, 2)});
  // Netgen's frame: centred on the bounding box, scaled to kPairMesherFrameDiagonal.
  const Eigen::RowVector3d lo = x.colwise().minCoeff(), hi = x.colwise().maxCoeff();
  const Eigen::RowVector3d centre = 0.5 * (lo + hi);
  const double scale = kPairMesherFrameDiagonal / (hi - lo).norm();
  PairMesh out;
  const auto t0 = Clock::now();
  NetgenSession ng;
  // Input: the points (1-based in Netgen), the triangles with normals out of the volume (Netgen's convention).
  for (int v = 0; v < ni + no; ++v) {
    Eigen::RowVector3d p = (x.row(v) - centre) * scale;
    nglib::Ng_AddPoint(ng.mesh(), p.data());
  }
  for (const Face& f : faces) {
    int v[3] = {f[0] + 1, f[1] + 1, f[2] + 1};
    nglib::Ng_AddSurfaceElement(ng.mesh(), nglib::NG_TRIG, v);
  }
  nglib::Ng_Meshing_Parameters mp;
  // nglib's volume mesher takes its size from its local size tree: maxh alone, or its global h, leave it unchanged
  // (measured), so the size is restricted over the whole bounding box.
  if (size.max_edge > 0.0) {
    mp.maxh = size.max_edge * scale;
    Eigen::RowVector3d box_lo = (lo - centre) * scale, box_hi = (hi - centre) * scale;
    nglib::Ng_RestrictMeshSizeBox(ng.mesh(), box_lo.data(), box_hi.data(), mp.maxh);
  }
  mp.optsteps_3d = size.optimise_steps;
  nglib::Ng_Result result = nglib::NG_ERROR;
  try {
    result = nglib::Ng_GenerateVolumeMesh(ng.mesh(), &mp);
  } catch (const std::exception& e) {
    throw PairMesherError(std::string("Netgen failed: ") + e.what());
  } catch (...) {
    throw PairMesherError("Netgen failed: it threw an exception of an unknown type (its log ends: " +
                          last_lines(ng.log(), kLogLinesInMessage) + ")");
  }
  const int np = nglib::Ng_GetNP(ng.mesh()), ne = nglib::Ng_GetNE(ng.mesh());
  if (result != nglib::NG_OK || ne == 0)
    throw PairMesherError("Netgen failed: " + result_name(result) + " with " + std::to_string(ne) +
                          " tets (its log ends: " + last_lines(ng.log(), kLogLinesInMessage) + ")");
  if (np < ni + no)
    not_kept("it returned " + std::to_string(np) + " points for " + std::to_string(ni + no) + " input vertices");
  // The nodes: the input vertices exactly where they were (checked), Netgen's added ones mapped back.
  out.mesh.rest.resize(np, 3);
  out.mesh.rest.topRows(ni + no) = x;
  for (int v = 0; v < np; ++v) {
    Eigen::RowVector3d p;
    nglib::Ng_GetPoint(ng.mesh(), v + 1, p.data());
    if (v >= ni + no) {
      out.mesh.rest.row(v) = p / scale + centre;
    } else if (!((p - (x.row(v) - centre) * scale).norm() <= kMovedVertexTolerance)) {
      not_kept("input vertex " + std::to_string(v) + " moved");
    }
  }
  // The tets, each made positive (Netgen's are negative in Lumen's convention).
  out.mesh.tets.resize(ne, 4);
  for (int e = 0; e < ne; ++e) {
    int v[10];
    if (nglib::Ng_GetVolumeElement(ng.mesh(), e + 1, v) != nglib::NG_TET)
      throw PairMesherError("Netgen failed: element " + std::to_string(e) + " is not a tetrahedron");
    for (int k = 0; k < 4; ++k) out.mesh.tets(e, k) = v[k] - 1;
    if (tet_volume(out.mesh.rest, out.mesh.tets, e) < 0.0) std::swap(out.mesh.tets(e, 0), out.mesh.tets(e, 1));
  }
  out.mesher_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  // Its result checked: no inverted or flat tet, the boundary exactly the input triangles.
  const MeshQuality q = mesh_quality(out.mesh.rest, out.mesh.tets);
  if (q.first_degenerate >= 0)
    not_kept("tet " + std::to_string(q.first_degenerate) + " is inverted or has zero volume (" +
             std::to_string(q.degenerate_tets) + " such tets)");
  require_kept_surface(out.mesh.tets, faces);
  // The walls: the inner triangles reversed (facing the lumen, out of the volume), the outer ones as given.
  out.added_nodes = np - ni - no;
  Tris in_tris = inner_tris;
  in_tris.col(1).swap(in_tris.col(2));
  out.mesh.surfaces = {{kInnerWall, in_tris}, {kOuterWall, outer_tris.array() + ni}, {kEndCaps, Tris(0, 3)}};
  return out;
}

}  // namespace lumen::physics
