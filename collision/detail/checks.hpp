#pragma once
// Input checks shared by the collision sources (internal: not part of the public interface).
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include "collision/surface.hpp"

namespace lumen::collision::detail {

// Throws std::invalid_argument unless x is n x 3 and finite (`name` names the parameter).
inline void check_points(const PointsRef& x, int n, const char* name) {
  if (x.rows() != n)
    throw std::invalid_argument(std::string(name) + " has " + std::to_string(x.rows()) +
                                " rows, expected n_points = " + std::to_string(n));
  for (int i = 0; i < n; ++i)
    for (int d = 0; d < 3; ++d)
      if (!std::isfinite(x(i, d))) {
        std::ostringstream msg;
        msg << name << "(" << i << ", " << d << ") must be finite, got " << x(i, d);
        throw std::invalid_argument(msg.str());
      }
}

// Throws std::invalid_argument "<rule>, got <gap>" unless the gap (metres) is finite and >= 0.
inline void check_gap(double gap, const char* rule = "gap must be finite and >= 0 metres") {
  if (!(gap >= 0.0) || !std::isfinite(gap)) {
    std::ostringstream msg;
    msg << rule << ", got " << gap;
    throw std::invalid_argument(msg.str());
  }
}

}  // namespace lumen::collision::detail
