// prtbake/env.h: the environment product: loading (envmap.h), projecting an environment onto SH, windowing, writing.
//
// Radiance coefficients: L_i = Σ_texels L(ω_t) Y_i(ω_t) Ω_t (exact texel solid
// angles Ω_t, see envmap.h). Irradiance: E_i = Â_l L_i (Ramamoorthi & Hanrahan
// 2001, Â from sh.h); irradiance_over_pi = E_i/π (the diffuse exit radiance for
// albedo 1). Windows multiply band l by w_l before the quantity is formed.
#pragma once

#include <array>
#include <functional>
#include <string>
#include <vector>

#include "prtbake/envmap.h"
#include "prtbake/runtime.h"
#include "prtbake/sh.h"

namespace prtbake {

enum class ShWindow { None, Hann, Lanczos, Auto };

const char* toString(ShWindow w);
// Parse "none" etc.; throw UsageError naming --window on anything else.
ShWindow parseWindow(const std::string& s);

struct EnvProjectOptions {
  int order = 3;                                    // 1..kMaxShOrder
  ShQuantity quantity = ShQuantity::Radiance;
  ShWindow window = ShWindow::None;
  // Tuning knobs (0 = automatic): lanes per work-item (1, 8 or 16) and rows per work-group.
  int vectorWidth = 0;
  int rowsPerGroup = 0;
};

struct EnvProjectResult {
  ShCoeffs coeffs;                 // after window and quantity
  ShCoeffs radiance;               // unwindowed radiance coefficients
  std::vector<double> windowWeights;  // w_l, l = 0..n-1 (all 1 for none)
  double autoWindowLambda = 0.0;   // the Laplacian-window strength chosen by auto
  double minIrradianceBefore = 0, minIrradianceAfter = 0;  // of the reconstruction (auto)
  double kernelSeconds = 0.0;      // device time of the projection kernels
  double uploadSeconds = 0.0;
  long long texels = 0;
};

// The OpenCL projection (work-item row partial sums in float, summed in double on the host).
EnvProjectResult projectEnvironment(Runtime& rt, const EnvMap& env, const EnvProjectOptions& options);

// loadEnvironment(path, loadOptions) with yawDegrees, then projectEnvironment, with the same
// result to the bit, except that a lat-long OpenEXR file is decoded and projected a band of
// rows (about bandBytes of float texels) at a time, so that its texels are never all in
// memory (forEachLatLongBand). *env receives the map's description (layout, size, files,
// clamped texels), and its texels only when it was not read in bands. `runtime` is called
// once the texels are read or, for bands, once the header is (so that a caller may create
// the device's context after the decoders' buffers are freed: 2 MB less at peak on a cube
// of six 2048² JPEGs).
EnvProjectResult projectEnvironmentFile(const std::function<Runtime&()>& runtime, const std::string& path,
                                        const EnvLoadOptions& loadOptions,
                                        double yawDegrees, const EnvProjectOptions& options, EnvMap* env,
                                        size_t bandBytes = size_t(32) << 20);

// Double-precision reference: every texel's direction, solid angle and Y in double.
ShCoeffs projectEnvironmentReference(const EnvMap& env, int order);

// Window weights w_l (l = 0..order-1) for none/hann/lanczos.
std::vector<double> windowWeights(ShWindow w, int order);

// Applies window weights and converts radiance → the requested quantity.
ShCoeffs applyWindowAndQuantity(const ShCoeffs& radiance, const std::vector<double>& weights, ShQuantity q);

// Sloan 2017-style deringing: the weakest Laplacian-penalty window
// w_l = 1/(1 + λ (l(l+1))²) that makes the reconstructed irradiance non-negative
// everywhere (each channel). Returns the weights; reports λ and the minima.
std::vector<double> deringingWindow(const ShCoeffs& radiance, double* lambda, double* minBefore,
                                    double* minAfter);

// Order selection ("--order auto"): the relative L2 error over the sphere of the
// order-n truncation of `quantity` (radiance, or irradiance = Â_l-weighted),
// measured against the given high-order projection by Parseval:
//   ε(n) = √(Σ_{l≥n} f_l² Σ_m |L_lm|²) / √(Σ_l f_l² Σ_m |L_lm|²),  f_l = 1 or Â_l,
// summed over the three channels. Returns the smallest n with ε(n) ≤ tolerance
// (or the high order itself when none is), and ε(n) in *achievedError.
double truncationError(const ShCoeffs& high, ShQuantity quantity, int order);
int chooseShOrder(const ShCoeffs& high, ShQuantity quantity, double tolerance, double* achievedError);
// Keeps the first `order` bands.
ShCoeffs truncateSh(const ShCoeffs& c, int order);

// Evaluates Σ c_i Y_i(ω) for each channel at a unit direction.
Rgb evalSh(const ShCoeffs& c, double x, double y, double z);

// Writers. The JSON states the conventions (docs/conventions.md "Environment SH"); `meta` is
// merged in (parameters, input hashes, timings; a JSON object as text).
void writeShJson(const std::string& path, const ShCoeffs& c, const std::string& metaJson);
// Reads a JSON written by writeShJson (for rotate). Throws InputError.
ShCoeffs readShJson(const std::string& path, std::string* metaJson = nullptr);
// GAMES202 light.txt: 9 lines of three numbers, single spaces, no trailing space (order 3 only:
// higher orders write n² lines).
void writeGames202Light(const std::string& path, const ShCoeffs& c);

}  // namespace prtbake
