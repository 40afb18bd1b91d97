// bench_preview: the mesh preview of an 800×600 image of the procedural ~200k-triangle
// bumpy sphere, after the kernels are built: BVH build, kernel (camera rays, shading and
// the SH background, read-back included) and PNG write, medians of N runs.
//
// usage: bench_preview [--repeats N] [--triangles N] [--size WxH] [--view YAW,PITCH] [--device SPEC]
// The transport is the unshadowed one (its values do not change the render's cost).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include <sys/resource.h>
#include <unistd.h>

#include "prtbake/mesh.h"
#include "prtbake/preview.h"
#include "prtbake/runtime.h"
#include "prtbake/transport.h"

using namespace prtbake;

namespace {
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}
double cpuSeconds() {
  rusage r{};
  getrusage(RUSAGE_SELF, &r);
  return r.ru_utime.tv_sec + r.ru_stime.tv_sec + 1e-6 * (r.ru_utime.tv_usec + r.ru_stime.tv_usec);
}
double since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}
}  // namespace

int main(int argc, char** argv) try {
  int repeats = 5, triangles = 200000, width = 800, height = 600;
  std::string device = "cpu";
  double yaw = 30, pitch = 20;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--repeats")) repeats = std::atoi(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--triangles")) triangles = std::atoi(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--size")) std::sscanf(argv[i + 1], "%dx%d", &width, &height);
    else if (!std::strcmp(argv[i], "--device")) device = argv[i + 1];
    else if (!std::strcmp(argv[i], "--view")) std::sscanf(argv[i + 1], "%lf,%lf", &yaw, &pitch);
  }
  Runtime rt(device);
  const Mesh mesh = makeBumpySphere(triangles);
  TransportOptions to;
  to.mode = TransportMode::Unshadowed;
  to.order = 3;
  const TransportResult tr = computeTransport(rt, mesh, to);
  TransportCoeffs t;
  t.order = tr.order, t.channels = tr.channels, t.vertexCount = tr.vertexCount, t.coeffs = tr.coeffs;
  ShCoeffs sky;
  sky.order = 3;
  sky.rgb.assign(9, Rgb{0, 0, 0});
  sky.rgb[0] = {3.0, 3.2, 3.6};
  sky.rgb[1] = {-1.5, -1.6, -1.8};  // brighter toward +Y
  MeshPreviewOptions o;
  o.width = width, o.height = height;
  o.yawDeg = yaw, o.pitchDeg = pitch;
  const double build0 = rt.buildSeconds();
  renderMeshPreview(rt, mesh, t, sky, o);  // program build and first launch
  const double buildSeconds = rt.buildSeconds() - build0;
  const std::string png = "/tmp/bench_preview_" + std::to_string(::getpid()) + ".png";
  std::vector<double> bvh, kernel, write, total, cpu;
  size_t hits = 0;
  for (int i = 0; i < repeats; ++i) {
    const double c0 = cpuSeconds();
    const auto t0 = std::chrono::steady_clock::now();
    const MeshPreviewResult r = renderMeshPreview(rt, mesh, t, sky, o);
    const auto t1 = std::chrono::steady_clock::now();
    writePreviewPng(png, r.image, ToneMap{});
    write.push_back(since(t1));
    total.push_back(since(t0));
    cpu.push_back(cpuSeconds() - c0);
    bvh.push_back(r.bvhSeconds);
    kernel.push_back(r.kernelSeconds);
    hits = size_t(std::count_if(r.hitTriangle.begin(), r.hitTriangle.end(), [](int32_t h) { return h >= 0; }));
  }
  std::remove(png.c_str());
  const double k = median(kernel);
  std::printf("device %s\n", rt.deviceLabel().c_str());
  std::printf("%zu triangles, %zu vertices, %dx%d pixels (%zu on the mesh), view %g,%g, %d runs (medians)\n",
              mesh.triangleCount(), mesh.vertexCount(), width, height, hits, yaw, pitch, repeats);
  std::printf("program build (first render) %.3f s\n", buildSeconds);
  std::printf("bvh %.3f s  kernel %.3f s (%.2f M rays/s)  png %.3f s  total %.3f s  (process CPU %.3f s)\n",
              median(bvh), k, width * height / k * 1e-6, median(write), median(total), median(cpu));
  return 0;
} catch (const std::exception& e) {  // a bad argument or a missing device: one line, no abort
  std::fprintf(stderr, "%s: %s\n", argv[0], e.what());
  return 1;
}
