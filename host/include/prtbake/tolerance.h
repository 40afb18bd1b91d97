// prtbake/tolerance.h: how "--tolerance E" chooses a sample count.
//
// Every Monte Carlo product (the BRDF table, per-vertex transport and each of its
// bounces) evaluates all of its items (texels, vertices) with the same low-discrepancy
// point set, and its error falls like N^−p in the count N (p ≈ 1 for the table, 0.75 for
// visibility). `--tolerance E` asks for the smallest N that brings 95 % of the items
// within E. It is found on a pilot before the product runs:
//
//   1. A pilot subset of the items (a regular grid of at most 256 texels, at most 128
//      vertices spread over the mesh) is evaluated at N = 16, 32, 64, ….
//   2. Each doubling gives every pilot item the change d_i(N) = max over its values of
//      |T_i(N) − T_i(N/2)|, pooled as their 95th percentile D(N); the rate p comes from
//      two successive D (clamped to [0.5, 1]: a smaller p only asks for more samples).
//      If the error falls like c/N^p with one sign, as the deterministic point sets do
//      (measured on the cloth table), D(N) = (2^p − 1) e(N), so e(N) = D(N)/(2^p − 1)
//      bounds the 95th-percentile error; where errors change sign it overestimates it
//      (by 2× on the GGX table, measured, docs/accuracy.md).
//   3. The count M = N (e(N)/E)^{1/p} that brings that below E is extrapolated from the
//      pilot once the pilot is within a factor 16 of it, then rounded to the nearest
//      quarter octave, 2^m × {1, 5/4, 3/2, 7/4} (at such counts the error falls steadily;
//      at arbitrary counts it can stay above the lower power of two's; nearest, not next:
//      e(N) overestimates by about 2×, so the at most 12 % of count given up rounding down
//      costs no accuracy, measured), and capped at --max-samples.
//   4. The product runs once, uniformly, with M samples: the same computation as
//      `--samples M`.
//
// The pilot costs about 2·N_last per pilot item against M per item of the run (N_last
// ≥ M/16, so a few per cent for 128² tables and meshes of thousands of vertices), and at
// least 48 samples per pilot item: at the loosest tolerances of small meshes it is then
// the larger share. Items that need no
// sampling (vertices no triangle can occlude, unshadowed transport) take their closed
// form instead, with no samples.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace prtbake {

// Pilot items: a 16 × 16 grid of texels; every k-th sampled vertex, with k the larger of
// ⌈V / kTolerancePilotVertices⌉ and min(kTolerancePilotShare, ⌊V / kTolerancePilotMinVertices⌋)
// for V sampled vertices: at most 128 vertices, since a vertex's rays cost as much in the
// pilot as in the run (at 256 the pilot of a 624-vertex mesh cost 30 % of its run at the
// loosest tolerance, measured); on smaller meshes one in up to 8 but not fewer than 64 (all
// of them below 128), so that the pilot's 16 + 32 rays per vertex cost at most a tenth of a
// run at 64 samples (128 of the 577 vertices of the open cavity made the loosest tolerance
// 1.2x the uniform run, measured).
constexpr size_t kTolerancePilotTexels = 256;
constexpr size_t kTolerancePilotVertices = 128;
constexpr size_t kTolerancePilotMinVertices = 64;
constexpr size_t kTolerancePilotShare = 8;
// The first pilot counts are kTolerancePilotStart and twice that.
constexpr int kTolerancePilotStart = 32;

// What "--tolerance" did for one product (or one term of transport: the direct term
// and each bounce), for sidecars and status lines.
struct ToleranceReport {
  double tolerance = 0;
  std::string strategy;         // "uniform, count predicted from a pilot" | "closed form"
  std::string why;              // one sentence
  int samples = 0;              // the count every sampled item got (0: none sampled)
  std::vector<int> pilotSamples;  // the pilot's counts
  size_t pilotItems = 0, items = 0;
  double rate = 0;              // the fitted convergence exponent p
  double pilotChange = 0;       // D(N_last), the 95th-percentile change at the last pilot count
  double predictedError = 0;    // e extrapolated to `samples`: the 95th percentile it predicts
  bool capped = false;          // M was cut to --max-samples (the prediction then exceeds E)
  double pilotSeconds = 0;
};

}  // namespace prtbake
