// The inputs kept for every file reader (tests/fuzz/inputs/<reader>/), replayed through the fuzz target's own entry
// (tests/fuzz/readers.hpp) in both of CI's builds: the seeds (seed-*, valid files of each format written by
// tests/fuzz/make_seeds.py) read; every other input (what tools/fuzz.sh found, or a bad file written by hand) is
// refused with the reader's documented error, and the message names the file.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "fuzz/readers.hpp"
#include "support/files.hpp"

namespace {

namespace fs = std::filesystem;
using lumen::fuzz::Reader;

std::string kept_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// The inputs of one reader's folder, sorted by name.
std::vector<fs::path> kept_inputs(const std::string& reader) {
  std::vector<fs::path> files;
  const fs::path folder = fs::path(LUMEN_FUZZ_INPUTS_DIR) / reader;
  if (fs::is_directory(folder))
    for (const auto& e : fs::directory_iterator(folder))
      if (e.is_regular_file()) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files;
}

bool is_fuzz_seed(const fs::path& p) { return p.filename().string().rfind("seed-", 0) == 0 || p.stem() == "seed"; }

TEST(FuzzInputs, EveryReaderHasSeedsAndEachReads) {
  for (const char* name : lumen::fuzz::kReaderNames) {
    SCOPED_TRACE(name);
    const fs::path dir = lumen::test::fresh_temp_dir("lumen_fuzz_seeds_", name);
    int seeds = 0;
    for (const fs::path& input : kept_inputs(name)) {
      if (!is_fuzz_seed(input)) continue;
      ++seeds;
      const lumen::fuzz::Outcome o = lumen::fuzz::read_input(lumen::fuzz::reader_named(name), kept_bytes(input), dir.string());
      EXPECT_TRUE(o.read) << input << ": " << o.message;
    }
    EXPECT_GE(seeds, 1) << "no seed for the reader " << name;
  }
}

TEST(FuzzInputs, KeptBadInputsAreRefusedNamingTheFile) {
  int bad = 0;
  for (const char* name : lumen::fuzz::kReaderNames) {
    const fs::path dir = lumen::test::fresh_temp_dir("lumen_fuzz_kept_", name);
    for (const fs::path& input : kept_inputs(name)) {
      if (is_fuzz_seed(input)) continue;
      SCOPED_TRACE(input.string());
      ++bad;
      lumen::fuzz::Outcome o;
      // read_input throws std::logic_error for any other exception, or a refusal without the file's name.
      ASSERT_NO_THROW(o = lumen::fuzz::read_input(lumen::fuzz::reader_named(name), kept_bytes(input), dir.string()));
      EXPECT_FALSE(o.read);
      EXPECT_NE(o.message.find(dir.string()), std::string::npos) << o.message;
    }
  }
  EXPECT_GE(bad, 1) << "no kept bad input under " << LUMEN_FUZZ_INPUTS_DIR;
}

// The harness itself: a refusal of a made-up reader's kind, and a bad scene's message passed through.
TEST(FuzzInputs, HarnessNamesItsReadersAndPassesTheRefusalOn) {
  EXPECT_EQ(lumen::fuzz::reader_named("vtk"), Reader::kVtk);
  EXPECT_EQ(lumen::fuzz::reader_named("step"), Reader::kCount);
  const fs::path dir = lumen::test::fresh_temp_dir("lumen_fuzz_harness", "");
  const lumen::fuzz::Outcome o = lumen::fuzz::read_input(Reader::kScene, "{\"frames\": -3}", dir.string());
  EXPECT_FALSE(o.read);
  EXPECT_EQ(o.message.rfind((dir / "input.json").string(), 0), 0u) << o.message;
}

}  // namespace
