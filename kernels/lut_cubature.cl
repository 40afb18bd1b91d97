// lut_cubature.cl: the BRDF tables' integrals over squares of the half-vector domain,
// for the adaptive cubature of "--tolerance" (host/src/lut_adaptive.cpp). One
// work-item per square: the 3×3 Gauss–Legendre rule (exact for degree 5 in each
// coordinate) over the square, in float.
//
// The domain and the integrands are those of the double reference
// (host/src/lut_reference.cpp), where their derivation is written out. With N = +z and
// V = (√(1 − μ²), 0, μ), over the half vector H(θ, φ):
//   A + B = ∫∫ D(θ) [G2/μ] F (V·H) sinθ dθ dφ,   C = ∫∫ D_C(θ) ν (V·H)/(ν + μ − νμ) sinθ dθ dφ,
// zero where ν = 2(V·H) cosθ − μ ≤ 0. Two smooth pieces, each the image of the unit
// square (s, t) (the integrand is even in φ, hence the factor 2):
//   cap   θ ∈ [0, θ1], φ = π t;             x = s x1
//   band  θ ∈ [θ1, θ2], φ = t acos c(θ);    x = x1 + (x2 − x1) s²(3 − 2s)
// with θ1,2 = π/4 ∓ θ_v/2, c(θ) = −μ cos 2θ/(√(1 − μ²) sin 2θ), and θ(x) given by
// tan θ = α tan(πx/2) (specular) or θ = πx/2 (cloth).
//
// Build options: -DLUT_NDF=0|1 (GGX | Beckmann), -DLUT_VIS=0|1|2 (height-correlated
// Smith | separable Smith | Schlick-GGX with k = α/2), -DLUT_PIECE=0..3 (LUT_PIECE_* bits:
// every square of one launch is of one kind of piece, so the work-items of a work-group
// take the same branches and PoCL can run them as vector lanes).
#ifndef LUT_NDF
#define LUT_NDF 0
#endif
#ifndef LUT_VIS
#define LUT_VIS 0
#endif
#ifndef LUT_PIECE
#define LUT_PIECE 0
#endif

#include "lut_cell.h"
#include "microfacet.clh"

#define LC_PI 3.14159265358979324f
#define LC_HALF_PI 1.57079632679489662f

// Λ_Beckmann(x), x in (0, 1]; 0 at x = 1.
inline float lc_beckmann_lambda(float x, float alpha) {
  if (x >= 1.0f) return 0.0f;
  const float c = x / (alpha * sqrt(1.0f - x * x));
  return 0.5f * (exp(-c * c) * MF_INV_SQRT_PI / c - erfc(c));
}

// D · G2/μ · (V·H) · sinθ at (θ, φ); *fc = (1 − V·H)^5. Zero below the horizon.
inline float lc_specular(float mu, float sv, float alpha, float st, float ct, float cphi, float* fc) {
  const float vdoth = sv * st * cphi + mu * ct;
  const float nl = 2.0f * vdoth * ct - mu;
  const float m = 1.0f - vdoth, m2 = m * m;
  *fc = m2 * m2 * m;
  if (nl <= 0.0f || vdoth <= 0.0f) return 0.0f;
  const float a2 = alpha * alpha;
#if LUT_NDF == 0
  const float tt = st * st + ct * ct * a2;  // cos²θ(α² − 1) + 1 without cancellation
  const float d = a2 / (LC_PI * tt * tt);
#else
  const float c2 = ct * ct;
  const float d = exp(-(st * st) / (c2 * a2)) / (LC_PI * a2 * c2 * c2);
#endif
  float g;  // G2/μ
#if LUT_VIS == 2
  const float k = 0.5f * alpha;
  g = 1.0f / (mu * (1.0f - k) + k) * nl / (nl * (1.0f - k) + k);
#elif LUT_NDF == 0
  const float aV = mf_ggx_root(mu, a2), aL = mf_ggx_root(nl, a2);
#if LUT_VIS == 0
  g = 2.0f * nl / (nl * aV + mu * aL);
#else
  g = 2.0f / (mu + aV) * 2.0f * nl / (nl + aL);
#endif
#else
  const float qV = mf_beckmann_mu_one_plus_lambda(mu, alpha), lL = lc_beckmann_lambda(nl, alpha);
#if LUT_VIS == 0
  g = 1.0f / (qV + mu * lL);
#else
  g = 1.0f / (qV * (1.0f + lL));
#endif
#endif
  return d * g * vdoth * st;
}

// D_C · ν (V·H)/(ν + μ − νμ) · sinθ (α already clamped).
inline float lc_cloth(float mu, float sv, float alpha, float st, float ct, float cphi) {
  const float vdoth = sv * st * cphi + mu * ct;
  const float nl = 2.0f * vdoth * ct - mu;
  if (nl <= 0.0f || vdoth <= 0.0f) return 0.0f;
  const float d = (2.0f + 1.0f / alpha) * pow(st, 1.0f / alpha) / (2.0f * LC_PI);
  return d * nl * vdoth / (nl + mu - nl * mu) * st;
}

// sin θ, cos θ and dθ/dx of the piece's θ map at x, without θ itself: for the specular
// map tan θ = α tan(πx/2) = T gives sin θ = T/√(1 + T²), cos θ = 1/√(1 + T²).
inline void lc_theta_of(float x, float alpha, int cloth, float* st, float* ct, float* dthdx) {
  if (cloth) {
    *dthdx = LC_HALF_PI;
    *st = sincos(LC_HALF_PI * x, ct);
    return;
  }
  const float tau = tan(LC_HALF_PI * x), t = alpha * tau, inv = rsqrt(1.0f + t * t);
  *st = t * inv;
  *ct = inv;
  *dthdx = LC_HALF_PI * alpha * (1.0f + tau * tau) * (inv * inv);
}

// count: squares; cells: count LutCell, all of piece LUT_PIECE; out: count × LUT_CELL_OUT_FLOAT4S float4, each
// (A, B, C, 0): first the square's 3×3 value Q, then for each quadrant k (s half k & 1,
// t half k >> 1, as the host splits) the integral over the quadrant of the degree-2
// (per coordinate) interpolant of the same 9 node values; these four sum to Q.
__kernel void lut_cells(int count, __global const LutCell* cells, __global float4* out) {
  const int gid = get_global_id(0);
  if (gid >= count) return;
  const LutCell c = cells[gid];
  const float mu = clamp(c.mu, 0.0f, 1.0f), alpha = c.alpha;
  const int cloth = (LUT_PIECE & LUT_PIECE_CLOTH) != 0, band = (LUT_PIECE & LUT_PIECE_BAND) != 0;
  const float sv = sqrt(fmax(1.0f - mu * mu, 0.0f));
  const float x1 = c.x1, x2 = c.x2;
  // 3-point Gauss–Legendre on [0, 1], and the integrals of its Lagrange basis over
  // [0, 1/2] and [1/2, 1].
  const float gx[3] = {0.11270166537925831f, 0.5f, 0.88729833462074169f};
  const float gw[3] = {0.27777777777777778f, 0.44444444444444444f, 0.27777777777777778f};
  const float lh[3][2] = {{0.30026319498086450f, -0.02248541720308683f},
                          {0.22222222222222222f, 0.22222222222222222f},
                          {-0.02248541720308683f, 0.30026319498086450f}};
  float4 sum = (float4)(0.0f), quad[4] = {sum, sum, sum, sum};
  for (int i = 0; i < 3; ++i) {
    const float s = c.s0 + c.h * gx[i];
    float x, dxds;
    if (band) {
      x = x1 + (x2 - x1) * s * s * (3.0f - 2.0f * s);
      dxds = (x2 - x1) * 6.0f * s * (1.0f - s);
    } else {
      x = s * x1;
      dxds = x1;
    }
    float st, ct, dthdx;
    lc_theta_of(x, alpha, cloth, &st, &ct, &dthdx);
    float phiMax = LC_PI;
    if (band) {  // cos φ_max = −μ cos 2θ/(√(1 − μ²) sin 2θ)
      const float cc = clamp(-mu * (ct - st) * (ct + st) / (sv * 2.0f * st * ct), -1.0f, 1.0f);
      phiMax = acos(cc);
    }
    const float jac = 2.0f * c.h * c.h * dxds * dthdx * phiMax;
    if (!(jac > 0.0f)) continue;
    for (int j = 0; j < 3; ++j) {
      const float cphi = cos((c.t0 + c.h * gx[j]) * phiMax);
      float4 v = (float4)(0.0f);
      if (cloth) {
        v.z = jac * lc_cloth(mu, sv, alpha, st, ct, cphi);
      } else {
        float fc;
        const float f = jac * lc_specular(mu, sv, alpha, st, ct, cphi, &fc);
        v.x = f * (1.0f - fc);
        v.y = f * fc;
      }
      sum += gw[i] * gw[j] * v;
      for (int k = 0; k < 4; ++k) quad[k] += lh[i][k & 1] * lh[j][k >> 1] * v;
    }
  }
  __global float4* o = out + (size_t)gid * LUT_CELL_OUT_FLOAT4S;
  o[0] = sum;
  for (int k = 0; k < 4; ++k) o[1 + k] = quad[k];
}
