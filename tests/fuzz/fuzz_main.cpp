// libFuzzer target over every file reader (tests/fuzz/readers.hpp). The reader is named by the environment
// variable LUMEN_FUZZ_READER (tests/fuzz/inputs/<reader>/ holds its seeds); tools/fuzz.sh runs each one for a fixed
// number of inputs. Inputs are written to a private temporary folder, removed at exit.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "fuzz/readers.hpp"

namespace {

lumen::fuzz::Reader g_reader = lumen::fuzz::Reader::kCount;
std::string g_folder;  // the private folder the inputs are written to

void remove_folder() {
  std::error_code ec;
  std::filesystem::remove_all(g_folder, ec);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  const char* name = std::getenv("LUMEN_FUZZ_READER");
  g_reader = lumen::fuzz::reader_named(name ? name : "");
  if (g_reader == lumen::fuzz::Reader::kCount) {
    std::fprintf(stderr, "lumen_fuzz: set LUMEN_FUZZ_READER to one of:");
    for (const char* n : lumen::fuzz::kReaderNames) std::fprintf(stderr, " %s", n);
    std::fprintf(stderr, " (not \"%s\")\n", name ? name : "");
    std::exit(2);
  }
  std::string pattern = (std::filesystem::temp_directory_path() / "lumen_fuzz_XXXXXX").string();
  if (!mkdtemp(pattern.data())) {
    std::perror("lumen_fuzz: mkdtemp");
    std::exit(2);
  }
  g_folder = pattern;
  std::atexit(remove_folder);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  lumen::fuzz::read_input(g_reader, std::string(reinterpret_cast<const char*>(data), size), g_folder);
  return 0;
}
