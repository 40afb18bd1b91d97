// prtbake/probes.h: light probe grids, SH radiance at points in space (docs/probes.md).
//
// A grid of NX × NY × NZ probes fills an axis-aligned box (the bounds) with one cell per
// probe and each probe at its cell's centre, as three.js's LightProbeGrid places them:
//   p(i, j, k) = min + ((i + ½) sx, (j + ½) sy, (k + ½) sz),  s = (max − min) / (NX, NY, NZ).
// Each probe holds the radiance arriving at its position, projected to real SH of order n
// (docs/conventions.md, "SH basis"), per linear RGB channel:
//   P_i = ∫_S² L(p, ω) Y_i(ω) dω,
// L(p, ω) the environment's radiance where the ray from p along ω escapes the scene, the
// exit radiance of the surface it hits first when that is a front face (with bounces:
// ρ(q) Σ_j l_j T_j(q), T the per-vertex transport of bounces − 1 interreflections, see
// transport.h; without: 0), and 0 at a back face. An empty scene gives P = l, the
// environment's own coefficients.
//
// Estimator: a product quadrature (Gauss–Legendre in cos θ × uniform in φ, exact for
// spherical polynomials of the degree the environment and the probe's order need), turned
// by a random rotation per probe; a probe that sees no geometry gets l to float precision,
// a probe that sees only geometry gets none of the environment.
//
// Validity: a probe whose rays hit back faces in more than `backfaceLimit` of its rays is
// inside geometry. It is moved to the nearest free point within `relocateFraction` of its
// cell (candidates on a lattice, tested with a pilot); where none is free it is marked
// invalid and filled with the mean of its valid neighbours (repeatedly, so that a block of
// invalid probes fills from its rim).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "prtbake/mesh.h"
#include "prtbake/runtime.h"
#include "prtbake/sh.h"
#include "prtbake/tolerance.h"

namespace prtbake {

constexpr int kMaxProbesPerAxis = 1024;
constexpr size_t kMaxProbes = size_t(1) << 22;  // 4 M probes: 450 MB of L2 coefficients

struct ProbeGridLayout {
  std::array<int, 3> resolution{};          // NX, NY, NZ
  std::array<double, 3> boundsMin{}, boundsMax{};
  std::array<double, 3> cell() const;       // (max − min) / resolution
  std::array<double, 3> probePosition(int i, int j, int k) const;
  size_t count() const { return size_t(resolution[0]) * resolution[1] * resolution[2]; }
};

struct ProbeOptions {
  // Either resolution (every entry ≥ 1) or spacing (> 0: NX = max(1, round(size_x / spacing)), …).
  std::optional<std::array<int, 3>> resolution;
  double spacing = 0;
  // The box; unset: the mesh's bounding box.
  std::optional<std::array<double, 3>> boundsMin, boundsMax;
  int order = 3;              // 2 (L1, 4 coefficients) or 3 (L2, 9)
  int samples = 256;          // rays per probe (rounded to the quadrature's rings × segments)
  // "--tolerance E" (0: off, `samples` is used): the count that brings 95 % of the probes'
  // coefficients within E × the environment's l_0 (its mean over the channels), predicted from a
  // pilot over at most 128 probes spread through the grid (prtbake/tolerance.h), capped at
  // toleranceMaxSamples.
  double tolerance = 0;
  int toleranceMaxSamples = 65536;
  uint64_t seed = 0;
  int bounces = 1;            // 0: surfaces are black; B ≥ 1: lit with B − 1 interreflections
  int transportSamples = 256; // rays per vertex of the surfaces' transport (bounces ≥ 1)
  std::optional<std::array<float, 3>> albedoOverride;
  double backfaceLimit = 0.25;     // fraction of back-face hits that marks a probe inside geometry
  double relocateFraction = 0.45;  // the farthest move, as a fraction of the smallest cell side (0: never)
  // InputError when the scene's bounding box does not meet the bounds (a mistake in a command or
  // job: the grid would see only the environment); false lets
  // a library caller bake an empty scene (the environment at every probe).
  bool requireGeometry = true;
  // The probes [firstProbe, firstProbe + probeCount) of the grid (x fastest; unset: to the
  // last), traced and relocated as in a whole run: each probe's rays depend only on its index
  // and the seed, so a range's probes are bit-identical to the same probes of a whole run on the
  // same device. The fill of invalid probes needs their neighbours, so a range leaves them as
  // traced (state 2); fillInvalidProbes completes a grid assembled from ranges.
  size_t firstProbe = 0;
  std::optional<size_t> probeCount;
  // Rays per packet: 16 (a probe's rays 16 at a time over the wide BVH) or 0 (one at a time;
  // the results agree up to float summation order); −1: by the device, as for the transport.
  int packetWidth = -1;
  // Work-items per probe of the one-ray kernel, as TransportOptions::rayLanes (−1: 1 on a CPU
  // device, 32 elsewhere).
  int rayLanes = -1;
};

// The base colour textures too where the surfaces are lit (bounces ≥ 1, no albedo override).
inline MeshAlbedo meshAlbedo(const ProbeOptions& o) {
  return o.bounces > 0 && !o.albedoOverride ? MeshAlbedo::Textures : MeshAlbedo::Factors;
}

struct ProbeGridResult {
  ProbeGridLayout layout;
  int order = 0;
  size_t firstProbe = 0;                // the range computed (ProbeOptions::firstProbe)
  size_t probeCount = 0;                // probes held: the range's size (the whole grid by default)
  // probeCount × order² × 3 floats, probe-major with x fastest, then y, then z ([NZ][NY][NX][n²][3]).
  std::vector<float> coeffs;
  std::vector<float> positions;         // count × 3: where each probe was baked (moved ones included)
  std::vector<uint8_t> state;           // count: 0 valid, 1 moved, 2 invalid (filled from neighbours)
  std::vector<float> backfaceFraction;  // count: at the position it was baked at
  size_t moved = 0, invalid = 0;
  int fillPasses = 0;                   // passes of the neighbours' fill
  int samples = 0, rings = 0, segments = 0;
  uint64_t rays = 0;
  int environmentOrder = 0;
  double bvhSeconds = 0, surfaceSeconds = 0, traceSeconds = 0, relocateSeconds = 0, totalSeconds = 0;
  std::string device;
  std::vector<ToleranceReport> tolerance;  // with --tolerance: what the pilot found (one entry)

  const float* probe(size_t index) const { return coeffs.data() + index * size_t(order) * order * 3; }
};

// The grid's layout from the options and the mesh's bounds; throws UsageError for empty or
// inverted bounds, a resolution of 0 or over the limits, InputError for a scene outside the
// bounds (unless options.requireGeometry is false).
ProbeGridLayout probeGridLayout(const Mesh& mesh, const ProbeOptions& options);

// Bakes the grid under the environment's radiance coefficients `environment` (any order).
// Throws UsageError for bad options, InputError when the scene lies outside the bounds.
ProbeGridResult computeProbeGrid(Runtime& rt, const Mesh& mesh, const ShCoeffs& environment,
                                 const ProbeOptions& options);

// Fills every invalid probe (state 2) of a whole grid with the mean of its valid (or already
// filled) face neighbours, pass after pass; sets and returns grid.fillPasses.
int fillInvalidProbes(ProbeGridResult& grid);

// The irradiance over π (the diffuse exit radiance for albedo 1) that the grid gives at
// point x for normal n: the probes' coefficients trilinearly interpolated (clamped at the
// outermost probes' centres), convolved with the clamped cosine and evaluated at n.
std::array<double, 3> probeGridIrradianceOverPi(const ProbeGridResult& grid, const std::array<double, 3>& x,
                                                const std::array<double, 3>& n);

// --- outputs (atomic; *Bytes twins return the contents) ---
// NumPy .npy, float32, shape [NZ, NY, NX, n², 3].
std::string probeGridNpyBytes(const ProbeGridResult& grid);
// A range's probes (a shard of a split job) as a 2-D .npy, one row per probe: its n² × 3
// coefficients, then its position (3), state and back-face fraction; and those rows appended
// to a grid being assembled (its order set).
constexpr size_t kProbeRangeExtraColumns = 5;
std::string probeRangeNpyBytes(const ProbeGridResult& range);
void appendProbeRange(ProbeGridResult& grid, const std::vector<float>& rows, size_t count);
// The sidecar JSON: parameters, layout, conventions, validity (every moved and invalid probe),
// sample counts and timings.
std::string probeGridSidecarBytes(const std::string& inputPath, const ProbeOptions& options,
                                  const ShCoeffs& environment, const std::string& environmentPath,
                                  const ProbeGridResult& grid);

// --- three.js ---
// The grid for three.js r187's LightProbeGridWebGL (examples/jsm/lighting), which holds L2
// radiance SH in three's basis, that of prtbake without the Condon–Shortley phase:
// k_lm = c_lm · (−1)^m (shCondonShortleyPhase), i.e. coefficients 1, 3, 5, 7 negated; the
// shader convolves with the clamped cosine itself. Only order-3 grids can go to three.js:
// other orders throw UsageError("--target", …). docs/probes.md "three.js".
//
// The KTX 2.0 file of its atlas: one 3D texture, RGBA16F (VK_FORMAT_R16G16B16A16_SFLOAT, linear,
// no supercompression, one level), NX × NY × 7 (NZ + 2) texels. Sub-volume t = 0 … 6 holds slices
// t (NZ + 2) … t (NZ + 2) + NZ + 1: a copy of probe slice 0, the NZ probe slices k = 0 … NZ − 1,
// a copy of slice NZ − 1. Texel (i, j) of a slice is probe (i, j); its four components are the
// numbers 4t … 4t + 3 of the 27 (k_0.r, k_0.g, k_0.b, k_1.r, …, k_8.b) and a 0 after them.
std::string probeGridThreejsKtx2Bytes(const ProbeGridResult& grid);
// An ES module for three.js r187 that exports `loadProbeGrid(renderer, scene[, url])`: it loads the
// atlas (`ktx2Name`, beside the module unless `url` says otherwise) with three's KTX2Loader, makes
// the LightProbeGridWebGL of the grid's bounds and resolution (not baked), adds it to `scene`
// and resolves to it. The page's import map must resolve 'three' and 'three/addons/'.
std::string probeGridThreejsLoaderBytes(const ProbeGridResult& grid, const std::string& ktx2Name);

}  // namespace prtbake
