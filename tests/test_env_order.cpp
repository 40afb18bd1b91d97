// --order auto: a smooth sky gets a low order, a sky with a sun a higher one,
// and the stated irradiance error holds against brute-force irradiance.
#include <catch2/catch.hpp>

#include <cmath>
#include <functional>

#include "prtbake/env.h"
#include "prtbake/sh.h"
#include "env_test_helpers.h"
#include "test_common.h"

using namespace prtbake;

namespace {

const double kPi = 3.14159265358979323846;

// Relative RMS over a spherical Fibonacci set of (E_n − E) where E is the exact
// irradiance of the texels (Σ L max(0, n·ω) Ω) and E_n the order-n SH irradiance.
double measuredIrradianceError(const EnvMap& e, const ShCoeffs& radiance, int order) {
  const ShCoeffs irr = applyWindowAndQuantity(truncateSh(radiance, order), std::vector<double>(size_t(order), 1.0),
                                              ShQuantity::Irradiance);
  std::vector<double> dirs, omega;
  for (size_t t = 0; t < e.texelCount(); ++t) {
    double d[3], w;
    texelDirection(e, t, d, &w);
    dirs.insert(dirs.end(), {d[0], d[1], d[2]});
    omega.push_back(w * e.rgb[3 * t]);
  }
  const int points = 1500;
  double num = 0, den = 0;
  const double golden = kPi * (3 - std::sqrt(5.0));
  for (int i = 0; i < points; ++i) {
    const double z = 1 - (2 * i + 1.0) / points, r = std::sqrt(1 - z * z);
    const double n[3] = {r * std::cos(golden * i), r * std::sin(golden * i), z};
    double exact = 0;
    for (size_t t = 0; t < omega.size(); ++t)
      exact += omega[t] * std::max(0.0, n[0] * dirs[3 * t] + n[1] * dirs[3 * t + 1] + n[2] * dirs[3 * t + 2]);
    const double approx = evalSh(irr, n[0], n[1], n[2])[0];
    num += (approx - exact) * (approx - exact);
    den += exact * exact;
  }
  return std::sqrt(num / den);
}

}  // namespace

TEST_CASE("Order auto: low for a smooth sky, higher with a sun, stated error holds", "[env][order]") {
  // The stated error is measured against an order-24 projection; irradiance beyond
  // band 24 carries Â_l² < 1e-5 of the energy, and the Fibonacci set of 1500 points
  // estimates the sphere's RMS to a few %: kSlack = 1.25 (relative) + 1e-3 (absolute).
  constexpr double kTolerance = 0.01, kSlackRel = 1.25, kSlackAbs = 1e-3;
  const EnvMap smooth = test::makeCube(48, [](const double* d) { const double v = 1.0 + 0.6 * d[1] + 0.2 * d[0] * d[2]; return Rgb{v, v, v}; });
  const EnvMap sun = test::makeCube(48, [](const double* d) {
    const double c = 0.3 * d[0] + 0.8 * d[1] + 0.52 * d[2];
    const double v = 0.5 + 0.3 * d[1] + (c > 0.9995 ? 20000.0 : 0.0);
    return Rgb{v, v, v};
  });
  int chosen[2];
  int k = 0;
  for (const EnvMap* e : {&smooth, &sun}) {
    EnvProjectOptions o;
    o.order = 24;
    const ShCoeffs high = projectEnvironment(test::runtime(), *e, o).radiance;
    double stated = 0;
    const int n = chooseShOrder(high, ShQuantity::Irradiance, kTolerance, &stated);
    const double measured = measuredIrradianceError(*e, high, n);
    INFO("chosen order " << n << ", stated error " << stated << ", measured " << measured);
    REQUIRE(stated <= kTolerance);
    REQUIRE(measured <= kSlackRel * stated + kSlackAbs);
    // Minimal: one order less would not meet the tolerance.
    if (n > 1) REQUIRE(truncationError(high, ShQuantity::Irradiance, n - 1) > kTolerance);
    chosen[k++] = n;
  }
  REQUIRE(chosen[0] <= 3);
  REQUIRE(chosen[1] > chosen[0] + 2);
}

TEST_CASE("CLI --order auto states its choice in the JSON", "[env][order][cli]") {
  const std::string dir = test::tempDir("orderauto");
  const std::string sky = std::string(PRTBAKE_TEST_SOURCE_DIR) + "/../assets/sky.exr";
  auto r = test::runCli("env '" + sky + "' -o '" + dir + "/a.json' --order auto --quantity irradiance --tolerance 0.02");
  REQUIRE(r.exitCode == 0);
  const ShCoeffs c = readShJson(dir + "/a.json");
  REQUIRE(c.order > 3);  // the demo sky has a sun
  REQUIRE(r.output.find("order auto: chose order " + std::to_string(c.order)) != std::string::npos);
  r = test::runCli("env '" + sky + "' -o '" + dir + "/b.json' --order 3 --tolerance 0.02");
  REQUIRE(r.exitCode == 2);
  REQUIRE_FALSE(test::fileExists(dir + "/b.json"));
}
