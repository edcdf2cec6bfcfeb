// run_isolated (engine/isolated.hpp): each way the child's work can end, told apart by the parent, which survives
// all of them.
#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <thread>

#include "engine/isolated.hpp"
#include "engine/scene.hpp"

namespace {

using lumen::engine::IsolatedRun;
using lumen::engine::run_isolated;

TEST(Isolated, ReturnsTheBytesTheWorkMade) {
  std::string big(300000, '\0');  // more than a pipe holds at once
  for (size_t i = 0; i < big.size(); ++i) big[i] = static_cast<char>(i * 7);
  const IsolatedRun r = run_isolated([&] { return big; }, 30.0);
  EXPECT_EQ(r.end, IsolatedRun::End::kDone);
  EXPECT_EQ(r.text, big);
}

TEST(Isolated, PassesAnExceptionsTextBack) {
  const IsolatedRun r = run_isolated([]() -> std::string { throw lumen::engine::InputError("f.ply: bad header"); }, 30.0);
  EXPECT_EQ(r.end, IsolatedRun::End::kThrew);
  EXPECT_EQ(r.text, "f.ply: bad header");
}

TEST(Isolated, AnAbortOrASegfaultEndsOnlyTheChild) {
  const IsolatedRun aborted = run_isolated([]() -> std::string { std::abort(); }, 30.0);
  EXPECT_EQ(aborted.end, IsolatedRun::End::kCrashed);
  EXPECT_EQ(aborted.text, "signal 6 (Aborted)");
  const IsolatedRun segv = run_isolated([]() -> std::string {
    std::raise(SIGSEGV);
    return "not reached";
  }, 30.0);
  EXPECT_EQ(segv.end, IsolatedRun::End::kCrashed);
  EXPECT_EQ(segv.text, "signal 11 (Segmentation fault)");
  const IsolatedRun exited = run_isolated([]() -> std::string { std::_Exit(3); }, 30.0);
  EXPECT_EQ(exited.end, IsolatedRun::End::kCrashed);
  EXPECT_EQ(exited.text, "exit status 3");
}

TEST(Isolated, WorkThatDoesNotFinishIsStoppedAtTheTimeout) {
  const auto t0 = std::chrono::steady_clock::now();
  const IsolatedRun r = run_isolated([]() -> std::string {
    for (;;) std::this_thread::sleep_for(std::chrono::seconds(1));
  }, 0.3);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(r.end, IsolatedRun::End::kTimedOut);
  EXPECT_GE(seconds, 0.3);  // waited out the timeout (the child never ends by itself: returning at all is the kill)
}

}  // namespace
