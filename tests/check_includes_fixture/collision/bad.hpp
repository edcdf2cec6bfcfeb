// Planted violation: engine through angle brackets.
#pragma once
#include "collision/ccd.hpp"
#include <engine/session.hpp>
