// "--tolerance E" (prtbake/tolerance.h): a pilot predicts the uniform sample count that
// brings 95 % of the items within E, and the product runs once with it. Asserted here:
//   - at least 95 % of the items within E, against analytic or double references;
//   - the run is the uniform run at the predicted count (bit for bit), plus the pilot;
//   - on the two cheapest cases of the speed/accuracy study (the convex sphere and the
//     128² GGX table), its wall time is at most 1.2 × that of the fastest uniform run whose
//     maximum error is at most its own (docs/accuracy.md runs the same comparison on
//     every case).
#include <catch2/catch.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <vector>

#include "prtbake/lut.h"
#include "prtbake/mesh.h"
#include "prtbake/sh.h"
#include "prtbake/transport.h"
#include "test_common.h"

using namespace prtbake;

namespace {
const double kPi = 3.14159265358979323846;
const double kY0 = 0.28209479177387814;
// Acceptance: at least 95 % of the vertices/texels within the tolerance.
constexpr double kMinFractionBelow = 0.95;
// Acceptance: --tolerance at most 1.2 × the fastest uniform run at its maximum error.
constexpr double kMaxTimeRatio = 1.2;

// Per-item error: the largest |x − ref| over the item's values.
struct Errors {
  std::vector<double> perItem;
  double max() const { return perItem.empty() ? 0 : *std::max_element(perItem.begin(), perItem.end()); }
  double fractionBelow(double e) const {
    size_t n = 0;
    for (double x : perItem) n += x <= e;
    return perItem.empty() ? 1 : double(n) / double(perItem.size());
  }
};

// Funk–Hecke oracle of a convex mesh: every coefficient of every vertex.
Errors sphereErrors(const Mesh& m, const TransportResult& r) {
  Errors e;
  const int nc = r.order * r.order;
  for (size_t v = 0; v < m.vertexCount(); ++v) {
    const auto ref = clampedCosineProjected(r.order, m.normals[3 * v], m.normals[3 * v + 1], m.normals[3 * v + 2]);
    double worst = 0;
    for (int k = 0; k < nc; ++k) worst = std::max(worst, std::abs(double(r.vertex(v)[k]) - ref[k]));
    e.perItem.push_back(worst);
  }
  return e;
}

// Open spherical cavity (see test_transport.cpp): every inner point has T00 = Y0 (1 − cos α)/2.
Errors cavityErrors(const Mesh& m, const TransportResult& r, double alpha) {
  Errors e;
  const double expect = kY0 * (1 - std::cos(alpha)) / 2;
  for (size_t v = 0; v < m.vertexCount(); ++v) {
    if (m.positions[3 * v + 2] > std::cos(alpha + kPi / 12)) continue;  // inner points only
    e.perItem.push_back(std::abs(double(r.vertex(v)[0]) - expect));
  }
  return e;
}

Errors lutErrors(const LutResult& lut, const LutValues& ref) {
  Errors e;
  for (size_t t = 0; t < lut.a.size(); ++t)
    e.perItem.push_back(std::max({std::abs(lut.a[t] - ref.a[t]), std::abs(lut.b[t] - ref.b[t]),
                                  ref.cloth.empty() ? 0.0 : std::abs(lut.third[t] - ref.cloth[t])}));
  return e;
}

// Shortest wall times of runs of a and of b, interleaved (a, b, a, b, ...) after an
// untimed run of each, repeated for at least kTimingSeconds and kTimingMinReps pairs.
// The shortest, not the median: a busy machine only ever adds time, and runs of about a
// millisecond are what a preempted slice or a late thread wake-up distorts most (medians
// of 21 read 1.24x in CI for a pair that is 1.08x here).
constexpr double kTimingSeconds = 1.0;
constexpr int kTimingMinReps = 21;
std::pair<double, double> interleavedMinimums(const std::function<void()>& a, const std::function<void()>& b) {
  a();
  b();
  double ta = 1e30, tb = 1e30, total = 0;
  auto time = [&total](const std::function<void()>& f) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    total += t;
    return t;
  };
  for (int i = 0; i < kTimingMinReps || total < kTimingSeconds; ++i) {
    ta = std::min(ta, time(a));
    tb = std::min(tb, time(b));
  }
  return {ta, tb};
}
}  // namespace

TEST_CASE("Tolerance: a convex sphere takes the closed form, unshadowed transport too", "[tolerance][transport]") {
  // Float rounding of the closed form's coefficients.
  constexpr double kClosedFormTol = 1e-6;
  const Mesh sphere = makeUvSphere(1.0, 12, 24);
  for (TransportMode mode : {TransportMode::Shadowed, TransportMode::Unshadowed, TransportMode::Interreflected}) {
    INFO(transportModeName(mode));
    TransportOptions o;
    o.mode = mode;
    o.tolerance = 1e-3;
    const TransportResult r = computeTransport(test::runtime(), sphere, o);
    CHECK(r.totalSamples == 0);
    CHECK(r.rays == 0);
    CHECK(sphereErrors(sphere, r).max() < kClosedFormTol);
    REQUIRE(!r.tolerance.empty());
    CHECK(r.tolerance[0].strategy == "closed form");
  }
}

TEST_CASE("Tolerance: the open cavity within E, and the same as the uniform run at the count", "[tolerance][transport]") {
  const double alpha = kPi / 3;
  const Mesh cavity = makeOpenSphereCavity(1.0, alpha, 12, 48);
  for (double tolerance : {1e-2, 2e-3}) {
    INFO("E = " << tolerance);
    TransportOptions o;
    o.tolerance = tolerance;
    const TransportResult r = computeTransport(test::runtime(), cavity, o);
    const Errors e = cavityErrors(cavity, r, alpha);
    REQUIRE(r.tolerance.size() == 1);
    const ToleranceReport& t = r.tolerance[0];
    INFO("count " << t.samples << ", predicted " << t.predictedError << ", max error " << e.max() << ", below E "
                  << e.fractionBelow(tolerance));
    CHECK(e.fractionBelow(tolerance) >= kMinFractionBelow);
    CHECK_FALSE(t.capped);
    // The pilot ran on one in 8 of the cavity's vertices (fewer than 1,024, more than 512).
    CHECK(t.pilotItems == (t.items + kTolerancePilotShare / 2 - 1) / kTolerancePilotShare);
    CHECK(t.items == cavity.vertexCount());
    // The sampled vertices are those of the uniform run at that count, bit for bit.
    TransportOptions u;
    u.samples = t.samples;
    const TransportResult ur = computeTransport(test::runtime(), cavity, u);
    CHECK(ur.coeffs == r.coeffs);
  }
}

TEST_CASE("Tolerance: interreflection, every term from its own pilot", "[tolerance][transport]") {
  // The open cavity (normals inward): every vertex is occludable and receives bounces.
  // Term k gets E/2^(k+1); the total is checked against a converged uniform run.
  Mesh scene = makeOpenSphereCavity(1.0, kPi / 4, 10, 40);
  constexpr double kTolerance = 4e-3;
  TransportOptions o;
  o.mode = TransportMode::Interreflected;
  o.bounces = 2;
  o.bounceTolerance = 0;
  o.albedoOverride = std::array<float, 3>{0.8f, 0.8f, 0.8f};
  o.tolerance = kTolerance;
  const TransportResult r = computeTransport(test::runtime(), scene, o);
  REQUIRE(r.tolerance.size() == 3);
  for (size_t k = 0; k < r.tolerance.size(); ++k) {
    INFO("term " << k << ": " << r.tolerance[k].samples << " samples");
    CHECK(r.tolerance[k].tolerance == Approx(kTolerance / std::pow(2.0, double(k + 1))));
    CHECK(r.tolerance[k].samples > 0);
  }
  TransportOptions ref = o;
  ref.tolerance = 0;
  ref.samples = 32768;
  const TransportResult rr = computeTransport(test::runtime(), scene, ref);
  Errors e;
  const int nc = 9;
  for (size_t v = 0; v < scene.vertexCount(); ++v) {
    double worst = 0;
    for (int k = 0; k < nc; ++k) worst = std::max(worst, std::abs(double(r.vertex(v)[k]) - rr.vertex(v)[k]));
    e.perItem.push_back(worst);
  }
  INFO("max error " << e.max() << ", below E " << e.fractionBelow(kTolerance));
  CHECK(e.fractionBelow(kTolerance) >= kMinFractionBelow);
}

TEST_CASE("Tolerance: LUT against the double reference", "[tolerance][lut]") {
  struct Case {
    const char* name;
    LutNdf ndf;
    bool cloth;
    double tolerance;
  };
  for (const Case& c : {Case{"ggx", LutNdf::Ggx, false, 1e-3}, Case{"ggx", LutNdf::Ggx, false, 1e-4},
                        Case{"beckmann", LutNdf::Beckmann, false, 3e-4}, Case{"ggx+cloth", LutNdf::Ggx, true, 1e-3}}) {
    INFO(c.name << " E = " << c.tolerance);
    LutOptions o;
    o.size = 32;
    o.ndf = c.ndf;
    o.cloth = c.cloth;
    o.tolerance = c.tolerance;
    const LutResult lut = computeLut(test::runtime(), o);
    const LutValues ref = evaluateLutReference(o, [&] {
      std::vector<LutPoint> p;
      for (int j = 0; j < o.size; ++j)
        for (int i = 0; i < o.size; ++i) p.push_back({(i + 0.5) / o.size, (j + 0.5) / o.size});
      return p;
    }());
    const Errors e = lutErrors(lut, ref);
    INFO("count " << lut.tolerance.samples << ", predicted " << lut.tolerance.predictedError << ", max error " << e.max()
                  << ", below E " << e.fractionBelow(c.tolerance));
    CHECK(e.fractionBelow(c.tolerance) >= kMinFractionBelow);
    // The table is the uniform table at that count.
    LutOptions u = o;
    u.tolerance = 0;
    u.samples = lut.tolerance.samples;
    const LutResult ul = computeLut(test::runtime(), u);
    CHECK(ul.a == lut.a);
    CHECK(ul.b == lut.b);
  }
}

TEST_CASE("Tolerance: no slower than the fastest uniform run at the same error (sphere, 128² GGX)",
          "[tolerance][timing]") {
  // The study's two cheapest cases. The fastest uniform run that meets the tolerance
  // run's maximum error is the smallest count among the powers of two and the pilot's
  // count that does (time grows with the count); the two are then timed interleaved,
  // the shortest runs of each over a second or more (interleavedMinimums).
  SECTION("sphere: the closed form, which no uniform count up to 65536 reaches") {
    const Mesh sphere = makeUvSphere(1.0, 24, 48);
    TransportOptions o;
    o.tolerance = 2e-3;
    const TransportResult r = computeTransport(test::runtime(), sphere, o);
    const double errTol = sphereErrors(sphere, r).max();
    CHECK(errTol < 1e-6);
    TransportOptions u;
    u.samples = 1 << 16;
    CHECK(sphereErrors(sphere, computeTransport(test::runtime(), sphere, u)).max() > errTol);
    // And its time against the cheapest uniform run at all (16 samples).
    u.samples = 16;
    const auto [tTol, tUniform] = interleavedMinimums(
        [&] { computeTransport(test::runtime(), sphere, o); }, [&] { computeTransport(test::runtime(), sphere, u); });
    INFO("closed form " << tTol << " s, 16 samples " << tUniform << " s");
    CHECK(tTol <= kMaxTimeRatio * tUniform);
  }
  SECTION("128² GGX table (the default size)") {
    LutOptions o;
    o.size = 128;
    const LutResult ref = computeLutReference(o);
    auto maxError = [&](const LutResult& l) {
      double m = 0;
      for (size_t i = 0; i < l.a.size(); ++i)
        m = std::max({m, double(std::abs(l.a[i] - ref.a[i])), double(std::abs(l.b[i] - ref.b[i]))});
      return m;
    };
    for (double tolerance : {1e-2, 1e-3, 1e-4}) {
      o.tolerance = tolerance;
      const LutResult lut = computeLut(test::runtime(), o);
      const double errTol = maxError(lut);
      std::vector<int> counts = {lut.tolerance.samples};
      for (int n = 16; n <= (1 << 16); n *= 2) counts.push_back(n);
      std::sort(counts.begin(), counts.end());
      LutOptions u = o;
      u.tolerance = 0;
      u.samples = 0;
      for (int n : counts) {
        u.samples = n;
        if (maxError(computeLut(test::runtime(), u)) <= errTol) break;
      }
      const auto [tTol, tUniform] = interleavedMinimums(
          [&] { computeLut(test::runtime(), o); }, [&] { computeLut(test::runtime(), u); });
      INFO("E = " << tolerance << ": tolerance " << tTol << " s (count " << lut.tolerance.samples << ", max error "
                  << errTol << "); fastest uniform meeting it: " << u.samples << " samples, " << tUniform << " s");
      CHECK(tTol <= kMaxTimeRatio * tUniform);
    }
  }
}

TEST_CASE("Tolerance: command line and sidecars", "[tolerance][cli]") {
  const std::string dir = test::tempDir("tolerance-cli");
  auto both = test::runCli("lut -o '" + dir + "/x.exr' --samples 64 --tolerance 1e-2");
  CHECK(both.exitCode == 2);
  CHECK_THAT(both.output, Catch::Contains("--tolerance: cannot be combined with samples"));
  auto lut = test::runCli("lut -o '" + dir + "/l.exr' --size 8 --tolerance 1e-2 --quiet");
  REQUIRE(lut.exitCode == 0);
  std::ifstream lj(dir + "/l.json");
  const std::string lutSidecar((std::istreambuf_iterator<char>(lj)), std::istreambuf_iterator<char>());
  CHECK_THAT(lutSidecar, Catch::Contains("\"strategy\": \"uniform, count predicted from a pilot\""));
  CHECK_THAT(lutSidecar, Catch::Contains("\"predicted_error_p95\""));
  const std::string obj = dir + "/tri.obj";
  std::ofstream(obj) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n";
  auto tr = test::runCli("transport '" + obj + "' -o '" + dir + "/t.npy' --tolerance 1e-2 --quiet");
  REQUIRE(tr.exitCode == 0);
  std::ifstream tj(dir + "/t.json");
  const std::string trSidecar((std::istreambuf_iterator<char>(tj)), std::istreambuf_iterator<char>());
  CHECK_THAT(trSidecar, Catch::Contains("\"vertices_unoccludable\": 3"));
  CHECK_THAT(trSidecar, Catch::Contains("\"strategy\": \"closed form\""));
  CHECK(test::runCli("transport '" + obj + "' -o '" + dir + "/u.npy' --samples 64 --tolerance 1e-2").exitCode == 2);
}
