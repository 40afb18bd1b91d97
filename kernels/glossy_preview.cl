// glossy_preview.cl: the mesh preview of glossy transfer, view-dependent (see
// host/include/prtbake/glossy.h, renderGlossyPreview).
//
// One camera ray per pixel through the BVH (as preview.cl). At the nearest hit, with
// barycentrics (1−u−v, u, v), the per-vertex transferred radiance t_v = M_v l (3 × OUT_COUNT,
// computed on the host for the rotated lighting) and the per-vertex hemisphere projection
// h_v = ĥ_l Y_lm(n_v) are interpolated, as a vertex shader's outputs would be. With the
// interpolated normal n (turned towards the eye), the view direction V and the reflected
// direction R = 2(n·V)n − V:
//   L_c = ρ_c Σ_lm ĝ_l t_c,lm Y_lm(R) / D,   D = Σ_lm ĝ_l h_lm Y_lm(R)   (normalised)
// D is what the lobe returns from an unoccluded vertex under a white sky, so the white
// furnace shows the albedo exactly, interpolation included; D = 1 when not normalised.
// Build options: OUT_ORDER, BG_ORDER, SH_BACKGROUND (as preview.cl).
#define BVH_EDGE_EPS 1e-4f
#include "sh.clh"
#include "bvh.clh"

#ifndef OUT_ORDER
#define OUT_ORDER 3
#endif
#ifndef BG_ORDER
#define BG_ORDER OUT_ORDER
#endif
#ifndef SH_BACKGROUND
#define SH_BACKGROUND 1
#endif
#define OUT_COUNT (OUT_ORDER * OUT_ORDER)
#define BG_COUNT (BG_ORDER * BG_ORDER)
#include "preview.clh"

// camera, nodes, tris, indices, albedo, background, rgb, hit: as preview_mesh (preview.cl)
// normals:     V × (x, y, z, 0) shading normals
// transferred: V × 3 × OUT_COUNT, t_v = M_v l per channel
// hemisphere:  V × OUT_COUNT, h_v
// lobe:        OUT_ORDER factors ĝ_l
// normalised:  1: divide by D
__kernel void preview_glossy(int width, int height, __global const float4* camera, __global const BvhNode* nodes,
                             __global const float4* tris, __global const int4* indices,
                             __global const float4* albedo, __global const float4* normals,
                             __global const float* transferred, __global const float* hemisphere,
                             __global const float* lobe, int normalised, __global const float* background,
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
    float3 n = bw * normals[idx.x].xyz + bu * normals[idx.y].xyz + bv * normals[idx.z].xyz;
    const float nl = length(n);
    n = nl > 0.0f ? n / nl : -d;
    const float3 view = -d;
    if (dot(n, view) < 0.0f) n = -n;
    const float3 r = 2.0f * dot(n, view) * n - view;
    float ylm[OUT_COUNT];
    sh_eval(OUT_ORDER, r.x, r.y, r.z, ylm);
    float norm = 1.0f;
    if (normalised) {
      float s = 0.0f;
      for (int l = 0; l < OUT_ORDER; ++l)
        for (int i = l * l; i < (l + 1) * (l + 1); ++i) {
          const float h = bw * hemisphere[(size_t)idx.x * OUT_COUNT + i] + bu * hemisphere[(size_t)idx.y * OUT_COUNT + i] +
                          bv * hemisphere[(size_t)idx.z * OUT_COUNT + i];
          s += lobe[l] * h * ylm[i];
        }
      norm = fmax(s, 1e-3f);
    }
    const float rhoc[3] = {rho.x, rho.y, rho.z};
    for (int ch = 0; ch < 3; ++ch) {
      float s = 0.0f;
      for (int l = 0; l < OUT_ORDER; ++l)
        for (int i = l * l; i < (l + 1) * (l + 1); ++i) {
          const float t = bw * transferred[((size_t)idx.x * 3 + ch) * OUT_COUNT + i] +
                          bu * transferred[((size_t)idx.y * 3 + ch) * OUT_COUNT + i] +
                          bv * transferred[((size_t)idx.z * 3 + ch) * OUT_COUNT + i];
          s += lobe[l] * t * ylm[i];
        }
      out[ch] = rhoc[ch] * s / norm;
    }
  } else {
    preview_background(d, background, out);
  }
  rgb[3 * (size_t)pixel] = out[0];
  rgb[3 * (size_t)pixel + 1] = out[1];
  rgb[3 * (size_t)pixel + 2] = out[2];
  hit[pixel] = tri;
}
