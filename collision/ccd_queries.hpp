#pragma once
// CCD query files (the data/ccd format): reading, running every query with timing, and reporting.
//
// Format (one query per line, ',' separated, '#' lines and blank lines skipped):
//   kind ('vf' or 'ee'), 24 doubles (4 points x 3 coordinates at t = 0, then the same at t = 1),
//   optionally truth (0 or 1), optionally a provenance id (ignored). 25, 26 or 27 fields.
//   vf: P0 = the vertex p, P1..P3 = the triangle a, b, c; ee: P0, P1 = edge ab, P2, P3 = edge cd.
#include <string>
#include <vector>

#include "collision/ccd.hpp"

namespace lumen::collision {

// One query of a file.
struct CcdQuery {
  bool edge_edge = false;  // false: vertex-face, true: edge-edge
  Vec3 x0[4];              // the 4 points at t = 0, metres
  Vec3 x1[4];              // the 4 points at t = 1, metres
  int truth = -1;          // 1 = contact, 0 = none, -1 = not given
  int line = 0;            // line number in the file (1-based)
};

// Results of one kind of query.
struct CcdKindStats {
  long queries = 0;          // queries run
  long positives = 0;        // queries the CCD reports as a contact
  long labelled = 0;         // queries with a truth value (false_* count only these)
  long false_negatives = 0;  // truth 1, reported no contact
  long false_positives = 0;  // truth 0, reported contact
  double mean_ns = 0.0;      // mean wall time per query (steady_clock), nanoseconds
  long max_ns = 0;           // slowest query, nanoseconds
};

// Results of a whole file, per kind.
struct CcdFileStats {
  CcdKindStats vf, ee;
};

// Reads a query file. Throws std::runtime_error naming the file (and for bad content the line number,
// field and value) when the file cannot be read or a line is malformed (bad kind, wrong field count,
// unparsable or non-finite coordinate, truth other than 0/1).
std::vector<CcdQuery> read_ccd_queries(const std::string& path);

// Runs every query (gap 0), timing each one.
CcdFileStats run_ccd_queries(const std::vector<CcdQuery>& queries, const CcdOptions& options = {});

// read_ccd_queries + run_ccd_queries.
CcdFileStats run_ccd_file(const std::string& path, const CcdOptions& options = {});

// Human-readable table, one row per kind.
std::string format_ccd_table(const CcdFileStats& stats);

// {"vf": {"queries":..,"positives":..,"false_negatives":..,"false_positives":..,"mean_ns":..,
//  "max_ns":..}, "ee": {...}}; false_* are null for a kind without truth values.
std::string format_ccd_json(const CcdFileStats& stats);

}  // namespace lumen::collision
