// bvh_types.h: POD structs shared by the host (C++) and the kernels (OpenCL C).
//
// No float3 (16 bytes on the device, 12 on the host): every vector is spelled out
// as scalars or packed into float4 by the code that uploads it. The host checks the
// sizes with static_assert (host/src/geometry/bvh.cpp).
#ifndef PRTBAKE_BVH_TYPES_H
#define PRTBAKE_BVH_TYPES_H

// One node of the flattened, depth-first binary BVH (32 bytes, as pbrt's LinearBVHNode).
//   inner node: count = −(1 + split axis) < 0 (0 = x, 1 = y, 2 = z), the left
//               child (lower coordinates along the axis) is the next node
//               (index + 1) and `offset` is the index of the right child;
//   leaf:       count > 0 triangles starting at `offset` in the leaf-ordered
//               triangle arrays.
typedef struct {
  float minX, minY, minZ;
  int offset;
  float maxX, maxY, maxZ;
  int count;
} BvhNode;

// One node of the 4-wide BVH the packet kernels traverse (128 bytes), collapsed from
// the binary one (host/src/geometry/bvh.cpp): child slot i holds its box in lane i of the six
// float4 (min x, min y, min z, max x, max y, max z) and
//   count[i] > 0:  a leaf of count[i] triangles in blocks from block child[i] (below);
//   count[i] = −1: an empty slot, whose box (min = +1e30, max = −1e30) no ray enters;
//   count[i] ≤ −2: an inner node, child[i] its index in the wide array, and −2 − count[i]
//                  the first block of that node's own leaves (0 if it has none), so that
//                  a traversal entering it can start fetching them with the node.
typedef struct {
  float minX[4], minY[4], minZ[4], maxX[4], maxY[4], maxZ[4];
  int child[4];
  int count[4];
} Bvh4Node;

// Triangles in leaf order, for the Möller–Trumbore test: three float4 per
// triangle, (v0, id), (e1 = v1 - v0, 0), (e2 = v2 - v0, 0), where `id` is the
// index of the triangle in the mesh, stored bit-for-bit as an int (as_int on
// the device, memcpy on the host).
#define BVH_TRI_FLOAT4S 3

// The wide tree's leaf triangles, BVH_BLOCK at a time as a structure of arrays: ten float4
// per block, v0.x, v0.y, v0.z, e1.x, e1.y, e1.z, e2.x, e2.y, e2.z, id (as int bits), lane i
// holding triangle i. A leaf of n triangles takes ceil(n / BVH_BLOCK) consecutive blocks,
// the lanes past its last triangle repeating it. Bvh4Node leaf slots point at their first
// block.
#define BVH_BLOCK 4
#define BVH_BLOCK_FLOAT4S 10

#endif
