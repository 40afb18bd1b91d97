// probes.cl: SH radiance at points in space, one work-item per probe (see prtbake/probes.h).
//
// For probe p and its quadrature (ω_s, w_s) (host/src/probes/probes.cpp: Gauss–Legendre in
// cos θ × uniform φ, turned by the probe's rotation):
//   P_i^c ≈ Σ_s w_s Y_i(ω_s) L^c(p, ω_s),
// L the environment's SH radiance Σ_j l_j^c Y_j(ω) where the ray escapes, the hit surface's
// exit radiance (interpolated from its vertices) at a front face, 0 at a back face. The
// back faces' weight Σ_s w_s [back face] is returned too (validity, relocation).
//
// Build options: PROBE_ORDER (the probes' SH order), ENV_ORDER (≥ PROBE_ORDER: the
// environment's; the directions' SH are evaluated once to this order and the first
// PROBE_ORDER² serve the projection).
#include "sh.clh"
#include "bvh.clh"
#include "sampling.clh"

#ifndef PROBE_ORDER
#define PROBE_ORDER 3
#endif
#ifndef ENV_ORDER
#define ENV_ORDER 3
#endif
#define PROBE_COUNT (PROBE_ORDER * PROBE_ORDER)
#define ENV_COUNT (ENV_ORDER * ENV_ORDER)

// probeCount, sampleCount: probes and directions per probe
// origins:  probes × float4, the probes' positions
// frames:   probes × 3 float4, the columns of each probe's rotation (sampling.clh)
// dirs:     sampleCount × (x, y, z, w): the quadrature's directions and weights
// nodes, tris: the BVH; tMax: the rays' length
// env:      ENV_COUNT × (r, g, b, 0): the environment's radiance coefficients
// indices:  triangles × (i0, i1, i2, 0); faceNormals: triangles × (n, 0), counter-clockwise
// radiance: vertices × (r, g, b, 0), the surfaces' exit radiance (lit = 0: surfaces black)
// coeffs:   probes × PROBE_COUNT × 3 output, coefficient-major (i, then r g b)
// backface: probes output, the back faces' summed weight
__kernel void probes_trace(int probeCount, int sampleCount, __global const float4* origins,
                           __global const float4* frames, __global const float4* dirs,
                           __global const BvhNode* nodes, __global const float4* tris, float tMax,
                           __global const float4* env, __global const int4* indices,
                           __global const float4* faceNormals, __global const float4* radiance, int lit,
                           __global float* coeffs, __global float* backface) {
  const int pi = get_global_id(0);
  if (pi >= probeCount) return;
  __global const float4* frame = frames + (size_t)pi * 3;
  const float3 o = origins[pi].xyz;
  float3 acc[PROBE_COUNT];
  for (int k = 0; k < PROBE_COUNT; ++k) acc[k] = (float3)(0.0f);
  float back = 0.0f;
  for (int s = 0; s < sampleCount; ++s) {
    const float4 dl = dirs[s];
    const float3 d = sampling_to_world(frame, dl);
    float u = 0.0f, v = 0.0f;
    const int tri = bvh_closest(nodes, tris, o, d, tMax, &u, &v);
    float y[ENV_COUNT];
    sh_eval(ENV_ORDER, d.x, d.y, d.z, y);
    float3 L = (float3)(0.0f);
    if (tri < 0) {
      for (int j = 0; j < ENV_COUNT; ++j) L += env[j].xyz * y[j];
    } else if (dot(faceNormals[tri].xyz, d) > 0.0f) {
      back += dl.w;
      continue;
    } else if (lit) {
      u = fmax(u, 0.0f);
      v = fmax(v, 0.0f);
      float w = fmax(1.0f - u - v, 0.0f);
      const float sum = u + v + w;
      const int4 idx = indices[tri];
      L = (radiance[idx.x].xyz * w + radiance[idx.y].xyz * u + radiance[idx.z].xyz * v) / sum;
    }
    L *= dl.w;
    for (int k = 0; k < PROBE_COUNT; ++k) acc[k] += y[k] * L;
  }
  __global float* out = coeffs + (size_t)pi * PROBE_COUNT * 3;
  for (int k = 0; k < PROBE_COUNT; ++k) out[3 * k] = acc[k].x, out[3 * k + 1] = acc[k].y, out[3 * k + 2] = acc[k].z;
  backface[pi] = back;
}
