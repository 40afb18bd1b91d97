// bench_embree: the peer of `prtbake transport` on Embree 3, for bench/bench_embree.sh.
//
//   bench_embree MESH OUT.npy [--samples N] [--order N] [--threads T]
//       Shadowed transport of every vertex of MESH traced with Embree's rtcOccluded16:
//       the same rays as prtbake (transportRays: origins, frames and directions as the
//       kernels read them, 16 consecutive directions per packet), the same estimator
//       T_i = (1/N) Σ_s V(p, ω_s) Y_i(ω_s) summed in double, the same .npy output. Loads
//       the mesh with prtbake's loader, builds Embree's BVH, traces on T threads (default:
//       the cores), writes OUT.npy, and prints the phases' times.
//   bench_embree --write-knot OUT.obj [--uv]
//       Writes the benchmark's torus knot (makeTorusKnot(800, 128): 102,400 vertices,
//       204,800 triangles) as an OBJ with normals; --uv adds a lightmap UV set (8 charts).
#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "prtbake/mesh.h"
#include "prtbake/sh.h"
#include "prtbake/transport.h"

using namespace prtbake;

namespace {
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// The knot as OBJ; with `uv`, also a lightmap UV set: the tube cut into 8 strips of 100 of its
// 800 rings, each strip unrolled (along the tube, around it) into one cell of a 4 × 2 grid with a
// margin of 5 % of the cell on each side, so that the charts neither overlap nor touch.
int writeKnot(const std::string& path, bool uv) {
  constexpr int kSegments = 800, kSides = 128, kStrips = 8, kRings = kSegments / kStrips;
  const Mesh m = makeTorusKnot(kSegments, kSides);
  std::ofstream out(path);
  char line[128];
  for (size_t v = 0; v < m.vertexCount(); ++v) {
    std::snprintf(line, sizeof line, "v %.9g %.9g %.9g\n", m.positions[3 * v], m.positions[3 * v + 1], m.positions[3 * v + 2]);
    out << line;
  }
  for (size_t v = 0; v < m.vertexCount(); ++v) {
    std::snprintf(line, sizeof line, "vn %.9g %.9g %.9g\n", m.normals[3 * v], m.normals[3 * v + 1], m.normals[3 * v + 2]);
    out << line;
  }
  // vt of strip s, ring r (0..kRings) and side j (0..kSides): (s · (kRings + 1) + r) · (kSides + 1) + j.
  auto vtIndex = [&](int s, int r, int j) { return uint32_t((s * (kRings + 1) + r) * (kSides + 1) + j) + 1; };
  if (uv)
    for (int s = 0; s < kStrips; ++s)
      for (int r = 0; r <= kRings; ++r)
        for (int j = 0; j <= kSides; ++j) {
          const double u = (s % 4 + 0.05 + 0.9 * r / kRings) / 4, v = (s / 4 + 0.05 + 0.9 * j / kSides) / 2;
          std::snprintf(line, sizeof line, "vt %.9g %.9g\n", u, v);
          out << line;
        }
  for (size_t t = 0; t < m.triangleCount(); ++t) {
    const uint32_t a = m.indices[3 * t] + 1, b = m.indices[3 * t + 1] + 1, c = m.indices[3 * t + 2] + 1;
    if (!uv) {
      std::snprintf(line, sizeof line, "f %u//%u %u//%u %u//%u\n", a, a, b, b, c, c);
    } else {
      // Quad (ring i, side j) makes triangles 2q and 2q + 1 (makeTorusKnot's order); its corners'
      // rings i and i + 1 and sides j and j + 1 within the strip of ring i, unwrapped.
      const int q = int(t / 2), i = q / kSides, j = q % kSides, s = i / kRings, r = i % kRings;
      const uint32_t ta = vtIndex(s, r, j), tb = vtIndex(s, r, j + 1), tc = vtIndex(s, r + 1, j + 1),
                     td = vtIndex(s, r + 1, j);
      const uint32_t t0 = ta, t1 = t % 2 ? tc : tb, t2 = t % 2 ? td : tc;  // {a, b, c}, {a, c, d}
      std::snprintf(line, sizeof line, "f %u/%u/%u %u/%u/%u %u/%u/%u\n", a, t0, a, b, t1, b, c, t2, c);
    }
    out << line;
  }
  return out ? 0 : 1;
}
}  // namespace

int main(int argc, char** argv) try {
  if ((argc == 3 || (argc == 4 && std::string(argv[3]) == "--uv")) && std::string(argv[1]) == "--write-knot")
    return writeKnot(argv[2], argc == 4);
  if (argc < 3) {
    std::fprintf(stderr, "usage: bench_embree MESH OUT.npy [--samples N] [--order N] [--threads T]\n"
                         "       bench_embree --write-knot OUT.obj [--uv]\n");
    return 2;
  }
  TransportOptions o;
  int threads = int(std::max(1u, std::thread::hardware_concurrency()));
  for (int i = 3; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--samples") o.samples = std::atoi(argv[i + 1]);
    else if (a == "--order") o.order = std::atoi(argv[i + 1]);
    else if (a == "--threads") threads = std::atoi(argv[i + 1]);
  }
  const auto t0 = Clock::now();
  const Mesh mesh = loadMesh(argv[1]);
  const double tLoad = since(t0);
  const auto t1 = Clock::now();
  const TransportRays rays = transportRays(mesh, o);
  const double tRays = since(t1);

  const auto t2 = Clock::now();
  RTCDevice device = rtcNewDevice(("threads=" + std::to_string(threads)).c_str());
  RTCScene scene = rtcNewScene(device);
  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  float* vb = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), mesh.vertexCount()));
  std::copy(mesh.positions.begin(), mesh.positions.end(), vb);
  unsigned* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                3 * sizeof(unsigned), mesh.triangleCount()));
  std::copy(mesh.indices.begin(), mesh.indices.end(), ib);
  rtcCommitGeometry(geom);
  rtcAttachGeometry(scene, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(scene);
  const double tBuild = since(t2);

  // Vertices in blocks of 64, handed out to the threads.
  const size_t nv = mesh.vertexCount();
  const int nc = o.order * o.order, ns = o.samples;
  std::vector<float> coeffs(nv * size_t(nc), 0.0f);
  std::atomic<size_t> next{0};
  const auto t3 = Clock::now();
  auto worker = [&] {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    std::vector<double> acc(nc), y(nc);
    alignas(64) int valid[16];
    alignas(64) RTCRay16 r;
    for (size_t first; (first = next.fetch_add(64)) < nv;) {
      for (size_t v = first; v < std::min(nv, first + 64); ++v) {
        const float* f = &rays.frames[9 * v];
        if (f[6] == 0 && f[7] == 0 && f[8] == 0) continue;  // no normal: zero transport
        std::fill(acc.begin(), acc.end(), 0.0);
        for (int s0 = 0; s0 < ns; s0 += 16) {
          for (int j = 0; j < 16; ++j) {
            const int s = std::min(s0 + j, ns - 1);
            const float* d = &rays.directions[3 * size_t(s)];
            valid[j] = s0 + j < ns ? -1 : 0;
            r.org_x[j] = rays.origins[3 * v], r.org_y[j] = rays.origins[3 * v + 1], r.org_z[j] = rays.origins[3 * v + 2];
            r.dir_x[j] = d[0] * f[0] + d[1] * f[3] + d[2] * f[6];
            r.dir_y[j] = d[0] * f[1] + d[1] * f[4] + d[2] * f[7];
            r.dir_z[j] = d[0] * f[2] + d[1] * f[5] + d[2] * f[8];
            r.tnear[j] = 0.0f;
            r.tfar[j] = rays.tMax;
            r.time[j] = 0.0f;
            r.mask[j] = ~0u;
            r.id[j] = unsigned(j);
            r.flags[j] = 0;
          }
          rtcOccluded16(valid, scene, &ctx, &r);
          if (o.order == 3) {
            // The order-3 polynomials of docs/conventions.md "SH basis" in float over the
            // packet's lanes (as prtbake's kernel evaluates them), summed per packet in float
            // and per vertex in double.
            float a[9] = {};
            for (int j = 0; j < 16; ++j) {
              const float w = (s0 + j < ns && r.tfar[j] >= 0) ? 1.0f : 0.0f;  // tfar = −inf: occluded
              const float x = r.dir_x[j], yy = r.dir_y[j], z = r.dir_z[j];
              a[0] += w * 0.282094792f;
              a[1] += w * -0.488602512f * yy;
              a[2] += w * 0.488602512f * z;
              a[3] += w * -0.488602512f * x;
              a[4] += w * 1.092548431f * x * yy;
              a[5] += w * -1.092548431f * yy * z;
              a[6] += w * 0.315391565f * (3 * z * z - 1);
              a[7] += w * -1.092548431f * x * z;
              a[8] += w * 0.546274215f * (x * x - yy * yy);
            }
            for (int k = 0; k < 9; ++k) acc[size_t(k)] += a[k];
          } else {
            for (int j = 0; j < 16 && s0 + j < ns; ++j) {
              if (r.tfar[j] < 0) continue;  // occluded
              shEval(o.order, r.dir_x[j], r.dir_y[j], r.dir_z[j], y.data());
              for (int k = 0; k < nc; ++k) acc[size_t(k)] += y[size_t(k)];
            }
          }
        }
        for (int k = 0; k < nc; ++k) coeffs[v * size_t(nc) + size_t(k)] = float(acc[size_t(k)] / ns);
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(worker);
  worker();
  for (auto& t : pool) t.join();
  const double tTrace = since(t3);
  rtcReleaseScene(scene);
  rtcReleaseDevice(device);

  const auto t4 = Clock::now();
  TransportResult out;
  out.order = o.order;
  out.channels = 1;
  out.vertexCount = nv;
  out.coeffs = std::move(coeffs);
  writeTransportNpy(argv[2], out);
  const double tWrite = since(t4);
  std::printf("embree: %zu vertices, %zu triangles, %d samples, %d threads: load %.3f s, rays %.3f s, build %.3f s, "
              "trace %.3f s (%.2f M rays/s), write %.3f s, total %.3f s\n",
              nv, mesh.triangleCount(), ns, threads, tLoad, tRays, tBuild, tTrace, double(nv) * ns / tTrace * 1e-6,
              tWrite, since(t0));
  return 0;
} catch (const std::exception& e) {  // a bad argument or a missing device: one line, no abort
  std::fprintf(stderr, "%s: %s\n", argv[0], e.what());
  return 1;
}
