// The installed package: `cmake --install` into a temp prefix, then the example in
// examples/pipeline/ is configured with find_package(prtbake), built against the
// install only, and run on an EXR written here. Its irradiance must match the
// white furnace and the CLI's output for the same file.
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <vector>

#include "prtbake/exr.h"
#include "test_common.h"

using namespace prtbake;
using namespace prtbake::test;

namespace {

const double kPi = 3.14159265358979323846;

// Runs a shell command, returns its exit code; its output goes to `log`.
int shell(const std::string& cmd, const std::string& log) {
  const int st = std::system((cmd + " >'" + log + "' 2>&1").c_str());
  return WIFEXITED(st) ? WEXITSTATUS(st) : 128;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

nlohmann::json readJson(const std::string& path) { return nlohmann::json::parse(slurp(path)); }

}  // namespace

TEST_CASE("installed package: find_package(prtbake) builds and runs the pipeline example", "[install]") {
  const std::string dir = tempDir("install");
  const std::string prefix = dir + "/prefix", exampleBuild = dir + "/example-build";
  const std::string cmake = std::string("'") + PRTBAKE_CMAKE_COMMAND + "'";

  REQUIRE(shell(cmake + " --install '" + PRTBAKE_BUILD_DIR + "' --prefix '" + prefix + "'", dir + "/install.log") == 0);
  CHECK(fileExists(prefix + "/bin/prtbake"));
  CHECK(fileExists(prefix + "/include/prtbake/runtime.h"));
  CHECK(fileExists(prefix + "/include/prtbake/env_sh.h"));
  CHECK(fileExists(prefix + "/lib/libprtbake.a"));
  REQUIRE(fileExists(prefix + "/lib/cmake/prtbake/prtbakeConfig.cmake"));
  // The export must not carry this machine's libstb path: the config finds stb itself.
  const std::string targets = slurp(prefix + "/lib/cmake/prtbake/prtbakeTargets.cmake");
  CHECK(targets.find("libstb") == std::string::npos);
  CHECK(targets.find("prtbake::stb") != std::string::npos);

  // Configure and build the example against the prefix only (no build-tree paths).
  const int configured = shell(cmake + " -S '" + PRTBAKE_SOURCE_DIR + "/examples/pipeline' -B '" + exampleBuild +
                                   "' -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH='" + prefix + "'",
                               dir + "/configure.log");
  INFO(slurp(dir + "/configure.log"));
  REQUIRE(configured == 0);
  const int built = shell(cmake + " --build '" + exampleBuild + "'", dir + "/build.log");
  INFO(slurp(dir + "/build.log"));
  REQUIRE(built == 0);

  // A constant white lat-long: radiance L00 = ∫ Y00 dω = 4π·Y00 = 2√π, irradiance
  // E00 = π·L00; with exact texel solid angles the sum of Ω is 4π to rounding.
  const int w = 64, h = 32;
  const std::vector<float> one(size_t(w) * h, 1.0f);
  ExrWriteOptions o;
  o.envmap = 0;  // lat-long
  writeExr(dir + "/white.exr", w, h, {{"R", one.data()}, {"G", one.data()}, {"B", one.data()}}, o);

  const std::string out = dir + "/white_irradiance.json";
  const int ran = shell("'" + exampleBuild + "/env_irradiance' '" + dir + "/white.exr' '" + out + "'", dir + "/run.log");
  INFO(slurp(dir + "/run.log"));
  REQUIRE(ran == 0);
  const nlohmann::json j = readJson(out);
  CHECK(j.at("order") == 3);
  CHECK(j.at("quantity") == "irradiance");
  const auto& c = j.at("coefficients");
  REQUIRE(c.size() == 9);
  // float32 kernel sums over 2048 texels, summed in double on the host.
  const double kFurnaceRelTol = 1e-5;
  const double e00 = kPi * 2.0 * std::sqrt(kPi);
  for (int ch = 0; ch < 3; ++ch) CHECK(c[0][ch].get<double>() == Approx(e00).epsilon(kFurnaceRelTol));

  // The same projection through the CLI: one library, one device, so the example's
  // coefficients equal the CLI's (only JSON number printing could differ).
  const CliResult cli = runCli("env '" + dir + "/white.exr' -o '" + dir + "/cli.json' --quantity irradiance --quiet");
  INFO(cli.output);
  REQUIRE(cli.exitCode == 0);
  const nlohmann::json cliJson = readJson(dir + "/cli.json");
  const auto& ref = cliJson.at("coefficients");
  const double kSameComputationTol = 1e-12;
  for (size_t i = 0; i < 9; ++i)
    for (int ch = 0; ch < 3; ++ch)
      CHECK(c[i][ch].get<double>() == Approx(ref[i][ch].get<double>()).margin(kSameComputationTol * e00));

  // The Python module, installed under the prefix into that Python's site-packages: imported
  // from there alone (not the build tree), it projects the same file to the same coefficients.
  if (std::string(PRTBAKE_PYTHON_INSTALL_DIR).empty()) {
    WARN("the Python module is not built here: its installation is not checked");
    return;
  }
  const std::string site = prefix + "/" + PRTBAKE_PYTHON_INSTALL_DIR;
  CHECK(fileExists(site + "/prtbake/__init__.py"));
  CHECK(fileExists(site + "/prtbake/__init__.pyi"));
  const int imported = shell("cd '" + dir + "' && PYTHONPATH='" + site + "' PRTBAKE_DEVICE=cpu '" + PRTBAKE_PYTHON +
                                 "' -c \"import json, prtbake; assert prtbake.__file__.startswith('" + site +
                                 "'), prtbake.__file__; r = prtbake.env('white.exr', quantity='irradiance'); "
                                 "json.dump(r.coeffs.tolist(), open('py.json', 'w'))\"",
                             dir + "/python.log");
  INFO(slurp(dir + "/python.log"));
  REQUIRE(imported == 0);
  const nlohmann::json py = readJson(dir + "/py.json");
  for (size_t i = 0; i < 9; ++i)
    for (int ch = 0; ch < 3; ++ch) CHECK(py[i][ch].get<double>() == ref[i][ch].get<double>());
}
