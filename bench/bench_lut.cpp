// bench_lut: speed and accuracy of the BRDF tables.
//
//   bench_lut [OUT_DIR]     (default bench/results; run from the repository root)
//
// Writes OUT_DIR/lut.json (all figures), lut_timing.csv, lut_columns.csv (max |Δ| per N·V
// column against the double reference), lut_precision.csv (direction table vs precise vs
// native trigonometry, with and without fast math) and lut_convergence.{csv,svg} (error
// against samples). Timings are medians; the machine is shared.
#include <sys/resource.h>
#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "prtbake/atomic_file.h"
#include "prtbake/lut.h"
#include "prtbake/runtime.h"

using namespace prtbake;

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

struct Err {
  double maxAbs = 0, rms = 0;
  std::vector<double> column;
};
// Kernel table vs reference values on the rows `rows` (all columns).
Err compareTable(const LutResult& k, const LutValues& ref, const std::vector<int>& rows) {
  const int n = k.size;
  Err e;
  e.column.assign(n, 0.0);
  double sum2 = 0;
  size_t p = 0;
  for (int j : rows)
    for (int i = 0; i < n; ++i, ++p) {
      const size_t t = size_t(j) * n + i;
      const double d = std::max(std::abs(k.a[t] - ref.a[p]), std::abs(k.b[t] - ref.b[p]));
      e.column[i] = std::max(e.column[i], d);
      e.maxAbs = std::max(e.maxAbs, d);
      sum2 += d * d;
    }
  e.rms = std::sqrt(sum2 / double(p));
  return e;
}

std::vector<LutPoint> rowPoints(int n, const std::vector<int>& rows) {
  std::vector<LutPoint> pts;
  for (int j : rows)
    for (int i = 0; i < n; ++i) pts.push_back({(i + 0.5) / n, (j + 0.5) / n});
  return pts;
}

// CPU seconds of this process (PoCL's worker threads included).
double cpuSeconds() {
  rusage u{};
  ::getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

// Median kernel seconds over `reps` runs after one warm-up (build + first launch).
// `cpuPerCore` gets the median CPU time of the whole computeLut call divided by the
// device's compute units: the wall time the call would take on idle cores, which the
// shared machine's wall clock (load average 3–5 during these runs) does not show.
double kernelMedian(Runtime& rt, const LutOptions& o, int reps, LutResult* keep = nullptr,
                    double* cpuPerCore = nullptr) {
  LutResult r = computeLut(rt, o);
  std::vector<double> ts, cs;
  for (int i = 0; i < reps; ++i) {
    const double c0 = cpuSeconds();
    r = computeLut(rt, o);
    cs.push_back((cpuSeconds() - c0) / std::max(1u, rt.info().computeUnits));
    ts.push_back(r.kernelSeconds);
  }
  if (keep) *keep = std::move(r);
  if (cpuPerCore) *cpuPerCore = median(cs);
  return median(ts);
}

double loadAverage() {
  double l[1] = {0};
  return ::getloadavg(l, 1) == 1 ? l[0] : -1;
}

// Median wall time of the whole `prtbake lut` command (process start to exit).
double commandMedian(const std::string& args, int reps) {
  std::vector<double> ts;
  for (int i = 0; i < reps + 1; ++i) {
    const double t0 = now();
    const int rc = std::system((std::string("'") + PRTBAKE_CLI_PATH + "' lut " + args + " --quiet").c_str());
    if (rc != 0) {
      std::fprintf(stderr, "bench_lut: prtbake lut %s failed\n", args.c_str());
      std::exit(1);
    }
    if (i > 0) ts.push_back(now() - t0);  // the first run fills PoCL's program cache
  }
  return median(ts);
}

std::string fmt(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.4g", v);
  return b;
}

void writeSvg(const std::string& path, const std::vector<int>& samples, const std::vector<double>& maxErr,
              const std::vector<double>& rmsErr, const std::vector<double>& stdErr) {
  const double W = 640, H = 420, L = 70, R = 20, T = 30, B = 50;
  const double x0 = std::log2(samples.front()), x1 = std::log2(samples.back());
  const double y0 = -7, y1 = -1;  // log10 error axis
  auto px = [&](double s) { return L + (std::log2(s) - x0) / (x1 - x0) * (W - L - R); };
  auto py = [&](double e) { return T + (y1 - std::log10(std::max(e, 1e-12))) / (y1 - y0) * (H - T - B); };
  std::ostringstream o;
  o << "<svg xmlns='http://www.w3.org/2000/svg' width='" << W << "' height='" << H << "' font-family='sans-serif' "
    << "font-size='12'>\n<rect width='100%' height='100%' fill='white'/>\n";
  for (int e = int(y0); e <= int(y1); ++e) {
    o << "<line x1='" << L << "' x2='" << W - R << "' y1='" << py(std::pow(10, e)) << "' y2='" << py(std::pow(10, e))
      << "' stroke='#ddd'/><text x='" << L - 8 << "' y='" << py(std::pow(10, e)) + 4
      << "' text-anchor='end'>1e" << e << "</text>\n";
  }
  for (int s : samples)
    o << "<text x='" << px(s) << "' y='" << H - B + 18 << "' text-anchor='middle'>" << s << "</text>\n";
  o << "<text x='" << (L + W - R) / 2 << "' y='" << H - 10 << "' text-anchor='middle'>samples per texel</text>\n"
    << "<text x='" << 14 << "' y='" << (T + H - B) / 2 << "' transform='rotate(-90 14 " << (T + H - B) / 2
    << ")' text-anchor='middle'>|kernel - reference|</text>\n";
  auto line = [&](const std::vector<double>& v, const char* colour, const char* dash) {
    o << "<polyline fill='none' stroke='" << colour << "' stroke-width='2' stroke-dasharray='" << dash << "' points='";
    for (size_t i = 0; i < v.size(); ++i) o << px(samples[i]) << "," << py(v[i]) << " ";
    o << "'/>\n";
  };
  // Reference slopes through the first point: n^-1 (QMC, smooth) and n^-1/2 (Monte Carlo).
  std::vector<double> s1, s05;
  for (int s : samples) {
    s1.push_back(maxErr.front() * samples.front() / double(s));
    s05.push_back(maxErr.front() * std::sqrt(samples.front() / double(s)));
  }
  line(maxErr, "#c00", "");
  line(rmsErr, "#06c", "");
  line(stdErr, "#080", "");
  line(s1, "#888", "4,4");
  line(s05, "#bbb", "2,4");
  const char* labels[] = {"max |error| (128 cols x 33 rows)", "rms error", "mean reported std error (sigma/sqrt n)",
                          "slope n^-1", "slope n^-1/2"};
  const char* colours[] = {"#c00", "#06c", "#080", "#888", "#bbb"};
  for (int i = 0; i < 5; ++i)
    o << "<line x1='" << W - 250 << "' x2='" << W - 225 << "' y1='" << T + 10 + 16 * i << "' y2='" << T + 10 + 16 * i
      << "' stroke='" << colours[i] << "' stroke-width='2'/><text x='" << W - 220 << "' y='" << T + 14 + 16 * i
      << "'>" << labels[i] << "</text>\n";
  o << "<text x='" << L << "' y='18'>prtbake lut: GGX, height-correlated Smith, 128x128, convergence</text>\n</svg>\n";
  std::ofstream(path) << o.str();
}

}  // namespace

int main(int argc, char** argv) try {
  const std::string dir = argc > 1 ? argv[1] : "bench/results";
  ::mkdir(dir.c_str(), 0755);
  Runtime rt(std::getenv("PRTBAKE_DEVICE") ? "" : "cpu");
  std::printf("device: %s\n", rt.deviceLabel().c_str());
  std::ostringstream json;
  json << "{\n  \"device\": \"" << rt.deviceLabel() << "\",\n  \"version\": \"" << version() << "\",\n";

  // --- timing ---
  std::ofstream timing(dir + "/lut_timing.csv");
  timing << "variant,size,samples,kernel_ms_median,cpu_per_core_ms_median,command_ms_median,load_average\n";
  json << "  \"timing\": [\n";
  struct Case {
    const char* name;
    int size, samples;
    LutNdf ndf;
    LutVisibility vis;
    bool cloth, fast;
    const char* extra;
  };
  const std::vector<Case> cases = {
      {"ggx/smith-correlated", 128, 1024, LutNdf::Ggx, LutVisibility::SmithCorrelated, false, false, ""},
      {"ggx/smith-correlated", 512, 4096, LutNdf::Ggx, LutVisibility::SmithCorrelated, false, false, ""},
      {"ggx/smith-correlated fast-math", 128, 1024, LutNdf::Ggx, LutVisibility::SmithCorrelated, false, true,
       " --fast-math"},
      {"ggx/smith-separable", 128, 1024, LutNdf::Ggx, LutVisibility::SmithSeparable, false, false,
       " --visibility smith-separable"},
      {"ggx/schlick-ggx", 128, 1024, LutNdf::Ggx, LutVisibility::SchlickGgx, false, false, " --visibility schlick-ggx"},
      {"beckmann/smith-correlated", 128, 1024, LutNdf::Beckmann, LutVisibility::SmithCorrelated, false, false,
       " --ndf beckmann"},
      {"ggx/smith-correlated + cloth", 128, 1024, LutNdf::Ggx, LutVisibility::SmithCorrelated, true, false,
       " --cloth"},
  };
  const std::string tmp = dir + "/.bench_lut_tmp.exr";
  for (size_t c = 0; c < cases.size(); ++c) {
    const Case& k = cases[c];
    LutOptions o;
    o.size = k.size, o.samples = k.samples, o.ndf = k.ndf, o.visibility = k.vis, o.cloth = k.cloth, o.fastMath = k.fast;
    const int reps = k.size > 256 ? 5 : 9;
    double cpu = 0;
    const double kernel = kernelMedian(rt, o, reps, nullptr, &cpu);
    const double command = commandMedian("-o '" + tmp + "' --size " + std::to_string(k.size) + " --samples " +
                                             std::to_string(k.samples) + k.extra,
                                         5);
    const double load = loadAverage();
    std::printf("%-32s %4d^2 x %5d: kernel %8.2f ms (cpu/core %8.2f ms), whole command %8.1f ms, load %.1f\n",
                k.name, k.size, k.samples, kernel * 1e3, cpu * 1e3, command * 1e3, load);
    timing << k.name << "," << k.size << "," << k.samples << "," << fmt(kernel * 1e3) << "," << fmt(cpu * 1e3) << ","
           << fmt(command * 1e3) << "," << fmt(load) << "\n";
    json << "    {\"variant\": \"" << k.name << "\", \"size\": " << k.size << ", \"samples\": " << k.samples
         << ", \"kernel_ms\": " << fmt(kernel * 1e3) << ", \"cpu_per_core_ms\": " << fmt(cpu * 1e3)
         << ", \"command_ms\": " << fmt(command * 1e3) << ", \"load_average\": " << fmt(load) << "}"
         << (c + 1 < cases.size() ? ",\n" : "\n");
  }
  std::remove(tmp.c_str());
  std::remove((dir + "/.bench_lut_tmp.json").c_str());
  json << "  ],\n";

  // --- accuracy vs the reference, full 128² table, per N·V column ---
  const int n = 128;
  std::vector<int> allRows(n);
  for (int j = 0; j < n; ++j) allRows[j] = j;
  const double tr0 = now();
  const LutValues ref = evaluateLutReference(LutOptions{}, rowPoints(n, allRows));
  std::printf("reference 128^2: %.1f s\n", now() - tr0);
  std::ofstream cols(dir + "/lut_columns.csv");
  cols << "column,mu,max_abs_err_1024,max_abs_err_16384\n";
  LutOptions o1024;
  LutOptions o16k;
  o16k.samples = 16384;
  const Err e1024 = compareTable(computeLut(rt, o1024), ref, allRows);
  const Err e16k = compareTable(computeLut(rt, o16k), ref, allRows);
  for (int i = 0; i < n; ++i)
    cols << i << "," << fmt((i + 0.5) / n) << "," << fmt(e1024.column[i]) << "," << fmt(e16k.column[i]) << "\n";
  const int worstCol = int(std::max_element(e1024.column.begin(), e1024.column.end()) - e1024.column.begin());
  std::printf("128^2 x 1024: max |d| %.3g (rms %.3g), worst column %d (mu %.4f); grazing column 0: %.3g\n",
              e1024.maxAbs, e1024.rms, worstCol, (worstCol + 0.5) / n, e1024.column[0]);
  std::printf("128^2 x 16384: max |d| %.3g (rms %.3g), grazing column 0: %.3g\n", e16k.maxAbs, e16k.rms,
              e16k.column[0]);
  json << "  \"accuracy_128\": {\"max_abs_1024\": " << fmt(e1024.maxAbs) << ", \"rms_1024\": " << fmt(e1024.rms)
       << ", \"worst_column_1024\": " << worstCol << ", \"column0_1024\": " << fmt(e1024.column[0])
       << ", \"max_abs_16384\": " << fmt(e16k.maxAbs) << ", \"rms_16384\": " << fmt(e16k.rms)
       << ", \"column0_16384\": " << fmt(e16k.column[0]) << "},\n";

  // --- why visible-normal sampling: NDF sampling at a 16² table, per N·V column ---
  // The classic estimator (Karis 2013; three.js's 16×16 DFG table): H with pdf D(H)(N·H),
  // weight G2 (V·H)/((N·H) μ) — unbounded as μ → 0. Same Hammersley points, in double here.
  {
    const int m = 16, ns = 1024;
    std::vector<int> rows16(m);
    for (int j = 0; j < m; ++j) rows16[j] = j;
    const LutValues ref16 = evaluateLutReference(LutOptions{}, rowPoints(m, rows16));
    LutOptions o16;
    o16.size = m;
    const LutResult k16 = computeLut(rt, o16);
    std::ofstream g(dir + "/lut_grazing16.csv");
    g << "column,mu,ndf_sampling_max_abs_err_A,vndf_kernel_max_abs_err_A\n";
    double worstNdf = 0, worstV = 0;
    for (int i = 0; i < m; ++i) {
      double eN = 0, eV = 0;
      const double mu = (i + 0.5) / m, sv = std::sqrt(1 - mu * mu);
      for (int j = 0; j < m; ++j) {
        const double alpha = std::pow((j + 0.5) / m, 2), a2 = alpha * alpha;
        const double aV = std::sqrt(mu * mu * (1 - a2) + a2);
        double sumA = 0;
        for (int k = 0; k < ns; ++k) {
          uint32_t b = uint32_t(k);
          b = (b << 16) | (b >> 16);
          b = ((b & 0x00ff00ffu) << 8) | ((b & 0xff00ff00u) >> 8);
          b = ((b & 0x0f0f0f0fu) << 4) | ((b & 0xf0f0f0f0u) >> 4);
          b = ((b & 0x33333333u) << 2) | ((b & 0xccccccccu) >> 2);
          b = ((b & 0x55555555u) << 1) | ((b & 0xaaaaaaaau) >> 1);
          const double u1 = (k + 0.5) / ns, u2 = b / 4294967296.0;
          const double c2 = (1 - u1) / (1 + (a2 - 1) * u1), ch = std::sqrt(c2), sh = std::sqrt(1 - c2);
          const double vdoth = sv * sh * std::cos(2 * 3.14159265358979323846 * u2) + mu * ch;
          const double nl = 2 * vdoth * ch - mu;
          if (nl <= 0 || vdoth <= 0) continue;
          const double aL = std::sqrt(nl * nl * (1 - a2) + a2);
          const double w = 2 * nl / (nl * aV + mu * aL) * vdoth / ch;  // G2/μ · (V·H)/(N·H)
          sumA += w * (1 - std::pow(1 - vdoth, 5));
        }
        const size_t t = size_t(j) * m + i;
        eN = std::max(eN, std::abs(sumA / ns - ref16.a[t]));
        eV = std::max(eV, std::abs(double(k16.a[t]) - ref16.a[t]));
      }
      g << i << "," << fmt(mu) << "," << fmt(eN) << "," << fmt(eV) << "\n";
      worstNdf = std::max(worstNdf, eN), worstV = std::max(worstV, eV);
      if (i < 2) std::printf("16^2 column %d (mu %.4f): NDF sampling max |dA| %.3g, VNDF kernel %.3g\n", i, mu, eN, eV);
    }
    json << "  \"grazing_16\": {\"ndf_sampling_max_abs_err_A\": " << fmt(worstNdf)
         << ", \"vndf_kernel_max_abs_err_A\": " << fmt(worstV) << "},\n";
  }

  // --- precise vs native ---
  std::ofstream prec(dir + "/lut_precision.csv");
  prec << "directions,fast_math,kernel_ms_median,cpu_per_core_ms_median,max_abs_err,rms_err,max_abs_diff_vs_default\n";
  const LutResult base = computeLut(rt, LutOptions{});
  json << "  \"precision\": [\n";
  const char* dirNames[] = {"table", "precise-trig", "native-trig"};
  bool firstP = true;
  for (int d = 0; d < 3; ++d)
    for (bool fast : {false, true}) {
      LutOptions o;
      o.directions = LutDirections(d);
      o.fastMath = fast;
      LutResult r;
      double cpu = 0;
      const double t = kernelMedian(rt, o, 5, &r, &cpu);
      const Err e = compareTable(r, ref, allRows);
      double diff = 0;
      for (size_t i = 0; i < r.a.size(); ++i)
        diff = std::max({diff, double(std::abs(r.a[i] - base.a[i])), double(std::abs(r.b[i] - base.b[i]))});
      std::printf("directions %-12s fast-math %d: kernel %8.2f ms (cpu/core %7.2f), max |d| %.3g, rms %.3g, "
                  "max |diff vs default| %.3g\n",
                  dirNames[d], fast, t * 1e3, cpu * 1e3, e.maxAbs, e.rms, diff);
      prec << dirNames[d] << "," << fast << "," << fmt(t * 1e3) << "," << fmt(cpu * 1e3) << "," << fmt(e.maxAbs) << ","
           << fmt(e.rms) << "," << fmt(diff) << "\n";
      json << (firstP ? "" : ",\n") << "    {\"directions\": \"" << dirNames[d] << "\", \"fast_math\": " << fast
           << ", \"kernel_ms\": " << fmt(t * 1e3) << ", \"cpu_per_core_ms\": " << fmt(cpu * 1e3)
           << ", \"max_abs_err\": " << fmt(e.maxAbs) << ", \"rms_err\": " << fmt(e.rms)
           << ", \"max_abs_diff_vs_default\": " << fmt(diff) << "}";
      firstP = false;
    }
  json << "\n  ],\n";

  // --- convergence ---
  std::vector<int> rows;
  for (int j = 0; j < n; j += 4) rows.push_back(j);
  rows.push_back(n - 1);
  std::vector<int> samples;
  std::vector<double> maxErr, rmsErr, stdErr;
  std::ofstream conv(dir + "/lut_convergence.csv");
  conv << "samples,max_abs_err,rms_err,mean_std_error\n";
  json << "  \"convergence\": [\n";
  for (int s = 16; s <= 65536; s *= 2) {
    LutOptions o;
    o.samples = s;
    const LutResult r = computeLut(rt, o);
    LutValues sub;
    for (int j : rows)
      for (int i = 0; i < n; ++i) {
        sub.a.push_back(ref.a[size_t(j) * n + i]);
        sub.b.push_back(ref.b[size_t(j) * n + i]);
      }
    const Err e = compareTable(r, sub, rows);
    samples.push_back(s);
    maxErr.push_back(e.maxAbs);
    rmsErr.push_back(e.rms);
    stdErr.push_back(r.stdErrMean);
    conv << s << "," << fmt(e.maxAbs) << "," << fmt(e.rms) << "," << fmt(r.stdErrMean) << "\n";
    json << "    {\"samples\": " << s << ", \"max_abs_err\": " << fmt(e.maxAbs) << ", \"rms_err\": " << fmt(e.rms)
         << ", \"mean_std_error\": " << fmt(r.stdErrMean) << "}" << (s < 65536 ? ",\n" : "\n");
    std::printf("samples %6d: max |d| %.3g, rms %.3g, mean std error %.3g\n", s, e.maxAbs, e.rms, r.stdErrMean);
  }
  // Least-squares slope of log rms error against log samples.
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  const double m = double(samples.size());
  for (size_t i = 0; i < samples.size(); ++i) {
    const double x = std::log(samples[i]), y = std::log(rmsErr[i]);
    sx += x, sy += y, sxx += x * x, sxy += x * y;
  }
  const double slope = (m * sxy - sx * sy) / (m * sxx - sx * sx);
  std::printf("rms error ~ n^%.2f\n", slope);
  json << "  ],\n  \"rms_slope\": " << fmt(slope) << "\n}\n";
  writeSvg(dir + "/lut_convergence.svg", samples, maxErr, rmsErr, stdErr);
  std::ofstream(dir + "/lut.json") << json.str();
  std::printf("wrote %s/lut.json and CSV/SVG files\n", dir.c_str());
  return 0;
} catch (const std::exception& e) {  // a bad argument or a missing device: one line, no abort
  std::fprintf(stderr, "%s: %s\n", argv[0], e.what());
  return 1;
}
