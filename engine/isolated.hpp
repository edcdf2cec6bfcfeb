#pragma once
// Work run in a child process, for third-party parsers that may crash or hang on a malformed file (assimp's
// surface loaders do: an ai_assert abort on a truncated OFF, an endless loop on a malformed PLY header, both found
// by tools/fuzz.sh). The parent survives either and says which.
#include <functional>
#include <string>

namespace lumen::engine {

// How work run in a child process ended.
struct IsolatedRun {
  enum class End { kDone, kThrew, kCrashed, kTimedOut };
  End end = End::kDone;
  // kDone: the bytes the work returned; kThrew: the exception's what(); kCrashed: how the child ended ("signal 6
  // (Aborted)" or "exit status 1"); kTimedOut: empty.
  std::string text;
};

// Run `work` in a forked child (its fatal-signal handlers reset, so that a crash ends only the child) and wait at
// most timeout_s seconds for it, killing it after that. The child sends back what `work` returns, or the what() of
// a std::exception it throws. Only the calling thread exists in the child: `work` must not wait on other threads.
// Throws std::runtime_error when the process or pipe cannot be made.
IsolatedRun run_isolated(const std::function<std::string()>& work, double timeout_s);

}  // namespace lumen::engine
