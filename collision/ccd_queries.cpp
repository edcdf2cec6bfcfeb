// CCD query files: parse, validate, run with timing, format.
#include "collision/ccd_queries.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace lumen::collision {
namespace {

constexpr int kCoordinates = 24;  // 4 points x 3 coordinates x 2 times

// Name of field `index` (1-based) of a query line, for error messages.
std::string field_name(int index) {
  if (index == 1) return "kind";
  if (index >= 2 && index <= 1 + kCoordinates) {
    const int c = index - 2;
    const int time = c / 12, point = (c % 12) / 3, axis = c % 3;
    return "P" + std::to_string(point) + "xyz"[axis] + " at t=" + std::to_string(time);
  }
  if (index == 2 + kCoordinates) return "truth";
  return "src";
}

[[noreturn]] void fail(const std::string& path, int line, int field, const std::string& value,
                       const std::string& what) {
  std::ostringstream msg;
  msg << path << ":" << line << ": field " << field << " (" << field_name(field) << ") " << what
      << ", got '" << value << "'";
  throw std::runtime_error(msg.str());
}

// Splits a line at ','.
void split(const std::string& line, std::vector<std::string>& fields) {
  fields.clear();
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    fields.push_back(line.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
}

// Accumulates one query's outcome into its kind's statistics.
void tally(CcdKindStats& s, const CcdQuery& q, bool contact, long ns) {
  ++s.queries;
  if (contact) ++s.positives;
  if (q.truth >= 0) {
    ++s.labelled;
    if (q.truth == 1 && !contact) ++s.false_negatives;
    if (q.truth == 0 && contact) ++s.false_positives;
  }
  s.mean_ns += static_cast<double>(ns);  // summed here, divided at the end
  s.max_ns = std::max(s.max_ns, ns);
}

void json_kind(std::ostringstream& out, const char* name, const CcdKindStats& s) {
  char mean[64];
  std::snprintf(mean, sizeof mean, "%.1f", s.mean_ns);
  out << "\"" << name << "\": {\"queries\":" << s.queries << ",\"positives\":" << s.positives
      << ",\"false_negatives\":" << (s.labelled > 0 ? std::to_string(s.false_negatives) : "null")
      << ",\"false_positives\":" << (s.labelled > 0 ? std::to_string(s.false_positives) : "null")
      << ",\"mean_ns\":" << mean << ",\"max_ns\":" << s.max_ns << "}";
}

}  // namespace

std::vector<CcdQuery> read_ccd_queries(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open the CCD query file for reading");
  std::vector<CcdQuery> queries;
  std::vector<std::string> fields;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    // Skip comments and blank lines.
    if (line.empty() || line[0] == '#') continue;
    split(line, fields);
    const int n = static_cast<int>(fields.size());
    if (n < 1 + kCoordinates || n > 3 + kCoordinates) {
      std::ostringstream msg;
      msg << path << ":" << number << ": expected 25, 26 or 27 fields (kind, 24 coordinates, truth, src), got "
          << n;
      throw std::runtime_error(msg.str());
    }
    CcdQuery q;
    q.line = number;
    // Kind.
    if (fields[0] == "vf") q.edge_edge = false;
    else if (fields[0] == "ee") q.edge_edge = true;
    else fail(path, number, 1, fields[0], "must be 'vf' or 'ee'");
    // Coordinates: finite doubles, the whole field consumed.
    for (int c = 0; c < kCoordinates; ++c) {
      const std::string& f = fields[1 + c];
      const char* begin = f.c_str();
      char* end = nullptr;
      const double x = std::strtod(begin, &end);
      if (f.empty() || end != begin + f.size()) fail(path, number, 2 + c, f, "is not a number");
      if (!std::isfinite(x)) fail(path, number, 2 + c, f, "must be finite");
      const int time = c / 12, point = (c % 12) / 3, axis = c % 3;
      (time == 0 ? q.x0 : q.x1)[point][axis] = x;
    }
    // Truth (optional).
    if (n >= 2 + kCoordinates) {
      const std::string& f = fields[1 + kCoordinates];
      if (f == "0") q.truth = 0;
      else if (f == "1") q.truth = 1;
      else fail(path, number, 2 + kCoordinates, f, "must be 0 or 1");
    }
    queries.push_back(q);
  }
  if (in.bad()) throw std::runtime_error(path + ": read error");
  return queries;
}

CcdFileStats run_ccd_queries(const std::vector<CcdQuery>& queries, const CcdOptions& options) {
  using Clock = std::chrono::steady_clock;
  CcdFileStats stats;
  for (const CcdQuery& q : queries) {
    // Run and time one query.
    const Vec3* a = q.x0;
    const Vec3* b = q.x1;
    const Clock::time_point start = Clock::now();
    const bool contact =
        q.edge_edge
            ? edge_edge_ccd(a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3], 0.0, options, nullptr)
            : vertex_face_ccd(a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3], 0.0, options, nullptr);
    const long ns = static_cast<long>(
        std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - start).count());
    tally(q.edge_edge ? stats.ee : stats.vf, q, contact, ns);
  }
  // Sums of times -> means.
  for (CcdKindStats* s : {&stats.vf, &stats.ee})
    if (s->queries > 0) s->mean_ns /= static_cast<double>(s->queries);
  return stats;
}

CcdFileStats run_ccd_file(const std::string& path, const CcdOptions& options) {
  return run_ccd_queries(read_ccd_queries(path), options);
}

std::string format_ccd_table(const CcdFileStats& stats) {
  std::ostringstream out;
  char row[256];
  std::snprintf(row, sizeof row, "%-4s %9s %9s %9s %9s %11s %11s\n", "kind", "queries", "positives",
                "false_neg", "false_pos", "mean_ns", "max_ns");
  out << row;
  const char* names[2] = {"vf", "ee"};
  const CcdKindStats* kinds[2] = {&stats.vf, &stats.ee};
  for (int k = 0; k < 2; ++k) {
    const CcdKindStats& s = *kinds[k];
    const std::string fn = s.labelled > 0 ? std::to_string(s.false_negatives) : "-";
    const std::string fp = s.labelled > 0 ? std::to_string(s.false_positives) : "-";
    std::snprintf(row, sizeof row, "%-4s %9ld %9ld %9s %9s %11.1f %11ld\n", names[k], s.queries,
                  s.positives, fn.c_str(), fp.c_str(), s.mean_ns, s.max_ns);
    out << row;
  }
  return out.str();
}

std::string format_ccd_json(const CcdFileStats& stats) {
  std::ostringstream out;
  out << "{";
  json_kind(out, "vf", stats.vf);
  out << ", ";
  json_kind(out, "ee", stats.ee);
  out << "}";
  return out.str();
}

}  // namespace lumen::collision
