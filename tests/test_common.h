// Shared helpers for the tests: one OpenCL runtime per process, the external
// data folder, temp directories and running the CLI.
#pragma once

#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "prtbake/runtime.h"

namespace prtbake::test {

inline Runtime& runtime() {
  static Runtime rt("cpu");
  return rt;
}

// A runtime on the CPU device whose ray-looping kernels run in groups of `size`
// ($PRTBAKE_GROUP_SIZE while it is made: Runtime::loopGroupSize), so that a GPU's group size
// can be held to the same outputs here.
inline std::unique_ptr<Runtime> runtimeWithGroupSize(const char* size) {
  ::setenv("PRTBAKE_GROUP_SIZE", size, 1);
  try {
    auto rt = std::make_unique<Runtime>("cpu");
    ::unsetenv("PRTBAKE_GROUP_SIZE");
    return rt;
  } catch (...) {
    ::unsetenv("PRTBAKE_GROUP_SIZE");
    throw;
  }
}

// ../shared/data (or $PRTBAKE_DATA_DIR); empty when absent.
inline std::string dataDir() {
  std::string dir = PRTBAKE_TEST_DATA_DIR;
  if (const char* env = std::getenv("PRTBAKE_DATA_DIR"); env && *env) dir = env;
  struct stat st {};
  return ::stat(dir.c_str(), &st) == 0 ? dir : std::string();
}

// Why a test that needs external data is skipped.
inline std::string noDataReason() {
  return std::string("external data not found (") + PRTBAKE_TEST_DATA_DIR +
         " or $PRTBAKE_DATA_DIR: the shared test data folder)";
}

// Path of a file in the data folder, or "" when it is absent.
inline std::string dataFile(const std::string& rel) {
  const std::string dir = dataDir();
  if (dir.empty()) return {};
  const std::string path = dir + "/" + rel;
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 ? path : std::string();
}

// A fresh empty directory under $TMPDIR (or /tmp), unique per process. The test
// main (catch_main.cpp) removes every such directory when the process's tests pass,
// and names the ones it keeps when one fails.
std::string tempDir(const std::string& name);

// Skipping (Catch2 v2 has none). A test case that cannot run here says why with
// PRTBAKE_SKIP(reason), which leaves the test case; skipPart(reason) records that a
// part of it could not run and goes on. The test main then exits with kSkipExitCode
// (ctest's SKIP_RETURN_CODE, so ctest counts the test as skipped) when no test case
// failed and every test case it ran skipped, prints each reason as a line
// "SKIPPED: <test case>: <reason>" and appends it to $PRTBAKE_SKIP_LOG, which
// scripts/test.sh lists after ctest's summary. Where every test must run (CI sets
// PRTBAKE_FORBID_SKIPS=1) a skip is a failure that gives the reason.
constexpr int kSkipExitCode = 77;
void skipPart(const std::string& reason);
// Records the skip of the current test case (PRTBAKE_SKIP then returns from it).
void skipTestCase(const std::string& reason);

struct CliResult {
  int exitCode;
  std::string output;  // stdout and stderr together
};
// Runs a shell command line; stdout and stderr together. A command killed by a
// signal reports 128 + the signal number, as the shell does.
inline CliResult runShell(const std::string& cmd) {
  CliResult r{-1, {}};
  FILE* p = ::popen((cmd + " 2>&1").c_str(), "r");
  if (!p) return r;
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) r.output.append(buf, n);
  const int st = ::pclose(p);
  r.exitCode = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
  return r;
}

// Runs the built prtbake executable with `args` (a shell-quoted string).
inline CliResult runCli(const std::string& args) { return runShell(std::string("'") + PRTBAKE_CLI_PATH + "' " + args); }

struct MeasuredRun {
  int exitCode;        // 128 + the signal number for a process killed by one
  double seconds;      // wall time from the spawn to the end
  double peakMiB;      // the process's own peak resident size (wait4)
  std::string output;  // stdout and stderr together
};
// Runs the built prtbake executable with `args` (one argument each, no shell), with its
// output in `outputFile`, through prtbake_peak_rss (tests/peak_rss.cpp): a child's peak
// resident size would otherwise count this process's memory up to its exec.
inline MeasuredRun runCliMeasured(std::vector<std::string> args, const std::string& outputFile) {
  const std::string result = outputFile + ".peak";
  args.insert(args.begin(), {PRTBAKE_PEAK_RSS_PATH, result, PRTBAKE_CLI_PATH});
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  ::posix_spawn_file_actions_init(&actions);
  ::posix_spawn_file_actions_addopen(&actions, 1, outputFile.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  ::posix_spawn_file_actions_adddup2(&actions, 1, 2);
  MeasuredRun r{-1, 0, 0, {}};
  const auto t0 = std::chrono::steady_clock::now();
  pid_t pid = 0;
  const int spawned = ::posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  ::posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) return r;
  int status = 0;
  if (::waitpid(pid, &status, 0) != pid || !WIFEXITED(status) || WEXITSTATUS(status) != 0) return r;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  long peakKiB = 0;
  if (FILE* f = std::fopen(result.c_str(), "r")) {
    if (std::fscanf(f, "%d %ld", &r.exitCode, &peakKiB) != 2) r.exitCode = -1;
    std::fclose(f);
  }
  r.peakMiB = double(peakKiB) / 1024.0;
  if (FILE* f = std::fopen(outputFile.c_str(), "rb")) {
    char buf[4096];
    size_t n;
    while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) r.output.append(buf, n);
    std::fclose(f);
  }
  return r;
}

inline bool fileExists(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0;
}

// Debian's Chromium, or "" when it is not installed.
inline std::string chromiumPath() {
  for (const char* p : {"/usr/bin/chromium", "/usr/bin/chromium-browser"})
    if (fileExists(p)) return p;
  return {};
}

// Loads `page` (an HTML file) in headless Chromium with WebGL on SwiftShader and returns what
// the page's `window.result` (a promise of a string) resolves to, as the output's last line
// (tests/js/chromium_page.mjs drives Chromium over its DevTools pipe; 100 s at most). Pages
// may read files beside them and import modules by absolute path.
inline CliResult chromiumPage(const std::string& chromium, const std::string& page) {
  return runShell("PRTBAKE_CHROMIUM_PROFILE='" + page + ".profile' timeout 110 node '" +
                  std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/chromium_page.mjs' '" + chromium + "' 'file://" + page +
                  "' 100");
}

}  // namespace prtbake::test

#define PRTBAKE_SKIP(reason)                   \
  do {                                         \
    ::prtbake::test::skipTestCase(reason);     \
    return;                                    \
  } while (0)

// For a path from dataFile(): skips when the external data is absent.
#define PRTBAKE_SKIP_IF_NO_DATA(path) \
  do {                                \
    if ((path).empty()) PRTBAKE_SKIP(::prtbake::test::noDataReason()); \
  } while (0)
