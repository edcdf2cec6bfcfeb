// Allowed: the module's own headers, system headers, and an include that is commented out.
#pragma once
#include "physics/types.hpp"
#include <Eigen/Core>
// #include "collision/ccd.hpp"
/* #include "render/renderer.hpp" is only mentioned here */
