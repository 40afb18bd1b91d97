// BRDF LUT: the double reference against closed forms and an independent quadrature,
// the kernel against the reference (grazing columns included), bounds at every texel,
// the extremes μ = 0, r = 0, r = 1 through the point API, Kulla–Conty, files and errors.
#include <catch2/catch.hpp>

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <vector>

#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/lut.h"
#include "test_common.h"

using namespace prtbake;

namespace {
const double kPi = 3.14159265358979323846;

// Acceptance (issue 3): kernel vs reference at 128² × 1024 samples, grazing included.
constexpr double kKernelTol1024 = 2e-3;
// Acceptance: at 16384 samples (measured ~7e-5; the float sums stay below 1e-5).
constexpr double kKernelTol16384 = 5e-4;
// The cloth table reaches ~4 at grazing view and small α (Ashikhmin's 1/(4(ν+μ−νμ))
// is not energy conserving), so its error is taken relative to max(1, C). Measured worst
// 1.9e-3 over every third row (bench_lut), always in the first column μ = 1/256 where g
// drops to 0 within Δν ~ μ; 2.5e-3 leaves room for the rows the test does not sample.
constexpr double kClothRelTol1024 = 2.5e-3;
// Bound on A + B: the directional albedo of the f0 = 1 BRDF is at most 1; 1e-4 is the
// acceptance slack for float sums and the estimator's noise.
constexpr double kAlbedoSlack = 1e-4;
// A + B → 1 as r → 0 (acceptance: within 1e-3).
constexpr double kSmoothLimitTol = 1e-3;
// The reference with twice and four times the nodes per axis agrees to ~2e-5 (measured,
// worst at small α and grazing view); 5e-5 keeps it 40× below the kernel tolerance.
constexpr double kReferenceConvergedTol = 5e-5;
// Independent L-space midpoint quadrature (1000 × 720 cells, O(h²)): ~4e-6 for α ≥ 0.25.
constexpr double kIndependentQuadTol = 2e-5;
// Closed forms evaluated in double by the reference: quadrature error only.
constexpr double kClosedFormRefTol = 1e-5;

std::vector<LutPoint> texelRows(int n, const std::vector<int>& rows) {
  std::vector<LutPoint> pts;
  for (int j : rows)
    for (int i = 0; i < n; ++i) pts.push_back({(i + 0.5) / n, (j + 0.5) / n});
  return pts;
}

// Rows 0–3 (smallest roughness), every 8th, and the last of a 128 table.
std::vector<int> sampleRows128() {
  std::vector<int> rows = {0, 1, 2, 3};
  for (int j = 8; j < 128; j += 8) rows.push_back(j);
  rows.push_back(127);
  return rows;
}

struct Diff {
  double maxAbs = 0;
  size_t worst = 0;
  std::vector<double> perColumn;
};
Diff compare(const LutValues& k, const LutValues& r, int n, bool cloth = false) {
  Diff d;
  d.perColumn.assign(n, 0.0);
  for (size_t i = 0; i < k.a.size(); ++i) {
    double e = std::max(std::abs(k.a[i] - r.a[i]), std::abs(k.b[i] - r.b[i]));
    if (cloth) e = std::abs(k.cloth[i] - r.cloth[i]) / std::max(1.0, r.cloth[i]);
    d.perColumn[i % n] = std::max(d.perColumn[i % n], e);
    if (e > d.maxAbs) d.maxAbs = e, d.worst = i;
  }
  return d;
}

std::string columnReport(const Diff& d, int n) {
  std::string s = "max |delta| per N.V column (first 8, last):";
  char buf[32];
  for (int i = 0; i < 8; ++i) std::snprintf(buf, sizeof buf, " %.1e", d.perColumn[i]), s += buf;
  std::snprintf(buf, sizeof buf, " ... %.1e", d.perColumn[n - 1]);
  return s + buf;
}

// Reads channel `name` of an EXR into floats.
std::vector<float> readExrChannel(const std::string& path, const std::string& name, int& w, int& h) {
  Imf::InputFile in(path.c_str());
  const auto dw = in.header().dataWindow();
  w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
  std::vector<float> px(size_t(w) * h);
  Imf::FrameBuffer fb;
  fb.insert(name, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(px.data()), sizeof(float), sizeof(float) * w));
  in.setFrameBuffer(fb);
  in.readPixels(dw.min.y, dw.max.y);
  return px;
}

LutOptions variant(LutNdf ndf, LutVisibility vis) {
  LutOptions o;
  o.ndf = ndf;
  o.visibility = vis;
  return o;
}

const std::vector<LutOptions>& allVariants() {
  static const std::vector<LutOptions> v = [] {
    std::vector<LutOptions> out;
    for (auto ndf : {LutNdf::Ggx, LutNdf::Beckmann})
      for (auto vis : {LutVisibility::SmithCorrelated, LutVisibility::SmithSeparable, LutVisibility::SchlickGgx})
        out.push_back(variant(ndf, vis));
    return out;
  }();
  return v;
}

std::string name(const LutOptions& o) {
  return std::string(lutNdfName(o.ndf)) + "/" + lutVisibilityName(o.visibility);
}
}  // namespace

TEST_CASE("LUT reference is converged and meets closed forms at the extremes", "[lut][reference]") {
  std::vector<LutPoint> pts;
  for (double mu : {0.0, 1.0 / 256, 0.03, 0.2, 0.5, 0.9, 1.0})
    for (double r : {0.0, 0.004, 0.05, 0.2, 0.5, 0.8, 1.0}) pts.push_back({mu, r});
  for (const auto& o0 : allVariants()) {
    LutOptions o = o0;
    o.cloth = o.ndf == LutNdf::Ggx && o.visibility == LutVisibility::SmithCorrelated;
    const LutValues a = evaluateLutReference(o, pts, 2), b = evaluateLutReference(o, pts, 4);
    for (size_t i = 0; i < pts.size(); ++i) {
      INFO(name(o) << " mu=" << pts[i].mu << " r=" << pts[i].roughness);
      REQUIRE(std::abs(a.a[i] - b.a[i]) < kReferenceConvergedTol);
      REQUIRE(std::abs(a.b[i] - b.b[i]) < kReferenceConvergedTol);
      if (o.cloth) REQUIRE(std::abs(a.cloth[i] - b.cloth[i]) < kReferenceConvergedTol * std::max(1.0, b.cloth[i]));
    }
  }
  // GGX, α = 1 (D = 1/π), μ = 0: the weight G2/G1(V) → 1 and H follows the visible-normal
  // density 2(V·H)/π on the quarter sphere, so B = ∫ (2/π) t (1 − t)^5 dω / 2 = 1/21, A = 20/21.
  const LutValues g = evaluateLutReference(LutOptions{}, {{0.0, 1.0}});
  CHECK(g.b[0] == Approx(1.0 / 21).margin(kClosedFormRefTol));
  CHECK(g.a[0] == Approx(20.0 / 21).margin(kClosedFormRefTol));
  // r = 0 is a mirror: A = 1 − (1 − μ)^5, B = (1 − μ)^5, for every variant.
  for (const auto& o : allVariants()) {
    const LutValues m = evaluateLutReference(o, {{0.3, 0.0}});
    CHECK(m.b[0] == Approx(std::pow(0.7, 5)).margin(1e-15));
  }
}

TEST_CASE("LUT reference agrees with an independent quadrature over L", "[lut][reference]") {
  // f_r cos θ_l integrated on a midpoint grid in (cos θ_l, φ_l): no half-vector change of
  // variables, no horizon analysis — a check of the Jacobian and of the visibility forms.
  auto lSpace = [](double mu, double alpha, LutVisibility vis, double& a, double& b) {
    const double sv = std::sqrt(1 - mu * mu), a2 = alpha * alpha;
    const int nc = 1000, np = 720;
    a = b = 0;
    for (int ic = 0; ic < nc; ++ic) {
      const double nl = (ic + 0.5) / nc, sl = std::sqrt(1 - nl * nl);
      for (int ip = 0; ip < np; ++ip) {
        const double ph = 2 * kPi * (ip + 0.5) / np;
        double hx = sl * std::cos(ph) + sv, hy = sl * std::sin(ph), hz = nl + mu;
        const double len = std::sqrt(hx * hx + hy * hy + hz * hz);
        hx /= len, hy /= len, hz /= len;
        const double vdoth = sv * hx + mu * hz;
        const double t = hz * hz * (a2 - 1) + 1, d = a2 / (kPi * t * t);
        const double aV = std::sqrt(mu * mu * (1 - a2) + a2), aL = std::sqrt(nl * nl * (1 - a2) + a2);
        double vis4;  // G2 / (4 μ ν)
        if (vis == LutVisibility::SmithCorrelated) vis4 = 0.5 / (nl * aV + mu * aL);
        else if (vis == LutVisibility::SmithSeparable) vis4 = 1 / ((mu + aV) * (nl + aL));
        else {
          const double k = alpha / 2;
          vis4 = 0.25 / ((mu * (1 - k) + k) * (nl * (1 - k) + k));
        }
        const double fc = std::pow(1 - vdoth, 5), f = d * vis4 * nl * (1.0 / nc) * (2 * kPi / np);
        a += f * (1 - fc), b += f * fc;
      }
    }
  };
  for (auto vis : {LutVisibility::SmithCorrelated, LutVisibility::SmithSeparable, LutVisibility::SchlickGgx})
    for (double mu : {0.1, 0.6, 1.0})
      for (double r : {0.5, 1.0}) {
        double a, b;
        lSpace(mu, r * r, vis, a, b);
        const LutValues ref = evaluateLutReference(variant(LutNdf::Ggx, vis), {{mu, r}});
        INFO(lutVisibilityName(vis) << " mu=" << mu << " r=" << r);
        CHECK(ref.a[0] == Approx(a).margin(kIndependentQuadTol));
        CHECK(ref.b[0] == Approx(b).margin(kIndependentQuadTol));
      }
}

TEST_CASE("LUT kernel vs reference at 128^2 x 1024 samples per N.V column", "[lut][kernel]") {
  auto& rt = test::runtime();
  const int n = 128;
  const auto pts = texelRows(n, sampleRows128());
  for (const auto& o : allVariants()) {
    const LutValues k = evaluateLut(rt, o, pts), r = evaluateLutReference(o, pts);
    const Diff d = compare(k, r, n);
    INFO(name(o) << ": max |delta| " << d.maxAbs << " at mu=" << pts[d.worst].mu << " r=" << pts[d.worst].roughness);
    INFO(columnReport(d, n));
    WARN(name(o) << " " << columnReport(d, n));
    REQUIRE(d.maxAbs < kKernelTol1024);
  }
}

TEST_CASE("LUT kernel vs reference: cloth and alpha-direct at 128^2 x 1024 samples", "[lut][kernel]") {
  auto& rt = test::runtime();
  const int n = 128;
  const auto pts = texelRows(n, sampleRows128());
  {
    LutOptions o;
    o.cloth = true;
    o.alphaDirect = true;
    const LutValues k = evaluateLut(rt, o, pts), r = evaluateLutReference(o, pts);
    REQUIRE(compare(k, r, n).maxAbs < kKernelTol1024);
    const Diff dc = compare(k, r, n, true);
    INFO("cloth worst mu=" << pts[dc.worst].mu << " r=" << pts[dc.worst].roughness);
    REQUIRE(dc.maxAbs < kClothRelTol1024);
  }
}

TEST_CASE("LUT kernel vs reference at 16384 samples", "[lut][kernel]") {
  auto& rt = test::runtime();
  const int n = 128;
  const auto pts = texelRows(n, {0, 1, 4, 16, 40, 64, 96, 127});
  for (auto ndf : {LutNdf::Ggx, LutNdf::Beckmann}) {
    LutOptions o = variant(ndf, LutVisibility::SmithCorrelated);
    o.samples = 16384;
    const LutValues k = evaluateLut(rt, o, pts), r = evaluateLutReference(o, pts);
    const Diff d = compare(k, r, n);
    INFO(lutNdfName(ndf) << ": max |delta| " << d.maxAbs << " at mu=" << pts[d.worst].mu
                         << " r=" << pts[d.worst].roughness);
    WARN(lutNdfName(ndf) << " 16384 samples: " << columnReport(d, n));
    REQUIRE(d.maxAbs < kKernelTol16384);
  }
}

TEST_CASE("LUT kernel and reference at the exact extremes mu 0 and r 0 and r 1", "[lut][kernel]") {
  auto& rt = test::runtime();
  std::vector<LutPoint> pts;
  for (double mu : {0.0, 1e-6, 0.5, 1.0})
    for (double r : {0.0, 1e-6, 1e-4, 1e-3, 0.5, 1.0}) pts.push_back({mu, r});
  for (const auto& o0 : allVariants())
    for (bool direct : {false, true}) {
      LutOptions o = o0;
      o.alphaDirect = direct;
      o.cloth = true;
      const LutValues k = evaluateLut(rt, o, pts), r = evaluateLutReference(o, pts);
      for (size_t i = 0; i < pts.size(); ++i) {
        INFO(name(o) << (direct ? " alpha-direct" : "") << " mu=" << pts[i].mu << " r=" << pts[i].roughness
                     << " A=" << k.a[i] << " B=" << k.b[i] << " C=" << k.cloth[i]);
        REQUIRE(std::isfinite(k.a[i]));
        REQUIRE(std::isfinite(k.b[i]));
        REQUIRE(std::isfinite(k.cloth[i]));
        REQUIRE(std::isfinite(k.stdErr[i]));
        REQUIRE(k.a[i] >= 0);
        REQUIRE(k.b[i] >= 0);
        REQUIRE(k.cloth[i] >= 0);
        REQUIRE(k.a[i] + k.b[i] <= 1 + kAlbedoSlack);
        REQUIRE(std::abs(k.a[i] - r.a[i]) < kKernelTol1024);
        REQUIRE(std::abs(k.b[i] - r.b[i]) < kKernelTol1024);
        // A + B → 1 as r → 0 for μ > 0. At μ = 0 exactly the separable and Schlick forms keep
        // masking at the scale of α (V and most L graze), so their limit is below 1 there
        // (0.936 and 0.840 for GGX; the reference agrees); only the correlated form reaches 1.
        // For μ > 0 the limit needs α ≪ μ (μ = 1e-6, α = 1e-6 is still in the transition).
        const double alpha = lutAlpha(o, pts[i].roughness);
        const bool limitIsOne =
            pts[i].mu > 0 ? alpha < 1e-3 * pts[i].mu : o.visibility == LutVisibility::SmithCorrelated;
        if (limitIsOne)
          REQUIRE(std::abs(k.a[i] + k.b[i] - 1) < kSmoothLimitTol);
      }
    }
  // The mirror at r = 0 is exact; μ = 0, r = 1 is the closed form 1/21 (see the reference test).
  const LutValues m = evaluateLut(rt, LutOptions{}, {{0.0, 0.0}, {0.25, 0.0}, {0.0, 1.0}});
  CHECK(m.b[0] == 1.0f);
  CHECK(m.a[0] == 0.0f);
  CHECK(m.b[1] == Approx(std::pow(0.75, 5)).margin(1e-7));
  CHECK(m.b[2] == Approx(1.0 / 21).margin(kKernelTol1024));
}

TEST_CASE("LUT bounds at every texel of every variant for sizes 16 to 1024", "[lut][kernel]") {
  auto& rt = test::runtime();
  for (int size : {16, 17, 128, 1024}) {
    for (const auto& o0 : allVariants()) {
      LutOptions o = o0;
      o.size = size;
      // Bounds, not accuracy: few samples keep 1024² affordable, and few samples are where
      // an estimator without a structural bound would overshoot first.
      o.samples = size >= 1024 ? 32 : 256;
      o.cloth = o.ndf == LutNdf::Ggx && o.visibility == LutVisibility::SmithCorrelated;
      o.kullaConty = true;
      const LutResult lut = computeLut(rt, o);
      REQUIRE(lut.a.size() == size_t(size) * size);
      for (size_t t = 0; t < lut.a.size(); ++t) {
        INFO(name(o) << " size " << size << " texel " << t);
        REQUIRE(std::isfinite(lut.a[t]));
        REQUIRE(std::isfinite(lut.b[t]));
        REQUIRE(lut.a[t] >= 0);
        REQUIRE(lut.b[t] >= 0);
        REQUIRE(lut.a[t] + lut.b[t] <= 1 + kAlbedoSlack);
        if (o.cloth) REQUIRE((std::isfinite(lut.third[t]) && lut.third[t] >= 0));
      }
      for (float e : lut.eAvg) REQUIRE((std::isfinite(e) && e >= 0 && e <= 1 + kAlbedoSlack));
      REQUIRE(std::isfinite(lut.stdErrMax));
      // Row 0 (the smallest roughness) is within 1e-3 of a mirror for sizes ≥ 128; Schlick-GGX
      // approaches 1 more slowly at grazing view (G1_S(μ) = μ/(μ + k), k = α/2: 0.996 at
      // μ = 1/256, r = 1/256 in the reference too), so it is held to this at size 1024.
      if (size >= 128 && (o.visibility != LutVisibility::SchlickGgx || size >= 1024))
        for (int i = 0; i < size; ++i) REQUIRE(std::abs(lut.a[i] + lut.b[i] - 1) < kSmoothLimitTol);
    }
  }
}

TEST_CASE("LUT Kulla-Conty E_avg and the multiscatter channel", "[lut][kernel]") {
  auto& rt = test::runtime();
  LutOptions o;
  o.size = 64;
  o.kullaConty = true;
  o.multiscatter = true;
  const LutResult lut = computeLut(rt, o);
  for (size_t t = 0; t < lut.a.size(); ++t) {
    REQUIRE(lut.e[t] == lut.a[t] + lut.b[t]);
    REQUIRE(lut.third[t] == lut.e[t]);
  }
  // E_avg(r) = 2 ∫ E μ dμ against the reference integrated by a fine midpoint rule.
  // The 64-column midpoint rule has O(1/64²) error on a smooth E: 2e-3 covers it and the kernel.
  constexpr double kEavgTol = 2e-3;
  for (int j : {0, 20, 63}) {
    std::vector<LutPoint> pts;
    const int m = 256;
    for (int i = 0; i < m; ++i) pts.push_back({(i + 0.5) / m, (j + 0.5) / o.size});
    const LutValues r = evaluateLutReference(o, pts);
    double eavg = 0;
    for (int i = 0; i < m; ++i) eavg += 2 * (r.a[i] + r.b[i]) * pts[i].mu / m;
    INFO("row " << j);
    CHECK(lut.eAvg[j] == Approx(eavg).margin(kEavgTol));
  }
}

TEST_CASE("LUT sample counts that are not a multiple of 16 mask the padding lanes", "[lut][kernel]") {
  auto& rt = test::runtime();
  const int n = 64;
  const auto pts = texelRows(n, {0, 9, 30, 63});
  for (auto ndf : {LutNdf::Ggx, LutNdf::Beckmann}) {
    LutOptions o = variant(ndf, LutVisibility::SmithCorrelated);
    o.samples = 1000;
    o.cloth = true;
    const LutValues k = evaluateLut(rt, o, pts), r = evaluateLutReference(o, pts);
    INFO(lutNdfName(ndf));
    REQUIRE(compare(k, r, n).maxAbs < kKernelTol1024);
    REQUIRE(compare(k, r, n, true).maxAbs < kClothRelTol1024);
    // One sample: 15 padding lanes, still finite and bounded.
    o.samples = 1;
    const LutValues one = evaluateLut(rt, o, pts);
    for (size_t i = 0; i < pts.size(); ++i) {
      REQUIRE((std::isfinite(one.a[i]) && std::isfinite(one.b[i]) && std::isfinite(one.cloth[i])));
      REQUIRE((one.a[i] >= 0 && one.b[i] >= 0 && one.a[i] + one.b[i] <= 1 + kAlbedoSlack));
    }
  }
}

TEST_CASE("LUT error never grows with the sample count: 2^16, 2^18, 2^20 per texel", "[lut][kernel]") {
  // Float sums over millions of samples lost precision (a 64² table at 2^20 samples was
  // 15× worse than at 2^16); the kernel now sums at most 16384 samples per launch and the
  // host adds the launches in double. Against the reference with four times the nodes
  // per axis (its own error is below 1e-7 here), the largest error over a 16² GGX table
  // must not grow from one count to the next beyond kNoise, and must fall overall.
  // kNoise: quasi-Monte Carlo errors are not strictly monotone per texel; 10 % of the
  // coarser count's error covers the wiggle measured between quarter-octave counts.
  constexpr double kNoise = 0.10;
  LutOptions o;
  o.size = 16;
  const std::vector<LutPoint> pts = [&] {
    std::vector<LutPoint> p;
    for (int j = 0; j < o.size; ++j)
      for (int i = 0; i < o.size; ++i) p.push_back({(i + 0.5) / o.size, (j + 0.5) / o.size});
    return p;
  }();
  const LutValues ref = evaluateLutReference(o, pts, 4);
  std::vector<double> errs;
  for (int n : {1 << 16, 1 << 18, 1 << 20}) {
    o.samples = n;
    const LutResult r = computeLut(test::runtime(), o);
    double e = 0;
    for (size_t i = 0; i < pts.size(); ++i) e = std::max({e, std::abs(r.a[i] - ref.a[i]), std::abs(r.b[i] - ref.b[i])});
    INFO(n << " samples: max error " << e);
    if (!errs.empty()) CHECK(e <= errs.back() * (1 + kNoise));
    errs.push_back(e);
  }
  CHECK(errs.back() < 0.5 * errs.front());
}

TEST_CASE("LUT is deterministic", "[lut][kernel]") {
  auto& rt = test::runtime();
  LutOptions o;
  o.size = 32;
  o.cloth = true;
  const LutResult a = computeLut(rt, o), b = computeLut(rt, o);
  REQUIRE(a.a == b.a);
  REQUIRE(a.b == b.b);
  REQUIRE(a.third == b.third);
}

TEST_CASE("LUT options: bad values are usage errors", "[lut]") {
  LutOptions o;
  for (int size : {0, -1, 8193}) {
    o = LutOptions{};
    o.size = size;
    REQUIRE_THROWS_AS(validateLutOptions(o), UsageError);
  }
  o = LutOptions{};
  o.samples = 0;
  REQUIRE_THROWS_AS(validateLutOptions(o), UsageError);
  o = LutOptions{};
  o.cloth = o.multiscatter = true;
  REQUIRE_THROWS_AS(validateLutOptions(o), UsageError);
  REQUIRE_THROWS_AS(parseLutNdf("phong"), UsageError);
  REQUIRE_THROWS_AS(parseLutVisibility("kelemen"), UsageError);
  REQUIRE(parseLutNdf("beckmann") == LutNdf::Beckmann);
  REQUIRE(parseLutVisibility("schlick-ggx") == LutVisibility::SchlickGgx);
  REQUIRE(lutSidecarPath("/a/b.c/out.exr") == "/a/b.c/out.json");
  REQUIRE(lutSidecarPath("/a/b.c/out") == "/a/b.c/out.json");
}

TEST_CASE("prtbake lut: bad input gives a clear error with exit 2 and no file", "[lut][cli]") {
  const std::string dir = test::tempDir("lut-bad");
  const std::string out = dir + "/t.exr";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"--size 0", "--size"},           {"--size -4", "--size"},          {"--size 8193", "--size"},
      {"--samples 0", "--samples"},     {"--ndf phong", "--ndf"},         {"--visibility kelemen", "--visibility"},
      {"--size abc", "--size"},         {"--cloth --multiscatter", "--cloth"}};
  for (const auto& [args, subject] : cases) {
    const auto r = test::runCli("lut -o '" + out + "' " + args + " --device cpu");
    INFO(args << " -> " << r.output);
    CHECK(r.exitCode == 2);
    CHECK(r.output.find("prtbake: error: " + subject) != std::string::npos);
    CHECK(!test::fileExists(out));
    CHECK(!test::fileExists(dir + "/t.json"));
  }
  // An unwritable destination is a failed job (exit 1) and leaves nothing.
  const auto r = test::runCli("lut -o '" + dir + "/missing/t.exr' --size 16 --device cpu");
  CHECK(r.exitCode == 1);
  CHECK(!test::fileExists(dir + "/missing"));
  CHECK(std::system(("test -z \"$(ls -A '" + dir + "')\"").c_str()) == 0);
}

TEST_CASE("prtbake lut writes the EXR channels and the sidecar", "[lut][cli]") {
  const std::string dir = test::tempDir("lut-cli");
  const std::string out = dir + "/dfg.exr";
  const auto r = test::runCli("lut -o '" + out + "' --size 32 --samples 256 --cloth --kulla-conty --device cpu");
  INFO(r.output);
  REQUIRE(r.exitCode == 0);
  int w = 0, h = 0;
  const auto a = readExrChannel(out, "R", w, h);
  REQUIRE((w == 32 && h == 32));
  const auto b = readExrChannel(out, "G", w, h);
  const auto c = readExrChannel(out, "B", w, h);
  const auto e = readExrChannel(out, "E", w, h);
  const auto eavg = readExrChannel(out, "Eavg", w, h);
  // The file matches the library call bit for bit (float32).
  LutOptions o;
  o.size = 32;
  o.samples = 256;
  o.cloth = o.kullaConty = true;
  const LutResult lut = computeLut(test::runtime(), o);
  REQUIRE(a == lut.a);
  REQUIRE(b == lut.b);
  REQUIRE(c == lut.third);
  REQUIRE(e == lut.e);
  REQUIRE(eavg[5 * 32 + 7] == lut.eAvg[5]);
  std::ifstream js(dir + "/dfg.json");
  REQUIRE(js.good());
  const auto j = nlohmann::json::parse(js);
  CHECK(j["tool"]["version"] == version());
  CHECK(j["samples"] == 256);
  CHECK(j["parameters"]["size"] == 32);
  CHECK(j["parameters"]["ndf"] == "ggx");
  CHECK(j["parameters"]["visibility"] == "smith-correlated");
  CHECK(j["channels"]["B"].get<std::string>().find("cloth") == 0);
  CHECK(j["error_estimate"]["std_error_max"].get<double>() > 0);
  CHECK(j["error_estimate"]["std_error_mean"].get<double>() <= j["error_estimate"]["std_error_max"].get<double>());
  CHECK(j["axes"]["x"].get<std::string>().find("(i + 0.5)/size") != std::string::npos);
  CHECK(j["definition"].contains("A"));
  CHECK(j["timings"].contains("kernel_s"));

  SECTION("half") {
    const std::string outH = dir + "/dfg_half.exr";
    REQUIRE(test::runCli("lut -o '" + outH + "' --size 16 --half --multiscatter --device cpu --quiet").exitCode == 0);
    Imf::InputFile in(outH.c_str());
    REQUIRE(in.header().channels().findChannel("R")->type == Imf::HALF);
    REQUIRE(in.header().channels().findChannel("B") != nullptr);
    std::ifstream jh(dir + "/dfg_half.json");
    const auto jj = nlohmann::json::parse(jh);
    CHECK(jj["parameters"]["pixel_type"] == "half");
    CHECK(jj["channels"]["B"].get<std::string>().find("1/E - 1") != std::string::npos);
  }
}
