#pragma once
// Proper rotations of deformation gradients (the corotational elements' per-tet and per-node rotations): one at a
// time, and many at once with Newton's polar iteration on several matrices in lockstep.
#include <algorithm>

#include <Eigen/Core>

namespace lumen::physics {

// Proper rotation of a deformation gradient F (3 x 3): the rotation of the polar decomposition F = R S when
// det F > 0; when det F <= 0 (inverted), R = U V^T from the SVD F = U Sigma V^T with the sign of the smallest
// singular value flipped so that det R = +1 (Irving et al. 2004). R^T F is then symmetric. Never NaN for finite F.
// inverted (optional) is set to det F <= 0. Throws std::invalid_argument when F is not finite.
Eigen::Matrix3d proper_rotation(const Eigen::Matrix3d& F, bool* inverted = nullptr);

namespace detail {

// Matrices per lockstep batch (BM_CorotationalRotations on the paper mesh, 9,360 tets: one at a time 739 us; 4
// lanes 400, 8 lanes 290, 16 lanes 244-260: four AVX2 registers a row, the iterations of a lane past its own
// convergence cheaper than the lost parallelism).
constexpr int kPolarLanes = 16;

// Newton's polar iteration of proper_rotation on kPolarLanes matrices at once: x[c][l] is entry c (column-major,
// c = 3 col + row) of lane l's matrix. The lanes step in lockstep, each frozen once its own step is below
// proper_rotation's tolerance. Returns the lanes it settled (bit l), x[.][l] then their rotations; the others
// (det <= proper_rotation's Newton threshold: inverted, nearly flat or not finite; or not converged) are left for
// proper_rotation, x[.][l] unspecified.
unsigned polar_newton_lanes(double (&x)[9][kPolarLanes]);

}  // namespace detail

// The rotations of a batch whose lanes x hold gradient(i0 + l) for l < m (identity past m): Newton's polar iteration on
// all lanes in lockstep, R[i0 + l] its rotation where it settled and proper_rotation(gradient(i0 + l)) where not.
// Returns how many were inverted (det <= 0).
template <class Gradient>
int rotations_of_lanes(double (&x)[9][detail::kPolarLanes], int i0, int m, const Gradient& gradient,
                       Eigen::Matrix3d* R) {
  int inverted = 0;
  const unsigned settled = detail::polar_newton_lanes(x);
  for (int l = 0; l < m; ++l) {
    if (settled >> l & 1u) {
      for (int c = 0; c < 9; ++c) R[i0 + l].data()[c] = x[c][l];
      continue;
    }
    bool flipped = false;
    R[i0 + l] = proper_rotation(gradient(i0 + l), &flipped);
    inverted += flipped ? 1 : 0;
  }
  return inverted;
}

// proper_rotation of gradient(i) for i in [0, n) into R[i] (n entries), kPolarLanes at a time in lockstep, and the
// lanes the lockstep iteration does not settle one by one. Returns how many were inverted (det <= 0). Equal to
// proper_rotation's to round-off; throws as it does on a gradient that is not finite.
template <class Gradient>
int proper_rotations(int n, const Gradient& gradient, Eigen::Matrix3d* R) {
  using detail::kPolarLanes;
  int inverted = 0;
  alignas(32) double x[9][kPolarLanes];
  for (int i0 = 0; i0 < n; i0 += kPolarLanes) {
    // The batch's gradients in lanes (identity past the end), then their rotations.
    const int m = std::min(kPolarLanes, n - i0);
    for (int l = 0; l < kPolarLanes; ++l) {
      const Eigen::Matrix3d F = l < m ? Eigen::Matrix3d(gradient(i0 + l)) : Eigen::Matrix3d::Identity();
      for (int c = 0; c < 9; ++c) x[c][l] = F.data()[c];
    }
    inverted += rotations_of_lanes(x, i0, m, gradient, R);
  }
  return inverted;
}

}  // namespace lumen::physics
