// Transport on the OpenCL device: BVH upload, direct term, bounces, and "--tolerance"
// (see transport.h and prtbake/tolerance.h).
#include "prtbake/transport.h"
#include "prtbake/progress.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <future>

#include "core/constants.h"
#include "core/kernel_options.h"
#include "prtbake/bvh.h"
#include "prtbake/clock.h"
#include "prtbake/error.h"
#include "prtbake/limits.h"
#include "prtbake/sh.h"
#include "core/tolerance_pilot.h"
#include "transport/transport_setup.h"

namespace prtbake {
namespace {
using Clock = std::chrono::steady_clock;

// Rays per launch when a progress hook wants the work in pieces: about 0.25 s on a 2-core CPU
// (16 M rays/s), a few milliseconds on a GPU.
constexpr size_t kRaysPerBlock = size_t(1) << 22;

// The most device memory the direct term's blocked-ray masks may take (a bit per ray:
// 1024 samples on 2 million vertices); beyond it the bounces trace every ray.
constexpr double kMaskBytes = 256.0 * 1024 * 1024;
// Rays per 16-bit mask word of the scalar kernels (LANES_MASK_BITS in kernels/lanes.clh; a
// packet kernel's word holds a packet).
constexpr int kScalarMaskBits = 16;
static_assert(detail::kTransportSampleChunk <= 1024,
              "a launch's rays fit the lane form's mask (Runtime::laneMaskMemory)");

// The scene on the device and the kernels over lists of vertices. Each call takes
// `samples` directions per vertex (the samples-point set of the seed and sampler) in
// launches of at most detail::kTransportSampleChunk directions and returns means in double.
class Tracer {
 public:
  // pointsAreVertices: setup holds the mesh's vertices (else surface points, whose blocked
  // rays are not kept: their bounce gathers another run's transport).
  Tracer(Runtime& rt, const Mesh& mesh, const TransportOptions& o, const detail::RaySetup& setup, bool visibility,
         TransportResult& r, bool pointsAreVertices = true)
      : rt_(rt), mesh_(mesh), o_(o), setup_(setup), visibility_(visibility), nc_(o.order * o.order) {
    // Without --tolerance the bounces trace the direct term's rays again (same count, seed,
    // origins and frames): a ray that nothing blocked there hits nothing in a bounce.
    const double words = std::ceil(o.samples / double(o.packetWidth > 0 ? o.packetWidth : kScalarMaskBits));
    keepBlocked_ = pointsAreVertices && visibility && o.mode == TransportMode::Interreflected && o.tolerance <= 0 &&
                   double(mesh.vertexCount()) * words * 2 <= kMaskBytes;
    noMask_ = rt.upload(std::vector<float>(1, 0.0f));
    if (visibility) {
      const auto t0 = Clock::now();
      const Bvh bvh = buildBvh(mesh);
      r.bvhSeconds = secondsSince(t0);
      r.bvhNodes = bvh.nodes.size();
      r.degenerateTriangles = bvh.degenerateTriangles;
      unoccludable_ = detail::unoccludableFromBvh(mesh, bvh, setup);
      nodes_ = detail::uploadBvhNodes(rt, bvh, o.packetWidth > 0);
      tris_ = detail::uploadBvhTriangles(rt, bvh, o.packetWidth > 0);
    } else {
      unoccludable_.assign(setup.count(), 0);
      nodes_ = rt.upload(std::vector<float>(8, 0.0f));
      tris_ = rt.upload(std::vector<float>(12, 0.0f));
    }
  }

  const std::vector<uint8_t>& unoccludable() const { return unoccludable_; }

  // T^(0) of `vertices` (order² each) and their unoccluded fractions. Unoccludable
  // vertices are marked in their origin's w: the kernel traces no rays for them.
  // With keepBlocked_, the whole mesh at o.samples keeps its blocked-ray masks for bounce().
  std::vector<double> direct(const std::vector<uint32_t>& vertices, int samples, std::vector<double>* visible,
                             TransportResult& r) {
    const int nv = int(vertices.size());
    std::vector<double> sums(size_t(nv) * nc_, 0.0), seen(size_t(nv), 0.0);
    blocked_.clear();
    stage_ = "transport: direct";
    if (nv > 0) {
      uploadVertices(vertices);
      cl::Buffer out(rt_.context(), CL_MEM_WRITE_ONLY, sums.size() * 4), vis(rt_.context(), CL_MEM_WRITE_ONLY, seen.size() * 4);
      cl::Kernel k = kernel("transport_direct", "transport_direct_packet", 1);
      k.setArg(8, out);
      k.setArg(9, vis);
      if (o_.packetWidth == 0) {  // the lane form's local memory (transport.cl)
        k.setArg(12, rt_.laneSumMemory(size_t(o_.rayLanes)));
        k.setArg(13, rt_.laneMaskMemory(size_t(o_.rayLanes)));
      }
      const bool keep = keepBlocked_ && samples == o_.samples && size_t(nv) == mesh_.vertexCount();
      std::vector<float> part(sums.size()), partSeen(seen.size());
      // With the masks: the blocked rays of each vertex in each launch (chunk-major), counted
      // from the masks themselves, which the first bounce traces (so the two agree).
      std::vector<uint32_t> chunkBlocked;
      std::vector<uint16_t> words;
      forEachChunk(k, samples, nv, 10, keep ? MaskUse::Write : MaskUse::None, [](int) {}, [&](int chunk, int) {
        // One wait for all reads (the queue runs in order).
        rt_.queue().enqueueReadBuffer(out, CL_FALSE, 0, part.size() * 4, part.data());
        if (keep) {
          words.resize(blocked_[size_t(chunk)].getInfo<CL_MEM_SIZE>() / 2);
          rt_.queue().enqueueReadBuffer(blocked_[size_t(chunk)], CL_FALSE, 0, words.size() * 2, words.data());
        }
        rt_.queue().enqueueReadBuffer(vis, CL_TRUE, 0, partSeen.size() * 4, partSeen.data());
        for (size_t i = 0; i < sums.size(); ++i) sums[i] += part[i];
        for (size_t i = 0; i < seen.size(); ++i) seen[i] += partSeen[i];
        const size_t perVertex = words.size() / size_t(nv);
        for (size_t i = 0; keep && i < size_t(nv); ++i) {
          uint32_t count = 0;
          for (size_t w = 0; w < perVertex; ++w) count += uint32_t(__builtin_popcount(words[i * perVertex + w]));
          chunkBlocked.push_back(count);
        }
      });
      size_t traced = 0;
      for (uint32_t v : vertices) traced += unoccludable_[v] ? 0 : 1;
      if (visibility_) r.rays += uint64_t(traced) * uint64_t(samples);
      planHits(chunkBlocked, size_t(nv), keep);
      r.totalSamples += uint64_t(nv) * uint64_t(samples);
    }
    for (double& x : sums) x /= samples;
    if (visible) {
      for (double& x : seen) x /= samples;
      *visible = std::move(seen);
    }
    return sums;
  }

  // T^(k+1) of `vertices` (channels × order² each) from T^(k) of every vertex in `prev`.
  // more: another bounce may follow (worth keeping the hits for).
  std::vector<double> bounce(const std::vector<uint32_t>& vertices, int samples, int channels,
                             const cl::Buffer& prev, bool more, TransportResult& r) {
    const int nv = int(vertices.size()), stride = channels * nc_;
    std::vector<double> sums(size_t(nv) * stride, 0.0);
    stage_ = "transport: bounce";
    if (nv > 0) {
      uploadSurface();
      uploadVertices(vertices);
      cl::Buffer out(rt_.context(), CL_MEM_WRITE_ONLY, sums.size() * 4);
      cl::Kernel k = kernel("transport_bounce", "transport_bounce_packet", channels);
      k.setArg(8, indices_);
      k.setArg(9, albedo_);
      k.setArg(10, prev);
      k.setArg(11, out);
      if (o_.packetWidth == 0) k.setArg(18, rt_.laneSumMemory(size_t(o_.rayLanes)));
      const bool reuse = !blocked_.empty() && samples == o_.samples && size_t(nv) == mesh_.vertexCount();
      const bool record = reuse && more && hitChunks_ > 0 && !hitsWritten_;
      const bool replay = reuse && hitChunks_ > 0 && hitsWritten_;
      if (record) hits_ = cl::Buffer(rt_.context(), CL_MEM_READ_WRITE, std::max<size_t>(12, size_t(blockedRays_) * 12));
      std::vector<float> part(sums.size());
      auto collect = [&](int, int) {
        rt_.queue().enqueueReadBuffer(out, CL_TRUE, 0, part.size() * 4, part.data());
        for (size_t i = 0; i < sums.size(); ++i) sums[i] += part[i];
      };
      if (replay) {  // the hits of the first bounce, gathered again
        gatherHits(nv, channels, prev, out, collect);
      } else {
        const int hitArg = o_.packetWidth > 0 ? 15 : 14;  // after the mask's two arguments
        forEachChunk(k, samples, nv, 12, reuse ? MaskUse::Read : MaskUse::None, [&](int chunk) {
          k.setArg(hitArg, record ? hits_ : noMask_);
          k.setArg(hitArg + 1, record ? hitStart_ : noMask_);
          k.setArg(hitArg + 2, record ? hitChunks_ : 0);
          k.setArg(hitArg + 3, chunk);
        }, collect);
        hitsWritten_ = record;
      }
      size_t traced = 0;  // the kernel skips vertices that nothing can reach
      for (uint32_t v : vertices) traced += unoccludable_[v] ? 0 : 1;
      r.rays += replay ? 0 : reuse ? blockedRays_ : uint64_t(traced) * uint64_t(samples);
      r.totalSamples += uint64_t(nv) * uint64_t(samples);
    }
    for (double& x : sums) x /= samples;
    return sums;
  }

 private:
  // With the masks kept: where each vertex's hits of each launch (chunkBlocked, chunk-major)
  // go, vertex-major so that a vertex's hits lie together; none kept when they would take
  // more than detail::kKeptHitBytes.
  void planHits(const std::vector<uint32_t>& chunkBlocked, size_t nv, bool keep) {
    blockedRays_ = 0;
    for (uint32_t b : chunkBlocked) blockedRays_ += b;
    hitsWritten_ = false;
    hitChunks_ = 0;
    if (!keep || double(blockedRays_) * 12 > detail::kKeptHitBytes) return;
    const size_t chunks = chunkBlocked.size() / nv;
    std::vector<int32_t> start(nv * chunks + 1, 0);
    for (size_t i = 0; i < nv; ++i)
      for (size_t c = 0; c < chunks; ++c)
        start[i * chunks + c + 1] = start[i * chunks + c] + int32_t(chunkBlocked[c * nv + i]);
    hitStart_ = rt_.upload(start);
    hitChunks_ = int(chunks);
  }

  // The first bounce's recorded hits, each launch's gathered again under `prev`.
  template <class Collect>
  void gatherHits(int nv, int channels, const cl::Buffer& prev, const cl::Buffer& out, Collect&& collect) {
    cl::Kernel g = rt_.kernel("transport.cl", "transport_gather",
                              detail::transportOptions(o_.order, visibility_, channels, o_.packetWidth, o_.rayLanes));
    g.setArg(0, nv);
    g.setArg(1, hits_);
    g.setArg(2, hitStart_);
    g.setArg(3, hitChunks_);
    g.setArg(5, indices_);
    g.setArg(6, albedo_);
    g.setArg(7, prev);
    g.setArg(8, out);
    for (int c = 0; c < hitChunks_; ++c) {
      g.setArg(4, c);
      launchVertices(g, nv, detail::kTransportSampleChunk, double(c) / hitChunks_, 1.0 / hitChunks_);
      collect(c, 0);
    }
  }

  // The triangles' vertex indices and the vertices' albedo, uploaded once for the bounces.
  void uploadSurface() {
    if (indices_()) return;
    std::vector<int32_t> idx(mesh_.triangleCount() * 4, 0);
    for (size_t t = 0; t < mesh_.triangleCount(); ++t)
      for (int c = 0; c < 3; ++c) idx[4 * t + c] = int32_t(mesh_.indices[3 * t + c]);
    indices_ = rt_.upload(idx);
    albedo_ = rt_.upload(detail::vertexAlbedo(mesh_, o_));
  }

  cl::Kernel kernel(const char* scalarName, const char* packetName, int channels) {
    const bool packet = o_.packetWidth > 0;
    cl::Kernel k = rt_.kernel("transport.cl", packet ? packetName : scalarName,
                              detail::transportOptions(o_.order, visibility_, channels, o_.packetWidth, o_.rayLanes));
    k.setArg(2, origins_);
    k.setArg(3, frames_);
    k.setArg(5, nodes_);
    k.setArg(6, tris_);
    k.setArg(7, setup_.tMax);
    return k;
  }

  // Origins (w = 1: unoccludable) and frames of the listed vertices.
  void uploadVertices(const std::vector<uint32_t>& vertices) {
    std::vector<float> origins(vertices.size() * 4), frames(vertices.size() * 12);
    for (size_t i = 0; i < vertices.size(); ++i) {
      std::copy_n(&setup_.origins[4 * size_t(vertices[i])], 4, &origins[4 * i]);
      std::copy_n(&setup_.frames[12 * size_t(vertices[i])], 12, &frames[12 * i]);
      origins[4 * i + 3] = unoccludable_[vertices[i]] ? 1.0f : 0.0f;
    }
    origins_ = rt_.upload(origins);
    frames_ = rt_.upload(frames);
  }

  // Launches `k` over nv vertices for each chunk of the direction set, then `collect`.
  // paddedArg: the argument index of the packet kernels' padded direction count, followed
  // by the blocked-ray mask and its words per vertex (written, read, or none: 0 words); the
  // scalar kernels take the mask there, without the count.
  // before(chunk) sets what else a launch needs; collect(chunk, directions) reads it back.
  enum class MaskUse { None, Write, Read };
  template <class Before, class Collect>
  void forEachChunk(cl::Kernel& k, int samples, int nv, int paddedArg, MaskUse mask, Before&& before,
                    Collect&& collect) {
    const bool packet = o_.packetWidth > 0;
    k.setArg(0, nv);
    for (int first = 0, chunk = 0; first < samples; first += detail::kTransportSampleChunk, ++chunk) {
      const int n = std::min(detail::kTransportSampleChunk, samples - first);
      std::vector<float> dirs = detail::directionChunk(samples, first, n, o_.seed, o_.sampler);
      int words = (n + kScalarMaskBits - 1) / kScalarMaskBits, maskArg = paddedArg;
      if (packet) {
        int padded = 0;
        dirs = detail::packetDirections(dirs, padded);
        k.setArg(paddedArg, padded);
        words = padded / o_.packetWidth;
        maskArg = paddedArg + 1;
      }
      const cl::Buffer d = rt_.upload(dirs);
      k.setArg(1, n);
      k.setArg(4, d);
      if (mask == MaskUse::Write) blocked_.emplace_back(rt_.context(), CL_MEM_READ_WRITE, size_t(nv) * size_t(words) * 2);
      k.setArg(maskArg, mask == MaskUse::None ? noMask_ : blocked_[size_t(chunk)]);
      k.setArg(maskArg + 1, mask == MaskUse::None ? 0 : words);
      before(chunk);
      const int chunks = (samples + detail::kTransportSampleChunk - 1) / detail::kTransportSampleChunk;
      launchVertices(k, nv, n, double(chunk) / chunks, 1.0 / chunks, size_t(o_.rayLanes));  // 1 with packets
      collect(chunk, n);
    }
  }

  // One launch of `k` over the nv vertices, `lanes` work-items each; with a progress hook
  // (prtbake/progress.h), blocks of about kRaysPerBlock rays, each waited for and reported as
  // fraction done + span × the part launched.
  void launchVertices(cl::Kernel& k, int nv, int raysPerVertex, double done, double span, size_t lanes = 1) {
    if (!progressWanted()) {
      rt_.enqueueLoop(k, size_t(nv), 0, lanes);
      return;
    }
    const size_t local = rt_.loopGroupSize();
    const size_t block = std::max(local, kRaysPerBlock / size_t(std::max(raysPerVertex, 1)) / local * local);
    for (size_t first = 0; first < size_t(nv); first += block) {
      const size_t n = std::min(block, size_t(nv) - first);
      rt_.enqueueLoop(k, n, first, lanes);
      rt_.queue().finish();
      reportProgress(stage_, done + span * double(first + n) / double(nv));
    }
  }

  Runtime& rt_;
  const Mesh& mesh_;
  const TransportOptions& o_;
  const detail::RaySetup& setup_;
  bool visibility_;
  int nc_;
  std::vector<uint8_t> unoccludable_;
  cl::Buffer nodes_, tris_, origins_, frames_, indices_, albedo_, noMask_;
  bool keepBlocked_ = false;
  const char* stage_ = "transport: direct";  // what launchVertices reports
  std::vector<cl::Buffer> blocked_;  // per chunk of directions: V × words ushort
  uint64_t blockedRays_ = 0;         // the rays the last direct() found blocked
  // The first bounce's hits of those rays (3 floats each) and where each vertex's start,
  // per launch (hitChunks_ launches; 0: not kept).
  cl::Buffer hits_, hitStart_;
  int hitChunks_ = 0;
  bool hitsWritten_ = false;
};

// The size of the requested vertex range; throws UsageError when it leaves the mesh
// or splits an interreflected job.
size_t rangeSize(const Mesh& mesh, const TransportOptions& o) {
  const size_t count = detail::vertexRangeSize(mesh, o.firstVertex, o.vertexCount);
  if (o.mode == TransportMode::Interreflected && count != mesh.vertexCount())
    throw UsageError("vertex range", "interreflected transport needs every vertex (each bounce reads the "
                                     "previous bounce of the whole mesh); compute the whole mesh");
  return count;
}

bool hasNormal(const detail::RaySetup& s, size_t v) {
  return s.frames[12 * v + 8] != 0 || s.frames[12 * v + 9] != 0 || s.frames[12 * v + 10] != 0;
}

// The count for one term under --tolerance: the pilot over every k-th sampled vertex of the
// whole mesh (prtbake/tolerance.h: at most 128, one in up to 8 of a small mesh's, at least
// 64), `evaluate` giving their values at N samples.
int toleranceCount(const std::vector<uint32_t>& sampled, size_t stride, double tolerance, const TransportOptions& o,
                   const std::function<std::vector<double>(const std::vector<uint32_t>&, int)>& evaluate,
                   TransportResult& r) {
  std::vector<uint32_t> pilot;
  const size_t v = sampled.size();
  const size_t step = std::max((v + kTolerancePilotVertices - 1) / kTolerancePilotVertices,
                               std::min(kTolerancePilotShare, v / kTolerancePilotMinVertices));
  for (size_t i : detail::pilotSubset(v, step)) pilot.push_back(sampled[i]);
  auto each = [&](const std::vector<int>& counts) {
    std::vector<std::vector<double>> out;
    for (int n : counts) out.push_back(evaluate(pilot, n));
    return out;
  };
  ToleranceReport rep =
      detail::runTolerancePilot(each, stride, tolerance, o.toleranceMaxSamples, int(std::max(o.packetWidth, 1)));
  rep.items = sampled.size();
  r.tolerance.push_back(rep);
  return rep.samples;
}

// The direct term under --tolerance: the closed form where nothing can be in the way (zero
// for a vertex without a normal), the others at the count the pilot predicts. Returns the
// vertices of the range that were sampled.
std::vector<uint32_t> directWithTolerance(Tracer& tracer, const detail::RaySetup& setup, const Mesh& mesh,
                                          const TransportOptions& o, bool visibility,
                                          const std::vector<uint32_t>& range, std::vector<double>* direct,
                                          std::vector<double>* visible, TransportResult& r) {
  auto needsSamples = [&](uint32_t v) { return visibility && hasNormal(setup, v) && !tracer.unoccludable()[v]; };
  const size_t nvAll = setup.count(), count = range.size();
  const int nc = o.order * o.order;
  std::vector<uint32_t> sampledAll;
  for (uint32_t v = 0; v < nvAll; ++v)
    if (needsSamples(v)) sampledAll.push_back(v);
  std::vector<uint32_t> sampled;
  for (uint32_t v : range)
    if (needsSamples(v)) sampled.push_back(v);
  std::vector<double>& t0 = *direct;
  std::vector<double>& vis = *visible;
  t0.assign(count * nc, 0.0);
  vis.assign(count, 1.0);
  for (size_t i = 0; i < count; ++i)
    if (hasNormal(setup, range[i]) && !needsSamples(range[i])) {
      const float* n = &setup.frames[12 * size_t(range[i]) + 8];
      const std::vector<double> c = clampedCosineProjected(o.order, n[0], n[1], n[2]);
      std::copy(c.begin(), c.end(), t0.begin() + std::ptrdiff_t(i * nc));
    }
  const double share = o.mode == TransportMode::Interreflected ? o.tolerance / 2 : o.tolerance;
  r.samples = 0;
  if (!sampledAll.empty()) {
    r.samples = toleranceCount(sampledAll, nc, share, o,
                               [&](const std::vector<uint32_t>& vs, int n) { return tracer.direct(vs, n, nullptr, r); }, r);
    std::vector<double> sVis;
    const std::vector<double> s = tracer.direct(sampled, r.samples, &sVis, r);
    for (size_t j = 0, i = 0; i < count; ++i)
      if (j < sampled.size() && sampled[j] == range[i]) {
        std::copy_n(s.begin() + std::ptrdiff_t(j * nc), nc, t0.begin() + std::ptrdiff_t(i * nc));
        vis[i] = sVis[j++];
      }
  } else {
    ToleranceReport rep;
    rep.tolerance = share;
    rep.strategy = "closed form";
    rep.why = visibility ? "no vertex can be occluded: each takes the Funk-Hecke projection of its clamped cosine"
                         : "unshadowed transport is the Funk-Hecke projection of the clamped cosine";
    rep.items = nvAll;
    r.tolerance.push_back(rep);
  }
  return sampled;
}

// The bounces over the whole mesh (range: every vertex): T^(k+1) from T^(k), until one adds
// less than bounceTolerance; the sum into r.coeffs. sampled: under --tolerance, the vertices
// that something can occlude (the others see no other surface: their bounces are zero).
void interreflect(Runtime& rt, Tracer& tracer, const TransportOptions& o, const std::vector<uint32_t>& range,
                  const std::vector<uint32_t>* sampled, const std::vector<double>& t0, TransportResult& r) {
  const size_t nvAll = range.size();
  const int nc = o.order * o.order, ch = r.channels, stride = ch * nc;
  std::vector<float> prev(nvAll * stride);
  for (size_t v = 0; v < nvAll; ++v)
    for (int c = 0; c < ch; ++c)
      for (int k = 0; k < nc; ++k) prev[v * stride + c * nc + k] = float(t0[v * nc + k]);
  std::vector<double> total(prev.begin(), prev.end());
  if (o.keepBounces) r.bounceCoeffs.push_back(prev);
  cl::Buffer prevBuf(rt.context(), CL_MEM_READ_ONLY, prev.size() * 4);
  for (int b = 1; b <= o.bounces; ++b) {
    rt.queue().enqueueWriteBuffer(prevBuf, CL_TRUE, 0, prev.size() * 4, prev.data());
    auto evaluate = [&](const std::vector<uint32_t>& vs, int n) {
      return tracer.bounce(vs, n, ch, prevBuf, b < o.bounces, r);
    };
    std::vector<double> next(prev.size(), 0.0);
    if (!sampled) {
      next = evaluate(range, o.samples);
    } else if (!sampled->empty()) {
      // Vertices nothing can occlude see no other surface: their bounces are zero.
      const int n = toleranceCount(*sampled, size_t(stride), o.tolerance / std::pow(2.0, b + 1), o, evaluate, r);
      const std::vector<double> s = evaluate(*sampled, n);
      for (size_t j = 0; j < sampled->size(); ++j)
        std::copy_n(s.begin() + std::ptrdiff_t(j * stride), stride,
                    next.begin() + std::ptrdiff_t((*sampled)[j] * size_t(stride)));
    }
    double maxNorm = 0;
    for (size_t v = 0; v < nvAll; ++v) {
      double n2 = 0;
      for (int k = 0; k < stride; ++k) {
        const double x = next[v * stride + k];
        n2 += x * x;
        total[v * stride + k] += x;
      }
      maxNorm = std::max(maxNorm, std::sqrt(n2));
    }
    prev.assign(next.begin(), next.end());
    r.bounceMaxNorm.push_back(maxNorm);
    r.bouncesUsed = b;
    if (o.keepBounces) r.bounceCoeffs.push_back(prev);
    if (maxNorm < o.bounceTolerance) break;
  }
  r.coeffs.assign(total.begin(), total.end());
}

// The standard error of the direct term (see transport.h) of each vertex of the range that was
// sampled (all, or those in `sampled`), with their maximum and mean, into r.
void standardErrors(const std::vector<double>& t0, const std::vector<double>& vis, const std::vector<uint32_t>& range,
                    const std::vector<uint32_t>* sampled, int order, size_t nvAll, TransportResult& r) {
  const size_t count = range.size();
  const int nc = order * order;
  r.stdError.assign(count, 0.0f);
  double sumErr = 0;
  const int nSamples = std::max(r.samples, 1);
  std::vector<char> isSampled(nvAll, sampled ? 0 : 1);
  if (sampled)
    for (uint32_t v : *sampled) isSampled[v] = 1;
  for (size_t i = 0; i < count; ++i) {
    if (!isSampled[range[i]]) continue;
    double norm2 = 0;
    for (int k = 0; k < nc; ++k) norm2 += t0[i * nc + k] * t0[i * nc + k];
    const double se = std::sqrt(std::max(0.0, nc / (4 * kPi) * vis[i] - norm2) / nSamples);
    r.stdError[i] = float(se);
    r.maxStdError = std::max(r.maxStdError, se);
    sumErr += se;
  }
  r.meanStdError = sumErr / double(count);
}

}  // namespace

std::string detail::transportOptions(int order, bool visibility, int channels, int packetWidth, int rayLanes) {
  return "-DSH_ORDER=" + std::to_string(order) + " -DVISIBILITY=" + (visibility ? "1" : "0") +
         " -DCHANNELS=" + std::to_string(channels) + " -DBVH_PACKET=" + std::to_string(packetWidth) +
         rayLanesOption(rayLanes);
}

namespace {

// The transport of `range` (indices into setup: the mesh's vertices, or surface points) into
// r: the direct term, its standard errors, and the bounces. bounceSource (surface points,
// interreflected): the mesh's per-vertex transport (channels × order² each) that one bounce
// gathers; else interreflected transport runs bounce after bounce over the vertices.
void bake(Runtime& rt, const Mesh& mesh, const TransportOptions& o, const detail::RaySetup& setup,
          const std::vector<uint32_t>& range, const std::vector<float>* bounceSource, TransportResult& r) {
  const bool visibility = o.mode != TransportMode::Unshadowed;
  // The direct term's program is built (or read from the caches) while the BVH is set up.
  auto program = std::async(std::launch::async, [&rt, &o, visibility] {
    rt.program("transport.cl", detail::transportOptions(o.order, visibility, 1, o.packetWidth, o.rayLanes));
  });
  for (uint32_t v : range) r.verticesWithoutNormal += hasNormal(setup, v) ? 0 : 1;
  Tracer tracer(rt, mesh, o, setup, visibility, r, bounceSource == nullptr);
  program.get();
  const auto tKernel = Clock::now();
  for (uint32_t v : range) r.verticesUnoccludable += tracer.unoccludable()[v];

  // The direct term T^(0) of the range; under --tolerance, the vertices that were sampled
  // (null: every vertex).
  std::vector<double> t0, vis;
  std::vector<uint32_t> sampledUnderTolerance;
  const std::vector<uint32_t>* sampled = nullptr;
  if (o.tolerance > 0) {
    sampledUnderTolerance = directWithTolerance(tracer, setup, mesh, o, visibility, range, &t0, &vis, r);
    sampled = &sampledUnderTolerance;
  } else {
    t0 = tracer.direct(range, o.samples, &vis, r);
  }
  standardErrors(t0, vis, range, sampled, o.order, setup.count(), r);
  if (o.mode != TransportMode::Interreflected) {
    r.coeffs.assign(t0.begin(), t0.end());
  } else if (!bounceSource) {
    interreflect(rt, tracer, o, range, sampled, t0, r);
  } else {
    // One bounce gathers the mesh's transport (every point of the range; under --tolerance the
    // sampled ones at the count its pilot predicts for E/2, the others see no surface).
    const int nc = o.order * o.order, stride = r.channels * nc;
    const cl::Buffer source = rt.upload(*bounceSource);
    std::vector<double> gathered(range.size() * stride, 0.0);
    if (!sampled) {
      gathered = tracer.bounce(range, o.samples, r.channels, source, false, r);
    } else if (!sampled->empty()) {
      auto evaluate = [&](const std::vector<uint32_t>& vs, int n) { return tracer.bounce(vs, n, r.channels, source, false, r); };
      const int n = toleranceCount(*sampled, size_t(stride), o.tolerance / 2, o, evaluate, r);
      const std::vector<double> g = evaluate(*sampled, n);
      for (size_t j = 0; j < sampled->size(); ++j)  // range is 0 … count − 1 here
        std::copy_n(g.begin() + std::ptrdiff_t(j * stride), stride, gathered.begin() + std::ptrdiff_t((*sampled)[j] * size_t(stride)));
    }
    r.coeffs.resize(range.size() * stride);
    for (size_t i = 0; i < range.size(); ++i)
      for (int c = 0; c < r.channels; ++c)
        for (int k = 0; k < nc; ++k)
          r.coeffs[i * stride + c * nc + k] = float(t0[i * nc + k] + gathered[i * stride + c * nc + k]);
  }
  r.kernelSeconds = secondsSince(tKernel);
}

// The options checked, with the packet width and lanes the device takes (detail::packetWidthFor,
// detail::rayLanesFor).
TransportOptions checkedFor(const Runtime& rt, const TransportOptions& options) {
  detail::checkTransportOptions(options);
  TransportOptions o = options;
  o.packetWidth = detail::packetWidthFor(rt.info(), o.packetWidth);
  o.rayLanes = detail::rayLanesFor(rt.info(), o.packetWidth, o.rayLanes);
  return o;
}

}  // namespace

double transportPeakBytes(const Mesh& mesh, const TransportOptions& o) {
  const double interreflected = o.mode == TransportMode::Interreflected ? 3 : 1;
  const double channels = detail::transportIsRgb(mesh, o) ? 3 : 1;
  return kRuntimeMemoryBytes + interreflected * (500.0 * double(mesh.vertexCount()) +
                                             16.0 * o.order * o.order * channels * double(rangeSize(mesh, o)));
}

TransportResult computeTransport(Runtime& rt, const Mesh& mesh, const TransportOptions& options) {
  const auto tStart = Clock::now();
  const TransportOptions o = checkedFor(rt, options);
  validateMesh(mesh, mesh.sourcePath.empty() ? "mesh" : mesh.sourcePath);
  TransportResult r;
  r.order = o.order;
  r.samples = o.samples;
  r.device = rt.deviceLabel();
  const size_t first = o.firstVertex, count = rangeSize(mesh, o);
  r.vertexCount = count;
  r.firstVertex = first;
  r.channels = detail::transportIsRgb(mesh, o) ? 3 : 1;
  if (count == 0) {
    r.totalSeconds = secondsSince(tStart);
    return r;
  }
  checkProcessMemory(mesh.sourcePath.empty() ? "mesh" : mesh.sourcePath,
                     "transport of " + std::to_string(count) + " vertices at order " + std::to_string(o.order),
                     transportPeakBytes(mesh, o));
  const detail::RaySetup setup = detail::makeRaySetup(mesh, o, false);
  std::vector<uint32_t> range(count);
  for (size_t i = 0; i < count; ++i) range[i] = uint32_t(first + i);
  bake(rt, mesh, o, setup, range, nullptr, r);
  r.totalSeconds = secondsSince(tStart);
  return r;
}

TransportResult computeTransportAtPoints(Runtime& rt, const Mesh& mesh, const SurfacePoints& pts,
                                         const TransportOptions& options) {
  const auto tStart = Clock::now();
  const TransportOptions o = checkedFor(rt, options);
  validateMesh(mesh, mesh.sourcePath.empty() ? "mesh" : mesh.sourcePath);
  if (pts.positions.size() % 3 || pts.normals.size() != pts.positions.size() ||
      pts.faceNormals.size() != pts.positions.size())
    throw UsageError("surface points", "positions, normals and face normals must hold 3 floats per point each");
  if (o.firstVertex != 0 || o.vertexCount)
    throw UsageError("vertex range", "the transport at surface points computes every point");
  for (float x : pts.positions)
    if (!std::isfinite(x)) throw UsageError("surface points", "a position is not finite");
  TransportResult r;
  r.order = o.order;
  r.samples = o.samples;
  r.device = rt.deviceLabel();
  r.vertexCount = pts.count();
  r.channels = detail::transportIsRgb(mesh, o) ? 3 : 1;
  if (r.vertexCount == 0) {
    r.totalSeconds = secondsSince(tStart);
    return r;
  }
  std::vector<float> source;  // interreflected: the mesh's transport with one bounce fewer
  if (o.mode == TransportMode::Interreflected) {
    TransportOptions vo = o;
    if (o.bounces == 1)
      vo.mode = TransportMode::Shadowed;
    else
      vo.bounces = o.bounces - 1;
    const TransportResult vr = computeTransport(rt, mesh, vo);
    const int nc = o.order * o.order;
    source.resize(vr.vertexCount * size_t(r.channels) * nc);
    for (size_t v = 0; v < vr.vertexCount; ++v)
      for (int c = 0; c < r.channels; ++c)  // a grey source serves every channel
        std::copy_n(vr.vertex(v) + (vr.channels == 1 ? 0 : c * nc), nc, &source[(v * r.channels + c) * nc]);
    r.rays += vr.rays;
    r.totalSamples += vr.totalSamples;
    r.bouncesUsed = vr.bouncesUsed + 1;
    r.bounceMaxNorm = vr.bounceMaxNorm;
  }
  const detail::RaySetup setup = detail::makePointRaySetup(mesh, pts, o);
  std::vector<uint32_t> range(pts.count());
  for (size_t i = 0; i < range.size(); ++i) range[i] = uint32_t(i);
  bake(rt, mesh, o, setup, range, o.mode == TransportMode::Interreflected ? &source : nullptr, r);
  r.totalSeconds = secondsSince(tStart);
  return r;
}

std::vector<uint8_t> traceVisibility(Runtime& rt, const Mesh& mesh, const TransportOptions& options) {
  const TransportOptions o = checkedFor(rt, options);
  validateMesh(mesh, mesh.sourcePath.empty() ? "mesh" : mesh.sourcePath);
  const detail::RaySetup setup = detail::makeRaySetup(mesh, o);
  const Bvh bvh = buildBvh(mesh);
  const bool packet = o.packetWidth > 0;
  cl::Buffer nodes = detail::uploadBvhNodes(rt, bvh, packet), tris = detail::uploadBvhTriangles(rt, bvh, packet);
  const int nv = int(mesh.vertexCount());
  int padded = 0;
  const std::vector<float> dirs = packet ? detail::packetDirections(setup.dirs, padded) : setup.dirs;
  cl::Kernel k = rt.kernel("transport.cl", packet ? "transport_visibility_packet" : "transport_visibility",
                           detail::transportOptions(o.order, true, 1, o.packetWidth));
  cl::Buffer out(rt.context(), CL_MEM_WRITE_ONLY, std::max<size_t>(size_t(nv) * o.samples, 16));
  // Held until the kernel has run: a kernel argument does not keep its buffer alive.
  const cl::Buffer origins = rt.upload(setup.origins), frames = rt.upload(setup.frames), dirsBuf = rt.upload(dirs);
  k.setArg(0, nv);
  k.setArg(1, o.samples);
  k.setArg(2, origins);
  k.setArg(3, frames);
  k.setArg(4, dirsBuf);
  k.setArg(5, nodes);
  k.setArg(6, tris);
  k.setArg(7, setup.tMax);
  k.setArg(8, out);
  if (packet) k.setArg(9, padded);
  rt.enqueueLoop(k, size_t(nv));
  std::vector<uint8_t> vis(size_t(nv) * o.samples);
  rt.queue().enqueueReadBuffer(out, CL_TRUE, 0, vis.size(), vis.data());
  return vis;
}

}  // namespace prtbake
