// Benchmark: environment projection throughput and whole-command wall time.
//
//   bench_env [RESULTS.json] [--kernel-only] [--sweep]
//   --sweep: order-3 kernel time for each vector width and rows per work-group, printed only.
// 1. Kernel throughput for 6×2048² float RGB faces (302 MB) at orders 3 and 8:
//    median (and minimum) device time of 15 runs after a warm-up, texels/s and the equivalent
//    read bandwidth (12 bytes per texel).
// 2. `prtbake env` on ../shared/data/envmaps/games202/Skybox2048 (six 2048² JPEGs):
//    first run with an empty kernel cache (cold build), then the median of 5 warm runs.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <sys/stat.h>
#include <vector>

#include "prtbake/env_sh.h"
#include "prtbake/runtime.h"

using namespace prtbake;

static double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

static double wallOf(const std::string& cmd) {
  const auto t0 = std::chrono::steady_clock::now();
  if (std::system(cmd.c_str()) != 0) {
    std::fprintf(stderr, "command failed: %s\n", cmd.c_str());
    std::exit(1);
  }
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

int main(int argc, char** argv) {
  std::string results = "bench/results/env.json";
  bool kernelOnly = false, sweep = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--kernel-only") kernelOnly = true;
    else if (a == "--sweep") sweep = true;
    else if (!a.empty() && a[0] == '-') {
      std::fprintf(stderr, "usage: bench_env [RESULTS.json] [--kernel-only] [--sweep]\n");
      return 2;
    } else results = a;
  }
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

  const std::string data = PRTBAKE_BENCH_DATA_DIR;
  const std::string faces = data + "/envmaps/games202/Skybox2048";
  struct stat st {};
  if (kernelOnly) {
    std::printf("--kernel-only: whole-command timing skipped, no results written\n");
    return 0;
  }
  if (::stat(faces.c_str(), &st) == 0) {
    const std::string cache = "/tmp/prtbake-bench-pocl-cache";
    std::system(("rm -rf " + cache).c_str());
    const std::string cmd = "POCL_CACHE_DIR=" + cache + " '" + std::string(PRTBAKE_CLI_PATH) + "' env '" + faces +
                            "' -o /tmp/prtbake-bench-env.json --quiet --device cpu";
    const double cold = wallOf(cmd);
    std::vector<double> warm;
    for (int i = 0; i < 5; ++i) warm.push_back(wallOf(cmd));
    std::printf("prtbake env Skybox2048: cold %.3f s, warm median %.3f s\n", cold, median(warm));
    char line[256];
    std::snprintf(line, sizeof line,
                  ",\n  \"command\": {\"input\": \"games202/Skybox2048 (6 x 2048^2 JPEG)\", \"cold_s\": %.3f, "
                  "\"warm_median_s\": %.3f}",
                  cold, median(warm));
    json += line;
  } else {
    std::printf("Skybox2048 not found under %s: whole-command timing skipped\n", data.c_str());
  }
  json += "\n}\n";
  std::ofstream(results) << json;
  std::printf("results written to %s\n", results.c_str());
  return 0;
}
