// Lobes for glossy shading (Funk–Hecke factors), the arbitrary-BRDF matrix, and the host
// reference of the shading (glossy.h).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "core/constants.h"
#include "core/gauss_legendre.h"
#include "prtbake/error.h"
#include "prtbake/glossy.h"
#include "prtbake/sh.h"
#include "prtbake/sh_rotate.h"

namespace prtbake {
namespace {

// P_0..P_{n−1} at t.
void legendre(int n, double t, double* p) {
  p[0] = 1;
  if (n > 1) p[1] = t;
  for (int l = 2; l < n; ++l) p[l] = ((2 * l - 1) * t * p[l - 1] - (l - 1) * p[l - 2]) / l;
}

}  // namespace

double hemisphereFactor(int l) {
  const detail::GaussRule g = detail::gaussLegendre(l / 2 + 2);
  double s = 0;
  std::vector<double> p(size_t(l) + 1);
  for (size_t k = 0; k < g.x.size(); ++k) {
    legendre(l + 1, g.x[k], p.data());
    s += g.w[k] * p[size_t(l)];
  }
  return 2 * kPi * s;
}

namespace {

std::vector<double> phongFactors(double s, int n) {
  std::vector<double> g(size_t(std::max(n, 2)));
  g[0] = 1;
  g[1] = (s + 1) / (s + 2);
  for (int l = 2; l < n; ++l) g[size_t(l)] = g[size_t(l) - 2] * (s - l + 2) / (s + l + 1);
  g.resize(size_t(n));
  return g;
}

// GGX D at cos θ_h (α = roughness²).
double ggxD(double alpha, double cosH) {
  const double a2 = alpha * alpha, d = (a2 - 1) * cosH * cosH + 1;
  return a2 / (kPi * d * d);
}

// Frame taking +z to the unit vector n.
Rotation frameOf(const double n[3]) {
  const double sign = std::copysign(1.0, n[2]);
  const double a = -1.0 / (sign + n[2]), b = n[0] * n[1] * a;
  const double t[3] = {1 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]};
  const double bb[3] = {b, sign + n[1] * n[1] * a, -n[1]};
  Rotation r;
  for (int c = 0; c < 3; ++c) r.m[3 * c] = t[c], r.m[3 * c + 1] = bb[c], r.m[3 * c + 2] = n[c];
  return r;
}

}  // namespace

GlossyLobe phongLobe(double s, int order) {
  if (!(s >= 0) || !std::isfinite(s)) throw UsageError("--lobe", "the Phong exponent must be a finite number >= 0");
  if (order < 1 || order > kMaxShOrder) throw UsageError("--order", "lobe order out of range");
  GlossyLobe lobe;
  char name[64];
  std::snprintf(name, sizeof name, "phong s=%g", s);
  lobe.name = name;
  // ĝ_l = (s+1) I_l, I_l = ∫_0^1 t^s P_l(t) dt. Bonnet's recurrence
  // (l+1) P_{l+1} = (2l+1) t P_l − l P_{l−1} with integration by parts gives
  // I_l = I_{l−2} (s − l + 2)/(s + l + 1), I_0 = 1/(s+1), I_1 = 1/(s+2).
  lobe.g = phongFactors(s, order);
  lobe.phongExponent = s;
  return lobe;
}

GlossyLobe ggxLobe(double roughness, int order) {
  if (!(roughness >= 0.02 && roughness <= 1)) throw UsageError("--lobe", "GGX roughness must lie in [0.02, 1]");
  const double alpha = roughness * roughness;
  // G(t) ∝ D(cos(θ/2)) t over t = cos θ ∈ [0, 1]; with u = 1 − t the peak sits at u = 0
  // with width ~2α²: geometric panels [0, u_0], [u_0, 2u_0], … each with a 24-point rule.
  constexpr int kBands = 64;
  std::vector<double> moments(kBands, 0.0), p(kBands);
  const detail::GaussRule g = detail::gaussLegendre(24);
  double lo = 0, hi = std::min(1.0, 1e-3 * alpha * alpha);
  double norm = 0;
  while (lo < 1) {
    for (size_t k = 0; k < g.x.size(); ++k) {
      const double u = lo + (hi - lo) * g.x[k], w = (hi - lo) * g.w[k], t = 1 - u;
      const double d = ggxD(alpha, std::sqrt(std::max(0.0, (1 + t) / 2))) * t;
      legendre(kBands, t, p.data());
      norm += w * d;
      for (int l = 0; l < kBands; ++l) moments[size_t(l)] += w * d * p[size_t(l)];
    }
    lo = hi;
    hi = std::min(1.0, hi * 2);
  }
  GlossyLobe lobe;
  char name[64];
  std::snprintf(name, sizeof name, "ggx r=%g", roughness);
  lobe.name = name;
  lobe.g.resize(size_t(order));
  for (int l = 0; l < order; ++l) lobe.g[size_t(l)] = moments[size_t(l)] / norm;
  // The band-limit error: the lobe's L2 energy beyond the kept bands (Parseval, with
  // Σ_m Y_lm(R)² = (2l+1)/4π), relative to its energy in the first 64 bands.
  double all = 0, kept = 0;
  for (int l = 0; l < kBands; ++l) {
    const double e = (2 * l + 1) * std::pow(moments[size_t(l)] / norm, 2);
    all += e;
    if (l < order) kept += e;
  }
  lobe.fitError = std::sqrt(std::max(0.0, all - kept) / all);
  // The normalised Phong exponent whose factors fit best (least squares over l < order),
  // by golden-section search on log s.
  auto cost = [&](double ls) {
    const std::vector<double> f = phongFactors(std::exp(ls), order);
    double c = 0;
    for (int l = 0; l < order; ++l) c += std::pow(f[size_t(l)] - lobe.g[size_t(l)], 2);
    return c;
  };
  double a = std::log(1e-3), b = std::log(1e7);
  const double phi = (std::sqrt(5.0) - 1) / 2;
  for (int it = 0; it < 200; ++it) {
    const double c = b - phi * (b - a), d = a + phi * (b - a);
    if (cost(c) < cost(d)) b = d;
    else a = c;
  }
  lobe.phongExponent = std::exp(0.5 * (a + b));
  return lobe;
}

namespace {
std::vector<std::string> splitColon(const std::string& t) {
  std::vector<std::string> parts;
  size_t a = 0;
  for (;;) {
    const size_t b = t.find(':', a);
    parts.push_back(t.substr(a, b == std::string::npos ? std::string::npos : b - a));
    if (b == std::string::npos) return parts;
    a = b + 1;
  }
}
double number(const std::string& s, const std::string& option, const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (s.empty() || *end != '\0' || !std::isfinite(v)) throw UsageError(option, "expected a number in '" + text + "'");
  return v;
}
}  // namespace

GlossyLobe parseGlossyLobe(const std::string& text, int order, const std::string& option) {
  const auto p = splitColon(text);
  if (p.size() == 1 && p[0] == "cosine") {
    GlossyLobe l = phongLobe(1.0, order);
    l.name = "cosine (clamped cosine / pi)";
    return l;
  }
  if (p.size() == 2 && p[0] == "phong") {
    const double s = number(p[1], option, text);
    if (!(s >= 0 && s <= 1e6)) throw UsageError(option, "the Phong exponent must lie in [0, 1e6]");
    return phongLobe(s, order);
  }
  if (p.size() == 2 && p[0] == "ggx") return ggxLobe(number(p[1], option, text), order);
  throw UsageError(option, "expected cosine, phong:S or ggx:R, got '" + text + "'");
}

BrdfSpec parseBrdfSpec(const std::string& text, const std::string& option) {
  const auto p = splitColon(text);
  BrdfSpec b;
  if (p[0] == "lambertian" && p.size() <= 2) {
    b.lambertian = true;
    if (p.size() == 2) b.albedo = number(p[1], option, text);
    if (!(b.albedo >= 0 && b.albedo <= 1)) throw UsageError(option, "the albedo must lie in [0, 1]");
    return b;
  }
  if (p[0] == "ggx" && (p.size() == 2 || p.size() == 3)) {
    b.roughness = number(p[1], option, text);
    if (p.size() == 3) b.f0 = number(p[2], option, text);
    if (!(b.roughness >= 0.05 && b.roughness <= 1)) throw UsageError(option, "roughness must lie in [0.05, 1]");
    if (!(b.f0 >= 0 && b.f0 <= 1)) throw UsageError(option, "f0 must lie in [0, 1]");
    return b;
  }
  throw UsageError(option, "expected ggx:R[:F0] or lambertian[:A], got '" + text + "'");
}

std::vector<double> brdfMatrixLocal(const BrdfSpec& brdf, int order, int q) {
  if (!brdf.lambertian && !(brdf.roughness >= 0.05 && brdf.roughness <= 1))
    throw UsageError("--brdf", "roughness must lie in [0.05, 1]");
  if (!(brdf.f0 >= 0 && brdf.f0 <= 1)) throw UsageError("--brdf", "f0 must lie in [0, 1]");
  const int nc = order * order, nphi = 2 * q;
  const detail::GaussRule g = detail::gaussLegendre(q);
  struct Dir {
    double x, y, z, w;
  };
  std::vector<Dir> dirs;
  for (int k = 0; k < q; ++k)
    for (int m = 0; m < nphi; ++m) {
      const double z = g.x[size_t(k)], r = std::sqrt(std::max(0.0, 1 - z * z)), phi = 2 * kPi * (m + 0.5) / nphi;
      dirs.push_back({r * std::cos(phi), r * std::sin(phi), z, g.w[size_t(k)] * 2 * kPi / nphi});
    }
  std::vector<double> y(dirs.size() * nc);
  for (size_t i = 0; i < dirs.size(); ++i) shEval(order, dirs[i].x, dirs[i].y, dirs[i].z, &y[i * nc]);
  const double alpha = brdf.roughness * brdf.roughness, a2 = alpha * alpha;
  auto lambda = [&](double c) {
    const double t2 = std::max(0.0, 1 - c * c) / (c * c);
    return 0.5 * (-1 + std::sqrt(1 + a2 * t2));
  };
  std::vector<double> b(size_t(nc) * nc, 0.0), v(static_cast<size_t>(nc));
  for (size_t o = 0; o < dirs.size(); ++o) {
    const Dir& wo = dirs[o];
    std::fill(v.begin(), v.end(), 0.0);
    for (size_t i = 0; i < dirs.size(); ++i) {
      const Dir& wi = dirs[i];
      double fc;  // f(ω_i, ω_o) cos θ_i
      if (brdf.lambertian) {
        fc = brdf.albedo / kPi * wi.z;
      } else {
        double h[3] = {wi.x + wo.x, wi.y + wo.y, wi.z + wo.z};
        const double hl = std::sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
        const double ch = h[2] / hl, vh = (wi.x * h[0] + wi.y * h[1] + wi.z * h[2]) / hl;
        const double f = brdf.f0 + (1 - brdf.f0) * std::pow(1 - std::max(0.0, vh), 5);
        const double g2 = 1 / (1 + lambda(wo.z) + lambda(wi.z));
        fc = ggxD(alpha, ch) * g2 * f / (4 * wo.z);
      }
      const double a = wi.w * fc;
      for (int k = 0; k < nc; ++k) v[size_t(k)] += a * y[i * nc + k];
    }
    for (int k = 0; k < nc; ++k)
      for (int k2 = 0; k2 < nc; ++k2) b[size_t(k) * nc + k2] += wo.w * y[o * nc + k] * v[size_t(k2)];
  }
  return b;
}

void exitRadianceBlock(const Mesh& mesh, size_t first, size_t count, int channels, int orderOut, int orderIn,
                       const std::vector<double>& brdf, float* values) {
  const int no2 = orderOut * orderOut, ni2 = orderIn * orderIn;
  PRTBAKE_CHECK(brdf.size() == size_t(no2) * no2, "BRDF matrix of the wrong order");
  std::vector<double> s(size_t(no2) * no2), tmp(size_t(no2) * no2), bw(size_t(no2) * no2), e(size_t(no2) * ni2);
  for (size_t i = 0; i < count; ++i) {
    const size_t v = first + i;
    double n[3] = {mesh.normals[3 * v], mesh.normals[3 * v + 1], mesh.normals[3 * v + 2]};
    const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    float* mv = values + i * size_t(channels) * no2 * ni2;
    if (!(len > 0)) {
      std::fill(mv, mv + size_t(channels) * no2 * ni2, 0.0f);
      continue;
    }
    for (double& c : n) c /= len;
    const ShRotationBlocks blocks = shRotationExact(frameOf(n), orderOut);
    std::fill(s.begin(), s.end(), 0.0);
    for (int l = 0; l < orderOut; ++l)
      for (int a = 0; a < 2 * l + 1; ++a)
        for (int b = 0; b < 2 * l + 1; ++b) s[size_t(l * l + a) * no2 + size_t(l * l + b)] = blocks[size_t(l)][size_t(a) * (2 * l + 1) + b];
    // B_world = S B Sᵀ (the local frame's functions rotated to the vertex: Y_j(Rω) = Σ_k S_jk Y_k(ω)).
    std::fill(tmp.begin(), tmp.end(), 0.0);
    std::fill(bw.begin(), bw.end(), 0.0);
    for (int a = 0; a < no2; ++a)
      for (int k = 0; k < no2; ++k)
        for (int b = 0; b < no2; ++b) tmp[size_t(a) * no2 + b] += s[size_t(a) * no2 + k] * brdf[size_t(k) * no2 + b];
    for (int a = 0; a < no2; ++a)
      for (int k = 0; k < no2; ++k)
        for (int b = 0; b < no2; ++b) bw[size_t(a) * no2 + b] += tmp[size_t(a) * no2 + k] * s[size_t(b) * no2 + k];
    for (int c = 0; c < channels; ++c) {
      float* m = mv + size_t(c) * no2 * ni2;
      std::fill(e.begin(), e.end(), 0.0);
      for (int a = 0; a < no2; ++a)
        for (int k = 0; k < no2; ++k)
          for (int b = 0; b < ni2; ++b) e[size_t(a) * ni2 + b] += bw[size_t(a) * no2 + k] * m[size_t(k) * ni2 + b];
      for (size_t k = 0; k < e.size(); ++k) m[k] = float(e[k]);
    }
  }
}

double glossyHorizonNorm(const GlossyLobe& lobe, int orderOut, double c) {
  const int n = std::min(orderOut, int(lobe.g.size()));
  std::vector<double> p(size_t(std::max(n, 1)));
  legendre(n, c, p.data());
  double s = 0;
  for (int l = 0; l < n; ++l) s += lobe.g[size_t(l)] * hemisphereFactor(l) * (2 * l + 1) / (4 * kPi) * p[size_t(l)];
  return s;
}

double shadeGlossy(const GlossyLobe& lobe, int orderOut, const double* t, const std::array<double, 3>& R,
                   bool normalised, double cosNR) {
  const int n = std::min(orderOut, int(lobe.g.size()));
  std::vector<double> y(size_t(n) * n);
  shEval(n, R[0], R[1], R[2], y.data());
  double s = 0;
  for (int l = 0; l < n; ++l)
    for (int m = -l; m <= l; ++m) s += lobe.g[size_t(l)] * t[shIndex(l, m)] * y[size_t(shIndex(l, m))];
  if (!normalised) return s;
  return s / glossyHorizonNorm(lobe, orderOut, std::max(0.0, cosNR));
}

}  // namespace prtbake
