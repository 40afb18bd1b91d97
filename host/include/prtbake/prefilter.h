// prtbake/prefilter.h: prefiltered specular environments (the split sum's first half).
//
// Definition (docs/conventions.md "Prefiltered specular"): for roughness r (α = r² unless a
// schedule says otherwise) level i of the chain holds, for each texel direction R,
//   P(R) = ∫ L(l) k(R·l) dl / ∫ k(R·l) dl,
//   k(μ) = D_α(h) · max(0, μ),  μ = R·l,  h = normalize(R + l),  N·H = √((1 + μ)/2),
// with D the lobe's distribution: GGX D ∝ 1/((N·H)²(α² − 1) + 1)², Charlie
// D ∝ sin^(1/α)θ_h (α clamped to kLutClothAlphaMin, as the LUT's cloth table), or for
// `lambertian` k = max(0, μ), which makes P the irradiance/π. Constant factors of D cancel
// in the ratio. Faces, order and orientation are docs/conventions.md "Cube faces"
// (+X, −X, +Y, −Y, +Z, −Z; row 0 at the top), the OpenGL/Vulkan/KTX one.
//
// Method (docs/prefilter.md): the environment's texels are gathered into a quadtree of
// cube-face bins (each bin keeps its flux, its solid angle and two centroids: the
// radiance-weighted and the solid-angle-weighted direction); for each tile of output
// texels the host picks a cut through that tree in which every bin is small compared
// with the lobe's local length scale (tolerance), and the kernel sums
//   P(R) ≈ Σ_b F_b k(R·c_b^L) / Σ_b Ω_b k(R·c_b^Ω)
// over the cut in float32. Every texel's flux enters exactly once, so no sample can miss or
// catch a sun (no fireflies); a constant environment gives the constant exactly. The
// r = 0 level is the source resampled to the level's size (area-weighted when minifying,
// bilinear when magnifying).
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "prtbake/envmap.h"
#include "prtbake/runtime.h"

namespace prtbake {

enum class PrefilterLobe { Ggx, Charlie, Lambertian };
enum class PrefilterSchedule { Linear, Filament, Babylon, Explicit };
// Cut: the exact sum over a tree cut (default). Sampled: the anchors' estimator (Filament
// cmgen, Khronos glTF-IBL-Sampler): `samples` Hammersley GGX half vectors per texel, each read
// from a box-filtered mip chain of the level-0 cube at the level Filament derives from the
// sample's pdf (K = 4), trilinear and seamless. Kept to measure against (GGX only).
enum class PrefilterMethod { Cut, Sampled };

// Limits accepted by validatePrefilterOptions.
constexpr int kPrefilterMaxSize = 8192;
constexpr int kPrefilterMaxLevels = 14;  // 8192 → 1
constexpr int kPrefilterMaxSamples = 1 << 20;

struct PrefilterOptions {
  PrefilterLobe lobe = PrefilterLobe::Ggx;
  PrefilterSchedule schedule = PrefilterSchedule::Linear;
  int baseSize = 256;                // level-0 face size (any size 1..kPrefilterMaxSize)
  int levels = 0;                    // 0: the default (down to 16², or to 1² for bases ≤ 16)
  std::vector<double> roughness;     // Explicit: one perceptual roughness per level, in [0, 1]
  // Cut: the target for every level's estimated 99th-percentile relative error. Each level
  // starts with a per-bin error bound of 2 × tolerance (prefilter_cut.cpp) and halves it,
  // up to three times, while its error estimate misses the target.
  double tolerance = 0.01;
  PrefilterMethod method = PrefilterMethod::Cut;
  int samples = 1024;                // Sampled only
  // Tuning knob: texels per work-item of the cut kernel (1, 8 or 16; 0: 16 on CPUs, 1 on GPUs).
  int vectorWidth = 0;
  // Per level, recompute a spread subset of tiles with a quarter of the per-bin error bound
  // and report the change (the error estimate, which also drives the tolerance). Off: one
  // pass per level at 2 × tolerance and no estimate.
  bool errorEstimate = true;
};

// One level of a schedule. Sizes halve from the base: size_i = max(1, base >> i).
struct PrefilterLevelSpec {
  int size = 0;
  double roughness = 0;  // perceptual roughness an engine looks this level up with
  double alpha = 0;      // the lobe's α (r² except for babylon: r² + 0.0005 = alphaG)
};

const char* toString(PrefilterLobe lobe);
const char* toString(PrefilterSchedule schedule);
const char* toString(PrefilterMethod method);
// Parse "ggx" etc.; throw UsageError naming `subject` on anything else.
PrefilterLobe parsePrefilterLobe(const std::string& text, const std::string& subject = "--lobe");
PrefilterSchedule parsePrefilterSchedule(const std::string& text, const std::string& subject = "--schedule");
PrefilterMethod parsePrefilterMethod(const std::string& text, const std::string& subject = "--method");

// Throws UsageError for a base size outside [1, kPrefilterMaxSize], a level count outside
// [1, floor(log2 base) + 1], roughness values outside [0, 1] or given without the explicit
// schedule, a tolerance outside [1e-4, 0.1], samples outside [1, kPrefilterMaxSamples], or the
// sampled method with another lobe than GGX; InputError (subject "--size") when the chain
// would not fit in the input memory limit (prtbake/limits.h).
void validatePrefilterOptions(const PrefilterOptions& options);

// The schedule's levels (validates first):
//   linear    r_i = i/(n − 1) (Khronos IBL sampler, glTF-Sample-Viewer), α = r²
//   filament  lod i of n ↔ r(2 − r) = i/(n − 1): r_i = 1 − √(1 − i/(n − 1)), α = r²
//   babylon   the glTF EXT_lights_image_based loader's LOD mapping: lod = log2(size·α_G)·(n − 1)/log2(size),
//             so level i is filtered with α_G = size^(i/(n−1) − 1) and read by roughness
//             r = √max(0, α_G − 0.0005) (Babylon's α_G = r² + 0.0005)
//   explicit  r_i from options.roughness, α = r²
// One level (n = 1): r = 0 (babylon: α_G = 1/size).
std::vector<PrefilterLevelSpec> prefilterLevels(const PrefilterOptions& options);

// Per-level error estimate: relative change |P − P'|/P' (max over channels) when about 1024
// texels per face (16 leaves of 8×8 or 4 of 16×16) are recomputed with a quarter of the
// per-bin error bound, scaled by 4/3 (the cut's error is of second order in the bins' size: it falls 4× when their radius
// halves). Zero for r = 0 levels (resampling).
struct PrefilterErrorEstimate {
  double mean = 0, p99 = 0, max = 0;
  size_t texels = 0;     // texels compared
};

struct PrefilterLevel {
  PrefilterLevelSpec spec;
  double alphaUsed = 0;             // α after the floor (narrower than a source texel) or clamp (Charlie)
  std::vector<float> rgb;           // 6 × size × size × 3, face-major, row 0 on top
  PrefilterErrorEstimate error;
  size_t binsSummed = 0;            // over all texels (cut) or samples taken (sampled)
  double binTolerance = 0;          // the per-bin error bound of the last pass (cut)
  int passes = 0;                   // cut passes (1 + the times the bound was halved)
  double kernelSeconds = 0, cutSeconds = 0, estimateSeconds = 0;
};

struct PrefilterResult {
  PrefilterOptions options;
  std::vector<PrefilterLevel> levels;
  int binFaceSize = 0;              // the finest bins' face size (cut)
  double alphaFloor = 0;            // lobes narrower than this are widened to it
  long long sourceTexels = 0;
  std::string device;
  double binSeconds = 0, resampleSeconds = 0, kernelSeconds = 0, buildSeconds = 0, totalSeconds = 0;
};

// Prefilters `env` (any layout; yaw applied) into the schedule's levels on the device.
// Deterministic: the same inputs and options give the same bits on the same device.
PrefilterResult prefilterEnvironment(Runtime& rt, const EnvMap& env, const PrefilterOptions& options);

// prefilterEnvironment of loadEnvironment(path, loadOptions) with yawDegrees, except that a
// lat-long OpenEXR file of more than one band is read a band of rows (about bandBytes of float
// texels) at a time (forEachLatLongBand) and never held whole: each band is added to the
// finest bins' sums (80 bytes per finest bin; the tree they give is buildBinTree's, to the
// bit) and to the r = 0 resamplings (double sums per output texel while its lookups span
// bands), then dropped. Every level is then the same bits as the whole map's, except r = 0
// texels whose lookups straddle two bands: their double sums are added in another order
// (at most one float ulp apart, 2⁻²³ relative). Invalid texels are refused (or clamped) as
// loadEnvironment does, counted over the whole file, before any level is computed.
// *env receives the map's description (layout, size, files, clamped texels, yaw), and its
// texels only when it was read whole. `runtime` is called once the texels are read and the
// bin tree is built. The result's totalSeconds counts the bands' reading too.
PrefilterResult prefilterEnvironmentFile(const std::function<Runtime&()>& runtime, const std::string& path,
                                         const EnvLoadOptions& loadOptions, double yawDegrees,
                                         const PrefilterOptions& options, EnvMap* env,
                                         size_t bandBytes = size_t(32) << 20);

// The r = 0 resampling of `env` onto an n×n cube (what level 0 of a linear chain holds):
// each texel averages S×S bilinear lookups at its subtexel centres, S = the ratio of the
// texel's angular size to the source's, rounded up. Double precision, host threads.
std::vector<float> resampleEnvironment(const EnvMap& env, int n);

// Double-precision brute force: the definition as a normalised sum over every texel t of
// `env` with exact solid angles, P(R) = Σ L_t k(R·ω_t) Ω_t / Σ k(R·ω_t) Ω_t, at each unit
// direction of `dirs` (x, y, z triples). RGB triples out. Host threads.
std::vector<double> prefilterBruteForce(const EnvMap& env, PrefilterLobe lobe, double alpha,
                                        const std::vector<double>& dirs);

// The lobe k(μ) in double, scaled so that its maximum is 1 (GGX: k(1) = 1; Charlie: its
// peak; lambertian: k(1) = 1). α as used (no floor or clamp applied here).
double prefilterLobeWeight(PrefilterLobe lobe, double alpha, double mu);

// Cube texel (face, row, col) of an n×n cube in docs/conventions.md "Cube faces" seen in unit
// direction `d`: the face whose axis is largest, then u, v. Returns face·n² + row·n + col.
size_t cubeTexelIndex(int n, const double d[3]);
// Unit direction of the centre of texel (face, row, col) of an n×n standard cube.
void cubeTexelCenter(int n, int face, int row, int col, double d[3]);

// Writers. The sidecar (JSON) states the definition, lobe, schedule, per-level roughness,
// α, size and error estimate, the conventions, the input hashes and the timings;
// `metaJson` (an object as text) is merged in.
std::string prefilterSidecarText(const PrefilterResult& result, const EnvMap& env, const std::string& metaJson);
// KTX 2.0: one cube (faceCount 6) with every level, VK_FORMAT_R16G16B16A16_SFLOAT (default;
// values beyond the half range are clamped to ±65504 and counted) or R32G32B32A32_SFLOAT,
// alpha 1, the Basic data format descriptor (RGBSDA, BT.709 primaries, linear), KTXwriter.
struct Ktx2Stats {
  long long clampedToHalf = 0;
};
std::string prefilterKtx2Bytes(const PrefilterResult& result, bool float32, Ktx2Stats* stats = nullptr);
// OpenEXR: one tiled, mip-mapped (ROUND_DOWN) cube map (envmap attribute ENVMAP_CUBE, faces
// laid out as ImfEnvmap.h defines), channels R, G, B (float32, or half). The levels of the
// schedule come first; OpenEXR's chain continues down to 1×1, and those further levels are
// 2×2 box filters of the level above (attribute prtbake:prefilteredLevels says how many are
// prefiltered). Needs a power-of-two base (OpenEXR's level sizes must stay N × 6N).
void writePrefilterExr(const std::string& path, const PrefilterResult& result, bool half);
// Writes the outputs whose paths are not empty: the sidecar first, then KTX2, then OpenEXR,
// each atomically; when one fails, those already written by this call are removed again.
void writePrefilterFiles(const PrefilterResult& result, const EnvMap& env, const std::string& jsonPath,
                         const std::string& ktx2Path, bool ktx2Float32, const std::string& exrPath, bool exrHalf,
                         const std::string& metaJson);

}  // namespace prtbake
