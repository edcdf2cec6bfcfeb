// lumen_bench_meshers: the surface-pair meshers measured on the same pair (docs/bench_meshers.csv): gmsh's HXT and
// Netgen's nglib as Lumen calls them at load (physics/pair_mesh.hpp) and TetGen's command-line program (Debian's
// tetgen), each run
// `repeats` times (the median time kept), their tets measured by Lumen's own quality measure, volume and boundary.
//   lumen_bench_meshers NAME INNER OUTER UNITS MAX_EDGE MESHER:PASSES[,...] REPEATS [TETGEN_SWITCHES...]  (CSV rows on stdout)
// UNITS: "mm" or "m" (the files'); MAX_EDGE in those units, 0 for none (the meshers' maxh; TetGen gets none);
// MESHER:PASSES: a comma-separated list of a mesher (gmsh, netgen) and its optimisation passes (one row each, e.g.
// gmsh:1,netgen:3); each
// TETGEN_SWITCHES (e.g. pYQ, pYQq1.414) is one TetGen run. TetGen's time is its whole process (starting, reading the
// .smesh written beforehand, meshing, writing its .node and .ele files).
#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "engine/clock.hpp"
#include "engine/surface_file.hpp"
#include "engine/surface_pair.hpp"
#include "physics/mesh_quality.hpp"
#include "physics/pair_mesh.hpp"
#include "physics/volume_mesh.hpp"

namespace fs = std::filesystem;
using lumen::engine::SurfaceMesh;

namespace {

using lumen::engine::Clock;
using lumen::engine::ms_since;
using Face = std::array<int, 3>;
constexpr int kFixedArguments = 8;
constexpr double kMillimetre = 1e-3;
// A hole point for TetGen (inside the lumen) is this fraction of the way from an inner triangle's centroid to the
// inner surface straight behind it.
constexpr double kHoleFraction = 0.5;
constexpr int kMedian = 2;

// Distance along unit d from p to the first triangle of s it meets (skipping triangle `skip`), or -1.
double ray_hit(const SurfaceMesh& s, const Eigen::Vector3d& p, const Eigen::Vector3d& d, int skip) {
  double best = -1.0;
  for (int t = 0; t < s.tris.rows(); ++t) {
    if (t == skip) continue;
    const Eigen::Vector3d a = s.points.row(s.tris(t, 0)), b = s.points.row(s.tris(t, 1)), c = s.points.row(s.tris(t, 2));
    const Eigen::Vector3d e1 = b - a, e2 = c - a, h = d.cross(e2);
    const double det = e1.dot(h);
    if (det == 0.0) continue;
    const Eigen::Vector3d q = p - a;
    const double u = q.dot(h) / det;
    const Eigen::Vector3d r = q.cross(e1);
    const double v = d.dot(r) / det, dist = e2.dot(r) / det;
    if (u >= 0 && v >= 0 && u + v <= 1 && dist > 0 && (best < 0 || dist < best)) best = dist;
  }
  return best;
}

// A point inside the inner surface (in the lumen): behind some triangle's centroid, with winding number 1.
Eigen::Vector3d lumen_point(const SurfaceMesh& in) {
  for (int t = 0; t < in.tris.rows(); ++t) {
    const Eigen::Vector3d a = in.points.row(in.tris(t, 0)), b = in.points.row(in.tris(t, 1)), c = in.points.row(in.tris(t, 2));
    const Eigen::Vector3d centroid = (a + b + c) / 3.0, inward = -(b - a).cross(c - a).normalized();
    const double gap = ray_hit(in, centroid, inward, t);
    if (gap <= 0) continue;
    const Eigen::Vector3d p = centroid + kHoleFraction * gap * inward;
    if (lumen::engine::winding_number(in, p) > lumen::engine::kInsideWindingNumber) return p;
  }
  throw std::runtime_error("no point inside the inner surface found");
}

// The measured facts of one run.
struct Row {
  std::string mesher, options;
  double ms = 0.0;
  lumen::physics::TetMesh mesh;
  int input_vertices = 0;
};

// Whether the tets' boundary faces are exactly the input triangles (by node ids; inputs are nodes 0..n-1).
bool keeps_surface(const lumen::Tets& tets, const std::vector<Face>& input) {
  const lumen::Tris b = lumen::physics::boundary_faces(tets);
  std::set<Face> in, out;
  for (Face f : input) {
    std::sort(f.begin(), f.end());
    in.insert(f);
  }
  for (Eigen::Index t = 0; t < b.rows(); ++t) {
    Face f = {b(t, 0), b(t, 1), b(t, 2)};
    std::sort(f.begin(), f.end());
    out.insert(f);
  }
  return in == out;
}

// TetGen on the pair (in file units): writes pair.smesh (both surfaces as facets, a hole in the lumen), runs it.
Row tetgen(const fs::path& dir, const SurfaceMesh& in, const SurfaceMesh& out, double unit, const std::string& sw) {
  const Eigen::Index ni = in.points.rows(), no = out.points.rows();
  {
    std::ofstream f(dir / "pair.smesh");
    f.precision(17);
    f << ni + no << " 3 0 0\n";
    for (Eigen::Index v = 0; v < ni + no; ++v) {
      const Eigen::RowVector3d p = (v < ni ? in.points.row(v) : out.points.row(v - ni)) / unit;
      f << v << " " << p(0) << " " << p(1) << " " << p(2) << "\n";
    }
    f << in.tris.rows() + out.tris.rows() << " 0\n";
    for (Eigen::Index t = 0; t < in.tris.rows(); ++t) f << "3 " << in.tris(t, 0) << " " << in.tris(t, 1) << " " << in.tris(t, 2) << "\n";
    for (Eigen::Index t = 0; t < out.tris.rows(); ++t)
      f << "3 " << ni + out.tris(t, 0) << " " << ni + out.tris(t, 1) << " " << ni + out.tris(t, 2) << "\n";
    const Eigen::Vector3d hole = lumen_point(in) / unit;
    f << "1\n0 " << hole(0) << " " << hole(1) << " " << hole(2) << "\n0\n";
  }
  fs::remove(dir / "pair.1.node");
  const std::string cmd = "cd " + dir.string() + " && tetgen -" + sw + " pair.smesh > tetgen.log 2>&1";
  Row r{"tetgen 1.5.0 (command line)", "-" + sw, 0.0, {}, static_cast<int>(ni + no)};
  const auto t0 = Clock::now();
  const int status = std::system(cmd.c_str());
  r.ms = ms_since(t0);
  if (status != 0) throw std::runtime_error("tetgen -" + sw + " failed (see " + (dir / "tetgen.log").string() + ")");
  std::ifstream nodes(dir / "pair.1.node"), eles(dir / "pair.1.ele");
  int n = 0, dim = 0, attr = 0, mark = 0;
  nodes >> n >> dim >> attr >> mark;
  r.mesh.rest.resize(n, 3);
  for (int v = 0; v < n; ++v) {
    int id;
    double x, y, z;
    nodes >> id >> x >> y >> z;
    for (int k = 0; k < attr + mark; ++k) nodes >> x;  // unused columns (never present with these switches)
    r.mesh.rest.row(id) << x, y, z;
  }
  // The input vertices exactly as given (TetGen's text round-trips them to 17 digits); the rest scaled.
  r.mesh.rest *= unit;
  for (Eigen::Index v = 0; v < ni + no; ++v) r.mesh.rest.row(v) = v < ni ? in.points.row(v) : out.points.row(v - ni);
  int m = 0, per = 0;
  eles >> m >> per >> attr;
  r.mesh.tets.resize(m, 4);
  for (int e = 0; e < m; ++e) {
    int id;
    eles >> id;
    for (int k = 0; k < 4; ++k) eles >> r.mesh.tets(e, k);
    if (lumen::physics::tet_volume(r.mesh.rest, r.mesh.tets, e) < 0) std::swap(r.mesh.tets(e, 0), r.mesh.tets(e, 1));
  }
  return r;
}

void print_row(const std::string& name, const Row& r, const std::vector<Face>& input, double volume_between) {
  const lumen::physics::MeshQuality q = lumen::physics::mesh_quality(r.mesh.rest, r.mesh.tets);
  double volume = 0.0;
  for (int t = 0; t < r.mesh.tets.rows(); ++t) volume += lumen::physics::tet_volume(r.mesh.rest, r.mesh.tets, t);
  std::printf("%s,%s,%s,%.1f,%ld,%ld,%ld,%.2f,%.2f,%.2f,%.4f,%.4f,%.4f,%d,%.2e,%s\n", name.c_str(), r.mesher.c_str(),
              r.options.c_str(), r.ms, static_cast<long>(r.mesh.tets.rows()), static_cast<long>(r.mesh.rest.rows()),
              static_cast<long>(r.mesh.rest.rows() - r.input_vertices), q.min_dihedral_deg.min, q.min_dihedral_deg.p1,
              q.min_dihedral_deg.p50, q.radius_ratio.min, q.radius_ratio.p1, q.radius_ratio.p50, q.degenerate_tets,
              std::abs(volume - volume_between) / volume_between, keeps_surface(r.mesh.tets, input) ? "yes" : "no");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < kFixedArguments) {
    std::fprintf(stderr, "usage: lumen_bench_meshers NAME INNER OUTER UNITS MAX_EDGE MESHER:PASSES[,...] REPEATS [TETGEN_SWITCHES...]\n");
    return 2;
  }
  try {
    const std::string name = argv[1], units = argv[4];
    const double unit = units == "mm" ? kMillimetre : 1.0, max_edge = std::atof(argv[5]) * unit;
    const int repeats = std::max(1, std::atoi(argv[7]));
    // Both surfaces as Lumen reads and checks them at load.
    lumen::engine::SurfacePairSpec spec{argv[2], argv[3], unit, {}};
    spec.options.max_edge = max_edge;
    const SurfaceMesh in = lumen::engine::read_closed_surface(spec.inner_file, unit);
    const SurfaceMesh out = lumen::engine::read_closed_surface(spec.outer_file, unit);
    const double between = lumen::engine::enclosed_volume(out) - lumen::engine::enclosed_volume(in);
    std::vector<Face> input;
    for (Eigen::Index t = 0; t < in.tris.rows(); ++t) input.push_back({in.tris(t, 0), in.tris(t, 1), in.tris(t, 2)});
    for (Eigen::Index t = 0; t < out.tris.rows(); ++t)
      input.push_back({static_cast<int>(in.points.rows()) + out.tris(t, 0), static_cast<int>(in.points.rows()) + out.tris(t, 1),
                       static_cast<int>(in.points.rows()) + out.tris(t, 2)});
    auto median = [&](std::vector<Row>& rs) {
      std::sort(rs.begin(), rs.end(), [](const Row& a, const Row& b) { return a.ms < b.ms; });
      return rs[rs.size() / kMedian];
    };
    // gmsh and Netgen, as at load (their own time, the checks before them excluded), each MESHER:PASSES.
    std::istringstream runs_wanted(argv[6]);
    for (std::string s; std::getline(runs_wanted, s, ',');) {
      const size_t colon = s.find(':');
      const std::string mesher = s.substr(0, colon);
      if (colon == std::string::npos || (mesher != "gmsh" && mesher != "netgen"))
        throw std::runtime_error("STEPS entry '" + s + "': want gmsh:N or netgen:N");
      spec.options.mesher = mesher == "gmsh" ? lumen::physics::PairMesher::kGmsh : lumen::physics::PairMesher::kNetgen;
      spec.options.optimise_steps = std::atoi(s.c_str() + colon + 1);
      std::vector<Row> runs;
      for (int k = 0; k < repeats; ++k) {
        lumen::engine::SurfacePair p = lumen::engine::mesh_surface_pair(spec);
        runs.push_back({lumen::physics::pair_mesher_name(spec.options.mesher),
                        (mesher == "gmsh" ? "optimise " : "optsteps_3d ") + s.substr(colon + 1) +
                            (max_edge > 0 ? " maxh " + std::string(argv[5]) + " " + units : ""),
                        p.mesher_ms, std::move(p.mesh), static_cast<int>(in.points.rows() + out.points.rows())});
      }
      print_row(name, median(runs), input, between);
    }
    // TetGen, each switch set.
    const fs::path dir = fs::temp_directory_path() / "lumen_bench_meshers";
    fs::create_directories(dir);
    for (int a = kFixedArguments; a < argc; ++a) {
      std::vector<Row> tg;
      for (int k = 0; k < repeats; ++k) tg.push_back(tetgen(dir, in, out, unit, argv[a]));
      print_row(name, median(tg), input, between);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lumen_bench_meshers: error: %s\n", e.what());
    return 2;
  }
  return 0;
}
