// Adaptive sample counts for the direct term ("--tolerance E"; see transport.h).
//
// R = kTransportReplicas independent randomisations of the sample set (each its own
// Cranley–Patterson shift and per-vertex rotation, drawn from the seed, the round and
// the replica). Round j adds to every unconverged vertex m_j fresh samples per replica
// (m_0 = n0, then m_j = n0·2^(j−1), so replica r holds N_j = n0·2^j samples), and keeps
// the sample-weighted mean of each replica:
//   T̂_r,i(p) = (Σ_rounds m_j T̂_r,i^(j)(p)) / N_j,   T̂_i = (1/R) Σ_r T̂_r,i,
//   s_i² = (1/(R−1)) Σ_r (T̂_r,i − T̂_i)²,   err(p) = K max_i s_i/√R   (K = kTransportErrorFactor).
// A vertex stops when err(p) < E, or when one more round would exceed the cap
// (R·N_{j+1} > toleranceMaxSamples; then it is reported at the cap). Each replica is an
// unbiased randomised-QMC estimate, so s_i/√R estimates the standard error of T̂_i.
#include <algorithm>
#include <chrono>
#include <cmath>

#include "prtbake/bvh.h"
#include "prtbake/error.h"
#include "prtbake/sh.h"
#include "transport_direct.h"
#include "transport_setup.h"

namespace prtbake::detail {
namespace {
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

uint64_t mix(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

template <class T>
cl::Buffer upload(Runtime& rt, const std::vector<T>& v) {
  const size_t bytes = std::max<size_t>(v.size() * sizeof(T), 16);
  cl::Buffer b(rt.context(), CL_MEM_READ_ONLY, bytes);
  if (!v.empty()) rt.queue().enqueueWriteBuffer(b, CL_TRUE, 0, v.size() * sizeof(T), v.data());
  return b;
}
}  // namespace

TransportResult computeTransportAdaptive(Runtime& rt, const Mesh& mesh, const TransportOptions& o) {
  const auto tStart = Clock::now();
  validateMesh(mesh, mesh.sourcePath.empty() ? "mesh" : mesh.sourcePath);
  TransportResult r;
  r.order = o.order;
  r.vertexCount = mesh.vertexCount();
  r.device = rt.deviceLabel();
  r.channels = 1;
  const int nc = o.order * o.order;
  const size_t nv = mesh.vertexCount();
  const bool visibility = o.mode != TransportMode::Unshadowed;
  constexpr int R = kTransportReplicas;
  const int n0 = kTransportMinReplicaSamples;

  // Scene: the BVH (once), and the vertices that need no rays.
  TransportOptions base = o;
  base.samples = 1;
  const RaySetup setup0 = makeRaySetup(mesh, base);
  r.verticesWithoutNormal = setup0.verticesWithoutNormal;
  cl::Buffer nodes = upload(rt, std::vector<float>(8, 0.0f)), tris = upload(rt, std::vector<float>(12, 0.0f));
  std::vector<uint8_t> unocc(nv, 1);
  if (visibility) {
    const auto t0 = Clock::now();
    const Bvh bvh = buildBvh(mesh);
    r.bvhSeconds = since(t0);
    r.bvhNodes = bvh.nodes.size();
    r.degenerateTriangles = bvh.degenerateTriangles;
    if (!bvh.nodes.empty()) {
      nodes = upload(rt, bvh.nodes);
      tris = upload(rt, bvh.packed);
      unocc = unoccludableFromBvh(mesh, bvh, setup0);
    }
    for (uint8_t u : unocc) r.verticesUnoccludable += u;
  }
  DirectRunner runner(rt, o, nodes, tris, setup0.tMax);

  std::vector<double> acc(size_t(R) * nv * nc, 0.0);
  std::vector<int> perReplica(nv, 0);
  r.coeffs.assign(nv * nc, 0.0f);
  r.stdError.assign(nv, 0.0f);
  r.errorEstimate.assign(nv, 0.0f);
  r.samplesPerVertex.assign(nv, 0);
  // Vertices that cannot be occluded get the closed form (Funk–Hecke: the clamped
  // cosine rotated to the normal), exact and sample-free; the others are sampled.
  std::vector<uint32_t> active;
  for (size_t v = 0; v < nv; ++v) {
    const float* n = &setup0.frames[12 * v + 8];
    if (!(n[0] * n[0] + n[1] * n[1] + n[2] * n[2] > 0)) continue;
    if (visibility && unocc[v]) {
      const auto c = clampedCosineProjected(o.order, n[0], n[1], n[2]);
      for (int k = 0; k < nc; ++k) r.coeffs[v * nc + k] = float(c[k]);
      continue;
    }
    active.push_back(uint32_t(v));
  }
  const auto tKernel = Clock::now();
  for (int round = 0; !active.empty(); ++round) {
    const int m = round == 0 ? n0 : n0 << (round - 1);
    const int total = n0 << round;  // per replica after this round
    for (int rep = 0; rep < R; ++rep) {
      TransportOptions ro = o;
      ro.samples = m;
      ro.seed = mix(o.seed ^ mix(uint64_t(round) * 64 + uint64_t(rep) + 1));
      const RaySetup setup = makeRaySetup(mesh, ro);
      for (int traced = 0; traced < 2; ++traced) {
        std::vector<uint32_t> list;
        for (uint32_t v : active)
          if ((visibility && !unocc[v]) == bool(traced)) list.push_back(v);
        if (list.empty()) continue;
        std::vector<float> c, f;
        runner.run(setup, list, traced == 1, c, f);
        if (traced) r.rays += uint64_t(list.size()) * uint64_t(m);
        for (size_t i = 0; i < list.size(); ++i) {
          double* a = &acc[(size_t(rep) * nv + list[i]) * nc];
          for (int k = 0; k < nc; ++k) a[k] += double(m) * c[i * nc + k];
        }
      }
    }
    std::vector<uint32_t> next;
    for (uint32_t v : active) {
      double errMax = 0, se2 = 0;
      for (int k = 0; k < nc; ++k) {
        double mean = 0, sq = 0;
        for (int rep = 0; rep < R; ++rep) mean += acc[(size_t(rep) * nv + v) * nc + k] / total;
        mean /= R;
        for (int rep = 0; rep < R; ++rep) {
          const double d = acc[(size_t(rep) * nv + v) * nc + k] / total - mean;
          sq += d * d;
        }
        const double s2 = sq / (R - 1);
        errMax = std::max(errMax, std::sqrt(s2 / R));
        se2 += s2 / R;
        r.coeffs[size_t(v) * nc + k] = float(mean);
      }
      const double err = kTransportErrorFactor * errMax;
      r.errorEstimate[v] = float(err);
      r.stdError[v] = float(std::sqrt(se2));
      r.samplesPerVertex[v] = R * total;
      if (err < o.tolerance) continue;
      if (int64_t(R) * total * 2 > o.toleranceMaxSamples) {
        ++r.verticesAtCap;
        continue;
      }
      next.push_back(v);
    }
    active.swap(next);
  }
  r.kernelSeconds = since(tKernel);

  double sumErr = 0, sumSe = 0;
  for (size_t v = 0; v < nv; ++v) {
    r.maxErrorEstimate = std::max(r.maxErrorEstimate, double(r.errorEstimate[v]));
    sumErr += r.errorEstimate[v];
    r.maxStdError = std::max(r.maxStdError, double(r.stdError[v]));
    sumSe += r.stdError[v];
    const int s = r.samplesPerVertex[v];
    r.totalSamples += uint64_t(s);
    r.samples = std::max(r.samples, s);
    if (s > 0) {
      const size_t k = size_t(std::lround(std::log2(double(s))));
      if (r.samplesHistogram.size() <= k) r.samplesHistogram.resize(k + 1, 0);
      ++r.samplesHistogram[k];
    }
  }
  r.meanErrorEstimate = nv ? sumErr / double(nv) : 0;
  r.meanStdError = nv ? sumSe / double(nv) : 0;
  r.totalSeconds = since(tStart);
  return r;
}

}  // namespace prtbake::detail
