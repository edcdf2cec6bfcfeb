// Work run in a child process (engine/isolated.hpp).
#include "engine/isolated.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <exception>
#include <stdexcept>

namespace lumen::engine {
namespace {

// The first byte of the child's answer: what follows is the work's result, or an exception's text.
constexpr char kResult = 'R';
constexpr char kException = 'E';
// The signals a crash raises; the child puts their default action back (sanitizers and fuzzers install handlers
// that would report and exit as if the parent had crashed).
constexpr int kCrashSignals[] = {SIGABRT, SIGSEGV, SIGBUS, SIGILL, SIGFPE, SIGTRAP};

// Write all of `bytes` to fd (the child's side of the pipe); false when the pipe is gone.
bool write_all(int fd, const std::string& bytes) {
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    done += static_cast<size_t>(n);
  }
  return true;
}

[[noreturn]] void run_child(int fd, const std::function<std::string()>& work) {
  for (int s : kCrashSignals) ::signal(s, SIG_DFL);
  std::string answer;
  try {
    answer = kResult + work();
  } catch (const std::exception& e) {
    answer = kException + std::string(e.what());
  } catch (...) {
    answer = kException + std::string("an exception that is not a std::exception");
  }
  // _exit: no atexit handlers or static destructors of the parent's state run in the child.
  ::_exit(write_all(fd, answer) ? 0 : 1);
}

// Read the child's answer until it closes the pipe or the deadline passes; false on the deadline.
bool read_until_closed(int fd, std::chrono::steady_clock::time_point deadline, std::string& out) {
  char buffer[1 << 16];
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return false;
    pollfd p{fd, POLLIN, 0};
    const int ready = ::poll(&p, 1, static_cast<int>(left.count()));
    if (ready < 0 && errno == EINTR) continue;
    if (ready < 0) throw std::runtime_error(std::string("run_isolated: poll: ") + std::strerror(errno));
    if (ready == 0) return false;
    const ssize_t n = ::read(fd, buffer, sizeof buffer);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return true;  // closed (or an error, which the child's exit status then explains)
    out.append(buffer, static_cast<size_t>(n));
  }
}

// The child's end: "signal 6 (Aborted)" or "exit status 1".
std::string how_it_ended(int status) {
  if (WIFSIGNALED(status))
    return "signal " + std::to_string(WTERMSIG(status)) + " (" + ::strsignal(WTERMSIG(status)) + ")";
  return "exit status " + std::to_string(WEXITSTATUS(status));
}

}  // namespace

IsolatedRun run_isolated(const std::function<std::string()>& work, double timeout_s) {
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) throw std::runtime_error(std::string("run_isolated: pipe: ") + std::strerror(errno));
  const pid_t pid = ::fork();
  if (pid < 0) {
    const int error = errno;
    ::close(fds[0]);
    ::close(fds[1]);
    throw std::runtime_error(std::string("run_isolated: fork: ") + std::strerror(error));
  }
  if (pid == 0) {
    ::close(fds[0]);
    run_child(fds[1], work);
  }
  ::close(fds[1]);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  std::string answer;
  bool closed = false;
  try {
    closed = read_until_closed(fds[0], std::chrono::time_point_cast<std::chrono::steady_clock::duration>(deadline), answer);
  } catch (...) {
    ::kill(pid, SIGKILL);
    ::waitpid(pid, nullptr, 0);
    ::close(fds[0]);
    throw;
  }
  ::close(fds[0]);
  if (!closed) ::kill(pid, SIGKILL);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (!closed) return {IsolatedRun::End::kTimedOut, ""};
  const bool exited_cleanly = WIFEXITED(status) && WEXITSTATUS(status) == 0;
  if (!exited_cleanly || answer.empty()) return {IsolatedRun::End::kCrashed, how_it_ended(status)};
  const IsolatedRun::End end = answer[0] == kResult ? IsolatedRun::End::kDone : IsolatedRun::End::kThrew;
  return {end, answer.substr(1)};
}

}  // namespace lumen::engine
