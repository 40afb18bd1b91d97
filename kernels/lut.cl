// lut.cl: split-sum BRDF lookup tables (docs/conventions.md "BRDF LUT"), one work-item per point.
//
// Build options (each variant is its own cached program):
//   -DLUT_NDF=0|1      GGX | Beckmann
//   -DLUT_VIS=0|1|2    height-correlated Smith | separable Smith | Schlick-GGX (k = α/2)
//   -DLUT_CLOTH=0|1    also the Charlie/Ashikhmin cloth table
//   -DLUT_PADDED=0|1   the sample table has padding lanes to mask, or none
//   -DLUT_DIRS=0|1|2   disk points from the host table | precise sin/cos | native_sin/cos
//   -DLUT_NATIVE=0|1   precise | native sqrt, rsqrt, divide, exp
#ifndef LUT_NDF
#define LUT_NDF 0
#endif
#ifndef LUT_VIS
#define LUT_VIS 0
#endif
#ifndef LUT_CLOTH
#define LUT_CLOTH 0
#endif
#ifndef LUT_PADDED
#define LUT_PADDED 1  // 0 when the sample count is a multiple of LUT_SIMD: no padding lanes
#endif
#ifndef LUT_DIRS
#define LUT_DIRS 0
#endif
#ifndef LUT_NATIVE
#define LUT_NATIVE 0
#endif

#if LUT_NATIVE
#define MF_SQRT native_sqrt
#define MF_RSQRT native_rsqrt
#define MF_DIV(a, b) native_divide((a), (b))
#define MF_EXP native_exp
#define MF_COS native_cos
#else
#define MF_COS cos
#endif

#include "lut_sampling.clh"
#include "microfacet.clh"

#define LUT_TWO_PI 6.28318530717958648f
#define LUT_INV_PI 0.31830988618379067f

static inline float lut_hsum16(float16 v) {
  float8 a = v.lo + v.hi;
  float4 b = a.lo + a.hi;
  float2 c = b.lo + b.hi;
  return c.x + c.y;
}

// ---------------------------------------------------------------------------
// Specular (A, B). View V = (√(1 − μ²), 0, μ), normal N = +z.
//
//   A + B = ∫ f_r(V, L) cos θ_l dω_l,   f_r = D(H) G2(V, L) F / (4 μ ν),   ν = N·L.
//
// Half vectors are drawn from the GGX distribution of visible normals (Heitz 2018,
// "Sampling the GGX Distribution of Visible Normals"):
//   p(H) = G1(V) max(0, V·H) D(H) / μ,   L = 2(V·H)H − V,   p(L) = p(H) / (4 V·H),
// so f_r cos θ_l / p(L) = [D G2 F / (4μ)] · [4μ / (G1(V) D)] = F · G2(V, L)/G1(V).
// Unlike NDF sampling (weight G2 (V·H)/((N·H) μ), unbounded as μ → 0) this weight
// lies in [0, 1] for GGX, so grazing columns converge like the others.
//
// Beckmann: the same GGX sampler (same α) is the proposal, and the estimate is
// self-normalised. With d = D_B/D_GGX = e^{−x}(1 + x)², x = tan²θ_h/α² (bounded by 4/e),
// the Beckmann visible-normal density is p_B(H) = p(H) · d · G1_B(V)/G1_GGX(V), and it
// integrates to 1, so E_p[d] = G1_GGX(V)/G1_B(V) and
//   A = Σ_k d_k (1 − F_c,k) y_k / Σ_k d_k,   B = Σ_k d_k F_c,k y_k / Σ_k d_k,
//   y = G2_B(V, L)/G1_B(V)  (0 where ν ≤ 0),
// a weighted mean of y ∈ [0, 1] for the Smith forms: A + B ≤ 1 holds for every sample
// count, where the plain ratio d·G2_B/G1_GGX(V) (up to 4/e · √π) could overshoot.
// The GGX tails are heavier than Beckmann's, so d stays bounded (a defensive proposal).
//
// The visibility ratios, written so that μ = 0 is finite (a_x = a(x), see microfacet.clh):
//   GGX correlated     G2/G1(V) = ν(μ + a_V) / (ν a_V + μ a_L)
//   GGX separable      G2/G1(V) = G1_GGX(ν) = 2ν / (ν + a_L)
//   GGX Schlick        G2_S/G1(V) = (μ + a_V) / (2 (μ(1 − k) + k)) · G1_S(ν)
//   Beckmann corr.     y = μ(1 + Λ_V) / (μ(1 + Λ_V) + μ Λ_L)
//   Beckmann separ.    y = 1 / (1 + Λ_L)
//   Beckmann Schlick   y = μ(1 + Λ_V) / (μ(1 − k) + k) · G1_S(ν)
//
// GGX estimator over n Hammersley points, w_k = 0 where ν ≤ 0 (L below the horizon):
//   A = (1/n) Σ_k (1 − F_c,k) w_k,   B = (1/n) Σ_k F_c,k w_k,   F_c = (1 − V·H)^5.
// α = 0 is a mirror: H = N, w = 1, A = 1 − (1 − μ)^5, B = (1 − μ)^5 exactly.
//
// Cloth C = ∫ D_C(H) V_A(V, L) ν dω_l with D_C = (2 + 1/α) sin^{1/α}θ_h / (2π)
// (Estevez–Kulla 2017) and V_A = 1/(4(ν + μ − νμ)) (Neubelt 2013). Over the half vector,
//   C = ∫∫ D_C(θ) g sinθ dθ dφ,   g = ν (V·H)/(ν + μ − νμ).
// D_C peaks at the horizon, where sampling p(H) = D_C cosθ_h alone starves (its weight
// g/cosθ_h is unbounded at grazing view). So θ comes from a three-way mixture, in dθ:
//   p(θ) = β0·2/π                                  θ uniform on [0, π/2]
//        + β1·λ e^{−λ cosθ} sinθ / (1 − e^{−λ})     cosθ exponential, λ = 1/√α: follows the
//                                                   horizon peak sin^{1/α}θ ≈ e^{−cos²θ/(2α)}
//        + β2·K sin^{1/α+1}θ cosθ,  K = 2 + 1/α     D_C cosθ (sinθ = u'^{1/K})
// u1 picks the branch and is rescaled to u' within it. φ is uniform on the arc where
// ν > 0, φ = u2 φ_max(θ) with cos φ_max = clamp(−μ cos 2θ/(√(1 − μ²) sin 2θ), −1, 1) (the
// integrand is even in φ; see host/src/lut_reference.cpp), p(φ | θ) = 1/φ_max on [0, φ_max],
// doubled for the mirror arc. Each sample is weighted by the whole mixture density
// (one-sample balance heuristic): with f(θ, φ) = K sin^{1/α+1}θ g/(2π),
//   C = (1/n) Σ_k K sin^{1/α+1}θ_k g_k φ_max(θ_k) / (π p(θ_k))   (0 where ν ≤ 0).
// ---------------------------------------------------------------------------

// count:  number of points
// points: count × (μ, α); μ in [0, 1] (clamped), α ≥ 0 the NDF width
// nPad:   this chunk's samples rounded up to a multiple of LUT_SIMD (the table row length)
// nReal:  this chunk's samples (the mirror's weight: every sample has the same value)
// table:  LUT_TAB_ROWS × nPad floats (lut_sampling.clh)
// split, nPad2, nReal2, table2: points split … count − 1 take this second sample set
//         instead (one launch for two counts: the "--tolerance" pilot's first step)
// out:    count × LUT_OUT_FLOAT4S float4 of sums (lut_sampling.clh)
__kernel void lut_eval(int count, __global const float2* points, int nPad, float nReal,
                       __global const float* table, int split, int nPad2, float nReal2,
                       __global const float* table2, __global float4* out) {
  const int gid = get_global_id(0);
  if (gid >= count) return;
  if (gid >= split) {
    nPad = nPad2;
    nReal = nReal2;
    table = table2;
  }
  const float mu = clamp(points[gid].x, 0.0f, 1.0f);
  const float alpha = fmax(points[gid].y, 0.0f);
  const float sv = sqrt(fmax(1.0f - mu * mu, 0.0f));
  float4 sums0 = (float4)(0.0f), sums1 = (float4)(0.0f), sums2 = (float4)(0.0f);

  if (alpha <= 0.0f) {
    // The mirror: every sample weighs the same; GGX-form sums (Beckmann's ratio reads
    // them through d = 1).
    const float m = 1.0f - mu, m2 = m * m, fc = m2 * m2 * m;
#if LUT_NDF == 0
    sums0 = (float4)((1.0f - fc) * nReal, fc * nReal, (1.0f - fc) * (1.0f - fc) * nReal, fc * fc * nReal);
#else
    sums0 = (float4)(nReal, (1.0f - fc) * nReal, fc * nReal, nReal);
    sums1 = (float4)((1.0f - fc) * nReal, fc * nReal, (1.0f - fc) * (1.0f - fc) * nReal, fc * fc * nReal);
#endif
  } else {
    // Per point: the stretched view direction of the VNDF sampler and its warp.
    const float vsx = alpha * sv, vsz = mu, vlen = rsqrt(vsx * vsx + vsz * vsz);
    const float vhx = vsx * vlen, vhz = vsz * vlen;
    const float s = 0.5f * (1.0f + vhz), oms = 1.0f - s;
    const float alpha2 = alpha * alpha;
    const float aV = mf_ggx_root(mu, alpha2);
#if LUT_VIS == 2
    const float kS = 0.5f * alpha;
#endif
    const float svAlpha = sv * alpha;
#if LUT_NDF == 0 && LUT_VIS == 0
    const float gScale = mu + aV;
#elif LUT_NDF == 0 && LUT_VIS == 1
    const float gScale = 2.0f;
#elif LUT_NDF == 0
    const float gScale = (mu + aV) / (2.0f * (mu * (1.0f - kS) + kS));
#elif LUT_NDF == 1
    const float qV = mf_beckmann_mu_one_plus_lambda(mu, alpha);
#if LUT_VIS == 2
    const float visV = qV / (mu * (1.0f - kS) + kS);
#endif
#endif
    // GGX: sums of w, w F_c and their squares. Beckmann (self-normalised): sums of d,
    // d y_A, d y_B, d², d² y_A, d² y_B, d² y_A², d² y_B² with y = g (1 − F_c), g F_c.
    // Summed in blocks of LUT_BLOCK samples whose partial sums are then added to the totals
    // S0 … S7 (see LUT_BLOCK).
    float16 S0 = 0.0f, S1 = 0.0f, S2 = 0.0f, S3 = 0.0f;
#if LUT_NDF == 1
    float16 S4 = 0.0f, S5 = 0.0f, S6 = 0.0f, S7 = 0.0f;
#endif
    for (int kb = 0; kb < nPad; kb += LUT_BLOCK) {
    float16 s0 = 0.0f, s1 = 0.0f, s2 = 0.0f, s3 = 0.0f;
#if LUT_NDF == 1
    float16 s4 = 0.0f, s5 = 0.0f, s6 = 0.0f, s7 = 0.0f;
#endif
    for (int k = kb; k < min(kb + LUT_BLOCK, nPad); k += LUT_SIMD) {
#if LUT_DIRS == 0
      const float16 t1sq = vload16(0, table + LUT_TAB_T1SQ * nPad + k);
      const float16 t2r = vload16(0, table + LUT_TAB_T2 * nPad + k);
      const float16 c = vload16(0, table + LUT_TAB_C * nPad + k);
      const float16 c2 = vload16(0, table + LUT_TAB_C2 * nPad + k);
#else
      const float16 r = sqrt(vload16(0, table + LUT_TAB_U1 * nPad + k));
      const float16 phi = LUT_TWO_PI * vload16(0, table + LUT_TAB_U2 * nPad + k);
#if LUT_DIRS == 1
      const float16 t1 = r * cos(phi), t2r = r * sin(phi);
#else
      const float16 t1 = r * native_cos(phi), t2r = r * native_sin(phi);
#endif
      const float16 t1sq = t1 * t1, c2 = fmax(1.0f - t1sq, 0.0f), c = sqrt(c2);
#endif
#if LUT_PADDED
      const float16 mask = vload16(0, table + LUT_TAB_MASK * nPad + k);
#endif
      // Heitz 2018 in the frame T1 = (0, 1, 0), T2 = (−v_z, 0, v_x) of the stretched view:
      // unit normal n = (nx, t1, nz) there, stretched back to H ∝ (α nx, α t1, nz).
      const float16 t2 = oms * c + s * t2r;
      const float16 nw = MF_SQRT(fmax(c2 - t2 * t2, 0.0f));
      const float16 nx = nw * vhx - t2 * vhz;
      const float16 nz = fmax(t2 * vhx + nw * vhz, 0.0f);
      const float16 nxy2 = nx * nx + t1sq;
      const float16 inv = MF_RSQRT(alpha2 * nxy2 + nz * nz);
      const float16 hz = nz * inv;
      const float16 vdoth = (svAlpha * nx + mu * nz) * inv;
      const float16 nl = 2.0f * vdoth * hz - mu;
      const float16 fc = mf_schlick_fc16(vdoth);
#if LUT_NDF == 0
      // g = w / gScale (the per-point factor of the weight is applied after the loop).
#if LUT_VIS == 0
      const float16 g = MF_DIV(nl, nl * aV + mu * mf_ggx_root16(nl, alpha2));
#elif LUT_VIS == 1
      const float16 g = MF_DIV(nl, nl + mf_ggx_root16(nl, alpha2));
#else
      const float16 g = mf_schlick_g1_16(nl, kS);
#endif
#if LUT_PADDED
      const float16 w = select((float16)(0.0f), g, nl > 0.0f) * mask;
#else
      const float16 w = select((float16)(0.0f), g, nl > 0.0f);
#endif
      const float16 wb = w * fc, wa = w - wb;
      s0 += w;
      s1 += wb;
      s2 += wa * wa;
      s3 += wb * wb;
#else
#if LUT_VIS == 0
      const float16 g = MF_DIV(qV, qV + mu * mf_beckmann_lambda16(nl, alpha));
#elif LUT_VIS == 1
      const float16 g = MF_DIV(1.0f, 1.0f + mf_beckmann_lambda16(nl, alpha));
#else
      const float16 g = visV * mf_schlick_g1_16(nl, kS);
#endif
#if LUT_PADDED
      const float16 d = mf_beckmann_over_ggx16(nxy2, nz) * mask;
#else
      const float16 d = mf_beckmann_over_ggx16(nxy2, nz);
#endif
      const float16 y = select((float16)(0.0f), g, nl > 0.0f);
      const float16 yb = y * fc, ya = y - yb;
      const float16 d2 = d * d;
      s0 += d;
      s1 += d * ya;
      s2 += d * yb;
      s3 += d2;
      s4 += d2 * ya;
      s5 += d2 * yb;
      s6 += d2 * ya * ya;
      s7 += d2 * yb * yb;
#endif
    }
    S0 += s0, S1 += s1, S2 += s2, S3 += s3;
#if LUT_NDF == 1
    S4 += s4, S5 += s5, S6 += s6, S7 += s7;
#endif
    }
#if LUT_NDF == 0
    const float sw = lut_hsum16(S0), sb = lut_hsum16(S1);
    sums0 = (float4)(gScale * (sw - sb), gScale * sb, gScale * gScale * lut_hsum16(S2),
                     gScale * gScale * lut_hsum16(S3));
#else
    sums0 = (float4)(lut_hsum16(S0), lut_hsum16(S1), lut_hsum16(S2), lut_hsum16(S3));
    sums1 = (float4)(lut_hsum16(S4), lut_hsum16(S5), lut_hsum16(S6), lut_hsum16(S7));
#endif
  }

#if LUT_CLOTH
  {
    const float ac = fmax(alpha, 0.007921f);  // kLutClothAlphaMin
    const float invA = 1.0f / ac, kC = 2.0f + invA, e = 1.0f / kC;
    const float lam = rsqrt(ac), c0 = -expm1(-lam);  // exponential branch: p(c) = λ e^{−λc}/c0
    const float b0 = LUT_CLOTH_BETA0 * 0.63661977236758134f, b1 = LUT_CLOTH_BETA1 * lam / c0;
    float16 totalC = 0.0f, totalC2 = 0.0f;
    for (int kb = 0; kb < nPad; kb += LUT_BLOCK) {
    float16 sumC = 0.0f, sumC2 = 0.0f;
    for (int k = kb; k < min(kb + LUT_BLOCK, nPad); k += LUT_SIMD) {
      const float16 br = vload16(0, table + LUT_TAB_CL_BRANCH * nPad + k);
      const float16 ta = vload16(0, table + LUT_TAB_CL_A * nPad + k);
      const float16 tb = vload16(0, table + LUT_TAB_CL_B * nPad + k);
      const float16 u2 = vload16(0, table + LUT_TAB_U2 * nPad + k);
      const float16 mask = vload16(0, table + LUT_TAB_MASK * nPad + k);
      const int16 isU = br < 0.5f, isE = br > 0.5f && br < 1.5f;
      // Branch 1: cos θ = −ln(1 − u' c0)/λ.  Branch 2: ln sin θ = ln u'/K.
      const float16 cE = -log1p(-fmax(ta, 0.0f) * c0) / lam;
      const float16 lnS = select(select(e * ta, 0.5f * log1p(-fmin(cE * cE, 1.0f - 1e-7f)), isE), ta, isU);
      const float16 sh = MF_EXP(lnS);
      const float16 ch = select(select(MF_SQRT(fmax(-expm1(2.0f * lnS), 0.0f)), cE, isE), tb, isU);
      const float16 p = MF_EXP((invA + 1.0f) * lnS);  // sin^{1/α + 1} θ_h
      // φ uniform on the arc where ν > 0: cos φ > −μ cos 2θ/(√(1 − μ²) sin 2θ).
      const float16 cBound = clamp(-mu * (ch * ch - sh * sh) / fmax(2.0f * sv * sh * ch, 1e-30f), -1.0f, 1.0f);
      const float16 phiMax = acos(cBound);
      const float16 cphi = MF_COS(u2 * phiMax);
      const float16 vdoth = sv * sh * cphi + mu * ch;
      const float16 nl = 2.0f * vdoth * ch - mu;
      const float16 g = MF_DIV(nl * vdoth, nl + mu - nl * mu);
      const float16 kp = kC * p;
      const float16 pdf = b0 + b1 * MF_EXP(-lam * ch) * sh + LUT_CLOTH_BETA2 * kp * ch;
      const float16 w = select((float16)(0.0f), MF_DIV(kp * g * phiMax * LUT_INV_PI, pdf), nl > 0.0f) * mask;
      sumC += w;
      sumC2 += w * w;
    }
    totalC += sumC, totalC2 += sumC2;
    }
    sums2 = (float4)(lut_hsum16(totalC), lut_hsum16(totalC2), 0.0f, 0.0f);
  }
#endif

  out[LUT_OUT_FLOAT4S * gid] = sums0;
  out[LUT_OUT_FLOAT4S * gid + 1] = sums1;
  out[LUT_OUT_FLOAT4S * gid + 2] = sums2;
}
