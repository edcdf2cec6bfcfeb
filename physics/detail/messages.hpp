#pragma once
// Error-message helpers of the physics sources (internal: not part of the public interface).
#include <sstream>
#include <stdexcept>
#include <string>

namespace lumen::physics::detail {

[[noreturn]] inline void fail(const std::string& what) { throw std::invalid_argument(what); }
// A file reader's error: "<file>: <where>: <problem>" (where: a line, a section, a field).
[[noreturn]] inline void fail(const std::string& file, const std::string& where, const std::string& problem) {
  throw std::invalid_argument(file + ": " + where + ": " + problem);
}

// A double with all 17 significant digits.
inline std::string num(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

// Throws std::invalid_argument "<subject> <rule>, got <value>" (numbers with 17 significant digits).
template <typename T>
[[noreturn]] void fail_value(const std::string& subject, const std::string& rule, T value) {
  std::ostringstream msg;
  msg.precision(17);
  msg << subject << " " << rule << ", got " << value;
  throw std::invalid_argument(msg.str());
}
// The same as "<where>: <what> must <rule>, got <value>".
template <typename T>
[[noreturn]] void fail_must(const char* where, const std::string& what, const std::string& rule, T value) {
  fail_value(std::string(where) + ": " + what, "must " + rule, value);
}

// Validates a node id of a slot that may be unused (-1).
inline void check_slot(int node, int n_nodes, const std::string& name) {
  if (node < -1 || node >= n_nodes)
    fail(name + " must be -1 (unused) or a node id in [0, " + std::to_string(n_nodes) + "), got " +
         std::to_string(node));
}

}  // namespace lumen::physics::detail
