// bench_transport: rays/s of shadowed per-vertex transport on mary.obj (GAMES202's
// scene, 1024 samples) and on a procedural ~200k-triangle bumpy sphere, SH orders 3 and 5.
//
// usage: bench_transport [--repeats N] [--samples-large N] [--device SPEC] [--packet-width W] [--knot]
//                        [--bounces B] [--ray-lanes L]
// --packet-width: TransportOptions::packetWidth (16, 8, 0 for the scalar kernels, or the
// default -1: 16 on a CPU device, 0 on a GPU);
// --ray-lanes: TransportOptions::rayLanes, the scalar kernels' work-items per vertex (1 to 32, or
// the default -1: 1 on a CPU device, 32 on a GPU);
// --bounces: B > 0 makes it interreflected with B bounces (--bounce-tolerance 0), rays counting
// the bounces' too (default 0: shadowed);
// --knot: the large mesh is the torus knot of bench_embree.sh (204,800 triangles).
// Prints one line per case: wall seconds of computeTransport (median of N runs; the
// programs are built beforehand on a tiny mesh), kernel seconds, rays, rays/s, and rays
// per CPU-second of this process (PoCL's threads included): on a shared machine the
// wall figures move with the other users' load, the CPU-second figure much less.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <sys/resource.h>

#include "prtbake/mesh.h"
#include "prtbake/runtime.h"
#include "prtbake/transport.h"

using namespace prtbake;

namespace {
double cpuSeconds() {
  rusage r{};
  getrusage(RUSAGE_SELF, &r);
  return r.ru_utime.tv_sec + r.ru_stime.tv_sec + 1e-6 * (r.ru_utime.tv_usec + r.ru_stime.tv_usec);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

int packetWidth = TransportOptions{}.packetWidth;
int bounces = 0;
int rayLanes = TransportOptions{}.rayLanes;

void run(Runtime& rt, const std::string& name, const Mesh& mesh, int order, int samples, int repeats) {
  TransportOptions o;
  o.packetWidth = packetWidth;
  o.rayLanes = rayLanes;
  o.mode = bounces > 0 ? TransportMode::Interreflected : TransportMode::Shadowed;
  o.bounces = bounces;
  o.bounceTolerance = 0;
  o.order = order;
  o.samples = samples;
  computeTransport(rt, makeUvSphere(1.0, 4, 8), o);  // program build and first launch
  std::vector<double> wall, kernel, cpu;
  uint64_t rays = 0;
  for (int i = 0; i < repeats; ++i) {
    const double c0 = cpuSeconds();
    const auto t0 = std::chrono::steady_clock::now();
    const auto r = computeTransport(rt, mesh, o);
    wall.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    cpu.push_back(cpuSeconds() - c0);
    kernel.push_back(r.kernelSeconds);
    rays = r.rays;
  }
  const double w = median(wall), k = median(kernel), c = median(cpu);
  std::printf("%-13s order %d  %6zu tris %6zu verts  %4d samples  wall %.3f s  kernel %.3f s  cpu %.3f s  "
              "%.3g rays  %.2f M rays/s (kernel)  %.2f M rays/s (wall)  %.2f M rays per CPU-s\n",
              name.c_str(), order, mesh.triangleCount(), mesh.vertexCount(), samples, w, k, c, double(rays),
              rays / k * 1e-6, rays / w * 1e-6, rays / c * 1e-6);
  std::fflush(stdout);
}
}  // namespace

int main(int argc, char** argv) try {
  int repeats = 3, samplesLarge = 1024;
  std::string device;
  bool knot = false;
  for (int i = 1; i < argc; ++i) knot = knot || std::string(argv[i]) == "--knot";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--repeats") repeats = std::atoi(argv[i + 1]);
    else if (a == "--samples-large") samplesLarge = std::atoi(argv[i + 1]);
    else if (a == "--device") device = argv[i + 1];
    else if (a == "--packet-width") packetWidth = std::atoi(argv[i + 1]);
    else if (a == "--bounces") bounces = std::atoi(argv[i + 1]);
    else if (a == "--ray-lanes") rayLanes = std::atoi(argv[i + 1]);
    else if (a == "--knot") --i;
  }
  Runtime rt(device);
  std::printf("device: %s\n", rt.deviceLabel().c_str());
  std::printf("%s transport, %d bounces, packet width %d (-1: 16 on a CPU device, 0 on a GPU), ray lanes %d (-1: 1 on a "
              "CPU device, 32 on a GPU); median of %d runs (mary.obj), %d (large mesh)\n",
              bounces > 0 ? "interreflected" : "shadowed", bounces, packetWidth, rayLanes, repeats, std::max(1, repeats / 3));
  const std::string maryPath = std::string(PRTBAKE_BENCH_DATA_DIR) + "/meshes/obj/mary.obj";
  try {
    const Mesh mary = loadMesh(maryPath);
    for (int order : {3, 5}) run(rt, "mary.obj", mary, order, 1024, repeats);
  } catch (const std::exception& e) {
    std::printf("mary.obj skipped: %s\n", e.what());
  }
  const Mesh large = knot ? makeTorusKnot(800, 128) : makeBumpySphere(204000);
  for (int order : {3, 5}) run(rt, knot ? "knot" : "bumpy sphere", large, order, samplesLarge, std::max(1, repeats / 3));
  return 0;
} catch (const std::exception& e) {  // a bad argument or a missing device: one line, no abort
  std::fprintf(stderr, "%s: %s\n", argv[0], e.what());
  return 1;
}
