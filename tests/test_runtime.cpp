// OpenCL runtime: device listing and choice, kernel source expansion with #line,
// build errors that carry the log and the device name, program caching.
#include <catch2/catch.hpp>

#include <cstdlib>
#include <fstream>

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
