// Test support: the tissue material and the small tubes the physics tests load.
#pragma once

#include <vector>

#include "physics/fem.hpp"
#include "physics/mesh.hpp"

namespace lumen::test {

inline const physics::LinearMaterial kTissue{5000.0, 0.45};  // the paper's: E 5 kPa, nu 0.45

// The spec of a small hollow cylinder (the default tube's radii): around x along x layers cells, length metres.
inline physics::HollowCylinderSpec small_tube_spec(int around = 8, int along = 4, int layers = 1, double length = 0.04) {
  physics::HollowCylinderSpec s;
  s.segments_around = around, s.segments_along = along, s.layers = layers, s.length = length;
  return s;
}
// Its tet4 mesh.
inline physics::TetMesh small_tube(int around = 8, int along = 4, int layers = 1, double length = 0.04) {
  return physics::make_hollow_cylinder(small_tube_spec(around, along, layers, length));
}

// The nodes of both ends of a tube.
inline std::vector<int> both_ends(const physics::TetMesh& m) {
  std::vector<int> f = m.node_set(physics::kStartEnd);
  f.insert(f.end(), m.node_set(physics::kStopEnd).begin(), m.node_set(physics::kStopEnd).end());
  return f;
}

}  // namespace lumen::test
