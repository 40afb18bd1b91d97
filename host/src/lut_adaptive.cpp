// Adaptive sample counts for the LUT ("--tolerance E"; see lut.h).
//
// R = kLutReplicas Hammersley sets with independent Cranley–Patterson shifts (drawn
// from the round and the replica). Round j adds m_j fresh samples per replica to every
// unconverged texel (m_0 = n0, then m_j = n0·2^(j−1): N_j = n0·2^j per replica) and keeps
// the sample-weighted mean of each replica:
//   X̂_r,c = (Σ_rounds m_j X̂_r,c^(j)) / N_j,   X̂_c = (1/R) Σ_r X̂_r,c,
//   s_c² = (1/(R−1)) Σ_r (X̂_r,c − X̂_c)²,   err = K max_c s_c/√R   (K = kLutErrorFactor),
// for the channels c = A, B (and cloth). A texel stops when err < E or when one more
// round would pass the cap (then it is counted at the cap).
#include <algorithm>
#include <chrono>
#include <cmath>

#include "lut_detail.h"
#include "prtbake/error.h"

namespace prtbake::detail {
namespace {
uint64_t mix(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}
double unit(uint64_t h) { return double(h >> 11) * 0x1.0p-53; }
}  // namespace

LutResult computeLutAdaptive(Runtime& rt, const LutOptions& options) {
  const auto tStart = std::chrono::steady_clock::now();
  LutResult r;
  r.options = options;
  r.size = options.size;
  r.device = rt.deviceLabel();
  const int n = options.size;
  const size_t texels = size_t(n) * n;
  const int nch = options.cloth ? 3 : 2;
  constexpr int R = kLutReplicas;
  const int n0 = kLutMinReplicaSamples;
  std::vector<double> acc(size_t(R) * texels * nch, 0.0);
  r.a.assign(texels, 0.0f), r.b.assign(texels, 0.0f);
  std::vector<float> cloth(options.cloth ? texels : 0, 0.0f), stdErr(texels, 0.0f);
  r.errorEstimate.assign(texels, 0.0f);
  r.samplesPerTexel.assign(texels, 0);
  std::vector<uint32_t> active(texels);
  for (size_t t = 0; t < texels; ++t) active[t] = uint32_t(t);
  for (int round = 0; !active.empty(); ++round) {
    const int m = round == 0 ? n0 : n0 << (round - 1);
    const int total = n0 << round;
    std::vector<std::pair<float, float>> pts(active.size());
    for (size_t i = 0; i < active.size(); ++i) {
      const size_t col = active[i] % size_t(n), row = active[i] / size_t(n);
      pts[i] = {float((col + 0.5) / n), float(lutAlpha(options, (row + 0.5) / n))};
    }
    LutOptions ro = options;
    ro.samples = m;
    ro.tolerance = 0;
    for (int rep = 0; rep < R; ++rep) {
      const uint64_t h = mix(uint64_t(round) * 64 + uint64_t(rep) + 1);
      std::vector<float> a, b, c;
      evaluateLutShifted(rt, ro, pts, unit(h), unit(mix(h)), a, b, c, &r.kernelSeconds);
      for (size_t i = 0; i < active.size(); ++i) {
        double* x = &acc[(size_t(rep) * texels + active[i]) * nch];
        x[0] += double(m) * a[i], x[1] += double(m) * b[i];
        if (nch == 3) x[2] += double(m) * c[i];
      }
    }
    std::vector<uint32_t> next;
    for (uint32_t t : active) {
      double errMax = 0;
      for (int c = 0; c < nch; ++c) {
        double mean = 0, sq = 0;
        for (int rep = 0; rep < R; ++rep) mean += acc[(size_t(rep) * texels + t) * nch + c] / total;
        mean /= R;
        for (int rep = 0; rep < R; ++rep) {
          const double d = acc[(size_t(rep) * texels + t) * nch + c] / total - mean;
          sq += d * d;
        }
        errMax = std::max(errMax, std::sqrt(sq / (R - 1) / R));
        (c == 0 ? r.a : c == 1 ? r.b : cloth)[t] = float(mean);
      }
      stdErr[t] = float(errMax);
      r.errorEstimate[t] = float(kLutErrorFactor * errMax);
      r.samplesPerTexel[t] = R * total;
      if (r.errorEstimate[t] < options.tolerance) continue;
      if (int64_t(R) * total * 2 > options.toleranceMaxSamples) {
        ++r.texelsAtCap;
        continue;
      }
      next.push_back(t);
    }
    active.swap(next);
  }
  finishLut(r, cloth, stdErr);
  double sum = 0;
  for (size_t t = 0; t < texels; ++t) {
    r.errorEstimateMax = std::max(r.errorEstimateMax, double(r.errorEstimate[t]));
    sum += r.errorEstimate[t];
    const int s = r.samplesPerTexel[t];
    r.totalSamples += uint64_t(s);
    const size_t k = size_t(std::lround(std::log2(double(s))));
    if (r.samplesHistogram.size() <= k) r.samplesHistogram.resize(k + 1, 0);
    ++r.samplesHistogram[k];
  }
  r.errorEstimateMean = texels ? sum / double(texels) : 0;
  r.totalSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - tStart).count();
  return r;
}

}  // namespace prtbake::detail
