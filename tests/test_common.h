// Shared helpers for the tests: one OpenCL runtime per process, the external
// data folder, temp directories and running the CLI.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <sys/wait.h>
#include <unistd.h>
#include <string>
#include <sys/stat.h>

#include "prtbake/runtime.h"

namespace prtbake::test {

inline Runtime& runtime() {
  static Runtime rt("cpu");
  return rt;
}

// ../shared/data (or $PRTBAKE_DATA_DIR); empty when absent.
inline std::string dataDir() {
  std::string dir = PRTBAKE_TEST_DATA_DIR;
  if (const char* env = std::getenv("PRTBAKE_DATA_DIR"); env && *env) dir = env;
  struct stat st {};
  return ::stat(dir.c_str(), &st) == 0 ? dir : std::string();
}

// Path of a file in the data folder, or "" (and a warning) when it is absent.
inline std::string dataFile(const std::string& rel) {
  const std::string dir = dataDir();
  if (dir.empty()) return {};
  const std::string path = dir + "/" + rel;
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 ? path : std::string();
}

// A fresh empty directory under $TMPDIR (or /tmp), unique per process.
inline std::string tempDir(const std::string& name) {
  const char* base = std::getenv("TMPDIR");
  std::string dir = std::string(base && *base ? base : "/tmp") + "/prtbake-test-" +
                    std::to_string(::getpid()) + "-" + name;
  std::system(("rm -rf '" + dir + "' && mkdir -p '" + dir + "'").c_str());
  return dir;
}

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

inline bool fileExists(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0;
}

}  // namespace prtbake::test

// Catch2 v2 has no SKIP: warn with the reason and leave the test case.
#define PRTBAKE_SKIP_IF_NO_DATA(path)                                                     \
  do {                                                                                    \
    if ((path).empty()) {                                                                 \
      WARN("skipped: external data not found (set PRTBAKE_DATA_DIR or ../shared/data)"); \
      return;                                                                             \
    }                                                                                     \
  } while (0)
