// The 4-node corotational element's stress kernel on several tets at once (physics/detail/element_lanes.hpp).
#include "physics/detail/element_lanes.hpp"

#include "physics/detail/target_clones.hpp"

namespace lumen::physics::detail {

LUMEN_TARGET_CLONES void gradient_lanes(const ElementLanes& e, bool deformation, double (&x)[9][kElementLanes]) {
  const double with_identity = deformation ? 1.0 : 0.0;
#pragma omp simd
  for (int l = 0; l < kElementLanes; ++l)
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r)
        x[3 * c + r][l] = (r == c ? with_identity : 0.0) + e.D[r][l] * e.G[3 * c][l] +
                          e.D[3 + r][l] * e.G[3 * c + 1][l] + e.D[6 + r][l] * e.G[3 * c + 2][l];
}

LUMEN_TARGET_CLONES void element_stress_lanes(ElementLanes& e, const double (&x)[9][kElementLanes], double lambda,
                                              double mu, bool deformation) {
  const double with_identity = deformation ? 1.0 : 0.0;
#pragma omp simd
  for (int l = 0; l < kElementLanes; ++l) {
    // H = R^T x.
    double H[9];
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i)
        H[3 * j + i] = e.R[3 * i][l] * x[3 * j][l] + e.R[3 * i + 1][l] * x[3 * j + 1][l] +
                       e.R[3 * i + 2][l] * x[3 * j + 2][l];
    // eps = sym(H) (- I), sigma, the energy V eps : sigma / 2.
    double eps[9];
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i) eps[3 * j + i] = 0.5 * (H[3 * j + i] + H[3 * i + j]);
    eps[0] -= with_identity, eps[4] -= with_identity, eps[8] -= with_identity;
    const double tr = eps[0] + eps[4] + eps[8];
    double sigma[9], work = 0.0;
    for (int k = 0; k < 9; ++k) {
      sigma[k] = 2.0 * mu * eps[k];
      work += eps[k] * sigma[k];
    }
    sigma[0] += lambda * tr, sigma[4] += lambda * tr, sigma[8] += lambda * tr;
    work += lambda * tr * tr;
    e.energy[l] = 0.5 * e.V[l] * work;
    // P = V (R sigma) G^T.
    double B[9];
    for (int j = 0; j < 3; ++j)
      for (int r = 0; r < 3; ++r)
        B[3 * j + r] = e.R[r][l] * sigma[3 * j] + e.R[3 + r][l] * sigma[3 * j + 1] + e.R[6 + r][l] * sigma[3 * j + 2];
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r)
        e.P[3 * c + r][l] =
            e.V[l] * (B[r] * e.G[c][l] + B[3 + r] * e.G[3 + c][l] + B[6 + r] * e.G[6 + c][l]);
  }
}

}  // namespace lumen::physics::detail
