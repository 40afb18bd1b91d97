// prefilter.cl: prefiltered specular environments (docs/conventions.md "Prefiltered specular").
//
//   P(R) = ∫ L(l) k(R·l) dl / ∫ k(R·l) dl
//
// prefilter_cut: the host has gathered the environment into bins (flux F_b = Σ L_t Ω_t,
// solid angle Ω_b, radiance-weighted centroid c_b^L, solid-angle centroid c_b^Ω) and chosen,
// for each tile of output texels, a cut through the bin tree fine enough for the lobe
// (host/src/prefilter_cut.cpp). Each texel then sums
//   P(R) ≈ Σ_b F_b k(R, c_b^L) / Σ_b Ω_b k(R, c_b^Ω)
// over its tile's cut. The lobe is evaluated from e = 1 − R·c = |R − c|²/2, which keeps
// its relative accuracy near the peak (1 − R·c itself cancels to ~1e-7 absolute, as large
// as α² for the narrowest lobes). A work-item holds VW texels of one tile in vector lanes
// and walks the tile's bin list once: PoCL runs loops scalar unless the data are vectors
// (PERF.md).
//
// prefilter_sampled: the anchors' estimator (Filament cmgen / Khronos IBL sampler), one
// texel per work-item: Σ_i NoL_i C(L_i, lod_i) / Σ_i NoL_i over a table of importance-sampled
// GGX directions with the pdf-based level lod_i, read trilinearly from a box-filtered mip
// chain whose faces carry a one-texel border from their neighbours (seamless bilinear).
//
// Build options: -DPF_LOBE=0|1|2 (GGX | Charlie | lambertian), -DVW=16|8|1.
#ifndef PF_LOBE
#define PF_LOBE 0
#endif
#ifndef VW
#define VW 16
#endif

#if VW == 16
#define V float16
#define VI int16
#define CONVERT_V convert_float16
#define CONVERT_VI convert_int16
#define AS_VI as_int16
#define AS_V as_float16
#define LANE_IDS ((int16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15))
#define VSTORE(v, p) vstore16((v), 0, (p))
#elif VW == 8
#define V float8
#define VI int8
#define CONVERT_V convert_float8
#define CONVERT_VI convert_int8
#define AS_VI as_int8
#define AS_V as_float8
#define LANE_IDS ((int8)(0, 1, 2, 3, 4, 5, 6, 7))
#define VSTORE(v, p) vstore8((v), 0, (p))
#else
#define V float
#define VI int
#define CONVERT_V (float)
#define CONVERT_VI (int)
#define AS_VI as_int
#define AS_V as_float
#define LANE_IDS 0
#define VSTORE(v, p) (*(p) = (v))
#endif

#if PF_LOBE == 1
// log2 and exp2 in vector arithmetic: PoCL's CPU device calls a scalar library function per
// lane for the built-ins, which took most of the Charlie kernel's time. log2 x = E + log2 m,
// m ∈ [√½, √2), log2 m = (2/ln 2) atanh t, t = (m − 1)/(m + 1), |t| ≤ 0.172, by its series to
// t⁹ (next term < 4e-9); exp2 y = 2^n · √2 · 2^f, f = y − n − ½ ∈ [−½, ½), by its Taylor series to
// f⁷ (next term < 1e-8), 0 below 2⁻¹²⁶, 2¹²⁷·√2·2^f above (the weight's y exceeds 127 only
// below the horizon, μ < −½ at α < 0.004, where the weight is μ⁺ · 2^y = 0: an infinity there would
// make it NaN). Both within a few float ulps (tests/test_prefilter.cpp).
static inline V pf_log2(V x) {
  const VI bits = AS_VI(x);
  V m = AS_V((bits & 0x007fffff) | 0x3f800000);
  const VI big = m > 1.41421356f;
  m = select(m, 0.5f * m, big);
  const VI ex = select(((bits >> 23) & 255) - 127, ((bits >> 23) & 255) - 126, big);
  const V t = (m - 1.0f) / (m + 1.0f), t2 = t * t;
  const V s = 1.0f + t2 * (0.33333333f + t2 * (0.2f + t2 * (0.14285714f + t2 * 0.11111111f)));
  return CONVERT_V(ex) + 2.88539008f * t * s;
}
static inline V pf_exp2(V y) {
  const V yc = clamp(y, -126.0f, 127.0f), nf = floor(yc), f = yc - nf - 0.5f;
  const V p = 1.0f + f * (0.69314718f + f * (0.24022651f + f * (0.05550411f + f * (0.00961813f +
              f * (0.00133336f + f * (1.5403530e-4f + f * 1.5252734e-5f))))));
  const V scale = AS_V((CONVERT_VI(nf) + 127) << 23);
  return select(1.41421356f * p * scale, (V)(0.0f), y < -126.0f);
}
#endif

// The lobe k as a function of e = 1 − μ, scaled to a peak of 1 (prefilterLobeWeight):
//   GGX        μ (α²/q)²,  q = (N·H)²(α² − 1) + 1 = e/2 + (1 − e/2) α²  ((N·H)² = 1 − e/2)
//   Charlie    μ (e/2)^(1/(2α)) / k_max, in log2 form
//   lambertian μ
// lobe = (α², 1/(2α), log2 k_max, 0). Zero below the horizon (μ ≤ 0).
static inline V pf_lobe(V e, float4 lobe) {
  V mu = 1.0f - e;
#if PF_LOBE == 0
  V q = 0.5f * e + (1.0f - 0.5f * e) * lobe.x;
  V w = lobe.x / q;
  return fmax(mu, 0.0f) * w * w;
#elif PF_LOBE == 1
  return fmax(mu, 0.0f) * pf_exp2(lobe.y * pf_log2(fmax(0.5f * e, 1e-30f)) - lobe.z);
#else
  return fmax(mu, 0.0f);
#endif
}

// One launch computes the leaves `leaves` (index ty·S_0 + tx) of one face; work-item gid holds
// lanes p = (gid mod wiPerLeaf)·VW + lane of leaf gid / wiPerLeaf, texel (ty·L + p / L,
// tx·L + p mod L). A texel sums the bin lists of its leaf and of every tile above it: tile
// (k, ty >> k, tx >> k) has id tileOffset[k] + (face·S_k + (ty >> k))·S_k + (tx >> k), S_k = S_0 >> k,
// and its list is bins[start[id] .. start[id + 1]): entries level:4 | depth:4 | face:3 | row:10 | col:10,
// bin (level, face, row, col) taken as its 4^depth descendants, each at
// binOffset[level − depth] + (face·m + r)·m + c, m = binSize0 >> (level − depth).
// flux/dirL/dirG: per bin (F_r, F_g, F_b, Ω), (c^L, 0), (c^Ω, 0). bases: 6 × (U, V, N) of the
// standard cube. out: the level's RGB, face-major, row 0 on top.
__kernel void prefilter_cut(__global const float4* flux, __global const float4* dirL,
                            __global const float4* dirG, __global const uint* start,
                            __global const uint* bins, __global const int* leaves, int face, int n,
                            int leafSize, int wiPerLeaf, int tileLevels, __constant uint* tileOffset,
                            int side0, __constant uint* binOffset, int binSize0, __constant float* bases,
                            float4 lobe, __global float* out) {
  const int gid = get_global_id(0);
  const int slot = gid / wiPerLeaf, w = gid - slot * wiPerLeaf;
  const int leaf = leaves[slot], ty = leaf / side0, tx = leaf - (leaf / side0) * side0;
  const VI p = (VI)(w * VW) + LANE_IDS;
  const VI row = (VI)(ty * leafSize) + p / leafSize, col = (VI)(tx * leafSize) + p % leafSize;
  const VI valid = (p < leafSize * leafSize) & (row < n) & (col < n);
  const float scale = 2.0f / n;
  const V u = (CONVERT_V(col) + 0.5f) * scale - 1.0f, v = (CONVERT_V(row) + 0.5f) * scale - 1.0f;
  __constant float* b = bases + 9 * face;
  V x = u * b[0] + v * b[3] + b[6];
  V y = u * b[1] + v * b[4] + b[7];
  V z = u * b[2] + v * b[5] + b[8];
  const V inv = rsqrt(x * x + y * y + z * z);
  x *= inv, y *= inv, z *= inv;

  V accR = 0.0f, accG = 0.0f, accB = 0.0f, accW = 0.0f;
  for (int lvl = tileLevels - 1; lvl >= 0; --lvl) {
    const int sk = side0 >> lvl;
    const uint id = tileOffset[lvl] + (uint)((face * sk + (ty >> lvl)) * sk + (tx >> lvl));
    const uint k1 = start[id + 1];
    for (uint k = start[id]; k < k1; ++k) {
      // Entry: bin (level, face, row, col) as its 4^depth descendants `depth` levels down.
      const uint e = bins[k];
      const int depth = (e >> 23) & 15u, lc = (int)(e >> 27) - depth, face = (e >> 20) & 7u;
      const int span = 1 << depth, m = binSize0 >> lc;
      const int r0 = ((e >> 10) & 1023u) * span, c0 = (e & 1023u) * span;
      for (int r = r0; r < r0 + span; ++r) {
        const uint row0 = binOffset[lc] + (uint)((face * m + r) * m);
        for (int c = c0; c < c0 + span; ++c) {
          const uint i = row0 + (uint)c;
          const float4 f = flux[i], cl = dirL[i], cg = dirG[i];
          V dx = x - cl.x, dy = y - cl.y, dz = z - cl.z;
          const V wl = pf_lobe(0.5f * (dx * dx + dy * dy + dz * dz), lobe);
          dx = x - cg.x, dy = y - cg.y, dz = z - cg.z;
          const V wg = pf_lobe(0.5f * (dx * dx + dy * dy + dz * dz), lobe);
          accR += wl * f.x;
          accG += wl * f.y;
          accB += wl * f.z;
          accW += wg * f.w;
        }
      }
    }
  }
  const V invW = select((V)(0.0f), 1.0f / accW, accW > 0.0f);
  float tr[VW], tg[VW], tb[VW];
  int tRow[VW], tCol[VW], tValid[VW];
  VSTORE(accR * invW, tr);
  VSTORE(accG * invW, tg);
  VSTORE(accB * invW, tb);
#if VW == 1
  tRow[0] = row, tCol[0] = col, tValid[0] = valid;
#elif VW == 16
  vstore16(row, 0, tRow), vstore16(col, 0, tCol), vstore16(valid, 0, tValid);
#else
  vstore8(row, 0, tRow), vstore8(col, 0, tCol), vstore8(valid, 0, tValid);
#endif
  for (int l = 0; l < VW; ++l) {
    if (!tValid[l]) continue;
    const size_t o = 3 * (((size_t)face * n + tRow[l]) * n + tCol[l]);
    out[o] = tr[l];
    out[o + 1] = tg[l];
    out[o + 2] = tb[l];
  }
}

// --- the anchors' estimator ---

// Bilinear lookup in level `lvl` of the bordered chain: levels[lvl] = (offset in texels of
// the level, face size m); each face stores (m + 2)² float4 texels, row 0 and column 0 being
// the border. (s, t) ∈ [0, 1]² on the face.
static inline float4 pf_bilinear(__global const float4* chain, __global const int2* levels, int lvl, int face, float s,
                                 float t) {
  const int2 lv = levels[lvl];
  const int m = lv.y, stride = m + 2;
  const float fx = s * m + 0.5f, fy = t * m + 0.5f;  // +1 for the border, −0.5 for texel centres
  const float x0f = floor(fx), y0f = floor(fy);
  const float ax = fx - x0f, ay = fy - y0f;
  const int x0 = clamp((int)x0f, 0, m), y0 = clamp((int)y0f, 0, m);
  __global const float4* f = chain + lv.x + face * stride * stride;
  const float4 a = f[y0 * stride + x0], bb = f[y0 * stride + x0 + 1];
  const float4 c = f[(y0 + 1) * stride + x0], d = f[(y0 + 1) * stride + x0 + 1];
  return mix(mix(a, bb, ax), mix(c, d, ax), ay);
}

// Face and (s, t) ∈ [0, 1]² of a direction (docs/conventions.md "Cube faces": +X (1, −v, −u), ...).
static inline int pf_face_st(float3 d, float* s, float* t) {
  const float3 a = fabs(d);
  int face;
  float u, v, ma;
  if (a.x >= a.y && a.x >= a.z) {
    face = d.x >= 0 ? 0 : 1;
    ma = a.x;
    u = d.x >= 0 ? -d.z : d.z;
    v = -d.y;
  } else if (a.y >= a.z) {
    face = d.y >= 0 ? 2 : 3;
    ma = a.y;
    u = d.x;
    v = d.y >= 0 ? d.z : -d.z;
  } else {
    face = d.z >= 0 ? 4 : 5;
    ma = a.z;
    u = d.z >= 0 ? d.x : -d.x;
    v = -d.y;
  }
  *s = 0.5f * (u / ma + 1.0f);
  *t = 0.5f * (v / ma + 1.0f);
  return face;
}

// samples: per sample (L_x, L_y, L_z in the frame with R = +z; NoL), lods: its mip level.
// maxLevel: the chain's last level. One texel per work-item, texel index gid of the level.
__kernel void prefilter_sampled(__global const float4* chain, __global const int2* levels, int maxLevel,
                                __global const float4* samples, __global const float* lods, int sampleCount,
                                int n, __constant float* bases, __global float* out) {
  const int gid = get_global_id(0);
  if (gid >= 6 * n * n) return;
  const int face = gid / (n * n), rem = gid - face * n * n, row = rem / n, col = rem - row * n;
  const float u = (col + 0.5f) * 2.0f / n - 1.0f, v = (row + 0.5f) * 2.0f / n - 1.0f;
  __constant float* b = bases + 9 * face;
  const float3 R = normalize((float3)(u * b[0] + v * b[3] + b[6], u * b[1] + v * b[4] + b[7],
                                     u * b[2] + v * b[5] + b[8]));
  // Frame (T, B, R) as the Khronos sampler builds it.
  float3 up = fabs(R.y) > 0.999f ? (float3)(0.0f, 0.0f, R.y > 0 ? -1.0f : 1.0f) : (float3)(0.0f, 1.0f, 0.0f);
  const float3 T = normalize(cross(up, R)), B = cross(R, T);
  float4 acc = 0.0f;
  for (int i = 0; i < sampleCount; ++i) {
    const float4 sm = samples[i];
    const float3 L = T * sm.x + B * sm.y + R * sm.z;
    float s, t;
    const int f = pf_face_st(L, &s, &t);
    const float lod = clamp(lods[i], 0.0f, (float)maxLevel);
    const int l0 = (int)floor(lod), l1 = min(l0 + 1, maxLevel);
    const float4 c = mix(pf_bilinear(chain, levels, l0, f, s, t), pf_bilinear(chain, levels, l1, f, s, t), lod - l0);
    acc += (float4)(c.xyz * sm.w, sm.w);
  }
  const float inv = acc.w > 0 ? 1.0f / acc.w : 0.0f;
  out[3 * gid] = acc.x * inv;
  out[3 * gid + 1] = acc.y * inv;
  out[3 * gid + 2] = acc.z * inv;
}
