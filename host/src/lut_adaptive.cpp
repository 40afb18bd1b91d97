// Adaptive sample counts for the LUT ("--tolerance E"; see lut.h).
//
// Every texel takes the points of ONE 2-D Sobol' sequence (sobol.h, unshifted: the
// uniform tables share one unshifted Hammersley set too), in blocks: round 0 takes
// points [0, n0), round j ≥ 1 points [N/2, N) with N = n0·2^j, so a texel at N samples
// holds exactly the first N points, a (0, log₂N, 2)-net like the N-point Hammersley set
// of the uniform path. With X̂_c(N) the mean of channel c over the first N points
// (channels A, B and cloth) and the differences of successive prefixes
//   d(N) = max_c |X̂_c(N) − X̂_c(N/2)|,
// a sequence whose error falls like 1/N has |X̂(N) − X̂(N/2)| ≈ err(N/2) ≈ 2 err(N). The
// estimate takes the last two differences, so that one lucky coincidence of two prefix
// means does not stop a texel, and pools them over the texel's 3×3 neighbourhood (RMS),
// because neighbours share the points and a texel whose successive prefixes happen to
// agree mostly has neighbours whose prefixes do not:
//   x(N) = max(d(N), d(N/2)/2),   err(N) = K · √(mean over the 3×3 neighbours of x²)
// (K = kLutErrorFactor; a neighbour that stopped at N' < N counts with x(N')·N'/N, its
// estimate carried to N by the 1/N fall that d(N/2)/2 assumes too), defined from
// N = 4 n0 on. A texel stops at the first N ≥ kLutToleranceMinSamples with err(N) < E, or
// when one more round would pass the cap (then it is counted at the cap). Measured
// (bench/study/replay_lut.py, 32² GGX, E = 1e-2 to 3e-4): the pooling lifts the fraction of
// texels below E from 0.947–1.000 to 0.974–1.000 at the same or a lower sample total.
#include <algorithm>
#include <chrono>
#include <cmath>

#include "lut_detail.h"
#include "prtbake/error.h"

namespace prtbake::detail {

LutResult computeLutAdaptive(Runtime& rt, const LutOptions& options) {
  const auto tStart = std::chrono::steady_clock::now();
  LutResult r;
  r.options = options;
  r.size = options.size;
  r.device = rt.deviceLabel();
  const int n = options.size;
  const size_t texels = size_t(n) * n;
  const int nch = options.cloth ? 3 : 2;
  const int n0 = kLutToleranceMinSamples / 4;
  std::vector<double> sum(texels * nch, 0.0), prev(texels * nch, 0.0), dPrev(texels, 0.0), x(texels, 0.0);
  r.a.assign(texels, 0.0f), r.b.assign(texels, 0.0f);
  std::vector<float> cloth(options.cloth ? texels : 0, 0.0f), stdErr(texels, 0.0f);
  r.errorEstimate.assign(texels, 0.0f);
  r.samplesPerTexel.assign(texels, 0);
  std::vector<uint32_t> active(texels);
  for (size_t t = 0; t < texels; ++t) active[t] = uint32_t(t);
  for (int round = 0; !active.empty(); ++round) {
    const int total = n0 << round;              // points per texel after this round
    const int first = round == 0 ? 0 : total / 2;  // this round's block [first, total)
    std::vector<std::pair<float, float>> pts(active.size());
    for (size_t i = 0; i < active.size(); ++i) {
      const size_t col = active[i] % size_t(n), row = active[i] / size_t(n);
      pts[i] = {float((col + 0.5) / n), float(lutAlpha(options, (row + 0.5) / n))};
    }
    LutOptions ro = options;
    ro.samples = total - first;
    ro.tolerance = 0;
    std::vector<float> a, b, c;
    evaluateLutSobol(rt, ro, pts, uint32_t(first), a, b, c, &r.kernelSeconds);
    // First every active texel's means and x(N), then the pooled decisions.
    for (size_t i = 0; i < active.size(); ++i) {
      const uint32_t t = active[i];
      const float v[3] = {a[i], b[i], nch == 3 ? c[i] : 0.0f};
      double d = 0;
      for (int ch = 0; ch < nch; ++ch) {
        double& s = sum[t * nch + ch];
        s += double(ro.samples) * v[ch];
        const double mean = s / total;
        d = std::max(d, std::abs(mean - prev[t * nch + ch]));
        prev[t * nch + ch] = mean;
        (ch == 0 ? r.a : ch == 1 ? r.b : cloth)[t] = float(mean);
      }
      r.samplesPerTexel[t] = total;
      if (round == 0) continue;  // no difference yet
      x[t] = std::max(d, dPrev[t] / 2);
      dPrev[t] = d;
    }
    std::vector<uint32_t> next;
    for (size_t i = 0; i < active.size() && round > 0; ++i) {
      const uint32_t t = active[i];
      const int col = int(t % size_t(n)), row = int(t / size_t(n));
      double pooled = 0;
      int count = 0;
      for (int rr = std::max(row - 1, 0); rr <= std::min(row + 1, n - 1); ++rr)
        for (int cc = std::max(col - 1, 0); cc <= std::min(col + 1, n - 1); ++cc, ++count) {
          const size_t j = size_t(rr) * n + cc;
          const double xj = x[j] * r.samplesPerTexel[j] / total;  // a stopped neighbour, carried to N
          pooled += xj * xj;
        }
      const double err = kLutErrorFactor * std::sqrt(pooled / count);
      stdErr[t] = float(err);
      r.errorEstimate[t] = float(err);
      const bool defined = round >= 2;
      if (!defined) {
        next.push_back(t);
        continue;
      }
      if (total >= kLutToleranceMinSamples && err < options.tolerance) continue;
      if (int64_t(total) * 2 > options.toleranceMaxSamples) {
        ++r.texelsAtCap;
        continue;
      }
      next.push_back(t);
    }
    if (round == 0) next = active;
    active.swap(next);
  }
  finishLut(r, cloth, stdErr);
  double errSum = 0;
  for (size_t t = 0; t < texels; ++t) {
    r.errorEstimateMax = std::max(r.errorEstimateMax, double(r.errorEstimate[t]));
    errSum += r.errorEstimate[t];
    const int s = r.samplesPerTexel[t];
    r.totalSamples += uint64_t(s);
    const size_t k = size_t(std::lround(std::log2(double(s))));
    if (r.samplesHistogram.size() <= k) r.samplesHistogram.resize(k + 1, 0);
    ++r.samplesHistogram[k];
  }
  r.errorEstimateMean = texels ? errSum / double(texels) : 0;
  r.totalSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - tStart).count();
  return r;
}

}  // namespace prtbake::detail
