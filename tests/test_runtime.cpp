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

namespace {
// Runs add_index (x[i] += i) on a fresh Runtime over {0.5, 0.5, 0.5, 0.5}.
std::vector<float> runAddIndex() {
  Runtime rt("cpu");
  std::vector<float> x(4, 0.5f);
  cl::Buffer b(rt.context(), CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR, x.size() * 4, x.data());
  cl::Kernel k = rt.kernel("cached.cl", "add_index");
  k.setArg(0, b);
  rt.queue().enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(x.size()));
  rt.queue().enqueueReadBuffer(b, CL_TRUE, 0, x.size() * 4, x.data());
  return x;
}

std::vector<std::string> cacheEntries(const std::string& dir) {
  std::vector<std::string> out;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec))
    if (e.path().extension() == ".bin") out.push_back(e.path().string());
  return out;
}
}  // namespace

TEST_CASE("Program binaries are cached across runtimes, and a damaged entry is rebuilt", "[runtime]") {
  const std::string dir = test::tempDir("programcache");
  std::ofstream(dir + "/cached.cl") << "__kernel void add_index(__global float* x) { x[get_global_id(0)] += (float)get_global_id(0); }\n";
  const std::string cache = dir + "/cache";
  ::setenv("PRTBAKE_KERNEL_DIR", dir.c_str(), 1);
  ::setenv("PRTBAKE_CACHE_DIR", cache.c_str(), 1);
  const std::vector<float> expect{0.5f, 1.5f, 2.5f, 3.5f};
  CHECK(runAddIndex() == expect);  // built from source, binary stored
  const auto entries = cacheEntries(cache);
  REQUIRE(entries.size() == 1);
  CHECK(runAddIndex() == expect);  // from the stored binary
  CHECK(cacheEntries(cache).size() == 1);
  std::ofstream(entries[0], std::ios::binary | std::ios::trunc) << "not a device binary";
  CHECK(runAddIndex() == expect);  // the damaged entry is ignored ...
  CHECK(readFile(entries[0]) != "not a device binary");  // ... and replaced
  // A changed source is a different entry.
  std::ofstream(dir + "/cached.cl") << "__kernel void add_index(__global float* x) { x[get_global_id(0)] += 2.0f * (float)get_global_id(0); }\n";
  CHECK(runAddIndex() == std::vector<float>{0.5f, 2.5f, 4.5f, 6.5f});
  CHECK(cacheEntries(cache).size() == 2);
  // "off" disables the cache: a third source builds, and nothing is stored.
  ::setenv("PRTBAKE_CACHE_DIR", "off", 1);
  std::ofstream(dir + "/cached.cl") << "__kernel void add_index(__global float* x) { x[get_global_id(0)] += 3.0f * (float)get_global_id(0); }\n";
  CHECK(runAddIndex() == std::vector<float>{0.5f, 3.5f, 6.5f, 9.5f});
  CHECK(cacheEntries(cache).size() == 2);
  CHECK_FALSE(std::filesystem::exists("off/"));  // not taken as a directory name
  ::unsetenv("PRTBAKE_CACHE_DIR");
  ::unsetenv("PRTBAKE_KERNEL_DIR");
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
