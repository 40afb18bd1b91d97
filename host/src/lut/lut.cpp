// Split-sum BRDF tables on the device: options, the sample table, the kernel launch.
#include "prtbake/lut.h"
#include "prtbake/progress.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>

#include "core/constants.h"
#include "core/kernel_options.h"
#include "lut/lut_detail.h"
#include "lut_sampling.clh"
#include "prtbake/clock.h"
#include "prtbake/error.h"
#include "prtbake/runtime.h"
#include "core/radical_inverse.h"
#include "core/tolerance_pilot.h"

namespace prtbake {
namespace {

// The per-sample table of lut_sampling.clh for points first … first + count − 1 of the
// `samples`-point Hammersley set, in double then rounded to float.
std::vector<float> sampleTable(int samples, int first, int count, int nPad) {
  std::vector<float> t(size_t(LUT_TAB_ROWS) * nPad, 0.0f);
  auto at = [&](int row, int k) -> float& { return t[size_t(row) * nPad + k]; };
  for (int k = 0; k < nPad; ++k) {
    // Padding repeats a harmless point (mask 0) so no lane computes NaN.
    const int kk = first + (k < count ? k : 0);
    const double u1 = (kk + 0.5) / samples, u2 = detail::radicalInverse2(uint32_t(kk));
    const double r = std::sqrt(u1), cphi = std::cos(2 * kPi * u2), sphi = std::sin(2 * kPi * u2);
    const double t1 = r * cphi;
    at(LUT_TAB_T1SQ, k) = float(t1 * t1);
    at(LUT_TAB_T2, k) = float(r * sphi);
    at(LUT_TAB_C, k) = float(std::sqrt(std::max(0.0, 1 - t1 * t1)));
    at(LUT_TAB_C2, k) = float(std::max(0.0, 1 - t1 * t1));
    at(LUT_TAB_MASK, k) = k < count ? 1.0f : 0.0f;
    at(LUT_TAB_U1, k) = float(u1);
    at(LUT_TAB_U2, k) = float(u2);
    // Cloth mixture (lut.cl): branch by u1, u' = u1 rescaled within its branch.
    const double b0 = LUT_CLOTH_BETA0, b1 = LUT_CLOTH_BETA1;
    if (u1 < b0) {
      const double th = kPi / 2 * u1 / b0;
      at(LUT_TAB_CL_BRANCH, k) = 0.0f;
      at(LUT_TAB_CL_A, k) = float(std::log(std::sin(th)));
      at(LUT_TAB_CL_B, k) = float(std::cos(th));
    } else if (u1 < b0 + b1) {
      at(LUT_TAB_CL_BRANCH, k) = 1.0f;
      at(LUT_TAB_CL_A, k) = float((u1 - b0) / b1);
    } else {
      at(LUT_TAB_CL_BRANCH, k) = 2.0f;
      at(LUT_TAB_CL_A, k) = float(std::log((u1 - b0 - b1) / (1 - b0 - b1)));
    }
  }
  return t;
}

}  // namespace

std::string detail::lutOptions(const LutOptions& o) {
  std::string s = "-DLUT_NDF=" + std::to_string(o.ndf == LutNdf::Beckmann ? 1 : 0) +
                  " -DLUT_VIS=" + std::to_string(int(o.visibility)) +
                  " -DLUT_CLOTH=" + std::to_string(o.cloth ? 1 : 0) +
                  " -DLUT_PADDED=" + std::to_string(o.samples % LUT_SIMD ? 1 : 0) +
                  " -DLUT_DIRS=" + std::to_string(int(o.directions)) +
                  " -DLUT_NATIVE=" + std::to_string(o.fastMath ? 1 : 0);
  if (o.fastMath) s += " -cl-fast-relaxed-math";
  return s;
}

namespace {

// Per-point results of the kernel, one entry per point.
struct KernelOut {
  std::vector<float> a, b, cloth, stdErr;
};

// Means and standard errors from a point's sums (lut_sampling.clh) over n samples.
void finishPoint(const LutOptions& o, const double* s, double n, KernelOut& res, size_t i) {
  auto stdErr = [n](double sum, double sum2) {
    const double m = sum / n;
    return std::sqrt(std::max(sum2 / n - m * m, 0.0) / n);
  };
  double errA, errB;
  if (o.ndf == LutNdf::Ggx) {
    res.a[i] = float(s[0] / n), res.b[i] = float(s[1] / n);
    errA = stdErr(s[0], s[2]), errB = stdErr(s[1], s[3]);
  } else {
    // The ratio Σ d y / Σ d; its standard error by the delta method, √(Σ d² (y − Ŷ)²) / Σ d,
    // expanded into the sums.
    const double ea = s[1] / s[0], eb = s[2] / s[0];
    res.a[i] = float(ea), res.b[i] = float(eb);
    errA = std::sqrt(std::max(s[6] - 2 * ea * s[4] + ea * ea * s[3], 0.0)) / s[0];
    errB = std::sqrt(std::max(s[7] - 2 * eb * s[5] + eb * eb * s[3], 0.0)) / s[0];
  }
  double err = std::max(errA, errB);
  if (o.cloth) {
    res.cloth[i] = float(s[8] / n);
    err = std::max(err, stdErr(s[8], s[9]));
  }
  res.stdErr[i] = float(err);
}

// One launch of every point with two sample counts (see runKernel's secondSamples).
template <class PointAt>
KernelOut runPair(Runtime& rt, cl::Kernel& kernel, const LutOptions& o, size_t count, PointAt&& pointAt,
                  int secondSamples, double* kernelSeconds) {
  constexpr int kSums = 4 * LUT_OUT_FLOAT4S;
  KernelOut res;
  const size_t total = 2 * count;
  res.a.resize(total), res.b.resize(total), res.stdErr.resize(total);
  if (o.cloth) res.cloth.resize(total);
  if (count == 0) return res;
  std::vector<float> muAlpha(2 * total), raw(total * kSums);
  for (size_t i = 0; i < count; ++i) {
    const auto p = pointAt(i);
    muAlpha[2 * i] = muAlpha[2 * (count + i)] = p.first;
    muAlpha[2 * i + 1] = muAlpha[2 * (count + i) + 1] = p.second;
  }
  const int n1 = o.samples, n2 = secondSamples;
  const int pad1 = (n1 + LUT_SIMD - 1) / LUT_SIMD * LUT_SIMD, pad2 = (n2 + LUT_SIMD - 1) / LUT_SIMD * LUT_SIMD;
  const std::vector<float> t1 = sampleTable(n1, 0, n1, pad1), t2 = sampleTable(n2, 0, n2, pad2);
  cl::Buffer pts(rt.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, muAlpha.size() * sizeof(float), muAlpha.data());
  cl::Buffer tab1(rt.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, t1.size() * sizeof(float),
                  const_cast<float*>(t1.data()));
  cl::Buffer tab2(rt.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, t2.size() * sizeof(float),
                  const_cast<float*>(t2.data()));
  cl::Buffer out(rt.context(), CL_MEM_WRITE_ONLY, raw.size() * sizeof(float));
  kernel.setArg(0, int(total));
  kernel.setArg(1, pts);
  kernel.setArg(2, pad1);
  kernel.setArg(3, float(n1));
  kernel.setArg(4, tab1);
  kernel.setArg(5, int(count));
  kernel.setArg(6, pad2);
  kernel.setArg(7, float(n2));
  kernel.setArg(8, tab2);
  kernel.setArg(9, out);
  cl::Event done;
  const size_t local = 16;
  rt.queue().enqueueNDRangeKernel(kernel, cl::NullRange, cl::NDRange((total + local - 1) / local * local),
                                  cl::NDRange(local), nullptr, &done);
  rt.queue().enqueueReadBuffer(out, CL_TRUE, 0, raw.size() * sizeof(float), raw.data());
  if (kernelSeconds)
    *kernelSeconds += 1e-9 * double(done.getProfilingInfo<CL_PROFILING_COMMAND_END>() -
                                    done.getProfilingInfo<CL_PROFILING_COMMAND_START>());
  std::vector<double> sums(kSums);
  for (size_t i = 0; i < total; ++i) {
    for (int k = 0; k < kSums; ++k) sums[size_t(k)] = raw[i * kSums + size_t(k)];
    finishPoint(o, sums.data(), double(i < count ? n1 : n2), res, i);
  }
  return res;
}

// Runs lut_eval over `count` points; pointAt(i) gives point i as (μ, α). Launches cover
// at most kChunk points, so that device and staging memory stay bounded for 8192²
// tables, and at most LUT_CHUNK samples, whose float sums the host adds up in double.
// With secondSamples > 0 (both counts at most LUT_CHUNK and count ≤ kChunk/2) every point
// is evaluated twice in the same launch, with o.samples and with secondSamples; the
// result then holds 2·count entries, the second count's after the first's.
template <class PointAt>
KernelOut runKernel(Runtime& rt, const LutOptions& o, size_t count, PointAt&& pointAt, double* kernelSeconds,
                    double* buildSeconds, int secondSamples = 0) {
  constexpr size_t kChunk = size_t(1) << 20;
  constexpr int kSums = 4 * LUT_OUT_FLOAT4S;
  const double build0 = rt.buildSeconds();
  cl::Kernel kernel = rt.kernel("lut.cl", "lut_eval", detail::lutOptions(o));
  if (buildSeconds) *buildSeconds = rt.buildSeconds() - build0;
  KernelOut res;
  if (kernelSeconds) *kernelSeconds = 0;
  if (secondSamples > 0) {
    PRTBAKE_CHECK(o.samples <= LUT_CHUNK && secondSamples <= LUT_CHUNK && 2 * count <= kChunk,
                  "two sample counts in one launch need small counts");
    return runPair(rt, kernel, o, count, pointAt, secondSamples, kernelSeconds);
  }
  res.a.resize(count), res.b.resize(count), res.stdErr.resize(count);
  if (o.cloth) res.cloth.resize(count);
  if (count == 0) return res;
  const size_t chunk = std::min(count, kChunk);
  const int sampleChunk = std::min(o.samples, LUT_CHUNK);
  const int nPadMax = (sampleChunk + LUT_SIMD - 1) / LUT_SIMD * LUT_SIMD;
  std::vector<float> muAlpha(2 * chunk), raw(chunk * kSums);
  std::vector<double> sums(chunk * kSums);
  cl::Buffer pts(rt.context(), CL_MEM_READ_ONLY, muAlpha.size() * sizeof(float));
  cl::Buffer out(rt.context(), CL_MEM_WRITE_ONLY, raw.size() * sizeof(float));
  cl::Buffer tab(rt.context(), CL_MEM_READ_ONLY, size_t(LUT_TAB_ROWS) * nPadMax * sizeof(float));
  const size_t local = 16;  // a fixed local size splits the points evenly over the compute units
  for (size_t first = 0; first < count; first += chunk) {
    const size_t m = std::min(chunk, count - first);
    for (size_t i = 0; i < m; ++i) {
      const auto p = pointAt(first + i);
      muAlpha[2 * i] = p.first, muAlpha[2 * i + 1] = p.second;
    }
    // One synchronisation per launch (the blocking read): the writes are queued ahead of
    // the kernel on the in-order queue, and the kernel is timed by its profiling event.
    rt.queue().enqueueWriteBuffer(pts, CL_FALSE, 0, 2 * m * sizeof(float), muAlpha.data());
    std::fill(sums.begin(), sums.begin() + std::ptrdiff_t(m * kSums), 0.0);
    for (int k0 = 0; k0 < o.samples; k0 += sampleChunk) {
      const int n = std::min(sampleChunk, o.samples - k0), nPad = (n + LUT_SIMD - 1) / LUT_SIMD * LUT_SIMD;
      const std::vector<float> table = sampleTable(o.samples, k0, n, nPad);
      rt.queue().enqueueWriteBuffer(tab, CL_FALSE, 0, table.size() * sizeof(float), table.data());
      kernel.setArg(0, int(m));
      kernel.setArg(1, pts);
      kernel.setArg(2, nPad);
      kernel.setArg(3, float(n));
      kernel.setArg(4, tab);
      kernel.setArg(5, int(m));  // no second sample set
      kernel.setArg(6, nPad);
      kernel.setArg(7, float(n));
      kernel.setArg(8, tab);
      kernel.setArg(9, out);
      cl::Event done;
      rt.queue().enqueueNDRangeKernel(kernel, cl::NullRange, cl::NDRange((m + local - 1) / local * local),
                                      cl::NDRange(local), nullptr, &done);
      rt.queue().enqueueReadBuffer(out, CL_TRUE, 0, m * kSums * sizeof(float), raw.data());
      if (kernelSeconds)
        *kernelSeconds += 1e-9 * double(done.getProfilingInfo<CL_PROFILING_COMMAND_END>() -
                                        done.getProfilingInfo<CL_PROFILING_COMMAND_START>());
      for (size_t i = 0; i < m * kSums; ++i) sums[i] += raw[i];
      reportProgress("lut", (double(first) + double(m) * double(k0 + n) / o.samples) / double(count));
    }
    for (size_t i = 0; i < m; ++i) finishPoint(o, &sums[i * kSums], double(o.samples), res, first + i);
  }
  return res;
}

}  // namespace

void validateLutOptions(const LutOptions& o) {
  if (o.size < 1 || o.size > kLutMaxSize)
    throw UsageError("--size", std::to_string(o.size) + " is out of range [1, " + std::to_string(kLutMaxSize) + "]");
  if (o.samples < 1 || o.samples > kLutMaxSamples)
    throw UsageError("--samples",
                     std::to_string(o.samples) + " is out of range [1, " + std::to_string(kLutMaxSamples) + "]");
  if (!(o.tolerance >= 0) || !std::isfinite(o.tolerance))
    throw UsageError("--tolerance", "must be a finite number ≥ 0");
  if (o.tolerance > 0 && (o.toleranceMaxSamples < 2 * kTolerancePilotStart || o.toleranceMaxSamples > kLutMaxSamples))
    throw UsageError("--max-samples", std::to_string(o.toleranceMaxSamples) + " is out of range [" +
                                          std::to_string(2 * kTolerancePilotStart) + ", " + std::to_string(kLutMaxSamples) + "]");
  if (o.cloth && o.multiscatter)
    throw UsageError("--cloth", "the B channel holds one third table: choose --cloth or --multiscatter");
}

LutNdf parseLutNdf(const std::string& text, const std::string& subject) {
  if (text == "ggx") return LutNdf::Ggx;
  if (text == "beckmann") return LutNdf::Beckmann;
  throw UsageError(subject, "unknown NDF '" + text + "' (expected ggx|beckmann)");
}

LutVisibility parseLutVisibility(const std::string& text, const std::string& subject) {
  if (text == "smith-correlated") return LutVisibility::SmithCorrelated;
  if (text == "smith-separable") return LutVisibility::SmithSeparable;
  if (text == "schlick-ggx") return LutVisibility::SchlickGgx;
  throw UsageError(subject,
                   "unknown visibility '" + text + "' (expected smith-correlated|smith-separable|schlick-ggx)");
}

const char* lutNdfName(LutNdf ndf) { return ndf == LutNdf::Ggx ? "ggx" : "beckmann"; }

const char* lutVisibilityName(LutVisibility vis) {
  switch (vis) {
    case LutVisibility::SmithCorrelated: return "smith-correlated";
    case LutVisibility::SmithSeparable: return "smith-separable";
    case LutVisibility::SchlickGgx: return "schlick-ggx";
  }
  return "?";
}

double lutAlpha(const LutOptions& options, double roughness) {
  const double r = std::clamp(roughness, 0.0, 1.0);
  return options.alphaDirect ? r : r * r;
}

LutValues evaluateLut(Runtime& rt, const LutOptions& options, const std::vector<LutPoint>& points,
                      double* kernelSeconds) {
  LutOptions o = options;
  o.size = 1;
  validateLutOptions(o);
  const KernelOut k = runKernel(
      rt, o, points.size(),
      [&](size_t i) {
        return std::pair<float, float>(float(std::clamp(points[i].mu, 0.0, 1.0)),
                                       float(lutAlpha(o, points[i].roughness)));
      },
      kernelSeconds, nullptr);
  LutValues v;
  v.a.assign(k.a.begin(), k.a.end());
  v.b.assign(k.b.begin(), k.b.end());
  v.cloth.assign(k.cloth.begin(), k.cloth.end());
  v.stdErr.assign(k.stdErr.begin(), k.stdErr.end());
  return v;
}

namespace detail {
// Fills the derived tables (third, Kulla–Conty, error summary) from a, b, cloth.
void finishLut(LutResult& r, const std::vector<float>& cloth, const std::vector<float>& stdErr) {
  const int n = r.size;
  const size_t texels = size_t(n) * n;
  if (r.options.multiscatter) {
    r.third.resize(texels);
    for (size_t i = 0; i < texels; ++i) r.third[i] = r.a[i] + r.b[i];
  } else if (r.options.cloth) {
    r.third = cloth;
  }
  if (r.options.kullaConty) {
    r.e.resize(texels);
    r.eAvg.resize(n);
    for (int j = 0; j < n; ++j) {
      double sum = 0;
      for (int i = 0; i < n; ++i) {
        const size_t t = size_t(j) * n + i;
        r.e[t] = r.a[t] + r.b[t];
        sum += double(r.e[t]) * ((i + 0.5) / n);
      }
      r.eAvg[j] = float(2.0 * sum / n);
    }
  }
  double mx = 0, sum = 0;
  for (float e : stdErr) mx = std::max(mx, double(e)), sum += e;
  r.stdErrMax = mx;
  r.stdErrMean = stdErr.empty() ? 0 : sum / double(stdErr.size());
}

std::vector<LutPoint> texelPoints(int n) {
  std::vector<LutPoint> pts;
  pts.reserve(size_t(n) * n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) pts.push_back({(i + 0.5) / n, (j + 0.5) / n});
  return pts;
}
}  // namespace detail

namespace {

// "--tolerance": the pilot over a grid of at most 16 × 16 texels (prtbake/tolerance.h),
// then the table with the predicted count.
LutResult computeLutWithTolerance(Runtime& rt, const LutOptions& options) {
  const int n = options.size, step = std::max(1, (n + 15) / 16);
  std::vector<LutPoint> pilot;
  for (int j = step / 2; j < n; j += step)
    for (int i = step / 2; i < n; i += step) pilot.push_back({(i + 0.5) / n, (j + 0.5) / n});
  uint64_t pilotSamples = 0;
  const size_t stride = options.cloth ? 3 : 2;
  auto evaluate = [&](const std::vector<int>& counts) {
    LutOptions o = options;
    o.samples = counts[0];
    o.tolerance = 0;
    const int second = counts.size() > 1 ? counts[1] : 0;
    const KernelOut k = runKernel(
        rt, o, pilot.size(),
        [&](size_t i) { return std::pair<float, float>(float(pilot[i].mu), float(lutAlpha(o, pilot[i].roughness))); },
        nullptr, nullptr, second);
    std::vector<std::vector<double>> out(counts.size());
    for (size_t c = 0; c < counts.size(); ++c) {
      pilotSamples += uint64_t(counts[c]) * pilot.size();
      for (size_t i = c * pilot.size(); i < (c + 1) * pilot.size(); ++i) {
        out[c].push_back(k.a[i]);
        out[c].push_back(k.b[i]);
        if (options.cloth) out[c].push_back(k.cloth[i]);
      }
    }
    return out;
  };
  const ToleranceReport report =
      detail::runTolerancePilot(evaluate, stride, options.tolerance, options.toleranceMaxSamples, LUT_SIMD);
  LutOptions uniform = options;
  uniform.samples = report.samples;
  uniform.tolerance = 0;
  LutResult r = computeLut(rt, uniform);
  r.options = options;
  r.options.samples = report.samples;
  r.tolerance = report;
  r.tolerance.items = size_t(n) * n;
  r.totalSamples += pilotSamples;
  return r;
}

}  // namespace

LutResult computeLut(Runtime& rt, const LutOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  validateLutOptions(options);
  if (options.tolerance > 0) {
    LutResult r = computeLutWithTolerance(rt, options);
    r.totalSeconds = secondsSince(t0);
    return r;
  }
  LutResult r;
  r.options = options;
  r.size = options.size;
  r.device = rt.deviceLabel();
  const int n = options.size;
  const size_t texels = size_t(n) * n;
  KernelOut k = runKernel(
      rt, options, texels,
      [&](size_t t) {
        const size_t i = t % size_t(n), j = t / size_t(n);
        return std::pair<float, float>(float((i + 0.5) / n), float(lutAlpha(options, (j + 0.5) / n)));
      },
      &r.kernelSeconds, &r.buildSeconds);
  r.a = std::move(k.a);
  r.b = std::move(k.b);
  r.totalSamples = uint64_t(texels) * uint64_t(options.samples);
  const std::vector<float> cloth = std::move(k.cloth), stdErr = std::move(k.stdErr);
  detail::finishLut(r, cloth, stdErr);
  r.totalSeconds = secondsSince(t0);
  return r;
}

}  // namespace prtbake
