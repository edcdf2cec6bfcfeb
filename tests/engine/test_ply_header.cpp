// A PLY file's header checked before assimp reads it (engine::require_ply_header): the shipped and seed files pass,
// every malformed header is refused naming the file, the line and its text, and a count the file cannot hold is
// refused before anything reads the body. The kept endless fuzz input (assimp loops on its header) is refused by the
// header check, not by the reader's timeout.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "engine/input.hpp"
#include "engine/surface_file.hpp"
#include "support/files.hpp"

namespace {

namespace fs = std::filesystem;
using lumen::engine::InputError;
using lumen::engine::require_ply_header;

// A triangle in ASCII PLY: the header lines given, then 3 vertices and 1 face (26 bytes).
constexpr char kHeader[] =
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
constexpr char kBody[] = "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";

std::string write_ply(const std::string& name, const std::string& bytes) {
  const fs::path dir = lumen::test::fresh_temp_dir("lumen_ply_header_", name);
  const fs::path file = dir / "s.ply";
  std::ofstream(file, std::ios::binary) << bytes;
  return file.string();
}

std::string refusal(const std::string& file) {
  return lumen::test::message_of<InputError>([&] { require_ply_header(file); });
}

// The triangle with one header line replaced (line numbers from 1).
std::string with_line(int line, const std::string& text) {
  std::string header = kHeader;
  size_t start = 0;
  for (int l = 1; l < line; ++l) start = header.find('\n', start) + 1;
  const size_t end = header.find('\n', start);
  return header.replace(start, end - start, text) + kBody;
}

TEST(PlyHeader, ShippedAndSeedFilesPass) {
  const std::vector<std::string> files = {
      std::string(LUMEN_SOURCE_DIR) + "/data/organs/gca-EdinGCA_3D_00090-large_intestine_20k.ply",
      std::string(LUMEN_FUZZ_INPUTS_DIR) + "/ply/seed-ascii.ply",
      std::string(LUMEN_FUZZ_INPUTS_DIR) + "/ply/seed-binary.ply",
      write_ply("triangle", std::string(kHeader) + kBody),
      write_ply("crlf", "ply\r\nformat ascii 1.0\r\ncomment made by hand\r\nelement vertex 3\r\nproperty float x\r\n"
                        "property float y\r\nproperty float z\r\nelement face 1\r\nproperty list uint8 int32 v\r\n"
                        "end_header\r\n0 0 0\r\n1 0 0\r\n0 1 0\r\n3 0 1 2\r\n"),
      // What writers put in headers: upper-case magic, obj_info, comments between properties, tabs, trailing
      // spaces, blank lines, sized type names, zero counts, elements besides vertex and face, bytes after the body.
      write_ply("writers", "PLY\nformat binary_little_endian 1.0\nobj_info made by hand\nelement vertex 3\n"
                           "property float32 x\ncomment between properties\nproperty float64 y\t\n\nproperty int16 z \n"
                           "element edge 0\nproperty int vertex1\nelement material 0\nproperty uchar red\n"
                           "end_header\n" + std::string(3 * (4 + 8 + 2) + 7, '\0'))};
  for (const std::string& f : files) EXPECT_EQ(refusal(f), "") << f;
}

TEST(PlyHeader, MalformedHeadersAreRefusedNamingLineAndText) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"plyx\nformat ascii 1.0\nend_header\n", "PLY header line 1: must be \"ply\" (\"plyx\")"},
      {with_line(2, "format ascii 2.0"),
       "PLY header line 2: must be \"format ascii|binary_little_endian|binary_big_endian 1.0\" (\"format ascii 2.0\")"},
      {with_line(3, "element vertex -3"),
       "PLY header line 3: must be \"element NAME COUNT\" with COUNT an integer in [0, 2147483647] (\"element vertex "
       "-3\")"},
      {with_line(4, "property quad x"),
       "PLY header line 4: must be \"property TYPE NAME\" with TYPE one of PLY's scalar types (\"property quad x\")"},
      // (the kept endless fuzz input's line: a list without its item type)
      {with_line(8, "property list uchar  6"),
       "PLY header line 8: must be \"property list COUNT_TYPE TYPE NAME\" (COUNT_TYPE an integer type) (\"property "
       "list uchar  6\")"},
      {with_line(8, "property list float int vertex_indices"),
       "PLY header line 8: must be \"property list COUNT_TYPE TYPE NAME\" (COUNT_TYPE an integer type) (\"property "
       "list float int vertex_indices\")"},
      {with_line(3, "vertex 3"), "PLY header line 3: not a PLY header keyword (\"vertex 3\")"},
      {"ply\nformat ascii 1.0\nproperty float x\nend_header\n",
       "PLY header line 3: a property before any element (\"property float x\")"},
      {"ply\nelement vertex 0\nformat ascii 1.0\nend_header\n",
       "PLY header line 2: an element before the format line (\"element vertex 0\")"},
      {with_line(9, "end_header now"), "PLY header line 9: \"end_header\" takes nothing after it (\"end_header now\")"},
      {"ply\nformat ascii 1.0\nelement vertex 3\n", "PLY header: no \"end_header\" line within its first 65536 bytes"},
      // More elements than the body can hold: ascii (2 bytes a property), binary (the properties' bytes).
      {with_line(3, "element vertex 99999999"),
       "PLY header line 3: element vertex declares 99999999 of them, more than the file's 26 bytes after the header "
       "can hold (\"element vertex 99999999\")"},
      {"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\nend_header\n" + std::string(23, 'x'),
       "PLY header line 3: element vertex declares 3 of them, more than the file's 23 bytes after the header can "
       "hold (\"element vertex 3\")"},
      // At the edge: one ascii vertex of 3 values needs "0 0 0" (5 bytes), a binary face with a list its count byte.
      {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0",
       "PLY header line 3: element vertex declares 1 of them, more than the file's 3 bytes after the header can hold "
       "(\"element vertex 1\")"},
      {"ply\nformat binary_big_endian 1.0\nelement face 2\nproperty list uchar int v\nend_header\n" + std::string(1, '\0'),
       "PLY header line 3: element face declares 2 of them, more than the file's 1 bytes after the header can hold "
       "(\"element face 2\")"},
      // A long line with unprintable bytes is quoted short and printable.
      {with_line(3, "element vertex\x01" + std::string(100, 'x')),
       "PLY header line 3: must be \"element NAME COUNT\" with COUNT an integer in [0, 2147483647] (\"element vertex?" +
           std::string(65, 'x') + "...\")"}};
  for (size_t i = 0; i < cases.size(); ++i) {
    const std::string file = write_ply("case" + std::to_string(i), cases[i].first);
    EXPECT_EQ(refusal(file), file + ": " + cases[i].second) << "case " << i;
  }
  // Bodies of exactly the least bytes pass: 3 binary doubles, an ascii vertex without its last separator, two
  // empty binary lists (their count bytes).
  EXPECT_EQ(refusal(write_ply("exact", "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\n"
                                       "end_header\n" + std::string(24, '\0'))),
            "");
  EXPECT_EQ(refusal(write_ply("exact_ascii", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty "
                                             "float y\nproperty float z\nend_header\n0 0 0")),
            "");
  EXPECT_EQ(refusal(write_ply("exact_list", "ply\nformat binary_big_endian 1.0\nelement face 2\nproperty list uchar "
                                            "int v\nend_header\n" + std::string(2, '\0'))),
            "");
}

// The input tools/fuzz.sh kept because assimp never finished on it: refused by its header, naming the line.
TEST(PlyHeader, TheKeptEndlessInputIsRefusedByItsHeader) {
  const fs::path kept = fs::path(LUMEN_FUZZ_INPUTS_DIR) / "ply" / "timeout-f505603172a75b6e25f80dfd0ff008d74c7a643f";
  const fs::path dir = lumen::test::fresh_temp_dir("lumen_ply_header_", "kept");
  const fs::path file = dir / "input.ply";
  fs::copy_file(kept, file);
  const std::string message = lumen::test::message_of<InputError>(
      [&] { lumen::engine::read_surface_file(file.string(), 1.0, "surface", 1.0); });
  EXPECT_EQ(message, file.string() +
                         ": PLY header line 8: must be \"property list COUNT_TYPE TYPE NAME\" (COUNT_TYPE an integer "
                         "type) (\"property list uchar  6\")");
}

}  // namespace
