#pragma once
// The volume mesh of every frame as VTK XML unstructured grids (ParaView): DIR/volume/volume_000001.vtu ... with
// point data displacement and contact and cell data von_mises, and the collection DIR/volume.pvd.
#include <string>
#include <utility>
#include <vector>

#include "engine/simulation.hpp"
#include "physics/fem.hpp"

namespace lumen::engine {

// VTK cell type of a linear tetrahedron. A tet10 model is exported as the 8 linear tets each element splits into
// (the mesh the state holds, physics::linear_view), so every cell is of this type.
inline constexpr int kVtkTetra = 10;

// Von Mises stress of every tet of the model's mesh at displacement u (3 n_nodes, metres), pascals, n_tets: from
// the element's small strain sym(H) (linear material), or its corotated strain sym(R^T F) - I with R the
// rotation of F = I + H (corotational material), and the isotropic stress of that strain.
Eigen::VectorXd tet_von_mises(const Model& model, const Eigen::VectorXd& u, const physics::LinearMaterial& material);

// One frame as VTK XML UnstructuredGrid (ASCII): points at the deformed positions state.x, point data
// displacement (x - rest, metres) and contact (1 for the nodes of this frame's active contacts,
// state.in_contact), cell data von_mises (pascals).
std::string volume_vtu(const Model& model, const State& state, const physics::LinearMaterial& material);

// The ParaView collection (.pvd) of (time in seconds, file relative to the .pvd) pairs, in frame order.
std::string volume_pvd(const std::vector<std::pair<double, std::string>>& frames);

}  // namespace lumen::engine
