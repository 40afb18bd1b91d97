// OpenCL runtime: device listing and choice, kernel source expansion with #line,
// build errors that carry the log and the device name, program caching.
#include <catch2/catch.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <vector>

#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/hash.h"
#include "prtbake/runtime.h"
#include "test_common.h"

using namespace prtbake;

TEST_CASE("Devices are listed and specs resolve", "[runtime]") {
  const auto devices = listDevices();
  REQUIRE_FALSE(devices.empty());
  const int cpu = resolveDevice("cpu");
  REQUIRE(devices[size_t(cpu)].type == "cpu");
  REQUIRE(resolveDevice("0") == 0);
  REQUIRE_THROWS_AS(resolveDevice("banana"), UsageError);
  REQUIRE_THROWS_AS(resolveDevice("99"), UsageError);
  ::setenv("PRTBAKE_DEVICE", "cpu", 1);
  REQUIRE(resolveDevice("") == cpu);
  ::unsetenv("PRTBAKE_DEVICE");
}

TEST_CASE("Kernel sources expand includes once, with #line naming each file", "[runtime]") {
  const std::string src = kernelSource("sh_eval.cl");
  REQUIRE(src.find("#line 1 \"") == 0);
  REQUIRE(src.find("sh.clh\"") != std::string::npos);
  REQUIRE(src.find("sh_eval_dirs") != std::string::npos);
  // After the included header, numbering resumes in the including file.
  REQUIRE(src.find("#line 3 \"") != std::string::npos);
  REQUIRE_THROWS_AS(kernelSource("no_such_kernel.cl"), DeviceError);
}

TEST_CASE("A kernel build error shows the build log, the file and the device", "[runtime]") {
  const std::string dir = test::tempDir("brokenkernel");
  std::ofstream(dir + "/broken.cl") << "// a deliberately broken kernel\n__kernel void k(__global float* x) {\n"
                                       "  x[0] = undefined_symbol;\n}\n";
  ::setenv("PRTBAKE_KERNEL_DIR", dir.c_str(), 1);
  Runtime rt("cpu");
  try {
    rt.program("broken.cl");
    FAIL("the build should have failed");
  } catch (const DeviceError& e) {
    const std::string msg = e.what();
    INFO(msg);
    REQUIRE(msg.find("broken.cl") != std::string::npos);           // file, via #line
    REQUIRE(msg.find(":3:") != std::string::npos);                 // the offending line
    REQUIRE(msg.find("undefined_symbol") != std::string::npos);    // the log itself
    REQUIRE(msg.find(rt.info().name.substr(0, 10)) != std::string::npos);  // device name
  }
  ::unsetenv("PRTBAKE_KERNEL_DIR");
}

TEST_CASE("Programs are cached per (file, options)", "[runtime]") {
  Runtime rt("cpu");
  cl::Program a = rt.program("sh_eval.cl", "-DX=1");
  const double t = rt.buildSeconds();
  cl::Program b = rt.program("sh_eval.cl", "-DX=1");
  REQUIRE(a() == b());
  REQUIRE(rt.buildSeconds() == t);
  cl::Program c = rt.program("sh_eval.cl", "-DX=2");
  REQUIRE(c() != a());
}

TEST_CASE("A shared, empty kernel cache: processes that start at once all build, agree and fill it", "[runtime][cli]") {
  // A cluster shares POCL_CACHE_DIR (README): four processes start together on an empty
  // cache, each builds the table's program and writes PoCL's entries (PoCL writes each
  // through a temporary file and a rename). All must succeed with the same bytes, and a
  // later process must find the entries (no new ones) and agree too.
  const std::string dir = test::tempDir("sharedcache"), cache = dir + "/pocl";
  auto q = [](const std::string& s) { return "'" + s + "'"; };
  std::string cmd = "cd " + q(dir) + " && for i in 1 2 3 4 5; do mkdir -p p$i; done && for i in 1 2 3 4; do (POCL_CACHE_DIR=" + q(cache) +
                    " '" + PRTBAKE_CLI_PATH + "' lut --size 16 --samples 256 -o p$i/t.exr --quiet; echo $? > rc$i) & done; wait";
  REQUIRE(test::runShell(cmd).exitCode == 0);
  const std::string first = readFile(dir + "/p1/t.exr");
  REQUIRE(!first.empty());
  for (int i = 1; i <= 4; ++i) {
    INFO("process " << i);
    CHECK(readFile(dir + "/rc" + std::to_string(i)) == "0\n");
    CHECK(readFile(dir + "/p" + std::to_string(i) + "/t.exr") == first);
  }
  auto entries = [&] {
    size_t n = 0;
    // PoCL also leaves an empty tempfile_* in the cache's root per process: not an entry.
    for (const auto& e : std::filesystem::recursive_directory_iterator(cache))
      n += e.is_regular_file() && e.path().filename().string().rfind("tempfile_", 0) != 0 ? 1 : 0;
    return n;
  };
  const size_t filled = entries();
  CHECK(filled > 0);
  const auto r = test::runShell("cd " + q(dir) + " && POCL_CACHE_DIR=" + q(cache) + " '" +
                                PRTBAKE_CLI_PATH + "' lut --size 16 --samples 256 -o p5/t.exr --quiet");
  CHECK(r.exitCode == 0);
  CHECK(readFile(dir + "/p5/t.exr") == first);
  CHECK(entries() == filled);
}

TEST_CASE("SHA-256 matches the FIPS 180-4 examples", "[hash]") {
  REQUIRE(sha256Hex("abc", 3) == "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  REQUIRE(sha256Hex("", 0) == "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  const std::string two = "abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq";
  REQUIRE(sha256Hex(two.data(), two.size()) == "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
}

TEST_CASE("CLI: devices, version, help and usage errors", "[cli]") {
  auto r = test::runCli("devices");
  REQUIRE(r.exitCode == 0);
  REQUIRE(r.output.find("* ") != std::string::npos);
  REQUIRE(test::runCli("--version").exitCode == 0);
  REQUIRE(test::runCli("env --help").exitCode == 0);
  r = test::runCli("frobnicate");
  REQUIRE(r.exitCode == 2);
  r = test::runCli("env x.exr -o y.json --ordr 3");
  REQUIRE(r.exitCode == 2);
  REQUIRE(r.output.find("--ordr") != std::string::npos);
  r = test::runCli("devices --device banana");
  REQUIRE(r.exitCode == 2);
}
