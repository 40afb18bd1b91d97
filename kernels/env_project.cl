// env_project.cl: projection of an environment onto real SH.
//
//   L_i = ∫ L(ω) Y_i(ω) dω  ≈  Σ_t L(ω_t) Y_i(ω_t) Ω_t
//
// with ω_t the texel-centre direction and Ω_t the texel's exact solid angle
// (computed on the host in double, see envmap.h). Each work-item sums one image
// row into 3·n² partial sums (float); the host adds the rows in double, in row
// order, so the result is deterministic. The row loop is written with explicit
// vectors of VW texels (float16, float8 or float) because PoCL runs loop kernels
// scalar otherwise (PERF.md); the SH basis is evaluated on the vector.
//
// Build options: -DSH_ORDER=n (1..32) -DVW=1|8|16 -DENV_TEXELS=0|1|2.
//
// Texels come in the storage the map was loaded in (envmap.h, EnvStorage): float
// (ENV_TEXELS 0), IEEE half read with vload_half (1: OpenEXR half files, half the
// memory), or 8-bit codes turned into linear radiance through the 256-entry table
// `codeToLinear` (2: PNG and JPEG, a quarter of the memory). Kernels take the table
// argument in every build and read it only in the last.
#ifndef ENV_TEXELS
#define ENV_TEXELS 0
#endif
#if ENV_TEXELS == 0
#define ENV_T float
#define ENV_AT(p, i) ((p)[(i)])
#elif ENV_TEXELS == 1
#define ENV_T half
#define ENV_AT(p, i) vload_half((i), (p))
#else
#define ENV_T uchar
#define ENV_AT(p, i) codeToLinear[(p)[(i)]]
#endif
// Three consecutive vectors of texel components from p (the de-interleaving below
// takes them apart). Codes are looked up lane by lane: the table stays in L1.
#if ENV_TEXELS == 2
#define ENV_LOOKUP16(c) \
  (float16)(codeToLinear[c.s0], codeToLinear[c.s1], codeToLinear[c.s2], codeToLinear[c.s3], codeToLinear[c.s4], \
            codeToLinear[c.s5], codeToLinear[c.s6], codeToLinear[c.s7], codeToLinear[c.s8], codeToLinear[c.s9], \
            codeToLinear[c.sa], codeToLinear[c.sb], codeToLinear[c.sc], codeToLinear[c.sd], codeToLinear[c.se], \
            codeToLinear[c.sf])
#define ENV_LOOKUP8(c)                                                                                       \
  (float8)(codeToLinear[c.s0], codeToLinear[c.s1], codeToLinear[c.s2], codeToLinear[c.s3], codeToLinear[c.s4], \
           codeToLinear[c.s5], codeToLinear[c.s6], codeToLinear[c.s7])
#define ENV_VLOAD16(k, p) ENV_LOOKUP16(vload16((k), (p)))
#define ENV_VLOAD8(k, p) ENV_LOOKUP8(vload8((k), (p)))
#elif ENV_TEXELS == 1
#define ENV_VLOAD16(k, p) vload_half16((k), (p))
#define ENV_VLOAD8(k, p) vload_half8((k), (p))
#else
#define ENV_VLOAD16(k, p) vload16((k), (p))
#define ENV_VLOAD8(k, p) vload8((k), (p))
#endif

#ifndef VW
#define VW 16
#endif
#ifndef SH_ORDER
#define SH_ORDER 3
#endif
#define NC (SH_ORDER * SH_ORDER)

#if VW == 16
#define SH_T float16
#define VLOAD(p) vload16(0, (p))
#define LANES ((float16)(0.f, 1.f, 2.f, 3.f, 4.f, 5.f, 6.f, 7.f, 8.f, 9.f, 10.f, 11.f, 12.f, 13.f, 14.f, 15.f))
#define HSUM(v) hsum16(v)
static inline float hsum16(float16 v) {
  float8 a = v.lo + v.hi;
  float4 b = a.lo + a.hi;
  float2 c = b.lo + b.hi;
  return c.x + c.y;
}
// Deinterleaves 16 RGB texels (48 floats) into three vectors.
#define LOAD_RGB(p, r, g, b)                                                                  \
  {                                                                                           \
    float16 A = ENV_VLOAD16(0, (p)), B = ENV_VLOAD16(1, (p)), C = ENV_VLOAD16(2, (p));        \
    r = (float16)(A.s0, A.s3, A.s6, A.s9, A.sc, A.sf, B.s2, B.s5, B.s8, B.sb, B.se, C.s1, C.s4, \
                  C.s7, C.sa, C.sd);                                                          \
    g = (float16)(A.s1, A.s4, A.s7, A.sa, A.sd, B.s0, B.s3, B.s6, B.s9, B.sc, B.sf, C.s2, C.s5, \
                  C.s8, C.sb, C.se);                                                          \
    b = (float16)(A.s2, A.s5, A.s8, A.sb, A.se, B.s1, B.s4, B.s7, B.sa, B.sd, C.s0, C.s3, C.s6, \
                  C.s9, C.sc, C.sf);                                                          \
  }
#elif VW == 8
#define SH_T float8
#define VLOAD(p) vload8(0, (p))
#define LANES ((float8)(0.f, 1.f, 2.f, 3.f, 4.f, 5.f, 6.f, 7.f))
#define HSUM(v) hsum8(v)
static inline float hsum8(float8 v) {
  float4 b = v.lo + v.hi;
  float2 c = b.lo + b.hi;
  return c.x + c.y;
}
#define LOAD_RGB(p, r, g, b)                                                         \
  {                                                                                  \
    float8 A = ENV_VLOAD8(0, (p)), B = ENV_VLOAD8(1, (p)), C = ENV_VLOAD8(2, (p));   \
    r = (float8)(A.s0, A.s3, A.s6, B.s1, B.s4, B.s7, C.s2, C.s5);                    \
    g = (float8)(A.s1, A.s4, A.s7, B.s2, B.s5, C.s0, C.s3, C.s6);                    \
    b = (float8)(A.s2, A.s5, B.s0, B.s3, B.s6, C.s1, C.s4, C.s7);                    \
  }
#else
#define SH_T float
#define VLOAD(p) (*(p))
#define LANES 0.f
#define HSUM(v) (v)
#define LOAD_RGB(p, r, g, b) \
  {                          \
    r = ENV_AT(p, 0);        \
    g = ENV_AT(p, 1);        \
    b = ENV_AT(p, 2);        \
  }
#endif

#include "sh.clh"

// Loops over accumulators and basis values must be unrolled completely, or their
// arrays stay in memory and each multiply-add becomes a load, an FMA and a store
// (measured: order-3 cube moments 28 ms → 16 ms for 6×2048², order 8 ~130 → ~75 ms).
// Past a few hundred accumulators full unrolling only spills, so it stops there.
#if SH_ORDER <= 8
#define UNROLL _Pragma("unroll")
#else
#define UNROLL
#endif

// Adds one vector of texels (directions x, y, z; weight w = solid angle, 0 for
// padding lanes; radiance r, g, b) to the accumulators.
// Plain multiply-add, not fma(): PoCL lowers the vector fma() builtin to a slow
// correctly-rounded routine here (measured 2x slower for the whole kernel).
static inline void accumulate(SH_T x, SH_T y, SH_T z, SH_T w, SH_T r, SH_T g, SH_T b, SH_T* acc) {
  SH_T basis[NC];
  sh_eval(SH_ORDER, x, y, z, basis);
  r *= w;
  g *= w;
  b *= w;
  UNROLL
  for (int k = 0; k < NC; ++k) {
    acc[k] += basis[k] * r;
    acc[NC + k] += basis[k] * g;
    acc[2 * NC + k] += basis[k] * b;
  }
}

static inline void store_row(SH_T* acc, __global float* out) {
  UNROLL
  for (int k = 0; k < 3 * NC; ++k) out[k] = HSUM(acc[k]);
}

// Loads lanes c0..c0+VW-1 of an RGB row and weight row that may end before the
// vector does (columns ≥ n get weight 0 and radiance 0).
static inline void load_tail(__global const ENV_T* rgbRow, __global const float* codeToLinear,
                             __global const float* wRow, int c0, int n, SH_T* r, SH_T* g, SH_T* b, SH_T* w) {
  float tr[VW], tg[VW], tb[VW], tw[VW];
  for (int l = 0; l < VW; ++l) {
    int c = c0 + l;
    bool in = c < n;
    tr[l] = in ? ENV_AT(rgbRow, 3 * c) : 0.f;
    tg[l] = in ? ENV_AT(rgbRow, 3 * c + 1) : 0.f;
    tb[l] = in ? ENV_AT(rgbRow, 3 * c + 2) : 0.f;
    tw[l] = in ? wRow[c] : 0.f;
  }
#if VW == 1
  *r = tr[0], *g = tg[0], *b = tb[0], *w = tw[0];
#else
  *r = VLOAD(tr), *g = VLOAD(tg), *b = VLOAD(tb), *w = VLOAD(tw);
#endif
}

// Lanes c0..c0+VW-1 of a row: RGB de-interleaved and the weights (solid angles).
static inline void load_texels(__global const ENV_T* rgbRow, __global const float* codeToLinear,
                               __global const float* wRow, int c0, int n, SH_T* r, SH_T* g, SH_T* b, SH_T* w) {
  if (c0 + VW <= n) {
    SH_T tr, tg, tb;
    LOAD_RGB(rgbRow + 3 * c0, tr, tg, tb);
    *r = tr, *g = tg, *b = tb;
    *w = VLOAD(wRow + c0);
  } else {
    load_tail(rgbRow, codeToLinear, wRow, c0, n, r, g, b, w);
  }
}

// One work-item per face row.
// rgb:      6 faces × n rows × n columns × RGB, interleaved (ENV_T)
// codeToLinear: 256 floats, the linear radiance of each 8-bit code (ENV_TEXELS 2)
// weights:  exact texel solid angles of rows 0..(n+1)/2-1 (rows mirror: Ω(r) = Ω(n-1-r)), n per row
// bases:    6 × (axisU, axisV, axisN), 9 floats per face, yaw applied
// n:        face size
// partials: 6n rows × 3·NC sums (R block, G block, B block)
__kernel void project_cube(__global const ENV_T* rgb, __global const float* codeToLinear,
                           __global const float* weights, __constant float* bases, int n,
                           __global float* partials) {
  int rowId = get_global_id(0);
  if (rowId >= 6 * n) return;
  int face = rowId / n, row = rowId - face * n;
  __constant float* B = bases + 9 * face;
  float v = 2.0f * (row + 0.5f) / n - 1.0f;
  float ox = v * B[3] + B[6], oy = v * B[4] + B[7], oz = v * B[5] + B[8];
  __global const float* wRow = weights + (size_t)min(row, n - 1 - row) * n;
  __global const ENV_T* rgbRow = rgb + (size_t)rowId * n * 3;
  SH_T acc[3 * NC];
  UNROLL
  for (int k = 0; k < 3 * NC; ++k) acc[k] = (SH_T)(0.0f);
  float invN2 = 2.0f / n;
  for (int c0 = 0; c0 < n; c0 += VW) {
    SH_T r, g, b, w;
    load_texels(rgbRow, codeToLinear, wRow, c0, n, &r, &g, &b, &w);
    SH_T u = ((SH_T)(c0 + 0.5f) + LANES) * invN2 - 1.0f;
    SH_T x = u * B[0] + ox, y = u * B[1] + oy, z = u * B[2] + oz;
    SH_T inv = rsqrt(x * x + y * y + z * z);
    accumulate(x * inv, y * inv, z * inv, w, r, g, b, acc);
  }
  store_row(acc, partials + (size_t)rowId * 3 * NC);
}

// Cube faces by row moments. On a face, the unnormalised direction
// h = u·axisU + v·axisV + axisN is linear in (u, v) and |h| = r = √(1+u²+v²).
// r^l·Y_lm(h/r) is a homogeneous polynomial of degree l in h, so along a row
// (v fixed) it is a polynomial P_lm(u) = Σ_{a≤l} p_lma(v) u^a. Hence
//   L_lm(row) = Σ_c L_c Ω_c Y_lm(h_c/r_c) = Σ_{a≤l} p_lma(v) · M_la,
//   M_la = Σ_c L_c Ω_c r_c^{−l} u_c^a,
// and the kernel only accumulates the n(n+1)/2 moments M_la per channel (18 at
// order 3 instead of 27 products with an evaluated basis); the host forms the
// polynomial coefficients p_lma(v) in double and combines them (env_project.cpp).
#define NM (SH_ORDER * (SH_ORDER + 1) / 2)
__kernel void project_cube_moments(__global const ENV_T* rgb, __global const float* codeToLinear,
                                   __global const float* weights, int n, __global float* partials) {
  int rowId = get_global_id(0);
  if (rowId >= 6 * n) return;
  int face = rowId / n, row = rowId - face * n;
  float v = 2.0f * (row + 0.5f) / n - 1.0f;
  __global const float* wRow = weights + (size_t)min(row, n - 1 - row) * n;
  __global const ENV_T* rgbRow = rgb + (size_t)rowId * n * 3;
  SH_T acc[3 * NM];
  UNROLL
  for (int k = 0; k < 3 * NM; ++k) acc[k] = (SH_T)(0.0f);
  float invN2 = 2.0f / n, v2p1 = 1.0f + v * v;
  for (int c0 = 0; c0 < n; c0 += VW) {
    SH_T r, g, b, w;
    load_texels(rgbRow, codeToLinear, wRow, c0, n, &r, &g, &b, &w);
    SH_T u = ((SH_T)(c0 + 0.5f) + LANES) * invN2 - 1.0f;
    SH_T ir = rsqrt(u * u + v2p1);
    SH_T basis[NM];
    SH_T t = w;  // Ω r^{-l}
    int k = 0;
    UNROLL
    for (int l = 0; l < SH_ORDER; ++l) {
      SH_T q = t;
      UNROLL
      for (int a = 0; a <= l; ++a) {
        basis[k++] = q;
        q *= u;
      }
      t *= ir;
    }
    UNROLL
    for (int m = 0; m < NM; ++m) {
      acc[m] += basis[m] * r;
      acc[NM + m] += basis[m] * g;
      acc[2 * NM + m] += basis[m] * b;
    }
  }
  UNROLL
  for (int m = 0; m < 3 * NM; ++m) partials[(size_t)rowId * 3 * NM + m] = HSUM(acc[m]);
}

// One work-item per lat-long row.
// rgb:       h rows × w columns × RGB (ENV_T; codeToLinear as for project_cube)
// colSinCos: per column sin(λ + yaw), cos(λ + yaw)  (2w floats: all sines, then all cosines)
// rowTrig:   per row sin φ, cos φ, solid angle of one texel of the row (3h floats)
__kernel void project_latlong(__global const ENV_T* rgb, __global const float* codeToLinear,
                              __global const float* colSinCos, __global const float* rowTrig, int w, int h,
                              __global float* partials) {
  int row = get_global_id(0);
  if (row >= h) return;
  float sinPhi = rowTrig[3 * row], cosPhi = rowTrig[3 * row + 1], omega = rowTrig[3 * row + 2];
  __global const ENV_T* rgbRow = rgb + (size_t)row * w * 3;
  __global const float* sinL = colSinCos;
  __global const float* cosL = colSinCos + w;
  SH_T acc[3 * NC];
  UNROLL
  for (int k = 0; k < 3 * NC; ++k) acc[k] = (SH_T)(0.0f);
  for (int c0 = 0; c0 < w; c0 += VW) {
    SH_T r, g, b, s, c;
    if (c0 + VW <= w) {
      LOAD_RGB(rgbRow + 3 * c0, r, g, b);
      s = VLOAD(sinL + c0);
      c = VLOAD(cosL + c0);
    } else {
      SH_T unusedW;
      load_tail(rgbRow, codeToLinear, sinL, c0, w, &r, &g, &b, &s);
      load_tail(rgbRow, codeToLinear, cosL, c0, w, &r, &g, &b, &c);
      unusedW = s;
      (void)unusedW;
    }
    // Padding lanes have r = g = b = 0, so their direction does not matter.
    accumulate(s * cosPhi, (SH_T)(sinPhi), c * cosPhi, (SH_T)(omega), r, g, b, acc);
  }
  store_row(acc, partials + (size_t)row * 3 * NC);
}
