// The test programs' main, built once (tests/CMakeLists.txt): Catch2's session plus
// what test_common.h promises: skips that ctest counts as skipped, and temporary
// directories removed when the tests pass.
#define CATCH_CONFIG_RUNNER
#include <catch2/catch.hpp>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <set>
#include <vector>

#include "test_common.h"

namespace prtbake::test {
namespace {

struct State {
  std::mutex mutex;
  std::vector<std::string> tempDirs;
  std::set<std::string> skippedCases;  // test cases that recorded a skip
  std::vector<std::string> skipLines;  // "<test case>: <reason>"
  size_t casesRun = 0;
};

State& state() {
  static State s;
  return s;
}

std::string currentTestCase() { return Catch::getResultCapture().getCurrentTestName(); }

void record(const std::string& reason, const char* kind) {
  const std::string name = currentTestCase();
  if (const char* forbid = std::getenv("PRTBAKE_FORBID_SKIPS"); forbid && *forbid && std::string(forbid) != "0")
    FAIL("this test must run here (PRTBAKE_FORBID_SKIPS is set) but " << kind << ": " << reason);
  const std::string line = name + ": " + (std::string(kind) == "skipped" ? "" : std::string(kind) + ": ") + reason;
  {
    std::lock_guard<std::mutex> lock(state().mutex);
    state().skippedCases.insert(name);
    // Once per line: a test case with sections runs once per section.
    if (std::find(state().skipLines.begin(), state().skipLines.end(), line) != state().skipLines.end()) return;
    state().skipLines.push_back(line);
  }
  std::printf("SKIPPED: %s\n", line.c_str());
  std::fflush(stdout);
  if (const char* log = std::getenv("PRTBAKE_SKIP_LOG"); log && *log)
    if (FILE* f = std::fopen(log, "a")) {  // O_APPEND: whole lines from parallel tests
      std::fprintf(f, "%s\n", line.c_str());
      std::fclose(f);
    }
}

// Counts the test cases that run, so that main can tell "all skipped" from "some skipped".
struct CaseCounter : Catch::TestEventListenerBase {
  using TestEventListenerBase::TestEventListenerBase;
  void testCaseStarting(const Catch::TestCaseInfo&) override { ++state().casesRun; }
};
CATCH_REGISTER_LISTENER(CaseCounter)

}  // namespace

std::string tempDir(const std::string& name) {
  const char* base = std::getenv("TMPDIR");
  const std::string dir = std::string(base && *base ? base : "/tmp") + "/prtbake-test-" + std::to_string(::getpid()) +
                          "-" + name;
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
  std::filesystem::create_directories(dir);
  std::lock_guard<std::mutex> lock(state().mutex);
  state().tempDirs.push_back(dir);
  return dir;
}

void skipTestCase(const std::string& reason) { record(reason, "skipped"); }
void skipPart(const std::string& reason) { record(reason, "partly skipped"); }

}  // namespace prtbake::test

int main(int argc, char** argv) {
  using prtbake::test::state;
  // PoCL's kernel cache in the build tree (not ~/.cache/pocl), for this process and the
  // CLI runs it starts; skip reasons where scripts/test.sh lists them after ctest's summary.
  ::setenv("POCL_CACHE_DIR", PRTBAKE_TEST_BINARY_DIR "/pocl-cache", 0);
  ::setenv("PRTBAKE_SKIP_LOG", PRTBAKE_TEST_BINARY_DIR "/Testing/skipped.log", 0);
  const int failed = Catch::Session().run(argc, argv);
  auto& s = state();
  if (failed == 0) {
    for (const auto& d : s.tempDirs) {
      std::error_code ec;
      std::filesystem::remove_all(d, ec);
    }
  } else if (!s.tempDirs.empty()) {
    std::fprintf(stderr, "kept for inspection (a test failed):\n");
    for (const auto& d : s.tempDirs) std::fprintf(stderr, "  %s\n", d.c_str());
  }
  if (!s.skipLines.empty() && s.casesRun > 1) {
    std::printf("%zu of %zu test cases skipped (in whole or in part):\n", s.skippedCases.size(), s.casesRun);
    for (const auto& l : s.skipLines) std::printf("  SKIPPED: %s\n", l.c_str());
  }
  if (failed == 0 && !s.skippedCases.empty() && s.skippedCases.size() == s.casesRun) return prtbake::test::kSkipExitCode;
  return failed;
}
