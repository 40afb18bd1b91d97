// Prefiltered specular chains: schedules, the furnace for every lobe and schedule, the kernel
// against its double reference, analytic oracles (a linear environment, one bright texel),
// seams, extremes, the KTX2 layout and lat-long files read in bands. Real maps: test_prefilter_data.cpp; the command,
// jobs and read-back: test_prefilter_cli.cpp.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "env_test_helpers.h"
#include "core/gauss_legendre.h"
#include "prefilter/prefilter_detail.h"
#include "prtbake/error.h"
#include "prtbake/exr.h"
#include "prtbake/lut.h"
#include "prtbake/prefilter.h"
#include "test_common.h"

using namespace prtbake;
using test::makeCube;
using test::makeLatLong;

namespace {

const double kPi = 3.14159265358979323846;

PrefilterOptions opts(PrefilterLobe lobe, PrefilterSchedule s, int base, int levels = 0) {
  PrefilterOptions o;
  o.lobe = lobe;
  o.schedule = s;
  o.baseSize = base;
  o.levels = levels;
  if (s == PrefilterSchedule::Explicit) o.roughness = {0.0, 0.2, 0.5, 1.0};
  return o;
}

PrefilterOptions rough(int base, std::vector<double> r) {
  PrefilterOptions o;
  o.schedule = PrefilterSchedule::Explicit;
  o.baseSize = base;
  o.roughness = std::move(r);
  return o;
}

// A smooth sky with a small bright sun: the kind of map the method must handle.
Rgb skyWithSun(const double* d) {
  const double sun = d[0] * 0.48 + d[1] * 0.6 + d[2] * 0.64;  // a unit vector
  const double s = sun > 0.9995 ? 2e4 : 0.0;
  return {0.3 + 0.5 * std::max(0.0, d[1]) + s, 0.35 + 0.4 * std::max(0.0, d[1]) + 0.8 * s, 0.5 + 0.2 * d[2] * d[2] + 0.6 * s};
}

// ∫_0^1 μ^p k(μ) dμ by composite Gauss–Legendre (40 panels × 20 nodes, graded toward μ = 1
// where narrow lobes live): far below the tolerances that use it.
double lobeMoment(PrefilterLobe lobe, double alpha, int p) {
  const detail::GaussRule g = detail::gaussLegendre(20);
  double sum = 0;
  const int panels = 40;
  for (int i = 0; i < panels; ++i) {
    // Panel edges in s, μ = 1 − s²... graded: μ = 1 − (1 − t)^3.
    for (size_t k = 0; k < g.x.size(); ++k) {
      const double t = (i + g.x[k]) / panels, mu = 1 - std::pow(1 - t, 3), dmu = 3 * std::pow(1 - t, 2) / panels;
      sum += g.w[k] * dmu * std::pow(mu, p) * prefilterLobeWeight(lobe, alpha, mu);
    }
  }
  return sum;
}

// A smooth sky with a broad bright spot (width ~0.06 rad) 5° from the +Z/+Y edge: continuous,
// so the chain must be continuous too.
Rgb smoothSky(const double* d) {
  const double s = std::exp(300.0 * (d[1] * 0.6428 + d[2] * 0.7660 - 1.0));  // axis 40° up from +Z
  return {0.3 + 0.5 * std::max(0.0, d[1]) + 50 * s, 0.35 + 0.4 * d[0] * d[0] + 40 * s, 0.5 + 0.2 * d[2] + 30 * s};
}

double relErr(double a, double b) { return std::abs(a - b) / std::max(std::abs(b), 1e-30); }

// Direction of texel (face, row, col) of an n×n level.
std::array<double, 3> texelDir(int n, int f, int r, int c) {
  std::array<double, 3> d;
  cubeTexelCenter(n, f, r, c, d.data());
  return d;
}

const float* texel(const PrefilterLevel& l, int f, int r, int c) {
  const int n = l.spec.size;
  return &l.rgb[3 * ((size_t(f) * size_t(n) + size_t(r)) * size_t(n) + size_t(c))];
}

}  // namespace

TEST_CASE("Schedules give each level's roughness and size", "[prefilter]") {
  {
    const auto l = prefilterLevels(opts(PrefilterLobe::Ggx, PrefilterSchedule::Linear, 256));
    REQUIRE(l.size() == 5);  // down to 16²
    for (size_t i = 0; i < l.size(); ++i) {
      CHECK(l[i].size == (256 >> i));
      CHECK(l[i].roughness == Approx(i / 4.0));
      CHECK(l[i].alpha == Approx(l[i].roughness * l[i].roughness));
    }
  }
  {
    // Filament: lod i of n satisfies i/(n − 1) = r(2 − r).
    const auto l = prefilterLevels(opts(PrefilterLobe::Ggx, PrefilterSchedule::Filament, 256));
    REQUIRE(l.size() == 5);
    for (size_t i = 0; i < l.size(); ++i) CHECK(l[i].roughness * (2 - l[i].roughness) == Approx(i / 4.0).margin(1e-12));
  }
  {
    // Babylon: lod = log2(size α_G)·(n − 1)/log2(size) must give back i.
    const auto l = prefilterLevels(opts(PrefilterLobe::Ggx, PrefilterSchedule::Babylon, 256));
    REQUIRE(l.size() == 5);
    for (size_t i = 0; i < l.size(); ++i) {
      CHECK(std::log2(256 * l[i].alpha) * 4 / 8 == Approx(double(i)).margin(1e-12));
      CHECK(l[i].roughness == Approx(std::sqrt(std::max(0.0, l[i].alpha - 0.0005))));
    }
    CHECK(l.back().alpha == Approx(1.0));
  }
  {
    const auto l = prefilterLevels(opts(PrefilterLobe::Ggx, PrefilterSchedule::Explicit, 64));
    REQUIRE(l.size() == 4);
    CHECK(l[1].roughness == 0.2);
    CHECK(l[3].size == 8);
  }
  // Defaults: down to 16², the full chain at 16 and below, one level for lambertian; explicit counts.
  CHECK(prefilterLevels(opts(PrefilterLobe::Ggx, PrefilterSchedule::Linear, 1024)).size() == 7);
  CHECK(prefilterLevels(opts(PrefilterLobe::Ggx, PrefilterSchedule::Linear, 16)).size() == 5);
  CHECK(prefilterLevels(opts(PrefilterLobe::Ggx, PrefilterSchedule::Linear, 1)).size() == 1);
  CHECK(prefilterLevels(opts(PrefilterLobe::Lambertian, PrefilterSchedule::Linear, 64)).size() == 1);
  const auto odd = prefilterLevels(opts(PrefilterLobe::Ggx, PrefilterSchedule::Linear, 100, 7));
  CHECK(odd.back().size == 1);
  CHECK(odd[3].size == 12);
}

TEST_CASE("Bad prefilter options are usage errors", "[prefilter]") {
  auto bad = [](PrefilterOptions o) { REQUIRE_THROWS_AS(validatePrefilterOptions(o), UsageError); };
  PrefilterOptions o;
  o.baseSize = 0;
  bad(o);
  o.baseSize = 65536;
  bad(o);
  o.baseSize = 16;
  o.levels = 6;  // 16 → 1 is five levels
  bad(o);
  o.levels = 0;
  o.roughness = {0.5};  // a list with a named schedule
  bad(o);
  o.schedule = PrefilterSchedule::Explicit;
  o.roughness = {0.0, 1.5};
  bad(o);
  o.roughness = {};
  bad(o);
  o = PrefilterOptions{};
  o.tolerance = 0;
  bad(o);
  o = PrefilterOptions{};
  o.method = PrefilterMethod::Sampled;
  o.lobe = PrefilterLobe::Charlie;
  bad(o);
  REQUIRE_THROWS_AS(parsePrefilterLobe("phong"), UsageError);
  REQUIRE_THROWS_AS(parsePrefilterSchedule("unreal"), UsageError);
}

TEST_CASE("Lobe weights follow their definitions", "[prefilter]") {
  // GGX: k(μ) ∝ D(N·H) μ with N·H = √((1 + μ)/2), scaled to k(1) = 1.
  for (double alpha : {0.05, 0.3, 1.0})
    for (double mu : {0.1, 0.5, 0.9, 0.999}) {
      const double nh2 = (1 + mu) / 2, q = nh2 * (alpha * alpha - 1) + 1;
      const double d = alpha * alpha / (kPi * q * q), d0 = 1 / (kPi * alpha * alpha);
      CHECK(prefilterLobeWeight(PrefilterLobe::Ggx, alpha, mu) == Approx(mu * d / d0).epsilon(1e-12));
    }
  CHECK(prefilterLobeWeight(PrefilterLobe::Ggx, 0.2, 1.0) == Approx(1.0));
  CHECK(prefilterLobeWeight(PrefilterLobe::Ggx, 0.2, -0.1) == 0.0);
  // Charlie: μ sin^(1/α)θ_h over its peak μ* = 1/(1 + 1/(2α)).
  const double a = 0.3, ms = 1 / (1 + 1 / (2 * a));
  CHECK(prefilterLobeWeight(PrefilterLobe::Charlie, a, ms) == Approx(1.0));
  CHECK(prefilterLobeWeight(PrefilterLobe::Charlie, a, 0.5) ==
        Approx(0.5 * std::pow(0.25, 1 / (2 * a)) / (ms * std::pow((1 - ms) / 2, 1 / (2 * a)))));
  CHECK(prefilterLobeWeight(PrefilterLobe::Lambertian, 0.0, 0.25) == 0.25);
}

TEST_CASE("White furnace: a constant environment at every texel of every level, every lobe and schedule",
          "[prefilter][kernel]") {
  // The weights are normalised by the same sum over the same bins (the solid-angle centroid
  // of a constant map is its radiance centroid), so only float rounding remains; the issue's
  // bound is 1e-5 relative.
  constexpr double kFurnaceTol = 1e-5;
  const EnvMap cube = makeCube(16, [](const double*) { return Rgb{2.5, 2.5, 2.5}; });
  const EnvMap ll = makeLatLong(32, [](const double*) { return Rgb{0.75, 0.75, 0.75}; });
  for (const EnvMap* env : {&cube, &ll})
    for (auto lobe : {PrefilterLobe::Ggx, PrefilterLobe::Charlie, PrefilterLobe::Lambertian})
      for (auto s : {PrefilterSchedule::Linear, PrefilterSchedule::Filament, PrefilterSchedule::Babylon,
                     PrefilterSchedule::Explicit}) {
        PrefilterOptions o = opts(lobe, s, 32, lobe == PrefilterLobe::Lambertian ? 3 : 0);
        if (s == PrefilterSchedule::Explicit) o.levels = 0;
        o.errorEstimate = false;
        const PrefilterResult r = prefilterEnvironment(test::runtime(), *env, o);
        const double value = env->rgb[0];
        double worst = 0;
        for (const auto& l : r.levels)
          for (float v : l.rgb) worst = std::max(worst, relErr(v, value));
        INFO(toString(lobe) << " " << toString(s) << " " << (env == &cube ? "cube" : "lat-long") << ": worst " << worst);
        REQUIRE(worst <= kFurnaceTol);
      }
}

TEST_CASE("The kernel matches its double-precision reference over the same cut", "[prefilter][kernel]") {
  // Same bins, same cut, same formula: the float32 kernel (directions from rsqrt, lobe from
  // e = |R − c|²/2, Charlie's power from the kernel's own log2 and exp2, float sums over a few
  // thousand bins) against double, at r = 0.3 and, for Charlie, at r = 0 too (α = 0.0079: the
  // power 1/(2α) = 63 multiplies the float rounding of e). Measured worst 1.4e-5 relative (GGX),
  // 8e-6 (Charlie r = 0.3), 1.8e-6 (lambertian); the bound leaves a factor 3.5 for other devices'
  // rounding. Charlie at r = 0: 7.8e-5 with OpenCL's built-in log2 and exp2 and with the kernel's
  // own alike, bounded at 3 times that. The kernel's log2 with its exponent off by one where it
  // halves the mantissa fails (worst 2.5 at r = 0.3).
  constexpr double kKernelTol = 5e-5, kRingKernelTol = 2.5e-4;
  const EnvMap env = makeCube(48, skyWithSun);
  for (auto [lobe, index] : {std::pair{PrefilterLobe::Ggx, 1}, {PrefilterLobe::Charlie, 1}, {PrefilterLobe::Charlie, 0},
                             {PrefilterLobe::Lambertian, 1}}) {
    PrefilterOptions o = rough(32, {0.0, 0.3, 0.7});
    o.lobe = lobe;
    o.errorEstimate = false;
    const PrefilterResult r = prefilterEnvironment(test::runtime(), env, o);
    const PrefilterLevel& level = r.levels[size_t(index)];
    const detail::BinTree tree = detail::buildBinTree(env, r.binFaceSize);
    const detail::LobeScale scale(lobe, level.alphaUsed, level.binTolerance);
    const detail::TileTree tt = detail::makeTileTree(level.spec.size);
    const std::vector<int> leaves = {0, 3, 5};
    for (int face : {0, 2, 5}) {
      const detail::TileCuts cuts = detail::buildTileCuts(tree, scale, tt, face, leaves);
      const std::vector<double> ref = detail::evaluateCutsReference(tree, cuts, tt, lobe, level.alphaUsed, face, leaves);
      size_t i = 0;
      double worst = 0;
      for (int leaf : leaves) {
        const int ty = leaf / tt.side(0), tx = leaf % tt.side(0);
        for (int row = ty * tt.leaf; row < std::min(tt.n, (ty + 1) * tt.leaf); ++row)
          for (int col = tx * tt.leaf; col < std::min(tt.n, (tx + 1) * tt.leaf); ++col, ++i)
            for (int c = 0; c < 3; ++c) worst = std::max(worst, relErr(texel(level, face, row, col)[c], ref[3 * i + size_t(c)]));
      }
      INFO(toString(lobe) << " alpha " << level.alphaUsed << " face " << face << ": worst " << worst);
      REQUIRE(i * 3 == ref.size());
      REQUIRE(worst <= (index == 0 ? kRingKernelTol : kKernelTol));
    }
  }
}

TEST_CASE("Analytic oracle: a linear environment gives a + c1(α) b·R", "[prefilter][kernel]") {
  // L(ω) = a + b·ω. With k isotropic about R, ∫ ω k dω = c1 R ∫ k dω, c1 = ∫ μ k dμ / ∫ k dμ
  // (μ = R·ω, only μ > 0 carries weight), so P(R) = a + c1 (b·R): for lambertian c1 = 2/3
  // exactly, for GGX and Charlie by 1D quadrature. The map holds the function at texel
  // centres of a 64² cube; centre sampling over curved texels leaves O(h²), and the cut adds its
  // own error (tolerance 1e-2 targets the 99th percentile): measured worst 1.2e-3 of a (GGX and
  // lambertian), 2.4e-4 (Charlie). 4e-3 of a is ten times below what a mirrored face +Z costs
  // (0.35 GGX, 0.063 lambertian, 0.085 Charlie).
  constexpr double kLinearTol = 4e-3;
  const std::array<double, 3> b = {0.4, -0.3, 0.25};
  const double a = 1.0;
  auto lin = [&](const double* d) {
    const double v = a + b[0] * d[0] + b[1] * d[1] + b[2] * d[2];
    return Rgb{v, v, v};
  };
  const EnvMap env = makeCube(64, lin);
  EnvMap mirrored = env;  // negative control: face +Z mirrored left-right
  const size_t n = 64;
  for (size_t r = 0; r < n; ++r)
    for (size_t c = 0; c < n / 2; ++c)
      for (int k = 0; k < 3; ++k)
        std::swap(mirrored.rgb[3 * ((4 * n + r) * n + c) + size_t(k)], mirrored.rgb[3 * ((4 * n + r) * n + n - 1 - c) + size_t(k)]);
  for (auto lobe : {PrefilterLobe::Lambertian, PrefilterLobe::Ggx, PrefilterLobe::Charlie}) {
    PrefilterOptions o = rough(32, {0.3, 1.0});
    o.lobe = lobe;
    auto worstOf = [&](const EnvMap& e) {
      const PrefilterResult r = prefilterEnvironment(test::runtime(), e, o);
      double worst = 0;
      for (const auto& l : r.levels) {
        const double c1 = lobe == PrefilterLobe::Lambertian
                              ? 2.0 / 3.0
                              : lobeMoment(lobe, l.alphaUsed, 1) / lobeMoment(lobe, l.alphaUsed, 0);
        for (int f = 0; f < 6; ++f)
          for (int row = 0; row < l.spec.size; ++row)
            for (int col = 0; col < l.spec.size; ++col) {
              const auto d = texelDir(l.spec.size, f, row, col);
              const double expect = a + c1 * (b[0] * d[0] + b[1] * d[1] + b[2] * d[2]);
              worst = std::max(worst, std::abs(texel(l, f, row, col)[0] - expect) / a);
            }
      }
      return worst;
    };
    const double good = worstOf(env), bad = worstOf(mirrored);
    INFO(toString(lobe) << ": worst " << good << ", with a mirrored face " << bad);
    CHECK(good <= kLinearTol);
    CHECK(bad > 10 * kLinearTol);
  }
}

TEST_CASE("Analytic oracle: one bright texel gives back the lobe", "[prefilter][kernel]") {
  // A black map but for one texel of radiance L (solid angle Ω, direction ω_s): every output
  // texel is P(R) = L Ω k(R·ω_s) / ∫ k dω exactly in the definition, with ∫ k dω = 2π ∫ k dμ.
  // The discrete denominator Σ k Ω differs from the integral by the cube quadrature, and the
  // cut adds its own error: measured worst 1.1e-3 (r = 0.5) and 1.6e-3 (r = 0.8) of the peak
  // value. The bound 4e-3 is far below a sun mirrored in x (the expected lobe around the wrong
  // direction: 0.3 and more of the peak).
  constexpr double kLobeTol = 4e-3;
  EnvMap env = makeCube(64, [](const double*) { return Rgb{0, 0, 0}; });
  const size_t hot = (size_t(4) * 64 + 20) * 64 + 41;  // face +Z, off centre
  env.rgb[3 * hot] = env.rgb[3 * hot + 1] = env.rgb[3 * hot + 2] = 1000.0f;
  double sun[3], omega;
  texelDirection(env, hot, sun, &omega);
  for (double r : {0.5, 0.8}) {
    PrefilterOptions o = rough(16, {r});
    const PrefilterResult res = prefilterEnvironment(test::runtime(), env, o);
    const PrefilterLevel& l = res.levels[0];
    const double norm = 2 * kPi * lobeMoment(PrefilterLobe::Ggx, l.alphaUsed, 0);
    const double peak = 1000.0 * omega / norm;
    double worst = 0, mirrored = 0, minValue = 1e30;
    for (int f = 0; f < 6; ++f)
      for (int row = 0; row < l.spec.size; ++row)
        for (int col = 0; col < l.spec.size; ++col) {
          const auto d = texelDir(l.spec.size, f, row, col);
          const double mu = d[0] * sun[0] + d[1] * sun[1] + d[2] * sun[2], muBad = mu - 2 * d[0] * sun[0];
          const double expect = 1000.0 * omega * prefilterLobeWeight(PrefilterLobe::Ggx, l.alphaUsed, mu) / norm;
          const double expectBad = 1000.0 * omega * prefilterLobeWeight(PrefilterLobe::Ggx, l.alphaUsed, muBad) / norm;
          worst = std::max(worst, std::abs(texel(l, f, row, col)[1] - expect) / peak);
          mirrored = std::max(mirrored, std::abs(texel(l, f, row, col)[1] - expectBad) / peak);
          minValue = std::min(minValue, double(texel(l, f, row, col)[1]));
        }
    INFO("r = " << r << ": worst " << worst << " of the peak " << peak << ", against a mirrored sun " << mirrored);
    CHECK(worst <= kLobeTol);
    CHECK(mirrored > 10 * kLobeTol);
    CHECK(minValue >= 0.0);
  }
}

namespace {

// Mean |step| across each cube edge (the edge texel of one face against its neighbour on
// the adjacent face) and inside the faces (the same edge texel against the one next to it
// inside its face), relative to the level's mean value. Pairs from directions: the texel
// centre pushed one texel further across the edge.
struct Steps {
  double across = 0, inside = 0;
};
Steps edgeSteps(const PrefilterLevel& l) {
  const int n = l.spec.size;
  const auto bases = standardCubeBases();
  double sumAcross = 0, sumInside = 0, mean = 0;
  size_t count = 0;
  for (float v : l.rgb) mean += v;
  mean /= double(l.rgb.size());
  auto lum = [&](size_t t) { return (l.rgb[3 * t] + l.rgb[3 * t + 1] + l.rgb[3 * t + 2]) / 3.0; };
  for (int f = 0; f < 6; ++f)
    for (int side = 0; side < 4; ++side)
      for (int i = 0; i < n; ++i) {
        // Edge texel (row, col) and the inward step (dr, dc).
        const int row = side == 0 ? 0 : side == 1 ? n - 1 : i, col = side == 2 ? 0 : side == 3 ? n - 1 : i;
        const int dr = side == 0 ? 1 : side == 1 ? -1 : 0, dc = side == 2 ? 1 : side == 3 ? -1 : 0;
        const double u = 2.0 * (col - dc + 0.5) / n - 1.0, v = 2.0 * (row - dr + 0.5) / n - 1.0;  // one texel outward
        double d[3];
        const auto& b = bases[size_t(f)];
        for (int k = 0; k < 3; ++k) d[k] = u * b.axisU[size_t(k)] + v * b.axisV[size_t(k)] + b.axisN[size_t(k)];
        const size_t t = (size_t(f) * size_t(n) + size_t(row)) * size_t(n) + size_t(col);
        const size_t in = (size_t(f) * size_t(n) + size_t(row + dr)) * size_t(n) + size_t(col + dc);
        sumAcross += std::abs(lum(t) - lum(cubeTexelIndex(n, d)));
        sumInside += std::abs(lum(t) - lum(in));
        ++count;
      }
  return {sumAcross / double(count) / mean, sumInside / double(count) / mean};
}

}  // namespace

TEST_CASE("Seams: the step across each cube edge is no larger than inside the faces", "[prefilter][kernel]") {
  // Every texel is the definition evaluated at its own exact direction, so the chain is as
  // smooth across an edge as inside a face. Texel centres at an edge are 5 % closer in angle to
  // their neighbour across the edge than to the next one inside, so on a smooth map the step
  // across measures 0.8 to 0.97 of the inside step (every level, r = 0 included); the bound is
  // 1. A face flipped upside down (as a wrong exporter would write it) makes the steps across
  // 1.4 (r = 1) to 6.5 (r = 0) times the inside ones.
  constexpr double kSeamRatio = 1.0;
  const EnvMap env = makeCube(64, [](const double* d) {
    return Rgb{0.3 + 0.5 * std::max(0.0, d[1]) + 0.2 * d[0], 0.35 + 0.4 * d[0] * d[0], 0.5 + 0.2 * d[2] - 0.1 * d[1]};
  });
  const PrefilterResult r = prefilterEnvironment(test::runtime(), env, opts(PrefilterLobe::Ggx, PrefilterSchedule::Linear, 32, 4));
  for (const PrefilterLevel& l : r.levels) {
    const Steps s = edgeSteps(l);
    INFO("level " << l.spec.size << " r = " << l.spec.roughness << ": across " << s.across << " inside " << s.inside);
    CHECK(s.across <= kSeamRatio * s.inside);
    // Negative control: the same level with face +Z flipped upside down.
    PrefilterLevel flipped = l;
    const int n = l.spec.size;
    for (int row = 0; row < n / 2; ++row)
      for (int col = 0; col < n; ++col)
        for (int c = 0; c < 3; ++c)
          std::swap(flipped.rgb[3 * ((size_t(4) * n + row) * n + col) + c], flipped.rgb[3 * ((size_t(4) * n + n - 1 - row) * n + col) + c]);
    const Steps bad = edgeSteps(flipped);
    INFO("flipped: across " << bad.across << " inside " << bad.inside);
    CHECK(bad.across > 1.3 * bad.inside);
  }
}

TEST_CASE("Seams: a bright spot on a cube edge steps across it exactly as the definition does", "[prefilter][kernel]") {
  // Near a feature the step across an edge can exceed the step inside (here 1.9 times at
  // r = 0.2: the spot's flank runs across the edge), in the definition itself. What must not
  // appear is any step the definition does not have: the chain's steps across every edge
  // against those of the double brute force at the same texels, relative to the level's mean,
  // measured 4e-4; bound 3e-3 (the cut's tolerance), against 0.1 for a flipped face.
  constexpr double kStepTol = 3e-3;
  const EnvMap env = makeCube(64, smoothSky);
  const PrefilterResult r = prefilterEnvironment(test::runtime(), env, rough(16, {0.2, 0.4}));
  for (const PrefilterLevel& l : r.levels) {
    const int n = l.spec.size;
    std::vector<double> dirs;
    for (int f = 0; f < 6; ++f)
      for (int row = 0; row < n; ++row)
        for (int col = 0; col < n; ++col) {
          const auto d = texelDir(n, f, row, col);
          dirs.insert(dirs.end(), d.begin(), d.end());
        }
    PrefilterLevel exact = l;
    const std::vector<double> ref = prefilterBruteForce(env, PrefilterLobe::Ggx, l.alphaUsed, dirs);
    exact.rgb.assign(ref.begin(), ref.end());
    const Steps a = edgeSteps(l), b = edgeSteps(exact);
    INFO("level " << n << " r = " << l.spec.roughness << ": across " << a.across << " (exact " << b.across << "), inside "
                  << a.inside << " (exact " << b.inside << ")");
    CHECK(std::abs(a.across - b.across) <= kStepTol);
    CHECK(std::abs(a.inside - b.inside) <= kStepTol);
  }
}

TEST_CASE("Extremes: r = 0 is the resampled source, r = 1, 1×1 levels, base sizes 1 to 2048", "[prefilter][kernel]") {
  // A cube source at the base size: level 0 is the source texel for texel, bit for bit.
  const EnvMap env = makeCube(32, skyWithSun);
  const PrefilterResult r = prefilterEnvironment(test::runtime(), env, rough(32, {0.0, 1.0}));
  REQUIRE(std::equal(r.levels[0].rgb.begin(), r.levels[0].rgb.end(), env.rgb.begin(), env.rgb.end()));
  REQUIRE(r.levels[0].rgb == resampleEnvironment(env, 32));
  for (float v : r.levels[1].rgb) REQUIRE((std::isfinite(v) && v > 0));
  // Every base size from 1 up, odd ones included, with every level down to 1×1.
  for (int base : {1, 2, 3, 5, 17, 100}) {
    PrefilterOptions o = opts(PrefilterLobe::Ggx, PrefilterSchedule::Linear, base);
    o.levels = int(prefilterLevels(o).size());
    while ((base >> o.levels) >= 1) ++o.levels;  // the full chain
    const PrefilterResult c = prefilterEnvironment(test::runtime(), env, o);
    INFO("base " << base);
    REQUIRE(c.levels.back().spec.size == 1);
    for (const auto& l : c.levels) {
      REQUIRE(l.rgb.size() == 18 * size_t(l.spec.size) * size_t(l.spec.size));
      for (float v : l.rgb) REQUIRE((std::isfinite(v) && v >= 0));
    }
  }
  // The largest base in the issue, as a resampling (the prefiltered levels of a 1024 chain are
  // run by bench/bench_prefilter.cpp): 6 × 2048² texels, each the source magnified bilinearly.
  const PrefilterResult big = prefilterEnvironment(test::runtime(), env, rough(2048, {0.0}));
  REQUIRE(big.levels[0].rgb.size() == 18 * size_t(2048) * 2048);
  double d[3];
  cubeTexelCenter(2048, 4, 1024, 1024, d);
  const float* centre = &big.levels[0].rgb[3 * ((size_t(4) * 2048 + 1024) * 2048 + 1024)];
  const size_t src = cubeTexelIndex(32, d);
  CHECK(centre[0] == Approx(env.rgb[3 * src]).epsilon(0.05));
}

TEST_CASE("Extremes: a 1e6 sun among 1e-3 texels gives no NaN and no negative value", "[prefilter][kernel]") {
  for (EnvMap e : {makeCube(32, [](const double*) { return Rgb{1e-3, 1e-3, 1e-3}; }),
                   makeLatLong(32, [](const double*) { return Rgb{1e-3, 1e-3, 1e-3}; })}) {
    const size_t hot = e.texelCount() / 3 + 17;
    e.rgb[3 * hot] = e.rgb[3 * hot + 1] = e.rgb[3 * hot + 2] = 1e6f;
    for (auto lobe : {PrefilterLobe::Ggx, PrefilterLobe::Charlie, PrefilterLobe::Lambertian}) {
      PrefilterOptions o = opts(lobe, PrefilterSchedule::Linear, 32, lobe == PrefilterLobe::Lambertian ? 1 : 6);
      const PrefilterResult r = prefilterEnvironment(test::runtime(), e, o);
      for (const auto& l : r.levels) {
        float lo = 1e30f, hi = 0;
        for (float v : l.rgb) {
          REQUIRE(std::isfinite(v));
          lo = std::min(lo, v), hi = std::max(hi, v);
        }
        INFO(toString(lobe) << " level " << l.spec.size << ": min " << lo << " max " << hi);
        REQUIRE(lo >= 0.0f);
        REQUIRE(hi <= 1e6f * 1.0001f);  // a weighted mean never exceeds the brightest texel
      }
      // RGBA16F cannot hold 1e6: clamped to the half maximum and counted, never inf.
      Ktx2Stats stats;
      prefilterKtx2Bytes(r, false, &stats);
      if (lobe == PrefilterLobe::Ggx) CHECK(stats.clampedToHalf > 0);
    }
  }
}

TEST_CASE("Extremes: alpha to 0 is stable and approaches the r = 0 level", "[prefilter][kernel]") {
  // Lobes narrower than half a source texel are widened to that floor, so the level settles
  // as r → 0 (r = 1e-8 and 1e-4 give the same bits) instead of picking single bins, and stays
  // within the floor lobe's blur of the r = 0 resampling: measured mean 1.9e-2 relative on
  // this smooth map (the blur of one texel where the bright spot curves), bound 3e-2. With a
  // sun the GGX tails spread it far (physics, not noise): there only finiteness and sign.
  constexpr double kNearZeroTol = 3e-2;
  const EnvMap smooth = makeCube(32, smoothSky), sunny = makeCube(32, skyWithSun);
  for (const EnvMap* env : {&smooth, &sunny}) {
    const std::vector<float> source = resampleEnvironment(*env, 32);
    std::vector<std::vector<float>> levels;
    for (double r : {1e-8, 1e-4, 1e-3, 0.3}) {
      const PrefilterResult res = prefilterEnvironment(test::runtime(), *env, rough(32, {r}));
      const PrefilterLevel& l = res.levels[0];
      for (float v : l.rgb) REQUIRE((std::isfinite(v) && v >= 0));
      double d = 0;
      for (size_t k = 0; k < l.rgb.size(); ++k) d += std::abs(l.rgb[k] - source[k]) / std::max(1e-6f, source[k]);
      d /= double(l.rgb.size());
      INFO("r = " << r << " (alpha used " << l.alphaUsed << ", floor " << res.alphaFloor << "): mean relative difference "
                    << std::to_string(d));
      if (env == &smooth && r <= 1e-3) CHECK(d <= kNearZeroTol);
      if (r <= 1e-3) CHECK(l.alphaUsed == res.alphaFloor);
      levels.push_back(l.rgb);
    }
    CHECK(levels[0] == levels[1]);
    CHECK(levels[1] == levels[2]);
  }
}

TEST_CASE("The kernel gives the same chain with 1, 8 or 16 texels per work-item", "[prefilter][kernel]") {
  // 1 is what a GPU runs (one texel per work-item, a leaf per work-group); PoCL runs all three.
  // Same bins, same order of the sums per texel: the results agree to float rounding of the
  // direction (rsqrt on vectors or scalars): measured 0 or a few ulp, bound 1e-6 relative.
  const EnvMap env = makeCube(32, skyWithSun);
  std::vector<std::vector<float>> out;
  for (int vw : {16, 8, 1}) {
    PrefilterOptions o = rough(16, {0.3});
    o.vectorWidth = vw;
    out.push_back(prefilterEnvironment(test::runtime(), env, o).levels[0].rgb);
  }
  for (size_t k = 1; k < out.size(); ++k)
    for (size_t i = 0; i < out[0].size(); ++i) REQUIRE(relErr(out[k][i], out[0][i]) <= 1e-6);
}

TEST_CASE("Prefiltering is deterministic", "[prefilter][kernel]") {
  const EnvMap env = makeLatLong(32, skyWithSun);
  const PrefilterOptions o = opts(PrefilterLobe::Ggx, PrefilterSchedule::Filament, 32);
  const PrefilterResult a = prefilterEnvironment(test::runtime(), env, o), b = prefilterEnvironment(test::runtime(), env, o);
  for (size_t i = 0; i < a.levels.size(); ++i) REQUIRE(a.levels[i].rgb == b.levels[i].rgb);
  REQUIRE(prefilterKtx2Bytes(a, false) == prefilterKtx2Bytes(b, false));
}

TEST_CASE("KTX2 layout: header, level index, data format descriptor", "[prefilter]") {
  const EnvMap env = makeCube(8, skyWithSun);
  const PrefilterResult r = prefilterEnvironment(test::runtime(), env, opts(PrefilterLobe::Ggx, PrefilterSchedule::Linear, 16));
  for (bool f32 : {false, true}) {
    const std::string k = prefilterKtx2Bytes(r, f32);
    auto u32 = [&](size_t at) {
      uint32_t v;
      std::memcpy(&v, k.data() + at, 4);
      return v;
    };
    auto u64 = [&](size_t at) {
      uint64_t v;
      std::memcpy(&v, k.data() + at, 8);
      return v;
    };
    REQUIRE(k.compare(0, 12, std::string("\xABKTX 20\xBB\r\n\x1A\n", 12)) == 0);
    CHECK(u32(12) == (f32 ? 109u : 97u));
    CHECK(u32(16) == (f32 ? 4u : 2u));
    CHECK(u32(20) == 16);
    CHECK(u32(24) == 16);
    CHECK(u32(28) == 0);
    CHECK(u32(32) == 0);
    CHECK(u32(36) == 6);
    CHECK(u32(40) == r.levels.size());
    CHECK(u32(44) == 0);
    const uint32_t dfdOffset = u32(48), dfdLength = u32(52);
    CHECK(dfdOffset == 80 + 24 * r.levels.size());
    CHECK(dfdLength == 92);
    // The Basic DFD bytes of KTX-Software's createdfd.c for R16G16B16A16_SFLOAT (R32G32B32A32_SFLOAT).
    const std::string half = std::string("\x5c\0\0\0\0\0\0\0\x02\0\x58\0\x01\x01\x01\0\0\0\0\0\x08\0\0\0\0\0\0\0", 28);
    const std::string full = std::string("\x5c\0\0\0\0\0\0\0\x02\0\x58\0\x01\x01\x01\0\0\0\0\0\x10\0\0\0\0\0\0\0", 28);
    CHECK(k.compare(dfdOffset, 28, f32 ? full : half) == 0);
    const char* samples16[4] = {"\x00\x00\x0f\xc0", "\x10\x00\x0f\xc1", "\x20\x00\x0f\xc2", "\x30\x00\x0f\xcf"};
    const char* samples32[4] = {"\x00\x00\x1f\xc0", "\x20\x00\x1f\xc1", "\x40\x00\x1f\xc2", "\x60\x00\x1f\xcf"};
    for (int s = 0; s < 4; ++s) {
      CHECK(k.compare(dfdOffset + 28 + 16 * s, 4, std::string(f32 ? samples32[s] : samples16[s], 4)) == 0);
      CHECK(u32(dfdOffset + 28 + 16 * s + 8) == 0xBF800000u);
      CHECK(u32(dfdOffset + 28 + 16 * s + 12) == 0x3F800000u);
    }
    // Level index: largest first, data smallest first, aligned, six faces each.
    const size_t align = f32 ? 16 : 8, texelBytes = f32 ? 16 : 8;
    uint64_t previous = 0;
    for (int l = int(r.levels.size()) - 1; l >= 0; --l) {
      const uint64_t offset = u64(80 + 24 * size_t(l)), length = u64(88 + 24 * size_t(l));
      const size_t n = size_t(r.levels[size_t(l)].spec.size);
      CHECK(offset % align == 0);
      CHECK(offset > previous);
      CHECK(length == 6 * n * n * texelBytes);
      CHECK(u64(96 + 24 * size_t(l)) == length);
      previous = offset;
    }
    CHECK(u64(80) + u64(88) == k.size());
  }
}

namespace {

// A sky with stripes a few source texels wide, so that every resampling lookup matters.
Rgb stripedSky(const double* d) {
  const Rgb sky = skyWithSun(d);
  const double s = 1.0 + 0.5 * std::sin(23.0 * d[0]) * std::cos(17.0 * d[2]) + 0.3 * std::sin(31.0 * d[1]);
  return {sky[0] * s, sky[1] * (2.0 - s), sky[2]};
}

// Writes `env` (lat-long) as a float OpenEXR file with the lat-long envmap attribute.
void writeLatLongExr(const std::string& path, const EnvMap& env) {
  std::vector<float> r(env.texelCount()), g(r.size()), b(r.size());
  for (size_t t = 0; t < r.size(); ++t) r[t] = env.rgb[3 * t], g[t] = env.rgb[3 * t + 1], b[t] = env.rgb[3 * t + 2];
  ExrWriteOptions o;
  o.envmap = 0;
  writeExr(path, env.width, env.height, {{"R", r.data()}, {"G", g.data()}, {"B", b.data()}}, o);
}

// The bytes of bands of `rows` float rows of a w-wide map (forEachLatLongBand's bandBytes).
size_t rowsOf(int w, int rows) { return 12 * size_t(w) * size_t(rows); }

// An r = 0 texel whose resampling lookups straddle two bands adds the same double terms as
// the whole map's, in another order: the double sums differ in their last bits, which the
// rounding to float turns into at most one float ulp, 2⁻²³ relative.
constexpr double kBandOrderTolerance = 0x1p-23;
// The sampled method reads its base through box filters and trilinear lookups in float, all
// with positive weights: a base texel one ulp away moves a lookup by a few ulps at most.
constexpr double kBandSampledTolerance = 1e-6;

// Max relative difference (per channel) and the count of texels that differ at all.
std::pair<double, size_t> compareTexels(const std::vector<float>& a, const std::vector<float>& b) {
  REQUIRE(a.size() == b.size());
  double worst = 0;
  size_t differ = 0;
  for (size_t i = 0; i < a.size(); i += 3) {
    bool d = false;
    for (size_t c = 0; c < 3; ++c) {
      worst = std::max(worst, relErr(a[i + c], b[i + c]));
      d = d || a[i + c] != b[i + c];
    }
    differ += d;
  }
  return {worst, differ};
}

}  // namespace

TEST_CASE("Bands: the bin tree and the resampling from bands of rows against the whole map's", "[prefilter][bands]") {
  EnvMap env = makeLatLong(40, stripedSky);
  env.yawDegrees = 30.0;
  const int m0 = detail::binFaceSizeFor(env);
  const detail::BinTree whole = detail::buildBinTree(env, m0);
  for (int rows : {1, 7, 40}) {
    INFO(rows << "-row bands");
    // The bin tree: the same bits, whatever the bands.
    detail::BinTreeBands bins(env, m0);
    for (int y = 0; y < env.height; y += rows) {
      const size_t first = size_t(y) * size_t(env.width), count = size_t(std::min(rows, env.height - y)) * size_t(env.width);
      bins.add(&env.rgb[3 * first], first, count);
    }
    const detail::BinTree banded = bins.finish();
    CHECK(banded.offset == whole.offset);
    CHECK(std::equal(banded.flux.begin(), banded.flux.end(), whole.flux.begin(), whole.flux.end()));
    CHECK(std::equal(banded.dirL.begin(), banded.dirL.end(), whole.dirL.begin(), whole.dirL.end()));
    CHECK(std::equal(banded.dirG.begin(), banded.dirG.end(), whole.dirG.begin(), whole.dirG.end()));
    CHECK(std::equal(banded.geom.begin(), banded.geom.end(), whole.geom.begin(), whole.geom.end()));
    // The resampling, minifying (16: 2 × 2 lookups per texel) and magnifying (64: one).
    for (int n : {16, 64}) {
      INFO("face size " << n);
      detail::ResampleBands resample(env, n);
      for (int y = 0; y < env.height; y += rows) {
        EnvMap band;
        band.layout = EnvLayout::LatLong;
        band.width = env.width, band.height = std::min(rows, env.height - y);
        band.rgb.assign(&env.rgb[3 * size_t(y) * size_t(env.width)],
                        &env.rgb[3 * size_t(y + band.height) * size_t(env.width)]);
        resample.add(band, y);
      }
      const auto [worst, differ] = compareTexels(resample.finish(), resampleEnvironment(env, n));
      INFO(differ << " texels differ, by at most " << worst);
      if (rows == env.height) CHECK(differ == 0);  // one band: every texel's lookups in order
      CHECK(worst <= kBandOrderTolerance);
    }
  }
}

TEST_CASE("Bands: a lat-long OpenEXR read in bands gives the whole map's chain", "[prefilter][bands]") {
  const std::string path = test::tempDir("prefilter-bands") + "/sky.exr";
  writeLatLongExr(path, makeLatLong(40, stripedSky));
  const double yaw = 30.0;
  EnvMap whole = loadEnvironment(path);
  whole.yawDegrees = yaw;
  PrefilterOptions sampled = opts(PrefilterLobe::Ggx, PrefilterSchedule::Linear, 32, 3);
  sampled.method = PrefilterMethod::Sampled;
  sampled.samples = 64;
  const std::vector<PrefilterOptions> cases = {rough(16, {0.0, 0.3, 1.0}), rough(64, {0.0, 0.1}),
                                               opts(PrefilterLobe::Charlie, PrefilterSchedule::Filament, 16), sampled};
  for (int rows : {1, 7}) {
    for (const PrefilterOptions& o : cases) {
      INFO(rows << "-row bands, " << toString(o.lobe) << " " << toString(o.method) << " base " << o.baseSize);
      const PrefilterResult a = prefilterEnvironment(test::runtime(), whole, o);
      EnvMap description;
      const PrefilterResult b = prefilterEnvironmentFile(test::runtime, path, {}, yaw, o, &description, rowsOf(whole.width, rows));
      CHECK(description.rgb.empty());  // never held whole
      CHECK(description.width == whole.width);
      CHECK(description.height == whole.height);
      CHECK(description.layoutName == whole.layoutName);
      CHECK(description.inputFiles == whole.inputFiles);
      CHECK(description.clampedTexels == 0);
      CHECK(description.yawDegrees == yaw);
      CHECK(b.sourceTexels == a.sourceTexels);
      CHECK(b.binFaceSize == a.binFaceSize);
      CHECK(b.alphaFloor == a.alphaFloor);
      REQUIRE(b.levels.size() == a.levels.size());
      for (size_t i = 0; i < a.levels.size(); ++i) {
        INFO("level " << i << ", r = " << a.levels[i].spec.roughness);
        CHECK(b.levels[i].alphaUsed == a.levels[i].alphaUsed);
        const auto [worst, differ] = compareTexels(b.levels[i].rgb, a.levels[i].rgb);
        INFO(differ << " texels differ, by at most " << worst);
        if (o.method == PrefilterMethod::Sampled)
          CHECK(worst <= kBandSampledTolerance);
        else if (a.levels[i].alphaUsed == 0.0)
          CHECK(worst <= kBandOrderTolerance);
        else
          CHECK(differ == 0);  // the same tree: the same cut, the same bits
      }
    }
  }
}

TEST_CASE("Bands: a map of one band is read whole and gives the same bits", "[prefilter][bands]") {
  // 64 × 32: one band of 32 rows (a 40-row map would come as 32 + 8: bands are whole chunks).
  const std::string path = test::tempDir("prefilter-one-band") + "/sky.exr";
  writeLatLongExr(path, makeLatLong(32, stripedSky));
  EnvMap whole = loadEnvironment(path);
  whole.yawDegrees = 30.0;
  const PrefilterOptions o = opts(PrefilterLobe::Ggx, PrefilterSchedule::Linear, 32);
  const PrefilterResult a = prefilterEnvironment(test::runtime(), whole, o);
  EnvMap description;
  const PrefilterResult b = prefilterEnvironmentFile(test::runtime, path, {}, 30.0, o, &description);
  CHECK(description.rgb.size() == whole.rgb.size());
  CHECK(std::equal(description.rgb.begin(), description.rgb.end(), whole.rgb.begin(), whole.rgb.end()));
  REQUIRE(b.levels.size() == a.levels.size());
  for (size_t i = 0; i < a.levels.size(); ++i) CHECK(b.levels[i].rgb == a.levels[i].rgb);
  CHECK(prefilterKtx2Bytes(b, true) == prefilterKtx2Bytes(a, true));
}

TEST_CASE("Bands: invalid texels in a later band are refused with the file's name before any level", "[prefilter][bands]") {
  const std::string dir = test::tempDir("prefilter-bands-nan");
  EnvMap env = makeLatLong(40, stripedSky);
  const size_t late = size_t(37) * size_t(env.width) + 11;  // in the sixth band of 7 rows
  env.rgb[3 * late + 1] = std::nanf("");
  writeLatLongExr(dir + "/nan.exr", env);
  std::string wholeError, bandError;
  try {
    loadEnvironment(dir + "/nan.exr");
  } catch (const InputError& e) {
    wholeError = e.what();
  }
  bool deviceAsked = false;
  auto runtime = [&]() -> Runtime& {
    deviceAsked = true;
    return test::runtime();
  };
  const PrefilterOptions o = rough(16, {0.0, 0.5});
  EnvMap description;
  try {
    prefilterEnvironmentFile(runtime, dir + "/nan.exr", {}, 0.0, o, &description, rowsOf(env.width, 7));
  } catch (const InputError& e) {
    bandError = e.what();
  }
  CHECK_THAT(wholeError, Catch::Contains("nan.exr") && Catch::Contains("1 invalid value"));
  CHECK(bandError == wholeError);
  CHECK_FALSE(deviceAsked);
  // Clamped, it is the whole map's chain with that texel at 0.
  EnvLoadOptions clamp;
  clamp.clampInvalid = true;
  const EnvMap clamped = loadEnvironment(dir + "/nan.exr", clamp);
  const PrefilterResult a = prefilterEnvironment(test::runtime(), clamped, o);
  const PrefilterResult b = prefilterEnvironmentFile(runtime, dir + "/nan.exr", clamp, 0.0, o, &description, rowsOf(env.width, 7));
  CHECK(description.clampedTexels == 1);
  CHECK(compareTexels(b.levels[0].rgb, a.levels[0].rgb).first <= kBandOrderTolerance);
  CHECK(b.levels[1].rgb == a.levels[1].rgb);
}
