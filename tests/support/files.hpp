// Test support: files written by a test, the message of the error a call throws, and a shell command's output.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

namespace lumen::test {

// An empty folder <prefix><name> in the temporary folder (removed first if it exists); its path.
inline std::filesystem::path fresh_temp_dir(const std::string& prefix, const std::string& name) {
  const std::filesystem::path d = std::filesystem::temp_directory_path() / (prefix + name);
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d;
}

// Write text to lumen_test_<name> in the temporary folder; its path.
inline std::string write_temp(const std::string& name, const std::string& text) {
  const auto path = std::filesystem::temp_directory_path() / ("lumen_test_" + name);
  std::ofstream(path) << text;
  return path.string();
}

// The message of the Error that f() throws ("" when it throws none).
template <class Error, class F>
std::string message_of(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

// A shell command's exit code (-1 when it could not start or did not exit normally) and what it printed.
struct CommandRun {
  int code = -1;
  std::string output;  // its standard output (append " 2>&1" to the command for its errors too)
};
inline CommandRun run_command(const std::string& command) {
  CommandRun r;
  FILE* p = popen(command.c_str(), "r");
  if (!p) return r;
  char buf[4096];
  for (size_t n; (n = fread(buf, 1, sizeof buf, p)) > 0;) r.output.append(buf, n);
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

}  // namespace lumen::test
