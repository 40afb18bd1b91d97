// Adaptive sample counts for the direct term ("--tolerance E"; see transport.h). Shadowed
// mode: the closed form for vertices that cannot be occluded, the visibility quadtree
// (transport_quadtree.cpp) for the others. Unshadowed mode:
//
// Every vertex takes the points of ONE 2-D Sobol' sequence (sobol.h) with a digital shift
// drawn from the seed, mapped to the cosine-weighted hemisphere and turned into the
// vertex's frame, whose tangent is rotated about the normal by the same per-vertex angle
// as on the uniform path (makeRaySetup): the rotation decorrelates neighbouring vertices
// and is identical in every round. Round 0 takes points [0, n0), round j ≥ 1 points
// [N/2, N) with N = n0·2^j, so a vertex at N samples holds exactly the first N points, a
// (0, log₂N, 2)-net like the uniform path's N-point Hammersley set. With T̂_i(N) the mean
// over the first N points and
//   d(N) = max_i |T̂_i(N) − T̂_i(N/2)|,
// an error falling like 1/N gives |T̂(N) − T̂(N/2)| ≈ err(N/2) ≈ 2 err(N); the estimate
// takes the last two differences so that one lucky coincidence does not stop a vertex:
//   err(p) = K · max(d(N), d(N/2)/2)   (K = kTransportErrorFactor),
// defined from N = 4 n0 on. A vertex stops at the first N ≥ kTransportToleranceMinSamples
// with err(p) < E, or when one more round would exceed the cap (2N > toleranceMaxSamples;
// then it is reported at the cap).
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
  const int n0 = kTransportToleranceMinSamples / 4;

  // Scene: the BVH (once), and the vertices that need no rays.
  TransportOptions base = o;
  base.samples = 1;
  const RaySetup setup0 = makeRaySetup(mesh, base);
  r.verticesWithoutNormal = setup0.verticesWithoutNormal;
  cl::Buffer nodes = rt.upload(std::vector<float>(8, 0.0f)), tris = rt.upload(std::vector<float>(12, 0.0f));
  std::vector<uint8_t> unocc(nv, 1);
  if (visibility) {
    const auto t0 = Clock::now();
    const Bvh bvh = buildBvh(mesh);
    r.bvhSeconds = since(t0);
    r.bvhNodes = bvh.nodes.size();
    r.degenerateTriangles = bvh.degenerateTriangles;
    if (!bvh.nodes.empty()) {
      nodes = rt.upload(bvh.nodes);
      tris = rt.upload(bvh.packed);
      unocc = unoccludableFromBvh(mesh, bvh, setup0);
    }
    for (uint8_t u : unocc) r.verticesUnoccludable += u;
  }
  DirectRunner runner(rt, o, nodes, tris, setup0.tMax);

  std::vector<double> sum(nv * nc, 0.0), prev(nv * nc, 0.0), dPrev(nv, 0.0);
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
  if (visibility) {  // every listed vertex can be occluded
    quadtreeTransport(rt, setup0, nodes, tris, active, o, r);
    active.clear();
  }
  RaySetup setup = setup0;  // frames and origins of the seed; directions per round
  for (int round = 0; !active.empty(); ++round) {
    const int total = n0 << round;                 // samples per vertex after this round
    const int first = round == 0 ? 0 : total / 2;  // this round's block [first, total)
    const int m = total - first;
    setup.dirs = sobolDirectionsLocal(uint32_t(first), m, o.seed);
    for (int traced = 0; traced < 2; ++traced) {
      std::vector<uint32_t> list;
      for (uint32_t v : active)
        if ((visibility && !unocc[v]) == bool(traced)) list.push_back(v);
      if (list.empty()) continue;
      std::vector<float> c, f;
      runner.run(setup, list, traced == 1, c, f);
      if (traced) r.rays += uint64_t(list.size()) * uint64_t(m);
      for (size_t i = 0; i < list.size(); ++i) {
        double* a = &sum[size_t(list[i]) * nc];
        for (int k = 0; k < nc; ++k) a[k] += double(m) * c[i * nc + k];
      }
    }
    std::vector<uint32_t> next;
    for (uint32_t v : active) {
      double d = 0;
      for (int k = 0; k < nc; ++k) {
        const double mean = sum[size_t(v) * nc + k] / total;
        d = std::max(d, std::abs(mean - prev[size_t(v) * nc + k]));
        prev[size_t(v) * nc + k] = mean;
        r.coeffs[size_t(v) * nc + k] = float(mean);
      }
      r.samplesPerVertex[v] = total;
      if (round == 0) {  // no difference yet
        next.push_back(v);
        continue;
      }
      const double err = kTransportErrorFactor * std::max(d, dPrev[v] / 2);
      dPrev[v] = d;
      r.errorEstimate[v] = float(err);
      r.stdError[v] = float(err);
      if (round < 2 || total < kTransportToleranceMinSamples || !(err < o.tolerance)) {
        if (int64_t(total) * 2 > o.toleranceMaxSamples) {
          ++r.verticesAtCap;
          continue;
        }
        next.push_back(v);
      }
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
