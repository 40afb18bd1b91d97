// The library calls that bench/bench_python.py times through the Python module, made from C++:
// the same inputs and options, so that the difference is the binding's cost.
//
//   bench_call lut CALLS [SIZE [SAMPLES]] | env CALLS [WIDTH] | transport CALLS [MESH]
//   bench_call peak 1 MESH: the peak resident memory (MiB) before and after one computeTransport
//   of MESH at order 8, 64 samples, the output's size and the resident memory at start-up
//   (bench_python.py compares the module's with it).
//   lut: computeLut, SIZE² (16), SAMPLES (64); env: validateEnvironment and projectEnvironment of
//   a WIDTH×WIDTH/2 (64) lat-long of ones, order 3; transport: computeTransport of MESH, shadowed,
//   64 samples.
// Prints one line: "<what> <calls> <median seconds per call> <min seconds per call>", each
// call timed alone after 20 warm-up calls (program builds, first-touch pages).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <sys/resource.h>
#include <vector>

#include "prtbake/clock.h"
#include "prtbake/env.h"
#include "prtbake/lut.h"
#include "prtbake/mesh.h"
#include "prtbake/runtime.h"
#include "prtbake/transport.h"

using namespace prtbake;

// The resident memory now (VmRSS), in MiB.
static double residentMiB() {
  FILE* f = std::fopen("/proc/self/status", "r");
  char line[256];
  double kib = 0;
  while (f && std::fgets(line, sizeof line, f))
    if (std::sscanf(line, "VmRSS: %lf", &kib) == 1) break;
  if (f) std::fclose(f);
  return kib / 1024.0;
}

// The CPU device's runtime, made on first use (after the mesh is loaded, as the module's calls make it).
static Runtime& rt0() {
  static Runtime rt("cpu");
  return rt;
}

int main(int argc, char** argv) try {
  if (argc < 3) {
    std::fprintf(stderr, "usage: bench_call lut CALLS [SIZE [SAMPLES]] | env CALLS [WIDTH] | transport CALLS [MESH]\n");
    return 2;
  }
  const std::string what = argv[1];
  const int calls = std::atoi(argv[2]);
  if (what == "peak" && argc > 3) {
    const double startup = residentMiB();
    const Mesh mesh = loadMesh(argv[3]);
    rusage before{}, after{};
    getrusage(RUSAGE_SELF, &before);
    TransportOptions o;
    o.order = 8, o.samples = 64;
    const TransportResult r = computeTransport(rt0(), mesh, o);
    getrusage(RUSAGE_SELF, &after);
    std::printf("%.1f %.1f %.1f %.1f\n", before.ru_maxrss / 1024.0, after.ru_maxrss / 1024.0, r.coeffs.size() * 4.0 / 1048576,
                startup);
    return 0;
  }
  const int size = what == "lut" && argc > 3 ? std::atoi(argv[3]) : 16;
  const int samples = what == "lut" && argc > 4 ? std::atoi(argv[4]) : 64;
  const int width = what == "env" && argc > 3 ? std::atoi(argv[3]) : 64;
  if ((what != "lut" && what != "env" && what != "transport") || calls < 1 || size < 1 || samples < 1 || width < 2) {
    std::fprintf(stderr, "usage: bench_call lut CALLS [SIZE [SAMPLES]] | env CALLS [WIDTH] | transport CALLS [MESH]\n");
    return 2;
  }
  Runtime& rt = rt0();
  Mesh mesh;
  if (what == "transport") mesh = loadMesh(argc > 3 ? argv[3] : "assets/scene.gltf");
  EnvMap env;
  env.layout = EnvLayout::LatLong;
  env.width = width, env.height = width / 2;
  env.rgb.assign(size_t(width) * (width / 2) * 3, 1.0f);
  // Each call's result is kept until just before the next call's clock starts, as the Python
  // side drops its previous result: freeing a large result (munmap) is not the call's time.
  std::shared_ptr<void> kept;
  auto once = [&]() {
    if (what == "lut") {
      LutOptions o;
      o.size = size, o.samples = samples;
      kept = std::make_shared<LutResult>(computeLut(rt, o));
    } else if (what == "env") {
      EnvProjectOptions o;
      validateEnvironment(env, false);  // as the module checks an array (and loadEnvironment a file)
      kept = std::make_shared<EnvProjectResult>(projectEnvironment(rt, env, o));
    } else {
      TransportOptions o;
      o.samples = 64;
      kept = std::make_shared<TransportResult>(computeTransport(rt, mesh, o));
    }
  };
  for (int i = 0; i < 20; ++i) once();
  std::vector<double> t;
  for (int i = 0; i < calls; ++i) {
    kept.reset();
    const auto t0 = std::chrono::steady_clock::now();
    once();
    t.push_back(secondsSince(t0));
  }
  std::sort(t.begin(), t.end());
  std::printf("%s %d %.9f %.9f\n", what.c_str(), calls, t[t.size() / 2], t[0]);
  return 0;
} catch (const std::exception& e) {  // a bad argument or a missing device: one line, no abort
  std::fprintf(stderr, "%s: %s\n", argv[0], e.what());
  return 1;
}
