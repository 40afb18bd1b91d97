// Glossy transfer matrices on the OpenCL device: direction sets, vertex blocks, the
// Gram and bounce kernels (kernels/glossy.cl), and the assembly of each block's matrices.
#include "prtbake/glossy.h"
#include "prtbake/progress.h"

#include <algorithm>
#include <bitset>
#include <chrono>
#include <cmath>

#include "core/constants.h"
#include "core/gauss_legendre.h"
#include "glossy/glossy_detail.h"
#include "core/kernel_options.h"
#include "prtbake/bvh.h"
#include "prtbake/clock.h"
#include "prtbake/error.h"
#include "prtbake/limits.h"
#include "prtbake/sh.h"
#include "transport/transport_setup.h"

namespace prtbake {
namespace {
using Clock = std::chrono::steady_clock;

// Directions per launch: no kernel sums more than this many in float.
constexpr int kSampleChunk = 1024;  // at most 1024: the lane form's mask (Runtime::laneMaskMemory)
// Host memory of one block's double sums, at most (the block size shrinks to fit).
constexpr double kBlockBytes = 64.0 * 1024 * 1024;

// x, y, z, w rows of paddedCount floats (padding: zero weight).
std::vector<float> soa4(const std::vector<float>& dirs, int& padded) {
  const int n = int(dirs.size() / 4);
  padded = (n + 15) / 16 * 16;
  std::vector<float> out(size_t(4) * padded, 0.0f);
  for (int i = 0; i < n; ++i)
    for (int c = 0; c < 4; ++c) out[size_t(c) * padded + i] = dirs[4 * size_t(i) + c];
  return out;
}

// One launch's directions: (SoA buffer, count, padded count, scale of the sums).
struct DirectionChunk {
  cl::Buffer soa;
  int count = 0, padded = 0;
};

}  // namespace

const char* matrixDtypeName(MatrixDtype d) { return d == MatrixDtype::Float16 ? "float16" : "float32"; }

MatrixDtype parseMatrixDtype(const std::string& name) {
  if (name == "float32") return MatrixDtype::Float32;
  if (name == "float16") return MatrixDtype::Float16;
  throw UsageError("--dtype", "unknown dtype '" + name + "' (expected float32|float16)");
}

int glossyChannels(const Mesh& mesh, const GlossyOptions& o) { return detail::glossyChannels(mesh, o); }

double glossyMatrixBytes(size_t vertices, int channels, int orderOut, int orderIn) {
  return double(vertices) * channels * double(orderOut * orderOut) * double(orderIn * orderIn) * 4.0;
}

void checkGlossyOptions(const GlossyOptions& o) {
  auto orderCheck = [](const char* name, int n) {
    if (n < kMinGlossyOrder || n > kMaxGlossyOrder)
      throw UsageError(name, std::to_string(n) + " is out of range [" + std::to_string(kMinGlossyOrder) + ", " +
                                 std::to_string(kMaxGlossyOrder) + "] (a transfer matrix of order " +
                                 std::to_string(n) + " has " + std::to_string(n * n) + " x " +
                                 std::to_string(n * n) + " = " + std::to_string(n * n * n * n) +
                                 " values per vertex)");
  };
  orderCheck("--order-out", o.orderOut);
  orderCheck("--order-in", o.orderIn);
  if (o.samples < 1 || o.samples > (1 << 24))
    throw UsageError("--samples", std::to_string(o.samples) + " is out of range [1, 16777216]");
  if (o.mode == TransportMode::Interreflected && (o.bounces < 1 || o.bounces > 64))
    throw UsageError("--bounces", std::to_string(o.bounces) + " is out of range [1, 64]");
  if (!(o.bounceTolerance >= 0) || !std::isfinite(o.bounceTolerance))
    throw UsageError("--bounce-tolerance", "must be a finite number >= 0");
  if (o.blockVertices < 1) throw UsageError("block size", "must be at least 1 vertex");
  detail::checkRayLanes(o.rayLanes);
  if (o.albedoOverride)
    for (float a : *o.albedoOverride)
      if (!(a >= 0 && a <= 1)) throw UsageError("--albedo", "albedo must lie in [0, 1]");
}

namespace detail {

std::string glossyOptions(int orderOut, int orderIn, bool visibility, int rayLanes) {
  return "-DSH_ORDER=" + std::to_string(std::max(orderOut, orderIn)) + " -DOUT_ORDER=" + std::to_string(orderOut) +
         " -DIN_ORDER=" + std::to_string(orderIn) + " -DVISIBILITY=" + (visibility ? "1" : "0") +
         rayLanesOption(rayLanes);
}

TransportOptions glossyTransportOptions(const GlossyOptions& o) {
  TransportOptions t;
  t.mode = o.mode;
  t.order = std::max(o.orderIn, o.orderOut);
  t.samples = o.samples;
  t.seed = o.seed;
  t.bounces = o.bounces;
  t.bounceTolerance = o.bounceTolerance;
  t.albedoOverride = o.albedoOverride;
  return t;
}

int glossyChannels(const Mesh& mesh, const GlossyOptions& o) {
  if (o.mode != TransportMode::Interreflected) return 1;
  TransportOptions t = glossyTransportOptions(o);
  t.mode = TransportMode::Interreflected;
  return transportIsRgb(mesh, t) ? 3 : 1;
}

std::vector<float> productRuleDirections(int order) {
  // Exact for Y_i Y_j (degree ≤ 2(order−1) in x, y, z) over z ∈ [0, 1]: after the
  // azimuthal sum (exact for trigonometric polynomials of degree < 2·order) only terms
  // x^a y^b z^c with a, b even survive, (1 − z²)^((a+b)/2) z^c: a polynomial in z of
  // degree ≤ 2(order−1) ≤ 2·order − 1, which the order-point Gauss–Legendre rule integrates.
  const GaussRule g = gaussLegendre(order);
  const int nphi = 2 * order;
  std::vector<float> dirs;
  for (size_t k = 0; k < g.x.size(); ++k)
    for (int m = 0; m < nphi; ++m) {
      const double z = g.x[k], r = std::sqrt(std::max(0.0, 1 - z * z)), phi = 2 * kPi * (m + 0.5) / nphi;
      dirs.insert(dirs.end(), {float(r * std::cos(phi)), float(r * std::sin(phi)), float(z),
                               float(g.w[k] * 2 * kPi / nphi)});
    }
  return dirs;
}

void assembleMatrix(const double* gram, int nmax2, const double* bounce, int no2, int ni2, double scale, float* out) {
  for (int i = 0; i < no2; ++i)
    for (int j = 0; j < ni2; ++j) {
      const int a = std::max(i, j), b = std::min(i, j);
      double v = gram[size_t(a) * (a + 1) / 2 + b] * scale;
      if (bounce) v += bounce[size_t(i) * ni2 + j] * scale;
      out[size_t(i) * ni2 + j] = float(v);
    }
  (void)nmax2;
}

}  // namespace detail

std::vector<float> glossyDirectionChunk(int samples, int first, int count, uint64_t seed) {
  // The cosine-distributed Hammersley chunk of transport.h, warped to the uniform
  // hemisphere: cosine samples have z_c = √(1 − u1), uniform ones z_u = 1 − u1 = z_c²,
  // and r_u/r_c = √(1 − z_c⁴)/√(1 − z_c²) = √(1 + z_c²) at the same azimuth. Same points
  // of the unit square, same Morton order within the chunk.
  std::vector<float> d = detail::directionChunk(samples, first, count, seed, TransportSampler::Hammersley);
  for (size_t i = 0; i < d.size() / 4; ++i) {
    const double x = d[4 * i], y = d[4 * i + 1], z = d[4 * i + 2];
    const double s = std::sqrt(1 + z * z);
    d[4 * i] = float(x * s);
    d[4 * i + 1] = float(y * s);
    d[4 * i + 2] = float(z * z);
    d[4 * i + 3] = 1.0f;
  }
  return d;
}

namespace {

// The glossy bake of one range of vertices, block by block: its set-up (the diffuse bounces
// for interreflection, the scene, the direction chunks, the kernels) and, per block, the Gram
// sums of the direct term, the bounce sums and the matrices (glossy.h).
class GlossyBaker {
 public:
  // `points`: surface points instead of the mesh's vertices (bakeGlossyTransferAtPoints).
  GlossyBaker(Runtime& rt, const Mesh& mesh, const GlossyOptions& o, GlossyStats& st, const SurfacePoints* points)
      : rt_(rt), mesh_(mesh), o_(o), st_(st), to_(detail::glossyTransportOptions(o)),
        setup_(points ? detail::makePointRaySetup(mesh, *points, to_) : detail::makeRaySetup(mesh, to_, false)) {
    no2_ = o.orderOut * o.orderOut, ni2_ = o.orderIn * o.orderIn;
    const int nmax = std::max(o.orderOut, o.orderIn);
    nmax2_ = nmax * nmax, gramCount_ = nmax2_ * (nmax2_ + 1) / 2, ch_ = st.channels;
    visibility_ = o.mode != TransportMode::Unshadowed;
    bounce_ = o.mode == TransportMode::Interreflected;
    lanes_ = size_t(detail::rayLanesFor(rt.info(), 0, o.rayLanes));
    if (bounce_) diffuseBounces();
    for (size_t v = o.firstVertex; v < o.firstVertex + st.vertexCount; ++v) {
      const float* n = &setup_.frames[12 * v + 8];
      st.verticesWithoutNormal += (n[0] == 0 && n[1] == 0 && n[2] == 0) ? 1 : 0;
    }
    uploadScene();
    for (size_t v = o.firstVertex; v < o.firstVertex + st.vertexCount; ++v) st.verticesUnoccludable += unocc_[v];
    directionChunks(nmax);
    const std::string opts = detail::glossyOptions(o.orderOut, o.orderIn, visibility_, int(lanes_));
    gramK_ = rt.kernel("glossy.cl", "glossy_gram", opts);
    noMask_ = rt.upload(std::vector<uint16_t>(8, 0));  // bound when no mask is kept
    if (bounce_) {
      bounceK_ = rt.kernel("glossy.cl", "glossy_bounce", opts);
      std::vector<int32_t> idx(mesh.triangleCount() * 4, 0);
      for (size_t t = 0; t < mesh.triangleCount(); ++t)
        for (int c = 0; c < 3; ++c) idx[4 * t + c] = int32_t(mesh.indices[3 * t + c]);
      indicesBuf_ = rt.upload(idx);
      albedoBuf_ = rt.upload(detail::vertexAlbedo(mesh, to_));
      diffuseBuf_ = rt.upload(diffuse_);
    }
  }

  // Vertices per block: the double sums of one block within kBlockBytes.
  size_t blockVertices() const {
    const double perVertexBytes =
        8.0 * (gramCount_ + (bounce_ ? double(ch_) * no2_ * ni2_ : 0.0)) + 4.0 * double(st_.valuesPerVertex());
    return std::max<size_t>(16, std::min(o_.blockVertices, size_t(kBlockBytes / perVertexBytes)));
  }

  // The matrices of vertices [first, first + nb), handed to the sink; their standard errors
  // summed into *errSum.
  void bakeBlock(size_t first, size_t nb, const GlossyBlockSink& sink, double* errSum) {
    std::vector<float> origins(nb * 4), frames(nb * 12);
    for (size_t i = 0; i < nb; ++i) {
      std::copy_n(&setup_.origins[4 * (first + i)], 4, &origins[4 * i]);
      std::copy_n(&setup_.frames[12 * (first + i)], 12, &frames[12 * i]);
      origins[4 * i + 3] = unocc_[first + i] ? 1.0f : 0.0f;
    }
    originsBuf_ = rt_.upload(origins), framesBuf_ = rt_.upload(frames);
    size_t traced = 0;
    for (size_t i = 0; i < nb; ++i) traced += unocc_[first + i] ? 0 : 1;
    traceGram(nb, traced);
    if (bounce_) traceBounce(nb);
    assemble(nb, errSum);
    sink(first, nb, values_.data());
    progress_ = double(first + nb) / double(std::max<size_t>(setup_.count(), 1));
    reportProgress("glossy", progress_);
  }

 private:
  // Interreflection: the diffuse transport of the whole mesh at order n_in, summed over
  // bounces 0..B−1 (the transport's bounce loop with its early stop).
  void diffuseBounces() {
    const auto t0 = Clock::now();
    TransportOptions d = to_;
    d.order = o_.orderIn;
    d.mode = o_.bounces > 1 ? TransportMode::Interreflected : TransportMode::Shadowed;
    d.bounces = std::max(1, o_.bounces - 1);
    const TransportResult tr = computeTransport(rt_, mesh_, d);
    diffuse_ = tr.coeffs;
    diffuseChannels_ = tr.channels;
    st_.bouncesUsed = (o_.bounces > 1 ? tr.bouncesUsed : 0) + 1;
    st_.rays += tr.rays;
    st_.diffuseSeconds = secondsSince(t0);
  }

  // The BVH (with visibility) and the vertices (points) nothing can occlude.
  void uploadScene() {
    unocc_.assign(setup_.count(), 0);
    if (!visibility_) {
      nodes_ = rt_.upload(std::vector<float>(8, 0.0f));
      tris_ = rt_.upload(std::vector<float>(12, 0.0f));
      return;
    }
    const Bvh bvh = buildBvh(mesh_);
    st_.bvhNodes = bvh.nodes.size();
    st_.degenerateTriangles = bvh.degenerateTriangles;
    unocc_ = detail::unoccludableFromBvh(mesh_, bvh, setup_);
    nodes_ = detail::uploadBvhNodes(rt_, bvh, lanes_ == 1);  // the lane form's rays take the binary BVH
    tris_ = detail::uploadBvhTriangles(rt_, bvh, lanes_ == 1);
  }

  // The direction chunks, uploaded once and reused by every block: the product rule of order
  // nmax without visibility, else the sample set in launches of kSampleChunk.
  void directionChunks(int nmax) {
    if (!visibility_) {
      DirectionChunk c;
      const std::vector<float> d = detail::productRuleDirections(nmax);
      c.count = int(d.size() / 4);
      c.soa = rt_.upload(soa4(d, c.padded));
      chunks_.push_back(c);
      return;
    }
    for (int first = 0; first < o_.samples; first += kSampleChunk) {
      DirectionChunk c;
      c.count = std::min(kSampleChunk, o_.samples - first);
      c.soa = rt_.upload(soa4(glossyDirectionChunk(o_.samples, first, c.count, o_.seed), c.padded));
      chunks_.push_back(c);
    }
    scale_ = 2 * kPi / o_.samples;
  }

  // The Gram sums of the block's direct term over every chunk. With a bounce to follow, the
  // kernel keeps a bit per ray (blocked or not): the bounce traces the same rays, and only a
  // blocked one can hit a surface; the other colour channels then read the first's hits (12
  // bytes a blocked ray, at most detail::kKeptHitBytes).
  void traceGram(size_t nb, size_t traced) {
    gram_.assign(nb * gramCount_, 0.0);
    cl::Buffer gramOut(rt_.context(), CL_MEM_WRITE_ONLY, nb * gramCount_ * 4);
    part_.resize(nb * gramCount_);
    keepMask_ = bounce_ && visibility_;
    masks_.clear();
    blockedRays_ = 0;
    std::vector<uint64_t> hitStart(keepMask_ ? nb * chunks_.size() : 0);  // blocked rays per (vertex, chunk), then offsets
    for (const DirectionChunk& c : chunks_) {
      const int maskWords = keepMask_ ? c.padded / 16 : 0;
      masks_.push_back(keepMask_ ? cl::Buffer(rt_.context(), CL_MEM_READ_WRITE, nb * size_t(maskWords) * 2) : noMask_);
      int a = 0;
      gramK_.setArg(a++, int(nb));
      gramK_.setArg(a++, c.count);
      gramK_.setArg(a++, originsBuf_);
      gramK_.setArg(a++, framesBuf_);
      gramK_.setArg(a++, c.soa);
      gramK_.setArg(a++, nodes_);
      gramK_.setArg(a++, tris_);
      gramK_.setArg(a++, setup_.tMax);
      gramK_.setArg(a++, gramOut);
      gramK_.setArg(a++, c.padded);
      gramK_.setArg(a++, masks_.back());
      gramK_.setArg(a++, maskWords);
      gramK_.setArg(a++, cl::Local(rt_.loopLocalSize(lanes_) * (1 + nmax2_) * sizeof(float)));
      gramK_.setArg(a++, rt_.laneMaskMemory(lanes_));
      rt_.enqueueLoop(gramK_, nb, 0, lanes_);
      rt_.queue().enqueueReadBuffer(gramOut, CL_TRUE, 0, part_.size() * 4, part_.data());
      reportProgress("glossy", progress_);
      if (keepMask_) {
        std::vector<uint16_t> bits(nb * size_t(maskWords));
        rt_.queue().enqueueReadBuffer(masks_.back(), CL_TRUE, 0, bits.size() * 2, bits.data());
        for (size_t i = 0; i < nb; ++i)
          for (int w = 0; w < maskWords; ++w)
            hitStart[i * chunks_.size() + masks_.size() - 1] += std::bitset<16>(bits[i * maskWords + w]).count();
      }
      for (size_t i = 0; i < part_.size(); ++i) gram_[i] += part_[i];
      if (visibility_) st_.rays += uint64_t(traced) * uint64_t(c.count);
    }
    for (uint64_t& h : hitStart) {
      const uint64_t n = h;
      h = blockedRays_;
      blockedRays_ += n;
    }
    keepHits_ = keepMask_ && ch_ > 1 && blockedRays_ > 0 && double(blockedRays_) * 12 <= detail::kKeptHitBytes;
    hits_ = keepHits_ ? cl::Buffer(rt_.context(), CL_MEM_READ_WRITE, blockedRays_ * 12) : noMask_;
    hitStart_ =  // offsets below 44 million when the hits are kept: int
        keepHits_ ? rt_.upload(std::vector<int32_t>(hitStart.begin(), hitStart.end())) : noMask_;
  }

  // The bounce sums of the block, per colour channel and chunk.
  void traceBounce(size_t nb) {
    const size_t nbc = size_t(no2_) * ni2_;
    bounceSums_.assign(nb * ch_ * nbc, 0.0);
    cl::Buffer bounceOut(rt_.context(), CL_MEM_WRITE_ONLY, nb * nbc * 4);
    part_.resize(nb * nbc);
    for (int c = 0; c < ch_; ++c)
      for (size_t ci = 0; ci < chunks_.size(); ++ci) {
        const DirectionChunk& dc = chunks_[ci];
        int a = 0;
        bounceK_.setArg(a++, int(nb));
        bounceK_.setArg(a++, dc.count);
        bounceK_.setArg(a++, originsBuf_);
        bounceK_.setArg(a++, framesBuf_);
        bounceK_.setArg(a++, dc.soa);
        bounceK_.setArg(a++, nodes_);
        bounceK_.setArg(a++, tris_);
        bounceK_.setArg(a++, setup_.tMax);
        bounceK_.setArg(a++, indicesBuf_);
        bounceK_.setArg(a++, albedoBuf_);
        bounceK_.setArg(a++, diffuseBuf_);
        bounceK_.setArg(a++, diffuseChannels_);
        bounceK_.setArg(a++, c);
        bounceK_.setArg(a++, bounceOut);
        bounceK_.setArg(a++, dc.padded);
        bounceK_.setArg(a++, masks_[ci]);
        bounceK_.setArg(a++, keepMask_ ? dc.padded / 16 : 0);
        bounceK_.setArg(a++, hits_);
        bounceK_.setArg(a++, hitStart_);
        bounceK_.setArg(a++, int(chunks_.size()));
        bounceK_.setArg(a++, int(ci));
        bounceK_.setArg(a++, keepHits_ ? (c == 0 ? 1 : 2) : 0);
        bounceK_.setArg(a++, cl::Local(rt_.loopLocalSize(lanes_) * (1 + no2_ + ni2_) * sizeof(float)));
        rt_.enqueueLoop(bounceK_, nb, 0, lanes_);
        rt_.queue().enqueueReadBuffer(bounceOut, CL_TRUE, 0, part_.size() * 4, part_.data());
        reportProgress("glossy", progress_);
        for (size_t i = 0; i < nb; ++i)
          for (size_t k = 0; k < nbc; ++k) bounceSums_[(i * ch_ + c) * nbc + k] += part_[i * nbc + k];
      }
    st_.rays += uint64_t(keepHits_ ? 1 : ch_) * blockedRays_;  // the bounce traces the blocked rays only
  }

  // The block's matrices from its sums, and the standard error of each direct term.
  void assemble(size_t nb, double* errSum) {
    const size_t perVertex = st_.valuesPerVertex();
    values_.resize(nb * perVertex);
    for (size_t i = 0; i < nb; ++i) {
      for (int c = 0; c < ch_; ++c)
        detail::assembleMatrix(&gram_[i * gramCount_], nmax2_,
                               bounce_ ? &bounceSums_[(i * ch_ + c) * size_t(no2_) * ni2_] : nullptr, no2_, ni2_,
                               scale_, &values_[i * perVertex + size_t(c) * no2_ * ni2_]);
      if (visibility_) {
        // Standard error of the direct term (glossy.h): v = 2 M_00.
        double norm2 = 0;
        for (int k = 0; k < no2_ * ni2_; ++k) norm2 += double(values_[i * perVertex + k]) * values_[i * perVertex + k];
        const double vis = 2 * gram_[i * gramCount_] * scale_;
        const double se = std::sqrt(std::max(0.0, vis * no2_ * ni2_ / 4.0 - norm2) / o_.samples);
        st_.maxStdError = std::max(st_.maxStdError, se);
        *errSum += se;
      }
    }
  }

  Runtime& rt_;
  const Mesh& mesh_;
  const GlossyOptions& o_;
  GlossyStats& st_;
  double progress_ = 0;  // the fraction of the mesh's vertices baked, for reportProgress
  const TransportOptions to_;
  const detail::RaySetup setup_;
  int no2_ = 0, ni2_ = 0, nmax2_ = 0, gramCount_ = 0, ch_ = 1;
  bool visibility_ = false, bounce_ = false;
  size_t lanes_ = 1;  // work-items per vertex (1: the packet kernels)
  std::vector<float> diffuse_;
  int diffuseChannels_ = 1;
  std::vector<uint8_t> unocc_;
  cl::Buffer nodes_, tris_, noMask_, indicesBuf_, albedoBuf_, diffuseBuf_;
  std::vector<DirectionChunk> chunks_;
  double scale_ = 1.0;
  cl::Kernel gramK_, bounceK_;
  // The current block's buffers and sums.
  cl::Buffer originsBuf_, framesBuf_, hits_, hitStart_;
  std::vector<cl::Buffer> masks_;
  bool keepMask_ = false, keepHits_ = false;
  uint64_t blockedRays_ = 0;
  std::vector<double> gram_, bounceSums_;
  std::vector<float> part_, values_;
};

}  // namespace

namespace {

GlossyStats bake(Runtime& rt, const Mesh& mesh, const GlossyOptions& o, const GlossyBlockSink& sink,
                 const SurfacePoints* points) {
  const auto tStart = Clock::now();
  checkGlossyOptions(o);
  validateMesh(mesh, mesh.sourcePath.empty() ? "mesh" : mesh.sourcePath);
  if (points && (o.firstVertex != 0 || o.vertexCount))
    throw UsageError("--vertex-range", "does not apply to surface points");
  const size_t count = points ? points->count() : detail::vertexRangeSize(mesh, o.firstVertex, o.vertexCount);
  GlossyStats st;
  st.orderOut = o.orderOut;
  st.orderIn = o.orderIn;
  st.channels = detail::glossyChannels(mesh, o);
  st.vertexCount = count;
  st.firstVertex = o.firstVertex;
  st.samples = o.mode == TransportMode::Unshadowed ? 0 : o.samples;
  st.device = rt.deviceLabel();
  if (count == 0) {
    st.totalSeconds = secondsSince(tStart);
    return st;
  }
  GlossyBaker baker(rt, mesh, o, st, points);
  const size_t block = baker.blockVertices();
  double errSum = 0;
  const auto tKernel = Clock::now();
  for (size_t b0 = 0; b0 < count; b0 += block)
    baker.bakeBlock(o.firstVertex + b0, std::min(block, count - b0), sink, &errSum);
  st.meanStdError = errSum / double(count);
  st.kernelSeconds = secondsSince(tKernel);
  st.totalSeconds = secondsSince(tStart);
  return st;
}

}  // namespace

GlossyStats bakeGlossyTransfer(Runtime& rt, const Mesh& mesh, const GlossyOptions& o, const GlossyBlockSink& sink) {
  return bake(rt, mesh, o, sink, nullptr);
}

GlossyStats bakeGlossyTransferAtPoints(Runtime& rt, const Mesh& mesh, const SurfacePoints& points,
                                       const GlossyOptions& o, const GlossyBlockSink& sink) {
  if (points.normals.size() != points.positions.size() || points.faceNormals.size() != points.positions.size())
    throw UsageError("points", "positions, normals and face normals differ in size");
  return bake(rt, mesh, o, sink, &points);
}

GlossyResult computeGlossyTransfer(Runtime& rt, const Mesh& mesh, const GlossyOptions& o) {
  checkGlossyOptions(o);
  const size_t nv = mesh.vertexCount();
  const size_t count = o.vertexCount ? *o.vertexCount : (o.firstVertex <= nv ? nv - o.firstVertex : 0);
  const int ch = detail::glossyChannels(mesh, o);
  const double bytes = glossyMatrixBytes(count, ch, o.orderOut, o.orderIn);
  if (bytes > double(inputMemoryLimit()))
    throw UsageError("--order", "transfer matrices of " + std::to_string(count) + " vertices at orders " +
                                    std::to_string(o.orderOut) + " x " + std::to_string(o.orderIn) + " need " +
                                    std::to_string(int64_t(bytes / (1024.0 * 1024.0))) +
                                    " MiB, more than the memory limit of " +
                                    std::to_string(inputMemoryLimit() / (1024 * 1024)) +
                                    " MiB (stream them to a file with prtbake transport --transfer matrix, "
                                    "or set PRTBAKE_INPUT_LIMIT_MB)");
  GlossyResult r;
  r.matrices.reserve(size_t(bytes / 4));
  const size_t perVertex = size_t(ch) * o.orderOut * o.orderOut * o.orderIn * o.orderIn;
  r.stats = bakeGlossyTransfer(rt, mesh, o, [&](size_t, size_t n, const float* values) {
    r.matrices.insert(r.matrices.end(), values, values + n * perVertex);
  });
  return r;
}

}  // namespace prtbake
