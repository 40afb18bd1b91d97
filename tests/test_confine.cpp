// Confinement of job files to roots (service/confine.h; docs/jobs.md, "A shared queue"):
// every escape route of an input or an output, a link swapped in after the check, the
// queue's owner-only config, and the limits on untrusted job files; through the built CLI.
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <catch2/catch.hpp>
#include <chrono>
#include <filesystem>
#include <thread>

#include "job_test_helpers.h"
#include "prtbake/error.h"

using namespace prtbake;
using namespace prtbake::test;
namespace fs = std::filesystem;

namespace {

std::string q(const std::string& s) { return "'" + s + "'"; }

// Every file below `dir`, as relative paths (links listed, not followed).
std::vector<std::string> tree(const std::string& dir) {
  std::vector<std::string> names;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); it != fs::recursive_directory_iterator(); it.increment(ec))
    names.push_back(it->path().lexically_relative(dir).string());
  std::sort(names.begin(), names.end());
  return names;
}

json lutJob(const std::string& id, const std::string& exr, int size = 8) {
  return {{"id", id}, {"type", "lut"}, {"size", size}, {"samples", 16}, {"outputs", {{"exr", exr}}}};
}

// The error line of job `id` in a run's output ("" when none).
std::string errorOf(const std::string& output, const std::string& id) {
  std::istringstream ss(output);
  std::string line;
  while (std::getline(ss, line))
    if (line.find("error: ") != std::string::npos && line.find("job '" + id + "'") != std::string::npos) return line;
  return "";
}

// A scene: in/ and out/ (the roots), secret/ beside them with a file and an environment,
// and links below the roots pointing into secret/.
struct Scene {
  std::string dir, in, out, secret;
  explicit Scene(const std::string& name) : dir(tempDir(name)), in(dir + "/in"), out(dir + "/out"), secret(dir + "/secret") {
    for (const auto& d : {in, out, secret, in + "/faces", dir + "/jobs"}) fs::create_directories(d);
    writeLatLongExr(in + "/sky.exr");
    writeLatLongExr(secret + "/sky.exr");
    writeText(secret + "/b.bin", std::string(64, '\0'));
    fs::create_symlink("../secret", in + "/link");
    fs::create_symlink("../secret/sky.exr", in + "/sky_link.exr");
    fs::create_symlink("../secret", out + "/link");
    fs::create_symlink("../secret/end.exr", out + "/end.exr");
    for (const char* f : {"px", "nx", "py", "ny", "pz"}) writeLatLongExr(in + "/faces/" + f + ".exr");
    fs::create_symlink("../../secret/sky.exr", in + "/faces/nz.exr");
    writeText(in + "/scene.gltf",
              R"({"asset": {"version": "2.0"}, "buffers": [{"uri": "..%2Fsecret%2Fb.bin", "byteLength": 64}]})");
    // The same in a GLB's JSON chunk (an absolute URI this time).
    std::string chunk = R"({"asset": {"version": "2.0"}, "buffers": [{"uri": ")" + secret + R"(/b.bin", "byteLength": 64}]})";
    while (chunk.size() % 4) chunk += ' ';
    auto le32 = [](uint32_t v) { return std::string{char(v), char(v >> 8), char(v >> 16), char(v >> 24)}; };
    writeText(in + "/scene.glb", "glTF" + le32(2) + le32(uint32_t(20 + chunk.size())) + le32(uint32_t(chunk.size())) +
                                     "JSON" + chunk);
  }
  std::string roots() const { return " --input-root " + q(in) + " --output-root " + q(out); }
};

}  // namespace

TEST_CASE("confinement: every escape route of an input or an output is refused, naming the job, key and root",
          "[confine]") {
  const Scene s("confine-routes");
  struct Route {
    json job;
    std::string key, root;
  };
  const std::vector<Route> routes = {
      {lutJob("out-parent", "../out/../secret/a.exr"), "outputs.exr", s.out},
      {lutJob("out-absolute", s.secret + "/a.exr"), "outputs.exr", s.out},
      {lutJob("out-link-middle", "../out/link/a.exr"), "outputs.exr", s.out},
      {lutJob("out-link-end", "../out/end.exr"), "outputs.exr", s.out},
      {envJob("in-parent", "../in/../secret/sky.exr", "../out/a.json"), "input", s.in},
      {envJob("in-absolute", s.secret + "/sky.exr", "../out/b.json"), "input", s.in},
      {envJob("in-link-middle", "../in/link/sky.exr", "../out/c.json"), "input", s.in},
      {envJob("in-link-end", "../in/sky_link.exr", "../out/d.json"), "input", s.in},
      {envJob("in-face-link", "../in/faces", "../out/e.json"), "input", s.in},
      {{{"id", "in-gltf-buffer"}, {"type", "transport"}, {"input", "../in/scene.gltf"},
        {"outputs", {{"npy", "../out/f.npy"}}}}, "input", s.in},
      {{{"id", "in-glb-buffer"}, {"type", "glossy"}, {"input", "../in/scene.glb"},
        {"outputs", {{"npy", "../out/h.npy"}}}}, "input", s.in},
      {{{"id", "in-preview-env"}, {"type", "transport"}, {"input", "../in/sky.exr"},
        {"preview_env", s.secret + "/sky.exr"}, {"outputs", {{"npy", "../out/g.npy"}, {"png", "../out/g.png"}}}},
       "preview_env", s.in},
  };
  std::vector<json> jobs = {envJob("allowed", "../in/sky.exr", "../out/ok/sky.json")};
  for (const auto& r : routes) jobs.push_back(r.job);
  writeJobFile(s.dir + "/jobs/all.json", jobs);
  const auto secretBefore = tree(s.secret);

  const CliResult r = runCli("run " + q(s.dir + "/jobs/all.json") + s.roots());
  INFO(r.output);
  CHECK(r.exitCode == 1);
  CHECK(r.output.find("[ok] allowed") != std::string::npos);
  CHECK(fs::exists(s.out + "/ok/sky.json"));
  for (const auto& route : routes) {
    const std::string id = route.job["id"];
    const std::string line = errorOf(r.output, id);
    INFO(id << ": " << line);
    CHECK(line.find(": " + route.key + ": ") != std::string::npos);
    CHECK(line.find(fs::canonical(route.root).string()) != std::string::npos);
    CHECK(r.output.find("[failed] " + id + ": invalid job") != std::string::npos);
  }
  CHECK(tree(s.secret) == secretBefore);
  // Nothing but the allowed job's output (and the links the scene made) below out/.
  CHECK(tree(s.out) == std::vector<std::string>{"end.exr", "link", "ok", "ok/sky.json", "ok/sky.json.manifest.json"});

  SECTION("without roots the same file reaches outside (the routes are real)") {
    const CliResult open = runCli("run " + q(s.dir + "/jobs/all.json") + " --jobs allowed,out-link-middle");
    INFO(open.output);
    CHECK(open.exitCode == 0);
    CHECK(fs::exists(s.secret + "/a.exr"));
  }
}

// The runner opens each output directory from its root without following links when the job
// runs, and writes through that descriptor: a link swapped in after the file was validated
// (while an earlier job runs) is refused, and one swapped in while the job itself writes
// cannot redirect its files.
TEST_CASE("confinement: a link swapped in after the check is never followed", "[confine]") {
  const Scene s("confine-swap");
  fs::create_directories(s.out + "/late");
  fs::create_directories(s.in + "/late");
  writeLatLongExr(s.in + "/late/sky.exr");
  // The first job takes long enough (hundreds of ms) for the swap to happen while it runs.
  json slow = lutJob("slow", "../out/slow.exr", 256);
  slow["samples"] = 4096;
  writeJobFile(s.dir + "/jobs/swap.json",
               {slow, lutJob("late-output", "../out/late/lut.exr"), envJob("late-input", "../in/late/sky.exr", "../out/late.json")});
  const std::string log = s.dir + "/events.txt";
  std::atomic<bool> swapped{false};
  std::atomic<double> swapTime{0};
  std::thread swapper([&] {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (std::chrono::steady_clock::now() < deadline) {
      if (readText(log).find("\"event\":\"job_start\"") != std::string::npos) {
        fs::rename(s.out + "/late", s.out + "/late.real");
        fs::create_symlink("../secret", s.out + "/late");
        fs::rename(s.in + "/late", s.in + "/late.real");
        fs::create_symlink("../secret", s.in + "/late");
        swapTime = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
        swapped = true;
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  });
  const CliResult r = runShell("{ " + q(PRTBAKE_CLI_PATH) + " run " + q(s.dir + "/jobs/swap.json") + s.roots() +
                                " --log-json 2> " + q(log) + "; }");
  swapper.join();
  INFO(r.output << readText(log));
  REQUIRE(swapped);
  double slowEnd = 0;
  std::string slowStatus;
  for (const auto& e : events(readText(log)))
    if (e.value("event", "") == "job_end" && e.value("id", "") == "slow") {
      slowEnd = e.value("time", 0.0);
      slowStatus = e.value("status", "");
    }
  REQUIRE(swapTime < slowEnd);  // the premise: the links appeared after the file was checked
  CHECK(slowStatus == "ok");
  CHECK(r.output.find("[failed] late-output: " + s.out + "/late: " + fs::canonical(s.out).string() +
                      "/late is a symbolic link") != std::string::npos);
  CHECK(r.output.find("[failed] late-input: input: " + s.in + "/late/sky.exr: " + fs::canonical(s.in).string() +
                      "/late is a symbolic link") != std::string::npos);
  CHECK(tree(s.secret) == std::vector<std::string>{"b.bin", "sky.exr"});
  CHECK(tree(s.out + "/late.real").empty());
}

TEST_CASE("confinement: a link swapped in while the job writes cannot redirect its outputs", "[confine]") {
  const Scene s("confine-during");
  fs::create_directories(s.out + "/d");
  // exr, json and png are written one after the other; the swap follows the first file seen.
  writeJobFile(s.dir + "/jobs/during.json",
               {{{"id", "lut"}, {"type", "lut"}, {"size", 128}, {"samples", 256},
                 {"outputs", {{"exr", "../out/d/lut.exr"}, {"json", "../out/d/lut.json"}, {"png", "../out/d/lut.png"}}}}});
  std::atomic<bool> stop{false}, swapped{false};
  std::thread swapper([&] {
    while (!stop && !swapped) {
      std::error_code ec;
      for (const auto& e : fs::directory_iterator(s.out + "/d", ec))
        if (e.path().filename().string().rfind(".", 0) == 0) {
          fs::rename(s.out + "/d", s.out + "/d.real");
          fs::create_symlink("../secret", s.out + "/d");
          swapped = true;
          break;
        }
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  });
  const CliResult r = runCli("run " + q(s.dir + "/jobs/during.json") + s.roots());
  stop = true;
  swapper.join();
  INFO(r.output);
  CHECK(tree(s.secret) == std::vector<std::string>{"b.bin", "sky.exr"});
  if (swapped) {  // the files went where the directory went
    CHECK(r.exitCode == 0);
    CHECK(tree(s.out + "/d.real") ==
          std::vector<std::string>{"lut.exr", "lut.exr.manifest.json", "lut.json", "lut.png"});
  } else {
    WARN("the job finished before a staging file was seen; only the outcome without a swap was checked");
    CHECK(r.exitCode == 0);
  }
}

TEST_CASE("confinement: the queue takes its roots from an owner-only queue.json", "[confine][queue]") {
  const Scene s("confine-queue");
  const std::string spool = s.dir + "/spool";
  fs::create_directories(spool + "/pending");
  ::chmod(spool.c_str(), 0755);
  writeText(spool + "/queue.json", json{{"input_roots", {s.in}}, {"output_roots", {s.out}}, {"max_jobs", 4}}.dump());
  ::chmod((spool + "/queue.json").c_str(), 0644);
  writeJobFile(s.dir + "/a.json", {lutJob("ok", s.out + "/q/ok.exr"), lutJob("escape", s.secret + "/q.exr")});
  writeJobFile(s.dir + "/b.json", std::vector<json>(5, lutJob("x", s.out + "/x.exr")));
  fs::rename(s.dir + "/a.json", spool + "/pending/a.json");
  fs::rename(s.dir + "/b.json", spool + "/pending/b.json");

  const CliResult r = runCli("queue " + q(spool) + " --drain");
  INFO(r.output);
  CHECK(r.exitCode == 1);
  const std::string logA = readText(spool + "/failed/a.log"), logB = readText(spool + "/failed/b.log");
  INFO(logA << logB);
  CHECK(logA.find("job 'escape': outputs.exr: " + s.secret + "/q.exr is outside the output roots (" +
                  fs::canonical(s.out).string() + ")") != std::string::npos);
  CHECK(logA.find("[ok] ok") != std::string::npos);
  CHECK(logB.find("5 jobs, more than the limit of 4 for a job file") != std::string::npos);
  CHECK(tree(s.secret) == std::vector<std::string>{"b.bin", "sky.exr"});

  SECTION("a config that others can write is refused, and the worker does not start") {
    ::chmod((spool + "/queue.json").c_str(), 0666);
    const CliResult w = runCli("queue " + q(spool) + " --drain");
    CHECK(w.exitCode != 0);
    CHECK(w.output.find(spool + "/queue.json: writable by group or others") != std::string::npos);
    ::chmod((spool + "/queue.json").c_str(), 0644);
    ::chmod(spool.c_str(), 0777);
    const CliResult d = runCli("queue " + q(spool) + " --drain");
    CHECK(d.exitCode != 0);
    CHECK(d.output.find(spool + ": writable by group or others") != std::string::npos);
    ::chmod(spool.c_str(), 0755);
    fs::rename(spool + "/queue.json", s.dir + "/queue.json");
    fs::create_symlink(s.dir + "/queue.json", spool + "/queue.json");
    const CliResult l = runCli("queue " + q(spool) + " --drain");
    CHECK(l.exitCode != 0);
    CHECK(l.output.find(spool + "/queue.json: not a regular file") != std::string::npos);
  }
}

TEST_CASE("untrusted job files: size, job count, UTF-8 and nesting are checked before anything runs", "[confine]") {
  const std::string dir = tempDir("jobfile-limits");
  const std::string ok = lutJob("a", dir + "/a.exr").dump();
  writeText(dir + "/big.json", "{\"jobs\": [" + ok + "]}" + std::string(size_t(17) << 20, ' '));
  writeText(dir + "/utf8.json", "{\"jobs\": [{\"id\": \"a\xff\", \"type\": \"lut\", \"outputs\": {\"exr\": \"a.exr\"}}]}");
  writeText(dir + "/deep.json", "{\"jobs\": [" + std::string(100, '[') + std::string(100, ']') + "]}");
  std::string many = "{\"jobs\": [";
  for (int i = 0; i < 10001; ++i) many += (i ? ",{}" : "{}");
  writeText(dir + "/many.json", many + "]}");
  const CliResult r = runCli("run " + q(dir + "/big.json") + " " + q(dir + "/utf8.json") + " " + q(dir + "/deep.json") +
                             " " + q(dir + "/many.json"));
  INFO(r.output);
  CHECK(r.exitCode == 1);
  CHECK(r.output.find("big.json: " + std::to_string(fs::file_size(dir + "/big.json")) +
                      " bytes, more than the limit of 16777216 for a job file") != std::string::npos);
  CHECK(r.output.find("utf8.json: parse error at line 1, column 20: syntax error while parsing value - invalid string: ill-formed UTF-8 byte") !=
        std::string::npos);
  CHECK(r.output.find("deep.json: JSON nested deeper than 64 levels") != std::string::npos);
  CHECK(r.output.find("many.json: jobs: 10001 jobs, more than the limit of 10000 for a job file") != std::string::npos);
  CHECK(!fs::exists(dir + "/a.exr"));
  CHECK(r.output.find("0 jobs: 0 ok, 0 skipped, 0 failed") != std::string::npos);
}

// The temp names of atomic writes are predictable (pid and a counter): a link or file that
// someone placed there is never written through, the next name is taken instead.
TEST_CASE("atomic writes never follow a link planted at the temp name", "[confine]") {
  const std::string dir = tempDir("atomic-link");
  writeText(dir + "/victim", "unchanged");
  std::string planted;
  {
    AtomicFile probe(dir + "/out.txt");  // learns this process's next temp name
    const std::string name = probe.tempPath();
    const size_t dot = name.rfind('.');
    planted = name.substr(0, dot + 1) + std::to_string(std::stoi(name.substr(dot + 1)) + 1);
  }
  fs::create_symlink(dir + "/victim", planted);
  writeFileAtomic(dir + "/out.txt", "written");
  CHECK(readText(dir + "/victim") == "unchanged");
  CHECK(readText(dir + "/out.txt") == "written");
  CHECK(fs::is_symlink(planted));
}

// The finished file is renamed into place, so a destination that is a device, a named pipe or
// a directory (or a link to one) would be replaced by a file: on 7 December `prtbake lut -o
// /dev/null`, run as root, left a regular file at /dev/null. Refused before the temp file is
// made, the node left as it was. (Links to /dev/null inside the test's folder: a failing check
// replaces the link, never the device.)
TEST_CASE("atomic writes refuse a destination that is not a regular file, and leave it as it was", "[confine]") {
  const std::string dir = tempDir("atomic-nonregular");
  REQUIRE(runShell("mkfifo '" + dir + "/fifo'").exitCode == 0);
  fs::create_symlink("/dev/null", dir + "/null");
  fs::create_symlink(dir + "/fifo", dir + "/fifo-link");
  fs::create_directories(dir + "/directory");
  for (const char* name : {"null", "fifo", "fifo-link", "directory"}) {
    INFO(name);
    const std::string path = dir + "/" + name;
    const auto before = fs::symlink_status(path).type();
    try {
      writeFileAtomic(path, "written");
      FAIL("no error");
    } catch (const OutputError& e) {
      CHECK(e.subject() == path);
      CHECK(std::string(e.what()).find(std::string(name) == "directory" ? "is a directory" : "not a regular file") !=
            std::string::npos);
    }
    CHECK(fs::symlink_status(path).type() == before);
  }
  size_t entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++entries;
  CHECK(entries == 4);  // no temp file left
  writeText(dir + "/target", "old");  // a link to a regular file is written over, as before
  fs::create_symlink(dir + "/target", dir + "/file-link");
  writeFileAtomic(dir + "/file-link", "new");
  CHECK(readText(dir + "/file-link") == "new");
}

// The job runner stages outputs and renames them into place: on 7 December a job with
// `"exr": "/dev/null"`, run as root, left a regular file at /dev/null and a manifest beside it.
// An output that exists and is not a regular file (links followed) is refused when the job
// file is read (outputs here are links to /dev/null inside the test's folder and a pipe: a
// failing check replaces the link or the pipe, never the device).
TEST_CASE("job runner: an output that is a device or a pipe is refused before the job runs", "[confine]") {
  const std::string dir = tempDir("runner-nonregular");
  fs::create_symlink("/dev/null", dir + "/null.exr");
  REQUIRE(runShell("mkfifo '" + dir + "/fifo.exr'").exitCode == 0);
  writeJobFile(dir + "/jobs.json", {lutJob("to-null", "null.exr"), lutJob("to-fifo", "fifo.exr")});
  const CliResult r = runCli("run '" + dir + "/jobs.json'");
  INFO(r.output);
  CHECK(r.exitCode != 0);
  for (const char* name : {"null.exr", "fifo.exr"}) {
    CHECK(r.output.find("outputs.exr: not a regular file (a device, pipe or socket): " + dir + "/" + name) !=
          std::string::npos);
    CHECK(!fs::exists(dir + "/" + name + ".manifest.json"));
  }
  CHECK(fs::is_symlink(dir + "/null.exr"));
  CHECK(fs::is_fifo(dir + "/fifo.exr"));
}
