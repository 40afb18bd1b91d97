// lightmap.cl: moving lightmap samples out of closed geometry (see prtbake/lightmap.h).
//
// A texel's sample p lies on its triangle; a floor texel under a wall has it inside the wall,
// where every ray it casts meets the wall's inside (back faces) and bakes black or leaks. As
// Godot's lightmapper's "unocclude" pass does, the sample casts UNOCCLUDE_RAYS rays in its
// tangent plane, as far as its reach (about a texel); if one meets a back face (the triangle's
// normal along the ray), the sample moves to the nearest such hit, ε past it along that face's
// normal: outside. If none does, one ray along its face normal tells whether it is buried: a
// back face above it, with no way out within its reach.
#include "bvh.clh"

#define UNOCCLUDE_RAYS 8

// count:    samples
// origins:  count × (p + ε g, reach): the sample ε above its face (g its face normal)
// frames:   count × 3 float4: tangent, bitangent, g
// nodes, tris: the binary BVH; tMax: the scene's ray length; eps: the offset ε
// faceNormals: triangles × (n, 0), unit, counter-clockwise
// corners:  triangles × 3 float4: the triangle's vertices (for the hit's distance)
// out:      count × (position, state): state 0 unchanged, 1 moved (position: the new one),
//           2 buried (position unchanged)
__kernel void lightmap_unocclude(int count, __global const float4* origins, __global const float4* frames,
                                 __global const BvhNode* nodes, __global const float4* tris, float tMax, float eps,
                                 __global const float4* faceNormals, __global const float4* corners,
                                 __global float4* out) {
  const int i = get_global_id(0);
  if (i >= count) return;
  const float3 o = origins[i].xyz;
  const float reach = origins[i].w;
  const float3 t = frames[3 * i].xyz, b = frames[3 * i + 1].xyz, g = frames[3 * i + 2].xyz;
  float best = reach;
  float3 moved = o;
  int found = 0;
  for (int k = 0; k < UNOCCLUDE_RAYS; ++k) {
    const float a = 2.0f * M_PI_F * (float)k / (float)UNOCCLUDE_RAYS;
    const float3 d = cos(a) * t + sin(a) * b;
    float u = 0.0f, v = 0.0f;
    const int tri = bvh_closest(nodes, tris, o, d, best, &u, &v);
    if (tri < 0) continue;
    const float3 n = faceNormals[tri].xyz;
    if (dot(n, d) <= 0.0f) continue;  // a front face: the sample is outside on this side
    const float3 w = bvh_hit_weights(u, v);
    const float3 hit = corners[3 * tri].xyz * w.x + corners[3 * tri + 1].xyz * w.y + corners[3 * tri + 2].xyz * w.z;
    const float dist = dot(hit - o, d);
    if (dist < best) {
      best = dist;
      moved = hit + n * eps;
      found = 1;
    }
  }
  int state = found;
  if (!found) {
    float u = 0.0f, v = 0.0f;
    const int tri = bvh_closest(nodes, tris, o, g, tMax, &u, &v);
    if (tri >= 0 && dot(faceNormals[tri].xyz, g) > 0.0f) state = 2;
  }
  out[i] = (float4)(moved, (float)state);
}
