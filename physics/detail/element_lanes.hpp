#pragma once
// The 4-node corotational element's stress kernel on several tets at once (the forces' and the warped product's
// loops): flat lanes, filled and scattered by the caller, computed in lockstep.

namespace lumen::physics::detail {

// Tets per batch. BM_CorotationalElasticForces / BM_CorotationalWarpedProduct on the paper mesh (9,360 tets): one tet
// at a time with Eigen 309 / 268 us; 4 lanes 214-227 / 212-225, 8 lanes 212 / 208-210, 16 lanes 207-210 / 205-210
// (the gathers and scatters of the nodes' values bound it); 16, the rotations' lanes, so that the evaluation at u
// (CorotationalElements::rotations_and_forces) runs both on one batch.
constexpr int kElementLanes = 16;

// One batch. Matrices are 3 x 3, entry c = 3 col + row (column-major) of lane l at [c][l].
struct ElementLanes {
  double R[9][kElementLanes];  // the tet's rotation
  double D[9][kElementLanes];  // edge displacements: column a = u_{a+1} - u_0, metres (or a direction's)
  double G[9][kElementLanes];  // Dm^-1: row a = grad N_{a+1}, 1/metres
  double V[kElementLanes];     // rest volume, cubic metres
  double P[9][kElementLanes];  // out: V R sigma G^T, newtons; column a is node a+1's force, minus their sum node 0's
  double energy[kElementLanes];  // out: V eps : sigma / 2, joules (with deformation only)
};

// Every lane's gradient D G into x (entries as the lanes', c = 3 col + row); deformation: F = I + D G, D the
// displacement edges.
void gradient_lanes(const ElementLanes& e, bool deformation, double (&x)[9][kElementLanes]);

// From x as gradient_lanes wrote it: the unrotated strain eps = sym(R^T x) (deformation: sym(R^T F) - I), the
// isotropic stress sigma = 2 mu eps + lambda tr(eps) I, and P and the energy from them, on every lane.
void element_stress_lanes(ElementLanes& e, const double (&x)[9][kElementLanes], double lambda, double mu,
                          bool deformation);

}  // namespace lumen::physics::detail
