// Light probe grids on the device: layout, quadrature, the surfaces' exit radiance, the
// trace, relocation of probes inside geometry and the fill of invalid ones (see probes.h).
#include "prtbake/probes.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>

#include "core/constants.h"
#include "core/gauss_legendre.h"
#include "core/kernel_options.h"
#include "core/radical_inverse.h"
#include "core/tolerance_pilot.h"
#include "prtbake/bvh.h"
#include "prtbake/clock.h"
#include "prtbake/error.h"
#include "prtbake/progress.h"
#include "prtbake/transport.h"
#include "transport/transport_setup.h"

namespace prtbake {
namespace {
using Clock = std::chrono::steady_clock;

// Rays per launch: about 0.25 s on a 2-core CPU, so that progress and Ctrl-C stay prompt.
constexpr size_t kRaysPerLaunch = size_t(1) << 21;
// The pilot that tests relocation candidates: rings × segments of its quadrature.
constexpr int kPilotRings = 6, kPilotSegments = 12;
// The environment orders the kernel evaluates (the transport's too).
constexpr int kMaxEnvOrder = kMaxTransportOrder;

using detail::splitmix64;
using detail::unitFromBits;

// A uniformly random rotation per probe (Shoemake's quaternion from three uniforms), as the
// three float4 columns that sampling_to_world reads.
void probeFrame(uint64_t seed, size_t probe, float* out) {
  const uint64_t h = splitmix64(seed * 0xD1B54A32D192ED03ull + probe);
  const double u1 = unitFromBits(h), u2 = unitFromBits(splitmix64(h + 1)), u3 = unitFromBits(splitmix64(h + 2));
  const double a = std::sqrt(1 - u1), b = std::sqrt(u1);
  const double x = a * std::sin(2 * kPi * u2), y = a * std::cos(2 * kPi * u2);
  const double z = b * std::sin(2 * kPi * u3), w = b * std::cos(2 * kPi * u3);
  const double m[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
                          {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
                          {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)}};
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) out[4 * c + r] = float(m[r][c]);
    out[4 * c + 3] = 0;
  }
}

// The product rule: `rings` Gauss–Legendre nodes in z = cos θ times `segments` equally spaced
// φ (each ring turned by a golden-ratio fraction of a segment), weights summing to 4π; exact
// for spherical polynomials of degree ≤ min(2 rings − 1, segments − 1).
std::vector<float> quadrature(int rings, int segments) {
  const detail::GaussRule g = detail::gaussLegendre(rings);
  std::vector<float> dirs;
  dirs.reserve(size_t(rings) * segments * 4);
  for (int k = 0; k < rings; ++k) {
    const double z = 2 * g.x[k] - 1, r = std::sqrt(std::max(0.0, 1 - z * z));
    const double w = 2 * g.w[k] * 2 * kPi / segments, shift = std::fmod(k * 0.6180339887498949, 1.0);
    for (int j = 0; j < segments; ++j) {
      const double phi = 2 * kPi * (j + shift) / segments;
      dirs.insert(dirs.end(), {float(r * std::cos(phi)), float(r * std::sin(phi)), float(z), float(w)});
    }
  }
  return dirs;
}

void checkOptions(const ProbeOptions& o) {
  if (o.order != 2 && o.order != 3) throw UsageError("--order", "probes take order 2 (L1) or 3 (L2), got " + std::to_string(o.order));
  if (o.samples < 1 || o.samples > 65536) throw UsageError("--samples", "expected 1..65536 rays per probe");
  if (!(o.tolerance >= 0) || !std::isfinite(o.tolerance)) throw UsageError("--tolerance", "must be a finite number >= 0");
  if (o.tolerance > 0 && (o.toleranceMaxSamples < 64 || o.toleranceMaxSamples > 65536))
    throw UsageError("--max-samples", "expected 64..65536");
  if (o.bounces < 0 || o.bounces > 16) throw UsageError("--bounces", "expected 0..16");
  if (o.packetWidth != -1 && o.packetWidth != 0 && o.packetWidth != 16)
    throw UsageError("packet width", std::to_string(o.packetWidth) + " (expected 0 or 16, or -1: by the device)");
  detail::checkRayLanes(o.rayLanes);
  if (o.transportSamples < 1 || o.transportSamples > (1 << 20)) throw UsageError("--transport-samples", "expected 1..1048576");
  if (!(o.backfaceLimit > 0 && o.backfaceLimit <= 1)) throw UsageError("--backface-limit", "expected a fraction in (0, 1]");
  if (!(o.relocateFraction >= 0 && o.relocateFraction <= 1)) throw UsageError("--relocate", "expected a fraction in [0, 1]");
}

// The probes' device pass: the scene, the environment and the surfaces' radiance uploaded
// once, then any list of positions traced with a quadrature.
class ProbeTracer {
 public:
  ProbeTracer(Runtime& rt, const Mesh& mesh, const Bvh& bvh, const ShCoeffs& env, int order, int envOrder,
              const std::vector<float>& radiance, int packetWidth, int rayLanes)
      : rt_(rt), order_(order), packet_(packetWidth), lanes_(size_t(rayLanes)) {
    nodes_ = detail::uploadBvhNodes(rt, bvh, packet_ > 0);
    tris_ = detail::uploadBvhTriangles(rt, bvh, packet_ > 0);
    std::vector<float> envRgb(size_t(envOrder) * envOrder * 4, 0.0f);
    for (int j = 0; j < std::min(env.order, envOrder) * std::min(env.order, envOrder); ++j)
      for (int c = 0; c < 3; ++c) envRgb[4 * j + c] = float(env.rgb[j][c]);
    env_ = rt.upload(envRgb);
    std::vector<int32_t> idx(mesh.triangleCount() * 4, 0);
    std::vector<float> normals(mesh.triangleCount() * 4, 0.0f);
    const float* p = mesh.positions.data();
    for (size_t t = 0; t < mesh.triangleCount(); ++t) {
      const uint32_t* i = &mesh.indices[3 * t];
      float e1[3], e2[3];
      for (int a = 0; a < 3; ++a) {
        idx[4 * t + a] = int32_t(i[a]);
        e1[a] = p[3 * i[1] + a] - p[3 * i[0] + a];
        e2[a] = p[3 * i[2] + a] - p[3 * i[0] + a];
      }
      normals[4 * t] = e1[1] * e2[2] - e1[2] * e2[1];
      normals[4 * t + 1] = e1[2] * e2[0] - e1[0] * e2[2];
      normals[4 * t + 2] = e1[0] * e2[1] - e1[1] * e2[0];
    }
    indices_ = rt.upload(idx);
    faceNormals_ = rt.upload(normals);
    lit_ = !radiance.empty();
    radiance_ = rt.upload(lit_ ? radiance : std::vector<float>(4, 0.0f));
    kernel_ = rt.kernel("probes.cl", packet_ ? "probes_trace_packet" : "probes_trace",
                        detail::probesOptions(order, envOrder, packet_, int(lanes_)));
    // Rays start at the probe and reach past the scene from anywhere in the grid.
    tMax_ = 1e30f;
  }

  // Traces probes at `positions` (3 floats each) with frames of `frameIndex[i]` and the
  // quadrature `dirs`; writes order² × 3 coefficients per probe and the back faces' weight.
  // The packet kernel stops a probe whose back faces weigh more than backStop (its
  // coefficients are then partial: the caller does not use them).
  void trace(const std::vector<float>& positions, const std::vector<size_t>& frameIndex, uint64_t seed,
             const std::vector<float>& dirs, float backStop, std::vector<float>& coeffs, std::vector<float>& backface,
             const char* stage, uint64_t& rays) {
    const size_t n = positions.size() / 3, nc = size_t(order_) * order_ * 3;
    const int samples = int(dirs.size() / 4);
    coeffs.assign(n * nc, 0.0f);
    backface.assign(n, 0.0f);
    if (n == 0) return;
    // The packet kernel reads the directions as rows x, y, z, weight of paddedCount floats.
    const int padded = (samples + 15) / 16 * 16;
    std::vector<float> soa(size_t(4) * padded, 0.0f);
    for (int i = 0; i < samples; ++i)
      for (int c = 0; c < 4; ++c) soa[size_t(c) * padded + i] = dirs[4 * size_t(i) + c];
    cl::Buffer dirBuf = rt_.upload(packet_ ? soa : dirs);
    const size_t local = rt_.loopGroupSize();
    const size_t block = std::max<size_t>(local, kRaysPerLaunch / size_t(samples) / local * local);
    for (size_t first = 0; first < n; first += block) {
      const size_t count = std::min(block, n - first);
      std::vector<float> origins(count * 4, 0.0f), frames(count * 12);
      for (size_t i = 0; i < count; ++i) {
        std::memcpy(&origins[4 * i], &positions[3 * (first + i)], 3 * sizeof(float));
        probeFrame(seed, frameIndex[first + i], &frames[12 * i]);
      }
      cl::Buffer o = rt_.upload(origins), f = rt_.upload(frames);
      cl::Buffer outC(rt_.context(), CL_MEM_WRITE_ONLY, count * nc * sizeof(float));
      cl::Buffer outB(rt_.context(), CL_MEM_WRITE_ONLY, count * sizeof(float));
      int a = 0;
      kernel_.setArg(a++, int(count));
      kernel_.setArg(a++, samples);
      for (cl::Buffer* b : {&o, &f, &dirBuf, &nodes_, &tris_}) kernel_.setArg(a++, *b);
      kernel_.setArg(a++, tMax_);
      for (cl::Buffer* b : {&env_, &indices_, &faceNormals_, &radiance_}) kernel_.setArg(a++, *b);
      kernel_.setArg(a++, int(lit_));
      kernel_.setArg(a++, outC);
      kernel_.setArg(a++, outB);
      if (packet_) {
        kernel_.setArg(a++, padded);
        kernel_.setArg(a++, backStop);
      } else {
        kernel_.setArg(a++, rt_.laneSumMemory(lanes_));
      }
      rt_.enqueueLoop(kernel_, count, 0, lanes_);
      rt_.queue().enqueueReadBuffer(outC, CL_FALSE, 0, count * nc * sizeof(float), coeffs.data() + first * nc);
      rt_.queue().enqueueReadBuffer(outB, CL_TRUE, 0, count * sizeof(float), backface.data() + first);
      rays += uint64_t(count) * uint64_t(samples);
      reportProgress(stage, double(first + count) / double(n));
    }
  }

 private:
  Runtime& rt_;
  int order_, packet_;
  size_t lanes_;  // work-items per probe of the one-ray kernel
  bool lit_ = false;
  float tMax_ = 0;
  cl::Buffer nodes_, tris_, env_, indices_, faceNormals_, radiance_;
  cl::Kernel kernel_;
};

// The surfaces' exit radiance per vertex (V × 4): ρ(v) Σ_j l_j T_j(v), T the transport of
// bounces − 1 interreflections at the environment's order.
std::vector<float> surfaceRadiance(Runtime& rt, const Mesh& mesh, const ShCoeffs& env, int envOrder,
                                   const ProbeOptions& o) {
  TransportOptions t;
  t.mode = o.bounces == 1 ? TransportMode::Shadowed : TransportMode::Interreflected;
  t.bounces = std::max(1, o.bounces - 1);
  t.bounceTolerance = 0;
  t.order = envOrder;
  t.samples = o.transportSamples;
  t.seed = o.seed;
  t.albedoOverride = o.albedoOverride;
  const TransportResult r = computeTransport(rt, mesh, t);
  const int nc = envOrder * envOrder;
  std::vector<float> out(mesh.vertexCount() * 4, 0.0f);
  for (size_t v = 0; v < mesh.vertexCount(); ++v) {
    const float* T = r.vertex(v);
    for (int c = 0; c < 3; ++c) {
      const float* Tc = T + (r.channels == 3 ? c * nc : 0);
      double sum = 0;
      for (int j = 0; j < std::min(env.order, envOrder) * std::min(env.order, envOrder); ++j) sum += env.rgb[j][c] * Tc[j];
      const double rho = o.albedoOverride ? (*o.albedoOverride)[c] : mesh.albedo[3 * v + c];
      out[4 * v + c] = float(std::max(0.0, rho * sum));
    }
  }
  return out;
}

// Whether the scene's bounding box meets the grid's bounds (a grid placed away from the scene,
// where it would only see the environment, is a mistake).
bool sceneMeetsBounds(const Mesh& mesh, const ProbeGridLayout& g) {
  if (mesh.triangleCount() == 0) return false;
  double lo[3], hi[3];
  meshBounds(mesh, lo, hi);
  for (int a = 0; a < 3; ++a)
    if (hi[a] < g.boundsMin[a] || lo[a] > g.boundsMax[a]) return false;
  return true;
}

// Offsets on a lattice of step r/2 within radius r, nearest first (32 of them).
std::vector<std::array<double, 3>> relocationOffsets(double r) {
  std::vector<std::array<double, 3>> out;
  for (int k = -2; k <= 2; ++k)
    for (int j = -2; j <= 2; ++j)
      for (int i = -2; i <= 2; ++i) {
        const int n2 = i * i + j * j + k * k;
        if (n2 == 0 || n2 > 4) continue;
        out.push_back({i * r / 2, j * r / 2, k * r / 2});
      }
  std::stable_sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
    return a[0] * a[0] + a[1] * a[1] + a[2] * a[2] < b[0] * b[0] + b[1] * b[1] + b[2] * b[2];
  });
  return out;
}

// Invalid probes take the mean of their valid (or already filled) face neighbours, pass after
// pass, so that a block of invalid probes fills from its rim. Returns the passes taken.
int fillPasses(ProbeGridResult& g) {
  const auto& res = g.layout.resolution;
  const size_t nc = size_t(g.order) * g.order * 3;
  std::vector<uint8_t> known(g.state.size());
  for (size_t i = 0; i < known.size(); ++i) known[i] = g.state[i] != 2;
  int passes = 0;
  for (;;) {
    std::vector<size_t> filled;
    for (int z = 0; z < res[2]; ++z)
      for (int y = 0; y < res[1]; ++y)
        for (int x = 0; x < res[0]; ++x) {
          const size_t i = (size_t(z) * res[1] + y) * res[0] + x;
          if (known[i]) continue;
          std::vector<double> sum(nc, 0.0);
          int count = 0;
          const int nb[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
          for (const auto& d : nb) {
            const int X = x + d[0], Y = y + d[1], Z = z + d[2];
            if (X < 0 || Y < 0 || Z < 0 || X >= res[0] || Y >= res[1] || Z >= res[2]) continue;
            const size_t j = (size_t(Z) * res[1] + Y) * res[0] + X;
            if (!known[j]) continue;
            for (size_t k = 0; k < nc; ++k) sum[k] += g.coeffs[j * nc + k];
            ++count;
          }
          if (count == 0) continue;
          for (size_t k = 0; k < nc; ++k) g.coeffs[i * nc + k] = float(sum[k] / count);
          filled.push_back(i);
        }
    if (filled.empty()) return passes;
    for (size_t i : filled) known[i] = 1;
    ++passes;
  }
}

// "--tolerance": the pilot over at most 128 probes spread through the grid (prtbake/tolerance.h),
// their coefficients in units of the environment's l_0; probes inside geometry count as exact
// (their values are not used: they are relocated or filled).
template <typename Rule>
int toleranceSamples(ProbeTracer& tracer, const ProbeGridLayout& layout, const ProbeOptions& o, const ShCoeffs& env,
                     float stop, const Rule& rule, ProbeGridResult& g) {
  const auto t0 = Clock::now();
  const size_t total = layout.count();
  const std::vector<size_t> pilot = detail::pilotSubset(total, (total + kTolerancePilotVertices - 1) / kTolerancePilotVertices);
  std::vector<float> positions;
  for (size_t q : pilot) {
    const auto& r = layout.resolution;
    const auto p = layout.probePosition(int(q % r[0]), int(q / r[0] % r[1]), int(q / (size_t(r[0]) * r[1])));
    positions.insert(positions.end(), {float(p[0]), float(p[1]), float(p[2])});
  }
  const double scale = std::max(1e-30, (std::abs(env.rgb[0][0]) + std::abs(env.rgb[0][1]) + std::abs(env.rgb[0][2])) / 3);
  const size_t stride = size_t(o.order) * o.order * 3;
  auto evaluate = [&](const std::vector<int>& counts) {
    std::vector<std::vector<double>> out;
    for (int n : counts) {
      int rings = 0, segments = 0;
      std::vector<float> coeffs, back;
      tracer.trace(positions, pilot, o.seed, rule(n, &rings, &segments), stop, coeffs, back, "probes: tolerance pilot",
                   g.rays);
      std::vector<double> v(coeffs.size());
      for (size_t i = 0; i < pilot.size(); ++i)
        for (size_t k = 0; k < stride; ++k)
          v[i * stride + k] = back[i] > stop ? 0.0 : coeffs[i * stride + k] / scale;
      out.push_back(std::move(v));
    }
    return out;
  };
  ToleranceReport report = detail::runTolerancePilot(evaluate, stride, o.tolerance, o.toleranceMaxSamples, 16);
  report.pilotItems = pilot.size();
  report.items = total;
  report.pilotSeconds = secondsSince(t0);
  g.tolerance = {report};
  return report.samples;
}

}  // namespace

int fillInvalidProbes(ProbeGridResult& g) {
  if (g.probeCount != g.layout.count() || g.state.size() != g.probeCount)
    throw UsageError("probes", "the fill needs the whole grid (" + std::to_string(g.layout.count()) + " probes, got " +
                                   std::to_string(g.probeCount) + ")");
  g.fillPasses = fillPasses(g);
  return g.fillPasses;
}

std::string detail::probesOptions(int order, int envOrder, int packetWidth, int rayLanes) {
  return "-DPROBE_ORDER=" + std::to_string(order) + " -DENV_ORDER=" + std::to_string(envOrder) +
         " -DBVH_PACKET=" + std::to_string(packetWidth) + rayLanesOption(rayLanes);
}

ProbeGridLayout probeGridLayout(const Mesh& mesh, const ProbeOptions& o) {
  ProbeGridLayout g;
  if (o.boundsMin.has_value() != o.boundsMax.has_value()) throw UsageError("--bounds", "needs both corners");
  if (o.boundsMin) {
    g.boundsMin = *o.boundsMin, g.boundsMax = *o.boundsMax;
  } else {
    if (mesh.vertexCount() == 0) throw UsageError("--bounds", "the scene has no vertices: give the bounds");
    for (int a = 0; a < 3; ++a) g.boundsMin[a] = INFINITY, g.boundsMax[a] = -INFINITY;
    for (size_t v = 0; v < mesh.vertexCount(); ++v)
      for (int a = 0; a < 3; ++a)
        g.boundsMin[a] = std::min(g.boundsMin[a], double(mesh.positions[3 * v + a])),
        g.boundsMax[a] = std::max(g.boundsMax[a], double(mesh.positions[3 * v + a]));
  }
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(g.boundsMin[a]) || !std::isfinite(g.boundsMax[a]))
      throw UsageError("--bounds", "the bounds must be finite");
    if (!(g.boundsMax[a] > g.boundsMin[a]))
      throw UsageError("--bounds", std::string("the bounds are empty or inverted along ") + "xyz"[a] + " (" +
                                      std::to_string(g.boundsMin[a]) + " to " + std::to_string(g.boundsMax[a]) +
                                      (o.boundsMin ? ")" : "; the scene is flat there: give --bounds)"));
  }
  if (o.resolution && o.spacing > 0) throw UsageError("--spacing", "cannot be combined with --resolution");
  if (o.spacing < 0 || !std::isfinite(o.spacing)) throw UsageError("--spacing", "expected a positive length");
  const double spacing = o.spacing > 0 ? o.spacing
                                       : std::max({g.boundsMax[0] - g.boundsMin[0], g.boundsMax[1] - g.boundsMin[1],
                                                   g.boundsMax[2] - g.boundsMin[2]}) / 8;
  for (int a = 0; a < 3; ++a) {
    const double n = o.resolution ? double((*o.resolution)[a])
                                  : std::max(1.0, std::round((g.boundsMax[a] - g.boundsMin[a]) / spacing));
    if (!(n >= 1) || n > kMaxProbesPerAxis)
      throw UsageError(o.resolution ? "--resolution" : "--spacing",
                       std::string("gives ") + std::to_string((long long)n) + " probes along " + "xyz"[a] +
                           " (expected 1.." + std::to_string(kMaxProbesPerAxis) + ")");
    g.resolution[a] = int(n);
  }
  if (g.count() > kMaxProbes)
    throw UsageError(o.resolution ? "--resolution" : "--spacing",
                     std::to_string(g.count()) + " probes is over the limit of " + std::to_string(kMaxProbes));
  if (o.requireGeometry && !sceneMeetsBounds(mesh, g))
    throw InputError(mesh.sourcePath.empty() ? "scene" : mesh.sourcePath,
                     "no geometry inside the probes' bounds (the scene's bounding box does not meet them)");
  return g;
}

ProbeGridResult computeProbeGrid(Runtime& rt, const Mesh& mesh, const ShCoeffs& environment, const ProbeOptions& o) {
  const auto t0 = Clock::now();
  checkOptions(o);
  if (environment.quantity != ShQuantity::Radiance || environment.order < 1)
    throw UsageError("--env", "the probes need the environment's radiance coefficients");
  ProbeGridResult g;
  g.layout = probeGridLayout(mesh, o);
  g.order = o.order;
  g.device = rt.deviceLabel();
  const int envOrder = std::max(o.order, std::min(environment.order, kMaxEnvOrder));
  g.environmentOrder = std::min(environment.order, kMaxEnvOrder);

  auto t = Clock::now();
  const Bvh bvh = buildBvh(mesh);
  g.bvhSeconds = secondsSince(t);
  t = Clock::now();
  const std::vector<float> radiance = o.bounces > 0 && bvh.nodes.size() > 0
                                          ? surfaceRadiance(rt, mesh, environment, envOrder, o)
                                          : std::vector<float>();
  g.surfaceSeconds = secondsSince(t);

  // The quadrature of N directions: exact for the products of the probe's and the environment's SH.
  const int degree = (o.order - 1) + (envOrder - 1);
  auto rule = [&](int samples, int* rings, int* segments) {
    *rings = std::max((degree + 2) / 2, int(std::lround(std::sqrt(samples / 2.0))));
    *segments = std::max(degree + 1, int(std::lround(double(samples) / *rings)));
    return quadrature(*rings, *segments);
  };

  const int width = detail::packetWidthFor(rt.info(), o.packetWidth);
  ProbeTracer tracer(rt, mesh, bvh, environment, o.order, envOrder, radiance, width,
                     detail::rayLanesFor(rt.info(), width, o.rayLanes));
  // A probe inside geometry (back faces over the limit) is relocated or filled: its trace may stop.
  const float stop = float(o.backfaceLimit * 4 * kPi);
  int samples = o.samples;
  if (o.tolerance > 0) samples = toleranceSamples(tracer, g.layout, o, environment, stop, rule, g);
  const std::vector<float> dirs = rule(samples, &g.rings, &g.segments);
  g.samples = g.rings * g.segments;
  const size_t total = g.layout.count();
  if (o.firstProbe > total || (o.probeCount && *o.probeCount > total - o.firstProbe))
    throw UsageError("probe range", "probes " + std::to_string(o.firstProbe) + " + " +
                                        std::to_string(o.probeCount.value_or(0)) + " run past the grid's " +
                                        std::to_string(total));
  g.firstProbe = o.firstProbe;
  g.probeCount = o.probeCount ? *o.probeCount : total - o.firstProbe;
  const size_t n = g.probeCount;
  g.positions.resize(n * 3);
  std::vector<size_t> frameIndex(n);
  const auto& res = g.layout.resolution;
  for (size_t i = 0; i < n; ++i) {
    const size_t q = g.firstProbe + i;  // the probe's index in the grid: its position and its rotation
    const auto p = g.layout.probePosition(int(q % res[0]), int(q / res[0] % res[1]), int(q / (size_t(res[0]) * res[1])));
    for (int a = 0; a < 3; ++a) g.positions[3 * i + a] = float(p[a]);
    frameIndex[i] = q;
  }
  t = Clock::now();
  tracer.trace(g.positions, frameIndex, o.seed, dirs, stop, g.coeffs, g.backfaceFraction, "probes", g.rays);
  for (float& b : g.backfaceFraction) b = float(b / (4 * kPi));
  g.traceSeconds = secondsSince(t);

  // Relocation: probes inside geometry try the nearest free lattice point within reach.
  t = Clock::now();
  g.state.assign(n, 0);
  std::vector<size_t> inside;
  for (size_t i = 0; i < n; ++i)
    if (g.backfaceFraction[i] > o.backfaceLimit) inside.push_back(i);
  if (!inside.empty() && o.relocateFraction > 0) {
    const auto cell = g.layout.cell();
    const auto offsets = relocationOffsets(o.relocateFraction * std::min({cell[0], cell[1], cell[2]}));
    std::vector<float> candidates;
    std::vector<size_t> candidateFrame, candidateOf;
    for (size_t i : inside)
      for (const auto& d : offsets) {
        float p[3];
        bool within = true;
        for (int a = 0; a < 3; ++a) {
          p[a] = float(g.positions[3 * i + a] + d[a]);
          within = within && p[a] >= g.layout.boundsMin[a] && p[a] <= g.layout.boundsMax[a];
        }
        if (!within) continue;
        candidates.insert(candidates.end(), p, p + 3);
        candidateFrame.push_back(g.firstProbe + i);
        candidateOf.push_back(i);
      }
    std::vector<float> pilotCoeffs, pilotBack;
    tracer.trace(candidates, candidateFrame, o.seed, quadrature(kPilotRings, kPilotSegments), stop, pilotCoeffs, pilotBack,
                 "probes: relocation", g.rays);
    // The first free candidate of each probe (candidates are nearest first).
    std::vector<float> moved;
    std::vector<size_t> movedIndex;
    for (size_t c = 0; c < candidateOf.size(); ++c) {
      const size_t i = candidateOf[c];
      if (!movedIndex.empty() && movedIndex.back() == i) continue;
      if (pilotBack[c] / (4 * kPi) > o.backfaceLimit) continue;
      moved.insert(moved.end(), &candidates[3 * c], &candidates[3 * c] + 3);
      movedIndex.push_back(i);
    }
    std::vector<size_t> movedFrame(movedIndex);
    for (size_t& f : movedFrame) f += g.firstProbe;
    std::vector<float> movedCoeffs, movedBack;
    tracer.trace(moved, movedFrame, o.seed, dirs, stop, movedCoeffs, movedBack, "probes: relocated", g.rays);
    const size_t nc = size_t(o.order) * o.order * 3;
    for (size_t m = 0; m < movedIndex.size(); ++m) {
      const size_t i = movedIndex[m];
      const float fraction = float(movedBack[m] / (4 * kPi));
      if (fraction > o.backfaceLimit) continue;  // the pilot was wrong: stays invalid
      std::copy(&movedCoeffs[m * nc], &movedCoeffs[m * nc] + nc, &g.coeffs[i * nc]);
      std::copy(&moved[3 * m], &moved[3 * m] + 3, &g.positions[3 * i]);
      g.backfaceFraction[i] = fraction;
      g.state[i] = 1;
    }
  }
  for (size_t i : inside)
    if (g.state[i] == 0) g.state[i] = 2;
  for (uint8_t s : g.state) g.moved += s == 1, g.invalid += s == 2;
  if (g.invalid && g.probeCount == total) g.fillPasses = fillPasses(g);
  g.relocateSeconds = secondsSince(t);
  g.totalSeconds = secondsSince(t0);
  return g;
}

}  // namespace prtbake
