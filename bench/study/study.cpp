// The speed-against-accuracy study (bench/study/run.sh builds and runs it; plots and
// docs/accuracy.md come from make_report.py). For every product it sweeps the knobs
// that trade speed for accuracy and writes one CSV row per (curve, point):
//   product,curve,param,value,wall_s,cpu_s,err_max,err_rms,samples_total,ref_bound
// err_* are against a high-accuracy reference (named in the curve's product block);
// wall_s and cpu_s (process CPU time, all threads) are medians over the repetitions.
// "--tolerance E" runs are rows of the curve <case>-tolerance (param "tolerance"), each
// followed by the comment lines
//   #tolerance,PRODUCT,CASE,E,FRACTION_WITHIN_E,COUNTS
//   #paired,PRODUCT,CASE,E,N,TOLERANCE_S,UNIFORM_S
// (COUNTS: the count of each term, '/'-separated; #paired: see pairedTiming), and every case has a "uniform" sweep of
// --samples N over powers of two (curve <case>-uniform), against which make_report.py
// finds the fastest run at the same maximum error. Curves <case>-monotone hold the
// maximum error from 2^10 to 2^24 samples per item.
#include <sys/resource.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "prtbake/env.h"
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
  if (warm) {
    // Runs of a few milliseconds vary by tens of per cent from one to the next (thread
    // wake-ups, launches): take the median of enough of them to fill about half a second.
    const auto t0 = std::chrono::steady_clock::now();
    f();
    const double once = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    reps = std::clamp(int(0.5 / std::max(once, 1e-6)), reps, 25);
  }
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

// The --tolerance run beside the uniform run it is judged by: the smallest count of the
// sweep (count, max error) whose maximum error is at most the tolerance run's, both timed in
// alternation (medians of at least 9 pairs, enough to fill about a second), so that their
// ratio does not move with the machine's speed between the sweeps. Writes
//   #paired,PRODUCT,CASE,E,N,TOLERANCE_S,UNIFORM_S
// and nothing when no count of the sweep reaches that error.
void pairedTiming(const std::string& product, const std::string& name, double tol,
                  const std::vector<std::pair<int, double>>& sweep, double errMax, const std::function<void()>& tolRun,
                  const std::function<void(int)>& uniformRun) {
  int n = 0;
  for (const auto& [count, err] : sweep)
    if (err <= errMax && (n == 0 || count < n)) n = count;
  if (n == 0) return;
  auto seconds = [](const std::function<void()>& f) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  std::vector<double> a, b;
  double spent = 0;
  while (a.size() < 9 || (spent < 1.0 && a.size() < 41)) {
    a.push_back(seconds(tolRun));
    b.push_back(seconds([&] { uniformRun(n); }));
    spent += a.back() + b.back();
  }
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  std::fprintf(gOut, "#paired,%s,%s,%g,%d,%.6g,%.6g\n", product.c_str(), name.c_str(), tol, n, a[a.size() / 2],
               b[b.size() / 2]);
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

// The fraction of items whose worst error is within e.
double fractionWithin(const std::vector<double>& perItem, double e) {
  size_t n = 0;
  for (double x : perItem) n += x <= e;
  return perItem.empty() ? 1.0 : double(n) / double(perItem.size());
}

std::string countsText(const std::vector<ToleranceReport>& terms) {
  std::string t;
  for (const auto& r : terms) t += (t.empty() ? "" : "/") + std::to_string(r.samples);
  return t.empty() ? "0" : t;
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
  cases.push_back({"cavity-shadowed", makeOpenSphereCavity(1.0, kPi / 3, 12, 48), TransportMode::Shadowed});
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
      const int rs = refSamples;
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
    // The samplers, every fourth power of two.
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
    // The default sampler at every power of two: the uniform runs --tolerance is judged by.
    std::vector<std::pair<int, double>> sweep;
    for (int n = 16; n <= top; n *= 2) {
      TransportOptions o = base;
      o.samples = n;
      TransportResult r;
      const Timing t = timeIt(3, true, [&] { r = computeTransport(rt, c.mesh, o); });
      const Err e = perVertex(coeffsOf(r), ref, nc);
      row("transport", c.name + "-uniform", "samples", n, t, e.max, e.rms, double(r.totalSamples), refBound);
      sweep.emplace_back(n, e.max);
    }
    for (double tol : {2e-2, 1e-2, 5e-3, 2e-3, 1e-3}) {
      TransportOptions o = base;
      o.tolerance = tol;
      TransportResult r;
      const Timing t = timeIt(3, true, [&] { r = computeTransport(rt, c.mesh, o); });
      const Err e = perVertex(coeffsOf(r), ref, nc);
      row("transport", c.name + "-tolerance", "tolerance", tol, t, e.max, e.rms, double(r.totalSamples), refBound);
      std::fprintf(gOut, "#tolerance,transport,%s,%g,%.6f,%s\n", c.name.c_str(), tol,
                   fractionWithin(vertexErrors(coeffsOf(r), ref, nc), tol), countsText(r.tolerance).c_str());
      pairedTiming("transport", c.name, tol, sweep, e.max, [&] { computeTransport(rt, c.mesh, o); }, [&](int n) {
        TransportOptions u = base;
        u.samples = n;
        computeTransport(rt, c.mesh, u);
      });
    }
    if (c.mode == TransportMode::Interreflected) continue;
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

// A closed box [−1, 1]² × [0, 1] (normals inward) with a square hole [−h, h]² in its
// ceiling; vertices 0 … 15 lie on its floor, normal +z, at x, y ∈ {−0.6, −0.2, 0.2, 0.6}.
// Seen from there only the hole is open, so T_00 = Y_0 × F, F the form factor of the
// hole from the ray origin, exact by Lambert's polygon formula
//   F = (1/2π) |Σ_i γ_i n·(r_i × r_{i+1})/|r_i × r_{i+1}||,  γ_i the angle between the
// unit vectors r_i, r_{i+1} to consecutive corners.
Mesh holeBox(double h) {
  Mesh m;
  auto vertex = [&](double x, double y, double z, double nx, double ny, double nz) {
    m.positions.insert(m.positions.end(), {float(x), float(y), float(z)});
    m.normals.insert(m.normals.end(), {float(nx), float(ny), float(nz)});
    m.albedo.insert(m.albedo.end(), {1, 1, 1});
    return uint32_t(m.vertexCount() - 1);
  };
  // Floor: a 6 × 6 grid over [−1, 1]², its 16 inner vertices first.
  const double g[6] = {-1, -0.6, -0.2, 0.2, 0.6, 1};
  uint32_t id[6][6];
  for (int pass = 0; pass < 2; ++pass)
    for (int j = 0; j < 6; ++j)
      for (int i = 0; i < 6; ++i) {
        const bool inner = i > 0 && i < 5 && j > 0 && j < 5;
        if (inner == (pass == 0)) id[j][i] = vertex(g[i], g[j], 0, 0, 0, 1);
      }
  for (int j = 0; j < 5; ++j)
    for (int i = 0; i < 5; ++i)
      m.indices.insert(m.indices.end(), {id[j][i], id[j][i + 1], id[j + 1][i + 1], id[j][i], id[j + 1][i + 1], id[j + 1][i]});
  // A quad facing n (corners counter-clockwise seen from the side n points to).
  auto quad = [&](std::array<std::array<double, 3>, 4> c, std::array<double, 3> n) {
    uint32_t q[4];
    for (int k = 0; k < 4; ++k) q[k] = vertex(c[k][0], c[k][1], c[k][2], n[0], n[1], n[2]);
    m.indices.insert(m.indices.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
  };
  quad({{{1, -1, 0}, {1, 1, 0}, {1, 1, 1}, {1, -1, 1}}}, {-1, 0, 0});
  quad({{{-1, 1, 0}, {-1, -1, 0}, {-1, -1, 1}, {-1, 1, 1}}}, {1, 0, 0});
  quad({{{1, 1, 0}, {-1, 1, 0}, {-1, 1, 1}, {1, 1, 1}}}, {0, -1, 0});
  quad({{{-1, -1, 0}, {1, -1, 0}, {1, -1, 1}, {-1, -1, 1}}}, {0, 1, 0});
  // Ceiling around the hole, facing down.
  quad({{{-1, h, 1}, {1, h, 1}, {1, 1, 1}, {-1, 1, 1}}}, {0, 0, -1});
  quad({{{-1, -1, 1}, {1, -1, 1}, {1, -h, 1}, {-1, -h, 1}}}, {0, 0, -1});
  quad({{{-1, -h, 1}, {-h, -h, 1}, {-h, h, 1}, {-1, h, 1}}}, {0, 0, -1});
  quad({{{h, -h, 1}, {1, -h, 1}, {1, h, 1}, {h, h, 1}}}, {0, 0, -1});
  // The winding above is clockwise from inside for some quads: transport uses the
  // vertex normals given and the geometric normal only to offset ray origins, which
  // only floor vertices use here.
  return m;
}

double holeFormFactor(const double o[3], double h) {
  h = double(float(h));  // the corners as the mesh holds them
  const double c[4][2] = {{-h, -h}, {h, -h}, {h, h}, {-h, h}};
  double r[4][3];
  for (int k = 0; k < 4; ++k) {
    const double v[3] = {c[k][0] - o[0], c[k][1] - o[1], 1 - o[2]};
    const double len = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int a = 0; a < 3; ++a) r[k][a] = v[a] / len;
  }
  double sum = 0;
  for (int k = 0; k < 4; ++k) {
    const double* a = r[k];
    const double* b = r[(k + 1) % 4];
    const double cx = a[1] * b[2] - a[2] * b[1], cy = a[2] * b[0] - a[0] * b[2], cz = a[0] * b[1] - a[1] * b[0];
    const double cl = std::sqrt(cx * cx + cy * cy + cz * cz);
    const double gamma = std::atan2(cl, a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
    sum += gamma * cz / cl;  // n = +z
  }
  return std::abs(sum) / (2 * kPi);
}

// More samples never make a product worse: the maximum error from 2^10 to 2^24 samples
// per item, against closed forms. Transport: T_00 of the 16 floor vertices of holeBox;
// LUT: a 16² GGX table against the reference with four times its nodes (its own error
// < 1e-6).
void studyMonotone(Runtime& rt, int maxLog2) {
  const double h = 0.3, y0 = 0.28209479177387814;
  const Mesh box = holeBox(h);
  // Ray origins as transport.h defines them: p + ε n_g, ε = 1e-4 × the bounding-box
  // diagonal (3) + 1e-6 × the largest coordinate (1), rounded to float as the kernel reads them.
  const double eps = 1e-4 * 3.0 + 1e-6 * 1.0;
  std::vector<double> expect(16);
  for (size_t v = 0; v < 16; ++v) {
    const double o[3] = {box.positions[3 * v], box.positions[3 * v + 1], double(float(eps))};
    expect[v] = y0 * holeFormFactor(o, h);
  }
  for (int k = 10; k <= maxLog2; k += 2) {
    TransportOptions o;
    o.samples = 1 << k;
    o.vertexCount = 16;
    TransportResult r;
    const Timing t = timeIt(1, false, [&] { r = computeTransport(rt, box, o); });
    double e = 0, s2 = 0;
    for (size_t v = 0; v < r.vertexCount; ++v) {
      const double d = std::abs(double(r.vertex(v)[0]) - expect[v]);
      e = std::max(e, d), s2 += d * d;
    }
    row("transport", "holebox-monotone", "samples", o.samples, t, e, std::sqrt(s2 / double(r.vertexCount)),
        double(o.samples) * 16, 0);
  }
  LutOptions o;
  o.size = 16;
  std::vector<LutPoint> pts;
  for (int j = 0; j < o.size; ++j)
    for (int i = 0; i < o.size; ++i) pts.push_back({(i + 0.5) / o.size, (j + 0.5) / o.size});
  const LutValues ref = evaluateLutReference(o, pts, 4);
  for (int k = 10; k <= maxLog2; k += 2) {
    o.samples = 1 << k;
    if (o.samples > kLutMaxSamples) break;
    LutValues v;
    const Timing t = timeIt(1, false, [&] { v = evaluateLut(rt, o, pts); });
    double e = 0, s2 = 0;
    for (size_t i = 0; i < pts.size(); ++i) {
      const double d = std::max(std::abs(v.a[i] - ref.a[i]), std::abs(v.b[i] - ref.b[i]));
      e = std::max(e, d), s2 += d * d;
    }
    row("lut", "ggx16-monotone", "samples", o.samples, t, e, std::sqrt(s2 / double(pts.size())),
        double(o.samples) * double(pts.size()), 0);
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
    // The default table at every power of two: the uniform runs --tolerance is judged by.
    std::vector<std::pair<int, double>> sweep;
    for (int n = 16; n <= maxSamples; n *= 2) {
      LutOptions o = base;
      o.samples = n;
      LutResult r;
      const Timing t = timeIt(3, true, [&] { r = computeLut(rt, o); });
      std::vector<double> rv(r.a.begin(), r.a.end());
      rv.insert(rv.end(), r.b.begin(), r.b.end());
      const Err e = diff(rv, refv);
      row("lut", nd + "-uniform", "samples", n, t, e.max, e.rms, double(r.totalSamples), bound);
      sweep.emplace_back(n, e.max);
    }
    for (double tol : {1e-2, 3e-3, 1e-3, 3e-4, 1e-4}) {
      LutOptions o = base;
      o.tolerance = tol;
      LutResult r;
      const Timing t = timeIt(3, true, [&] { r = computeLut(rt, o); });
      std::vector<double> rv(r.a.begin(), r.a.end());
      rv.insert(rv.end(), r.b.begin(), r.b.end());
      const Err e = diff(rv, refv);
      const size_t texels = size_t(size) * size;
      std::vector<double> perTexel(texels);
      for (size_t i = 0; i < texels; ++i)
        perTexel[i] = std::max(std::abs(rv[i] - refv[i]), std::abs(rv[texels + i] - refv[texels + i]));
      row("lut", nd + "-tolerance", "tolerance", tol, t, e.max, e.rms, double(r.totalSamples), bound);
      std::fprintf(gOut, "#tolerance,lut,%s,%g,%.6f,%d\n", nd.c_str(), tol, fractionWithin(perTexel, tol),
                   r.tolerance.samples);
      pairedTiming("lut", nd, tol, sweep, e.max, [&] { computeLut(rt, o); }, [&](int n) {
        LutOptions u = base;
        u.samples = n;
        computeLut(rt, u);
      });
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
  std::fprintf(gOut, "product,curve,param,value,wall_s,cpu_s,err_max,err_rms,samples_total,ref_bound\n");
  Runtime rt("cpu");
  std::fprintf(stderr, "device: %s\n", rt.deviceLabel().c_str());
  // STUDY_ONLY=env|lut|transport|monotone runs one part (for debugging a sweep).
  const std::string only = std::getenv("STUDY_ONLY") ? std::getenv("STUDY_ONLY") : "";
  if (only.empty() || only == "env") studyEnv(rt, argv[2]);
  if (only.empty() || only == "lut") studyLut(rt, quick ? 32 : 128, quick ? 4096 : 65536);
  if (only.empty() || only == "transport") studyTransport(rt, quick ? 1024 : 16384, quick ? 4096 : 32768);
  if (only.empty() || only == "monotone") studyMonotone(rt, quick ? 16 : 24);
  std::fclose(gOut);
  return 0;
}
