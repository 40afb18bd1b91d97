// Private: the direct-term kernel over a subset of vertices, with the BVH uploaded
// once. Used by the adaptive driver (transport_adaptive.cpp) and by computeTransport to
// trace only the vertices that can be occluded.
#pragma once

#include <cstdint>
#include <vector>

#include "prtbake/bvh.h"
#include "prtbake/runtime.h"
#include "prtbake/transport.h"
#include "transport_setup.h"

namespace prtbake::detail {

// Flags per vertex (see unoccludableVertices in transport.h) from an existing BVH.
std::vector<uint8_t> unoccludableFromBvh(const Mesh& mesh, const Bvh& bvh, const RaySetup& setup);

class DirectRunner {
 public:
  // nodes/tris: the BVH on the device (any valid buffers when nothing is traced).
  DirectRunner(Runtime& rt, const TransportOptions& o, cl::Buffer nodes, cl::Buffer tris, float tMax)
      : rt_(rt), o_(o), nodes_(std::move(nodes)), tris_(std::move(tris)), tMax_(tMax) {}
  // The direct term T^(0) (vertices.size() × order², in the order of `vertices`) and the
  // unoccluded fraction of each listed vertex, for setup's directions and frames.
  void run(const RaySetup& setup, const std::vector<uint32_t>& vertices, bool visibility,
           std::vector<float>& coeffs, std::vector<float>& visible);

 private:
  Runtime& rt_;
  TransportOptions o_;
  cl::Buffer nodes_, tris_;
  float tMax_;
};

// The shadowed quadtree of "--tolerance" (transport_quadtree.cpp) for `vertices` (each
// with a normal): fills their coeffs, samplesPerVertex, errorEstimate and stdError, and
// adds to r.rays and r.verticesAtCap.
void quadtreeTransport(Runtime& rt, const RaySetup& setup, cl::Buffer nodes, cl::Buffer tris,
                       const std::vector<uint32_t>& vertices, const TransportOptions& o, TransportResult& r);
// The adaptive driver (TransportOptions::tolerance > 0).
TransportResult computeTransportAdaptive(Runtime& rt, const Mesh& mesh, const TransportOptions& o);

}  // namespace prtbake::detail
