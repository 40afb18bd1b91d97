// transport.cl: per-vertex PRT transport in SH (see DESIGN.md, "Transport").
//
// For a vertex p with normal n,
//   T_i(p) = (1/π) ∫ V(p, ω) max(0, n·ω) Y_i(ω) dω.
// With N directions ω_s drawn with pdf cos θ/π over the hemisphere of n (sampling.clh)
// the 1/π and the cosine cancel against the pdf:
//   T_i(p) ≈ (1/N) Σ_s V(p, ω_s) Y_i(ω_s).
// Interreflection, bounce k → k+1 (ρ the albedo at the hit point q, T^(k)(q)
// interpolated with barycentrics):
//   T^(k+1)(p) = (1/π) ∫ ρ(q) T^(k)(q) max(0, n·ω) dω ≈ (1/N) Σ_{s hits q_s} ρ(q_s) T^(k)(q_s).
//
// Build options: SH_ORDER (1..8 or more), VISIBILITY (0: unshadowed, no BVH access;
// 1: shadowed), CHANNELS (1 grey, 3 RGB: bounce kernel only).
#include "sh.clh"
#include "bvh.clh"
#include "sampling.clh"

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

// Direct (bounce 0) transport, one work-item per vertex.
// vertexCount, sampleCount: V and N
// origins:  V × (x, y, z, 0), ray origins already offset along the geometric normal
// frames:   V × 3 float4 (t, b, n); n = 0 marks a vertex without a normal (zero output)
// dirs:     N × (x, y, z, 0) local cosine-distributed directions
// nodes, tris: the BVH (unused when VISIBILITY is 0)
// tMax:     ray length (beyond the scene's bounding box)
// coeffs:   V × SH_COUNT output, vertex-major
// visible:  V output, the fraction of unoccluded directions (for the error estimate)
__kernel void transport_direct(int vertexCount, int sampleCount, __global const float4* origins,
                               __global const float4* frames, __global const float4* dirs,
                               __global const BvhNode* nodes, __global const float4* tris, float tMax,
                               __global float* coeffs, __global float* visible) {
  const int vi = get_global_id(0);
  if (vi >= vertexCount) return;
  __global const float4* frame = frames + (size_t)vi * 3;
  float acc[SH_COUNT];
  for (int k = 0; k < SH_COUNT; ++k) acc[k] = 0.0f;
  int seen = 0;
  if (dot(frame[2].xyz, frame[2].xyz) > 0.0f) {
    const float3 o = origins[vi].xyz;
    for (int s = 0; s < sampleCount; ++s) {
      const float3 d = sampling_to_world(frame, dirs[s]);
#if VISIBILITY
      if (bvh_occluded(nodes, tris, o, d, tMax)) continue;
#endif
      ++seen;
      float y[SH_COUNT];
      sh_eval(SH_ORDER, d.x, d.y, d.z, y);
      for (int k = 0; k < SH_COUNT; ++k) acc[k] += y[k];
    }
  }
  const float invN = 1.0f / (float)sampleCount;
  for (int k = 0; k < SH_COUNT; ++k) coeffs[(size_t)vi * SH_COUNT + k] = acc[k] * invN;
  visible[vi] = (float)seen * invN;
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

// One interreflection bounce, one work-item per vertex.
// indices: T × (i0, i1, i2, 0) vertex indices of every mesh triangle
// albedo:  V × (r, g, b, 0) linear albedo (CHANNELS = 1 reads r)
// prev:    V × CHANNELS × SH_COUNT, the previous bounce T^(k)
// next:    V × CHANNELS × SH_COUNT output, T^(k+1)
__kernel void transport_bounce(int vertexCount, int sampleCount, __global const float4* origins,
                               __global const float4* frames, __global const float4* dirs,
                               __global const BvhNode* nodes, __global const float4* tris, float tMax,
                               __global const int4* indices, __global const float4* albedo,
                               __global const float* prev, __global float* next) {
  const int vi = get_global_id(0);
  if (vi >= vertexCount) return;
  __global const float4* frame = frames + (size_t)vi * 3;
  float acc[CHANNELS * SH_COUNT];
  for (int k = 0; k < CHANNELS * SH_COUNT; ++k) acc[k] = 0.0f;
  if (dot(frame[2].xyz, frame[2].xyz) > 0.0f) {
    const float3 o = origins[vi].xyz;
    for (int s = 0; s < sampleCount; ++s) {
      const float3 d = sampling_to_world(frame, dirs[s]);
      float u = 0.0f, v = 0.0f;
      const int tri = bvh_closest(nodes, tris, o, d, tMax, &u, &v);
      if (tri < 0) continue;
      // Barycentrics may stray by BVH_EDGE_EPS outside the triangle: clamp and renormalise.
      u = fmax(u, 0.0f);
      v = fmax(v, 0.0f);
      float w = fmax(1.0f - u - v, 0.0f);
      const float sum = u + v + w;
      u /= sum, v /= sum, w /= sum;
      const int4 idx = indices[tri];
      const float4 rho = albedo[idx.x] * w + albedo[idx.y] * u + albedo[idx.z] * v;
      __global const float* t0 = prev + (size_t)idx.x * CHANNELS * SH_COUNT;
      __global const float* t1 = prev + (size_t)idx.y * CHANNELS * SH_COUNT;
      __global const float* t2 = prev + (size_t)idx.z * CHANNELS * SH_COUNT;
      for (int c = 0; c < CHANNELS; ++c) {
        const float r = c == 0 ? rho.x : (c == 1 ? rho.y : rho.z);
        for (int k = 0; k < SH_COUNT; ++k) {
          const int j = c * SH_COUNT + k;
          acc[j] += r * (w * t0[j] + u * t1[j] + v * t2[j]);
        }
      }
    }
  }
  const float invN = 1.0f / (float)sampleCount;
  for (int k = 0; k < CHANNELS * SH_COUNT; ++k) next[(size_t)vi * CHANNELS * SH_COUNT + k] = acc[k] * invN;
}
