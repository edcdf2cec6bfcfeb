// k-DOP choice validation (the k-DOP type and the BVH are templates in kdop.hpp).
#include "collision/kdop.hpp"

#include <stdexcept>
#include <string>

#include "collision/surface.hpp"

namespace lumen::collision {

int validate_kdop(int k) {
  if (k != 6 && k != 14 && k != 18 && k != 26) {
    throw std::invalid_argument("kdop must be 6, 14, 18 or 26, got " + std::to_string(k));
  }
  return k;
}

}  // namespace lumen::collision
