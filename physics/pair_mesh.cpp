// The volume between two closed surfaces tetrahedralised by gmsh or Netgen's nglib (physics/pair_mesh.hpp).
#include "physics/pair_mesh.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <chrono>
#include <exception>
#include <mutex>
#include <ostream>
#include <set>
#include <unordered_map>
#include <utility>
#include <sstream>
#include <vector>

#include "physics/detail/messages.hpp"
#include "physics/mesh_quality.hpp"
#include "physics/volume_mesh.hpp"

#include <gmsh.h>

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
// gmsh's element type numbers (its documentation's table) and its HXT volume algorithm (Mesh.Algorithm3D).
constexpr int kGmshTriangle = 2;
constexpr int kGmshTet = 4;
constexpr int kGmshHxt = 10;

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

[[noreturn]] void not_kept(PairMesher mesher, const std::string& what) {
  throw PairMesherError(std::string(mesher == PairMesher::kGmsh ? "gmsh" : "Netgen") +
                        " did not keep the input surface: " + what);
}

// Refuses Netgen's tets unless their boundary faces are exactly the input triangles (as sets of node ids).
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
  throw PairMesherError(std::string(mesher == PairMesher::kGmsh ? "gmsh" : "Netgen") + " failed: " + what);
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

// gmsh keeps global state too: one initialisation (no configuration files, nothing on the terminal), one model at a
// time, its log collected meanwhile and removed on every path.
class GmshSession {
 public:
  GmshSession() : lock_(gmsh_mutex()) {
    static std::once_flag once;
    std::call_once(once, [] {
      gmsh::initialize(0, nullptr, false);
      gmsh::option::setNumber("General.Terminal", 0);
    });
    gmsh::logger::start();
    gmsh::model::add("lumen_pair");
  }
  ~GmshSession() {
    try {
      gmsh::model::remove();
      gmsh::logger::stop();
    } catch (...) {  // nothing to add to the failure being reported
    }
  }
  GmshSession(const GmshSession&) = delete;
  GmshSession& operator=(const GmshSession&) = delete;
  // Its last error, or the last lines of its log.
  static std::string said() {
    std::string error;
    gmsh::logger::getLastError(error);
    if (!error.empty()) return error;
    std::vector<std::string> log;
    gmsh::logger::get(log);
    std::string joined;
    for (const std::string& line : log) joined += line + "\n";
    return "its log ends: " + last_lines(joined, kLogLinesInMessage);
  }

 private:
  static std::mutex& gmsh_mutex() {
    static std::mutex m;
    return m;
  }
  std::lock_guard<std::mutex> lock_;
};

// gmsh's HXT on the two surfaces as discrete entities (their triangles kept), one thread (the same mesh every run),
// then its tet optimiser. No maximum size (kGmshMaxEdgeRefused).
RawMesh run_gmsh(const PairInput& in, int steps) {
  GmshSession session;
  std::vector<std::size_t> tets, node_tags;
  std::vector<double> coords, parametric;
  try {
    // Input: each surface a discrete entity with its vertices (tags 1-based, in x's order) and triangles; the
    // volume between them.
    const size_t nv = static_cast<size_t>(in.x.rows()), ni = static_cast<size_t>(in.inner_vertices);
    auto add_surface = [&](size_t v0, size_t v1, size_t f0, size_t f1) {
      const int entity = gmsh::model::addDiscreteEntity(2);
      std::vector<std::size_t> tags;
      std::vector<double> xyz;
      for (size_t v = v0; v < v1; ++v) {
        tags.push_back(v + 1);
        for (int c = 0; c < 3; ++c) xyz.push_back(in.x(static_cast<Eigen::Index>(v), c));
      }
      gmsh::model::mesh::addNodes(2, entity, tags, xyz);
      std::vector<std::size_t> tri;
      for (size_t f = f0; f < f1; ++f)
        for (int k = 0; k < 3; ++k) tri.push_back(static_cast<std::size_t>(in.faces[f][static_cast<size_t>(k)]) + 1);
      gmsh::model::mesh::addElementsByType(entity, kGmshTriangle, {}, tri);
      return gmsh::model::geo::addSurfaceLoop({entity});
    };
    const int inner_loop = add_surface(0, ni, 0, in.inner_faces);
    const int outer_loop = add_surface(ni, nv, in.inner_faces, in.faces.size());
    gmsh::model::geo::addVolume({outer_loop, inner_loop});
    gmsh::model::geo::synchronize();
    gmsh::option::setNumber("Mesh.Algorithm3D", kGmshHxt);
    gmsh::option::setNumber("Mesh.Optimize", steps > 0 ? 1 : 0);
    gmsh::option::setNumber("General.NumThreads", 1);
    gmsh::option::setNumber("Mesh.MaxNumThreads3D", 1);
    gmsh::model::mesh::generate(3);
    if (steps > 1) gmsh::model::mesh::optimize("", false, steps - 1);
    std::vector<std::size_t> element_tags;
    gmsh::model::mesh::getElementsByType(kGmshTet, element_tags, tets);
    gmsh::model::mesh::getNodes(node_tags, coords, parametric, -1, -1, false, false);
  } catch (const std::exception& e) {
    mesher_failed(PairMesher::kGmsh, std::string(e.what()) + " (" + GmshSession::said() + ")");
  } catch (...) {
    mesher_failed(PairMesher::kGmsh, GmshSession::said());
  }
  if (tets.empty()) mesher_failed(PairMesher::kGmsh, "no tets (" + GmshSession::said() + ")");
  // The nodes by tag: the input vertices keep theirs (1..#vertices), the added ones follow in tag order.
  const size_t nv = static_cast<size_t>(in.x.rows());
  std::vector<std::pair<std::size_t, size_t>> added;  // (tag, position in coords)
  std::vector<long> index_of_input(nv + 1, -1);
  for (size_t k = 0; k < node_tags.size(); ++k) {
    if (node_tags[k] >= 1 && node_tags[k] <= nv)
      index_of_input[node_tags[k]] = static_cast<long>(k);
    else
      added.push_back({node_tags[k], k});
  }
  std::sort(added.begin(), added.end());
  RawMesh out{Points(static_cast<Eigen::Index>(nv + added.size()), 3), Tets(static_cast<Eigen::Index>(tets.size() / 4), 4)};
  std::unordered_map<std::size_t, int> node_of_tag;
  for (size_t v = 0; v < nv; ++v) {
    if (index_of_input[v + 1] < 0) not_kept(PairMesher::kGmsh, "input vertex " + std::to_string(v) + " is missing");
    for (int c = 0; c < 3; ++c) out.nodes(static_cast<Eigen::Index>(v), c) = coords[3 * index_of_input[v + 1] + c];
    node_of_tag[v + 1] = static_cast<int>(v);
  }
  for (size_t a = 0; a < added.size(); ++a) {
    const Eigen::Index row = static_cast<Eigen::Index>(nv + a);
    for (int c = 0; c < 3; ++c) out.nodes(row, c) = coords[3 * added[a].second + c];
    node_of_tag[added[a].first] = static_cast<int>(row);
  }
  for (Eigen::Index e = 0; e < out.tets.rows(); ++e)
    for (int k = 0; k < 4; ++k) {
      const auto it = node_of_tag.find(tets[static_cast<size_t>(4 * e + k)]);
      if (it == node_of_tag.end()) mesher_failed(PairMesher::kGmsh, "tet " + std::to_string(e) + " names an unknown node");
      out.tets(e, k) = it->second;
    }
  return out;
}

}  // namespace

const char* pair_mesher_name(PairMesher mesher) {
  return mesher == PairMesher::kGmsh ? kGmshMesherName : kNetgenMesherName;
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
  const PairMesher mesher = options.mesher;
  const int steps = options.optimise_steps >= 0
                        ? options.optimise_steps
                        : (mesher == PairMesher::kGmsh ? kGmshOptimiseSteps : kNetgenOptimiseSteps);
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
  PairMesh out;
  const auto t0 = Clock::now();
  RawMesh raw = mesher == PairMesher::kGmsh ? run_gmsh(in, steps)
                                            : run_netgen(in, options.max_edge * scale, steps);
  const Eigen::Index np = raw.nodes.rows();
  if (np < ni + no)
    not_kept(mesher, "it returned " + std::to_string(np) + " points for " + std::to_string(ni + no) +
                         " input vertices");
  // The nodes: the input vertices exactly where they were (checked), the added ones mapped back.
  out.mesh.rest.resize(np, 3);
  out.mesh.rest.topRows(ni + no) = x;
  for (Eigen::Index v = 0; v < np; ++v) {
    if (v >= ni + no)
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
  out.added_nodes = static_cast<int>(np) - ni - no;
  Tris in_tris = inner_tris;
  in_tris.col(1).swap(in_tris.col(2));
  out.mesh.surfaces = {{kInnerWall, in_tris}, {kOuterWall, outer_tris.array() + ni}, {kEndCaps, Tris(0, 3)}};
  return out;
}

}  // namespace lumen::physics
