#include "engine/mesh_check.hpp"

#include <cstdio>
#include <sstream>
#include <string>

#include "engine/scene.hpp"
#include "engine/simulation.hpp"
#include "physics/pair_mesh.hpp"

namespace lumen::engine {

namespace {

nlohmann::json percentiles_json(const physics::QualityPercentiles& p) {
  return {{"min", p.min}, {"p1", p.p1}, {"p50", p.p50}};
}

// Milliseconds to one decimal, for the mesh line.
std::string one_decimal(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f", v);
  return text;
}

// A length to three significant digits, for the mesh line.
std::string three_digits(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", v);
  return text;
}

}  // namespace

void require_valid_tets(const physics::TetMesh& mesh, const std::string& file) {
  const physics::MeshQuality q = physics::mesh_quality(mesh.rest, mesh.tets);
  if (q.first_degenerate < 0) return;
  std::ostringstream msg;
  msg << file << ": mesh: tet " << q.first_degenerate << " (of " << q.tets
      << ") is inverted or has zero volume (signed volume "
      << physics::tet_volume(mesh.rest, mesh.tets, q.first_degenerate) << " m^3); " << q.degenerate_tets
      << " such tets";
  throw InputError(msg.str());
}

nlohmann::json mesh_quality_json(const physics::MeshQuality& q) {
  return {{"quality_tets", q.tets},
          {"min_dihedral_deg", percentiles_json(q.min_dihedral_deg)},
          {"radius_ratio", percentiles_json(q.radius_ratio)},
          {"degenerate_tets", q.degenerate_tets}};
}

std::string mesh_quality_line(const Model& model, const physics::MeshQuality& q) {
  // A tet10 model's quality is measured on the linear tets its elements split into (the mesh the state holds).
  const std::string measured =
      q.tets == model.n_elements ? std::string() : " (quality over their " + std::to_string(q.tets) + " linear sub-tets)";
  // A swept tube also says how many of its rings the bend clamp reduced (and the surface its radius came from); a
  // volume mesh or a surface wall names its file, a surface wall how many vertices' offsets were clamped and how
  // many of its surface's vertices were moved to untangle fold-overs, a surface pair names both files and its mesher's
  // time and added nodes.
  const std::string from = model.mesh_file.empty() ? std::string() : " from " + model.mesh_file;
  // A surface wall or pair remeshed to a target edge says from how many of its files' triangles, and in how long.
  const std::string remeshed =
      model.remesh_target_edge > 0.0
          ? ", " + std::to_string(model.remesh_file_triangles) + " file triangles remeshed to a target edge of " +
                three_digits(1e3 * model.remesh_target_edge) + " mm in " + one_decimal(model.remesh_ms) + " ms"
          : std::string();
  const std::string suffix =
      model.mesh_type == MeshType::kSweptTube
          ? ", " + std::to_string(model.clamped_rings) + " rings clamped at bends" +
                (from.empty() ? std::string() : ", radius sampled" + from)
      : model.mesh_type == MeshType::kSurfaceWall
          ? from + ", " + std::to_string(model.clamped_vertices) + " vertices' offsets clamped below the thickness, " +
                std::to_string(model.untangled_vertices) + " vertices moved to untangle fold-overs" + remeshed
      : model.mesh_type == MeshType::kSurfacePair
          ? from + " and " + model.mesh_outer_file + ", tetrahedralised by " +
                physics::pair_mesher_name(model.pair_mesher) + " in " + one_decimal(model.mesher_ms) + " ms (" +
                std::to_string(model.mesher_added_nodes) +
                " nodes added inside the wall" +
                (model.gmsh_failure.empty() ? std::string() : "; first " + model.gmsh_failure) + ")" + remeshed
          : from;
  char line[400];
  std::snprintf(line, sizeof line,
                "mesh: %d nodes, %d tets%s, %ld inner + %ld outer wall triangles; min dihedral angle %.1f deg (p1 %.1f, "
                "median %.1f), radius ratio %.3f (p1 %.3f, median %.3f), %d inverted or zero-volume tets; %s built in "
                "%.1f ms",
                model.mesh.n_nodes(), model.n_elements, measured.c_str(), static_cast<long>(model.inner_wall().rows()),
                static_cast<long>(model.outer_wall().rows()), q.min_dihedral_deg.min, q.min_dihedral_deg.p1,
                q.min_dihedral_deg.p50, q.radius_ratio.min, q.radius_ratio.p1, q.radius_ratio.p50, q.degenerate_tets,
                name_of(model.mesh_type), model.mesh_build_ms);
  return line + suffix;
}

}  // namespace lumen::engine
