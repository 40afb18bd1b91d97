// Vertices whose hemisphere cannot be occluded are computed without visibility rays:
// the test itself (convex sphere: all; box on a plane: exactly the vertices no ray of
// which is blocked) and the coefficients (unchanged against the traced reference).
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

#include "prtbake/mesh.h"
#include "prtbake/sh.h"
#include "prtbake/transport.h"
#include "test_common.h"

using namespace prtbake;

namespace {
// Float sums of the same directions in the same order (kernel) against double
// sums (reference): a few ulps of coefficients of size ≤ 0.5 over ≤ 1024 terms.
constexpr double kSameRaysTol = 2e-5;

// An axis-aligned box [−h, h]² × [0, 2h] with outward normals, 4 vertices per face.
Mesh makeBox(float h) {
  Mesh m;
  const float c[8][3] = {{-h, -h, 0}, {h, -h, 0}, {h, h, 0}, {-h, h, 0},
                         {-h, -h, 2 * h}, {h, -h, 2 * h}, {h, h, 2 * h}, {-h, h, 2 * h}};
  // Faces as corner quads, counter-clockwise seen from outside, with their normals.
  const int faces[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {2, 3, 7, 6}, {1, 2, 6, 5}, {3, 0, 4, 7}};
  const float normals[6][3] = {{0, 0, -1}, {0, 0, 1}, {0, -1, 0}, {0, 1, 0}, {1, 0, 0}, {-1, 0, 0}};
  for (int f = 0; f < 6; ++f) {
    const uint32_t base = uint32_t(m.vertexCount());
    for (int k = 0; k < 4; ++k) {
      for (int a = 0; a < 3; ++a) {
        m.positions.push_back(c[faces[f][k]][a]);
        m.normals.push_back(normals[f][a]);
        m.albedo.push_back(1.0f);
      }
    }
    for (uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) m.indices.push_back(base + i);
  }
  return m;
}

double maxDiff(const TransportResult& a, const TransportResult& b, size_t v) {
  const int nc = a.order * a.order;
  double d = 0;
  for (int k = 0; k < nc; ++k) d = std::max(d, std::abs(double(a.vertex(v)[k]) - double(b.vertex(v)[k])));
  return d;
}
}  // namespace

TEST_CASE("Unoccludable: every vertex of a UV sphere, same coefficients", "[unoccludable][transport]") {
  const Mesh sphere = makeUvSphere(1.0, 8, 16);
  const auto flags = unoccludableVertices(sphere);
  CHECK(size_t(std::count(flags.begin(), flags.end(), 1)) == sphere.vertexCount());
  TransportOptions o;
  o.mode = TransportMode::Shadowed;
  o.samples = 256;
  const TransportResult r = computeTransport(test::runtime(), sphere, o);
  CHECK(r.verticesUnoccludable == sphere.vertexCount());
  CHECK(r.rays == 0);
  // The traced double reference (every ray, brute force) gives the same numbers.
  const TransportResult ref = computeTransportReference(sphere, o);
  for (size_t v = 0; v < sphere.vertexCount(); ++v) {
    INFO("vertex " << v);
    CHECK(maxDiff(r, ref, v) < kSameRaysTol);
  }
}

TEST_CASE("Unoccludable: box on a plane skips only vertices no ray of which is blocked",
          "[unoccludable][transport]") {
  Mesh scene = makeSquare(2.0, 0.0, 4, false);
  const size_t planeVertices = scene.vertexCount();
  appendMesh(scene, makeBox(0.5f));
  const auto flags = unoccludableVertices(scene);
  TransportOptions o;
  o.mode = TransportMode::Shadowed;
  o.samples = 1024;
  const std::vector<uint8_t> vis = traceVisibility(test::runtime(), scene, o);
  size_t skipped = 0;
  for (size_t v = 0; v < scene.vertexCount(); ++v) {
    bool allVisible = true;
    for (int s = 0; s < o.samples; ++s) allVisible = allVisible && vis[v * o.samples + s];
    INFO("vertex " << v << (v < planeVertices ? " (plane)" : " (box)"));
    CHECK(bool(flags[v]) == allVisible);
    skipped += flags[v];
  }
  // The box's top and bottom faces: nothing lies above the top, nothing below the bottom.
  CHECK(skipped == 8);
  const TransportResult r = computeTransport(test::runtime(), scene, o);
  CHECK(r.verticesUnoccludable == 8);
  CHECK(r.rays == uint64_t(scene.vertexCount() - 8) * uint64_t(o.samples));
  const TransportResult ref = computeTransportReference(scene, o);
  for (size_t v = 0; v < scene.vertexCount(); ++v)
    if (flags[v]) CHECK(maxDiff(r, ref, v) < kSameRaysTol);
}
