// Sample directions, per-vertex frames and ray origins (see transport.h, sampling.clh).
#include "transport/transport_setup.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <tuple>

#include "core/constants.h"
#include "prtbake/error.h"
#include "prtbake/sh.h"
#include "core/radical_inverse.h"

namespace prtbake {
namespace {

using detail::splitmix64;
using detail::unitFromBits;

// Orders a direction set along a Morton curve over the projected disk (x, y), so that
// consecutive samples (the packets of the vector kernel) point in nearby directions.
// The set, and so the estimate, is unchanged up to summation order.
std::vector<std::array<double, 3>> mortonSorted(const std::vector<std::array<double, 3>>& out) {
  auto spread = [](uint32_t v) {
    uint64_t x = v;
    x = (x | (x << 16)) & 0x0000FFFF0000FFFFull;
    x = (x | (x << 8)) & 0x00FF00FF00FF00FFull;
    x = (x | (x << 4)) & 0x0F0F0F0F0F0F0F0Full;
    x = (x | (x << 2)) & 0x3333333333333333ull;
    x = (x | (x << 1)) & 0x5555555555555555ull;
    return x;
  };
  std::vector<std::pair<uint64_t, size_t>> keys(out.size());
  for (size_t i = 0; i < out.size(); ++i) {
    const uint32_t qx = uint32_t(std::min(65535.0, (out[i][0] + 1) * 32768.0));
    const uint32_t qy = uint32_t(std::min(65535.0, (out[i][1] + 1) * 32768.0));
    keys[i] = {spread(qx) | (spread(qy) << 1), i};
  }
  std::sort(keys.begin(), keys.end());
  std::vector<std::array<double, 3>> sorted(out.size());
  for (size_t i = 0; i < out.size(); ++i) sorted[i] = out[keys[i].second];
  return sorted;
}

std::array<double, 3> cosineHemisphere(double u1, double u2) {
  const double r = std::sqrt(u1), phi = 2 * kPi * u2;
  return {r * std::cos(phi), r * std::sin(phi), std::sqrt(std::max(0.0, 1 - u1))};
}
}  // namespace

const char* transportModeName(TransportMode mode) {
  switch (mode) {
    case TransportMode::Unshadowed: return "unshadowed";
    case TransportMode::Shadowed: return "shadowed";
    case TransportMode::Interreflected: return "interreflected";
  }
  return "?";
}

TransportMode parseTransportMode(const std::string& name) {
  if (name == "unshadowed") return TransportMode::Unshadowed;
  if (name == "shadowed") return TransportMode::Shadowed;
  if (name == "interreflected") return TransportMode::Interreflected;
  throw UsageError("--mode", "unknown mode '" + name + "' (expected unshadowed|shadowed|interreflected)");
}

const char* transportSamplerName(TransportSampler sampler) {
  switch (sampler) {
    case TransportSampler::Hammersley: return "hammersley";
    case TransportSampler::Stratified: return "stratified";
    case TransportSampler::Random: return "random";
  }
  return "?";
}

size_t detail::vertexRangeSize(const Mesh& mesh, size_t first, const std::optional<size_t>& count) {
  const size_t nv = mesh.vertexCount();
  if (first > nv)
    throw UsageError("vertex range", "first vertex " + std::to_string(first) + " is beyond the mesh's " +
                                         std::to_string(nv) + " vertices");
  const size_t n = count ? *count : nv - first;
  if (n > nv - first)
    throw UsageError("vertex range", std::to_string(n) + " vertices from " + std::to_string(first) +
                                         " run past the mesh's " + std::to_string(nv) + " vertices");
  return n;
}

TransportSampler parseTransportSampler(const std::string& name) {
  if (name == "hammersley") return TransportSampler::Hammersley;
  if (name == "stratified") return TransportSampler::Stratified;
  if (name == "random") return TransportSampler::Random;
  throw UsageError("--sampler", "unknown sampler '" + name + "' (expected hammersley|stratified|random)");
}

std::vector<std::array<double, 3>> sampleDirectionsLocal(int samples, uint64_t seed) {
  return sampleDirectionsLocal(samples, seed, TransportSampler::Hammersley);
}

namespace {

// Direction i of the `samples`-point set of a sampler (see transport.h):
// Hammersley (u1 stratified, u2 the base-2 radical inverse) with a Cranley–Patterson
// shift from the seed, mapped to the cosine-weighted hemisphere:
//   r = √u1, φ = 2π u2, ω = (r cos φ, r sin φ, √(1 − u1)),  pdf = cos θ / π.
// Stratified: (u1, u2) jittered in cell (i mod m, i div m) of an m × m grid (the last
// N − m² points, when N is not a square, are independent); Random: independent (u1, u2).
std::array<double, 3> directionAt(int i, int samples, uint64_t seed, TransportSampler sampler) {
  const double s1 = unitFromBits(splitmix64(seed * 2 + 1)), s2 = unitFromBits(splitmix64(seed * 2 + 2));
  const int m = int(std::sqrt(double(std::max(samples, 0))));
  double u1 = (i + 0.5) / samples + s1, u2 = detail::radicalInverse2(uint32_t(i)) + s2;
  if (sampler != TransportSampler::Hammersley) {
    const uint64_t h = splitmix64(seed * 0x9E3779B97F4A7C15ull + 2 * uint64_t(i) + 7);
    const double j1 = unitFromBits(h), j2 = unitFromBits(splitmix64(h));
    if (sampler == TransportSampler::Stratified && i < m * m)
      u1 = ((i % m) + j1) / m, u2 = ((i / m) + j2) / m;
    else
      u1 = j1, u2 = j2;
  }
  u1 -= std::floor(u1), u2 -= std::floor(u2);
  return cosineHemisphere(u1, u2);
}

}  // namespace

std::vector<std::array<double, 3>> sampleDirectionsLocal(int samples, uint64_t seed, TransportSampler sampler) {
  std::vector<std::array<double, 3>> out(size_t(std::max(samples, 0)));
  for (int i = 0; i < samples; ++i) out[size_t(i)] = directionAt(i, samples, seed, sampler);
  return mortonSorted(out);
}

TransportRays transportRays(const Mesh& mesh, const TransportOptions& o) {
  detail::checkTransportOptions(o);
  const detail::RaySetup s = detail::makeRaySetup(mesh, o, false);
  TransportRays r;
  r.tMax = s.tMax;
  const size_t nv = mesh.vertexCount();
  r.origins.resize(3 * nv);
  r.frames.resize(9 * nv);
  for (size_t v = 0; v < nv; ++v) {
    for (int c = 0; c < 3; ++c) r.origins[3 * v + c] = s.origins[4 * v + c];
    for (int k = 0; k < 3; ++k)
      for (int c = 0; c < 3; ++c) r.frames[9 * v + 3 * k + c] = s.frames[12 * v + 4 * k + c];
  }
  for (int first = 0; first < o.samples; first += detail::kTransportSampleChunk) {
    const std::vector<float> d = detail::directionChunk(
        o.samples, first, std::min(detail::kTransportSampleChunk, o.samples - first), o.seed, o.sampler);
    for (size_t i = 0; i < d.size() / 4; ++i) r.directions.insert(r.directions.end(), {d[4 * i], d[4 * i + 1], d[4 * i + 2]});
  }
  return r;
}

namespace detail {

std::vector<float> directionChunk(int samples, int first, int count, uint64_t seed, TransportSampler sampler) {
  std::vector<std::array<double, 3>> out(size_t(std::max(count, 0)));
  for (int i = 0; i < count; ++i) out[size_t(i)] = directionAt(first + i, samples, seed, sampler);
  const auto sorted = mortonSorted(out);
  std::vector<float> dirs(sorted.size() * 4, 0.0f);
  for (size_t i = 0; i < sorted.size(); ++i)
    for (int c = 0; c < 3; ++c) dirs[4 * i + c] = float(sorted[i][c]);
  return dirs;
}

std::vector<float> packetDirections(const std::vector<float>& dirs, int& paddedCount) {
  const int ns = int(dirs.size() / 4);
  paddedCount = (ns + 15) / 16 * 16;
  std::vector<float> soa(size_t(3) * paddedCount, 0.0f);
  for (int i = 0; i < ns; ++i)
    for (int c = 0; c < 3; ++c) soa[size_t(c) * paddedCount + i] = dirs[4 * size_t(i) + c];
  return soa;
}

int packetWidthFor(const DeviceInfo& device, int requested) {
  return requested >= 0 ? requested : device.type == "cpu" ? 16 : 0;
}

void checkRayLanes(int requested) {
  if (requested != -1 && (requested < 1 || requested > 32 || (requested & (requested - 1)) != 0))
    throw UsageError("ray lanes", std::to_string(requested) + " (expected 1, 2, 4, 8, 16 or 32, or -1: by the device)");
}

int rayLanesFor(const DeviceInfo& device, int packetWidth, int requested) {
  if (packetWidth > 0) return 1;
  return requested >= 1 ? requested : device.type == "cpu" ? 1 : 32;
}

void checkTransportOptions(const TransportOptions& o) {
  if (o.order < 1 || o.order > kMaxTransportOrder)
    throw UsageError("--order", std::to_string(o.order) + " is out of range [1, " + std::to_string(kMaxTransportOrder) + "]");
  if (o.samples < 1 || o.samples > (1 << 24))
    throw UsageError("--samples", std::to_string(o.samples) + " is out of range [1, 16777216]");
  if (o.mode == TransportMode::Interreflected && (o.bounces < 1 || o.bounces > 64))
    throw UsageError("--bounces", std::to_string(o.bounces) + " is out of range [1, 64]");
  if (o.packetWidth != -1 && o.packetWidth != 0 && o.packetWidth != 8 && o.packetWidth != 16)
    throw UsageError("packet width", std::to_string(o.packetWidth) + " (expected 0, 8 or 16, or -1: by the device)");
  checkRayLanes(o.rayLanes);
  if (!(o.bounceTolerance >= 0) || !std::isfinite(o.bounceTolerance))
    throw UsageError("--bounce-tolerance", "must be a finite number ≥ 0");
  if (!(o.tolerance >= 0) || !std::isfinite(o.tolerance))
    throw UsageError("--tolerance", "must be a finite number ≥ 0");
  if (o.tolerance > 0 && (o.toleranceMaxSamples < 2 * kTolerancePilotStart || o.toleranceMaxSamples > (1 << 24)))
    throw UsageError("--max-samples", std::to_string(o.toleranceMaxSamples) + " is out of range [" +
                                          std::to_string(2 * kTolerancePilotStart) + ", 16777216]");
  if (!(o.maxDistance >= 0) || !std::isfinite(o.maxDistance))
    throw UsageError("--max-distance", "must be a finite number ≥ 0");
  if (o.maxDistance > 0 && o.mode != TransportMode::Shadowed)
    throw UsageError("--max-distance", "applies to shadowed transport only (the range of the occlusion)");
  if (o.albedoOverride)
    for (float a : *o.albedoOverride)
      if (!(a >= 0 && a <= 1)) throw UsageError("--albedo", "albedo must lie in [0, 1]");
}

std::vector<float> vertexAlbedo(const Mesh& mesh, const TransportOptions& o) {
  std::vector<float> a(mesh.vertexCount() * 4, 0.0f);
  for (size_t v = 0; v < mesh.vertexCount(); ++v)
    for (int c = 0; c < 3; ++c) a[4 * v + c] = o.albedoOverride ? (*o.albedoOverride)[c] : mesh.albedo[3 * v + c];
  return a;
}

bool transportIsRgb(const Mesh& mesh, const TransportOptions& o) {
  if (o.mode != TransportMode::Interreflected) return false;
  if (o.albedoOverride) {
    const auto& a = *o.albedoOverride;
    return !(a[0] == a[1] && a[0] == a[2]);
  }
  return !mesh.greyAlbedo();
}

namespace {

// ε and the ray length from the scene's bounding box: a scale-relative offset; the second
// term keeps it above float spacing (~6e-8 × |p|) for scenes far from the origin.
void sceneScale(const Mesh& mesh, const TransportOptions& o, RaySetup& s) {
  double bmin[3], bmax[3];
  meshBounds(mesh, bmin, bmax);
  double diag2 = 0, maxAbs = 0;
  for (int c = 0; c < 3; ++c) {
    diag2 += (bmax[c] - bmin[c]) * (bmax[c] - bmin[c]);
    maxAbs = std::max({maxAbs, std::abs(bmin[c]), std::abs(bmax[c])});
  }
  const double diag = std::sqrt(diag2);
  s.epsilon = 1e-4 * diag + 1e-6 * maxAbs;
  s.tMax = float(4 * diag + 4 * s.epsilon);
  if (o.maxDistance > 0) s.tMax = std::min(s.tMax, float(o.maxDistance));
}

// Point v's origin and frame: p offset by ε along the geometric normal g (turned to the side
// of the shading normal n, so that a flipped winding does not bury the origin), and an
// orthonormal basis about n (Duff et al. 2017) rotated by a per-index angle. A zero n marks
// a point without a normal (origin p, frame zero).
// v: where the point is stored; rotation: the index its frame's rotation is drawn for.
void setPoint(RaySetup& s, size_t v, const float* p, const float* shading, std::array<double, 3> g, uint64_t seed,
              size_t rotation) {
  for (int c = 0; c < 3; ++c) s.points[3 * v + c] = p[c];
  double n[3] = {shading[0], shading[1], shading[2]};
  const double nlen = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  const double glen = std::sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
  if (!(nlen > 0)) {
    ++s.verticesWithoutNormal;
    for (int c = 0; c < 3; ++c) s.origins[4 * v + c] = p[c];
    return;
  }
  for (double& c : n) c /= nlen;
  if (glen > 0) {
    for (double& c : g) c /= glen;
    if (g[0] * n[0] + g[1] * n[1] + g[2] * n[2] < 0)
      for (double& c : g) c = -c;
  } else {
    g = {n[0], n[1], n[2]};
  }
  for (int c = 0; c < 3; ++c) s.origins[4 * v + c] = float(p[c] + s.epsilon * g[c]);
  const double sign = std::copysign(1.0, n[2]);
  const double a = -1.0 / (sign + n[2]), b = n[0] * n[1] * a;
  const double t0[3] = {1 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]};
  const double b0[3] = {b, sign + n[1] * n[1] * a, -n[1]};
  const double phi = 2 * kPi * unitFromBits(splitmix64(seed ^ (0xD1B54A32D192ED03ull * (rotation + 1))));
  const double cp = std::cos(phi), sp = std::sin(phi);
  for (int c = 0; c < 3; ++c) {
    s.frames[12 * v + c] = float(cp * t0[c] + sp * b0[c]);
    s.frames[12 * v + 4 + c] = float(-sp * t0[c] + cp * b0[c]);
    s.frames[12 * v + 8 + c] = float(n[c]);
  }
}

void allocate(RaySetup& s, size_t n) {
  s.points.assign(n * 3, 0.0f);
  s.origins.assign(n * 4, 0.0f);
  s.frames.assign(n * 12, 0.0f);
}

}  // namespace

RaySetup makeRaySetup(const Mesh& mesh, const TransportOptions& o, bool withDirections) {
  RaySetup s;
  const size_t nv = mesh.vertexCount();
  sceneScale(mesh, o, s);
  // Geometric normal per position (welded by exact coordinates): the area-weighted sum
  // of the face normals of every triangle touching that position, in triangle order.
  // Positions are welded by sorting the vertices by coordinates (equal as floats: one).
  const auto& p = mesh.positions;
  std::vector<uint32_t> weld(nv), byPos(nv);
  std::iota(byPos.begin(), byPos.end(), 0u);
  auto key = [&](uint32_t v) { return std::make_tuple(p[3 * v], p[3 * v + 1], p[3 * v + 2]); };
  std::sort(byPos.begin(), byPos.end(), [&](uint32_t a, uint32_t b) { return key(a) < key(b); });
  for (size_t i = 0, id = 0; i < nv; ++i) {
    if (i > 0 && key(byPos[i - 1]) < key(byPos[i])) ++id;
    weld[byPos[i]] = uint32_t(id);
  }
  std::vector<std::array<double, 3>> geo(nv, {0, 0, 0});
  for (size_t t = 0; t < mesh.triangleCount(); ++t) {
    const uint32_t i0 = mesh.indices[3 * t], i1 = mesh.indices[3 * t + 1], i2 = mesh.indices[3 * t + 2];
    double e1[3], e2[3];
    for (int c = 0; c < 3; ++c) e1[c] = double(p[3 * i1 + c]) - p[3 * i0 + c], e2[c] = double(p[3 * i2 + c]) - p[3 * i0 + c];
    const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    for (uint32_t v : {i0, i1, i2}) {
      auto& g = geo[weld[v]];
      for (int c = 0; c < 3; ++c) g[c] += n[c];
    }
  }
  if (withDirections) s.dirs = directionChunk(o.samples, 0, o.samples, o.seed, o.sampler);
  allocate(s, nv);
  for (size_t v = 0; v < nv; ++v) setPoint(s, v, &p[3 * v], &mesh.normals[3 * v], geo[weld[v]], o.seed, v);
  return s;
}

RaySetup makePointRaySetup(const Mesh& mesh, const SurfacePoints& pts, const TransportOptions& o) {
  RaySetup s;
  sceneScale(mesh, o, s);
  const size_t n = pts.count();
  allocate(s, n);
  for (size_t v = 0; v < n; ++v) {
    const float* f = &pts.faceNormals[3 * v];
    setPoint(s, v, &pts.positions[3 * v], &pts.normals[3 * v], {f[0], f[1], f[2]}, o.seed, pts.firstIndex + v);
  }
  return s;
}

}  // namespace detail
}  // namespace prtbake
