// prtbake/lut.h: split-sum BRDF lookup tables for image-based lighting.
//
// Conventions (docs/conventions.md "BRDF LUT"): μ = N·V in [0, 1], perceptual roughness r in
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

#include <cstdint>
#include <string>
#include <vector>

#include "prtbake/tolerance.h"

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
  int samples = 1024;   // samples per texel (Hammersley points; sums in double over chunks of 16384)
  LutNdf ndf = LutNdf::Ggx;
  LutVisibility visibility = LutVisibility::SmithCorrelated;
  bool alphaDirect = false;   // roughness axis holds α itself instead of r (α = r²)
  bool multiscatter = false;  // third channel: E = A + B
  bool cloth = false;         // third channel: the Charlie/Ashikhmin cloth table
  bool kullaConty = false;    // extra channels E and Eavg
  bool fastMath = false;      // -cl-fast-relaxed-math and native sqrt/rsqrt/divide
  LutDirections directions = LutDirections::Table;
  // "--tolerance E" (0: off, `samples` is used): the sample count that brings 95 % of
  // the texels' A, B (and cloth) within E, predicted from a pilot over a grid of texels
  // (prtbake/tolerance.h), at most toleranceMaxSamples; then the table is computed as
  // with `samples` = that count.
  double tolerance = 0;
  int toleranceMaxSamples = kLutMaxSamples;
};

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
  uint64_t totalSamples = 0;    // samples per texel × texels (with --tolerance: the pilot's too)
  ToleranceReport tolerance;    // what --tolerance did (empty without it)
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
