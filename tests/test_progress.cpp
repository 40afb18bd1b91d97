// Progress lines of `prtbake run` on stderr: off when stderr is not a terminal
// (as here, under ctest), on with --progress, even with --quiet.
#include <catch2/catch.hpp>

#include "job_test_helpers.h"

using namespace prtbake::test;

TEST_CASE("run: --progress prints one line per job, and no progress without it off a terminal", "[jobs][progress]") {
  const std::string dir = tempDir("progress");
  writeLatLongExr(dir + "/sky.exr");
  writeJobFile(dir + "/jobs.json", {envJob("a", "sky.exr", "out/a.json"), envJob("b", "sky.exr", "out/b.json"),
                                    envJob("c", "sky.exr", "out/c.json")});
  const CliResult plain = runCli("run '" + dir + "/jobs.json' --force");
  INFO(plain.output);
  REQUIRE(plain.exitCode == 0);
  CHECK(plain.output.find("[1/3]") == std::string::npos);

  const CliResult forced = runCli("run '" + dir + "/jobs.json' --force --progress --quiet");
  INFO(forced.output);
  REQUIRE(forced.exitCode == 0);
  CHECK(forced.output.find("[1/3] a ...\n") != std::string::npos);  // no ETA before a job has run
  CHECK(forced.output.find("[2/3] b ... ETA ") != std::string::npos);
  CHECK(forced.output.find("[3/3] c ... ETA ") != std::string::npos);
  CHECK(forced.output.find("\033[K") == std::string::npos);  // no terminal codes off a terminal
  CHECK(forced.output.find("[ok]") == std::string::npos);     // --quiet still hides status lines
}
