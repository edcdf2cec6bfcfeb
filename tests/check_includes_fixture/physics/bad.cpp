// Planted violations: another module by its prefix, and a relative path around the include directories.
#include "physics/ok.hpp"
#include "collision/ccd.hpp"
#include <vector>
#include "../render/renderer.hpp"
