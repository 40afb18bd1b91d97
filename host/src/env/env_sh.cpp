// Windows, quantities, deringing, SH evaluation and the env SH writers.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "core/constants.h"
#include "prtbake/atomic_file.h"
#include "prtbake/env.h"
#include "prtbake/error.h"
#include "prtbake/sh.h"

namespace prtbake {
const char* toString(ShWindow w) {
  switch (w) {
    case ShWindow::None: return "none";
    case ShWindow::Hann: return "hann";
    case ShWindow::Lanczos: return "lanczos";
    case ShWindow::Auto: return "auto";
  }
  return "?";
}

ShWindow parseWindow(const std::string& s) {
  for (auto w : {ShWindow::None, ShWindow::Hann, ShWindow::Lanczos, ShWindow::Auto})
    if (s == toString(w)) return w;
  throw UsageError("--window", "unknown value '" + s + "' (expected none|hann|lanczos|auto)");
}

std::vector<double> windowWeights(ShWindow w, int order) {
  // Both windows reach zero at l = order (the first band not stored), so every
  // stored band keeps a positive weight (Sloan, "Stupid SH Tricks", §windowing).
  std::vector<double> out(size_t(order), 1.0);
  for (int l = 0; l < order; ++l) {
    const double t = kPi * l / order;
    if (w == ShWindow::Hann) out[size_t(l)] = 0.5 * (1.0 + std::cos(t));
    if (w == ShWindow::Lanczos) out[size_t(l)] = l == 0 ? 1.0 : std::sin(t) / t;
  }
  return out;
}

ShCoeffs applyWindowAndQuantity(const ShCoeffs& radiance, const std::vector<double>& weights, ShQuantity q) {
  ShCoeffs out = radiance;
  out.quantity = q;
  for (int l = 0; l < radiance.order; ++l) {
    double f = weights[size_t(l)];
    if (q != ShQuantity::Radiance) f *= clampedCosineFactor(l);
    if (q == ShQuantity::IrradianceOverPi) f /= kPi;
    for (int m = -l; m <= l; ++m)
      for (double& v : out.rgb[size_t(shIndex(l, m))]) v *= f;
  }
  return out;
}

double truncationError(const ShCoeffs& high, ShQuantity quantity, int order) {
  double total = 0, tail = 0;
  for (int l = 0; l < high.order; ++l) {
    const double f = quantity == ShQuantity::Radiance ? 1.0 : clampedCosineFactor(l);
    double band = 0;
    for (int m = -l; m <= l; ++m)
      for (double v : high.rgb[size_t(shIndex(l, m))]) band += v * v;
    total += f * f * band;
    if (l >= order) tail += f * f * band;
  }
  return total > 0 ? std::sqrt(tail / total) : 0.0;
}

int chooseShOrder(const ShCoeffs& high, ShQuantity quantity, double tolerance, double* achievedError) {
  for (int n = 1; n <= high.order; ++n) {
    const double e = truncationError(high, quantity, n);
    if (e <= tolerance || n == high.order) {
      if (achievedError) *achievedError = e;
      return n;
    }
  }
  return high.order;
}

ShCoeffs truncateSh(const ShCoeffs& c, int order) {
  ShCoeffs out = c;
  out.order = std::min(order, c.order);
  out.rgb.resize(size_t(out.order) * size_t(out.order));
  return out;
}

Rgb evalSh(const ShCoeffs& c, double x, double y, double z) {
  std::vector<double> basis(c.rgb.size());
  shEval(c.order, x, y, z, basis.data());
  Rgb out{0, 0, 0};
  for (size_t k = 0; k < basis.size(); ++k)
    for (int ch = 0; ch < 3; ++ch) out[size_t(ch)] += basis[k] * c.rgb[k][size_t(ch)];
  return out;
}

namespace {

// A dense, even point set on the sphere (spherical Fibonacci), with the basis
// evaluated once so that each trial window costs one matrix-vector product.
struct SphereGrid {
  int order;
  size_t points;
  std::vector<double> dirs, basis;
  SphereGrid(int order_, size_t points_) : order(order_), points(points_) {
    const size_t nc = size_t(order) * size_t(order);
    dirs.resize(3 * points);
    basis.resize(points * nc);
    const double golden = kPi * (3.0 - std::sqrt(5.0));
    for (size_t i = 0; i < points; ++i) {
      const double z = 1.0 - (2.0 * double(i) + 1.0) / double(points), r = std::sqrt(1.0 - z * z);
      const double phi = golden * double(i);
      dirs[3 * i] = r * std::cos(phi), dirs[3 * i + 1] = r * std::sin(phi), dirs[3 * i + 2] = z;
      shEval(order, dirs[3 * i], dirs[3 * i + 1], dirs[3 * i + 2], basis.data() + i * nc);
    }
  }
};

// Minimum over the grid (then refined around the worst point) of the irradiance
// Σ w_l Â_l L_lm Y_lm over the three channels.
double minIrradiance(const ShCoeffs& radiance, const std::vector<double>& w, const SphereGrid& grid) {
  const ShCoeffs e = applyWindowAndQuantity(radiance, w, ShQuantity::Irradiance);
  const size_t nc = e.rgb.size();
  double best = 1e300;
  size_t bestI = 0;
  for (size_t i = 0; i < grid.points; ++i) {
    const double* y = grid.basis.data() + i * nc;
    for (int ch = 0; ch < 3; ++ch) {
      double s = 0;
      for (size_t k = 0; k < nc; ++k) s += y[k] * e.rgb[k][size_t(ch)];
      if (s < best) best = s, bestI = i;
    }
  }
  // Local refinement: a shrinking pattern search around the worst grid point.
  double d[3] = {grid.dirs[3 * bestI], grid.dirs[3 * bestI + 1], grid.dirs[3 * bestI + 2]};
  double step = 2.0 / std::sqrt(double(grid.points));
  for (int it = 0; it < 40 && step > 1e-7; ++it) {
    bool improved = false;
    for (int axis = 0; axis < 3; ++axis)
      for (double sgn : {-1.0, 1.0}) {
        double t[3] = {d[0], d[1], d[2]};
        t[axis] += sgn * step;
        const double n = std::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
        t[0] /= n, t[1] /= n, t[2] /= n;
        const Rgb v = evalSh(e, t[0], t[1], t[2]);
        const double m = std::min({v[0], v[1], v[2]});
        if (m < best) best = m, d[0] = t[0], d[1] = t[1], d[2] = t[2], improved = true;
      }
    if (!improved) step *= 0.5;
  }
  return best;
}

std::vector<double> laplacianWindow(int order, double lambda) {
  std::vector<double> w(static_cast<size_t>(order));
  for (int l = 0; l < order; ++l) {
    const double ll = double(l) * (l + 1);
    w[size_t(l)] = 1.0 / (1.0 + lambda * ll * ll);
  }
  return w;
}

}  // namespace

// Deringing after Sloan 2017: among windows that damp band l by the Laplacian
// penalty w_l = 1/(1 + λ (l(l+1))²) (the minimiser of ‖f − g‖² + λ‖Δg‖² for
// band-limited g), take the smallest λ whose reconstructed irradiance has no
// negative value on a dense sphere grid refined around its minimum. λ is found
// by doubling then bisection (the minimum rises monotonically towards the
// non-negative constant term as λ grows, when L_00 ≥ 0).
std::vector<double> deringingWindow(const ShCoeffs& radiance, double* lambdaOut, double* minBefore,
                                    double* minAfter) {
  const int order = radiance.order;
  const SphereGrid grid(order, std::max<size_t>(4000, size_t(150) * order * order));
  const std::vector<double> ones(size_t(order), 1.0);
  const double m0 = minIrradiance(radiance, ones, grid);
  if (minBefore) *minBefore = m0;
  // Aim a hair above zero so that float storage and points between grid nodes stay non-negative.
  const double e00 = std::max({radiance.rgb[0][0], radiance.rgb[0][1], radiance.rgb[0][2]}) * kPi * 0.28209479177387814;
  const double target = 1e-6 * std::max(e00, 0.0);
  double lambda = 0.0;
  std::vector<double> w = ones;
  if (m0 < target && order > 1) {
    double lo = 0.0, hi = 1e-8;
    while (minIrradiance(radiance, laplacianWindow(order, hi), grid) < target && hi < 1e12) hi *= 4.0;
    for (int it = 0; it < 50 && hi - lo > 1e-9 * hi; ++it) {
      const double mid = lo == 0.0 ? hi / 4.0 : std::sqrt(lo * hi);
      if (minIrradiance(radiance, laplacianWindow(order, mid), grid) < target)
        lo = mid;
      else
        hi = mid;
    }
    lambda = hi;
    w = laplacianWindow(order, lambda);
  }
  if (lambdaOut) *lambdaOut = lambda;
  if (minAfter) *minAfter = minIrradiance(radiance, w, grid);
  return w;
}

namespace {

nlohmann::json conventionsBlock(const ShCoeffs& c) {
  std::string scaling = "none: L_i = sum over texels of L(w) Y_i(w) dw (radiance coefficients)";
  if (c.quantity == ShQuantity::Irradiance) scaling = "E_i = A_l L_i with A_0 = pi, A_1 = 2pi/3, A_2 = pi/4 (clamped cosine)";
  if (c.quantity == ShQuantity::IrradianceOverPi) scaling = "E_i / pi = A_l L_i / pi (exit radiance of a white Lambertian surface)";
  return {
      {"basis", "real orthonormal spherical harmonics with the Condon-Shortley phase"},
      {"index", "i = l(l+1) + m"},
      {"order", c.order},
      {"coefficients", c.order * c.order},
      {"frame", "the input's world frame (cube faces +X,-X,+Y,-Y,+Z,-Z per OpenGL/Direct3D; lat-long per OpenEXR LatLongMap, +Y up)"},
      {"quantity", toString(c.quantity)},
      {"scaling", scaling},
      {"layout", "coefficients[i] = [r, g, b]"},
  };
}

}  // namespace

void writeShJson(const std::string& path, const ShCoeffs& c, const std::string& metaJson) {
  nlohmann::json j;
  if (!metaJson.empty()) j = nlohmann::json::parse(metaJson);
  j["tool"] = {{"name", "prtbake"}, {"version", version()}};
  j["conventions"] = conventionsBlock(c);
  j["order"] = c.order;
  j["quantity"] = toString(c.quantity);
  nlohmann::json arr = nlohmann::json::array();
  for (const auto& v : c.rgb) arr.push_back({v[0], v[1], v[2]});
  j["coefficients"] = arr;
  writeFileAtomic(path, j.dump(2) + "\n");
}

ShCoeffs readShJson(const std::string& path, std::string* metaJson) {
  const std::string text = readFile(path);
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {  // parse_error, or out_of_range for a number like 1e400
    throw InputError(path, std::string("not valid JSON: ") + e.what());
  }
  ShCoeffs c;
  try {
    // An integer beyond int64 parses as a double; get<int> of that is undefined (found by fuzzing).
    const auto& order = j.at("order");
    if (!order.is_number_integer() || order.get<long long>() < 1 || order.get<long long>() > kMaxShOrder)
      throw InputError(path, "'order' must be an integer in [1, " + std::to_string(kMaxShOrder) + "]");
    c.order = order.get<int>();
    c.quantity = parseQuantity(j.at("quantity").get<std::string>());
    const auto& arr = j.at("coefficients");
    if (c.order < 1 || c.order > kMaxShOrder || arr.size() != size_t(c.order) * size_t(c.order))
      throw InputError(path, "'coefficients' does not hold order² entries");
    for (const auto& v : arr) {
      if (v.size() != 3) throw InputError(path, "each coefficient must be [r, g, b]");
      Rgb rgb{v[0].get<double>(), v[1].get<double>(), v[2].get<double>()};
      for (double x : rgb)
        if (!std::isfinite(x)) throw InputError(path, "non-finite coefficient");
      c.rgb.push_back(rgb);
    }
  } catch (const nlohmann::json::exception& e) {
    throw InputError(path, std::string("not an SH coefficient file: ") + e.what());
  } catch (const UsageError& e) {
    throw InputError(path, e.what());
  }
  if (metaJson) {
    j.erase("coefficients");
    *metaJson = j.dump();
  }
  return c;
}

void writeGames202Light(const std::string& path, const ShCoeffs& c) {
  // The framework's viewer splits each line on single spaces: no trailing space.
  std::string text;
  char buf[128];
  for (const auto& v : c.rgb) {
    std::snprintf(buf, sizeof buf, "%.9g %.9g %.9g\n", v[0], v[1], v[2]);
    text += buf;
  }
  writeFileAtomic(path, text);
}

}  // namespace prtbake
