// prtbake/transport.h: per-vertex PRT transport in SH (docs/conventions.md, "Transport").
//
// For vertex p with unit normal n and SH order N (N² coefficients, index l(l+1)+m):
//   T_i(p) = (1/π) ∫ V(p, ω) max(0, n·ω) Y_i(ω) dω           (shadowed)
// Unshadowed drops V. Interreflected adds bounces
//   T^(k+1)(p) = (1/π) ∫_{ray p→q hits} ρ(q) T^(k)(q) max(0, n·ω) dω,   T = Σ_{k=0..B} T^(k),
// computed bounce by bounce over all vertices (cost linear in B), T^(k)(q) interpolated
// with barycentrics. Units: an unoccluded vertex under a constant white environment
// (L = 1 everywhere, l_0 = √(4π)) gives Σ l_i T_i = 1; the runtime shades
// L_o = ρ(p) Σ_i l_i T_i. The GAMES202 framework's units are π × these.
//
// Estimator: N cosine-distributed low-discrepancy directions per vertex (a shifted
// Hammersley set, rotated about n by a per-vertex angle; see kernels/sampling.clh):
//   T_i(p) ≈ (1/N) Σ_s V(p, ω_s) Y_i(ω_s).
// Shadow rays start at p + ε n_g (n_g: the area-weighted geometric normal at p,
// ε = 1e-4 × the scene's bounding-box diagonal + 1e-6 × its largest coordinate).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "prtbake/mesh.h"
#include "prtbake/runtime.h"
#include "prtbake/tolerance.h"

namespace prtbake {

enum class TransportMode { Unshadowed, Shadowed, Interreflected };
const char* transportModeName(TransportMode mode);
// "unshadowed" | "shadowed" | "interreflected"; throws UsageError otherwise.
TransportMode parseTransportMode(const std::string& name);

// How the per-vertex directions are drawn (all cosine-distributed):
//   Hammersley  shifted Hammersley points (low discrepancy; the default)
//   Stratified  one jittered point per cell of a √N × √N grid (N rounded to a square)
//   Random      independent uniform points (plain Monte Carlo)
enum class TransportSampler { Hammersley, Stratified, Random };
const char* transportSamplerName(TransportSampler sampler);
// "hammersley" | "stratified" | "random"; throws UsageError otherwise.
TransportSampler parseTransportSampler(const std::string& name);

struct TransportOptions {
  TransportMode mode = TransportMode::Shadowed;
  int order = 3;            // SH order 1..kMaxTransportOrder
  int samples = 1024;       // directions per vertex (and per bounce); summed in double over chunks of 1024
  uint64_t seed = 0;        // selects the direction set and the per-vertex rotations
  int bounces = 3;          // interreflected only: the most bounces B ≥ 1
  // Interreflected only: stop after a bounce whose largest per-vertex coefficient
  // norm max_p |T^(k)(p)| is below this (0: always do B bounces).
  double bounceTolerance = 1e-4;
  // Replaces every vertex's albedo (linear RGB) when set.
  std::optional<std::array<float, 3>> albedoOverride;
  // Rays per packet of the direct-term kernel: 16 or 8 (vector types, one vertex's
  // rays share an origin), or 0 for the scalar one-ray-at-a-time kernel. The results
  // agree up to float summation order. −1: by the device (detail::packetWidthFor: 16 on a
  // CPU, 0 on a GPU).
  int packetWidth = -1;
  // Work-items per vertex of the scalar kernels (packetWidth 0): 1, 2, 4, 8, 16 or 32, each
  // taking every rayLanes-th ray, their sums added in a fixed tree (so a vertex's result does
  // not depend on the work-group size or on other vertices). −1: by the device
  // (detail::rayLanesFor: 1 on a CPU, 32 elsewhere). Ignored by the packet kernels.
  int rayLanes = -1;
  // Interreflected only: also return each bounce's T^(k) (TransportResult::bounceCoeffs).
  bool keepBounces = false;
  // computeTransport only: the vertex range [firstVertex, firstVertex + vertexCount)
  // to compute (vertexCount unset: up to the last vertex), traced against the whole
  // mesh. Each vertex's rays depend only on its global index (frame rotation) and the
  // seed, and a vertex's own work-items compute it, so the range's coefficients are
  // bit-identical to the same vertices of a full run on the same device. An empty range
  // returns an empty result. Interreflected transport needs every vertex's previous
  // bounce, so it accepts only the whole mesh (UsageError otherwise).
  size_t firstVertex = 0;
  std::optional<size_t> vertexCount;
  TransportSampler sampler = TransportSampler::Hammersley;
  // "--tolerance E" (0: off, `samples` is used): each term (the direct term, each bounce)
  // takes the sample count that brings 95 % of its vertices within its share of E, E/2^(k+1)
  // for term k of interreflected transport (E for the others), predicted from a pilot over
  // at most 128 of the mesh's sampled vertices, one in up to 8 of a small mesh's but at least
  // 64 (prtbake/tolerance.h), and capped at
  // toleranceMaxSamples. Vertices that no triangle can occlude, and every vertex of
  // unshadowed transport, take the closed form (clampedCosineProjected) instead of samples;
  // their bounces are exactly zero. The pilot uses the whole mesh's vertices, so a vertex
  // range gets the counts of the whole mesh.
  double tolerance = 0;
  int toleranceMaxSamples = 65536;
  // Shadowed only (> 0): only occluders nearer than this distance count, the range of ambient
  // occlusion; 0: the whole scene.
  double maxDistance = 0;
};

// The albedo a bake with these options reads from a mesh file (loadMesh): the base colour
// textures too when interreflected without an albedo override.
inline MeshAlbedo meshAlbedo(const TransportOptions& o) {
  return o.mode == TransportMode::Interreflected && !o.albedoOverride ? MeshAlbedo::Textures : MeshAlbedo::Factors;
}

// Orders accepted by the transport product.
constexpr int kMaxTransportOrder = 8;

struct TransportResult {
  int order = 0;
  int channels = 1;          // 1 (grey albedo) or 3 (coloured albedo, interreflected)
  size_t vertexCount = 0;     // vertices computed (the range's size)
  size_t firstVertex = 0;    // global index of the first one (TransportOptions::firstVertex)
  std::vector<float> coeffs; // vertexCount × channels × order², vertex-major
  // Per-vertex standard error of the direct term (L2 norm over the coefficients),
  // for independent samples: √((N²/(4π)·v − |T|²)/N_s) with v the unoccluded
  // fraction (Σ_i Y_i² = N²/(4π)); low-discrepancy sampling usually does better.
  std::vector<float> stdError;
  double maxStdError = 0, meanStdError = 0;
  int bouncesUsed = 0;                 // interreflected: bounces computed
  std::vector<double> bounceMaxNorm;   // max_p |T^(k)(p)| for k = 1..bouncesUsed
  // T^(0), T^(1), ... (same layout as coeffs) when TransportOptions::keepBounces is set.
  std::vector<std::vector<float>> bounceCoeffs;
  uint64_t rays = 0;                   // rays traced (0 when unshadowed)
  int samples = 0;
  // Vertices whose hemisphere no triangle can reach (every vertex of a convex mesh):
  // computed without visibility rays (shadowed and interreflected modes).
  size_t verticesUnoccludable = 0;
  uint64_t totalSamples = 0;  // Σ over vertices of the samples used (every term, the pilots too)
  // With --tolerance: what it did for the direct term, then for each bounce.
  std::vector<ToleranceReport> tolerance;
  double bvhSeconds = 0, kernelSeconds = 0, totalSeconds = 0;
  size_t bvhNodes = 0, degenerateTriangles = 0, verticesWithoutNormal = 0;
  std::string device;

  const float* vertex(size_t v) const { return coeffs.data() + v * size_t(channels) * order * order; }
};

// Computes the transport of every vertex of `mesh` on the runtime's device.
// Throws UsageError for bad options, InputError for an unusable mesh.
TransportResult computeTransport(Runtime& rt, const Mesh& mesh, const TransportOptions& options);

// Points on the mesh's surface that need not be vertices (lightmap texels): 3 floats each of
// position, unit shading normal (zero: no transport, as a vertex without a normal) and the
// normal of the face the point lies on (its rays start ε along it, on the shading normal's side).
struct SurfacePoints {
  std::vector<float> positions, normals, faceNormals;
  // Point k takes the rays of index firstIndex + k (below: "point i"), so that a range of a
  // larger set of points bakes as it would within the whole set (a split lightmap's shard).
  size_t firstIndex = 0;
  size_t count() const { return positions.size() / 3; }
};

// The estimated peak memory in bytes of computeTransport(mesh, options), fitted to peaks
// measured on 0.26 M to 10 M vertices (docs/transport.md, "Memory"): the runtime's memory
// (kRuntimeMemoryBytes, prtbake/limits.h), 500 bytes a mesh
// vertex (the mesh, the tree, the rays' set-up) and 16 bytes for each coefficient baked (the
// device's, the kernel's and the result's copies), three times over with interreflection; it
// errs high. computeTransport refuses a mesh whose estimate exceeds the memory the process can
// have (checkProcessMemory, prtbake/limits.h) with a UsageError naming the mesh.
double transportPeakBytes(const Mesh& mesh, const TransportOptions& options);

// The transport of each point, as computeTransport defines a vertex's, traced against `mesh`:
// point i takes the rays a vertex of index i would (the same directions, the frame's rotation
// from i), from its position offset along its face normal. Interreflected: the direct term at
// the points plus one bounce that gathers, at the points' hits, the per-vertex transport of
// the mesh with B − 1 bounces (computed here with the same options; B = 1: its shadowed
// transport), interpolated with barycentrics:
//   T(p) = T^(0)(p) + (1/π) ∫_{hits q} ρ(q) Σ_{k<B} T^(k)(q) max(0, n·ω) dω.
// The result holds one entry per point (vertexCount = points, firstVertex 0); the options'
// vertex range must be the default. Throws as computeTransport, and UsageError for point
// arrays of unequal sizes.
TransportResult computeTransportAtPoints(Runtime& rt, const Mesh& mesh, const SurfacePoints& points,
                                         const TransportOptions& options);

// Double-precision CPU reference with the same directions and ray origins, by brute
// force over all triangles (small meshes only). Optionally returns the visibility of
// every (vertex, sample) ray and the distance of each blocking hit to its triangle's
// nearest edge in barycentric units.
struct ReferenceRays {
  std::vector<uint8_t> visible;     // vertexCount × samples
  std::vector<double> edgeDistance; // vertexCount × samples; 1 where no hit is near an edge
};
TransportResult computeTransportReference(const Mesh& mesh, const TransportOptions& options,
                                          ReferenceRays* rays = nullptr);

// The rays computeTransport traces for options.samples, as the float values its kernels
// read: per vertex the origin p + ε n_g and the frame (t, b, n; n = 0 marks a vertex
// without a normal), and the local directions (z along n) in the kernels' order (chunks of
// 1024, each Morton-ordered; a packet is 16 consecutive directions). World direction of
// sample s at vertex v: x_s t + y_s b + z_s n. For tracing the same rays with another
// ray tracer (bench/bench_embree.cpp).
struct TransportRays {
  std::vector<float> origins;     // V × 3
  std::vector<float> frames;      // V × 9: t, b, n
  std::vector<float> directions;  // samples × 3
  float tMax = 0;                 // the rays' length
};
TransportRays transportRays(const Mesh& mesh, const TransportOptions& options);

// The kernel's per-ray visibility (vertexCount × samples bytes, 1 = unoccluded).
std::vector<uint8_t> traceVisibility(Runtime& rt, const Mesh& mesh, const TransportOptions& options);

// The sample set: `samples` local directions (x, y, z; z along the normal),
// cosine-distributed, for `seed`.
std::vector<std::array<double, 3>> sampleDirectionsLocal(int samples, uint64_t seed);
std::vector<std::array<double, 3>> sampleDirectionsLocal(int samples, uint64_t seed, TransportSampler sampler);

// Vertices that cannot be occluded: no triangle has a point above the plane through
// the vertex's ray origin perpendicular to its normal n (all triangle vertices q with
// n·(q − p) ≤ ½ ε (n·n_g), ε the ray offset), so every ray of its hemisphere escapes.
// Conservative (a false "occludable" only costs rays). Tested with the BVH: a node whose
// box lies below the plane is skipped whole. One flag per vertex.
std::vector<uint8_t> unoccludableVertices(const Mesh& mesh);

// --- outputs (all atomic: a failure leaves no file) ---
// Each write* function has a *Bytes twin that returns the file's contents, so that a
// caller writing several outputs can produce them all before committing any.
std::string transportNpyBytes(const TransportResult& result);
std::string games202TransportBytes(const Mesh& mesh, const TransportResult& result);
std::string transportGltfBytes(const std::string& path, const Mesh& mesh, const TransportResult& result);
std::string transportSidecarBytes(const std::string& inputPath, const Mesh& mesh, const TransportOptions& options,
                                  const TransportResult& result);

// NumPy .npy, float32, shape [V, n²] or [V, 3, n²].
void writeTransportNpy(const std::string& path, const TransportResult& result);
// GAMES202 transport.txt: the vertex count, then one line of n² numbers per
// triangle corner in face order, in the framework's units (×π); single spaces,
// no trailing space, a final newline. Grey transport only (RGB: channel-mean is
// not meaningful, so it throws UsageError).
void writeGames202Transport(const std::string& path, const Mesh& mesh, const TransportResult& result);
// A copy of the input glTF (mesh.sourcePath) with VEC4 float attributes _PRT_T0,
// _PRT_T1, … (coefficients 4k..4k+3, zero-padded) on every primitive; RGB
// transport gets _PRT_R*, _PRT_G*, _PRT_B*. .glb output is binary, .gltf embeds
// its buffers. A primitive instanced by several nodes carries the first instance's
// transport.
void writeTransportGltf(const std::string& path, const Mesh& mesh, const TransportResult& result);
// The JSON sidecar: version, parameters, input SHA-256, conventions, sample counts,
// error summary, bounces, timings and device.
void writeTransportSidecar(const std::string& path, const std::string& inputPath, const Mesh& mesh,
                           const TransportOptions& options, const TransportResult& result);

// Per-vertex transport coefficients (docs/conventions.md "Transport"): grey [V, n²] or RGB [V, 3, n²],
// vertex-major, as written by `prtbake transport` (.npy) and TransportResult::coeffs.
struct TransportCoeffs {
  int order = 0;           // n: n² coefficients per channel
  int channels = 1;        // 1 (grey) or 3 (RGB)
  size_t vertexCount = 0;
  std::vector<float> coeffs;  // vertexCount × channels × order²
};

// Reads a transport .npy (float32 little-endian, C order, shape [V, n²] or [V, 3, n²]).
// Throws InputError(path, ...) for a missing or malformed file, another dtype or
// shape, a coefficient count that is not a square, or, when expectedVertices > 0,
// a vertex count other than the mesh's.
TransportCoeffs readTransportNpy(const std::string& path, size_t expectedVertices = 0);

// Reads the transport back from a glTF copy written by writeTransportGltf (the
// _PRT_T0, _PRT_T1, … or _PRT_R*/_PRT_G*/_PRT_B* VEC4 attributes of every primitive),
// for `mesh` loaded from that same file. The order is the largest n with n² ≤ 4 ×
// (attributes per channel): the zero padding of the last attribute is not read.
// Throws InputError(mesh.sourcePath, ...) when a primitive lacks the attributes or
// they disagree between primitives.
TransportCoeffs readTransportGltf(const Mesh& mesh);

}  // namespace prtbake
