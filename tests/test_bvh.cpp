// BVH structure and the OpenCL traversal against the double-precision brute-force
// reference (same rays): visibility and coefficients.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <utility>
#include <vector>

#include "bvh_types.h"
#include "prtbake/bvh.h"
#include "prtbake/error.h"
#include "prtbake/mesh.h"
#include "prtbake/runtime.h"
#include "prtbake/transport.h"
#include "test_common.h"
#include "transport/transport_setup.h"

using namespace prtbake;

namespace {
// A small scene with self-occlusion, a ground plane and a floating square: a bumpy
// sphere (concave folds), a floor and a tilted roof. ~1.2k triangles.
Mesh occludingScene() {
  Mesh m = makeBumpySphere(800);
  appendMesh(m, makeSquare(2.0, -1.3, 3, false));
  Mesh roof = makeSquare(0.8, 1.4, 2, true);
  for (size_t v = 0; v < roof.vertexCount(); ++v) roof.positions[3 * v + 2] += 0.2f * roof.positions[3 * v];
  appendMesh(m, roof);
  return m;
}

void checkNode(const Bvh& bvh, int index, int depth, std::vector<int>& seen, int& maxDepth) {
  const auto& n = bvh.nodes[index];
  maxDepth = std::max(maxDepth, depth);
  if (n.count > 0) {
    for (int i = n.offset; i < n.offset + n.count; ++i) ++seen[i];
    return;
  }
  for (int child : {index + 1, n.offset}) {
    const auto& c = bvh.nodes[child];
    for (int k = 0; k < 3; ++k) {
      REQUIRE(c.bmin[k] >= n.bmin[k]);
      REQUIRE(c.bmax[k] <= n.bmax[k]);
    }
    checkNode(bvh, child, depth + 1, seen, maxDepth);
  }
}
}  // namespace

TEST_CASE("BVH: every non-degenerate triangle in exactly one leaf, nested bounds", "[bvh]") {
  Mesh m = occludingScene();
  // Two zero-area triangles: left out.
  m.indices.insert(m.indices.end(), {0, 0, 0, 1, 2, 1});
  const Bvh bvh = buildBvh(m);
  REQUIRE(bvh.degenerateTriangles == 2);
  REQUIRE(bvh.triangles.size() == m.triangleCount() - 2);
  std::vector<int> seen(bvh.triangles.size(), 0);
  int depth = 0;
  checkNode(bvh, 0, 0, seen, depth);
  for (int s : seen) REQUIRE(s == 1);
  CHECK(depth == bvh.depth);
  CHECK(depth <= kBvhMaxDepth);
  std::vector<uint32_t> ids = bvh.triangles;
  std::sort(ids.begin(), ids.end());
  CHECK(std::adjacent_find(ids.begin(), ids.end()) == ids.end());
  // Each leaf's box holds its triangles' vertices.
  for (const auto& n : bvh.nodes) {
    if (n.count <= 0) continue;
    for (int i = n.offset; i < n.offset + n.count; ++i)
      for (int k = 0; k < 3; ++k) {
        const float* p = &m.positions[3 * m.indices[3 * bvh.triangles[i] + k]];
        for (int c = 0; c < 3; ++c) REQUIRE((p[c] >= n.bmin[c] && p[c] <= n.bmax[c]));
      }
  }
}

TEST_CASE("BVH: the wide tree's leaf blocks hold every triangle once, and inner slots name their child's first block",
          "[bvh]") {
  Mesh m = occludingScene();
  m.indices.insert(m.indices.end(), {0, 0, 0});  // zero area: in no block
  const Bvh bvh = buildBvh(m);
  REQUIRE(bvh.blocks.size() % (4 * BVH_BLOCK_FLOAT4S) == 0);
  const size_t nBlocks = bvh.blocks.size() / (4 * BVH_BLOCK_FLOAT4S);
  // Lane `lane` of float4 `c` of block b.
  auto at = [&](size_t b, int c, int lane) { return bvh.blocks[(b * BVH_BLOCK_FLOAT4S + size_t(c)) * 4 + size_t(lane)]; };
  std::vector<int> seen(m.triangleCount(), 0);
  std::vector<int> stack = {0};
  size_t leaves = 0, sizes = 0;
  while (!stack.empty()) {
    const Bvh::WideNode& w = bvh.wide[size_t(stack.back())];
    stack.pop_back();
    for (int k = 0; k < 4; ++k) {
      const int count = w.count[k], child = w.child[k];
      if (count == -1) {
        REQUIRE(w.bmin[0][k] > w.bmax[0][k]);  // no ray enters an empty slot
        continue;
      }
      if (count <= -2) {
        const Bvh::WideNode& c = bvh.wide[size_t(child)];
        int first = -1;  // the child's first leaf block (0 when it has no leaf)
        for (int j = 0; j < 4; ++j)
          if (c.count[j] > 0) first = first < 0 ? c.child[j] : std::min(first, c.child[j]);
        CHECK(-2 - count == std::max(first, 0));
        stack.push_back(child);
        continue;
      }
      ++leaves, sizes += size_t(count);
      const size_t blocks = size_t(count + BVH_BLOCK - 1) / BVH_BLOCK;
      REQUIRE(size_t(child) + blocks <= nBlocks);
      for (int i = 0; i < int(blocks) * BVH_BLOCK; ++i) {
        const size_t b = size_t(child) + size_t(i / BVH_BLOCK);
        const int lane = i % BVH_BLOCK, last = std::min(i, count - 1);  // past the leaf's end: its last again
        int32_t id;
        const float idBits = at(b, 9, lane);
        std::memcpy(&id, &idBits, 4);
        REQUIRE(id >= 0);
        REQUIRE(size_t(id) < m.triangleCount());
        if (i < count) ++seen[size_t(id)];
        else {
          const float lastBits = at(size_t(child) + size_t(last / BVH_BLOCK), 9, last % BVH_BLOCK);
          CHECK(std::memcmp(&idBits, &lastBits, 4) == 0);
        }
        // The corner and edges are the triangle's, and inside the slot's box.
        const float* v[3];
        for (int c = 0; c < 3; ++c) v[c] = &m.positions[3 * size_t(m.indices[3 * size_t(id) + size_t(c)])];
        for (int c = 0; c < 3; ++c) {
          CHECK(at(b, c, lane) == v[0][c]);
          CHECK(at(b, 3 + c, lane) == v[1][c] - v[0][c]);
          CHECK(at(b, 6 + c, lane) == v[2][c] - v[0][c]);
          for (int q = 0; q < 3; ++q) REQUIRE((v[q][c] >= w.bmin[c][k] && v[q][c] <= w.bmax[c][k]));
        }
      }
    }
  }
  for (size_t t = 0; t + 1 < m.triangleCount(); ++t) REQUIRE(seen[t] == 1);
  CHECK(seen.back() == 0);  // the zero-area triangle
  // Leaves fill their blocks: the SAH counts a leaf's cost per block of four.
  CHECK(double(sizes) / double(leaves) > 2.5);
}

TEST_CASE("Kernel vs double reference: same visibility except at edges, same coefficients", "[bvh][kernel]") {
  const Mesh m = occludingScene();
  TransportOptions o;
  o.order = 3;
  o.samples = 128;
  // The kernel accepts barycentrics within 1e-6 of an edge (BVH_EDGE_EPS) and works
  // in float; the reference is exact on the closed triangle in double. A ray may
  // therefore differ only when it passes within ~1e-6 (barycentric units, plus float
  // rounding of the ray) of some triangle's edge.
  constexpr double kEdgeBand = 1e-5;
  // Where every ray agrees the coefficients are sums of the same Y_i(ω) in float vs
  // double: 128 terms of size ≤ 0.5 with relative rounding 6e-8, well below 1e-5.
  constexpr double kCoeffTol = 1e-5;
  ReferenceRays rays;
  const auto ref = computeTransportReference(m, o, &rays);
  const auto vis = traceVisibility(test::runtime(), m, o);
  REQUIRE(vis.size() == rays.visible.size());
  size_t mismatches = 0, blocked = 0;
  std::vector<char> vertexOk(m.vertexCount(), 1);
  for (size_t i = 0; i < vis.size(); ++i) {
    blocked += rays.visible[i] == 0;
    if (vis[i] != rays.visible[i]) {
      ++mismatches;
      vertexOk[i / o.samples] = 0;
      INFO("ray " << i << " kernel " << int(vis[i]) << " reference " << int(rays.visible[i]) << " edge distance "
                  << rays.edgeDistance[i]);
      CHECK(rays.edgeDistance[i] < kEdgeBand);
    }
  }
  INFO("rays " << vis.size() << ", blocked " << blocked << ", mismatches " << mismatches);
  CHECK(blocked > vis.size() / 10);  // the scene really occludes
  CHECK(mismatches <= vis.size() / 10000);
  const auto r = computeTransport(test::runtime(), m, o);
  double worst = 0;
  for (size_t v = 0; v < m.vertexCount(); ++v) {
    if (!vertexOk[v]) continue;
    for (int k = 0; k < 9; ++k) worst = std::max(worst, std::abs(double(r.vertex(v)[k]) - ref.vertex(v)[k]));
  }
  INFO("max |kernel - reference| = " << worst);
  CHECK(worst < kCoeffTol);
}

TEST_CASE("Kernel vs double reference: interreflection bounces", "[bvh][kernel]") {
  Mesh m = makeOpenSphereCavity(1.0, 1.0, 6, 12);
  appendMesh(m, makeSquare(1.5, -1.2, 2, false));
  TransportOptions o;
  o.mode = TransportMode::Interreflected;
  o.order = 2;
  o.samples = 64;
  o.bounces = 2;
  o.bounceTolerance = 0;
  o.albedoOverride = std::array<float, 3>{0.9f, 0.5f, 0.2f};
  const auto ref = computeTransportReference(m, o);
  // The packet kernels and the scalar ones, one and 32 work-items per vertex (each tracing only
  // the direct term's blocked rays in the first bounce and gathering its hits in the second)
  // against every ray in double.
  for (auto [width, lanes] : {std::pair{16, 1}, {0, 1}, {0, 32}}) {
    o.packetWidth = width, o.rayLanes = lanes;
    const auto r = computeTransport(test::runtime(), m, o);
    REQUIRE(r.channels == 3);
    REQUIRE(r.coeffs.size() == ref.coeffs.size());
    // Float gather and barycentrics vs double; a ray hitting a different triangle at a
    // shared edge interpolates the same T there. 1e-4 of coefficients ~0.3.
    constexpr double kBounceTol = 1e-4;
    double worst = 0;
    for (size_t i = 0; i < r.coeffs.size(); ++i) worst = std::max(worst, std::abs(double(r.coeffs[i]) - ref.coeffs[i]));
    INFO("packet width " << width << ", lanes " << lanes << ": max |kernel - reference| = " << worst);
    CHECK(worst < kBounceTol);
  }
}

TEST_CASE("The scalar kernels' lanes trace the same rays, and a vertex's sums are its own", "[bvh][kernel]") {
  DeviceInfo cpu, gpu;
  cpu.type = "cpu", gpu.type = "gpu";
  CHECK(detail::rayLanesFor(cpu, 0, -1) == 1);
  CHECK(detail::rayLanesFor(gpu, 0, -1) == 32);
  CHECK(detail::rayLanesFor(gpu, 0, 4) == 4);
  CHECK(detail::rayLanesFor(gpu, 16, 32) == 1);  // the packet kernels take none
  // L work-items per vertex, lane j taking rays j, j + L, …, the masks of blocked rays
  // assembled across lanes and the bounce's hits written at their rank: against one
  // work-item per vertex, the same rays traced (counts equal, so the masks agree) and the
  // same sums up to float summation order (1e-5, as for the packets above). 1030 samples: two
  // launches, neither a multiple of 32 rays; two bounces: the first traces the blocked rays and
  // keeps their hits, the second gathers them.
  const Mesh m = occludingScene();
  TransportOptions o;
  o.samples = 1030;
  o.packetWidth = 0;
  o.bounces = 2, o.bounceTolerance = 0;
  o.albedoOverride = std::array<float, 3>{0.8f, 0.6f, 0.3f};
  constexpr double kSumOrderTol = 1e-5;
  for (TransportMode mode : {TransportMode::Shadowed, TransportMode::Interreflected}) {
    o.mode = mode, o.rayLanes = 1;
    const auto one = computeTransport(test::runtime(), m, o);
    for (int lanes : {2, 8, 32}) {
      o.rayLanes = lanes;
      const auto r = computeTransport(test::runtime(), m, o);
      INFO("mode " << int(mode) << ", lanes " << lanes);
      CHECK(r.rays == one.rays);
      REQUIRE(r.coeffs.size() == one.coeffs.size());
      double worst = 0;
      for (size_t i = 0; i < r.coeffs.size(); ++i) worst = std::max(worst, std::abs(double(r.coeffs[i]) - one.coeffs[i]));
      INFO("max |lanes - one| = " << worst);
      CHECK(worst < kSumOrderTol);
    }
  }
  // A vertex's lanes sum in a fixed tree of their own: a range of vertices gives the same
  // bytes as those vertices of the whole mesh (ids offset within the groups).
  o.mode = TransportMode::Shadowed, o.rayLanes = 32, o.samples = 100;
  const auto whole = computeTransport(test::runtime(), m, o);
  o.firstVertex = 5, o.vertexCount = 40;
  const auto part = computeTransport(test::runtime(), m, o);
  REQUIRE(part.coeffs.size() == 40 * 9);
  CHECK(std::memcmp(part.coeffs.data(), whole.coeffs.data() + 5 * 9, part.coeffs.size() * sizeof(float)) == 0);
  for (int bad : {0, 3, 64}) {
    o.rayLanes = bad;
    CHECK_THROWS_AS(computeTransport(test::runtime(), m, o), UsageError);
  }
}

TEST_CASE("Packet kernels (16, 8 lanes) agree with the scalar kernel", "[bvh][kernel]") {
  const Mesh m = occludingScene();
  TransportOptions o;
  o.order = 4;
  o.samples = 200;  // not a multiple of the packet width: the tail lanes are masked
  o.packetWidth = 0;
  const auto scalar = computeTransport(test::runtime(), m, o);
  const auto visScalar = traceVisibility(test::runtime(), m, o);
  // Same rays and the same triangle test: identical visibility; the sums differ only
  // in float summation order (200 terms of size ≤ 0.7: ~1e-6).
  constexpr double kSumOrderTol = 1e-5;
  for (int width : {16, 8}) {
    o.packetWidth = width;
    const auto packet = computeTransport(test::runtime(), m, o);
    const auto vis = traceVisibility(test::runtime(), m, o);
    size_t differ = 0;
    for (size_t i = 0; i < vis.size(); ++i) differ += vis[i] != visScalar[i];
    INFO("width " << width << ": " << differ << " rays differ");
    CHECK(differ == 0);
    double worst = 0;
    for (size_t i = 0; i < packet.coeffs.size(); ++i)
      worst = std::max(worst, std::abs(double(packet.coeffs[i]) - scalar.coeffs[i]));
    CHECK(worst < kSumOrderTol);
  }
  // Bounces: packet closest hit + gather vs the scalar kernel. A tie at a shared edge
  // may pick the neighbour, which interpolates the same T there up to rounding.
  o.mode = TransportMode::Interreflected;
  o.bounces = 2;
  o.bounceTolerance = 0;
  o.albedoOverride = std::array<float, 3>{0.8f, 0.6f, 0.3f};
  o.packetWidth = 0;
  const auto scalarBounce = computeTransport(test::runtime(), m, o);
  o.packetWidth = 16;
  const auto packetBounce = computeTransport(test::runtime(), m, o);
  REQUIRE(packetBounce.coeffs.size() == scalarBounce.coeffs.size());
  double worst = 0;
  for (size_t i = 0; i < packetBounce.coeffs.size(); ++i)
    worst = std::max(worst, std::abs(double(packetBounce.coeffs[i]) - scalarBounce.coeffs[i]));
  INFO("bounces: max |packet - scalar| = " << worst);
  CHECK(worst < kSumOrderTol);
}

TEST_CASE("The default packet width follows the device", "[bvh]") {
  // Packets where a device's vector units run their lanes side by side (PoCL's CPU device),
  // the scalar kernels elsewhere; a width asked for is kept. (That the default takes the
  // packets on this CPU device is seen below: only the packet kernels keep the blocked rays.)
  DeviceInfo cpu, gpu, other;
  cpu.type = "cpu", gpu.type = "gpu", other.type = "other";
  CHECK(detail::packetWidthFor(cpu, TransportOptions{}.packetWidth) == 16);
  CHECK(detail::packetWidthFor(gpu, TransportOptions{}.packetWidth) == 0);
  CHECK(detail::packetWidthFor(other, -1) == 0);
  CHECK(detail::packetWidthFor(gpu, 16) == 16);
  CHECK(detail::packetWidthFor(cpu, 0) == 0);
  TransportOptions o;
  o.packetWidth = 4;
  CHECK_THROWS_AS(computeTransport(test::runtime(), occludingScene(), o), UsageError);
}

TEST_CASE("The ray-looping kernels' group size follows the device, and every size gives the same bytes", "[bvh][kernel]") {
  DeviceInfo cpu, gpu, other;
  cpu.type = "cpu", gpu.type = "gpu", other.type = "other";
  CHECK(defaultLoopGroupSize(cpu) == 16);
  CHECK(defaultLoopGroupSize(gpu) == 64);
  CHECK(defaultLoopGroupSize(other) == 64);
  CHECK(test::runtime().loopGroupSize() == 16);
  // A GPU's group size (and an odd one) on this CPU device: each vertex's sums are its own,
  // so the coefficients are the same bytes, direct and with two bounces (the blocked-ray masks
  // and kept hits indexed by vertex), packets and scalar kernels (one or 32 work-items per
  // vertex: groups of 64 and 32, as 7 rounds up to the lanes); the scene's vertex count is no
  // multiple of either size, so the last group is part-filled.
  const Mesh m = occludingScene();
  REQUIRE(m.vertexCount() % 64 != 0);
  TransportOptions o;
  o.samples = 100;
  o.albedoOverride = std::array<float, 3>{0.8f, 0.6f, 0.3f};
  for (const char* size : {"64", "7"}) {
    const auto grouped = test::runtimeWithGroupSize(size);
    Runtime& rt = *grouped;
    CHECK(rt.loopGroupSize() == size_t(std::atoi(size)));
    for (TransportMode mode : {TransportMode::Shadowed, TransportMode::Interreflected})
      for (auto [width, lanes] : {std::pair{16, 1}, {0, 1}, {0, 32}}) {
        o.mode = mode, o.bounces = 2, o.bounceTolerance = 0, o.packetWidth = width, o.rayLanes = lanes;
        const auto a = computeTransport(test::runtime(), m, o), b = computeTransport(rt, m, o);
        INFO("group size " << size << ", mode " << int(mode) << ", packet width " << width << ", lanes " << lanes);
        REQUIRE(a.coeffs.size() == b.coeffs.size());
        CHECK(std::memcmp(a.coeffs.data(), b.coeffs.data(), a.coeffs.size() * sizeof(float)) == 0);
        CHECK(a.rays == b.rays);
      }
  }
  for (const char* bad : {"0", "abc", "64x", "1000000000"}) {
    INFO(bad);
    CHECK_THROWS_AS(test::runtimeWithGroupSize(bad), UsageError);
  }
}

TEST_CASE("Bounces trace only the rays that the direct term found blocked, once", "[bvh][kernel]") {
  // The bounces trace the direct term's rays again; a ray that nothing blocked there
  // hits nothing, and the kernels, packet and scalar, skip it (and every ray of a vertex that
  // no triangle can reach). The first bounce keeps its hits and the second gathers from
  // them without tracing. 1030 samples: two launches of directions, the last packet and
  // the last mask word part-filled.
  const Mesh m = occludingScene();
  TransportOptions o;
  o.samples = 1030;
  const std::vector<uint8_t> vis = traceVisibility(test::runtime(), m, o);
  uint64_t blocked = 0;
  for (uint8_t x : vis) blocked += x == 0;
  REQUIRE(blocked > 0);
  o.mode = TransportMode::Interreflected;
  o.bounces = 2;
  o.bounceTolerance = 0;
  o.albedoOverride = std::array<float, 3>{0.8f, 0.6f, 0.3f};
  const auto packet = computeTransport(test::runtime(), m, o);
  const uint64_t direct = uint64_t(m.vertexCount() - packet.verticesUnoccludable) * uint64_t(o.samples);
  CHECK(packet.rays == direct + blocked);
  // The same rays traced by the scalar kernels, and the same coefficients: float summation
  // order (1e-5, as above) and ties at shared edges, which interpolate the same T. (Both
  // forms against the brute-force reference, which traces every ray: test_transport.)
  o.packetWidth = 0;
  const auto scalar = computeTransport(test::runtime(), m, o);
  CHECK(scalar.rays == direct + blocked);
  REQUIRE(packet.coeffs.size() == scalar.coeffs.size());
  double worst = 0;
  for (size_t i = 0; i < packet.coeffs.size(); ++i)
    worst = std::max(worst, std::abs(double(packet.coeffs[i]) - scalar.coeffs[i]));
  INFO("max |packet - scalar| = " << worst);
  CHECK(worst < 1e-5);
}
