// Glossy transfer matrices on the OpenCL device: direction sets, vertex blocks, the
// Gram and bounce kernels (kernels/glossy.cl), and the assembly of each block's matrices.
#include "prtbake/glossy.h"

#include <algorithm>
#include <bitset>
#include <chrono>
#include <cmath>

#include "core/constants.h"
#include "core/gauss_legendre.h"
#include "glossy/glossy_detail.h"
#include "core/kernel_options.h"
#include "prtbake/bvh.h"
#include "prtbake/error.h"
#include "prtbake/limits.h"
#include "prtbake/sh.h"
#include "transport/transport_setup.h"

namespace prtbake {
namespace {
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Work-items per group (one vertex each; the kernels loop, so PoCL runs them scalar
// over work-items and 16 lanes wide inside each).
constexpr size_t kLocalSize = 16;
// Directions per launch: no kernel sums more than this many in float.
constexpr int kSampleChunk = 1024;
// Host memory of one block's double sums, at most (the block size shrinks to fit).
constexpr double kBlockBytes = 64.0 * 1024 * 1024;

size_t roundUp(size_t n, size_t m) { return (n + m - 1) / m * m; }

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
  if (o.albedoOverride)
    for (float a : *o.albedoOverride)
      if (!(a >= 0 && a <= 1)) throw UsageError("--albedo", "albedo must lie in [0, 1]");
}

namespace detail {

std::string glossyOptions(int orderOut, int orderIn, bool visibility) {
  return "-DSH_ORDER=" + std::to_string(std::max(orderOut, orderIn)) + " -DOUT_ORDER=" + std::to_string(orderOut) +
         " -DIN_ORDER=" + std::to_string(orderIn) + " -DVISIBILITY=" + (visibility ? "1" : "0");
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

GlossyStats bakeGlossyTransfer(Runtime& rt, const Mesh& mesh, const GlossyOptions& o, const GlossyBlockSink& sink) {
  const auto tStart = Clock::now();
  checkGlossyOptions(o);
  validateMesh(mesh, mesh.sourcePath.empty() ? "mesh" : mesh.sourcePath);
  const size_t nvAll = mesh.vertexCount();
  if (o.firstVertex > nvAll)
    throw UsageError("vertex range", "first vertex " + std::to_string(o.firstVertex) + " is beyond the mesh's " +
                                         std::to_string(nvAll) + " vertices");
  const size_t count = o.vertexCount ? *o.vertexCount : nvAll - o.firstVertex;
  if (count > nvAll - o.firstVertex)
    throw UsageError("vertex range", std::to_string(count) + " vertices from " + std::to_string(o.firstVertex) +
                                         " run past the mesh's " + std::to_string(nvAll) + " vertices");
  GlossyStats st;
  st.orderOut = o.orderOut;
  st.orderIn = o.orderIn;
  st.channels = detail::glossyChannels(mesh, o);
  st.vertexCount = count;
  st.firstVertex = o.firstVertex;
  st.samples = o.mode == TransportMode::Unshadowed ? 0 : o.samples;
  st.device = rt.deviceLabel();
  if (count == 0) {
    st.totalSeconds = since(tStart);
    return st;
  }
  const int no2 = o.orderOut * o.orderOut, ni2 = o.orderIn * o.orderIn, nmax = std::max(o.orderOut, o.orderIn);
  const int nmax2 = nmax * nmax, gramCount = nmax2 * (nmax2 + 1) / 2, ch = st.channels;
  const bool visibility = o.mode != TransportMode::Unshadowed;
  const bool bounce = o.mode == TransportMode::Interreflected;
  const TransportOptions to = detail::glossyTransportOptions(o);

  // Interreflection: the diffuse transport of the whole mesh at order n_in, summed over
  // bounces 0..B−1 (the existing bounce loop with its early stop).
  std::vector<float> diffuse;
  int diffuseChannels = 1;
  if (bounce) {
    const auto t0 = Clock::now();
    TransportOptions d = to;
    d.order = o.orderIn;
    d.mode = o.bounces > 1 ? TransportMode::Interreflected : TransportMode::Shadowed;
    d.bounces = std::max(1, o.bounces - 1);
    const TransportResult tr = computeTransport(rt, mesh, d);
    diffuse = tr.coeffs;
    diffuseChannels = tr.channels;
    st.bouncesUsed = (o.bounces > 1 ? tr.bouncesUsed : 0) + 1;
    st.rays += tr.rays;
    st.diffuseSeconds = since(t0);
  }

  const detail::RaySetup setup = detail::makeRaySetup(mesh, to, false);
  for (size_t v = o.firstVertex; v < o.firstVertex + count; ++v) {
    const float* n = &setup.frames[12 * v + 8];
    st.verticesWithoutNormal += (n[0] == 0 && n[1] == 0 && n[2] == 0) ? 1 : 0;
  }
  cl::Buffer nodes, tris;
  std::vector<uint8_t> unocc(nvAll, 0);
  if (visibility) {
    const Bvh bvh = buildBvh(mesh);
    st.bvhNodes = bvh.nodes.size();
    st.degenerateTriangles = bvh.degenerateTriangles;
    unocc = detail::unoccludableFromBvh(mesh, bvh, setup);
    nodes = detail::uploadBvhNodes(rt, bvh, true);
    tris = detail::uploadBvhTriangles(rt, bvh, true);
  } else {
    nodes = rt.upload(std::vector<float>(8, 0.0f));
    tris = rt.upload(std::vector<float>(12, 0.0f));
  }
  for (size_t v = o.firstVertex; v < o.firstVertex + count; ++v) st.verticesUnoccludable += unocc[v];

  // The direction chunks (uploaded once, reused by every block).
  std::vector<DirectionChunk> chunks;
  double scale = 1.0;
  if (!visibility) {
    DirectionChunk c;
    const std::vector<float> d = detail::productRuleDirections(nmax);
    c.count = int(d.size() / 4);
    c.soa = rt.upload(soa4(d, c.padded));
    chunks.push_back(c);
  } else {
    for (int first = 0; first < o.samples; first += kSampleChunk) {
      DirectionChunk c;
      c.count = std::min(kSampleChunk, o.samples - first);
      c.soa = rt.upload(soa4(glossyDirectionChunk(o.samples, first, c.count, o.seed), c.padded));
      chunks.push_back(c);
    }
    scale = 2 * kPi / o.samples;
  }

  const std::string opts = detail::glossyOptions(o.orderOut, o.orderIn, visibility);
  cl::Kernel gramK = rt.kernel("glossy.cl", "glossy_gram", opts);
  const cl::Buffer noMask = rt.upload(std::vector<uint16_t>(8, 0));  // bound when no mask is kept
  cl::Kernel bounceK;
  cl::Buffer indicesBuf, albedoBuf, diffuseBuf;
  if (bounce) {
    bounceK = rt.kernel("glossy.cl", "glossy_bounce", opts);
    std::vector<int32_t> idx(mesh.triangleCount() * 4, 0);
    for (size_t t = 0; t < mesh.triangleCount(); ++t)
      for (int c = 0; c < 3; ++c) idx[4 * t + c] = int32_t(mesh.indices[3 * t + c]);
    indicesBuf = rt.upload(idx);
    albedoBuf = rt.upload(detail::vertexAlbedo(mesh, to));
    diffuseBuf = rt.upload(diffuse);
  }

  const size_t perVertex = st.valuesPerVertex();
  const double perVertexBytes = 8.0 * (gramCount + (bounce ? double(ch) * no2 * ni2 : 0.0)) + 4.0 * double(perVertex);
  const size_t block = std::max<size_t>(16, std::min(o.blockVertices, size_t(kBlockBytes / perVertexBytes)));
  std::vector<double> gram, bounceSums;
  std::vector<float> part, values;
  double errSum = 0;
  const auto tKernel = Clock::now();
  for (size_t b0 = 0; b0 < count; b0 += block) {
    const size_t nb = std::min(block, count - b0), first = o.firstVertex + b0;
    std::vector<float> origins(nb * 4), frames(nb * 12);
    for (size_t i = 0; i < nb; ++i) {
      std::copy_n(&setup.origins[4 * (first + i)], 4, &origins[4 * i]);
      std::copy_n(&setup.frames[12 * (first + i)], 12, &frames[12 * i]);
      origins[4 * i + 3] = unocc[first + i] ? 1.0f : 0.0f;
    }
    const cl::Buffer originsBuf = rt.upload(origins), framesBuf = rt.upload(frames);
    size_t traced = 0;
    for (size_t i = 0; i < nb; ++i) traced += unocc[first + i] ? 0 : 1;
    const cl::NDRange global(roundUp(nb, kLocalSize)), local(kLocalSize);

    gram.assign(nb * gramCount, 0.0);
    cl::Buffer gramOut(rt.context(), CL_MEM_WRITE_ONLY, nb * gramCount * 4);
    part.resize(nb * gramCount);
    // With a bounce to follow, the direct kernel keeps a bit per ray: blocked or not. The
    // bounce traces the same rays, and only a blocked one can hit a surface.
    const bool keepMask = bounce && visibility;
    std::vector<cl::Buffer> masks;
    uint64_t blockedRays = 0;
    std::vector<uint64_t> hitStart(keepMask ? nb * chunks.size() : 0);  // blocked rays per (vertex, chunk), then their offsets
    for (const DirectionChunk& c : chunks) {
      const int maskWords = keepMask ? c.padded / 16 : 0;
      masks.push_back(keepMask ? cl::Buffer(rt.context(), CL_MEM_READ_WRITE, nb * size_t(maskWords) * 2) : noMask);
      int a = 0;
      gramK.setArg(a++, int(nb));
      gramK.setArg(a++, c.count);
      gramK.setArg(a++, originsBuf);
      gramK.setArg(a++, framesBuf);
      gramK.setArg(a++, c.soa);
      gramK.setArg(a++, nodes);
      gramK.setArg(a++, tris);
      gramK.setArg(a++, setup.tMax);
      gramK.setArg(a++, gramOut);
      gramK.setArg(a++, c.padded);
      gramK.setArg(a++, masks.back());
      gramK.setArg(a++, maskWords);
      rt.queue().enqueueNDRangeKernel(gramK, cl::NullRange, global, local);
      rt.queue().enqueueReadBuffer(gramOut, CL_TRUE, 0, part.size() * 4, part.data());
      if (keepMask) {
        std::vector<uint16_t> bits(nb * size_t(maskWords));
        rt.queue().enqueueReadBuffer(masks.back(), CL_TRUE, 0, bits.size() * 2, bits.data());
        for (size_t i = 0; i < nb; ++i)
          for (int w = 0; w < maskWords; ++w)
            hitStart[i * chunks.size() + masks.size() - 1] += std::bitset<16>(bits[i * maskWords + w]).count();
      }
      for (size_t i = 0; i < part.size(); ++i) gram[i] += part[i];
      if (visibility) st.rays += uint64_t(traced) * uint64_t(c.count);
    }
    // The other colour channels trace the same rays: the first keeps their hits (12 bytes
    // a blocked ray, at most detail::kKeptHitBytes) and the others read them.
    for (uint64_t& h : hitStart) {
      const uint64_t n = h;
      h = blockedRays;
      blockedRays += n;
    }
    const bool keepHits = keepMask && ch > 1 && blockedRays > 0 && double(blockedRays) * 12 <= detail::kKeptHitBytes;
    const cl::Buffer hits = keepHits ? cl::Buffer(rt.context(), CL_MEM_READ_WRITE, blockedRays * 12) : noMask;
    const cl::Buffer hitStartBuf =  // offsets below 44 million when the hits are kept: int
        keepHits ? rt.upload(std::vector<int32_t>(hitStart.begin(), hitStart.end())) : noMask;
    if (bounce) {
      const size_t nbc = size_t(no2) * ni2;
      bounceSums.assign(nb * ch * nbc, 0.0);
      cl::Buffer bounceOut(rt.context(), CL_MEM_WRITE_ONLY, nb * nbc * 4);
      part.resize(nb * nbc);
      for (int c = 0; c < ch; ++c)
        for (size_t ci = 0; ci < chunks.size(); ++ci) {
          const DirectionChunk& dc = chunks[ci];
          int a = 0;
          bounceK.setArg(a++, int(nb));
          bounceK.setArg(a++, dc.count);
          bounceK.setArg(a++, originsBuf);
          bounceK.setArg(a++, framesBuf);
          bounceK.setArg(a++, dc.soa);
          bounceK.setArg(a++, nodes);
          bounceK.setArg(a++, tris);
          bounceK.setArg(a++, setup.tMax);
          bounceK.setArg(a++, indicesBuf);
          bounceK.setArg(a++, albedoBuf);
          bounceK.setArg(a++, diffuseBuf);
          bounceK.setArg(a++, diffuseChannels);
          bounceK.setArg(a++, c);
          bounceK.setArg(a++, bounceOut);
          bounceK.setArg(a++, dc.padded);
          bounceK.setArg(a++, masks[ci]);
          bounceK.setArg(a++, keepMask ? dc.padded / 16 : 0);
          bounceK.setArg(a++, hits);
          bounceK.setArg(a++, hitStartBuf);
          bounceK.setArg(a++, int(chunks.size()));
          bounceK.setArg(a++, int(ci));
          bounceK.setArg(a++, keepHits ? (c == 0 ? 1 : 2) : 0);
          rt.queue().enqueueNDRangeKernel(bounceK, cl::NullRange, global, local);
          rt.queue().enqueueReadBuffer(bounceOut, CL_TRUE, 0, part.size() * 4, part.data());
          for (size_t i = 0; i < nb; ++i)
            for (size_t k = 0; k < nbc; ++k) bounceSums[(i * ch + c) * nbc + k] += part[i * nbc + k];
        }
      st.rays += uint64_t(keepHits ? 1 : ch) * blockedRays;  // the bounce traces the blocked rays only
    }
    values.resize(nb * perVertex);
    for (size_t i = 0; i < nb; ++i) {
      for (int c = 0; c < ch; ++c)
        detail::assembleMatrix(&gram[i * gramCount], nmax2,
                               bounce ? &bounceSums[(i * ch + c) * size_t(no2) * ni2] : nullptr, no2, ni2, scale,
                               &values[i * perVertex + size_t(c) * no2 * ni2]);
      if (visibility) {
        // Standard error of the direct term (glossy.h): v = 2 M_00.
        double norm2 = 0;
        for (int k = 0; k < no2 * ni2; ++k) norm2 += double(values[i * perVertex + k]) * values[i * perVertex + k];
        const double vis = 2 * gram[i * gramCount] * scale;
        const double se = std::sqrt(std::max(0.0, vis * no2 * ni2 / 4.0 - norm2) / o.samples);
        st.maxStdError = std::max(st.maxStdError, se);
        errSum += se;
      }
    }
    sink(first, nb, values.data());
  }
  st.meanStdError = errSum / double(count);
  st.kernelSeconds = since(tKernel);
  st.totalSeconds = since(tStart);
  return st;
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
