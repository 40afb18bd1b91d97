// Scale-out on a real Slurm cluster: a single-node cluster (tests/slurm/cluster.sh,
// all state in a temp dir) runs `prtbake submit slurm` (an 8-task array job and a
// merge job with afterok), for a large split transport job and for a job file of
// many small jobs; the merged outputs must equal a one-process run bit for bit, also
// when one array task is killed mid-run and requeued (scontrol requeue).
// Skipped, with cluster.sh's reason, where a cluster cannot run (not root, Slurm or
// Munge not installed, no cgroup filesystem, a daemon that exits at once); the
// packages come with scripts/test.sh.
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <thread>
#include <catch2/catch.hpp>

#include "shard_test_helpers.h"

using namespace prtbake;
using namespace prtbake::test;

namespace {

using Clock = std::chrono::steady_clock;

// The whole test (cluster start, two arrays of 8, the reference runs) takes about a
// minute on 2 cores; a job that has not finished after this long has failed.
constexpr double kJobDeadlineSeconds = 150;

std::string q(const std::string& s) { return "'" + s + "'"; }

const std::string kClusterScript = std::string(PRTBAKE_TEST_SOURCE_DIR) + "/slurm/cluster.sh";

// The cluster's lifetime: started in the constructor, stopped (by PID) in the destructor.
struct Cluster {
  std::string dir;
  CliResult start;
  explicit Cluster(const std::string& d) : dir(d) {
    start = runShell(q(kClusterScript) + " start " + q(dir));
    ::setenv("SLURM_CONF", (dir + "/slurm.conf").c_str(), 1);
  }
  ~Cluster() {
    runShell(q(kClusterScript) + " stop " + q(dir));
    ::unsetenv("SLURM_CONF");
  }
  std::string logs() const {
    return runShell("tail -n 20 " + q(dir) + "/slurmctld.log " + q(dir) + "/slurmd.log").output;
  }
};

// Submits `jobFile` as `tasks` shards; returns {array id, merge id}.
std::pair<std::string, std::string> submit(const std::string& jobFile, int tasks) {
  const CliResult r = runCli("submit slurm " + q(jobFile) + " --tasks " + std::to_string(tasks) + " --time 00:10:00");
  INFO(r.output);
  REQUIRE(r.exitCode == 0);
  std::istringstream ss(r.output.substr(r.output.rfind('\n', r.output.size() - 2) + 1));
  std::string array, merge;
  ss >> array >> merge;
  REQUIRE(!array.empty());
  REQUIRE(!merge.empty());
  return {array, merge};
}

// "JobState=..." of a job (or array task "ID_T").
std::string jobState(const std::string& id) {
  const std::string out = runShell("scontrol show job " + id).output;
  const auto at = out.find("JobState=");
  return at == std::string::npos ? "?" : out.substr(at + 9, out.find(' ', at) - at - 9);
}

// Waits until the merge job has left the queue; returns its final state.
std::string waitForMerge(const std::string& array, const std::string& merge) {
  const auto t0 = Clock::now();
  while (std::chrono::duration<double>(Clock::now() - t0).count() < kJobDeadlineSeconds) {
    const CliResult r = runShell("squeue -h -j " + array + "," + merge);
    if (r.exitCode == 0 && r.output.find_first_not_of(" \n") == std::string::npos) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  return jobState(merge);
}

void requireSameBytes(const std::string& a, const std::string& b) {
  INFO(a << " vs " << b);
  const std::string x = readText(a), y = readText(b);
  REQUIRE(!x.empty());
  CHECK(x.size() == y.size());
  CHECK(x == y);
}

// Writes the job file twice, with outputs under ref/ and out/, runs the ref one in one
// process (the result every array must reproduce) and submits the other as 8 tasks.
template <class Jobs>
std::pair<std::string, std::string> runReferenceAndSubmit(const std::string& dir, Jobs&& jobs) {
  writeJobFile(dir + "/ref.json", jobs("ref"));
  writeJobFile(dir + "/jobs.json", jobs("out"));
  const CliResult ref = runCli("run " + q(dir + "/ref.json") + " --quiet");
  INFO(ref.output);
  REQUIRE(ref.exitCode == 0);
  return submit(dir + "/jobs.json", 8);
}
}  // namespace

TEST_CASE("slurm: 8-task arrays and merge equal one process also after a requeued task", "[slurm]") {
  const std::string dir = tempDir("slurm");
  Cluster cluster(dir + "/cluster");
  if (cluster.start.exitCode == 3) {  // cluster.sh's last line says why
    std::string why = cluster.start.output;
    while (!why.empty() && why.back() == '\n') why.pop_back();
    PRTBAKE_SKIP(why.substr(why.rfind('\n') + 1));
  }
  INFO(cluster.start.output);
  REQUIRE(cluster.start.exitCode == 0);

  SECTION("a large split transport job; one task killed mid-run and requeued") {
    writeSceneObj(dir + "/scene.obj", 56, 57);
    auto jobs = [&](const std::string& out) {
      return std::vector<json>{{{"id", "scene"}, {"type", "transport"}, {"input", "scene.obj"}, {"split", true},
                                {"outputs", {{"npy", out + "/scene.npy"}, {"games202", out + "/scene.txt"}}},
                                {"samples", 131072}}};
    };
    const auto [array, merge] = runReferenceAndSubmit(dir, jobs);
    // Catch a task while it computes (its partial result not yet committed) and requeue it.
    std::string victim;
    const auto t0 = Clock::now();
    while (victim.empty() && std::chrono::duration<double>(Clock::now() - t0).count() < 60) {
      const CliResult running = runShell("squeue -h -r -j " + array + " -t R -o %K");
      std::istringstream ss(running.output);
      std::string task;
      if (ss >> task) {
        std::this_thread::sleep_for(std::chrono::milliseconds(400));  // past the OpenCL start-up
        const std::string manifest = dir + "/out/scene.npy.shard-" + task + "-of-8.npy.manifest.json";
        if (!fileExists(manifest) && jobState(array + "_" + task) == "RUNNING") {
          const CliResult rq = runShell("scontrol requeue " + array + "_" + task);
          INFO(rq.output);
          REQUIRE(rq.exitCode == 0);
          // The task may have committed between the check and the requeue (each takes
          // ~1 s of compute here): then it simply runs again and another task is caught.
          if (!fileExists(manifest)) victim = task;  // killed before its commit
          // Slurm makes a requeued job eligible only ~2 minutes later; as an operator
          // would, start it now (once it is pending again).
          const std::string id = array + "_" + task;
          for (int i = 0; i < 100 && jobState(id) != "PENDING"; ++i)
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
          const CliResult now = runShell("scontrol update jobid=" + id + " starttime=now");
          INFO(now.output);
          CHECK(now.exitCode == 0);
        }
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    REQUIRE(!victim.empty());
    const std::string state = waitForMerge(array, merge);
    INFO("merge job " << merge << ": " << state << "\n" << readText(dir + "/.prtbake-slurm-jobs/logs/merge.out")
                      << cluster.logs());
    REQUIRE(state == "COMPLETED");
    CHECK_THAT(runShell("scontrol show job " + array + "_" + victim).output, Catch::Contains("Restarts=1"));
    requireSameBytes(dir + "/ref/scene.npy", dir + "/out/scene.npy");
    requireSameBytes(dir + "/ref/scene.txt", dir + "/out/scene.txt");
  }

  SECTION("a job file of many small jobs") {
    writeLatLongExr(dir + "/sky.exr", 1.0f);
    auto jobs = [&](const std::string& out) {
      std::vector<json> v;
      for (int i = 0; i < 12; ++i) {
        json env = envJob("sky" + std::to_string(i), "sky.exr", out + "/sky" + std::to_string(i) + ".json");
        env["yaw"] = 15.0 * i;
        env["order"] = 2 + i % 4;
        v.push_back(env);
        v.push_back({{"id", "lut" + std::to_string(i)}, {"type", "lut"},
                     {"outputs", {{"exr", out + "/lut" + std::to_string(i) + ".exr"}}},
                     {"size", 8 + i}, {"samples", 32 + 8 * i}});
      }
      return v;
    };
    const auto [array, merge] = runReferenceAndSubmit(dir, jobs);
    const std::string state = waitForMerge(array, merge);
    const std::string mergeLog = readText(dir + "/.prtbake-slurm-jobs/logs/merge.out");
    INFO("merge job " << merge << ": " << state << "\n" << mergeLog << cluster.logs());
    REQUIRE(state == "COMPLETED");
    CHECK_THAT(mergeLog, Catch::Contains("24 jobs: 0 merged, 24 complete, 0 failed"));
    for (int i = 0; i < 12; ++i) {
      requireSameBytes(dir + "/ref/lut" + std::to_string(i) + ".exr", dir + "/out/lut" + std::to_string(i) + ".exr");
      const json a = json::parse(readText(dir + "/ref/sky" + std::to_string(i) + ".json"));
      const json b = json::parse(readText(dir + "/out/sky" + std::to_string(i) + ".json"));
      CHECK(a["coefficients"] == b["coefficients"]);
    }
  }
}
