// Every fuzz target (tests/fuzz/fuzz_*.cpp) over its seed corpus and its regression
// inputs, in the ordinary build and, through scripts/ci-sanitize.sh, under ASan and
// UBSan. A regression input is an input a fuzzer once found a crash or a contract
// violation with (tests/fuzz/README.md); the target aborts on any such finding, so a
// regression fails this test by killing it.
#include <catch2/catch.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "fuzz/fuzz_target.h"

namespace fs = std::filesystem;

namespace {

std::vector<std::string> filesIn(const std::string& dir) {
  std::vector<std::string> out;
  if (!fs::is_directory(dir)) return out;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.is_regular_file()) out.push_back(e.path().string());
  std::sort(out.begin(), out.end());
  return out;
}

std::string bytesOf(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

}  // namespace

TEST_CASE("fuzz targets: every seed and every regression input runs clean", "[fuzz]") {
  const std::string root = std::string(PRTBAKE_TEST_SOURCE_DIR) + "/fuzz";
  const auto& targets = prtbake::fuzz::targets();
  // One target per fuzz_*.cpp: a target that failed to register would go unreplayed.
  size_t sources = 0;
  for (const auto& f : filesIn(root))
    sources += fs::path(f).filename().string().rfind("fuzz_", 0) == 0 && fs::path(f).extension() == ".cpp";
  CHECK(targets.size() == sources);
  for (const auto& t : targets) {
    const std::vector<std::string> seeds = filesIn(root + "/corpus/" + t.name);
    const std::vector<std::string> regressions = filesIn(root + "/regressions/" + t.name);
    INFO(t.name << ": " << seeds.size() << " seeds, " << regressions.size() << " regression inputs");
    CHECK(seeds.size() >= 3);
    for (const auto& list : {seeds, regressions})
      for (const auto& f : list) {
        INFO(f);
        const std::string bytes = bytesOf(f);
        CHECK(t.fn(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()) == 0);
      }
  }
}
