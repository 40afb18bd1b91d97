// Private: the per-vertex ray set-up shared by the kernel driver and the CPU reference,
// so both trace exactly the same rays.
#pragma once

#include <array>
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

RaySetup makeRaySetup(const Mesh& mesh, const TransportOptions& options);
void checkTransportOptions(const TransportOptions& options);
// Albedo per vertex (override applied), V × 4.
std::vector<float> vertexAlbedo(const Mesh& mesh, const TransportOptions& options);
bool transportIsRgb(const Mesh& mesh, const TransportOptions& options);

}  // namespace prtbake::detail
