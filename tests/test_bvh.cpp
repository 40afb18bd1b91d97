// BVH structure and the OpenCL traversal against the double-precision brute-force
// reference (same rays): visibility and coefficients.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

#include "prtbake/bvh.h"
#include "prtbake/mesh.h"
#include "prtbake/transport.h"
#include "test_common.h"

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
  const auto r = computeTransport(test::runtime(), m, o);
  REQUIRE(r.channels == 3);
  REQUIRE(r.coeffs.size() == ref.coeffs.size());
  // Float gather and barycentrics vs double; a ray hitting a different triangle at a
  // shared edge interpolates the same T there. 1e-4 of coefficients ~0.3.
  constexpr double kBounceTol = 1e-4;
  double worst = 0;
  for (size_t i = 0; i < r.coeffs.size(); ++i) worst = std::max(worst, std::abs(double(r.coeffs[i]) - ref.coeffs[i]));
  INFO("max |kernel - reference| = " << worst);
  CHECK(worst < kBounceTol);
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

TEST_CASE("Bounces trace only the rays that the direct term found blocked, once", "[bvh][kernel]") {
  // The bounces trace the direct term's rays again; a ray that nothing blocked there
  // hits nothing, and the packet kernels skip it (and every ray of a vertex that no
  // triangle can reach). The first bounce keeps its hits and the second gathers from
  // them without tracing. 1030 samples: two launches of directions, the last packet
  // part-filled.
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
  // The same coefficients as the scalar kernels, which trace every ray: float summation
  // order (1e-5, as above) and ties at shared edges, which interpolate the same T.
  o.packetWidth = 0;
  const auto scalar = computeTransport(test::runtime(), m, o);
  REQUIRE(packet.coeffs.size() == scalar.coeffs.size());
  double worst = 0;
  for (size_t i = 0; i < packet.coeffs.size(); ++i)
    worst = std::max(worst, std::abs(double(packet.coeffs[i]) - scalar.coeffs[i]));
  INFO("max |packet - scalar| = " << worst);
  CHECK(worst < 1e-5);
}
