// The speed-against-accuracy study (bench/study/run.sh builds and runs it; plots and
// docs/accuracy.md come from make_report.py). For every product it sweeps the knobs
// that trade speed for accuracy and writes one CSV row per (curve, point):
//   product,curve,param,value,wall_s,cpu_s,err_max,err_rms,samples_total,ref_bound
// err_* are against a high-accuracy reference (named in the curve's product block);
// wall_s and cpu_s (process CPU time, all threads) are medians over the repetitions.
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "prtbake/env_sh.h"
#include "prtbake/envmap.h"
#include "prtbake/lut.h"
#include "prtbake/mesh.h"
#include "prtbake/runtime.h"
#include "prtbake/sh.h"
#include "prtbake/transport.h"

using namespace prtbake;

namespace {
const double kPi = 3.14159265358979323846;
FILE* gOut = nullptr;
std::string gPerVertexPath;  // bumpy-shadowed per-vertex errors (next to the CSV)

double cpuNow() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

struct Timing {
  double wall = 0, cpu = 0;
};

// Runs f `reps` times (after one untimed warm-up when warm is set); medians.
Timing timeIt(int reps, bool warm, const std::function<void()>& f) {
  if (warm) f();
  std::vector<double> w, c;
  for (int i = 0; i < reps; ++i) {
    const double c0 = cpuNow();
    const auto t0 = std::chrono::steady_clock::now();
    f();
    w.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    c.push_back(cpuNow() - c0);
  }
  std::sort(w.begin(), w.end());
  std::sort(c.begin(), c.end());
  return {w[w.size() / 2], c[c.size() / 2]};
}

void row(const std::string& product, const std::string& curve, const std::string& param, double value, Timing t,
         double errMax, double errRms, double samplesTotal, double refBound) {
  std::fprintf(gOut, "%s,%s,%s,%.8g,%.6g,%.6g,%.6g,%.6g,%.8g,%.6g\n", product.c_str(), curve.c_str(), param.c_str(),
               value, t.wall, t.cpu, errMax, errRms, samplesTotal, refBound);
  std::fflush(gOut);
  std::fprintf(stderr, "%-10s %-26s %s=%-8g wall %.4fs cpu %.4fs max %.3g rms %.3g\n", product.c_str(), curve.c_str(),
               param.c_str(), value, t.wall, t.cpu, errMax, errRms);
}

struct Err {
  double max = 0, rms = 0;
};
Err diff(const std::vector<double>& a, const std::vector<double>& b) {
  Err e;
  double s = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    const double d = std::abs(a[i] - b[i]);
    e.max = std::max(e.max, d);
    s += d * d;
  }
  e.rms = a.empty() ? 0 : std::sqrt(s / double(a.size()));
  return e;
}

// --- environment projection ---
std::vector<double> flat(const ShCoeffs& c) {
  std::vector<double> v;
  for (const auto& x : c.rgb) v.insert(v.end(), x.begin(), x.end());
  return v;
}

void studyEnv(Runtime& rt, const std::string& skyPath) {
  const EnvMap sky = loadEnvironment(skyPath);
  std::fprintf(stderr, "env: %s, %lld texels\n", skyPath.c_str(), (long long)sky.texelCount());
  // Reference: the double host projection (same texels, directions, solid angles).
  for (int order : {2, 3, 4, 5, 6, 8}) {
    ShCoeffs ref;
    const Timing tr = timeIt(1, false, [&] { ref = projectEnvironmentReference(sky, order); });
    const std::vector<double> r = flat(ref);
    double scale = 0;
    for (double x : r) scale = std::max(scale, std::abs(x));
    row("env", "double-reference", "order", order, tr, 0, 0, double(sky.texelCount()), 0);
    for (int vw : {1, 8, 16}) {
      for (int rows : {0, 1, 4, 16}) {
        EnvProjectOptions o;
        o.order = order, o.vectorWidth = vw, o.rowsPerGroup = rows;
        EnvProjectResult res;
        Timing t;
        try {
          t = timeIt(3, true, [&] { res = projectEnvironment(rt, sky, o); });
        } catch (const std::exception& e) {
          std::fprintf(stderr, "env vw %d rows %d: %s\n", vw, rows, e.what());
          continue;
        }
        const Err e = diff(flat(res.radiance), r);
        row("env", "float-vw" + std::to_string(vw) + "-rows" + std::to_string(rows), "order", order, t,
            e.max / scale, e.rms / scale, double(sky.texelCount()), 0);
      }
    }
  }
}

// --- transport ---
std::vector<double> coeffsOf(const TransportResult& r) { return std::vector<double>(r.coeffs.begin(), r.coeffs.end()); }

std::vector<double> funkHecke(const Mesh& m, int order) {
  std::vector<double> out;
  for (size_t v = 0; v < m.vertexCount(); ++v) {
    const auto c = clampedCosineProjected(order, m.normals[3 * v], m.normals[3 * v + 1], m.normals[3 * v + 2]);
    out.insert(out.end(), c.begin(), c.end());
  }
  return out;
}

// Each vertex's worst coefficient error (stride coefficients per vertex).
std::vector<double> vertexErrors(const std::vector<double>& a, const std::vector<double>& b, int stride) {
  std::vector<double> w(a.size() / size_t(stride), 0.0);
  for (size_t v = 0; v < w.size(); ++v)
    for (int k = 0; k < stride; ++k) w[v] = std::max(w[v], std::abs(a[v * stride + k] - b[v * stride + k]));
  return w;
}

// Largest and RMS of the per-vertex worst coefficient errors.
Err perVertex(const std::vector<double>& a, const std::vector<double>& b, int stride) {
  Err e;
  double s = 0;
  const std::vector<double> w = vertexErrors(a, b, stride);
  for (double x : w) e.max = std::max(e.max, x), s += x * x;
  e.rms = w.empty() ? 0 : std::sqrt(s / double(w.size()));
  return e;
}

void studyTransport(Runtime& rt, int maxSamples, int refSamples) {
  const TransportSampler samplers[] = {TransportSampler::Hammersley, TransportSampler::Stratified,
                                       TransportSampler::Random};
  struct Case {
    std::string name;
    Mesh mesh;
    TransportMode mode;
  };
  std::vector<Case> cases;
  cases.push_back({"sphere-unoccluded", makeUvSphere(1.0, 24, 48), TransportMode::Shadowed});
  cases.push_back({"bumpy-shadowed", makeBumpySphere(2000), TransportMode::Shadowed});
  // The open cavity of tests/test_tolerance.cpp (every vertex occludable, one smooth edge).
  cases.push_back({"cavity-shadowed", makeOpenSphereCavity(1.0, 3.14159265358979323846 / 3, 12, 48),
                   TransportMode::Shadowed});
  cases.push_back({"bumpy-interreflected", makeBumpySphere(2000), TransportMode::Interreflected});
  for (const Case& c : cases) {
    const int order = 3, nc = order * order;
    TransportOptions base;
    base.mode = c.mode;
    base.order = order;
    base.bounces = 2;
    base.bounceTolerance = 0;
    base.albedoOverride = std::array<float, 3>{0.8f, 0.8f, 0.8f};
    std::vector<double> ref;
    double refBound = 0;
    if (c.name == "sphere-unoccluded") {
      ref = funkHecke(c.mesh, order);
    } else {
      // A converged run, and its own error bound: two independent seeds differ by
      // √2 × the error of one (max over vertices of the worst coefficient).
      const int rs = c.mode == TransportMode::Interreflected ? refSamples / 4 : refSamples;
      TransportOptions ro = base;
      ro.samples = rs;
      TransportResult a, b;
      const Timing t = timeIt(1, false, [&] { a = computeTransport(rt, c.mesh, ro); });
      ro.seed = 99;
      b = computeTransport(rt, c.mesh, ro);
      const std::vector<double> va = coeffsOf(a), vb = coeffsOf(b);
      ref.resize(va.size());
      for (size_t i = 0; i < va.size(); ++i) ref[i] = 0.5 * (va[i] + vb[i]);
      const Err e = perVertex(va, vb, nc);
      refBound = e.max / std::sqrt(2.0) / std::sqrt(2.0);  // the mean of the two
      row("transport", c.name + "-reference", "samples", 2.0 * rs, t, refBound, e.rms / 2, 2.0 * rs * c.mesh.vertexCount(),
          refBound);
    }
    const std::vector<uint8_t> unocc = unoccludableVertices(c.mesh);
    std::fprintf(stderr, "transport %s: %zu vertices, %zu unoccludable\n", c.name.c_str(), c.mesh.vertexCount(),
                 size_t(std::count(unocc.begin(), unocc.end(), 1)));
    const int top = c.mode == TransportMode::Interreflected ? maxSamples / 4 : maxSamples;
    for (TransportSampler s : samplers) {
      for (int n = 16; n <= top; n *= 4) {
        TransportOptions o = base;
        o.samples = n;
        o.sampler = s;
        TransportResult r;
        const Timing t = timeIt(n <= 1024 ? 3 : 1, n <= 1024, [&] { r = computeTransport(rt, c.mesh, o); });
        const Err e = perVertex(coeffsOf(r), ref, nc);
        row("transport", c.name + "-" + transportSamplerName(s), "samples", n, t, e.max, e.rms,
            double(n) * c.mesh.vertexCount(), refBound);
      }
    }
    if (c.mode == TransportMode::Interreflected) continue;
    if (c.name == "bumpy-shadowed") {
      // Per-vertex errors of the default sampler on a 2^(1/2) grid of counts, for the
      // offline oracle bounds (replay_transport.py): one line per count, "N e_0 e_1 …".
      FILE* f = std::fopen(gPerVertexPath.c_str(), "w");
      if (!f) throw std::runtime_error("cannot write " + gPerVertexPath);
      for (int k = 0; k <= 16; ++k) {
        TransportOptions o = base;
        o.samples = int(std::lround(64 * std::pow(2.0, k / 2.0)));
        std::fprintf(f, "%d", o.samples);
        for (double w : vertexErrors(coeffsOf(computeTransport(rt, c.mesh, o)), ref, nc)) std::fprintf(f, " %.4g", w);
        std::fprintf(f, "\n");
      }
      std::fclose(f);
    }
    for (double tol : {2e-2, 1e-2, 5e-3, 2e-3, 1e-3}) {
      TransportOptions o = base;
      o.tolerance = tol;
      TransportResult r;
      const Timing t = timeIt(1, false, [&] { r = computeTransport(rt, c.mesh, o); });
      const Err e = perVertex(coeffsOf(r), ref, nc);
      const std::vector<double> w = vertexErrors(coeffsOf(r), ref, nc);
      const size_t below = size_t(std::count_if(w.begin(), w.end(), [tol](double x) { return x < tol; }));
      row("transport", c.name + "-adaptive", "tolerance", tol, t, e.max, e.rms, double(r.totalSamples), refBound);
      std::fprintf(gOut, "#adaptive,transport,%s,%g,%.6f,%zu,%zu,%g\n", c.name.c_str(), tol,
                   double(below) / double(c.mesh.vertexCount()), r.verticesAtCap, r.verticesUnoccludable,
                   r.maxErrorEstimate);
    }
    // Packet width (the only work-size knob of the transport kernels; local size is 16).
    for (int pw : {0, 8, 16}) {
      TransportOptions o = base;
      o.samples = 1024;
      o.packetWidth = pw;
      TransportResult r;
      const Timing t = timeIt(3, true, [&] { r = computeTransport(rt, c.mesh, o); });
      const Err e = perVertex(coeffsOf(r), ref, nc);
      row("transport", c.name + "-packet" + std::to_string(pw), "samples", 1024, t, e.max, e.rms,
          1024.0 * c.mesh.vertexCount(), refBound);
    }
  }
}

// --- LUT ---
void studyLut(Runtime& rt, int size, int maxSamples) {
  for (LutNdf ndf : {LutNdf::Ggx, LutNdf::Beckmann}) {
    LutOptions base;
    base.size = size;
    base.ndf = ndf;
    LutResult ref;
    const Timing tr = timeIt(1, false, [&] { ref = computeLutReference(base); });
    // The reference's own bound: its change when the nodes are doubled per axis.
    std::vector<LutPoint> pts;
    for (int j = 0; j < size; j += 7)
      for (int i = 0; i < size; i += 3) pts.push_back({(i + 0.5) / size, (j + 0.5) / size});
    const LutValues r1 = evaluateLutReference(base, pts, 1), r2 = evaluateLutReference(base, pts, 2);
    double bound = 0;
    for (size_t i = 0; i < pts.size(); ++i)
      bound = std::max({bound, std::abs(r1.a[i] - r2.a[i]), std::abs(r1.b[i] - r2.b[i])});
    bound = std::max(bound, 1e-7);
    const std::string nd = lutNdfName(ndf);
    std::vector<double> refv(ref.a.begin(), ref.a.end());
    refv.insert(refv.end(), ref.b.begin(), ref.b.end());
    row("lut", nd + "-reference", "samples", 0, tr, bound, 0, 0, bound);
    struct Variant {
      std::string name;
      LutDirections dirs;
      bool fast;
    };
    std::vector<Variant> variants = {{"table", LutDirections::Table, false}};
    if (ndf == LutNdf::Ggx) {
      variants.push_back({"table-fastmath", LutDirections::Table, true});
      variants.push_back({"precise-trig", LutDirections::PreciseTrig, false});
      variants.push_back({"native-trig", LutDirections::NativeTrig, false});
      variants.push_back({"native-trig-fastmath", LutDirections::NativeTrig, true});
    }
    for (const Variant& v : variants) {
      for (int n = 16; n <= maxSamples; n *= 4) {
        LutOptions o = base;
        o.samples = n;
        o.directions = v.dirs;
        o.fastMath = v.fast;
        LutResult r;
        const Timing t = timeIt(3, true, [&] { r = computeLut(rt, o); });
        std::vector<double> rv(r.a.begin(), r.a.end());
        rv.insert(rv.end(), r.b.begin(), r.b.end());
        const Err e = diff(rv, refv);
        row("lut", nd + "-" + v.name, "samples", n, t, e.max, e.rms, double(n) * size * size, bound);
      }
    }
    for (double tol : {1e-2, 3e-3, 1e-3, 3e-4, 1e-4}) {
      LutOptions o = base;
      o.tolerance = tol;
      LutResult r;
      const Timing t = timeIt(1, true, [&] { r = computeLut(rt, o); });
      std::vector<double> rv(r.a.begin(), r.a.end());
      rv.insert(rv.end(), r.b.begin(), r.b.end());
      const Err e = diff(rv, refv);
      size_t below = 0;
      const size_t texels = size_t(size) * size;
      for (size_t i = 0; i < texels; ++i)
        below += std::max(std::abs(rv[i] - refv[i]), std::abs(rv[texels + i] - refv[texels + i])) < tol;
      row("lut", nd + "-adaptive", "tolerance", tol, t, e.max, e.rms, double(r.totalSamples), bound);
      std::fprintf(gOut, "#adaptive,lut,%s,%g,%.6f,%zu,0,%g\n", nd.c_str(), tol, double(below) / double(texels),
                   r.texelsAtCap, r.errorEstimateMax);
    }
  }
}
}  // namespace

int main(int argc, char** argv) {
  // study OUT.csv SKY.exr [quick]
  if (argc < 3) {
    std::fprintf(stderr, "usage: study OUT.csv SKY.exr [quick]\n");
    return 2;
  }
  const bool quick = argc > 3 && std::string(argv[3]) == "quick";
  gOut = std::fopen(argv[1], "w");
  if (!gOut) return 1;
  const std::string csv = argv[1];
  gPerVertexPath = csv.substr(0, csv.find_last_of('/') + 1) + "transport_pervertex.txt";
  std::fprintf(gOut, "product,curve,param,value,wall_s,cpu_s,err_max,err_rms,samples_total,ref_bound\n");
  Runtime rt("cpu");
  std::fprintf(stderr, "device: %s\n", rt.deviceLabel().c_str());
  // STUDY_ONLY=env|lut|transport runs one product (for debugging a sweep).
  const std::string only = std::getenv("STUDY_ONLY") ? std::getenv("STUDY_ONLY") : "";
  if (only.empty() || only == "env") studyEnv(rt, argv[2]);
  if (only.empty() || only == "lut") studyLut(rt, quick ? 32 : 64, quick ? 4096 : 65536);
  if (only.empty() || only == "transport") studyTransport(rt, quick ? 1024 : 16384, quick ? 4096 : 32768);
  std::fclose(gOut);
  return 0;
}
