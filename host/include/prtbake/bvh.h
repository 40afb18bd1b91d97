// prtbake/bvh.h: the bounding volume hierarchy the transport kernels traverse.
//
// Built on the host with the surface area heuristic over binned centroids
// (kBvhBins bins per axis, leaves of at most kBvhMaxLeaf triangles, a leaf's
// cost counted in blocks of kBvhBlock), then
// flattened depth-first: the left child of an inner node is the next node, the
// right child is `offset` (pbrt's LinearBVHNode layout, 32 bytes). Zero-area
// triangles cannot occlude and are left out. The node layout is the POD struct
// of kernels/bvh_types.h; Bvh::Node mirrors it (checked by static_assert).
#pragma once

#include <cstdint>
#include <vector>

#include "prtbake/mesh.h"

namespace prtbake {

constexpr int kBvhBins = 16;
constexpr int kBvhMaxLeaf = 4;
constexpr int kBvhBlock = 4;  // triangles the single-ray kernels test at once (SAH leaf cost per block)
constexpr int kBvhMaxDepth = 60;  // the kernels' traversal stack holds 64 entries

struct Bvh {
  struct Node {
    float bmin[3];
    int32_t offset;  // inner: right child index; leaf: first triangle in leaf order
    float bmax[3];
    int32_t count;   // > 0: triangles in the leaf; inner node: −(1 + split axis)
  };
  std::vector<Node> nodes;           // nodes[0] is the root
  // The same tree with four children per node (kernels/bvh_types.h, Bvh4Node): every
  // inner node takes its children's children until it has four, expanding the largest
  // child box first. wide[0] is the root (empty when `nodes` is).
  struct WideNode {
    float bmin[3][4], bmax[3][4];  // [axis][child slot]
    int32_t child[4], count[4];
  };
  // Leaf slots: child = first block, count = triangles; inner slots: count = −2 − the first
  // block of the child's own leaves; empty slots: count = −1.
  std::vector<WideNode> wide;
  std::vector<uint32_t> triangles;   // mesh triangle index of each leaf slot
  // Leaf-ordered triangles packed for the kernels: 12 floats per triangle,
  // (v0, id-as-int-bits), (v1 − v0, 0), (v2 − v0, 0).
  std::vector<float> packed;
  // The wide tree's leaf triangles in blocks of kBvhBlock (kernels/bvh_types.h, 40 floats
  // each): a leaf takes ceil(count / kBvhBlock) blocks, the last padded with its last triangle.
  std::vector<float> blocks;
  int depth = 0;
  size_t degenerateTriangles = 0;   // zero-area triangles left out
};

// Builds the BVH of the mesh's triangles. An empty result (no node) means every
// triangle has zero area.
Bvh buildBvh(const Mesh& mesh);

}  // namespace prtbake
