// Double-precision reference for the BRDF tables: deterministic quadrature over
// the half vector, independent of the kernel's sampler.
//
// With dω_l = 4 (V·H) dω_h and N = +z, V = (√(1 − μ²), 0, μ), H = (sinθ cosφ, sinθ sinφ, cosθ):
//   A + B = ∫ f_r cos θ_l dω_l = ∫∫ D(θ) [G2(μ, ν)/μ] F (V·H) sinθ dθ dφ,
//   C     = ∫∫ D_C(θ) ν (V·H)/(ν + μ − νμ) sinθ dθ dφ,        ν = 2(V·H) cosθ − μ.
// The integrand is zero where ν ≤ 0. ν > 0 ⇔ cos φ > c(θ) = −μ cos 2θ / (√(1 − μ²) sin 2θ),
// and c rises through −1 at θ1 = π/4 − θ_v/2 and +1 at θ2 = π/4 + θ_v/2 (θ_v = acos μ). So
//   θ ∈ [0, θ1]:  all φ ∈ [0, π];   θ ∈ [θ1, θ2]:  φ ∈ [0, acos c(θ)];   θ > θ2: nothing,
// (the integrand is even in φ: twice the integral over [0, π]). Each piece is smooth inside;
// the θ-piece [θ1, θ2] is mapped by the smoothstep x = x1 + (x2 − x1) s²(3 − 2s), which
// removes the square-root behaviour of acos c(θ) at both ends. θ itself is reached from x by
// tan θ = α tan(πx/2) for the microfacet lobes (spreads a lobe of any width α over x ∈ [0, 1]),
// θ = πx/2 for cloth. Composite 8-point Gauss–Legendre on every axis.
// G2/μ is written so that μ = 0 is finite (see kernels/lut.cl for the same forms).
#include <algorithm>
#include <array>
#include <cmath>

#include "core/constants.h"
#include "core/gauss_legendre.h"
#include "core/parallel.h"
#include "prtbake/error.h"
#include "prtbake/lut.h"

namespace prtbake {

namespace detail {
void finishLut(LutResult& r, const std::vector<float>& cloth, const std::vector<float>& stdErr);
std::vector<LutPoint> texelPoints(int n);
}  // namespace detail

namespace {

// Host threads of the double-precision reference.
constexpr int kReferenceThreads = 4;

const detail::GaussRule& gauss8() {
  static const detail::GaussRule g = detail::gaussLegendre(8);
  return g;
}

// Calls f(t, weight) for a composite Gauss–Legendre rule with `panels` panels on [0, 1].
template <class F>
void composite(int panels, F&& f) {
  const auto& g = gauss8();
  for (int p = 0; p < panels; ++p)
    for (int i = 0; i < 8; ++i) f((p + g.x[i]) / panels, g.w[i] / panels);
}

double ggxRoot(double x, double alpha2) { return std::sqrt(x * x * (1 - alpha2) + alpha2); }

double beckmannLambda(double x, double alpha) {
  if (x >= 1) return 0;
  const double c = x / (alpha * std::sqrt(1 - x * x));
  return 0.5 * (std::exp(-c * c) / (c * std::sqrt(kPi)) - std::erfc(c));
}

// μ(1 + Λ_B(μ)), finite at μ = 0.
double beckmannMuOnePlusLambda(double mu, double alpha) {
  const double as = alpha * std::sqrt(std::max(0.0, 1 - mu * mu));
  if (as <= 0) return mu;
  const double c = mu / as;
  return mu + 0.5 * (std::exp(-c * c) * as / std::sqrt(kPi) - mu * std::erfc(c));
}

struct Point3 {
  double a = 0, b = 0, c = 0;
};

class Integrand {
 public:
  Integrand(const LutOptions& o, double mu, double alpha) : o_(o), mu_(mu), alpha_(alpha) {
    sv_ = std::sqrt(std::max(0.0, 1 - mu * mu));
    a2_ = alpha * alpha;
    aV_ = ggxRoot(mu, a2_);
    k_ = 0.5 * alpha;
    if (o.ndf == LutNdf::Beckmann) qV_ = beckmannMuOnePlusLambda(mu, alpha);
  }
  double sv() const { return sv_; }

  // D(θ) · G2/μ · (V·H) · sinθ; `fc` gets F_c. Zero below the horizon.
  double specular(double theta, double phi, double& fc) const {
    const double st = std::sin(theta), ct = std::cos(theta);
    const double vdoth = sv_ * st * std::cos(phi) + mu_ * ct;
    const double nl = 2 * vdoth * ct - mu_;
    fc = std::pow(1 - vdoth, 5);
    if (nl <= 0 || vdoth <= 0) return 0;
    double d;
    if (o_.ndf == LutNdf::Ggx) {
      const double t = st * st + ct * ct * a2_;  // cos²θ(α² − 1) + 1 without cancellation
      d = a2_ / (kPi * t * t);
    } else {
      const double c2 = ct * ct;
      d = std::exp(-(st * st) / (c2 * a2_)) / (kPi * a2_ * c2 * c2);
    }
    double g;  // G2/μ
    if (o_.visibility == LutVisibility::SchlickGgx) {
      g = 1 / (mu_ * (1 - k_) + k_) * nl / (nl * (1 - k_) + k_);
    } else if (o_.ndf == LutNdf::Ggx) {
      const double aL = ggxRoot(nl, a2_);
      g = o_.visibility == LutVisibility::SmithCorrelated ? 2 * nl / (nl * aV_ + mu_ * aL)
                                                          : 2 / (mu_ + aV_) * 2 * nl / (nl + aL);
    } else {
      const double lL = beckmannLambda(nl, alpha_);
      g = o_.visibility == LutVisibility::SmithCorrelated ? 1 / (qV_ + mu_ * lL) : 1 / (qV_ * (1 + lL));
    }
    return d * g * vdoth * st;
  }

  // D_C(θ) · ν (V·H)/(ν + μ − νμ) · sinθ, α_c = max(α, kLutClothAlphaMin).
  double cloth(double theta, double phi) const {
    const double st = std::sin(theta), ct = std::cos(theta);
    const double vdoth = sv_ * st * std::cos(phi) + mu_ * ct;
    const double nl = 2 * vdoth * ct - mu_;
    if (nl <= 0 || vdoth <= 0) return 0;
    const double ac = std::max(alpha_, kLutClothAlphaMin);
    const double d = (2 + 1 / ac) * std::pow(st, 1 / ac) / (2 * kPi);
    return d * nl * vdoth / (nl + mu_ - nl * mu_) * st;
  }

 private:
  const LutOptions& o_;
  double mu_, alpha_, sv_, a2_, aV_, k_, qV_ = 0;
};

// ∫∫ over the visible region of f(θ, φ) sinθ... (f includes sinθ), for a θ ↔ x map.
template <class F, class ToTheta, class ToX>
void integrateHalfVector(double mu, double sv, int nodes, ToTheta&& thetaOf, ToX&& xOf, F&& f) {
  const double thetaV = std::acos(std::clamp(mu, 0.0, 1.0));
  const double th1 = std::max(0.0, kPi / 4 - thetaV / 2), th2 = kPi / 4 + thetaV / 2;
  const double x1 = xOf(th1), x2 = xOf(th2);
  const int xPanels = 8 * nodes, phiPanels = 4 * nodes;
  // θ ∈ [0, θ1], φ ∈ [0, π].
  if (x1 > 0) {
    composite(xPanels, [&](double s, double ws) {
      double dthdx;
      const double th = thetaOf(s * x1, dthdx);
      composite(phiPanels, [&](double t, double wt) { f(th, t * kPi, 2 * ws * x1 * dthdx * wt * kPi); });
    });
  }
  // θ ∈ [θ1, θ2] by the smoothstep map, φ ∈ [0, acos c(θ)].
  if (x2 > x1 && sv > 0) {
    composite(xPanels, [&](double s, double ws) {
      const double h = s * s * (3 - 2 * s), dh = 6 * s * (1 - s);
      double dthdx;
      const double th = thetaOf(x1 + (x2 - x1) * h, dthdx);
      const double c = std::clamp(-mu * std::cos(2 * th) / (sv * std::sin(2 * th)), -1.0, 1.0);
      const double phiMax = std::acos(c);
      if (phiMax <= 0) return;
      const double jac = 2 * ws * (x2 - x1) * dh * dthdx;
      composite(phiPanels, [&](double t, double wt) { f(th, t * phiMax, jac * wt * phiMax); });
    });
  }
}

Point3 referencePoint(const LutOptions& o, double mu, double roughness, int nodes) {
  mu = std::clamp(mu, 0.0, 1.0);
  const double alpha = lutAlpha(o, roughness);
  Integrand in(o, mu, alpha);
  Point3 r;
  if (alpha <= 0) {
    const double fc = std::pow(1 - mu, 5);
    r.a = 1 - fc, r.b = fc;
  } else {
    // tan θ = α tan(πx/2); dθ/dx = (π/2) α (1 + τ²)/(1 + α²τ²), τ = tan(πx/2).
    auto thetaOf = [alpha](double x, double& dthdx) {
      const double tau = std::tan(kPi / 2 * x);
      dthdx = kPi / 2 * alpha * (1 + tau * tau) / (1 + alpha * alpha * tau * tau);
      return std::atan(alpha * tau);
    };
    auto xOf = [alpha](double th) { return th >= kPi / 2 ? 1.0 : 2 / kPi * std::atan(std::tan(th) / alpha); };
    integrateHalfVector(mu, in.sv(), nodes, thetaOf, xOf, [&](double th, double ph, double w) {
      double fc;
      const double v = in.specular(th, ph, fc) * w;
      r.a += v * (1 - fc);
      r.b += v * fc;
    });
  }
  if (o.cloth) {
    auto thetaOf = [](double x, double& dthdx) {
      dthdx = kPi / 2;
      return kPi / 2 * x;
    };
    auto xOf = [](double th) { return th / (kPi / 2); };
    // The cloth lobe is narrow near the horizon at small α: twice the nodes.
    integrateHalfVector(mu, in.sv(), 2 * nodes, thetaOf, xOf,
                        [&](double th, double ph, double w) { r.c += in.cloth(th, ph) * w; });
  }
  return r;
}

}  // namespace

LutValues evaluateLutReference(const LutOptions& options, const std::vector<LutPoint>& points, int nodes) {
  LutOptions o = options;
  o.size = 1;
  validateLutOptions(o);
  if (nodes < 1) throw UsageError("nodes", "must be at least 1");
  const size_t n = points.size();
  LutValues v;
  v.a.resize(n), v.b.resize(n), v.stdErr.assign(n, 0.0);
  if (o.cloth) v.cloth.resize(n);
  detail::parallelEach(n, kReferenceThreads, [&](size_t i) {
    const Point3 p = referencePoint(o, points[i].mu, points[i].roughness, nodes);
    v.a[i] = p.a, v.b[i] = p.b;
    if (o.cloth) v.cloth[i] = p.c;
  });
  return v;
}

LutResult computeLutReference(const LutOptions& options) {
  validateLutOptions(options);
  LutResult r;
  r.options = options;
  r.size = options.size;
  r.reference = true;
  r.device = "host reference (double, Gauss-Legendre quadrature)";
  const LutValues v = evaluateLutReference(options, detail::texelPoints(options.size));
  const size_t texels = v.a.size();
  r.a.resize(texels), r.b.resize(texels);
  std::vector<float> cloth(v.cloth.size());
  for (size_t t = 0; t < texels; ++t) r.a[t] = float(v.a[t]), r.b[t] = float(v.b[t]);
  for (size_t t = 0; t < cloth.size(); ++t) cloth[t] = float(v.cloth[t]);
  detail::finishLut(r, cloth, std::vector<float>(texels, 0.0f));
  return r;
}

}  // namespace prtbake
