// The bad-input corpus (tests/corpus/, written by corpus/make_corpus.cpp): empty,
// truncated, garbage and lying files of every supported format, fed to the CLI.
// The contract (docs/conventions.md "Errors"): no crash, no hang, exit code 1 (2 for usage),
// an error line "prtbake: error: <file>: ..." and no output file, not even a temp.
#include <catch2/catch.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <vector>

#include "prtbake/exr.h"
#include "job_test_helpers.h"
#include "test_common.h"

namespace fs = std::filesystem;
using namespace prtbake;
using namespace prtbake::test;

namespace {

// The slowest corpus case takes well under a second; a hang (a decoder looping on a
// truncated file) shows up as exit code 124 instead of stalling the suite.
const char* const kTimeout = "timeout 60 ";

const std::string kCorpus = std::string(PRTBAKE_TEST_SOURCE_DIR) + "/corpus";

std::string cli() { return std::string(kTimeout) + "'" + PRTBAKE_CLI_PATH + "' "; }

// Corpus files with one of the extensions, sorted.
std::vector<std::string> corpusFiles(const std::vector<std::string>& exts, const std::string& prefix = "") {
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(kCorpus)) {
    const std::string name = e.path().filename().string();
    if (name.rfind(prefix, 0) != 0) continue;
    if (std::find(exts.begin(), exts.end(), e.path().extension().string()) != exts.end())
      out.push_back(e.path().string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Every file under `dir`, hidden ones included (temp and staging files are hidden).
std::vector<std::string> filesUnder(const std::string& dir) {
  std::vector<std::string> out;
  if (!fs::exists(dir)) return out;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (!e.is_directory()) out.push_back(e.path().string());
  return out;
}

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  size_t start = 0;
  while (start < text.size()) {
    const size_t nl = text.find('\n', start);
    out.push_back(text.substr(start, nl == std::string::npos ? std::string::npos : nl - start));
    if (nl == std::string::npos) break;
    start = nl + 1;
  }
  return out;
}

// A named pipe (opening it for reading waits for a writer) or a link to /dev/zero (reading
// it never ends, and its size is 0) at `path`: before 7 December `env` on either hung, on
// the pipe in open() and on /dev/zero growing its buffer without end.
std::string nonRegularFile(const std::string& path, bool fifo) {
  fs::create_directories(fs::path(path).parent_path());
  fs::remove(path);
  if (fifo)
    REQUIRE(runShell("mkfifo '" + path + "'").exitCode == 0);
  else
    fs::create_symlink("/dev/zero", path);
  return path;
}

void writeWhiteLatLong(const std::string& path) {
  const std::vector<float> one(8 * 4, 1.0f);
  ExrWriteOptions o;
  o.envmap = 0;
  writeExr(path, 8, 4, {{"R", one.data()}, {"G", one.data()}, {"B", one.data()}}, o);
}

}  // namespace

TEST_CASE("corpus: committed and small", "[corpus]") {
  // Kept small so the repository stays light: every case only claims huge sizes.
  const uintmax_t kMaxCorpusBytes = 200 * 1024;
  uintmax_t total = 0;
  size_t count = 0;
  for (const auto& e : fs::directory_iterator(kCorpus)) total += e.file_size(), ++count;
  CHECK(total < kMaxCorpusBytes);
  CHECK(count > 60);
}

TEST_CASE("corpus: env fails cleanly on every bad image", "[corpus]") {
  const std::string dir = tempDir("corpus-env");
  std::vector<std::string> inputs = corpusFiles({".exr", ".hdr", ".png", ".jpg"});
  REQUIRE(inputs.size() >= 25);
  for (const char* ext : {".exr", ".hdr"}) {  // a directory, a pipe, a device where a file is expected
    const std::string d = dir + "/in/directory" + ext;
    fs::create_directories(d);
    inputs.push_back(d);
    inputs.push_back(nonRegularFile(dir + "/in/fifo" + ext, true));
    inputs.push_back(nonRegularFile(dir + "/in/zero" + ext, false));
  }
  for (const auto& input : inputs) {
    INFO(input);
    const std::string outDir = dir + "/out";
    fs::remove_all(outDir);
    fs::create_directories(outDir);
    const CliResult r = runShell(cli() + "env '" + input + "' -o '" + outDir + "/sh.json' --games202 '" + outDir +
                              "/light.txt' --quiet");
    INFO(r.output);
    CHECK(r.exitCode == 1);
    CHECK(r.output.rfind("prtbake: error: " + input + ": ", 0) == 0);
    CHECK(lines(r.output).size() == 1);
    CHECK(filesUnder(outDir).empty());
  }
}

namespace {

// The contract for transport jobs on bad meshes: a clean failure that names the mesh
// (the job id is the file name), no signal, no hang, nothing written.
void expectTransportJobsFailCleanly(const std::string& dir, const std::vector<std::string>& inputs) {
  for (size_t i = 0; i < inputs.size(); ++i) {
    const std::string& input = inputs[i];
    const std::string id = fs::path(input).filename().string();
    INFO(input);
    const std::string jobDir = dir + "/case" + std::to_string(i);  // not named after the mesh
    fs::create_directories(jobDir);
    {
      std::ofstream job(jobDir + "/job.json");
      job << R"({"jobs": [{"id": ")" << id << R"(", "type": "transport", "input": ")" << input
          << R"(", "outputs": {"npy": "out/t.npy", "games202": "out/transport.txt"}}]})" << "\n";
    }
    const CliResult r = runShell(cli() + "run '" + jobDir + "/job.json' --quiet");
    INFO(r.output);
    CHECK((r.exitCode == 1 || r.exitCode == 2));
    CHECK(r.output.rfind("prtbake: error: ", 0) == 0);
    CHECK(r.output.find(id) != std::string::npos);
    CHECK(filesUnder(jobDir + "/out").empty());
  }
}

}  // namespace

TEST_CASE("corpus: transport jobs fail cleanly on every bad mesh", "[corpus]") {
  const std::string dir = tempDir("corpus-mesh");
  std::vector<std::string> inputs = corpusFiles({".glb", ".gltf", ".obj"});
  REQUIRE(inputs.size() >= 20);
  fs::create_directories(dir + "/in/directory.glb");
  inputs.push_back(dir + "/in/directory.glb");
  inputs.push_back(nonRegularFile(dir + "/in/fifo.obj", true));
  inputs.push_back(nonRegularFile(dir + "/in/zero.glb", false));
  expectTransportJobsFailCleanly(dir, inputs);
}

TEST_CASE("corpus: transport jobs fail cleanly on the external bad meshes", "[corpus][data]") {
  std::vector<std::string> inputs;
  for (const char* rel : {"meshes/gltf/BoxBadNormals.glb", "meshes/gltf/BoxWithInfinites.glb"}) {
    inputs.push_back(dataFile(rel));
    PRTBAKE_SKIP_IF_NO_DATA(inputs.back());
  }
  expectTransportJobsFailCleanly(tempDir("corpus-mesh-data"), inputs);
}

TEST_CASE("corpus: run fails cleanly on every bad job file, naming it on every line", "[corpus]") {
  const std::string dir = tempDir("corpus-jobs");
  std::vector<std::string> jobFiles = corpusFiles({".json"}, "job_");
  REQUIRE(jobFiles.size() >= 15);
  for (const auto& src : jobFiles) {
    const std::string name = fs::path(src).filename().string();
    INFO(name);
    const std::string runDir = dir + "/" + fs::path(name).stem().string();
    fs::create_directories(runDir);
    fs::copy_file(src, runDir + "/" + name);
    writeWhiteLatLong(runDir + "/white.exr");  // the input the valid parts of the jobs name
    const std::string path = runDir + "/" + name;
    const CliResult r = runShell(cli() + "run '" + path + "' --quiet");
    INFO(r.output);
    CHECK(r.exitCode == 1);
    const auto ls = lines(r.output);
    CHECK(!ls.empty());
    for (const auto& l : ls) CHECK(l.rfind("prtbake: error: " + path + ": ", 0) == 0);
    CHECK(filesUnder(runDir + "/out").empty());
  }
  // A directory where a job file is expected.
  fs::create_directories(dir + "/directory.json");
  const CliResult r = runShell(cli() + "run '" + dir + "/directory.json' --quiet");
  INFO(r.output);
  CHECK((r.exitCode == 1 || r.exitCode == 2));
  CHECK(r.output.rfind("prtbake: error: " + dir + "/directory.json", 0) == 0);
}

// The readers outside env and the mesh loaders: one error naming the file, exit 1, at once.
TEST_CASE("corpus: every other input refuses a pipe or a device, naming it", "[corpus]") {
  const std::string dir = tempDir("corpus-nonregular");
  {
    std::ofstream tri(dir + "/tri.obj");
    tri << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  }
  for (bool fifo : {true, false}) {
    const std::string tag = fifo ? "fifo" : "zero";
    const std::string json = nonRegularFile(dir + "/" + tag + ".json", fifo);
    const std::string npy = nonRegularFile(dir + "/" + tag + ".npy", fifo);
    const std::string out = dir + "/out-" + tag;
    fs::create_directories(out);
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"rotate '" + json + "' -o '" + out + "/r.json' --euler-zyz 10,20,30", json},
        {"cpca '" + npy + "' -o '" + out + "/c.npz' --clusters 2 --vectors 1", npy},
        {"preview mesh '" + dir + "/tri.obj' --transport '" + npy + "' --env '" + json + "' -o '" + out + "/p.png'", npy},
        {"probes '" + dir + "/tri.obj' --env '" + json + "' -o '" + out + "/probes'", json},
        {"run '" + json + "'", json},
        {"submit slurm '" + json + "' --tasks 2 --dry-run", json}};
    for (const auto& [args, file] : cases) {
      INFO(args);
      const CliResult r = runShell(cli() + args + " --quiet");
      INFO(r.output);
      CHECK(r.exitCode == 1);
      CHECK(r.output.find("prtbake: error: " + file + ": not a regular file") != std::string::npos);
    }
    CHECK(filesUnder(out).empty());
  }
}

// An output path that names an input (the same file, by any path or link), or a package
// directory that holds one, is refused before anything is read or written: `env sky.hdr -o
// sky.hdr` wrote its JSON over the image, a job's environment key was not compared with its
// outputs, `ibl pkg/sky.exr -o pkg` deleted the environment with the previous package, `transport
// tri.gltf -o tri.bin` wrote over the glTF's buffer, and `cpca g.npy -o g.npz` over g.npy's sidecar.
TEST_CASE("an output that names an input is refused, and the input is left as it was", "[corpus]") {
  const std::string dir = tempDir("corpus-overwrite");
  {
    std::ofstream tri(dir + "/tri.obj");
    tri << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  }
  writeWhiteLatLong(dir + "/sky.exr");
  fs::create_symlink("tri.obj", dir + "/same.obj");
  fs::create_symlink("pkg/sky.exr", dir + "/same.exr");
  writeText(dir + "/env.json", "{}");  // the job is refused before it is read
  // A previous ibl package holding the environment: a package replaces its directory whole,
  // and the environment inside was deleted once the new package was in place.
  fs::create_directory(dir + "/pkg");
  writeText(dir + "/pkg/ibl.json", "{}");
  fs::copy_file(dir + "/sky.exr", dir + "/pkg/sky.exr");
  // A glTF's buffer is an input too, and a glossy bake's sidecar is kept from cpca's.
  writeText(dir + "/tri.gltf", R"({"asset": {"version": "2.0"}, "buffers": [{"uri": "tri.bin", "byteLength": 36}]})");
  writeText(dir + "/tri.bin", std::string(36, '\1'));
  REQUIRE(runShell("cd '" + dir + "' && " + cli() + "transport tri.obj -o g.npy --transfer matrix --samples 16 --quiet")
              .exitCode == 0);
  const std::string jobs = dir + "/jobs.json";
  writeText(jobs, R"({"jobs": [{"id": "e", "type": "env", "input": "sky.exr", "outputs": {"json": "./sky.exr"}},
    {"id": "b", "type": "transport", "input": "tri.gltf", "outputs": {"npy": "tri.bin"}},
    {"id": "p", "type": "probes", "input": "tri.obj", "env": "env.json", "bounds": [0, 0, 0, 1, 1, 1],
     "outputs": {"npy": "g.npy", "json": "env.json"}},
    {"id": "i", "type": "ibl", "input": "pkg/sky.exr", "size": 16, "outputs": {"dir": "pkg"}}]})");
  auto bytes = [&] {
    std::string all;
    for (const char* f : {"/tri.obj", "/sky.exr", "/env.json", "/pkg/sky.exr", "/pkg/ibl.json", "/tri.bin", "/g.json"})
      all += readText(dir + f);
    return all;
  };
  const std::string before = bytes();
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"transport tri.obj -o tri.obj", "tri.obj: would overwrite the input tri.obj"},
      {"transport tri.obj -o t.npy --games202 same.obj", "same.obj: would overwrite the input tri.obj"},
      {"transport tri.obj -o tri.obj --transfer matrix --samples 16", "tri.obj: would overwrite the input tri.obj"},
      {"env sky.exr -o s.json --games202 sky.exr", "sky.exr: would overwrite the input sky.exr"},
      {"prefilter sky.exr -o p.ktx2 --json " + dir + "/sky.exr", "would overwrite the input sky.exr"},
      {"preview env sky.exr -o sky.exr", "sky.exr: would overwrite the input sky.exr"},
      {"transport tri.gltf -o tri.bin", "tri.bin: would overwrite the input tri.bin (a file tri.gltf reads)"},
      {"cpca g.npy -o g.npz --clusters 1 --vectors 1", "g.npz: its sidecar would replace g.json, the sidecar of the input"},
      {"ibl pkg/sky.exr -o pkg --size 16", "pkg: would delete the input pkg/sky.exr, which lies inside it"},
      {"ibl same.exr -o ./pkg/ --size 16", "./pkg/: would delete the input same.exr, which lies inside it"},
      {"run jobs.json", "job 'e': outputs.json: would overwrite the input " + dir + "/sky.exr"},
      {"run jobs.json", "job 'b': outputs.npy: would overwrite the input " + dir + "/tri.bin (a file " + dir + "/tri.gltf reads)"},
      {"run jobs.json", "job 'p': outputs.json: would overwrite the input " + dir + "/env.json"},
      {"run jobs.json", "job 'i': outputs.dir: would delete the input " + dir + "/pkg/sky.exr, which lies inside it"}};
  for (const auto& [args, what] : cases) {
    INFO(args);
    const CliResult r = runShell("cd '" + dir + "' && " + cli() + args + " --quiet");
    INFO(r.output);
    CHECK(r.exitCode == (args.rfind("run", 0) == 0 ? 1 : 2));
    CHECK(r.output.find(what) != std::string::npos);
    CHECK(bytes() == before);
  }
}

// Two outputs of one command that name the same file: one replaced the other without a word
// (`transport -o t.npy --games202 t.json` kept the sidecar, not the GAMES202 text).
TEST_CASE("two outputs of one command that are the same file are refused, and neither is written", "[corpus]") {
  const std::string dir = tempDir("corpus-two-outputs");
  {
    std::ofstream tri(dir + "/tri.obj");
    tri << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  }
  writeWhiteLatLong(dir + "/sky.exr");
  REQUIRE(runShell("cd '" + dir + "' && " + cli() + "transport tri.obj -o g.npy --transfer matrix --samples 16 --quiet")
              .exitCode == 0);
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"transport tri.obj -o t.npy --games202 t.json", "t.json: is both the games202 and the json output"},
      {"transport tri.obj -o t.npy --games202 ./t.npy", "t.npy: is both the games202 and the npy output"},
      {"transport tri.obj -o t.json --transfer matrix --samples 16", "t.json: is both the json and the npy output"},
      {"env sky.exr -o t.json --games202 ./t.json", "t.json: is both the games202 and the json output"},
      {"prefilter sky.exr -o t.ktx2 --json t.ktx2", "t.ktx2: is both the json and the ktx2 output"},
      {"cpca g.npy -o t.json --clusters 1 --vectors 1", "t.json: is both the npz and the json output"}};
  for (const auto& [args, what] : cases) {
    INFO(args);
    const CliResult r = runShell("cd '" + dir + "' && " + cli() + args + " --quiet");
    INFO(r.output);
    CHECK(r.exitCode == 2);
    CHECK(r.output.find(what) != std::string::npos);
    for (const char* f : {"/t.npy", "/t.json", "/t.ktx2"}) CHECK_FALSE(fileExists(dir + f));
  }
}

TEST_CASE("limits: a header that claims a huge image fails before allocating and states the limit", "[corpus]") {
  const std::string dir = tempDir("corpus-limits");
  // The corpus headers claim 65535² (JPEG), 200000×100000 (Radiance) and 2³²×32 (OpenEXR)
  // over a few hundred bytes: refused from the header and the file's size (a file too short
  // for its claim), before the input memory limit is even asked.
  for (const char* name : {"huge_header.jpg", "huge_header.hdr", "extreme_window.exr"}) {
    const std::string input = kCorpus + "/" + name;
    INFO(input);
    const CliResult r = runShell(cli() + "env '" + input + "' -o '" + dir + "/sh.json' --quiet");
    INFO(r.output);
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.output, Catch::Contains("truncated"));
  }
  // The limit is configurable: a 64×32 float lat-long (24 KiB decoded) loads by default
  // and is refused under a limit of 0.01 MiB, which the message states.
  const std::vector<float> one(64 * 32, 1.0f);
  ExrWriteOptions o;
  o.envmap = 0;
  writeExr(dir + "/small.exr", 64, 32, {{"R", one.data()}, {"G", one.data()}, {"B", one.data()}}, o);
  CHECK(runShell(cli() + "env '" + dir + "/small.exr' -o '" + dir + "/ok.json' --quiet").exitCode == 0);
  const CliResult r = runShell("PRTBAKE_INPUT_LIMIT_MB=0.01 " + cli() + "env '" + dir + "/small.exr' -o '" + dir +
                               "/no.json' --quiet");
  INFO(r.output);
  CHECK(r.exitCode == 1);
  CHECK_THAT(r.output, Catch::Contains("more than the input memory limit of 0.01 MiB"));
  CHECK_FALSE(fileExists(dir + "/no.json"));
}

TEST_CASE("limits: a device allocation that fails names the device and leaves no output", "[corpus]") {
  // PoCL's POCL_MEMORY_LIMIT=1 gives its CPU device 1 GiB of global memory and a largest
  // allocation of 256 MiB; the preview of an 8192×4096 float32 lat-long projects it whole, from
  // a 384 MiB buffer of texels (a half file would be read as halves: 192 MiB; `prtbake env`
  // reads a lat-long OpenEXR file in bands of 32 MiB).
  const std::string dir = tempDir("corpus-device-memory");
  const int w = 8192, h = 4096;
  {
    const std::vector<float> one(size_t(w) * h, 0.5f);
    ExrWriteOptions o;
    o.envmap = 0;
    writeExr(dir + "/big.exr", w, h, {{"R", one.data()}, {"G", one.data()}, {"B", one.data()}}, o);
  }
  const CliResult r = runShell("POCL_MEMORY_LIMIT=1 " + cli() + "preview env '" + dir + "/big.exr' -o '" + dir +
                               "/out/env.png' --device cpu --quiet");
  INFO(r.output);
  CHECK(r.exitCode == 1);
  CHECK(lines(r.output).size() == 1);
  CHECK_THAT(r.output, Catch::StartsWith("prtbake: error: ") && Catch::Contains("(Portable Computing Language)") &&
                           Catch::Contains("out of device memory"));
  CHECK(filesUnder(dir + "/out").empty());
  // `prtbake env` on the same file and device: bands of 32 MiB fit.
  const CliResult banded = runShell("POCL_MEMORY_LIMIT=1 " + cli() + "env '" + dir + "/big.exr' -o '" + dir +
                                    "/sh.json' --device cpu --quiet");
  INFO(banded.output);
  CHECK(banded.exitCode == 0);
  CHECK(fileExists(dir + "/sh.json"));
}
