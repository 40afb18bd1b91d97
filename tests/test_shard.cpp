// Scale-out: a job file run as N shards and merged gives the one-process result
// bit for bit; merge refuses incomplete or failed shards and names them; a shard
// rerun writes the same partial bytes (docs/scaleout.md). Through the built CLI.
#include <cmath>
#include <cstring>
#include <filesystem>
#include <catch2/catch.hpp>

#include "prtbake/error.h"
#include "prtbake/mesh.h"
#include "prtbake/transport.h"
#include "shard_test_helpers.h"

using namespace prtbake;
using namespace prtbake::test;

namespace {

std::string q(const std::string& s) { return "'" + s + "'"; }

// The job file used by every run of a case, writing under `out` (relative).
void writeJobs(const std::string& path, const std::string& out, const std::string& duck) {
  std::vector<json> jobs = {
      envJob("sky", "sky.exr", out + "/sky.json"),
      {{"id", "scene"}, {"type", "transport"}, {"input", "scene.obj"}, {"split", true},
       {"outputs", {{"npy", out + "/scene.npy"}, {"games202", out + "/scene.txt"}, {"json", out + "/scene.meta.json"}}},
       {"samples", 128}, {"order", 3}},
      {{"id", "lut"}, {"type", "lut"}, {"outputs", {{"exr", out + "/lut.exr"}}}, {"size", 16}, {"samples", 64}},
      {{"id", "scene-whole"}, {"type", "transport"}, {"input", "scene.obj"}, {"mode", "unshadowed"},
       {"outputs", {{"npy", out + "/scene_unshadowed.npy"}}}, {"samples", 32}},
  };
  if (!duck.empty())
    jobs.push_back({{"id", "duck"}, {"type", "transport"}, {"input", duck}, {"split", true},
                    {"outputs", {{"npy", out + "/duck.npy"}, {"gltf", out + "/duck.glb"}}}, {"samples", 64}});
  writeJobFile(path, jobs);
}

// The files whose bytes must equal the one-process run's (env and transport JSON
// sidecars carry timings: their coefficients are compared instead).
std::vector<std::string> exactFiles(bool duck) {
  std::vector<std::string> f = {"scene.npy", "scene.txt", "lut.exr", "scene_unshadowed.npy"};
  if (duck) f.insert(f.end(), {"duck.npy", "duck.glb"});
  return f;
}

struct Fixture {
  std::string dir, duck;
  Fixture(const std::string& name) : dir(tempDir(name)), duck(dataFile("meshes/gltf/Duck.glb")) {
    if (duck.empty()) skipPart("the Duck.glb job and its glTF output: " + noDataReason());
    writeLatLongExr(dir + "/sky.exr", 1.0f);
    writeSceneObj(dir + "/scene.obj");
  }
  // Runs the one-process reference into ref/.
  void reference() {
    writeJobs(dir + "/ref.json", "ref", duck);
    const CliResult r = runCli("run " + q(dir + "/ref.json") + " --quiet");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
  }
  std::string jobFile(int n) {
    const std::string path = dir + "/jobs" + std::to_string(n) + ".json";
    writeJobs(path, "s" + std::to_string(n), duck);
    return path;
  }
  void runShards(const std::string& jobFile, int n) {
    for (int i = 0; i < n; ++i) {
      const CliResult r = runCli("run " + q(jobFile) + " --quiet --shard " + std::to_string(i) + "/" + std::to_string(n));
      INFO(r.output);
      REQUIRE(r.exitCode == 0);
    }
  }
  void checkIdentical(const std::string& out) {
    for (const auto& f : exactFiles(!duck.empty())) {
      INFO(f);
      const std::string a = readText(dir + "/ref/" + f), b = readText(dir + "/" + out + "/" + f);
      REQUIRE(!a.empty());
      CHECK(a.size() == b.size());
      CHECK(a == b);
    }
    const json envA = json::parse(readText(dir + "/ref/sky.json")), envB = json::parse(readText(dir + "/" + out + "/sky.json"));
    CHECK(envA["coefficients"] == envB["coefficients"]);
    const json metaA = json::parse(readText(dir + "/ref/scene.meta.json"));
    const json metaB = json::parse(readText(dir + "/" + out + "/scene.meta.json"));
    for (const char* key : {"parameters", "input", "conventions", "samples"}) CHECK(metaA[key] == metaB[key]);
  }
};

}  // namespace

TEST_CASE("shard: 1 or 3 or 8 shards merge to the one-process result bit for bit", "[shard]") {
  Fixture fx("shard-identical");
  fx.reference();
  for (int n : {1, 3, 8}) {
    INFO("shards: " << n);
    const std::string jobFile = fx.jobFile(n);
    fx.runShards(jobFile, n);
    const CliResult m = runCli("merge " + q(jobFile) + " --shards " + std::to_string(n));
    INFO(m.output);
    REQUIRE(m.exitCode == 0);
    CHECK_THAT(m.output, Catch::Contains("[merged] scene (" + std::to_string(n) + " shards"));
    fx.checkIdentical("s" + std::to_string(n));
    // The merged manifest makes the jobs up to date for a plain run.
    const CliResult again = runCli("run " + q(jobFile));
    INFO(again.output);
    CHECK(again.exitCode == 0);
    CHECK(countOf(again.output, "[skipped]") == (fx.duck.empty() ? 4 : 5));
  }
}

TEST_CASE("shard: merge names missing and failed shards and a rerun gives the same partial bytes", "[shard]") {
  Fixture fx("shard-refuse");
  fx.reference();
  const std::string jobFile = fx.jobFile(3);
  fx.runShards(jobFile, 3);
  const std::string partial1 = fx.dir + "/s3/scene.npy.shard-1-of-3.npy";
  const std::string partial2 = fx.dir + "/s3/scene.npy.shard-2-of-3.npy";
  const std::string bytes1 = readText(partial1);
  REQUIRE(!bytes1.empty());

  SECTION("a rerun writes or keeps the same bytes") {
    const CliResult skip = runCli("run " + q(jobFile) + " --shard 1/3");
    CHECK_THAT(skip.output, Catch::Contains("[skipped] scene [shard 1/3] (up to date)"));
    // A staging file of a shard on another host (its pid means nothing here) is left alone.
    const std::string foreign = fx.dir + "/s3/.stage.prtbake-tmp.999999.0.npy.npy";
    writeText(foreign, "being written elsewhere");
    const CliResult force = runCli("run " + q(jobFile) + " --shard 1/3 --force");
    INFO(force.output);
    REQUIRE(force.exitCode == 0);
    CHECK(readText(partial1) == bytes1);
    CHECK(fileExists(foreign));
    // A task killed before its commit leaves nothing; its rerun starts from scratch.
    std::filesystem::remove(partial1);
    std::filesystem::remove(partial1 + ".manifest.json");
    REQUIRE(runCli("run " + q(jobFile) + " --shard 1/3").exitCode == 0);
    CHECK(readText(partial1) == bytes1);
  }

  SECTION("a missing shard") {
    std::filesystem::remove(partial1 + ".manifest.json");
    const CliResult m = runCli("merge " + q(jobFile) + " --shards 3");
    INFO(m.output);
    CHECK(m.exitCode == 1);
    CHECK_THAT(m.output, Catch::Contains("[failed] scene: cannot merge: shard 1/3 missing: no partial result"));
    CHECK_FALSE(fileExists(fx.dir + "/s3/scene.npy"));
    CHECK_FALSE(fileExists(fx.dir + "/s3/scene.npy.manifest.json"));
  }

  SECTION("a failed shard, then its successful rerun") {
    std::filesystem::remove(partial2);
    std::filesystem::remove(partial2 + ".manifest.json");
    std::filesystem::create_directories(partial2);  // the commit's rename fails on it
    const CliResult f = runCli("run " + q(jobFile) + " --shard 2/3");
    INFO(f.output);
    CHECK(f.exitCode == 1);
    CHECK(fileExists(fx.dir + "/s3/scene.npy.shard-2-of-3.failed.json"));
    const CliResult m = runCli("merge " + q(jobFile) + " --shards 3");
    INFO(m.output);
    CHECK(m.exitCode == 1);
    CHECK_THAT(m.output, Catch::Contains("shard 2/3 failed: "));
    std::filesystem::remove(partial2);
    REQUIRE(runCli("run " + q(jobFile) + " --shard 2/3").exitCode == 0);
    CHECK_FALSE(fileExists(fx.dir + "/s3/scene.npy.shard-2-of-3.failed.json"));
    const CliResult ok = runCli("merge " + q(jobFile) + " --shards 3");
    INFO(ok.output);
    CHECK(ok.exitCode == 0);
    fx.checkIdentical("s3");
  }

  SECTION("a partial of another run or a wrong count") {
    writeText(partial1, readText(partial2));  // same size class, other bytes
    const CliResult m = runCli("merge " + q(jobFile) + " --shards 3");
    CHECK(m.exitCode == 1);
    CHECK_THAT(m.output, Catch::Contains("shard 1/3 is not usable"));
    const CliResult four = runCli("merge " + q(jobFile) + " --shards 4");
    CHECK(four.exitCode == 1);
    CHECK_THAT(four.output, Catch::Contains("shard 3/4 missing"));
  }

  SECTION("a whole job whose shard has not run") {
    std::filesystem::remove(fx.dir + "/s3/lut.exr.manifest.json");  // job #3 (k = 2): shard 2/3
    const CliResult m = runCli("merge " + q(jobFile) + " --shards 3");
    CHECK(m.exitCode == 1);
    CHECK_THAT(m.output, Catch::Contains("[failed] lut: shard 2/3 has not completed it (no manifest)"));
  }
}

TEST_CASE("shard: usage errors and jobs that cannot be split", "[shard]") {
  const std::string dir = tempDir("shard-usage");
  writeSceneObj(dir + "/scene.obj");
  writeJobFile(dir + "/jobs.json", {{{"id", "ir"}, {"type", "transport"}, {"input", "scene.obj"}, {"split", true},
                                     {"mode", "interreflected"}, {"outputs", {{"npy", "ir.npy"}}}}});
  const CliResult ir = runCli("run " + q(dir + "/jobs.json") + " --shard 0/2");
  CHECK(ir.exitCode == 1);
  CHECK_THAT(ir.output, Catch::Contains("job 'ir': split: interreflected jobs cannot be split by vertices"));
  for (const char* bad : {"2/2", "1", "a/3", "0/0", "-1/3"}) {
    const CliResult r = runCli("run " + q(dir + "/jobs.json") + " --shard=" + bad);
    INFO(bad << ": " << r.output);
    CHECK(r.exitCode == 2);
  }
  ::unsetenv("SLURM_ARRAY_TASK_ID");
  ::unsetenv("JOB_COMPLETION_INDEX");
  const CliResult noIndex = runCli("run " + q(dir + "/jobs.json") + " --shard auto/4");
  CHECK(noIndex.exitCode == 2);
  CHECK_THAT(noIndex.output, Catch::Contains("auto needs $SLURM_ARRAY_TASK_ID or $JOB_COMPLETION_INDEX"));
  ::setenv("JOB_COMPLETION_INDEX", "1", 1);  // shard 1/2 does not own job 0: nothing to run
  const CliResult indexed = runCli("run " + q(dir + "/jobs.json") + " --shard auto/2");
  ::unsetenv("JOB_COMPLETION_INDEX");
  INFO(indexed.output);
  CHECK_THAT(indexed.output, Catch::Contains("0 jobs: 0 ok"));
  const CliResult dry = runCli("submit slurm " + q(dir + "/jobs.json") + " --tasks 8 --partition batch --time 00:10:00 --dry-run");
  INFO(dry.output);
  CHECK(dry.exitCode == 0);
  CHECK_THAT(dry.output, Catch::Contains("#SBATCH --array=0-7"));
  CHECK_THAT(dry.output, Catch::Contains("--shard \"$SLURM_ARRAY_TASK_ID/8\""));
  CHECK_THAT(dry.output, Catch::Contains(" merge '" + dir + "/jobs.json' --shards 8"));
  CHECK_THAT(dry.output, Catch::Contains("--dependency=afterok:ARRAY_ID"));
  CHECK_THAT(dry.output, Catch::Contains("#SBATCH --partition=batch"));
}

TEST_CASE("shard: a vertex range of computeTransport equals the same vertices of the whole mesh", "[shard]") {
  const std::string dir = tempDir("shard-range");
  writeSceneObj(dir + "/scene.obj");
  const Mesh mesh = loadMesh(dir + "/scene.obj");
  const size_t nv = mesh.vertexCount();
  for (int packet : {16, 8, 0}) {
    TransportOptions o;
    o.samples = 96;  // not a multiple of the packet width
    o.seed = 7;
    o.packetWidth = packet;
    const TransportResult full = computeTransport(runtime(), mesh, o);
    REQUIRE(full.coeffs.size() == nv * 9);
    for (auto [first, count] : {std::pair<size_t, size_t>{0, 1}, {1, 37}, {nv / 3, nv / 3 + 5}, {nv - 13, 13}}) {
      INFO("packet " << packet << ", vertices " << first << " + " << count);
      TransportOptions ro = o;
      ro.firstVertex = first;
      ro.vertexCount = count;
      const TransportResult part = computeTransport(runtime(), mesh, ro);
      REQUIRE(part.vertexCount == count);
      CHECK(part.firstVertex == first);
      REQUIRE(part.coeffs.size() == count * 9);
      CHECK(std::memcmp(part.coeffs.data(), full.coeffs.data() + first * 9, count * 9 * sizeof(float)) == 0);
      CHECK(std::memcmp(part.stdError.data(), full.stdError.data() + first, count * sizeof(float)) == 0);
    }
  }
  TransportOptions o;
  o.samples = 16;
  o.firstVertex = nv;  // an empty range at the end
  CHECK(computeTransport(runtime(), mesh, o).coeffs.empty());
  o.firstVertex = nv + 1;
  CHECK_THROWS_AS(computeTransport(runtime(), mesh, o), UsageError);
  o.firstVertex = 10;
  o.vertexCount = nv;
  CHECK_THROWS_AS(computeTransport(runtime(), mesh, o), UsageError);
  o.firstVertex = 0;
  o.vertexCount = 10;
  o.mode = TransportMode::Interreflected;
  CHECK_THROWS_AS(computeTransport(runtime(), mesh, o), UsageError);
}
