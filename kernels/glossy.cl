// glossy.cl: per-vertex glossy transfer matrices (docs/conventions.md, "Glossy transfer").
//
// For a vertex p with normal n,
//   M_ij(p) = ∫ V(p, ω) H(n·ω) Y_i(ω) Y_j(ω) dω.
// With directions ω_s over the hemisphere of n and weights w_s (uniform samples: w_s = 1,
// the host multiplies by 2π/N; the exact product rule of the unshadowed matrix: its
// quadrature weights), the kernel returns
//   G_ij = Σ_s w_s V_s Y_i(ω_s) Y_j(ω_s),   j ≤ i < SH_COUNT     (glossy_gram)
// a Gram matrix Yᵀ W Y: only its lower triangle is summed, row by row
// (index i(i+1)/2 + j). Interreflection adds, for rays that hit q_s,
//   B_ij = Σ_s w_s Y_i(ω_s) ρ_c(q_s) T_j(q_s),  i < OUT_COUNT, j < IN_COUNT   (glossy_bounce)
// with T(q) the diffuse transport interpolated with barycentrics.
//
// The packet form (RAY_LANES = 1, a CPU's): a work-item takes one vertex and its directions
// BVH_PACKET (16) at a time, as the transport kernels do: the packet is traced with
// bvh_packet_occluded / bvh_packet_closest, SH are evaluated on float16 directions, and every
// (i, j) entry keeps one float16 accumulator, so the batched product Yᵀ diag(w V) Y runs 16 lanes wide
// (PoCL turns explicit vector types into AVX-512). The lanes are summed in a fixed order
// at the end: deterministic, and no launch sums more than the directions it was given
// (at most 1024: the host adds launches in double).
//
// The lane form (RAY_LANES = L > 1, a GPU's; lanes.clh): the packet form's float16
// accumulators take every register of a GPU's thread and spill (bench/results/gpu.md), so there
// a vertex has L work-items. Step by step, lane j traces ray s0 + j alone (the binary BVH of
// bvh.clh) and puts its weight and SH values (and, in glossy_bounce, g_j) in local memory;
// then each lane sums the step's L rays, in ray order, into the entries it owns (entry k:
// lane k % L) and adds that to the entry's total: two levels, as the packets' 16 lanes, so the
// float rounding stays as small as theirs; a result does not depend on the group size.
//
// Build options: SH_ORDER (glossy_gram: max(n_out, n_in)), OUT_ORDER and IN_ORDER
// (glossy_bounce), VISIBILITY (0: no BVH access, for the unshadowed product rule), RAY_LANES.
#include "lanes.clh"
#if RAY_LANES == 1
#define SH_T float16  // the packet form's SH: 16 directions at once
#endif
#include "bvh.clh"
#include "sh.clh"

#ifndef SH_ORDER
#define SH_ORDER 5
#endif
#ifndef OUT_ORDER
#define OUT_ORDER SH_ORDER
#endif
#ifndef IN_ORDER
#define IN_ORDER SH_ORDER
#endif
#ifndef VISIBILITY
#define VISIBILITY 1
#endif
#define SH_COUNT (SH_ORDER * SH_ORDER)
#define GRAM_COUNT (SH_COUNT * (SH_COUNT + 1) / 2)
#define OUT_COUNT (OUT_ORDER * OUT_ORDER)
#define IN_COUNT (IN_ORDER * IN_ORDER)

#if RAY_LANES > 1

typedef BvhNode GlossyNode;  // one ray at a time: the binary BVH (bvh.clh)

// Sample s of the launch in the vertex's frame (t, b, n), and its weight.
static inline float3 glossy_dir(float3 t, float3 b, float3 n, __global const float* dirsSoA, int paddedCount, int s,
                                       float* weight) {
  const float lx = dirsSoA[s], ly = dirsSoA[paddedCount + s], lz = dirsSoA[2 * paddedCount + s];
  *weight = dirsSoA[3 * paddedCount + s];
  return t * lx + b * ly + n * lz;
}

#define GRAM_PER_LANE ((GRAM_COUNT + RAY_LANES - 1) / RAY_LANES)
#define GRAM_RAY_FLOATS (1 + SH_COUNT)
#define BOUNCE_PER_LANE ((OUT_COUNT * IN_COUNT + RAY_LANES - 1) / RAY_LANES)
#define BOUNCE_RAY_FLOATS (1 + OUT_COUNT + IN_COUNT)

#else  // the packet form

#define BVH_PACKET 16
#define PK_CAT2(a, b) a##b
#define PK_CAT(a, b) PK_CAT2(a, b)
#include "bvh_packet.clh"

typedef Bvh4Node GlossyNode;  // the 4-wide BVH of bvh_packet.clh

static inline float glossy_hsum(float16 a) {
  float s = 0.0f;
  for (int j = 0; j < 16; ++j) s += ((float*)&a)[j];
  return s;
}

#endif

// Arguments (one vertex to a work-item, or to RAY_LANES of them):
// vertexCount, sampleCount: V and the directions of this launch
// origins:  V × (x, y, z, w): ray origins offset along the geometric normal; w = 1 marks a
//           vertex no triangle can reach (no rays traced; as transport.cl)
// frames:   V × 3 float4 (t, b, n); n = 0 marks a vertex without a normal (zero output)
// dirsSoA:  4 rows of paddedCount floats: local x, y, z and the weight w (0 in padding lanes)
// nodes, tris, tMax: the BVH and the ray length
// out:      V × GRAM_COUNT, the lower triangle of G, row by row
// blocked, maskWords: when maskWords > 0 (= paddedCount / 16), V × maskWords words, one per
//           packet, with bit j set where the packet's ray j is blocked (for glossy_bounce,
//           which traces the same rays), written for every vertex
// rays, bits: local memory of the lane form (unused by the packets): GRAM_RAY_FLOATS floats per
//           work-item (a step's weights and SH values) and LANES_LAUNCH_UINTS uints per vertex of
//           the group (its blocked rays)
__kernel void glossy_gram(int vertexCount, int sampleCount, __global const float4* origins,
                          __global const float4* frames, __global const float* dirsSoA,
                          __global const GlossyNode* nodes, __global const float4* tris, float tMax,
                          __global float* out, int paddedCount, __global ushort* blocked, int maskWords,
                          __local float* rays, __local uint* bits) {
#if RAY_LANES > 1
  const int vi = get_global_id(0) / RAY_LANES, lane = get_global_id(0) % RAY_LANES;
  const bool active = vi < vertexCount;  // the last group's work-items past the end: no rays, no output
  __global const float4* frame = frames + (size_t)(active ? vi : 0) * 3;
  const float3 t = frame[0].xyz, b = frame[1].xyz, n = frame[2].xyz;
  const float4 o = origins[active ? vi : 0];
  const bool sums = active && dot(n, n) > 0.0f, trace = sums && o.w == 0.0f;
  __local float* step = rays + get_local_id(0) / RAY_LANES * RAY_LANES * GRAM_RAY_FLOATS;  // this vertex's
  __local uint* mine = bits + get_local_id(0) / RAY_LANES * LANES_LAUNCH_UINTS;
  lanes_mask_clear(mine, lane);
  // The entries k = m·L + lane of the lower triangle, row i and column j.
  int ei[GRAM_PER_LANE], ej[GRAM_PER_LANE];
  float acc[GRAM_PER_LANE];
  for (int m = 0; m < GRAM_PER_LANE; ++m) ei[m] = -1, ej[m] = 0, acc[m] = 0.0f;
  for (int i = 0, k = 0; i < SH_COUNT; ++i)
    for (int j = 0; j <= i; ++j, ++k)
      if (k % RAY_LANES == lane) ei[k / RAY_LANES] = i, ej[k / RAY_LANES] = j;
  barrier(CLK_LOCAL_MEM_FENCE);
  for (int s0 = 0; s0 < sampleCount; s0 += RAY_LANES) {  // every work-item takes every step (barriers)
    const int s = s0 + lane;
    __local float* r = step + lane * GRAM_RAY_FLOATS;
    float weight = 0.0f, y[SH_COUNT];
    float3 d = n;
    if (sums && s < sampleCount) {
      d = glossy_dir(t, b, n, dirsSoA, paddedCount, s, &weight);
#if VISIBILITY
      if (trace && bvh_occluded(nodes, tris, o.xyz, d, tMax)) {
        weight = 0.0f;
        if (maskWords > 0) atomic_or(mine + s / 32, 1u << (s % 32));
      }
#endif
    }
    sh_eval(SH_ORDER, d.x, d.y, d.z, y);
    r[0] = weight;
    for (int k = 0; k < SH_COUNT; ++k) r[1 + k] = y[k];
    barrier(CLK_LOCAL_MEM_FENCE);  // the step's rays are in
    for (int m = 0; m < GRAM_PER_LANE; ++m) {
      if (ei[m] < 0) continue;
      float a = 0.0f;  // the step's sum, then the entry's: two levels, as the packets' lanes
      for (int q = 0; q < RAY_LANES; ++q) {
        __local const float* rq = step + q * GRAM_RAY_FLOATS;
        a = fma(rq[0] * rq[1 + ei[m]], rq[1 + ej[m]], a);
      }
      acc[m] += a;
    }
    barrier(CLK_LOCAL_MEM_FENCE);  // read by every lane: free for the next step
  }
  if (active) {
    lanes_mask_store(mine, blocked + (size_t)vi * maskWords, lane, maskWords);
    for (int m = 0; m < GRAM_PER_LANE; ++m)
      if (ei[m] >= 0) out[(size_t)vi * GRAM_COUNT + m * RAY_LANES + lane] = acc[m];
  }
#else  // the packet form
  const int vi = get_global_id(0);
  if (vi >= vertexCount) return;
  __global const float4* frame = frames + (size_t)vi * 3;
  // No normal or no triangle in reach: no ray is blocked (the words the loop below skips).
  for (int w = 0; w < maskWords; ++w) blocked[(size_t)vi * maskWords + w] = 0;
  float16 acc[GRAM_COUNT];
  for (int k = 0; k < GRAM_COUNT; ++k) acc[k] = (float16)(0.0f);
  const float3 t = frame[0].xyz, b = frame[1].xyz, n = frame[2].xyz;
  if (dot(n, n) > 0.0f) {
    const float3 o = origins[vi].xyz;
    const bool trace = origins[vi].w == 0.0f;
#if VISIBILITY
    PkFrontier front;
    if (trace) pk_frontier(nodes, tris, o, n, tMax, &front);
#endif
    const int16 lane = PK_LANE_INDEX;
    for (int s = 0; s < sampleCount; s += 16) {
      PK_WORLD_DIRS(s);
      const float16 lw = vload16(0, dirsSoA + 3 * paddedCount + s);
      int16 live = (lane + s) < sampleCount;
#if VISIBILITY
      if (trace) {
        const int16 hit = bvh_packet_occluded(nodes, tris, o, dx, dy, dz, tMax, live, &front);
        live &= ~hit;
        if (maskWords > 0) blocked[(size_t)vi * maskWords + s / 16] = (ushort)pk_bits(hit);
      }
#endif
      float16 y[SH_COUNT];
      sh_eval(SH_ORDER, dx, dy, dz, y);
      const float16 w = select((float16)(0.0f), lw, live);
      int k = 0;
      for (int i = 0; i < SH_COUNT; ++i) {
        const float16 wy = w * y[i];
        for (int j = 0; j <= i; ++j, ++k) acc[k] = fma(wy, y[j], acc[k]);
      }
    }
  }
  for (int k = 0; k < GRAM_COUNT; ++k) out[(size_t)vi * GRAM_COUNT + k] = glossy_hsum(acc[k]);
#endif  // RAY_LANES
}

// One channel of the interreflected term. Arguments as glossy_gram, and:
// indices: T × (i0, i1, i2, 0) vertex indices of every mesh triangle
// albedo:  V × (r, g, b, 0)
// diffuse: V × diffuseChannels × IN_COUNT, the diffuse transport T at every vertex
// channel: 0, 1, 2 (albedo channel; T's channel when diffuseChannels = 3)
// out:     V × OUT_COUNT × IN_COUNT, Σ_s w_s Y_i(ω_s) ρ_c(q_s) T_j(q_s)
// blocked, maskWords: when maskWords > 0, glossy_gram's mask of these same rays: the rays it
//          did not find blocked hit nothing and are not traced
// hits, hitStart, chunks, chunk, hitMode (with a mask): 0, trace; 1, trace and write every
//          traced ray's hit (triangle id as int bits, or −1, u, v: 3 floats) in lane order
//          from hits + 3 · hitStart[vertex · chunks + chunk]; 2, read those hits instead of
//          tracing (the other colour channels: the same rays, so the same hits)
// rays:    local memory of the lane form: BOUNCE_RAY_FLOATS floats per work-item (a step's
//          weights, SH values and g)
__kernel void glossy_bounce(int vertexCount, int sampleCount, __global const float4* origins,
                            __global const float4* frames, __global const float* dirsSoA,
                            __global const GlossyNode* nodes, __global const float4* tris, float tMax,
                            __global const int4* indices, __global const float4* albedo,
                            __global const float* diffuse, int diffuseChannels, int channel,
                            __global float* out, int paddedCount, __global const ushort* blocked, int maskWords,
                            __global float* hits, __global const int* hitStart, int chunks, int chunk, int hitMode,
                            __local float* rays) {
#if RAY_LANES > 1
  const int vi = get_global_id(0) / RAY_LANES, lane = get_global_id(0) % RAY_LANES;
  const bool active = vi < vertexCount;
  __global const float4* frame = frames + (size_t)(active ? vi : 0) * 3;
  const float3 t = frame[0].xyz, b = frame[1].xyz, n = frame[2].xyz;
  const float4 o = origins[active ? vi : 0];
  // A vertex no triangle can reach sees no surface: its term is zero.
  const bool reach = active && dot(n, n) > 0.0f && o.w == 0.0f;
  const int tc = diffuseChannels == 3 ? channel : 0;
  __local float* step = rays + get_local_id(0) / RAY_LANES * RAY_LANES * BOUNCE_RAY_FLOATS;
  __global float* kept = hitMode != 0 && active ? hits + 3 * (size_t)hitStart[(size_t)vi * chunks + chunk] : hits;
  float acc[BOUNCE_PER_LANE];  // entry k = m·L + lane: row k / IN_COUNT, column k % IN_COUNT
  for (int m = 0; m < BOUNCE_PER_LANE; ++m) acc[m] = 0.0f;
  int before = 0;  // the traced rays before the step, for the kept hits' places
  for (int s0 = 0; s0 < sampleCount; s0 += RAY_LANES) {
    const int s = s0 + lane;
    uint traced = reach ? 0xffffffffu >> (32 - RAY_LANES) : 0u;  // only the rays glossy_gram found blocked
    if (reach && maskWords > 0) traced = lanes_mask_step(blocked + (size_t)vi * maskWords, s0, maskWords);
    const int rank = before + popcount(traced & ((1u << lane) - 1u));
    before += popcount(traced);
    __local float* r = step + lane * BOUNCE_RAY_FLOATS;
    float weight = 0.0f, y[OUT_COUNT];
    float3 d = n;
    for (int k = 0; k < IN_COUNT; ++k) r[1 + OUT_COUNT + k] = 0.0f;
    if (s < sampleCount && ((traced >> lane) & 1u)) {
      float lw;
      d = glossy_dir(t, b, n, dirsSoA, paddedCount, s, &lw);
      int tri;
      float u, v;
      if (hitMode == 2) {  // the hit the first channel's launch kept
        tri = as_int(kept[3 * rank]), u = kept[3 * rank + 1], v = kept[3 * rank + 2];
      } else {
        tri = bvh_closest(nodes, tris, o.xyz, d, tMax, &u, &v);
        if (hitMode == 1) kept[3 * rank] = as_float(tri), kept[3 * rank + 1] = u, kept[3 * rank + 2] = v;
      }
      if (tri >= 0) {  // g_j = ρ_c(q) T_j(q)
        const float3 bw = bvh_hit_weights(u, v);
        const int4 idx = indices[tri];
        const float4 rho4 = albedo[idx.x] * bw.x + albedo[idx.y] * bw.y + albedo[idx.z] * bw.z;
        const float rho = channel == 0 ? rho4.x : (channel == 1 ? rho4.y : rho4.z);
        __global const float* t0 = diffuse + ((size_t)idx.x * diffuseChannels + tc) * IN_COUNT;
        __global const float* t1 = diffuse + ((size_t)idx.y * diffuseChannels + tc) * IN_COUNT;
        __global const float* t2 = diffuse + ((size_t)idx.z * diffuseChannels + tc) * IN_COUNT;
        for (int k = 0; k < IN_COUNT; ++k) r[1 + OUT_COUNT + k] = rho * (bw.x * t0[k] + bw.y * t1[k] + bw.z * t2[k]);
        weight = lw;
      }
    }
    sh_eval(OUT_ORDER, d.x, d.y, d.z, y);
    r[0] = weight;
    for (int k = 0; k < OUT_COUNT; ++k) r[1 + k] = y[k];
    barrier(CLK_LOCAL_MEM_FENCE);  // the step's rays are in
    for (int m = 0; m < BOUNCE_PER_LANE; ++m) {
      const int k = m * RAY_LANES + lane, i = k / IN_COUNT, j = k % IN_COUNT;
      if (k >= OUT_COUNT * IN_COUNT) break;
      float a = 0.0f;
      for (int q = 0; q < RAY_LANES; ++q) {
        __local const float* rq = step + q * BOUNCE_RAY_FLOATS;
        a = fma(rq[0] * rq[1 + i], rq[1 + OUT_COUNT + j], a);
      }
      acc[m] += a;
    }
    barrier(CLK_LOCAL_MEM_FENCE);  // free for the next step
  }
  for (int m = 0; active && m < BOUNCE_PER_LANE && m * RAY_LANES + lane < OUT_COUNT * IN_COUNT; ++m)
    out[(size_t)vi * OUT_COUNT * IN_COUNT + m * RAY_LANES + lane] = acc[m];
#else  // the packet form
  const int vi = get_global_id(0);
  if (vi >= vertexCount) return;
  __global const float4* frame = frames + (size_t)vi * 3;
  float16 acc[OUT_COUNT * IN_COUNT];
  for (int k = 0; k < OUT_COUNT * IN_COUNT; ++k) acc[k] = (float16)(0.0f);
  const float3 t = frame[0].xyz, b = frame[1].xyz, n = frame[2].xyz;
  // A vertex no triangle can reach sees no surface: its term is zero.
  if (dot(n, n) > 0.0f && origins[vi].w == 0.0f) {
    const float3 o = origins[vi].xyz;
    const int16 lane = PK_LANE_INDEX;
    const int tc = diffuseChannels == 3 ? channel : 0;
    PkFrontier front;
    if (hitMode != 2) pk_frontier(nodes, tris, o, n, tMax, &front);
    __global float* kept = hitMode != 0 ? hits + 3 * (size_t)hitStart[(size_t)vi * chunks + chunk] : hits;
    for (int s = 0; s < sampleCount; s += 16) {
      PK_WORLD_DIRS(s);
      const float16 lw = vload16(0, dirsSoA + 3 * paddedCount + s);
      int16 live = (lane + s) < sampleCount;
      if (maskWords > 0) {  // only the rays glossy_gram found blocked can hit a surface
        live &= pk_lanes(blocked[(size_t)vi * maskWords + s / 16]);
        if (!pk_any(live)) continue;
      }
      int16 hitTri = (int16)(-1);
      float16 hitU = (float16)(0.0f), hitV = (float16)(0.0f);
      if (hitMode == 2) {  // the hits the first channel's launch kept, in the same order
        for (int j = 0; j < 16; ++j)
          if (((int*)&live)[j])
            ((int*)&hitTri)[j] = as_int(kept[0]), ((float*)&hitU)[j] = kept[1], ((float*)&hitV)[j] = kept[2], kept += 3;
      } else {
        bvh_packet_closest(nodes, tris, o, dx, dy, dz, tMax, live, &front, &hitTri, &hitU, &hitV);
        if (hitMode == 1)
          for (int j = 0; j < 16; ++j)
            if (((int*)&live)[j])
              kept[0] = as_float(((int*)&hitTri)[j]), kept[1] = ((float*)&hitU)[j], kept[2] = ((float*)&hitV)[j], kept += 3;
      }
      if (!pk_any(hitTri >= 0)) continue;
      // g_j = ρ_c(q) T_j(q) lane by lane (a gather), zero where the ray escaped.
      float16 g[IN_COUNT];
      for (int k = 0; k < IN_COUNT; ++k) g[k] = (float16)(0.0f);
      for (int j = 0; j < 16; ++j) {
        const int tri = ((int*)&hitTri)[j];
        if (tri < 0) continue;
        // Barycentrics may stray by BVH_EDGE_EPS outside the triangle: clamp, renormalise.
        float u = fmax(((float*)&hitU)[j], 0.0f), v = fmax(((float*)&hitV)[j], 0.0f);
        float w = fmax(1.0f - u - v, 0.0f);
        const float sum = u + v + w;
        u /= sum, v /= sum, w /= sum;
        const int4 idx = indices[tri];
        const float4 rho4 = albedo[idx.x] * w + albedo[idx.y] * u + albedo[idx.z] * v;
        const float rho = channel == 0 ? rho4.x : (channel == 1 ? rho4.y : rho4.z);
        __global const float* t0 = diffuse + ((size_t)idx.x * diffuseChannels + tc) * IN_COUNT;
        __global const float* t1 = diffuse + ((size_t)idx.y * diffuseChannels + tc) * IN_COUNT;
        __global const float* t2 = diffuse + ((size_t)idx.z * diffuseChannels + tc) * IN_COUNT;
        for (int k = 0; k < IN_COUNT; ++k) ((float*)&g[k])[j] = rho * (w * t0[k] + u * t1[k] + v * t2[k]);
      }
      float16 y[OUT_COUNT];
      sh_eval(OUT_ORDER, dx, dy, dz, y);
      const float16 wl = select((float16)(0.0f), lw, live);
      for (int i = 0; i < OUT_COUNT; ++i) {
        const float16 wy = wl * y[i];
        for (int j = 0; j < IN_COUNT; ++j) acc[i * IN_COUNT + j] = fma(wy, g[j], acc[i * IN_COUNT + j]);
      }
    }
  }
  for (int k = 0; k < OUT_COUNT * IN_COUNT; ++k) out[(size_t)vi * OUT_COUNT * IN_COUNT + k] = glossy_hsum(acc[k]);
#endif  // RAY_LANES
}
