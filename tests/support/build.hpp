// Test support: what kind of build the tests run in.
#pragma once

namespace lumen::test {

inline constexpr double kPi = 3.14159265358979323846;  // as a double

// Optimised builds run the finer meshes a test names; the Debug + sanitizer build coarse ones (the same checks,
// quickly).
#ifdef NDEBUG
inline constexpr bool kOptimised = true;
#else
inline constexpr bool kOptimised = false;
#endif

}  // namespace lumen::test
