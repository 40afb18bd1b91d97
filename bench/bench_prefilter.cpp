// Benchmark: prefiltered specular environments, accuracy against the brute force and speed.
//
//   bench_prefilter accuracy [MAP...] [--size N] [--schedule S] [--levels L] [--tolerance E]
//                  [--texels K] [--method cut|sampled] [--samples S]
//     per level: mean, 99th percentile and maximum relative error (max over channels) of the
//     chain against the double brute force (every source texel, exact solid angles) at K
//     texels drawn uniformly (fixed seed) plus the 64 texels nearest the map's brightest
//     texel (the sun); both methods when --method is not given.
//   bench_prefilter samples [MAP...] [--size N] [--schedule S]
//     the anchors' sampled method at 256, 1024, 4096 and 16384 samples per texel beside
//     the cut: the error of each level against the brute force and the kernel time (equal error).
//   bench_prefilter timing [MAP] [--size N] [--schedule S] [--runs K] [-- EXTRA ARGS]
//     whole `prtbake prefilter` commands after a warm-up run (program caches warm): median and
//     minimum of K wall times, the child's user + system CPU time and peak resident memory
//     (wait4), and the load average before and after.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "prtbake/envmap.h"
#include "prtbake/prefilter.h"
#include "prtbake/runtime.h"

using namespace prtbake;

namespace {

struct Args {
  std::vector<std::string> maps;
  PrefilterOptions o;
  int texels = 400;
  bool both = true;
};

Args parse(int argc, char** argv, int first) {
  Args a;
  a.o.schedule = PrefilterSchedule::Filament;
  for (int i = first; i < argc; ++i) {
    const std::string s = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", s.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (s == "--size") a.o.baseSize = std::atoi(next().c_str());
    else if (s == "--schedule") a.o.schedule = parsePrefilterSchedule(next());
    else if (s == "--levels") a.o.levels = std::atoi(next().c_str());
    else if (s == "--tolerance") a.o.tolerance = std::atof(next().c_str());
    else if (s == "--texels") a.texels = std::atoi(next().c_str());
    else if (s == "--samples") a.o.samples = std::atoi(next().c_str());
    else if (s == "--lobe") a.o.lobe = parsePrefilterLobe(next());
    else if (s == "--method") a.o.method = parsePrefilterMethod(next()), a.both = false;
    else a.maps.push_back(s);
  }
  return a;
}

// User + system CPU seconds of this process (all threads, PoCL's included).
double cpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

std::string dataPath(const std::string& rel) { return std::string(PRTBAKE_BENCH_DATA_DIR) + "/" + rel; }

// Texel indices to compare: `count` uniform ones and the 64 nearest the brightest source texel.
std::vector<size_t> pickTexels(const EnvMap& env, int n, int count) {
  std::mt19937_64 rng(12345);
  const size_t total = size_t(6) * size_t(n) * size_t(n);
  std::vector<size_t> out;
  for (int i = 0; i < count && size_t(i) < total; ++i) out.push_back(size_t(rng() % total));
  size_t bright = 0;
  float best = -1;
  for (size_t t = 0; t < env.texelCount(); ++t) {
    const float y = env.rgb[3 * t] + env.rgb[3 * t + 1] + env.rgb[3 * t + 2];
    if (y > best) best = y, bright = t;
  }
  double sun[3];
  texelDirection(env, bright, sun, nullptr);
  std::vector<std::pair<double, size_t>> near;
  for (int f = 0; f < 6; ++f)
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) {
        double d[3];
        cubeTexelCenter(n, f, r, c, d);
        near.push_back({-(d[0] * sun[0] + d[1] * sun[1] + d[2] * sun[2]), (size_t(f) * n + r) * n + c});
      }
  const size_t k = std::min<size_t>(64, near.size());
  std::partial_sort(near.begin(), near.begin() + long(k), near.end());
  for (size_t i = 0; i < k; ++i) out.push_back(near[i].second);
  return out;
}

struct Stats {
  double mean = 0, p99 = 0, max = 0;
};

Stats compare(const PrefilterLevel& lv, const EnvMap& env, PrefilterLobe lobe, const std::vector<size_t>& idx,
              size_t uniformCount) {
  const int n = lv.spec.size;
  std::vector<double> dirs;
  for (size_t t : idx) {
    double d[3];
    cubeTexelCenter(n, int(t / (size_t(n) * n)), int((t / n) % n), int(t % n), d);
    dirs.insert(dirs.end(), d, d + 3);
  }
  const double alpha = lv.alphaUsed > 0 ? lv.alphaUsed : lv.spec.alpha;
  const std::vector<double> ref = prefilterBruteForce(env, lobe, alpha, dirs);
  std::vector<double> rel, all;
  for (size_t i = 0; i < idx.size(); ++i) {
    double e = 0;
    for (int c = 0; c < 3; ++c) {
      const double r = ref[3 * i + c], v = lv.rgb[3 * idx[i] + c];
      e = std::max(e, std::abs(v - r) / std::max(r, 1e-12));
    }
    if (i < uniformCount) rel.push_back(e);
    all.push_back(e);
  }
  std::sort(rel.begin(), rel.end());
  Stats s;
  for (double x : rel) s.mean += x;
  s.mean /= double(rel.size());
  s.p99 = rel[std::min(rel.size() - 1, size_t(0.99 * rel.size()))];
  s.max = *std::max_element(all.begin(), all.end());
  return s;
}

int accuracy(const Args& a) {
  Runtime rt(std::getenv("PRTBAKE_DEVICE") ? "" : "cpu");
  std::vector<std::string> maps = a.maps;
  if (maps.empty())
    for (const char* m : {"venice_sunset_1k.hdr", "potsdamer_platz_1k.hdr", "studio_small_03_1k.hdr", "grace_latlong.exr"})
      maps.push_back(dataPath(std::string("envmaps/hdr/") + m));
  std::printf("| map | method | level | size | r | alpha used | mean rel | p99 rel | max rel | est. mean | est. p99 | kernel s | cut s |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const std::string& path : maps) {
    const EnvMap env = loadEnvironment(path);
    std::vector<PrefilterMethod> methods = {a.o.method};
    if (a.both) methods = {PrefilterMethod::Cut, PrefilterMethod::Sampled};
    for (PrefilterMethod m : methods) {
      PrefilterOptions o = a.o;
      o.method = m;
      if (!std::getenv("PF_NOWARM")) prefilterEnvironment(rt, env, o);  // warm-up (program builds)
      const double cpu0 = cpuSeconds();
      const PrefilterResult r = prefilterEnvironment(rt, env, o);
      const double cpu = cpuSeconds() - cpu0;
      for (size_t l = 0; l < r.levels.size() && a.texels > 0; ++l) {
        const PrefilterLevel& lv = r.levels[l];
        if (lv.alphaUsed == 0) continue;  // the resampled source (GGX r = 0): no lobe to compare
        const std::vector<size_t> idx = pickTexels(env, lv.spec.size, a.texels);
        const Stats s = compare(lv, env, o.lobe, idx, size_t(std::min(a.texels, 6 * lv.spec.size * lv.spec.size)));
        std::printf("| %s | %s | %zu | %d | %.3f | %.4f | %.2e | %.2e | %.2e | %.1e | %.1e | %.3f | %.3f |\n",
                    path.substr(path.find_last_of('/') + 1).c_str(), toString(m), l, lv.spec.size,
                    lv.spec.roughness, lv.alphaUsed, s.mean, s.p99, s.max, lv.error.mean, lv.error.p99,
                    lv.kernelSeconds, lv.cutSeconds);
      }
      std::printf("| %s | %s | total | | | | | | | | | %.3f | bins %.3f s, total %.3f s, cpu %.3f s |\n",
                  path.substr(path.find_last_of('/') + 1).c_str(), toString(m), r.kernelSeconds, r.binSeconds,
                  r.totalSeconds, cpu);
      std::fflush(stdout);
    }
  }
  return 0;
}

int samples(const Args& a) {
  Runtime rt(std::getenv("PRTBAKE_DEVICE") ? "" : "cpu");
  std::vector<std::string> maps = a.maps;
  if (maps.empty())
    for (const char* m : {"venice_sunset_1k.hdr", "studio_small_03_1k.hdr"}) maps.push_back(dataPath(std::string("envmaps/hdr/") + m));
  std::printf("| map | method | level | r | mean rel | p99 rel | max rel | kernel s | level s |\n|---|---|---|---|---|---|---|---|---|\n");
  for (const std::string& path : maps) {
    const EnvMap env = loadEnvironment(path);
    const std::string name = path.substr(path.find_last_of('/') + 1);
    std::vector<std::pair<std::string, PrefilterOptions>> runs;
    PrefilterOptions cut = a.o;
    cut.method = PrefilterMethod::Cut;
    runs.push_back({"cut", cut});
    for (int n : {256, 1024, 4096, 16384}) {
      PrefilterOptions o = a.o;
      o.method = PrefilterMethod::Sampled;
      o.samples = n;
      runs.push_back({"sampled " + std::to_string(n), o});
    }
    bool warm = false;
    for (const auto& [label, o] : runs) {
      if (!warm) prefilterEnvironment(rt, env, o), warm = true;  // program builds (kernel times exclude them anyway)
      const PrefilterResult r = prefilterEnvironment(rt, env, o);
      for (size_t l = 0; l < r.levels.size(); ++l) {
        const PrefilterLevel& lv = r.levels[l];
        if (lv.spec.roughness < 0.1) continue;
        const std::vector<size_t> idx = pickTexels(env, lv.spec.size, a.texels);
        const Stats st = compare(lv, env, o.lobe, idx, size_t(std::min(a.texels, 6 * lv.spec.size * lv.spec.size)));
        std::printf("| %s | %s | %zu | %.3f | %.2e | %.2e | %.2e | %.3f | %.3f |\n", name.c_str(), label.c_str(), l,
                    lv.spec.roughness, st.mean, st.p99, st.max, lv.kernelSeconds,
                    lv.kernelSeconds + lv.cutSeconds + lv.estimateSeconds);
      }
      std::fflush(stdout);
    }
  }
  return 0;
}

struct Child {
  double wall = 0, cpu = 0;
  long maxRssKb = 0;
  int status = 0;
};

Child runChild(const std::vector<std::string>& argv) {
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid == 0) {
    std::vector<char*> args;
    for (const auto& s : argv) args.push_back(const_cast<char*>(s.c_str()));
    args.push_back(nullptr);
    execv(args[0], args.data());
    _exit(127);
  }
  Child c;
  rusage u{};
  wait4(pid, &c.status, 0, &u);
  c.wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  c.cpu = double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
  c.maxRssKb = u.ru_maxrss;
  return c;
}

std::string loadAverage() {
  FILE* f = std::fopen("/proc/loadavg", "r");
  char buf[64] = {0};
  if (f) {
    if (!std::fgets(buf, sizeof buf, f)) buf[0] = 0;
    std::fclose(f);
  }
  std::string s(buf);
  return s.substr(0, s.find(' '));
}

int timing(int argc, char** argv) {
  std::string map = dataPath("envmaps/hdr/venice_sunset_1k.hdr"), size = "256", schedule = "filament";
  int runs = 5;
  std::vector<std::string> extra;
  for (int i = 2; i < argc; ++i) {
    const std::string s = argv[i];
    if (s == "--") {
      for (++i; i < argc; ++i) extra.push_back(argv[i]);
      break;
    }
    if (s == "--size" && i + 1 < argc) size = argv[++i];
    else if (s == "--schedule" && i + 1 < argc) schedule = argv[++i];
    else if (s == "--runs" && i + 1 < argc) runs = std::atoi(argv[++i]);
    else map = s;
  }
  const std::string out = "/tmp/bench_prefilter_" + std::to_string(getpid()) + ".ktx2";
  std::vector<std::string> cmd = {PRTBAKE_CLI_PATH, "prefilter", map, "-o", out, "--size", size, "--schedule", schedule, "-q"};
  cmd.insert(cmd.end(), extra.begin(), extra.end());
  std::string line;
  for (const auto& c : cmd) line += c + " ";
  const std::string before = loadAverage();
  runChild(cmd);  // warm-up: program caches
  std::vector<double> walls, cpus;
  long rss = 0;
  for (int i = 0; i < runs; ++i) {
    const Child c = runChild(cmd);
    if (c.status != 0) {
      std::fprintf(stderr, "command failed: %s\n", line.c_str());
      return 1;
    }
    walls.push_back(c.wall), cpus.push_back(c.cpu), rss = std::max(rss, c.maxRssKb);
  }
  std::sort(walls.begin(), walls.end());
  std::sort(cpus.begin(), cpus.end());
  std::printf("%s\n  wall median %.2f s (min %.2f, max %.2f) over %d runs; CPU (user + system) median %.2f s; peak RSS %.0f MB; "
              "load average %s before, %s after\n",
              line.c_str(), walls[walls.size() / 2], walls.front(), walls.back(), runs, cpus[cpus.size() / 2], rss / 1024.0,
              before.c_str(), loadAverage().c_str());
  std::remove(out.c_str());
  std::remove(("/tmp/bench_prefilter_" + std::to_string(getpid()) + ".json").c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) try {
  if (argc < 2) {
    std::fprintf(stderr, "usage: bench_prefilter accuracy|samples|timing [MAP...] [options]\n");
    return 2;
  }
  const std::string mode = argv[1];
  if (mode == "timing") return timing(argc, argv);
  const Args a = parse(argc, argv, 2);
  if (mode == "accuracy") return accuracy(a);
  if (mode == "samples") return samples(a);
  std::fprintf(stderr, "unknown mode %s\n", mode.c_str());
  return 2;
} catch (const std::exception& e) {  // a bad argument or a missing device: one line, no abort
  std::fprintf(stderr, "%s: %s\n", argv[0], e.what());
  return 1;
}
