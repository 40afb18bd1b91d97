// prtbake/lut.h: split-sum BRDF lookup tables for image-based lighting.
//
// Conventions (DESIGN.md "BRDF LUT"): μ = N·V in [0, 1], perceptual roughness r in
// [0, 1] with α = r² (or α = r with alphaDirect). For f0 = 1 Fresnel-Schlick split
// F = (1 − F_c) + F_c with F_c = (1 − V·H)^5, the table holds
//   A(μ, r) = ∫ f_r (1 − F_c)/F cos θ_l dω_l,   B(μ, r) = ∫ f_r F_c/F cos θ_l dω_l,
// so that the directional albedo of the BRDF with Fresnel-Schlick(f0, f90) is f0·A + f90·B.
// Texel (i, j) of an N×N table holds μ = (i + 0.5)/N, r = (j + 0.5)/N; row j = 0
// (smallest roughness) comes first in memory and in the file.
//
// Optional tables (one third channel in the EXR "B" slot):
//   multiscatter  E(μ, r) = A + B, Filament's DFG.y; the runtime compensates energy with
//                 f_ms = f_ss · (1 + f0 (1/E − 1))            (Fdez-Agüera 2019, Filament)
//   cloth         C(μ, r) = ∫ D_Charlie V_Ashikhmin cos θ_l dω_l  (Estevez–Kulla 2017,
//                 Neubelt 2013), α clamped to ≥ kLutClothAlphaMin as Filament does
// and the Kulla–Conty tables (extra named EXR channels "E" and "Eavg"):
//   E(μ, r) = A + B,  E_avg(r) = 2 ∫_0^1 E(μ, r) μ dμ (midpoint rule over the N columns).
#pragma once

#include <string>
#include <vector>

namespace prtbake {

class Runtime;

enum class LutNdf { Ggx, Beckmann };
enum class LutVisibility { SmithCorrelated, SmithSeparable, SchlickGgx };
// How the kernel turns its low-discrepancy points into directions: a table
// computed on the host in double (default), or sin/cos in the kernel, precise or
// native (the latter two exist to measure what each choice costs).
enum class LutDirections { Table, PreciseTrig, NativeTrig };

// Filament's smallest cloth α (MIN_ROUGHNESS = 0.007921); the Charlie NDF
// sin^(1/α) θ has no usable limit at α = 0.
constexpr double kLutClothAlphaMin = 0.007921;
// Sizes and sample counts accepted by validateLutOptions.
constexpr int kLutMaxSize = 8192;
constexpr int kLutMaxSamples = 1 << 20;

struct LutOptions {
  int size = 128;       // N: the table is N×N
  int samples = 1024;   // samples per texel (Hammersley points)
  LutNdf ndf = LutNdf::Ggx;
  LutVisibility visibility = LutVisibility::SmithCorrelated;
  bool alphaDirect = false;   // roughness axis holds α itself instead of r (α = r²)
  bool multiscatter = false;  // third channel: E = A + B
  bool cloth = false;         // third channel: the Charlie/Ashikhmin cloth table
  bool kullaConty = false;    // extra channels E and Eavg
  bool fastMath = false;      // -cl-fast-relaxed-math and native sqrt/rsqrt/divide
  LutDirections directions = LutDirections::Table;
  // Adaptive cubature ("--tolerance E"; 0: off, `samples` is used). Each texel's
  // integrals are taken over the smooth pieces of the half-vector domain of the double
  // reference (evaluateLutReference), each split into square cells (kLutRootCells² at
  // first). A cell carries its 3×3 Gauss–Legendre value Q and its four children's values;
  // it contributes the children's sum and estimates its error by max over channels
  // |Q − Σ children| (the error of the coarser rule: pessimistic; for a root cell at
  // least a quarter of the children's summed distance from the quadrants of Q's own
  // interpolant, against chance agreement of Q and Σ children). The cells with the
  // largest estimates are split until the texel's sum of estimates is below `tolerance`,
  // or until the next split would pass toleranceMaxSamples integrand evaluations
  // (counted at the cap). Channels: A, B and cloth when requested (E = A + B is then
  // below 2·tolerance). Samples are integrand evaluations. Deterministic.
  double tolerance = 0;
  int toleranceMaxSamples = 65536;
};

// Cells per side of each piece of a texel's domain before any split (see
// LutOptions::tolerance); the root cells cost 5 squares × 9 evaluations each.
constexpr int kLutRootCells = 2;
// The least --max-samples with --tolerance: room for the root cells of the specular and
// the cloth pieces (720 evaluations) and one split (144).
constexpr int kLutToleranceMinSamples = 1024;

// Throws UsageError (subject "--size", "--samples", ...) for a size outside
// [1, kLutMaxSize], samples outside [1, kLutMaxSamples], or both cloth and multiscatter.
void validateLutOptions(const LutOptions& options);

// Parses "ggx"/"beckmann", "smith-correlated"/"smith-separable"/"schlick-ggx";
// throws UsageError naming `subject` for anything else.
LutNdf parseLutNdf(const std::string& text, const std::string& subject = "--ndf");
LutVisibility parseLutVisibility(const std::string& text, const std::string& subject = "--visibility");
const char* lutNdfName(LutNdf ndf);
const char* lutVisibilityName(LutVisibility vis);

// α for a roughness value under `options` (r² or r).
double lutAlpha(const LutOptions& options, double roughness);

// One evaluation point: μ = N·V and roughness r (the table's axes), both in [0, 1].
struct LutPoint {
  double mu = 1.0;
  double roughness = 0.5;
};

// Values at a list of points; every vector has one entry per point.
struct LutValues {
  std::vector<double> a, b;
  std::vector<double> cloth;   // empty unless options.cloth
  std::vector<double> stdErr;  // estimator standard error, max over the channels (0 for references)
};

// The kernel at arbitrary points (tests use it at μ = 0 and r = 0 exactly).
// Points outside [0, 1] are clamped.
LutValues evaluateLut(Runtime& rt, const LutOptions& options, const std::vector<LutPoint>& points,
                      double* kernelSeconds = nullptr);
// The double-precision reference at the same points: deterministic Gauss–Legendre
// quadrature over the half vector with the horizon handled analytically (not the
// kernel's sampler). `nodes` scales the node count (1 = default, 2 = twice per axis).
LutValues evaluateLutReference(const LutOptions& options, const std::vector<LutPoint>& points,
                               int nodes = 1);

struct LutResult {
  LutOptions options;
  int size = 0;
  // size × size values each, row (roughness) major, row 0 first.
  std::vector<float> a, b;
  std::vector<float> third;     // multiscatter E or cloth; empty when neither is requested
  std::vector<float> e, eAvg;   // Kulla–Conty; empty unless options.kullaConty (eAvg: size values)
  double stdErrMax = 0, stdErrMean = 0;  // over texels, of the per-texel max over channels
  double kernelSeconds = 0;     // device time of the LUT kernel (excluding the program build)
  double buildSeconds = 0;      // program build time on this call (0 when cached)
  double totalSeconds = 0;      // whole computeLut call
  std::string device;           // Runtime::deviceLabel()
  bool reference = false;       // computed by computeLutReference
  // Adaptive sampling (LutOptions::tolerance > 0): samples per texel (row major),
  // histogram[k] = texels that used [2^k, 2^(k+1)) integrand evaluations, texels that hit the cap, and the
  // prefix-difference error estimate (max over channels) per texel, max and mean.
  std::vector<int> samplesPerTexel;
  std::vector<size_t> samplesHistogram;
  size_t texelsAtCap = 0;
  uint64_t totalSamples = 0;    // Σ over texels of the samples used
  std::vector<float> errorEstimate;
  double errorEstimateMax = 0, errorEstimateMean = 0;
};

// The table on the device. Throws UsageError for invalid options.
LutResult computeLut(Runtime& rt, const LutOptions& options);
// The table by the host reference (slow: ~0.3 ms per texel; for tests and benchmarks).
LutResult computeLutReference(const LutOptions& options);

// OUT.exr → OUT.json.
std::string lutSidecarPath(const std::string& exrPath);

// Writes the EXR (float32, or half) and its JSON sidecar, both atomically. On
// failure neither file is left behind (the EXR is removed if the sidecar fails).
// Throws OutputError.
void writeLut(const LutResult& lut, const std::string& exrPath, bool half = false,
              double commandSeconds = -1);
// The same with the sidecar's path given (empty: no sidecar), for runners that
// choose their own file names.
void writeLutFiles(const LutResult& lut, const std::string& exrPath, const std::string& jsonPath, bool half = false,
                   double commandSeconds = -1);

}  // namespace prtbake
