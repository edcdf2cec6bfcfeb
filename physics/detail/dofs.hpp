#pragma once
// Norms over the free or the fixed DOFs of a mask, and the checks of a DOF vector (internal: shared by the
// nonlinear and dynamic solves).
#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "physics/detail/messages.hpp"

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

// Index of the first non-finite entry of v, or -1.
inline int first_non_finite(const Eigen::VectorXd& v) {
  for (Eigen::Index i = 0; i < v.size(); ++i)
    if (!std::isfinite(v[i])) return static_cast<int>(i);
  return -1;
}

// Checks a 3n vector: the given size and finite entries (std::invalid_argument naming `where` and `name`).
inline void check_vector(const char* where, const char* name, const Eigen::VectorXd& v, int n) {
  if (v.size() != n) fail_must(where, std::string(name) + ".size()", "be " + std::to_string(n), v.size());
  const int bad = first_non_finite(v);
  if (bad >= 0) fail_must(where, std::string(name) + "[" + std::to_string(bad) + "]", "be finite", v[bad]);
}

}  // namespace lumen::physics::detail
