// The mesh check at load: an inverted or zero-volume tet is refused (InputError naming the file and the tet);
// the report's quality fields.
#include <gtest/gtest.h>

#include <string>

#include "engine/mesh_check.hpp"
#include "engine/scene.hpp"

namespace lumen::engine {
namespace {

// The message of the InputError require_valid_tets throws, or "" when it accepts the mesh.
std::string refusal(const physics::TetMesh& mesh) {
  try {
    require_valid_tets(mesh, "organ.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(MeshCheck, RefusesInvertedAndFlatTetsByIndex) {
  physics::TetMesh mesh = physics::make_hollow_cylinder(physics::HollowCylinderSpec{});
  EXPECT_EQ(refusal(mesh), "");
  // Tet 41 inverted (two corners swapped).
  physics::TetMesh inverted = mesh;
  inverted.tets.row(41).tail<2>().reverseInPlace();
  EXPECT_NE(refusal(inverted).find("organ.json: mesh: tet 41 (of 9360) is inverted or has zero volume"),
            std::string::npos)
      << refusal(inverted);
  // Tet 3 flat: its fourth corner the same node as its first (zero volume; no other tet changes).
  physics::TetMesh flat = mesh;
  flat.tets(3, 3) = flat.tets(3, 0);
  const std::string msg = refusal(flat);
  EXPECT_NE(msg.find("tet 3 (of 9360) is inverted or has zero volume (signed volume 0 m^3); 1 such tets"),
            std::string::npos)
      << msg;
}

TEST(MeshCheck, QualityJsonCarriesThePercentiles) {
  const physics::TetMesh mesh = physics::make_hollow_cylinder(physics::HollowCylinderSpec{});
  const nlohmann::json j = mesh_quality_json(physics::mesh_quality(mesh.rest, mesh.tets));
  EXPECT_EQ(j["quality_tets"], 9360);
  EXPECT_EQ(j["degenerate_tets"], 0);
  EXPECT_GT(j["min_dihedral_deg"]["min"].get<double>(), 0.0);
  EXPECT_LE(j["min_dihedral_deg"]["min"].get<double>(), j["min_dihedral_deg"]["p1"].get<double>());
  EXPECT_LE(j["radius_ratio"]["p1"].get<double>(), j["radius_ratio"]["p50"].get<double>());
  EXPECT_LE(j["radius_ratio"]["p50"].get<double>(), 1.0);
}

}  // namespace
}  // namespace lumen::engine
