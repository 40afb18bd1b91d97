// Benchmark: environment projection throughput, whole-command wall time and peak memory.
//
//   bench_env [RESULTS.json] [--kernel-only] [--sweep]
//   bench_env --write-latlong PATH: only write the float32 8192×4096 lat-long (for bench_ab.sh).
//   --sweep: order-3 kernel time for each vector width and rows per work-group, printed only.
// 1. Kernel throughput for 6×2048² float RGB faces (302 MB) at orders 3 and 8:
//    median (and minimum) device time of 15 runs after a warm-up, texels/s and the equivalent
//    read bandwidth (12 bytes per texel).
// 2. `prtbake env` as a separate process (wall time and peak resident memory from wait4):
//    on ../shared/data/envmaps/games202/Skybox2048 (six 2048² JPEGs), first with an empty
//    kernel cache (cold build), then the median of 5 warm runs; and warm on generated
//    8192×4096 lat-long OpenEXR files, half and float32.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

#include "prtbake/env.h"
#include "prtbake/exr.h"
#include "prtbake/runtime.h"

using namespace prtbake;

static double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

struct Run {
  double wallSeconds;
  double peakMiB;  // the child's maximum resident set size
};

// This process's resident memory (a child's peak includes it until exec).
static double selfRssMiB() {
  std::ifstream f("/proc/self/status");
  for (std::string line; std::getline(f, line);)
    if (line.rfind("VmRSS:", 0) == 0) return std::atof(line.c_str() + 6) / 1024.0;
  return 0;
}

// Runs argv as a child process and measures it.
static Run runCommand(const std::vector<std::string>& args, const std::vector<std::string>& env = {}) {
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = ::fork();
  if (pid == 0) {
    for (const auto& e : env) ::putenv(const_cast<char*>(e.c_str()));
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  int status = 0;
  struct rusage usage {};
  if (pid < 0 || ::wait4(pid, &status, 0, &usage) != pid || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    std::fprintf(stderr, "command failed: %s ...\n", args[0].c_str());
    std::exit(1);
  }
  return {std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), double(usage.ru_maxrss) / 1024.0};
}

// An 8192×4096 lat-long with a smooth sky and a small bright sun, as an OpenEXR file.
static void writeLatLong(const std::string& path, bool half) {
  const int w = 8192, h = 4096;
  std::vector<float> r(size_t(w) * h), g(r.size()), b(r.size());
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const size_t i = size_t(y) * w + size_t(x);
      const float up = 1.0f - float(y) / float(h), sun = (std::abs(x - w / 3) < 8 && std::abs(y - h / 4) < 8) ? 5e4f : 0.0f;
      r[i] = 0.2f + 0.8f * up + sun, g[i] = 0.3f + 0.7f * up + sun, b[i] = 0.5f + up + sun;
    }
  ExrWriteOptions o;
  o.half = half;
  o.envmap = 0;
  writeExr(path, w, h, {{"R", r.data()}, {"G", g.data()}, {"B", b.data()}}, o);
}

// Whole commands, each a child process. Run before this process allocates anything
// large: a child's peak resident memory counts what it shares with its parent at fork.
static std::string measureCommands() {
  const std::string cli = PRTBAKE_CLI_PATH, out = "/tmp/prtbake-bench-env.json";
  const std::string data = PRTBAKE_BENCH_DATA_DIR;
  const std::string faces = data + "/envmaps/games202/Skybox2048";
  std::string json;
  bool first = true;
  auto record = [&](const std::string& input, const std::string& label) {
    const std::string cache = "/tmp/prtbake-bench-env-cache";
    const std::vector<std::string> args = {cli, "env", input, "-o", out, "--quiet", "--device", "cpu"};
    const std::vector<std::string> env = {"POCL_CACHE_DIR=" + cache};
    std::system(("rm -rf " + cache).c_str());
    const Run coldRun = runCommand(args, env);  // builds the programs
    std::vector<double> wall, peak;
    for (int i = 0; i < 5; ++i) {
      const Run r = runCommand(args, env);
      wall.push_back(r.wallSeconds), peak.push_back(r.peakMiB);
    }
    const double peakMax = *std::max_element(peak.begin(), peak.end());
    std::printf("prtbake env %s: cold %.3f s (peak %.0f MiB), warm median %.3f s, peak %.0f MiB (this process: %.0f MiB)\n",
                label.c_str(), coldRun.wallSeconds, coldRun.peakMiB, median(wall), peakMax, selfRssMiB());
    char line[400];
    std::snprintf(line, sizeof line,
                  "%s\n    {\"input\": \"%s\", \"cold_s\": %.3f, \"cold_peak_MiB\": %.1f, \"warm_median_s\": %.3f, "
                  "\"warm_min_s\": %.3f, \"warm_peak_MiB_max\": %.1f}",
                  first ? "" : ",", label.c_str(), coldRun.wallSeconds, coldRun.peakMiB, median(wall),
                  *std::min_element(wall.begin(), wall.end()), peakMax);
    json += line;
    first = false;
  };
  struct stat st {};
  if (::stat(faces.c_str(), &st) == 0) record(faces, "games202/Skybox2048 (6 x 2048^2 JPEG)");
  else std::printf("Skybox2048 not found under %s: its whole-command timing skipped\n", data.c_str());
  for (const bool half : {true, false}) {
    const std::string path = std::string("/tmp/prtbake-bench-latlong-") + (half ? "half" : "float") + ".exr";
    writeLatLong(path, half);
    record(path, std::string("8192x4096 lat-long OpenEXR, ") + (half ? "half" : "float32"));
    std::remove(path.c_str());
  }
  return json;
}

int main(int argc, char** argv) try {
  std::string results = "bench/results/env.json";
  bool kernelOnly = false, sweep = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--write-latlong" && i + 1 < argc) {
      writeLatLong(argv[i + 1], false);
      return 0;
    }
    if (a == "--kernel-only") kernelOnly = true;
    else if (a == "--sweep") sweep = true;
    else if (!a.empty() && a[0] == '-') {
      std::fprintf(stderr, "usage: bench_env [RESULTS.json] [--kernel-only] [--sweep] | --write-latlong PATH\n");
      return 2;
    } else results = a;
  }
  const std::string commands = kernelOnly || sweep ? "" : measureCommands();
  Runtime rt(std::getenv("PRTBAKE_DEVICE") ? "" : "cpu");
  std::string json = "{\n  \"device\": \"" + rt.deviceLabel() + "\",\n  \"kernel\": [\n";

  EnvMap env;
  env.layout = EnvLayout::Cube;
  env.width = env.height = 2048;
  env.rgb.resize(env.texelCount() * 3);
  for (size_t i = 0; i < env.rgb.size(); ++i) env.rgb[i] = float((i * 2654435761u) % 1000) * 1e-3f;
  const double bytes = double(env.rgb.size()) * 4.0;
  if (sweep) {
    for (int vw : {8, 16})
      for (int rows : {1, 4, 16, 64}) {
        EnvProjectOptions o;
        o.order = 3;
        o.vectorWidth = vw;
        o.rowsPerGroup = rows;
        projectEnvironment(rt, env, o);
        std::vector<double> t;
        for (int i = 0; i < 7; ++i) t.push_back(projectEnvironment(rt, env, o).kernelSeconds);
        std::printf("order 3, VW %2d, %2d rows per group: %.2f ms\n", vw, rows, median(t) * 1e3);
      }
    return 0;
  }
  bool first = true;
  for (int order : {3, 8}) {
    EnvProjectOptions o;
    o.order = order;
    projectEnvironment(rt, env, o);  // warm-up: build + first launch
    std::vector<double> t;
    for (int i = 0; i < 15; ++i) t.push_back(projectEnvironment(rt, env, o).kernelSeconds);
    const double s = median(t), best = *std::min_element(t.begin(), t.end());
    std::printf("order %d: kernel median %.2f ms (min %.2f), %.2f Gtexel/s, %.1f GB/s equivalent\n", order,
                s * 1e3, best * 1e3, double(env.texelCount()) / s * 1e-9, bytes / s * 1e-9);
    char line[320];
    std::snprintf(line, sizeof line,
                  "%s    {\"faces\": \"6x2048^2 float RGB\", \"order\": %d, \"kernel_ms_median\": %.3f, "
                  "\"kernel_ms_min\": %.3f, \"texels_per_s\": %.4g, \"equivalent_GB_per_s\": %.2f}",
                  first ? "" : ",\n", order, s * 1e3, best * 1e3, double(env.texelCount()) / s, bytes / s * 1e-9);
    json += line;
    first = false;
  }
  json += "\n  ]";
  if (kernelOnly) {
    std::printf("--kernel-only: whole-command timing skipped, no results written\n");
    return 0;
  }
  json += ",\n  \"command\": [" + commands + "\n  ]\n}\n";
  std::ofstream(results) << json;
  std::printf("results written to %s\n", results.c_str());
  return 0;
} catch (const std::exception& e) {  // a bad argument or a missing device: one line, no abort
  std::fprintf(stderr, "%s: %s\n", argv[0], e.what());
  return 1;
}
