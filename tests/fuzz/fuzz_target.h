// Fuzz targets: one per parser that a user's file reaches (tests/fuzz/README.md).
//
// Each fuzz_*.cpp defines its entry point with PRTBAKE_FUZZ_TARGET(name). Built with
// -DPRTBAKE_FUZZ=ON (clang, libFuzzer, ASan + UBSan) the macro defines libFuzzer's
// LLVMFuzzerTestOneInput; in the ordinary test build (PRTBAKE_FUZZ_REPLAY) it
// registers the function instead, and tests/test_fuzz_replay.cpp runs every seed and
// every regression input of every target through it.
//
// The contract each target checks, beyond "no crash, no leak, no undefined
// behaviour": a bad input fails with a prtbake::Error whose subject is the file (or
// directory) that was read and whose message is one line; anything else (a
// std::exception from a library, bad_alloc) escapes, terminates the process and
// counts as a finding. Inputs that load must satisfy the product's invariants.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "prtbake/error.h"

namespace prtbake::fuzz {

using TargetFn = int (*)(const uint8_t* data, size_t size);

// A finding that is not a crash: prints why and aborts, so that libFuzzer saves the input.
[[noreturn]] inline void fail(const std::string& why) {
  std::fprintf(stderr, "fuzz contract violated: %s\n", why.c_str());
  std::fflush(stderr);
  std::abort();
}

// A per-process scratch directory (in /dev/shm when it exists: a file is written per
// input), emptied of the previous input's files by clear().
const std::string& scratchDir();
void clearScratch();
// Writes bytes to scratchDir()/name and returns the path.
std::string writeScratch(const std::string& name, const std::string& bytes);

// Splits `data` into `count` parts: each part but the last is preceded by its length
// (4 bytes, little-endian, clamped to what is left); the last takes the rest.
std::vector<std::string> splitParts(const uint8_t* data, size_t size, size_t count);

// Runs `load`; a prtbake::Error must name `subject` (or a file under it) and be one
// line. Returns true when `load` succeeded.
template <class F>
bool expectCleanFailure(const std::string& subject, F&& load) {
  try {
    load();
    return true;
  } catch (const Error& e) {
    const std::string what = e.what();
    if (e.subject().compare(0, subject.size(), subject) != 0)
      fail("error subject '" + e.subject() + "' is not '" + subject + "': " + what);
    if (what.find('\n') != std::string::npos || what.find('\r') != std::string::npos)
      fail("error message spans lines: " + what);
    return false;
  }
}

#ifdef PRTBAKE_FUZZ_REPLAY
struct Registrar {
  Registrar(const char* name, TargetFn fn);
};
struct Target {
  std::string name;
  TargetFn fn;
};
std::vector<Target>& targets();
#define PRTBAKE_FUZZ_TARGET(name)                                             \
  static int name##TestOneInput(const uint8_t* data, size_t size);           \
  static ::prtbake::fuzz::Registrar name##Registrar(#name, name##TestOneInput); \
  static int name##TestOneInput(const uint8_t* data, size_t size)
#else
#define PRTBAKE_FUZZ_TARGET(name) extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
#endif

}  // namespace prtbake::fuzz
