// prtbake queue: claiming by rename, concurrent workers, stale-claim recovery
// and logs, tested through the built CLI.
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <filesystem>
#include <set>
#include <thread>

#include "job_test_helpers.h"

using namespace prtbake;
using namespace prtbake::test;
namespace fs = std::filesystem;

namespace {

std::string q(const std::string& s) { return "'" + s + "'"; }

std::vector<std::string> listDir(const std::string& dir) {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

size_t countSuffix(const std::vector<std::string>& names, const std::string& suffix) {
  return std::count_if(names.begin(), names.end(), [&](const std::string& n) {
    return n.size() >= suffix.size() && n.compare(n.size() - suffix.size(), suffix.size(), suffix) == 0;
  });
}

std::string hostName() {
  char buf[256] = {};
  ::gethostname(buf, sizeof buf - 1);
  return buf;
}

pid_t deadPid() {
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  ::waitpid(child, nullptr, 0);
  return child;
}

// A job file holding one env job whose outputs are already up to date (so that
// running it needs no product), with absolute paths. Prepared outside the queue.
void prepareUpToDateJobFile(const std::string& work, const std::string& name, const std::string& queueDir) {
  const std::string stem = name.substr(0, name.size() - 5);
  writeText(work + "/" + stem + ".exr", "environment " + stem);
  writeJobFile(work + "/" + name, {envJob(stem, work + "/" + stem + ".exr", work + "/out/" + stem + ".json")});
  fakeCompletedRun(work + "/" + name);
  REQUIRE(::rename((work + "/" + name).c_str(), (queueDir + "/pending/" + name).c_str()) == 0);
}

}  // namespace

TEST_CASE("queue: two workers share 20 job files, none lost, none run twice", "[queue]") {
  const std::string dir = tempDir("queue-two"), work = dir + "/work", spool = dir + "/spool";
  REQUIRE(std::system(("mkdir -p " + q(work + "/out") + " " + q(spool + "/pending")).c_str()) == 0);
  for (int i = 0; i < 20; ++i) prepareUpToDateJobFile(work, "job" + std::to_string(100 + i) + ".json", spool);
  REQUIRE(listDir(spool + "/pending").size() == 20);

  const std::string cli = q(PRTBAKE_CLI_PATH);
  const CliResult r = runCli("queue " + q(spool) + " --drain > " + q(dir + "/w1.txt") + " 2>&1 & " + cli + " queue " +
                             q(spool) + " --drain > " + q(dir + "/w2.txt") + " 2>&1; wait");
  const std::string w1 = readText(dir + "/w1.txt"), w2 = readText(dir + "/w2.txt");
  INFO("worker 1:\n" << w1 << "worker 2:\n" << w2);
  CHECK(r.exitCode == 0);

  const auto done = listDir(spool + "/done");
  CHECK(countSuffix(done, ".json") == 20);
  CHECK(countSuffix(done, ".log") == 20);
  CHECK(listDir(spool + "/pending").empty());
  CHECK(listDir(spool + "/running").empty());
  CHECK(listDir(spool + "/failed").empty());
  // Each file was claimed exactly once, by one of the two workers.
  CHECK(countOf(w1 + w2, "[claimed] ") == 20);
  std::set<std::string> claimed;
  for (const std::string& w : {w1, w2}) {
    std::istringstream ss(w);
    std::string line;
    while (std::getline(ss, line))
      if (line.rfind("[claimed] ", 0) == 0) claimed.insert(line.substr(10, line.find(' ', 10) - 10));
  }
  CHECK(claimed.size() == 20);
  for (int i = 0; i < 20; ++i) {
    const std::string log = readText(spool + "/done/job" + std::to_string(100 + i) + ".log");
    INFO(log);
    CHECK(countOf(log, "[claimed] ") == 1);
    CHECK(countOf(log, "[skipped] job" + std::to_string(100 + i) + " (up to date)") == 1);
    CHECK(countOf(log, "finished ") == 1);
  }
}

TEST_CASE("queue: claims of dead or silent workers are taken back", "[queue]") {
  const std::string dir = tempDir("queue-stale"), work = dir + "/work", spool = dir + "/spool";
  REQUIRE(std::system(("mkdir -p " + q(work + "/out") + " " + q(spool + "/pending") + " " + q(spool + "/running")).c_str()) == 0);
  // Killed local worker: its pid is gone.
  prepareUpToDateJobFile(work, "local.json", spool);
  const std::string localClaim = spool + "/running/local.json." + hostName() + "." + std::to_string(deadPid());
  REQUIRE(::rename((spool + "/pending/local.json").c_str(), localClaim.c_str()) == 0);
  // Worker on another host, silent for longer than --stale-after.
  prepareUpToDateJobFile(work, "remote.json", spool);
  REQUIRE(::rename((spool + "/pending/remote.json").c_str(), (spool + "/running/remote.json.farm-node-7.example.org.4242").c_str()) == 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(3100));
  // A worker on another host that is alive (its claim is fresh): left alone.
  prepareUpToDateJobFile(work, "busy.json", spool);
  const std::string busyClaim = spool + "/running/busy.json.farm-node-8.4343";
  REQUIRE(::rename((spool + "/pending/busy.json").c_str(), busyClaim.c_str()) == 0);

  const CliResult r = runCli("queue " + q(spool) + " --drain --stale-after 2");
  INFO(r.output);
  CHECK(r.exitCode == 0);
  CHECK_THAT(r.output, Catch::Contains("(worker process is gone)"));
  CHECK_THAT(r.output, Catch::Contains("[reclaimed] remote.json.farm-node-7.example.org.4242 (no sign of life for"));
  CHECK(fileExists(spool + "/done/local.json"));
  CHECK(fileExists(spool + "/done/remote.json"));
  CHECK(fileExists(busyClaim));
  CHECK_FALSE(fileExists(spool + "/done/busy.json"));
}

TEST_CASE("queue: a job file with problems ends in failed/ with a log naming them", "[queue]") {
  const std::string dir = tempDir("queue-failed"), spool = dir + "/spool";
  REQUIRE(std::system(("mkdir -p " + q(spool + "/pending")).c_str()) == 0);
  writeText(spool + "/pending/typo.json", R"({"jobs": [{"id": "t", "type": "env", "input": "sky.exr", "outputs": {"jsn": "t.json"}}]})");
  writeText(spool + "/pending/syntax.json", R"({"jobs": [)");
  writeText(spool + "/pending/.partial.json", "being written");  // hidden: not submitted yet
  writeText(spool + "/pending/notes.txt", "not a job file");
  const CliResult r = runCli("queue " + q(spool) + " --drain");
  INFO(r.output);
  CHECK(r.exitCode == 1);
  CHECK(fileExists(spool + "/failed/typo.json"));
  CHECK(fileExists(spool + "/failed/syntax.json"));
  const std::string log = readText(spool + "/failed/typo.log");
  CHECK_THAT(log, Catch::Contains("typo.json: job 't': input: file does not exist: " + spool + "/pending/sky.exr"));
  CHECK_THAT(log, Catch::Contains("typo.json: job 't': outputs.jsn: not an output of env jobs (expected json, games202, png) (did you mean 'json'?)"));
  CHECK_THAT(readText(spool + "/failed/syntax.log"), Catch::Contains("parse error at line 1"));
  CHECK(fileExists(spool + "/pending/.partial.json"));
  CHECK(fileExists(spool + "/pending/notes.txt"));
}

TEST_CASE("queue: usage errors", "[queue]") {
  CHECK(runCli("queue").exitCode == 2);
  CHECK(runCli("queue /tmp --poll never").exitCode == 2);
  CHECK(runCli("queue /nonexistent/prtbake-spool --drain").exitCode == 1);
}

// ---- with the env product ----

TEST_CASE("queue: env job files run and land in done/ with their outputs", "[queue][env]") {
  const std::string dir = tempDir("queue-env"), spool = dir + "/spool";
  REQUIRE(std::system(("mkdir -p " + q(spool + "/pending") + " " + q(dir + "/inputs")).c_str()) == 0);
  for (int i = 0; i < 4; ++i) {
    const std::string id = "sky" + std::to_string(i);
    writeLatLongExr(dir + "/inputs/" + id + ".exr", 0.5f + i);
    // Relative paths in a queued file resolve against spool/pending.
    writeJobFile(dir + "/" + id + ".json", {envJob(id, "../../inputs/" + id + ".exr", "../../out/" + id + ".json")});
    REQUIRE(::rename((dir + "/" + id + ".json").c_str(), (spool + "/pending/" + id + ".json").c_str()) == 0);
  }
  const CliResult r = runCli("queue " + q(spool) + " --drain");
  INFO(r.output);
  CHECK(r.exitCode == 0);
  for (int i = 0; i < 4; ++i) {
    const std::string id = "sky" + std::to_string(i);
    CHECK(fileExists(spool + "/done/" + id + ".json"));
    CHECK(fileExists(dir + "/out/" + id + ".json"));
    CHECK(fileExists(dir + "/out/" + id + ".json.manifest.json"));
    CHECK_THAT(readText(spool + "/done/" + id + ".log"), Catch::Contains("[ok] " + id + " ("));
  }
  CHECK(countOf(r.output, "[claimed] ") == 4);
}
