// CCD query files: parsing, validation messages, running with truth, and the table / JSON output.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string>

#include "collision/ccd_queries.hpp"

namespace lumen::collision {
namespace {

// A temporary query file with the given content, removed at the end of the test.
class TempFile {
 public:
  explicit TempFile(const std::string& content) {
    path_ = ::testing::TempDir() + "ccd_queries_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name() + ".csv";
    std::ofstream out(path_);
    out << content;
  }
  ~TempFile() { std::remove(path_.c_str()); }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

// 24 coordinates: a vertex falling from z = h to z = h - 1 onto the static unit triangle at z = 0
// (contact at t = h when h is in [0, 1]), as a query line of the given kind prefix.
std::string falling_vertex(double h) {
  const std::string p0 = "0.25,0.25," + std::to_string(h), p1 = "0.25,0.25," + std::to_string(h - 1.0);
  const std::string tri = "0,0,0,1,0,0,0,1,0";
  return p0 + "," + tri + "," + p1 + "," + tri;
}

// Edges crossing at t = h: ab along x at z = 0, cd along y falling from z = h.
std::string crossing_edges(double h) {
  const std::string ab = "-1,0,0,1,0,0";
  return ab + ",0,-1," + std::to_string(h) + ",0,1," + std::to_string(h) + "," + ab + ",0,-1," +
         std::to_string(h - 1.0) + ",0,1," + std::to_string(h - 1.0);
}

// The line with field k (1-based) replaced by value.
std::string with_field(const std::string& line, int k, const std::string& value) {
  std::size_t start = 0;
  for (int i = 1; i < k; ++i) start = line.find(',', start) + 1;
  const std::size_t end = line.find(',', start);
  return line.substr(0, start) + value + (end == std::string::npos ? "" : line.substr(end));
}

// The message of the std::runtime_error thrown by reading `content`, or "" when none is thrown.
std::string read_error(const std::string& content) {
  TempFile f(content);
  try {
    read_ccd_queries(f.path());
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

void expect_contains(const std::string& text, const std::string& part) {
  EXPECT_NE(text.find(part), std::string::npos) << "'" << part << "' not in: " << text;
}

TEST(CcdQueries, ReadsQueriesWithCommentsTruthAndProvenance) {
  TempFile f("# comment\n# kind,...\nvf," + falling_vertex(0.5) + ",1,SQ:a#0\n\nee," + crossing_edges(2.0) +
             ",0\r\nvf," + falling_vertex(0.25) + "\n");
  const std::vector<CcdQuery> q = read_ccd_queries(f.path());
  ASSERT_EQ(q.size(), 3u);
  EXPECT_FALSE(q[0].edge_edge);
  EXPECT_TRUE(q[1].edge_edge);
  EXPECT_EQ(q[0].truth, 1);
  EXPECT_EQ(q[1].truth, 0);
  EXPECT_EQ(q[2].truth, -1);
  EXPECT_EQ(q[0].line, 3);
  EXPECT_EQ(q[1].line, 5);
  EXPECT_EQ(q[0].x0[0], Vec3(0.25, 0.25, 0.5));
  EXPECT_EQ(q[0].x1[0], Vec3(0.25, 0.25, -0.5));
  EXPECT_EQ(q[0].x1[2], Vec3(1, 0, 0));
  EXPECT_EQ(q[1].x0[3], Vec3(0, 1, 2));
}

// Counts against the truth column: contacts at t = 1/2 (vf, ee) are positives; a vertex that stops short
// (h = 1.5) and edges that stop short are negatives; one truth deliberately wrong in each direction.
TEST(CcdQueries, CountsAgainstTheTruth) {
  TempFile f("vf," + falling_vertex(0.5) + ",1\n" +      // true positive
             "vf," + falling_vertex(1.5) + ",0\n" +      // true negative
             "vf," + falling_vertex(0.5) + ",0\n" +      // labelled 0, contact: false positive
             "vf," + falling_vertex(1.5) + "\n" +        // no truth
             "ee," + crossing_edges(0.5) + ",1\n" +      // true positive
             "ee," + crossing_edges(1.5) + ",1\n");      // labelled 1, no contact: false negative
  const CcdFileStats s = run_ccd_file(f.path());
  EXPECT_EQ(s.vf.queries, 4);
  EXPECT_EQ(s.vf.positives, 2);
  EXPECT_EQ(s.vf.labelled, 3);
  EXPECT_EQ(s.vf.false_positives, 1);
  EXPECT_EQ(s.vf.false_negatives, 0);
  EXPECT_EQ(s.ee.queries, 2);
  EXPECT_EQ(s.ee.positives, 1);
  EXPECT_EQ(s.ee.false_negatives, 1);
  EXPECT_EQ(s.ee.false_positives, 0);
  EXPECT_GT(s.vf.mean_ns, 0.0);
  EXPECT_GE(static_cast<double>(s.vf.max_ns), s.vf.mean_ns);
}

TEST(CcdQueries, ErrorsNameFileLineFieldAndValue) {
  {
    const std::string e = read_error("# c\nvx," + falling_vertex(0.5) + ",1\n");
    expect_contains(e, "ccd_queries_ErrorsNameFileLineFieldAndValue.csv:2:");
    expect_contains(e, "field 1 (kind)");
    expect_contains(e, "'vx'");
  }
  {
    const std::string e = read_error("vf,1,2,3\n");
    expect_contains(e, ".csv:1:");
    expect_contains(e, "expected 25, 26 or 27 fields");
    expect_contains(e, "got 4");
  }
  {
    const std::string e = read_error(with_field("vf," + falling_vertex(0.5) + ",1", 2, "0.2x") + "\n");
    expect_contains(e, ".csv:1:");
    expect_contains(e, "field 2 (P0x at t=0) is not a number");
    expect_contains(e, "'0.2x'");
  }
  {
    const std::string good = "ee," + crossing_edges(0.5);
    const std::string e = read_error(good + "\n" + with_field(good, 23, "inf") + "\n");
    expect_contains(e, ".csv:2:");
    expect_contains(e, "field 23 (P3x at t=1) must be finite");
    expect_contains(e, "'inf'");
  }
  {
    const std::string e = read_error(with_field("vf," + falling_vertex(0.5), 13, "-nan") + "\n");
    expect_contains(e, "field 13 (P3z at t=0) must be finite");
    expect_contains(e, "'-nan'");
  }
  {
    const std::string e = read_error("vf," + falling_vertex(0.5) + ",nan\n");
    expect_contains(e, "field 26 (truth) must be 0 or 1");
    expect_contains(e, "'nan'");
  }
  {
    const std::string e = read_error("vf," + falling_vertex(0.5) + ",,x\n");
    expect_contains(e, "field 26 (truth) must be 0 or 1");
    expect_contains(e, "''");
  }
  try {
    read_ccd_queries("/nonexistent/dir/queries.csv");
    FAIL() << "expected std::runtime_error";
  } catch (const std::runtime_error& e) {
    expect_contains(e.what(), "/nonexistent/dir/queries.csv");
    expect_contains(e.what(), "cannot open");
  }
}

TEST(CcdQueries, FormatsJsonAndTable) {
  CcdFileStats s;
  s.vf = CcdKindStats{3, 2, 3, 0, 1, 1250.25, 4000};
  s.ee = CcdKindStats{2, 1, 0, 0, 0, 500.0, 700};
  EXPECT_EQ(format_ccd_json(s),
            "{\"vf\": {\"queries\":3,\"positives\":2,\"false_negatives\":0,\"false_positives\":1,"
            "\"mean_ns\":1250.2,\"max_ns\":4000}, \"ee\": {\"queries\":2,\"positives\":1,"
            "\"false_negatives\":null,\"false_positives\":null,\"mean_ns\":500.0,\"max_ns\":700}}");
  const std::string table = format_ccd_table(s);
  expect_contains(table, "kind");
  expect_contains(table, "false_neg");
  expect_contains(table, "vf           3         2         0         1      1250.2        4000");
  expect_contains(table, "ee           2         1         -         -       500.0         700");
}

}  // namespace
}  // namespace lumen::collision
