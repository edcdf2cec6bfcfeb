#pragma once
// Shape quality of a tetrahedral mesh: per-tet minimum dihedral angle and radius ratio, their low percentiles,
// and the tets that are inverted or degenerate (refused at load).
#include <Eigen/Core>

#include "physics/types.hpp"

namespace lumen::physics {

// A tet whose signed volume is at most this fraction of its longest edge cubed counts as degenerate (zero
// volume); a regular tet has V / l^3 = 1 / (6 sqrt 2) = 0.118.
inline constexpr double kDegenerateVolumeFraction = 1e-12;

// Shape of one tet.
struct TetShape {
  double volume = 0.0;             // signed, cubic metres (negative: inverted)
  double min_dihedral_deg = 0.0;   // smallest of its six dihedral angles, degrees (regular: acos(1/3) = 70.53)
  double radius_ratio = 0.0;       // 3 inradius / circumradius, 1 for the regular tet, 0 when degenerate
  bool degenerate = false;         // volume <= kDegenerateVolumeFraction * (longest edge)^3 (inverted or flat)
};
// The shape of a tet with vertices X (4 x 3, metres, rows in the mesh's order).
TetShape tet_shape(const Eigen::Matrix<double, 4, 3>& X);

// Low percentiles of a per-tet quality measure.
struct QualityPercentiles {
  double min = 0.0, p1 = 0.0, p50 = 0.0;
};

// The mesh's quality over all tets (positions x, n x 3, metres; tets n_tets x 4).
struct MeshQuality {
  int tets = 0;
  QualityPercentiles min_dihedral_deg;  // degrees
  QualityPercentiles radius_ratio;      // dimensionless
  int degenerate_tets = 0;              // inverted or zero-volume tets
  int first_degenerate = -1;            // index of the first of them, -1 when none
};
MeshQuality mesh_quality(const Points& x, const Tets& tets);

// Percentile q (0..100) of values sorted ascending, by linear interpolation between order statistics; 0 when
// empty.
double sorted_percentile(const Eigen::Ref<const Eigen::VectorXd>& sorted, double q);

}  // namespace lumen::physics
