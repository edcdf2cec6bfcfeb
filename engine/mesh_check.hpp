#pragma once
// The volume mesh at load: inverted or zero-volume tets refused with their index, and its quality for the report
// and the terminal.
#include <string>

#include <nlohmann/json.hpp>

#include "physics/mesh.hpp"
#include "physics/mesh_quality.hpp"

namespace lumen::engine {

struct Model;

// Throws InputError "<file>: mesh: tet <i> (of <n>) is inverted or has zero volume (signed volume V m^3); <k>
// such tets" when the mesh has such a tet (physics::TetShape::degenerate), naming the first.
void require_valid_tets(const physics::TetMesh& mesh, const std::string& file);

// The quality fields report.json's `mesh` object carries (quality_tets, min_dihedral_deg, radius_ratio,
// degenerate_tets).
nlohmann::json mesh_quality_json(const physics::MeshQuality& q);
// One line for the terminal at `run` start: nodes, tets, wall triangles, angle and ratio percentiles.
std::string mesh_quality_line(const Model& model, const physics::MeshQuality& q);

}  // namespace lumen::engine
