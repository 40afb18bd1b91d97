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
// PROBE_ORDER² serve the projection), BVH_PACKET (0: one ray at a time over the binary BVH;
// 16: the packet kernel over the wide one, a probe's rays 16 at a time), RAY_LANES (the
// one-ray kernel's work-items per probe: lanes.clh).
#ifndef BVH_PACKET
#define BVH_PACKET 0
#endif
#if BVH_PACKET
#define PK_CAT2(a, b) a##b
#define PK_CAT(a, b) PK_CAT2(a, b)
#define SH_T PK_CAT(float, BVH_PACKET)
#endif
#include "sh.clh"
#include "bvh.clh"
#include "sampling.clh"
#include "lanes.clh"

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
// red:      the lane form's local memory (RAY_LANES > 1; lanes.clh), a float per work-item
#if !BVH_PACKET
__kernel void probes_trace(int probeCount, int sampleCount, __global const float4* origins,
                           __global const float4* frames, __global const float4* dirs,
                           __global const BvhNode* nodes, __global const float4* tris, float tMax,
                           __global const float4* env, __global const int4* indices,
                           __global const float4* faceNormals, __global const float4* radiance, int lit,
                           __global float* coeffs, __global float* backface, __local float* red) {
  const int pi = get_global_id(0) / RAY_LANES, lane = get_global_id(0) % RAY_LANES;
#if RAY_LANES == 1
  if (pi >= probeCount) return;
#endif
  const bool active = pi < probeCount;  // the lane form's part-filled last group: no rays, no output
  __global const float4* frame = frames + (size_t)(active ? pi : 0) * 3;
  const float3 o = origins[active ? pi : 0].xyz;
  float3 acc[PROBE_COUNT];
  for (int k = 0; k < PROBE_COUNT; ++k) acc[k] = (float3)(0.0f);
  float back = 0.0f;
  for (int s = lane; active && s < sampleCount; s += RAY_LANES) {
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
      const float3 bw = bvh_hit_weights(u, v);
      const int4 idx = indices[tri];
      L = radiance[idx.x].xyz * bw.x + radiance[idx.y].xyz * bw.y + radiance[idx.z].xyz * bw.z;
    }
    L *= dl.w;
    for (int k = 0; k < PROBE_COUNT; ++k) acc[k] += y[k] * L;
  }
  __global float* out = coeffs + (size_t)pi * PROBE_COUNT * 3;
  for (int k = 0; k < PROBE_COUNT; ++k) {
    const float r = lanes_sum(acc[k].x, red), g = lanes_sum(acc[k].y, red), b = lanes_sum(acc[k].z, red);
    if (active && lane == 0) out[3 * k] = r, out[3 * k + 1] = g, out[3 * k + 2] = b;
  }
  back = lanes_sum(back, red);
  if (active && lane == 0) backface[pi] = back;
}

#else  // BVH_PACKET

#include "bvh_packet.clh"

// Packet form of probes_trace: a probe's rays BVH_PACKET at a time from its frontier (every
// child box around it: no plane culls a sphere of directions), the SH and the environment
// evaluated on the vectors, the hit lanes' surfaces one lane at a time.
// dirsSoA: 4 rows of paddedCount floats (x, y, z, weight; padding lanes weigh 0).
// backStop: a probe stops tracing once its back faces weigh more (it is inside geometry and
//           its coefficients will not be used: relocated or filled); a larger value never stops.
__kernel void probes_trace_packet(int probeCount, int sampleCount, __global const float4* origins,
                                  __global const float4* frames, __global const float* dirsSoA,
                                  __global const Bvh4Node* nodes, __global const float4* tris, float tMax,
                                  __global const float4* env, __global const int4* indices,
                                  __global const float4* faceNormals, __global const float4* radiance, int lit,
                                  __global float* coeffs, __global float* backface, int paddedCount, float backStop) {
  const int pi = get_global_id(0);
  if (pi >= probeCount) return;
  __global const float4* frame = frames + (size_t)pi * 3;
  const float3 t = frame[0].xyz, b = frame[1].xyz, n = frame[2].xyz;
  const float3 o = origins[pi].xyz;
  floatP accR[PROBE_COUNT], accG[PROBE_COUNT], accB[PROBE_COUNT];
  for (int k = 0; k < PROBE_COUNT; ++k) accR[k] = accG[k] = accB[k] = (floatP)(0.0f);
  float back = 0.0f;
  PkFrontier front;
  pk_frontier(nodes, tris, o, (float3)(0.0f), tMax, &front);
  for (int s = 0; s < sampleCount && back <= backStop; s += BVH_PACKET) {
    const floatP lx = PK_CAT(vload, BVH_PACKET)(0, dirsSoA + s);
    const floatP ly = PK_CAT(vload, BVH_PACKET)(0, dirsSoA + paddedCount + s);
    const floatP lz = PK_CAT(vload, BVH_PACKET)(0, dirsSoA + 2 * paddedCount + s);
    const floatP w = PK_CAT(vload, BVH_PACKET)(0, dirsSoA + 3 * paddedCount + s);
    const floatP dx = t.x * lx + b.x * ly + n.x * lz;
    const floatP dy = t.y * lx + b.y * ly + n.y * lz;
    const floatP dz = t.z * lx + b.z * ly + n.z * lz;
    const intP live = w > 0.0f;
    intP hitTri;
    floatP hitU, hitV;
    bvh_packet_closest(nodes, tris, o, dx, dy, dz, tMax, live, &front, &hitTri, &hitU, &hitV);
    floatP y[ENV_COUNT];
    sh_eval(ENV_ORDER, dx, dy, dz, y);
    floatP r = (floatP)(0.0f), g = (floatP)(0.0f), bl = (floatP)(0.0f);
    for (int j = 0; j < ENV_COUNT; ++j) r += env[j].x * y[j], g += env[j].y * y[j], bl += env[j].z * y[j];
    const intP miss = hitTri < 0;
    r = select((floatP)(0.0f), r, miss), g = select((floatP)(0.0f), g, miss), bl = select((floatP)(0.0f), bl, miss);
    if (pk_any(~miss & live)) {
      for (int j = 0; j < BVH_PACKET; ++j) {
        const int tri = ((int*)&hitTri)[j];
        if (tri < 0 || !((int*)&live)[j]) continue;
        const float3 d = (float3)(((float*)&dx)[j], ((float*)&dy)[j], ((float*)&dz)[j]);
        if (dot(faceNormals[tri].xyz, d) > 0.0f) {
          back += ((float*)&w)[j];
          continue;
        }
        if (!lit) continue;
        const float3 bw = bvh_hit_weights(((float*)&hitU)[j], ((float*)&hitV)[j]);
        const int4 idx = indices[tri];
        const float3 L = radiance[idx.x].xyz * bw.x + radiance[idx.y].xyz * bw.y + radiance[idx.z].xyz * bw.z;
        ((float*)&r)[j] = L.x, ((float*)&g)[j] = L.y, ((float*)&bl)[j] = L.z;
      }
    }
    r *= w, g *= w, bl *= w;
    for (int k = 0; k < PROBE_COUNT; ++k) accR[k] += y[k] * r, accG[k] += y[k] * g, accB[k] += y[k] * bl;
  }
  __global float* out = coeffs + (size_t)pi * PROBE_COUNT * 3;
  for (int k = 0; k < PROBE_COUNT; ++k)
    out[3 * k] = pk_sumf(accR[k]), out[3 * k + 1] = pk_sumf(accG[k]), out[3 * k + 2] = pk_sumf(accB[k]);
  backface[pi] = back;
}

#endif  // BVH_PACKET
