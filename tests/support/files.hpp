// Test support: files written by a test and the message of the error a call throws.
#pragma once

#include <filesystem>
#include <fstream>
#include <string>

namespace lumen::test {

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

}  // namespace lumen::test
