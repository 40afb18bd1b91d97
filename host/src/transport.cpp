// Transport on the OpenCL device: BVH upload, direct term, bounces (see transport.h).
#include "prtbake/transport.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "prtbake/bvh.h"
#include "prtbake/error.h"
#include "prtbake/sh.h"
#include "transport_direct.h"
#include "transport_setup.h"

namespace prtbake {
namespace {
const double kPi = 3.14159265358979323846;
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Work-items per group: the kernels loop (samples, traversal), so PoCL runs them
// scalar; 16 keeps the groups numerous enough to balance over the cores.
constexpr size_t kLocalSize = 16;

size_t roundUp(size_t n, size_t m) { return (n + m - 1) / m * m; }

struct DeviceScene {
  cl::Buffer origins, frames, dirs, dirsSoA, nodes, tris;
  int paddedCount = 0;
  float tMax = 0;
  std::vector<uint8_t> unoccludable;  // per vertex (filled when the BVH is built)
};

void setCommonArgs(cl::Kernel& k, int nv, int ns, const DeviceScene& s) {
  k.setArg(0, nv);
  k.setArg(1, ns);
  k.setArg(2, s.origins);
  k.setArg(3, s.frames);
  k.setArg(4, s.dirs);
  k.setArg(5, s.nodes);
  k.setArg(6, s.tris);
  k.setArg(7, s.tMax);
}

DeviceScene prepare(Runtime& rt, const Mesh& mesh, const TransportOptions& o, const detail::RaySetup& setup,
                    bool needBvh, TransportResult& r) {
  DeviceScene s;
  s.tMax = setup.tMax;
  s.origins = rt.upload(setup.origins);
  s.frames = rt.upload(setup.frames);
  s.dirs = rt.upload(setup.dirs);
  s.dirsSoA = rt.upload(detail::packetDirections(setup.dirs, s.paddedCount));
  if (needBvh) {
    const auto t0 = Clock::now();
    const Bvh bvh = buildBvh(mesh);
    r.bvhSeconds = since(t0);
    r.bvhNodes = bvh.nodes.size();
    r.degenerateTriangles = bvh.degenerateTriangles;
    s.nodes = rt.upload(bvh.nodes);
    s.tris = rt.upload(bvh.packed);
    s.unoccludable = detail::unoccludableFromBvh(mesh, bvh, setup);
    if (bvh.nodes.empty()) {
      // Every triangle has zero area: nothing can occlude. One leaf whose empty box
      // (min > max) no ray enters.
      const std::vector<Bvh::Node> one{Bvh::Node{{1, 1, 1}, 0, {-1, -1, -1}, 1}};
      s.nodes = rt.upload(one);
      s.tris = rt.upload(std::vector<float>(12, 0.0f));
    }
  } else {
    s.nodes = rt.upload(std::vector<float>(8, 0.0f));
    s.tris = rt.upload(std::vector<float>(12, 0.0f));
  }
  return s;
}

std::string options(int order, bool visibility, int channels, int packet = 0) {
  return "-DSH_ORDER=" + std::to_string(order) + " -DVISIBILITY=" + (visibility ? "1" : "0") +
         " -DCHANNELS=" + std::to_string(channels) + " -DBVH_PACKET=" + std::to_string(packet);
}

// The direct-term (or visibility) kernel: packet or scalar form, arguments set.
cl::Kernel directKernel(Runtime& rt, const TransportOptions& o, bool visibility, const DeviceScene& s, int nv,
                        const char* scalarName, const char* packetName, int paddedCountArg) {
  const bool packet = o.packetWidth > 0;
  cl::Kernel k = rt.kernel("transport.cl", packet ? packetName : scalarName,
                           options(o.order, visibility, 1, o.packetWidth));
  setCommonArgs(k, nv, o.samples, s);
  if (packet) {
    k.setArg(4, s.dirsSoA);
    k.setArg(paddedCountArg, s.paddedCount);
  }
  return k;
}

// The size of the requested vertex range; throws UsageError when it leaves the mesh
// or splits an interreflected job.
size_t rangeSize(const Mesh& mesh, const TransportOptions& o) {
  const size_t nv = mesh.vertexCount();
  if (o.firstVertex > nv)
    throw UsageError("vertex range", "first vertex " + std::to_string(o.firstVertex) + " is beyond the mesh's " +
                                         std::to_string(nv) + " vertices");
  const size_t count = o.vertexCount ? *o.vertexCount : nv - o.firstVertex;
  if (count > nv - o.firstVertex)
    throw UsageError("vertex range", std::to_string(count) + " vertices from " + std::to_string(o.firstVertex) +
                                         " run past the mesh's " + std::to_string(nv) + " vertices");
  if (o.mode == TransportMode::Interreflected && count != nv)
    throw UsageError("vertex range", "interreflected transport needs every vertex (each bounce reads the "
                                     "previous bounce of the whole mesh); compute the whole mesh");
  return count;
}

}  // namespace

TransportResult computeTransport(Runtime& rt, const Mesh& mesh, const TransportOptions& o) {
  const auto tStart = Clock::now();
  detail::checkTransportOptions(o);
  if (o.tolerance > 0) {
    if (o.firstVertex != 0 || (o.vertexCount && *o.vertexCount != mesh.vertexCount()))
      throw UsageError("tolerance", "adaptive sampling computes whole meshes only (no vertex range)");
    return detail::computeTransportAdaptive(rt, mesh, o);  // transport_adaptive.cpp
  }
  validateMesh(mesh, mesh.sourcePath.empty() ? "mesh" : mesh.sourcePath);
  TransportResult r;
  r.order = o.order;
  r.samples = o.samples;
  r.device = rt.deviceLabel();
  const int nc = o.order * o.order;
  const size_t first = o.firstVertex;
  const size_t count = rangeSize(mesh, o);
  const int nv = int(count);
  r.vertexCount = count;
  r.firstVertex = first;
  const bool rgb = detail::transportIsRgb(mesh, o);
  r.channels = rgb ? 3 : 1;
  if (count == 0) {
    r.totalSeconds = since(tStart);
    return r;
  }
  detail::RaySetup setup = detail::makeRaySetup(mesh, o);
  if (count != mesh.vertexCount()) {
    // Keep the range's origins and frames (computed from global indices); the BVH and
    // everything else stay those of the whole mesh.
    setup.origins.assign(setup.origins.begin() + 4 * first, setup.origins.begin() + 4 * (first + count));
    setup.frames.assign(setup.frames.begin() + 12 * first, setup.frames.begin() + 12 * (first + count));
    setup.verticesWithoutNormal = 0;
    for (size_t v = 0; v < count; ++v)
      if (setup.frames[12 * v + 8] == 0 && setup.frames[12 * v + 9] == 0 && setup.frames[12 * v + 10] == 0)
        ++setup.verticesWithoutNormal;
  }
  r.verticesWithoutNormal = setup.verticesWithoutNormal;
  const bool visibility = o.mode != TransportMode::Unshadowed;
  DeviceScene scene = prepare(rt, mesh, o, setup, visibility, r);

  auto& q = rt.queue();
  const cl::NDRange global(roundUp(size_t(nv), kLocalSize)), local(kLocalSize);
  cl::Buffer direct(rt.context(), CL_MEM_READ_WRITE, size_t(nv) * nc * 4);
  cl::Buffer visible(rt.context(), CL_MEM_WRITE_ONLY, size_t(nv) * 4);
  cl::Kernel kd = directKernel(rt, o, visibility, scene, nv, "transport_direct", "transport_direct_packet", 10);
  kd.setArg(8, direct);
  kd.setArg(9, visible);
  const auto tKernel = Clock::now();
  std::vector<float> t0(size_t(nv) * nc), vis(static_cast<size_t>(nv));
  // scene.unoccludable is indexed by the whole mesh's vertices; this call covers [first, first + nv).
  auto unoccludable = [&](int v) { return scene.unoccludable.empty() ? uint8_t(0) : scene.unoccludable[first + size_t(v)]; };
  for (int v = 0; v < nv; ++v) r.verticesUnoccludable += unoccludable(v);
  if (r.verticesUnoccludable > 0) {
    // Unoccludable vertices are marked in the origins' w (transport.cl): the same launch
    // computes them without rays, with the same directions as every other vertex.
    std::vector<float> marked = setup.origins;
    for (int v = 0; v < nv; ++v)
      if (unoccludable(v)) marked[4 * size_t(v) + 3] = 1.0f;
    scene.origins = rt.upload(marked);
    kd.setArg(2, scene.origins);
  }
  q.enqueueNDRangeKernel(kd, cl::NullRange, global, local);
  q.enqueueReadBuffer(direct, CL_TRUE, 0, t0.size() * 4, t0.data());
  q.enqueueReadBuffer(visible, CL_TRUE, 0, vis.size() * 4, vis.data());
  r.totalSamples = uint64_t(nv) * uint64_t(o.samples);
  if (visibility) r.rays += uint64_t(nv - int(r.verticesUnoccludable)) * uint64_t(o.samples);

  // Standard error of the direct term (see transport.h).
  r.stdError.assign(size_t(nv), 0.0f);
  double sumErr = 0;
  for (int v = 0; v < nv; ++v) {
    double norm2 = 0;
    for (int k = 0; k < nc; ++k) norm2 += double(t0[size_t(v) * nc + k]) * t0[size_t(v) * nc + k];
    const double var = nc / (4 * kPi) * vis[v] - norm2;
    const double se = std::sqrt(std::max(0.0, var) / o.samples);
    r.stdError[v] = float(se);
    r.maxStdError = std::max(r.maxStdError, se);
    sumErr += se;
  }
  r.meanStdError = nv ? sumErr / nv : 0;

  if (o.mode != TransportMode::Interreflected) {
    r.coeffs = std::move(t0);
  } else {
    const int ch = r.channels, stride = ch * nc;
    std::vector<float> prev(size_t(nv) * stride);
    for (int v = 0; v < nv; ++v)
      for (int c = 0; c < ch; ++c)
        for (int k = 0; k < nc; ++k) prev[size_t(v) * stride + c * nc + k] = t0[size_t(v) * nc + k];
    std::vector<double> total(prev.begin(), prev.end());
    if (o.keepBounces) r.bounceCoeffs.push_back(prev);
    // Triangle indices and albedo for the gather.
    std::vector<int32_t> idx(mesh.triangleCount() * 4, 0);
    for (size_t t = 0; t < mesh.triangleCount(); ++t)
      for (int k = 0; k < 3; ++k) idx[4 * t + k] = int32_t(mesh.indices[3 * t + k]);
    cl::Buffer idxBuf = rt.upload(idx);
    cl::Buffer albedoBuf = rt.upload(detail::vertexAlbedo(mesh, o));
    cl::Buffer prevBuf(rt.context(), CL_MEM_READ_WRITE, prev.size() * 4);
    cl::Buffer nextBuf(rt.context(), CL_MEM_READ_WRITE, prev.size() * 4);
    q.enqueueWriteBuffer(prevBuf, CL_TRUE, 0, prev.size() * 4, prev.data());
    const bool packet = o.packetWidth > 0;
    cl::Kernel kb = rt.kernel("transport.cl", packet ? "transport_bounce_packet" : "transport_bounce",
                              options(o.order, true, ch, o.packetWidth));
    setCommonArgs(kb, nv, o.samples, scene);
    if (packet) {
      kb.setArg(4, scene.dirsSoA);
      kb.setArg(12, scene.paddedCount);
    }
    kb.setArg(8, idxBuf);
    kb.setArg(9, albedoBuf);
    std::vector<float> next(prev.size());
    for (int b = 1; b <= o.bounces; ++b) {
      kb.setArg(10, prevBuf);
      kb.setArg(11, nextBuf);
      q.enqueueNDRangeKernel(kb, cl::NullRange, global, local);
      q.enqueueReadBuffer(nextBuf, CL_TRUE, 0, next.size() * 4, next.data());
      r.rays += uint64_t(nv) * uint64_t(o.samples);
      double maxNorm = 0;
      for (int v = 0; v < nv; ++v) {
        double n2 = 0;
        for (int k = 0; k < stride; ++k) {
          const double x = next[size_t(v) * stride + k];
          n2 += x * x;
          total[size_t(v) * stride + k] += x;
        }
        maxNorm = std::max(maxNorm, std::sqrt(n2));
      }
      r.bounceMaxNorm.push_back(maxNorm);
      r.bouncesUsed = b;
      if (o.keepBounces) r.bounceCoeffs.push_back(next);
      if (maxNorm < o.bounceTolerance) break;
      std::swap(prevBuf, nextBuf);
    }
    r.coeffs.assign(total.begin(), total.end());
  }
  r.kernelSeconds = since(tKernel);
  r.totalSeconds = since(tStart);
  return r;
}

std::vector<uint8_t> traceVisibility(Runtime& rt, const Mesh& mesh, const TransportOptions& o) {
  detail::checkTransportOptions(o);
  validateMesh(mesh, mesh.sourcePath.empty() ? "mesh" : mesh.sourcePath);
  TransportResult r;
  const detail::RaySetup setup = detail::makeRaySetup(mesh, o);
  DeviceScene scene = prepare(rt, mesh, o, setup, true, r);
  const int nv = int(mesh.vertexCount());
  cl::Buffer out(rt.context(), CL_MEM_WRITE_ONLY, std::max<size_t>(size_t(nv) * o.samples, 16));
  cl::Kernel k = directKernel(rt, o, true, scene, nv, "transport_visibility", "transport_visibility_packet", 9);
  k.setArg(8, out);
  rt.queue().enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(roundUp(size_t(nv), kLocalSize)),
                                  cl::NDRange(kLocalSize));
  std::vector<uint8_t> vis(size_t(nv) * o.samples);
  rt.queue().enqueueReadBuffer(out, CL_TRUE, 0, vis.size(), vis.data());
  return vis;
}

}  // namespace prtbake
