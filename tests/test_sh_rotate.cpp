// SH rotation: exact vs projection method vs projecting a rotated environment.
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>

#include "prtbake/env.h"
#include "prtbake/error.h"
#include "prtbake/sh.h"
#include "prtbake/sh_rotate.h"
#include "test_common.h"

using namespace prtbake;

namespace {

ShCoeffs someCoeffs(int order) {
  ShCoeffs c;
  c.order = order;
  for (int i = 0; i < order * order; ++i)
    c.rgb.push_back({std::sin(1.3 * i + 0.2), std::cos(0.7 * i), 1.0 / (1 + i)});
  return c;
}

double bandEnergy(const ShCoeffs& c, int l, int ch) {
  double s = 0;
  for (int m = -l; m <= l; ++m) s += c.rgb[size_t(shIndex(l, m))][size_t(ch)] * c.rgb[size_t(shIndex(l, m))][size_t(ch)];
  return s;
}

}  // namespace

TEST_CASE("Exact rotation rotates the function: f'(R d) = f(d)", "[rotate]") {
  // Evaluating the rotated expansion at R·d must give the original at d; this fixes
  // the direction convention and the basis signs. Rounding only: 1e-10.
  constexpr double kPointTol = 1e-10;
  const int order = 10;
  const ShCoeffs c = someCoeffs(order);
  for (const Rotation& r : {rotationFromEulerZYZ(30, 50, -70), rotationFromQuaternion(0.3, -0.5, 0.7, 0.2),
                            rotationFromEulerZYZ(0, 180, 0), rotationFromEulerZYZ(90, 0, 0)}) {
    const ShCoeffs rc = applyShRotation(c, shRotationExact(r, order));
    for (int k = 0; k < 20; ++k) {
      std::array<double, 3> d{std::sin(k * 1.1), std::cos(k * 0.4), std::sin(k * 2.3 + 0.5)};
      const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      for (double& x : d) x /= n;
      const auto rd = r.apply(d);
      const Rgb a = evalSh(c, d[0], d[1], d[2]), b = evalSh(rc, rd[0], rd[1], rd[2]);
      for (int ch = 0; ch < 3; ++ch) REQUIRE(std::abs(a[size_t(ch)] - b[size_t(ch)]) < kPointTol);
    }
  }
}

TEST_CASE("Rotation keeps band energy, exact and projection methods agree", "[rotate]") {
  constexpr double kEnergyTol = 1e-6;      // acceptance bound (observed ~1e-14)
  constexpr double kMethodsAgreeTol = 1e-8;  // both are exact up to cond(A)·ε ≈ 1e4·1e-16
  for (int order : {3, 8, 16}) {
    const ShCoeffs c = someCoeffs(order);
    const Rotation r = rotationFromEulerZYZ(12, 77, 201);
    double cond = 0;
    const ShCoeffs a = applyShRotation(c, shRotationExact(r, order));
    const ShCoeffs b = applyShRotation(c, shRotationProjection(r, order, {}, 1e8, &cond));
    INFO("order " << order << " worst cond(A) " << cond);
    for (int l = 0; l < order; ++l)
      for (int ch = 0; ch < 3; ++ch) {
        const double e0 = bandEnergy(c, l, ch);
        REQUIRE(std::abs(bandEnergy(a, l, ch) - e0) <= kEnergyTol * std::max(1.0, e0));
        REQUIRE(std::abs(bandEnergy(b, l, ch) - e0) <= kEnergyTol * std::max(1.0, e0));
      }
    for (size_t i = 0; i < c.rgb.size(); ++i)
      for (int ch = 0; ch < 3; ++ch) REQUIRE(std::abs(a.rgb[i][size_t(ch)] - b.rgb[i][size_t(ch)]) < kMethodsAgreeTol);
  }
}

TEST_CASE("Projection method refuses an ill-conditioned direction set", "[rotate]") {
  // Band 2 with five directions of which two coincide: A is singular.
  std::vector<std::vector<std::array<double, 3>>> dirs = {
      {{0, 0, 1}},
      {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}},
      {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 0, 1}, {0.6, 0.8, 0}}};
  REQUIRE_THROWS_WITH(shRotationProjection(rotationFromEulerZYZ(10, 20, 30), 3, dirs),
                      Catch::Contains("ill-conditioned") && Catch::Contains("band 2"));
  // Antipodal pairs make even bands rank-deficient (Y_l(−n) = Y_l(n) for even l).
  dirs[2] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}};
  REQUIRE_THROWS_WITH(shRotationProjection(rotationFromEulerZYZ(10, 20, 30), 3, dirs),
                      Catch::Contains("ill-conditioned"));
}

TEST_CASE("Rotating coefficients equals projecting the rotated environment", "[rotate][kernel]") {
  // Yaw about +Y is a rotation the loader can apply to the texels themselves;
  // projecting that environment must give the rotated coefficients up to the
  // discretisation error of the cube (smooth signal, N = 96: < 1e-4 of L00).
  constexpr double kDiscretisationTol = 1e-4;
  EnvMap e;
  e.layout = EnvLayout::Cube;
  e.width = e.height = 96;
  e.rgb.resize(e.texelCount() * 3);
  for (size_t t = 0; t < e.texelCount(); ++t) {
    double d[3];
    texelDirection(e, t, d, nullptr);
    const float v = float(1.0 + std::exp(3 * (0.48 * d[0] + 0.6 * d[1] + 0.64 * d[2] - 1)));
    e.rgb[3 * t] = e.rgb[3 * t + 1] = e.rgb[3 * t + 2] = v;
  }
  EnvProjectOptions o;
  o.order = 5;
  const ShCoeffs base = projectEnvironment(test::runtime(), e, o).coeffs;
  e.yawDegrees = 63;
  const ShCoeffs turned = projectEnvironment(test::runtime(), e, o).coeffs;
  // Yaw maps d to Ry(yaw)·d, i.e. Euler ZYZ would need a frame change: build Ry directly.
  const double a = 63 * 3.14159265358979323846 / 180;
  Rotation ry;
  ry.m = {std::cos(a), 0, std::sin(a), 0, 1, 0, -std::sin(a), 0, std::cos(a)};
  const ShCoeffs rotated = applyShRotation(base, shRotationExact(ry, 5));
  for (size_t i = 0; i < rotated.rgb.size(); ++i) {
    INFO("coefficient " << i);
    REQUIRE(std::abs(rotated.rgb[i][0] - turned.rgb[i][0]) < kDiscretisationTol * base.rgb[0][0]);
  }
}

TEST_CASE("CLI rotate: exact and projection give the same file values, bad input", "[rotate][cli]") {
  const std::string dir = test::tempDir("rotatecli");
  ShCoeffs c;
  c.order = 4;
  for (int i = 0; i < 16; ++i) c.rgb.push_back({0.1 * i, -0.05 * i, 1.0 / (1 + i)});
  writeShJson(dir + "/in.json", c, "{}");
  auto r = test::runCli("rotate '" + dir + "/in.json' -o '" + dir + "/a.json' --euler-zyz 10,20,30 --quiet");
  REQUIRE(r.exitCode == 0);
  r = test::runCli("rotate '" + dir + "/in.json' -o '" + dir + "/b.json' --euler-zyz 10,20,30 --method projection --quiet");
  REQUIRE(r.exitCode == 0);
  const ShCoeffs a = readShJson(dir + "/a.json"), b = readShJson(dir + "/b.json");
  const ShCoeffs expect = applyShRotation(c, shRotationExact(rotationFromEulerZYZ(10, 20, 30), 4));
  for (size_t i = 0; i < 16; ++i)
    for (int ch = 0; ch < 3; ++ch) {
      REQUIRE(a.rgb[i][size_t(ch)] == Approx(expect.rgb[i][size_t(ch)]).margin(1e-12));
      REQUIRE(b.rgb[i][size_t(ch)] == Approx(expect.rgb[i][size_t(ch)]).margin(1e-9));
    }
  // A quaternion for the same rotation about +Z by 90° as Euler (90, 0, 0).
  r = test::runCli("rotate '" + dir + "/in.json' -o '" + dir + "/q.json' --quat 0.70710678118654752,0,0,0.70710678118654752 --quiet");
  REQUIRE(r.exitCode == 0);
  const ShCoeffs q = readShJson(dir + "/q.json");
  const ShCoeffs e = applyShRotation(c, shRotationExact(rotationFromEulerZYZ(90, 0, 0), 4));
  for (size_t i = 0; i < 16; ++i) REQUIRE(q.rgb[i][0] == Approx(e.rgb[i][0]).margin(1e-12));
  // Bad input: no rotation, both, malformed angles, a zero quaternion, a missing or non-SH file.
  for (const std::string& bad : {std::string(""), std::string("--euler-zyz 1,2,3 --quat 1,0,0,0"),
                                  std::string("--euler-zyz 1,2"), std::string("--quat 0,0,0,0")}) {
    r = test::runCli("rotate '" + dir + "/in.json' -o '" + dir + "/bad.json' " + bad);
    INFO(bad << ": " << r.output);
    REQUIRE(r.exitCode == 2);
    REQUIRE_FALSE(test::fileExists(dir + "/bad.json"));
  }
  std::ofstream(dir + "/junk.json") << "{\"order\": 3}";
  r = test::runCli("rotate '" + dir + "/junk.json' -o '" + dir + "/bad.json' --euler-zyz 1,2,3");
  REQUIRE(r.exitCode == 1);
  REQUIRE(r.output.find("junk.json") != std::string::npos);
  REQUIRE_FALSE(test::fileExists(dir + "/bad.json"));
}
