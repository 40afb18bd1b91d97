// prtbake/lightmap.h: per-texel lighting data on a mesh's lightmap UVs (docs/lightmap.md).
//
// A W × H lightmap over one UV set of the mesh (glTF's convention: texel (x, y) covers
// u ∈ [x, x + 1]/W, v ∈ [y, y + 1]/H, row 0 at v = 0, the image's top). Each texel that a
// triangle touches, even where its centre lies outside it (conservative rasterisation), is
// baked at one point on that triangle: its centre where a triangle contains it, else the
// point of the nearest touching triangle nearest to it, pulled just inside. Per texel sample
// p with shading normal n (interpolated from the vertices) the products are those of the
// per-vertex transport (prtbake/transport.h, docs/conventions.md "Transport") at p:
//   ao          A(p) = (1/π) ∫_{n·ω>0} V_D(p, ω) (n·ω) dω, V_D: no occluder nearer than
//               the maximum distance D (none: the whole scene); 1 for an open plane.
//   bent        the cosine-weighted mean unoccluded direction (unit; object space):
//               B ∝ ∫ V_D(p, ω) (n·ω) ω dω, from the order-2 transport; n where all is occluded.
//               When the mesh has tangents (glTF TANGENT), also in tangent space: (B·t, B·b, B·n)
//               with t the interpolated tangent made orthogonal to n and b = w n × t (glTF's
//               bitangent), the frame a normal map's and Filament's bentNormal input use.
//   irradiance  E(p)/π = Σ_i l_i T_i(p) per linear RGB channel under the environment's radiance
//               coefficients l (shadowed, or interreflected with `bounces`): the exit radiance
//               of a white Lambertian surface.
//   sh          directional irradiance: per linear RGB channel the SH coefficients (order m = 2,
//               L1, 4 of them; or m = 3, L2, 9) D_j = (Â_l/π) ∫_{n·ω>0} L_p(ω) Y_j(ω) dω of the light
//               L_p reaching p from above its tangent plane: the environment's radiance where
//               nothing blocks it (order n), and with `bounces` the exit radiance of the diffuse
//               surfaces hit there (their transport of B − 1 bounces), so that a normal n′ (a
//               normal map's) shades E(p, n′)/π ≈ Σ_j D_j Y_j(n′): the clamped cosine truncated
//               at order m; at n′ = n this approximates the irradiance product. The glossy
//               transfer matrices' estimator (prtbake/glossy.h) at the texels: D = diag(Â/π) M l.
//   transport   T_i(p) of order n (grey, or RGB with coloured interreflection), so that the
//               lighting can change at run time: L_o = ρ Σ_i l_i T_i.
//
// Repairs: a sample inside closed geometry (a floor texel under a wall) is moved out through
// the nearest back face met by rays in its tangent plane as long as half its texel (Godot's
// "unocclude": the texel's own area reaches outside); one that finds no way out that near
// and sees a back face along its normal is marked buried (baked there: dark). Empty texels within `dilation`
// texels of baked ones take their neighbours' mean, ring by ring, so that bilinear and mip
// lookups near a chart's edge read no unbaked texel. Then the seams are stitched: where one
// edge of the surface lies on two UV edges, the texels both sides read are adjusted in the
// least-squares sense (the data held near its values, the bilinear lookups of the two sides
// along the seam made to agree), so that no seam shows.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "prtbake/mesh.h"
#include "prtbake/runtime.h"
#include "prtbake/sh.h"
#include "prtbake/transport.h"

namespace prtbake {

constexpr int kMaxLightmapSize = 16384;

enum LightmapProduct : unsigned {
  kLightmapAo = 1u,
  kLightmapBent = 2u,
  kLightmapIrradiance = 4u,
  kLightmapTransport = 8u,
  kLightmapSh = 16u,
  // Not a product to ask for: bent's image in tangent space (meshes with tangents).
  kLightmapBentTangent = 32u,
};
constexpr unsigned kLightmapAllProducts = 31u;
// "ao,bent,irradiance,transport,sh" (any subset, comma-separated) → bits; UsageError otherwise.
unsigned parseLightmapProducts(const std::string& list);
std::string lightmapProductsName(unsigned products);

struct LightmapOptions {
  int uvSet = -1;              // the UV set (TEXCOORD_k); −1: 1 where the mesh has it, else 0
  int size = 0;                // W = H; 0: from texelsPerUnit
  double texelsPerUnit = 0;    // texels per world unit along each side (size = that × √(surface
                               // area / UV area), rounded up to a multiple of 4); 0 with size 0: 512
  unsigned products = kLightmapAo;
  int samples = 256;           // rays per texel
  double tolerance = 0;        // > 0: the transport's --tolerance (prtbake/tolerance.h) per pass
  int toleranceMaxSamples = 65536;
  uint64_t seed = 0;
  int order = 3;               // SH order of transport and of the irradiance's environment (1..8;
                               // with sh: 1..6, the glossy transfer's input orders)
  int shOrder = 3;             // sh: 2 (L1: 4 coefficients) or 3 (L2: 9); `samples` rays per texel
                               // (the tolerance does not apply to it)
  double maxDistance = 0;      // ao and bent: the occluders' range D (0: the whole scene)
  int bounces = 0;             // irradiance and transport: interreflections (0: shadowed)
  std::optional<std::array<float, 3>> albedoOverride;
  int dilation = 8;            // rings of texels filled around the charts (0: none)
  bool unocclude = true;       // move samples out of closed geometry
  bool stitchSeams = true;     // least-squares agreement of the two sides of every UV seam
  int packetWidth = -1;        // the transport kernels' packet width (0: one ray at a time; −1: by the device)
  // A shard of a split bake: {first, count} of the samples in lightmapSamples' order. Only those
  // are baked (each with the rays it takes in the whole bake), the other texels stay Empty and
  // nothing is repaired: repairLightmap runs once on the assembled map. Not with tolerance.
  std::optional<std::pair<size_t, size_t>> sampleRange;
};

// The base colour textures too where bounces light the surfaces (no albedo override).
inline MeshAlbedo meshAlbedo(const LightmapOptions& o) {
  return o.bounces > 0 && !o.albedoOverride ? MeshAlbedo::Textures : MeshAlbedo::Factors;
}

// Texel states (LightmapResult::state).
enum class TexelState : uint8_t { Empty = 0, Baked = 1, Moved = 2, Buried = 3, Dilated = 4 };

struct LightmapResult {
  int width = 0, height = 0, uvSet = 0;
  unsigned products = 0;
  std::vector<uint8_t> state;       // W × H TexelState, row 0 first
  std::vector<float> ao;            // W × H
  std::vector<float> bent;          // W × H × 3
  std::vector<float> bentTangent;   // W × H × 3, bent in tangent space (empty: no tangents)
  std::vector<float> irradiance;    // W × H × 3 (E/π, linear RGB)
  std::vector<float> transport;     // W × H × channels × order²
  std::vector<float> sh;            // W × H × shOrder² × 3: per coefficient j, R G B
  int order = 0, transportChannels = 1, shOrder = 0;
  size_t baked = 0, moved = 0, buried = 0, dilated = 0;  // texels of each state
  size_t centreOutside = 0;         // baked texels whose centre no triangle contains
  size_t charts = 0, degenerateTriangles = 0;
  size_t contested = 0;             // texels touched by two charts (none contains the centre)
  size_t seamEdges = 0;             // surface edges whose sides lie on different UV edges
  double seamJumpBefore = 0, seamJumpAfter = 0;  // the largest jump across them (first product)
  int samples = 0;
  uint64_t rays = 0;
  double maxStdError = 0, meanStdError = 0;  // the transport's standard error of the AO pass
  double rasterSeconds = 0, unoccludeSeconds = 0, bakeSeconds = 0, repairSeconds = 0, totalSeconds = 0;
  std::string device;
  size_t texels() const { return size_t(width) * size_t(height); }
  bool valid(size_t i) const {
    const auto s = TexelState(state[i]);
    return s == TexelState::Baked || s == TexelState::Moved;
  }
};

// The lightmap's size for the options and mesh (options.size, or from texelsPerUnit).
// Throws UsageError for a size outside [1, kMaxLightmapSize], InputError (naming the mesh) for
// a missing UV set or non-finite UVs.
int lightmapSize(const Mesh& mesh, const LightmapOptions& options);

// The estimated peak memory in bytes of a bake of `options`' products at width x height (errs
// high); lightmapSamples refuses a size whose estimate exceeds the memory the process can have
// (checkProcessMemory, prtbake/limits.h) with a UsageError naming --size or --texels-per-unit.
double lightmapPeakBytes(const LightmapOptions& options, int width, int height);

// The bake's first stage, without a device: the UV checks, the charts, the conservative
// rasterisation and each touched texel's sample. Throws as computeLightmap does for the mesh
// and UVs (and UsageError for the size).
struct LightmapSamples {
  LightmapResult lm;                 // size, UV set, state (Baked where a sample lies, else Empty), counts
  SurfacePoints points;              // one sample per baked texel: position, shading and face normals
  std::vector<uint32_t> texelOf;     // the texel (y·W + x) of each sample
  std::vector<float> reach;          // half the texel's width in world units at each sample
  std::vector<float> tangentFrames;  // 6 per sample (t, b) where the mesh has tangents, else empty
  std::vector<char> usable;          // per triangle: positive area in UV and in space
};
LightmapSamples lightmapSamples(const Mesh& mesh, const LightmapOptions& options);

// Bakes the products asked for under the environment's radiance coefficients (irradiance).
// Throws UsageError for bad options; InputError naming the mesh for a missing UV set, UVs
// that are not finite, no triangle of positive UV area, or overlapping charts (a texel
// centre inside triangles of two charts, or strictly inside two triangles of one chart: UVs
// stacked or folded; charts: triangles joined by edges whose UV coordinates agree), naming
// the texel and the two triangles.
LightmapResult computeLightmap(Runtime& rt, const Mesh& mesh, const ShCoeffs& environment,
                               const LightmapOptions& options);

// The repairs computeLightmap ends with (dilation, seam stitching, bent normals made unit again),
// for a map assembled from the shards of a split bake; `usable`: lightmapSamples(mesh, options).usable.
void repairLightmap(const Mesh& mesh, const LightmapOptions& options, const std::vector<char>& usable,
                    LightmapResult& lightmap);

// --- outputs (*Bytes: the file's contents; the command writes them atomically) ---
// OpenEXR of one product: ao "Y"; bent and irradiance "R", "G", "B"; transport "T0" … (grey)
// or "R.T0" …, "G.T0" …, "B.T0" …; sh "SH0.R", "SH0.G", "SH0.B", "SH1.R" … (one RGB layer per
// coefficient); and "A": 1 where the texel's sample is valid (baked or
// moved), 0 elsewhere (empty, buried, dilated). Half or float.
std::string lightmapExrBytes(const LightmapResult& lm, LightmapProduct product, bool half);
// KTX 2.0, RGBA16F, one level, of ao (R = G = B = A(p)), bent or irradiance, A as the EXR's.
std::string lightmapKtx2Bytes(const LightmapResult& lm, LightmapProduct product);
// PNG of the AO, grey, 8 or 16 bits, linear values (as glTF's occlusionTexture reads them).
std::string lightmapAoPngBytes(const LightmapResult& lm, int bits);
// A copy of the input glTF (mesh.sourcePath) whose materials use the AO (its 8-bit PNG, embedded)
// as the core occlusionTexture on texCoord = the lightmap's UV set, so that any glTF viewer shows
// it; a baked primitive without a material gets a default one. `path`'s extension picks .glb
// (binary) or .gltf (buffers as data URIs). UsageError without ao or for a mesh that is not glTF.
std::string lightmapGltfBytes(const std::string& path, const Mesh& mesh, const LightmapResult& lm);
// The sidecar JSON: parameters, conventions, counts, samples, errors, timings.
std::string lightmapSidecarBytes(const std::string& inputPath, const LightmapOptions& options,
                                 const LightmapResult& lm);

// A split bake's shard (computeLightmap with sampleRange) as a float32 .npy of one row per sample of
// the range, in order: the texel's state, then the values of every product the result holds, in
// the order ao, bent, bent_tangent, irradiance, transport, sh. `texelOf`: lightmapSamples' texels;
// {first, count}: the shard's sampleRange.
std::string lightmapRangeNpyBytes(const LightmapResult& part, const std::vector<uint32_t>& texelOf, size_t first,
                                  size_t count);
// Scatters such rows (`rows` × `columns` floats) for the samples [first, first + rows) into `lm`,
// whose planes are already sized as the shards' results hold them. Throws InputError naming
// `path` when the columns or the range do not fit.
void addLightmapRange(LightmapResult& lm, const std::vector<uint32_t>& texelOf, size_t first, const std::vector<float>& values,
                      size_t rows, size_t columns, const std::string& path);

// Reads back what prtbake lightmap wrote to `dir`: the UV set from lightmap.json and every
// product whose OpenEXR is there (ao, bent, bent_tangent, irradiance, sh, transport), all of one
// size. The state comes from each texel's A: valid (1) is Baked; otherwise Dilated where any
// product holds a non-zero value, else Empty. Counts, samples and timings are not read. Throws
// InputError naming the file for a missing sidecar or no product, sizes that differ, or channels
// that are not the product's.
LightmapResult readLightmap(const std::string& dir);

}  // namespace prtbake
