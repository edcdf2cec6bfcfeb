#pragma once
// Norms over the free or the fixed DOFs of a mask (internal: shared by the nonlinear and dynamic solves).
#include <cmath>
#include <vector>

#include <Eigen/Core>

namespace lumen::physics::detail {

// |v| over the DOFs whose mask entry is `on_fixed` (1: the fixed DOFs, e.g. the support reactions; 0: the free).
inline double masked_norm(const Eigen::VectorXd& v, const std::vector<char>& fixed, bool on_fixed) {
  double s = 0.0;
  for (Eigen::Index i = 0; i < v.size(); ++i)
    if ((fixed[i] != 0) == on_fixed) s += v[i] * v[i];
  return std::sqrt(s);
}
inline double free_norm(const Eigen::VectorXd& v, const std::vector<char>& fixed) { return masked_norm(v, fixed, false); }
// The support reactions' size: |f_int| on the fixed DOFs, newtons.
inline double reaction_norm(const Eigen::VectorXd& f_int, const std::vector<char>& fixed) {
  return masked_norm(f_int, fixed, true);
}

}  // namespace lumen::physics::detail
