// preview.cl: the mesh preview, one camera ray per pixel through the transport BVH,
// shaded as a real-time engine shades baked PRT (docs/conventions.md, "Transport"):
//
//   nearest hit in triangle (a, b, c) at barycentrics (w, u, v), w = 1 − u − v;
//   T_i[ch] = w T_i[ch](a) + u T_i[ch](b) + v T_i[ch](c)     (interpolated transport)
//   ρ[ch]   = w ρ[ch](a)   + u ρ[ch](b)   + v ρ[ch](c)       (interpolated albedo)
//   L_o[ch] = ρ[ch] Σ_i l_i[ch] T_i[ch]                       (l: radiance coefficients)
//
// Grey transport (CHANNELS 1) serves the three colour channels. A ray that misses
// returns the SH reconstruction Σ_i l_i Y_i(d) of the environment in its direction d
// (SH_BACKGROUND 1, order BG_ORDER), or zero for the host to fill from a map.
//
// Build options: SH_ORDER (the transport's order), CHANNELS (1 or 3), BG_ORDER (the
// environment's order), SH_BACKGROUND (0 or 1).
// Camera rays come from afar (the eye is a few bounding radii away), where the float
// error of Möller–Trumbore's barycentrics grows to ~1e-5 on small triangles: with the
// transport's 1e-6 edge tolerance a ray through a shared vertex could slip between the
// triangles and show the far side. Rays start where they enter the root box, and edges
// get a 1e-4 tolerance (silhouettes grow by 1e-4 of a triangle, invisible).
#define BVH_EDGE_EPS 1e-4f
#include "sh.clh"
#include "bvh.clh"

#ifndef SH_ORDER
#define SH_ORDER 3
#endif
#ifndef CHANNELS
#define CHANNELS 1
#endif
#ifndef BG_ORDER
#define BG_ORDER SH_ORDER
#endif
#ifndef SH_BACKGROUND
#define SH_BACKGROUND 1
#endif
#define SH_COUNT (SH_ORDER * SH_ORDER)
#define BG_COUNT (BG_ORDER * BG_ORDER)
#include "preview.clh"

// width, height: image size; pixel (x, y) = work-item y·width + x, row 0 on top
// camera:    4 float4: (eye, scene radius), forward (unit), right × tan(hfov/2), up × tan(vfov/2)
// nodes, tris: the BVH (bvh_types.h)
// indices:   T × (i0, i1, i2, 0) vertex indices of every mesh triangle
// albedo:    V × (r, g, b, 0) linear albedo
// transport: V × CHANNELS × SH_COUNT, vertex-major
// light:     3 × SH_COUNT radiance coefficients, channel-major (zero beyond the env's order)
// background: 3 × BG_COUNT radiance coefficients, channel-major (the whole environment)
// rgb:       width × height × 3 output, linear radiance
// hit:       width × height output, the mesh triangle seen or −1
__kernel void preview_mesh(int width, int height, __global const float4* camera, __global const BvhNode* nodes,
                           __global const float4* tris, __global const int4* indices,
                           __global const float4* albedo, __global const float* transport,
                           __global const float* light, __global const float* background,
                           __global float* rgb, __global int* hit) {
  const int pixel = (int)get_global_id(0);
  if (pixel >= width * height) return;
  float3 d;
  float bu, bv;
  const int tri = preview_hit(pixel, width, height, camera, nodes, tris, &d, &bu, &bv);
  float out[3] = {0.0f, 0.0f, 0.0f};
  if (tri >= 0) {
    const int4 idx = indices[tri];
    const float bw = 1.0f - bu - bv;
    const float3 rho = bw * albedo[idx.x].xyz + bu * albedo[idx.y].xyz + bv * albedo[idx.z].xyz;
    const float rhoc[3] = {rho.x, rho.y, rho.z};
    __global const float* ta = transport + (size_t)idx.x * (CHANNELS * SH_COUNT);
    __global const float* tb = transport + (size_t)idx.y * (CHANNELS * SH_COUNT);
    __global const float* tc = transport + (size_t)idx.z * (CHANNELS * SH_COUNT);
    for (int ch = 0; ch < 3; ++ch) {
      const int o = (CHANNELS == 3 ? ch : 0) * SH_COUNT;
      float sum = 0.0f;
      for (int i = 0; i < SH_COUNT; ++i) {
        const float t = bw * ta[o + i] + bu * tb[o + i] + bv * tc[o + i];
        sum += light[ch * SH_COUNT + i] * t;
      }
      out[ch] = rhoc[ch] * sum;
    }
  } else {
    preview_background(d, background, out);
  }
  rgb[3 * (size_t)pixel] = out[0];
  rgb[3 * (size_t)pixel + 1] = out[1];
  rgb[3 * (size_t)pixel + 2] = out[2];
  hit[pixel] = tri;
}
