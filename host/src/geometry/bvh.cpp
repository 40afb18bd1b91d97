// Binned-SAH BVH build, flattened depth-first (see prtbake/bvh.h).
#include "prtbake/bvh.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <future>
#include <utility>

#include "bvh_types.h"
#include "core/parallel.h"

#include <vector>

namespace prtbake {

static_assert(sizeof(BvhNode) == 32, "BvhNode must be 32 bytes on the host and the device");
static_assert(sizeof(Bvh::Node) == sizeof(BvhNode), "Bvh::Node mirrors BvhNode");
static_assert(offsetof(Bvh::Node, offset) == offsetof(BvhNode, offset), "Bvh::Node mirrors BvhNode");
static_assert(offsetof(Bvh::Node, count) == offsetof(BvhNode, count), "Bvh::Node mirrors BvhNode");
static_assert(BVH_TRI_FLOAT4S == 3, "packed triangles are three float4");
static_assert(BVH_BLOCK_FLOAT4S == 10 && BVH_BLOCK == kBvhBlock, "triangle blocks are ten float4");
static_assert(sizeof(Bvh4Node) == 128 && sizeof(Bvh::WideNode) == sizeof(Bvh4Node), "Bvh::WideNode mirrors Bvh4Node");
static_assert(offsetof(Bvh::WideNode, child) == offsetof(Bvh4Node, child), "Bvh::WideNode mirrors Bvh4Node");

namespace {

// Four floats (x, y, z, unused) in one SIMD register, by the GCC/Clang vector extension.
typedef float F4 __attribute__((vector_size(16)));
F4 min4(F4 a, F4 b) { return a < b ? a : b; }
F4 max4(F4 a, F4 b) { return a > b ? a : b; }

struct Box {
  F4 lo = {INFINITY, INFINITY, INFINITY, INFINITY}, hi = {-INFINITY, -INFINITY, -INFINITY, -INFINITY};
  void grow(F4 p) { lo = min4(lo, p), hi = max4(hi, p); }
  void grow(const Box& b) { lo = min4(lo, b.lo), hi = max4(hi, b.hi); }
  double area() const {
    if (lo[0] > hi[0]) return 0;
    const double dx = hi[0] - lo[0], dy = hi[1] - lo[1], dz = hi[2] - lo[2];
    return 2 * (dx * dy + dy * dz + dz * dx);
  }
};

struct Prim {
  Box box;
  F4 centroid;
  uint32_t tri;
};

// Blocks of kBvhBlock triangles that n triangles fill.
double blocks(size_t n) { return double((n + kBvhBlock - 1) / kBvhBlock); }

// Ranges of at least this many triangles split at the root are built on two threads.
constexpr size_t kParallelBuild = 4096;

struct Builder {
  std::vector<Prim>& prims;
  std::vector<Bvh::Node>& nodes;
  int depth = 0;
  int threads = 1;

  struct Split {
    double cost = INFINITY;
    int axis = -1, bin = 0;  // axis -1: no split (all centroids coincide)
  };

  // Binned SAH, all three axes binned in one pass over the range.
  Split bestSplit(size_t begin, size_t end, const Box& cbounds) const {
    Split best;
    Box binBox[3][kBvhBins];
    size_t binCount[3][kBvhBins] = {};
    double scale[3];
    for (int axis = 0; axis < 3; ++axis)
      scale[axis] = cbounds.hi[axis] > cbounds.lo[axis] ? kBvhBins / double(cbounds.hi[axis] - cbounds.lo[axis]) : 0.0;
    for (size_t i = begin; i < end; ++i) {
      const Prim& pr = prims[i];
      _Pragma("GCC unroll 3") for (int axis = 0; axis < 3; ++axis) {
        const int b = std::min(kBvhBins - 1, int((pr.centroid[axis] - cbounds.lo[axis]) * scale[axis]));
        binBox[axis][b].grow(pr.box);
        ++binCount[axis][b];
      }
    }
    for (int axis = 0; axis < 3; ++axis) {
      if (!(cbounds.hi[axis] > cbounds.lo[axis])) continue;
      double rightArea[kBvhBins];
      size_t rightCount[kBvhBins];
      Box acc;
      size_t cnt = 0;
      for (int b = kBvhBins - 1; b > 0; --b) {
        const bool same = binCount[axis][b] == 0 && b < kBvhBins - 1;  // an empty bin changes nothing
        if (!same) acc.grow(binBox[axis][b]);
        cnt += binCount[axis][b];
        rightArea[b] = same ? rightArea[b + 1] : acc.area();
        rightCount[b] = cnt;
      }
      Box left;
      size_t leftCount = 0;
      for (int b = 0; b < kBvhBins - 1; ++b) {
        left.grow(binBox[axis][b]);
        leftCount += binCount[axis][b];
        // A split after an empty bin costs what the split before it did (kept: the first wins).
        if (leftCount == 0 || rightCount[b + 1] == 0 || (b > 0 && binCount[axis][b] == 0)) continue;
        const double cost = left.area() * blocks(leftCount) + rightArea[b + 1] * blocks(rightCount[b + 1]);
        if (cost < best.cost) best = {cost, axis, b};
      }
    }
    return best;
  }

  // The two halves on two threads, each into its own list, then appended in depth-first
  // order with their inner nodes' right-child indices moved: the same tree as one thread
  // builds. Returns the right child's index.
  int buildHalvesInParallel(size_t begin, size_t mid, size_t end, int level) {
    std::vector<Bvh::Node> leftNodes, rightNodes;
    Builder left{prims, leftNodes}, rightHalf{prims, rightNodes};
    auto leftDone = std::async(std::launch::async, [&] { left.build(begin, mid, level + 1); });
    rightHalf.build(mid, end, level + 1);  // should it throw, leftDone's destructor waits
    leftDone.get();
    depth = std::max({depth, left.depth, rightHalf.depth});
    const int leftAt = int(nodes.size());
    const int right = leftAt + int(leftNodes.size());
    for (const auto& [part, at] : {std::pair{&leftNodes, leftAt}, std::pair{&rightNodes, right}})
      for (Bvh::Node n : *part) {
        if (n.count <= 0) n.offset += at;
        nodes.push_back(n);
      }
    return right;
  }

  int build(size_t begin, size_t end, int level) {
    depth = std::max(depth, level);
    const int index = int(nodes.size());
    nodes.emplace_back();
    Box bounds, cbounds;
    for (size_t i = begin; i < end; ++i) bounds.grow(prims[i].box), cbounds.grow(prims[i].centroid);
    auto makeLeaf = [&]() {
      Bvh::Node& n = nodes[index];
      for (int c = 0; c < 3; ++c) n.bmin[c] = bounds.lo[c], n.bmax[c] = bounds.hi[c];
      n.offset = int32_t(begin);
      n.count = int32_t(end - begin);
      return index;
    };
    const size_t count = end - begin;
    if (count <= 1 || level >= kBvhMaxDepth) return makeLeaf();
    const Split best = bestSplit(begin, end, cbounds);
    // Leaf when splitting is not cheaper (traversal cost 1, intersection cost 1 per block of
    // kBvhBlock triangles, which the single-ray kernels test at once).
    const double leafCost = bounds.area() * blocks(count);
    size_t mid;
    int splitAxis = best.axis;
    if (best.axis < 0) {
      if (count <= size_t(kBvhMaxLeaf)) return makeLeaf();
      mid = begin + count / 2;  // all centroids coincide: split by index
      const float ext[3] = {bounds.hi[0] - bounds.lo[0], bounds.hi[1] - bounds.lo[1], bounds.hi[2] - bounds.lo[2]};
      splitAxis = ext[0] >= ext[1] && ext[0] >= ext[2] ? 0 : (ext[1] >= ext[2] ? 1 : 2);
    } else {
      if (count <= size_t(kBvhMaxLeaf) && best.cost + bounds.area() >= leafCost) return makeLeaf();
      const float lo = cbounds.lo[best.axis];
      const double scale = kBvhBins / double(cbounds.hi[best.axis] - lo);
      auto it = std::partition(prims.begin() + begin, prims.begin() + end, [&](const Prim& p) {
        return std::min(kBvhBins - 1, int((p.centroid[best.axis] - lo) * scale)) <= best.bin;
      });
      mid = size_t(it - prims.begin());
      if (mid == begin || mid == end) mid = begin + count / 2;
    }
    int right;
    if (level == 0 && count >= kParallelBuild && threads > 1) {
      right = buildHalvesInParallel(begin, mid, end, level);
    } else {
      build(begin, mid, level + 1);
      right = build(mid, end, level + 1);
    }
    Bvh::Node& n = nodes[index];
    for (int c = 0; c < 3; ++c) n.bmin[c] = bounds.lo[c], n.bmax[c] = bounds.hi[c];
    n.offset = right;
    n.count = -(1 + splitAxis);
    return index;
  }
};

// The wide node for binary node `index` (an inner node), appended to `wide`; returns its
// position. Slots take the node's children, then the inner child with the largest box
// is replaced by its two children while a slot is free.
int collapse(const std::vector<Bvh::Node>& nodes, int index, std::vector<Bvh::WideNode>& wide) {
  auto area = [&](int i) {
    const Bvh::Node& n = nodes[size_t(i)];
    const double dx = n.bmax[0] - n.bmin[0], dy = n.bmax[1] - n.bmin[1], dz = n.bmax[2] - n.bmin[2];
    return dx * dy + dy * dz + dz * dx;
  };
  std::vector<int> slots = {index + 1, nodes[size_t(index)].offset};
  while (slots.size() < 4) {
    int best = -1;
    for (size_t k = 0; k < slots.size(); ++k)
      if (nodes[size_t(slots[k])].count <= 0 && (best < 0 || area(slots[k]) > area(slots[size_t(best)]))) best = int(k);
    if (best < 0) break;
    const int n = slots[size_t(best)];
    slots[size_t(best)] = n + 1;
    slots.push_back(nodes[size_t(n)].offset);
  }
  const int at = int(wide.size());
  wide.emplace_back();
  Bvh::WideNode w{};
  for (int k = 0; k < 4; ++k) {
    if (k >= int(slots.size())) {
      for (int c = 0; c < 3; ++c) w.bmin[c][k] = 1e30f, w.bmax[c][k] = -1e30f;
      w.child[k] = 0, w.count[k] = -1;
      continue;
    }
    const Bvh::Node& n = nodes[size_t(slots[size_t(k)])];
    for (int c = 0; c < 3; ++c) w.bmin[c][k] = n.bmin[c], w.bmax[c][k] = n.bmax[c];
    if (n.count > 0) {
      w.child[k] = n.offset, w.count[k] = n.count;
    } else {
      w.child[k] = collapse(nodes, slots[size_t(k)], wide), w.count[k] = 0;
    }
  }
  wide[size_t(at)] = w;
  return at;
}

// One primitive (box, centroid, triangle) for every triangle that can be hit; triangles of
// zero area in the float arithmetic the kernel uses are counted in *degenerate instead.
std::vector<Prim> primitives(const Mesh& mesh, size_t* degenerate) {
  std::vector<Prim> prims;
  prims.reserve(mesh.triangleCount());
  const float* p = mesh.positions.data();
  for (size_t t = 0; t < mesh.triangleCount(); ++t) {
    const float* v[3] = {p + 3 * size_t(mesh.indices[3 * t]), p + 3 * size_t(mesh.indices[3 * t + 1]),
                         p + 3 * size_t(mesh.indices[3 * t + 2])};
    // Zero area in the float arithmetic the kernel uses: it can never be hit.
    float e1[3], e2[3];
    for (int c = 0; c < 3; ++c) e1[c] = v[1][c] - v[0][c], e2[c] = v[2][c] - v[0][c];
    const float cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2],
                cz = e1[0] * e2[1] - e1[1] * e2[0];
    if (cx == 0 && cy == 0 && cz == 0) {
      ++*degenerate;
      continue;
    }
    Prim pr;
    for (int k = 0; k < 3; ++k) pr.box.grow(F4{v[k][0], v[k][1], v[k][2], 0.0f});
    pr.centroid = (pr.box.lo + pr.box.hi) * 0.5f;
    pr.tri = uint32_t(t);
    prims.push_back(pr);
  }
  return prims;
}

// The triangles in the tree's order: their indices, and each as v0, id, e1, e2 (12 floats).
void packTriangles(const Mesh& mesh, const std::vector<Prim>& prims, Bvh& bvh) {
  const float* p = mesh.positions.data();
  bvh.triangles.resize(prims.size());
  bvh.packed.resize(prims.size() * 12);
  for (size_t i = 0; i < prims.size(); ++i) {
    const uint32_t t = prims[i].tri;
    bvh.triangles[i] = t;
    const float* v0 = p + 3 * size_t(mesh.indices[3 * t]);
    const float* v1 = p + 3 * size_t(mesh.indices[3 * t + 1]);
    const float* v2 = p + 3 * size_t(mesh.indices[3 * t + 2]);
    float* o = &bvh.packed[12 * i];
    const int32_t id = int32_t(t);
    o[0] = v0[0], o[1] = v0[1], o[2] = v0[2];
    std::memcpy(&o[3], &id, 4);
    for (int c = 0; c < 3; ++c) o[4 + c] = v1[c] - v0[c], o[8 + c] = v2[c] - v0[c];
    o[7] = o[11] = 0.0f;
  }
}

// The wide tree's leaves in blocks (see below), from bvh.packed and bvh.wide.
void packBlocks(Bvh& bvh) {
  // The wide tree's leaves in blocks, in the order the wide nodes reference them (a node's
  // leaves side by side); each leaf slot's child becomes its first block, and each inner
  // slot's count −2 − the first block of that child's leaves (block 0 if it has none).
  constexpr size_t kBlockFloats = 4 * BVH_BLOCK_FLOAT4S;
  size_t nBlocks = 0;
  for (const Bvh::WideNode& w : bvh.wide)
    for (int k = 0; k < 4; ++k) nBlocks += w.count[k] > 0 ? size_t(blocks(size_t(w.count[k]))) : 0;
  bvh.blocks.resize(nBlocks * kBlockFloats);
  std::vector<int32_t> firstBlock(bvh.wide.size(), 0);
  size_t next = 0;
  for (size_t i = 0; i < bvh.wide.size(); ++i) {
    Bvh::WideNode& w = bvh.wide[i];
    const size_t own = next;
    for (int k = 0; k < 4; ++k) {
      if (w.count[k] <= 0) continue;
      const size_t first = size_t(w.child[k]), n = size_t(w.count[k]);
      w.child[k] = int32_t(next);
      for (size_t b = 0; b < n; b += kBvhBlock, ++next) {
        float* blk = &bvh.blocks[next * kBlockFloats];
        for (size_t l = 0; l < size_t(kBvhBlock); ++l) {
          const float* t = &bvh.packed[12 * (first + std::min(b + l, n - 1))];  // pad: the last again
          const float src[BVH_BLOCK_FLOAT4S] = {t[0], t[1], t[2], t[4], t[5], t[6], t[8], t[9], t[10], t[3]};
          for (int c = 0; c < BVH_BLOCK_FLOAT4S; ++c) blk[4 * c + l] = src[c];
        }
      }
    }
    firstBlock[i] = next > own ? int32_t(own) : 0;
  }
  for (Bvh::WideNode& w : bvh.wide)
    for (int k = 0; k < 4; ++k)
      if (w.count[k] == 0) w.count[k] = -2 - firstBlock[size_t(w.child[k])];
}

}  // namespace

Bvh buildBvh(const Mesh& mesh) {
  Bvh bvh;
  std::vector<Prim> prims = primitives(mesh, &bvh.degenerateTriangles);
  if (prims.empty()) return bvh;
  bvh.nodes.reserve(2 * prims.size() / kBvhMaxLeaf + 2);
  Builder b{prims, bvh.nodes};
  b.threads = detail::hostThreads();
  b.build(0, prims.size(), 0);
  bvh.depth = b.depth;
  // The wide tree; a root that is a leaf becomes one wide node with that leaf in slot 0.
  if (bvh.nodes[0].count > 0) {
    Bvh::WideNode w{};
    for (int k = 0; k < 4; ++k) {
      for (int c = 0; c < 3; ++c) w.bmin[c][k] = 1e30f, w.bmax[c][k] = -1e30f;
      w.child[k] = 0, w.count[k] = -1;
    }
    for (int c = 0; c < 3; ++c) w.bmin[c][0] = bvh.nodes[0].bmin[c], w.bmax[c][0] = bvh.nodes[0].bmax[c];
    w.child[0] = bvh.nodes[0].offset, w.count[0] = bvh.nodes[0].count;
    bvh.wide.push_back(w);
  } else {
    bvh.wide.reserve(bvh.nodes.size() / 3 + 1);
    collapse(bvh.nodes, 0, bvh.wide);
  }
  packTriangles(mesh, prims, bvh);
  packBlocks(bvh);
  return bvh;
}
}  // namespace prtbake
