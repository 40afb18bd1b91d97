// Private: the per-vertex ray set-up shared by the kernel driver and the CPU reference,
// so both trace exactly the same rays.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "prtbake/mesh.h"
#include "prtbake/transport.h"

namespace prtbake::detail {

struct RaySetup {
  std::vector<float> origins;  // V × 4: p + ε n_g
  std::vector<float> frames;   // V × 12: t, b, n as float4 (n = 0: no normal)
  std::vector<float> dirs;     // N × 4: local directions (float)
  float tMax = 0;              // ray length
  double epsilon = 0;          // the origin offset
  size_t verticesWithoutNormal = 0;
};

// Points first … first + count − 1 of the 2-D Sobol' sequence (sobol.h) with a digital
// shift drawn from the seed (the same for every block, so each power-of-two prefix stays
// a net), cosine-mapped like sampleDirectionsLocal and Morton-ordered; N × 4 floats.
std::vector<float> sobolDirectionsLocal(uint32_t first, int count, uint64_t seed);
RaySetup makeRaySetup(const Mesh& mesh, const TransportOptions& options);
// The directions (N × 4) as the packet kernels read them: x, y, z as three rows of
// paddedCount floats, N rounded up to a multiple of 16 (padding lanes are zero).
std::vector<float> packetDirections(const std::vector<float>& dirs, int& paddedCount);
void checkTransportOptions(const TransportOptions& options);
// Albedo per vertex (override applied), V × 4.
std::vector<float> vertexAlbedo(const Mesh& mesh, const TransportOptions& options);
bool transportIsRgb(const Mesh& mesh, const TransportOptions& options);

}  // namespace prtbake::detail
