// SH basis: hard-coded vs recurrence, exact values on the axes, orthonormality
// by quadrature (double reference and float kernel), clamped-cosine factors.
#include <catch2/catch.hpp>

#include <cmath>
#include <vector>

#include "core/gauss_legendre.h"
#include "prtbake/sh.h"
#include "test_common.h"

using namespace prtbake;

namespace {
// Hard-coded and recurrence evaluate the same polynomials in a different order of
// operations: they agree to a few ulps of double.
constexpr double kHardVsRecurrenceTol = 1e-13;
// docs/conventions.md "SH basis" prints the constants to 6 decimals: up to 1.6e-6 relative rounding.
constexpr double kTableTol = 2e-6;
const double kPi = 3.14159265358979323846;
}  // namespace

TEST_CASE("SH hard-coded polynomials equal the recurrence", "[sh]") {
  std::vector<double> a(16), b(16);
  for (int k = 0; k < 200; ++k) {
    double x = std::sin(k * 1.7), y = std::cos(k * 0.3), z = std::sin(k * 2.9 + 1.0);
    const double r = std::sqrt(x * x + y * y + z * z);
    x /= r, y /= r, z /= r;
    for (int order = 1; order <= 4; ++order) {
      shEvalHardcoded(order, x, y, z, a.data());
      shEvalRecurrence(order, x, y, z, b.data());
      for (int i = 0; i < order * order; ++i) REQUIRE(std::abs(a[i] - b[i]) < kHardVsRecurrenceTol);
    }
  }
}

TEST_CASE("SH matches the docs/conventions.md table and closed forms on the axes and poles", "[sh]") {
  // Closed forms: Y_l0(±z) = (±1)^l √((2l+1)/(4π)) and every m ≠ 0 vanishes at the poles;
  // on the equator Y_l,±l of (1,0,0) and (0,1,0) follow from (x+iy)^l.
  const int order = 16;
  std::vector<double> y(order * order);
  for (double s : {1.0, -1.0}) {
    shEvalRecurrence(order, 0, 0, s, y.data());
    for (int l = 0; l < order; ++l)
      for (int m = -l; m <= l; ++m) {
        const double expect = m == 0 ? std::pow(s, l) * std::sqrt((2 * l + 1) / (4 * kPi)) : 0.0;
        REQUIRE(y[shIndex(l, m)] == Approx(expect).margin(1e-15).epsilon(1e-13));
      }
  }
  // The docs/conventions.md "SH basis" table at ±x, ±y.
  const double c1 = 0.488603, c2a = 1.092548, c2c = 0.546274, c2b = 0.315392;
  shEval(3, 1, 0, 0, y.data());
  CHECK(y[3] == Approx(-c1).epsilon(kTableTol));
  CHECK(y[8] == Approx(c2c).epsilon(kTableTol));
  CHECK(y[6] == Approx(-c2b).epsilon(kTableTol));
  CHECK(y[1] == 0.0);
  shEval(3, 0, -1, 0, y.data());
  CHECK(y[1] == Approx(c1).epsilon(kTableTol));
  CHECK(y[8] == Approx(-c2c).epsilon(kTableTol));
  const double h = std::sqrt(0.5);
  shEval(3, h, h, 0, y.data());
  CHECK(y[4] == Approx(c2a * 0.5).epsilon(kTableTol));
  // Y_l,l at +x = √2 Q_l^l, |Y_l,-l| at +y = |Y_l,l| at +x; Y_l,l at +y = Re(i^l)·...
  shEvalRecurrence(order, 1, 0, 0, y.data());
  std::vector<double> yy(order * order);
  shEvalRecurrence(order, 0, 1, 0, yy.data());
  for (int l = 1; l < order; ++l) {
    REQUIRE(y[shIndex(l, -l)] == Approx(0.0).margin(1e-15));
    REQUIRE(std::abs(yy[shIndex(l, l % 2 ? -l : l)]) == Approx(std::abs(y[shIndex(l, l)])).epsilon(1e-13));
  }
}

// Gauss–Legendre nodes/weights on [-1, 1] (gauss_legendre.h gives them on [0, 1]), for
// exact quadrature of polynomials on the sphere: n nodes in z times 2n+1 in φ integrate
// products of SH up to degree 2n−1 exactly.
static void gaussLegendre(int n, std::vector<double>& x, std::vector<double>& w) {
  const prtbake::detail::GaussRule g = prtbake::detail::gaussLegendre(n);
  x.resize(n), w.resize(n);
  for (int i = 0; i < n; ++i) x[i] = 2 * g.x[i] - 1, w[i] = 2 * g.w[i];
}

TEST_CASE("SH orthonormality by exact quadrature to 16 bands (double)", "[sh]") {
  // Gauss–Legendre × uniform φ is exact for these polynomials; what remains is
  // rounding, ~1e-14. kDoubleOrthoTol = 1e-10 is the acceptance bound.
  constexpr double kDoubleOrthoTol = 1e-10;
  const int order = 16, n = order + 1, nphi = 2 * order + 1, nc = order * order;
  std::vector<double> zs, ws, y(nc), gram(nc * nc, 0.0);
  gaussLegendre(n, zs, ws);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < nphi; ++j) {
      const double phi = 2 * kPi * j / nphi, s = std::sqrt(1 - zs[i] * zs[i]);
      shEval(order, s * std::cos(phi), s * std::sin(phi), zs[i], y.data());
      const double wt = ws[i] * 2 * kPi / nphi;
      for (int a = 0; a < nc; ++a)
        for (int b = 0; b < nc; ++b) gram[a * nc + b] += wt * y[a] * y[b];
    }
  double worst = 0;
  for (int a = 0; a < nc; ++a)
    for (int b = 0; b < nc; ++b) worst = std::max(worst, std::abs(gram[a * nc + b] - (a == b)));
  INFO("max |G - I| = " << worst);
  REQUIRE(worst < kDoubleOrthoTol);
}

TEST_CASE("SH orthonormality by quadrature to 16 bands (float kernel)", "[sh][kernel]") {
  // The kernel evaluates in float: each Y carries ~1e-6 relative error (the
  // recurrence grows it mildly with l), and the Gram sums are formed in double on
  // the host, so |G − I| stays near 1e-5; kFloatOrthoTol = 1e-4 is the acceptance bound.
  constexpr double kFloatOrthoTol = 1e-4;
  const int order = 16, n = order + 1, nphi = 2 * order + 1, nc = order * order;
  std::vector<double> zs, ws;
  gaussLegendre(n, zs, ws);
  std::vector<float> dirs;
  std::vector<double> wts;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < nphi; ++j) {
      const double phi = 2 * kPi * j / nphi, s = std::sqrt(1 - zs[i] * zs[i]);
      dirs.insert(dirs.end(), {float(s * std::cos(phi)), float(s * std::sin(phi)), float(zs[i])});
      wts.push_back(ws[i] * 2 * kPi / nphi);
    }
  auto& rt = test::runtime();
  const int count = int(wts.size());
  cl::Buffer dirBuf(rt.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, dirs.size() * 4, dirs.data());
  cl::Buffer outBuf(rt.context(), CL_MEM_WRITE_ONLY, size_t(count) * nc * 4);
  cl::Kernel k = rt.kernel("sh_eval.cl", "sh_eval_dirs");
  k.setArg(0, order);
  k.setArg(1, count);
  k.setArg(2, dirBuf);
  k.setArg(3, outBuf);
  rt.queue().enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(size_t(count)));
  std::vector<float> y(size_t(count) * nc);
  rt.queue().enqueueReadBuffer(outBuf, CL_TRUE, 0, y.size() * 4, y.data());
  std::vector<double> gram(nc * nc, 0.0);
  for (int d = 0; d < count; ++d)
    for (int a = 0; a < nc; ++a)
      for (int b = 0; b < nc; ++b) gram[a * nc + b] += wts[d] * y[size_t(d) * nc + a] * y[size_t(d) * nc + b];
  double worst = 0;
  for (int a = 0; a < nc; ++a)
    for (int b = 0; b < nc; ++b) worst = std::max(worst, std::abs(gram[a * nc + b] - (a == b)));
  INFO("max |G - I| = " << worst);
  REQUIRE(worst < kFloatOrthoTol);
  // And the kernel against the double reference, value by value.
  std::vector<double> ref(nc);
  double worstVal = 0;
  for (int d = 0; d < count; ++d) {
    shEval(order, dirs[3 * d], dirs[3 * d + 1], dirs[3 * d + 2], ref.data());
    for (int a = 0; a < nc; ++a) worstVal = std::max(worstVal, std::abs(ref[a] - y[size_t(d) * nc + a]));
  }
  INFO("max |Y_kernel - Y_ref| = " << worstVal);
  REQUIRE(worstVal < 1e-4);
}

TEST_CASE("Clamped-cosine factors match closed values and quadrature", "[sh]") {
  CHECK(clampedCosineFactor(0) == Approx(kPi));
  CHECK(clampedCosineFactor(1) == Approx(2 * kPi / 3));
  CHECK(clampedCosineFactor(2) == Approx(kPi / 4));
  CHECK(clampedCosineFactor(3) == 0.0);
  CHECK(clampedCosineFactor(4) == Approx(-kPi / 24));
  // Â_l = 2π ∫_0^1 t P_l(t) dt · ... checked numerically via Y_l0 for l up to 12.
  for (int l = 0; l <= 12; ++l) {
    const int steps = 200000;
    double s = 0;
    std::vector<double> y((l + 1) * (l + 1));
    for (int i = 0; i < steps; ++i) {
      const double t = (i + 0.5) / steps;
      shEval(l + 1, 0, std::sqrt(1 - t * t), t, y.data());
      s += t * y[shIndex(l, 0)] / steps;
    }
    const double ahat = 2 * kPi * s / std::sqrt((2 * l + 1) / (4 * kPi));
    INFO("l = " << l);
    CHECK(clampedCosineFactor(l) == Approx(ahat).margin(1e-8));
  }
}
