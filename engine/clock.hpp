#pragma once
// Wall-clock timing of the engine's stages and loads: one steady clock, milliseconds as doubles.
#include <chrono>

namespace lumen::engine {

using Clock = std::chrono::steady_clock;

// Milliseconds from t0 to now.
inline double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

}  // namespace lumen::engine
