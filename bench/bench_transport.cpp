// bench_transport: rays/s of shadowed per-vertex transport on mary.obj (GAMES202's
// scene, 1024 samples) and on a procedural ~200k-triangle bumpy sphere, SH orders 3 and 5.
//
// usage: bench_transport [--repeats N] [--samples-large N] [--device SPEC]
// Prints one line per case: wall seconds (median of N runs, programs already built),
// kernel seconds, rays and rays/s. Program builds are excluded (first run discarded).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "prtbake/mesh.h"
#include "prtbake/runtime.h"
#include "prtbake/transport.h"

using namespace prtbake;

namespace {
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

void run(Runtime& rt, const std::string& name, const Mesh& mesh, int order, int samples, int repeats) {
  TransportOptions o;
  o.mode = TransportMode::Shadowed;
  o.order = order;
  o.samples = samples;
  computeTransport(rt, mesh, o);  // warm-up: program build, first launch
  std::vector<double> wall, kernel;
  uint64_t rays = 0;
  for (int i = 0; i < repeats; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    const auto r = computeTransport(rt, mesh, o);
    wall.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    kernel.push_back(r.kernelSeconds);
    rays = r.rays;
  }
  const double w = median(wall), k = median(kernel);
  std::printf("%-22s order %d  %7zu tris %7zu verts  %5d samples  wall %.3f s  kernel %.3f s  %.3g rays  %.2f M rays/s (kernel)  %.2f M rays/s (wall)\n",
              name.c_str(), order, mesh.triangleCount(), mesh.vertexCount(), samples, w, k, double(rays),
              rays / k * 1e-6, rays / w * 1e-6);
  std::fflush(stdout);
}
}  // namespace

int main(int argc, char** argv) {
  int repeats = 3, samplesLarge = 256;
  std::string device;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--repeats") repeats = std::atoi(argv[i + 1]);
    else if (a == "--samples-large") samplesLarge = std::atoi(argv[i + 1]);
    else if (a == "--device") device = argv[i + 1];
  }
  Runtime rt(device);
  std::printf("device: %s\n", rt.deviceLabel().c_str());
  const std::string maryPath = std::string(PRTBAKE_BENCH_DATA_DIR) + "/meshes/obj/mary.obj";
  try {
    const Mesh mary = loadMesh(maryPath);
    for (int order : {3, 5}) run(rt, "mary.obj", mary, order, 1024, repeats);
  } catch (const std::exception& e) {
    std::printf("mary.obj skipped: %s\n", e.what());
  }
  const Mesh large = makeBumpySphere(204000);
  for (int order : {3, 5}) run(rt, "bumpy sphere", large, order, samplesLarge, std::max(1, repeats / 2));
  return 0;
}
