// transport.cl: per-vertex PRT transport in SH (see docs/conventions.md, "Transport").
//
// For a vertex p with normal n,
//   T_i(p) = (1/π) ∫ V(p, ω) max(0, n·ω) Y_i(ω) dω.
// With N directions ω_s drawn with pdf cos θ/π over the hemisphere of n (sampling.clh)
// the 1/π and the cosine cancel against the pdf:
//   T_i(p) ≈ (1/N) Σ_s V(p, ω_s) Y_i(ω_s).
// Interreflection, bounce k → k+1 (ρ the albedo at the hit point q, T^(k)(q)
// interpolated with barycentrics):
//   T^(k+1)(p) = (1/π) ∫ ρ(q) T^(k)(q) max(0, n·ω) dω ≈ (1/N) Σ_{s hits q_s} ρ(q_s) T^(k)(q_s).
// Every kernel returns the sums Σ_s over the directions it was given (at most 1024 per
// launch); the host adds the launches up in double and divides by N, so that float
// sums over millions of samples do not lose precision.
//
// Build options: SH_ORDER (1..8 or more), VISIBILITY (0: unshadowed, no BVH access;
// 1: shadowed), CHANNELS (1 grey, 3 RGB: bounce kernel only), BVH_PACKET (0: the
// scalar kernels below; 8 or 16: the packet kernels after them instead, which evaluate
// SH on float8/float16 directions; transport_gather, at the end, in both), RAY_LANES (the
// scalar kernels' work-items per vertex: 1, 2, 4, 8, 16 or 32; lanes.clh).
#ifndef BVH_PACKET
#define BVH_PACKET 0
#endif
#if BVH_PACKET
#define SH_T PK_CAT(float, BVH_PACKET)
#define PK_CAT2(a, b) a##b
#define PK_CAT(a, b) PK_CAT2(a, b)
#endif
#include "sh.clh"
#include "bvh.clh"
#include "sampling.clh"
#include "lanes.clh"

#ifndef SH_ORDER
#define SH_ORDER 3
#endif
#ifndef VISIBILITY
#define VISIBILITY 1
#endif
#ifndef CHANNELS
#define CHANNELS 1
#endif
#define SH_COUNT (SH_ORDER * SH_ORDER)
// Per-coefficient loops of the packet kernels are unrolled up to order 8, so their
// accumulators stay in registers instead of a load, add and store per coefficient.
#if SH_ORDER <= 8
#define UNROLL _Pragma("unroll")
#else
#define UNROLL
#endif

// Adds ρ(q) T^(k)(q) at the hit (tri, u, v) to acc (tri < 0: no hit). Barycentrics may
// stray by BVH_EDGE_EPS outside the triangle: clamped and renormalised.
static inline void bounce_gather(int tri, float u, float v, __global const int4* indices, __global const float4* albedo,
                                 __global const float* prev, float* acc) {
  if (tri < 0) return;
  const float3 bw = bvh_hit_weights(u, v);
  const float w = bw.x;
  u = bw.y, v = bw.z;
  const int4 idx = indices[tri];
  const float4 rho = albedo[idx.x] * w + albedo[idx.y] * u + albedo[idx.z] * v;
  __global const float* t0 = prev + (size_t)idx.x * CHANNELS * SH_COUNT;
  __global const float* t1 = prev + (size_t)idx.y * CHANNELS * SH_COUNT;
  __global const float* t2 = prev + (size_t)idx.z * CHANNELS * SH_COUNT;
  for (int c = 0; c < CHANNELS; ++c) {
    const float r = c == 0 ? rho.x : (c == 1 ? rho.y : rho.z);
    for (int k = 0; k < SH_COUNT; ++k) {
      const int m = c * SH_COUNT + k;
      acc[m] += r * (w * t0[m] + u * t1[m] + v * t2[m]);
    }
  }
}

#if !BVH_PACKET

// Direct (bounce 0) transport, one vertex to RAY_LANES work-items.
// vertexCount, sampleCount: V and N
// origins:  V × (x, y, z, w), ray origins already offset along the geometric normal;
//           w = 1 marks a vertex whose hemisphere no triangle can reach (transport.h,
//           unoccludableVertices): the direct kernels trace no rays for it, so one
//           launch serves both kinds of vertex. w = 0 otherwise.
// frames:   V × 3 float4 (t, b, n); n = 0 marks a vertex without a normal (zero output)
// dirs:     N × (x, y, z, 0) local cosine-distributed directions
// nodes, tris: the BVH (unused when VISIBILITY is 0)
// tMax:     ray length (beyond the scene's bounding box)
// coeffs:   V × SH_COUNT output, vertex-major: Σ_s V(p, ω_s) Y_i(ω_s)
// visible:  V output, the number of unoccluded directions (for the error estimate)
// blocked:  when maskWords > 0, V × maskWords words, bit s % 16 of word s / 16 set where ray s
//           is blocked, written for every vertex (for the bounces, which trace the same rays:
//           transport_bounce)
// red, bits: local memory of the lane form (RAY_LANES > 1; unused otherwise): a float per
//           work-item, and LANES_LAUNCH_UINTS uints per vertex of the group (lanes.clh).
__kernel void transport_direct(int vertexCount, int sampleCount, __global const float4* origins,
                               __global const float4* frames, __global const float4* dirs,
                               __global const BvhNode* nodes, __global const float4* tris, float tMax,
                               __global float* coeffs, __global float* visible, __global ushort* blocked,
                               int maskWords, __local float* red, __local uint* bits) {
  const int vi = get_global_id(0) / RAY_LANES, lane = get_global_id(0) % RAY_LANES;
#if RAY_LANES == 1
  if (vi >= vertexCount) return;
#endif
  const bool active = vi < vertexCount;  // the lane form's part-filled last group: no rays, no output
  __global const float4* frame = frames + (size_t)(active ? vi : 0) * 3;
  float acc[SH_COUNT];
  for (int k = 0; k < SH_COUNT; ++k) acc[k] = 0.0f;
  int seen = 0;
#if RAY_LANES > 1
  __local uint* mine = bits + get_local_id(0) / RAY_LANES * LANES_LAUNCH_UINTS;  // this vertex's rays
  lanes_mask_clear(mine, lane);
  barrier(CLK_LOCAL_MEM_FENCE);  // unconditional, as in lanes_sum
#endif
  if (active && dot(frame[2].xyz, frame[2].xyz) > 0.0f) {
    const float3 o = origins[vi].xyz;
    const bool trace = origins[vi].w == 0.0f;
#if RAY_LANES == 1
    uint word = 0;  // the blocked rays of the current mask word
#endif
    for (int s = lane; s < sampleCount; s += RAY_LANES) {
      const float3 d = sampling_to_world(frame, dirs[s]);
#if VISIBILITY
      const bool hit = trace && bvh_occluded(nodes, tris, o, d, tMax);
#if RAY_LANES > 1
      if (hit && maskWords > 0) atomic_or(mine + s / 32, 1u << (s % 32));
#else
      word |= (uint)hit << (s % LANES_MASK_BITS);
      if (maskWords > 0 && (s % LANES_MASK_BITS == LANES_MASK_BITS - 1 || s == sampleCount - 1)) {
        blocked[(size_t)vi * maskWords + s / LANES_MASK_BITS] = (ushort)word;
        word = 0;
      }
#endif
      if (hit) continue;
#endif
      ++seen;
      float y[SH_COUNT];
      sh_eval(SH_ORDER, d.x, d.y, d.z, y);
      for (int k = 0; k < SH_COUNT; ++k) acc[k] += y[k];
    }
  } else if (RAY_LANES == 1) {
    for (int w = 0; w < maskWords; ++w) blocked[(size_t)vi * maskWords + w] = 0;  // no normal: no rays
  }
#if RAY_LANES > 1
  barrier(CLK_LOCAL_MEM_FENCE);  // every lane's bits are in
  if (active) lanes_mask_store(mine, blocked + (size_t)vi * maskWords, lane, maskWords);
#endif
  for (int k = 0; k < SH_COUNT; ++k) {
    const float sum = lanes_sum(acc[k], red);
    if (active && lane == 0) coeffs[(size_t)vi * SH_COUNT + k] = sum;
  }
  const float total = lanes_sum((float)seen, red);
  if (active && lane == 0) visible[vi] = total;
}

// Visibility of every (vertex, sample) ray, for the kernel-vs-reference tests.
// out: V × N bytes, 1 = unoccluded.
__kernel void transport_visibility(int vertexCount, int sampleCount, __global const float4* origins,
                                   __global const float4* frames, __global const float4* dirs,
                                   __global const BvhNode* nodes, __global const float4* tris, float tMax,
                                   __global uchar* out) {
  const int vi = get_global_id(0);
  if (vi >= vertexCount) return;
  __global const float4* frame = frames + (size_t)vi * 3;
  const float3 o = origins[vi].xyz;
  for (int s = 0; s < sampleCount; ++s) {
    const float3 d = sampling_to_world(frame, dirs[s]);
    out[(size_t)vi * sampleCount + s] = bvh_occluded(nodes, tris, o, d, tMax) ? 0 : 1;
  }
}


// One interreflection bounce, one vertex to RAY_LANES work-items as in transport_direct
// (no rays for a vertex that no triangle can reach: origin w = 1, as there).
// indices: T × (i0, i1, i2, 0) vertex indices of every mesh triangle
// albedo:  V × (r, g, b, 0) linear albedo (CHANNELS = 1 reads r)
// prev:    V × CHANNELS × SH_COUNT, the previous bounce T^(k)
// next:    V × CHANNELS × SH_COUNT output, the sums of T^(k+1)
// blocked, maskWords: when maskWords > 0, the direct term's blocked rays (transport_direct) of
//          these same rays: the others hit nothing and are not traced.
// hits, hitStart, chunks, chunk: when chunks > 0 (with the masks), the hits of the traced
//          rays are also written (tri as int bits, u, v: 3 floats each), those of this vertex
//          and launch (of `chunks`) in sample order from hits + 3 · hitStart[vertex · chunks +
//          chunk], for transport_gather.
// red:     as transport_direct's.
__kernel void transport_bounce(int vertexCount, int sampleCount, __global const float4* origins,
                               __global const float4* frames, __global const float4* dirs,
                               __global const BvhNode* nodes, __global const float4* tris, float tMax,
                               __global const int4* indices, __global const float4* albedo,
                               __global const float* prev, __global float* next, __global const ushort* blocked,
                               int maskWords, __global float* hits, __global const int* hitStart, int chunks,
                               int chunk, __local float* red) {
  const int vi = get_global_id(0) / RAY_LANES, lane = get_global_id(0) % RAY_LANES;
#if RAY_LANES == 1
  if (vi >= vertexCount) return;
#endif
  const bool active = vi < vertexCount;
  __global const float4* frame = frames + (size_t)(active ? vi : 0) * 3;
  float acc[CHANNELS * SH_COUNT];
  for (int k = 0; k < CHANNELS * SH_COUNT; ++k) acc[k] = 0.0f;
  if (active && dot(frame[2].xyz, frame[2].xyz) > 0.0f && origins[vi].w == 0.0f) {  // w = 1: nothing in reach
    const float3 o = origins[vi].xyz;
    __global float* out = chunks > 0 ? hits + 3 * (size_t)hitStart[(size_t)vi * chunks + chunk] : hits;
    // Steps of RAY_LANES rays s0 … s0 + RAY_LANES − 1 (within one mask word, or two whole ones),
    // lane j taking s0 + j; `before` counts the blocked rays before s0.
    int before = 0;
    for (int s0 = 0; s0 < sampleCount; s0 += RAY_LANES) {
      const int s = s0 + lane;
      uint step = 0xffffffffu >> (32 - RAY_LANES);  // the step's rays to trace
      if (maskWords > 0) {
        step = lanes_mask_step(blocked + (size_t)vi * maskWords, s0, maskWords);
        if (step == 0) continue;  // no blocked ray in this step (the whole vertex skips it)
      }
      const int rank = before + popcount(step & ((1u << lane) - 1u));
      before += popcount(step);
      if (s >= sampleCount || !((step >> lane) & 1u)) continue;
      const float3 d = sampling_to_world(frame, dirs[s]);
      float u = 0.0f, v = 0.0f;
      const int tri = bvh_closest(nodes, tris, o, d, tMax, &u, &v);
      if (chunks > 0) out[3 * rank] = as_float(tri), out[3 * rank + 1] = u, out[3 * rank + 2] = v;
      bounce_gather(tri, u, v, indices, albedo, prev, acc);
    }
  }
  for (int k = 0; k < CHANNELS * SH_COUNT; ++k) {
    const float sum = lanes_sum(acc[k], red);
    if (active && lane == 0) next[(size_t)vi * CHANNELS * SH_COUNT + k] = sum;
  }
}

#else  // BVH_PACKET

#include "bvh_packet.clh"

// Packet form of transport_direct: the N samples of a vertex go through the BVH
// BVH_PACKET at a time (sampleCount padded up; the padding lanes are dead).
// dirsSoA: 3 × paddedCount floats, local x then y then z (structure of arrays).
// blocked: when maskWords > 0, V × maskWords (= paddedCount / BVH_PACKET) words, one per
//          packet, with bit j set where the packet's ray j is blocked, written for every
//          vertex (for the bounces, which trace the same rays: transport_bounce_packet).
// Other arguments as transport_direct; outputs identical up to float summation order.
__kernel void transport_direct_packet(int vertexCount, int sampleCount, __global const float4* origins,
                                      __global const float4* frames, __global const float* dirsSoA,
                                      __global const Bvh4Node* nodes, __global const float4* tris, float tMax,
                                      __global float* coeffs, __global float* visible, int paddedCount,
                                      __global ushort* blocked, int maskWords) {
  const int vi = get_global_id(0);
  if (vi >= vertexCount) return;
  __global const float4* frame = frames + (size_t)vi * 3;
  floatP acc[SH_COUNT];
  UNROLL
  for (int k = 0; k < SH_COUNT; ++k) acc[k] = (floatP)(0.0f);
  intP seen = (intP)(0);
  const float3 t = frame[0].xyz, b = frame[1].xyz, n = frame[2].xyz;
  if (dot(n, n) > 0.0f) {
    const float3 o = origins[vi].xyz;
    const bool trace = origins[vi].w == 0.0f;
#if VISIBILITY
    PkFrontier front;
    if (trace) pk_frontier(nodes, tris, o, n, tMax, &front);
#endif
    const intP lane = PK_LANE_INDEX;
    for (int s = 0; s < sampleCount; s += BVH_PACKET) {
      PK_WORLD_DIRS(s);
      intP live = (lane + s) < sampleCount;
#if VISIBILITY
      const intP hit = trace ? bvh_packet_occluded(nodes, tris, o, dx, dy, dz, tMax, live, &front) : (intP)(0);
      live &= ~hit;
      if (maskWords > 0) blocked[(size_t)vi * maskWords + s / BVH_PACKET] = (ushort)pk_bits(hit);
#endif
      seen -= live;  // live lanes are −1
      floatP y[SH_COUNT];
      sh_eval(SH_ORDER, dx, dy, dz, y);
      UNROLL
      for (int k = 0; k < SH_COUNT; ++k) acc[k] += select((floatP)(0.0f), y[k], live);
    }
  } else {
    for (int w = 0; w < maskWords; ++w) blocked[(size_t)vi * maskWords + w] = 0;  // no normal: no rays
  }
  // Fixed-order horizontal sums: deterministic.
  for (int k = 0; k < SH_COUNT; ++k) {
    float sum = 0.0f;
    for (int j = 0; j < BVH_PACKET; ++j) sum += ((float*)&acc[k])[j];
    coeffs[(size_t)vi * SH_COUNT + k] = sum;
  }
  int total = 0;
  for (int j = 0; j < BVH_PACKET; ++j) total += ((int*)&seen)[j];
  visible[vi] = (float)total;
}

// Packet form of transport_visibility (the production visibility, for the tests).
__kernel void transport_visibility_packet(int vertexCount, int sampleCount, __global const float4* origins,
                                          __global const float4* frames, __global const float* dirsSoA,
                                          __global const Bvh4Node* nodes, __global const float4* tris,
                                          float tMax, __global uchar* out, int paddedCount) {
  const int vi = get_global_id(0);
  if (vi >= vertexCount) return;
  __global const float4* frame = frames + (size_t)vi * 3;
  const float3 t = frame[0].xyz, b = frame[1].xyz, n = frame[2].xyz;
  const float3 o = origins[vi].xyz;
  PkFrontier front;
  pk_frontier(nodes, tris, o, n, tMax, &front);
  for (int s = 0; s < sampleCount; s += BVH_PACKET) {
    PK_WORLD_DIRS(s);
    const intP blocked = bvh_packet_occluded(nodes, tris, o, dx, dy, dz, tMax, (intP)(-1), &front);
    for (int j = 0; j < BVH_PACKET && s + j < sampleCount; ++j)
      out[(size_t)vi * sampleCount + s + j] = ((int*)&blocked)[j] ? 0 : 1;
  }
}

// Packet form of transport_bounce: closest hits BVH_PACKET at a time, then the gather
// (bounce_gather) lane by lane. Arguments as transport_bounce, with dirsSoA and paddedCount as
// in transport_direct_packet. A vertex that no triangle can reach (origin w = 1) sees
// nothing. blocked, maskWords: when maskWords > 0, the direct term's blocked rays
// (transport_direct_packet) of these same rays: the others hit nothing and are not
// traced. hits, hitStart, chunks, chunk: when chunks > 0, the hits of the traced rays
// are also written (tri as int bits, u, v: 3 floats each), those of this vertex and
// launch (of `chunks`) in lane order from hits + 3 · hitStart[vertex · chunks + chunk],
// for transport_gather.
__kernel void transport_bounce_packet(int vertexCount, int sampleCount, __global const float4* origins,
                                      __global const float4* frames, __global const float* dirsSoA,
                                      __global const Bvh4Node* nodes, __global const float4* tris, float tMax,
                                      __global const int4* indices, __global const float4* albedo,
                                      __global const float* prev, __global float* next, int paddedCount,
                                      __global const ushort* blocked, int maskWords, __global float* hits,
                                      __global const int* hitStart, int chunks, int chunk) {
  const int vi = get_global_id(0);
  if (vi >= vertexCount) return;
  __global const float4* frame = frames + (size_t)vi * 3;
  float acc[CHANNELS * SH_COUNT];
  for (int k = 0; k < CHANNELS * SH_COUNT; ++k) acc[k] = 0.0f;
  const float3 t = frame[0].xyz, b = frame[1].xyz, n = frame[2].xyz;
  if (dot(n, n) > 0.0f && origins[vi].w == 0.0f) {
    const float3 o = origins[vi].xyz;
    PkFrontier front;
    pk_frontier(nodes, tris, o, n, tMax, &front);
    const intP lane = PK_LANE_INDEX;
    __global float* out = chunks > 0 ? hits + 3 * (size_t)hitStart[(size_t)vi * chunks + chunk] : hits;
    for (int s = 0; s < sampleCount; s += BVH_PACKET) {
      intP live = (lane + s) < sampleCount;
      if (maskWords > 0) {
        live &= pk_lanes(blocked[(size_t)vi * maskWords + s / BVH_PACKET]);
        if (!pk_any(live)) continue;
      }
      PK_WORLD_DIRS(s);
      intP hitTri;
      floatP hitU, hitV;
      bvh_packet_closest(nodes, tris, o, dx, dy, dz, tMax, live, &front, &hitTri, &hitU, &hitV);
      for (int j = 0; j < BVH_PACKET; ++j) {
        if (!((int*)&live)[j]) continue;
        const int tri = ((int*)&hitTri)[j];
        const float u = ((float*)&hitU)[j], v = ((float*)&hitV)[j];
        if (chunks > 0) out[0] = as_float(tri), out[1] = u, out[2] = v, out += 3;
        bounce_gather(tri, u, v, indices, albedo, prev, acc);
      }
    }
  }
  for (int k = 0; k < CHANNELS * SH_COUNT; ++k) next[(size_t)vi * CHANNELS * SH_COUNT + k] = acc[k];
}

#endif  // BVH_PACKET

// A bounce from the hits that transport_bounce or transport_bounce_packet wrote for launch
// `chunk` (the same rays in the same order, so the same sums; against the lane form's tree of
// sums, the same up to float rounding): no tracing. Arguments as there.
__kernel void transport_gather(int vertexCount, __global const float* hits, __global const int* hitStart, int chunks,
                               int chunk, __global const int4* indices, __global const float4* albedo,
                               __global const float* prev, __global float* next) {
  const int vi = get_global_id(0);
  if (vi >= vertexCount) return;
  float acc[CHANNELS * SH_COUNT];
  for (int k = 0; k < CHANNELS * SH_COUNT; ++k) acc[k] = 0.0f;
  const int first = hitStart[(size_t)vi * chunks + chunk], last = hitStart[(size_t)vi * chunks + chunk + 1];
  for (int h = first; h < last; ++h)
    bounce_gather(as_int(hits[3 * (size_t)h]), hits[3 * (size_t)h + 1], hits[3 * (size_t)h + 2], indices, albedo, prev, acc);
  for (int k = 0; k < CHANNELS * SH_COUNT; ++k) next[(size_t)vi * CHANNELS * SH_COUNT + k] = acc[k];
}
