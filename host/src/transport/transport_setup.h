// Private: the per-vertex ray set-up shared by the kernel driver and the CPU reference,
// so both trace exactly the same rays.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include "prtbake/bvh.h"
#include "prtbake/mesh.h"
#include "prtbake/runtime.h"
#include "prtbake/transport.h"

namespace prtbake::detail {

struct RaySetup {
  std::vector<float> points;   // V × 3: the points p (the mesh's vertices, or surface points)
  std::vector<float> origins;  // V × 4: p + ε n_g
  std::vector<float> frames;   // V × 12: t, b, n as float4 (n = 0: no normal)
  std::vector<float> dirs;     // N × 4: local directions (float); empty unless asked for
  float tMax = 0;              // ray length
  double epsilon = 0;          // the origin offset
  size_t verticesWithoutNormal = 0;
  size_t count() const { return points.size() / 3; }
};

// Directions per launch of the transport kernels: they sum at most this many in float
// (16 lanes of a packet: 64 additions each); the host adds the launches up in double. A
// float run of additions of near-equal values (Y_0 over the visible rays) drifts with its
// length: the BRDF table's 1024 additions per lane biased it by 1.4e-5 (measured), 64
// keep it below the transport's error at 2^24 samples. Default counts take one launch.
constexpr int kTransportSampleChunk = 1024;

// The most the kept hits of blocked rays may take (12 bytes each: 44 million), for the
// later bounces (transport) or the other colour channels (glossy) to read instead of
// tracing the same rays again; beyond it they trace.
constexpr double kKeptHitBytes = 512.0 * 1024 * 1024;

// Directions first … first + count − 1 of the `samples`-point set of sampleDirectionsLocal,
// Morton-ordered among themselves; count × 4 floats. The kernels take the set in such
// chunks, so that no launch sums more than a chunk in float.
std::vector<float> directionChunk(int samples, int first, int count, uint64_t seed, TransportSampler sampler);
// Origins and frames of every vertex; with `withDirections`, the whole direction set of
// options.samples too (the CPU reference reads it; the device takes it in chunks).
RaySetup makeRaySetup(const Mesh& mesh, const TransportOptions& options, bool withDirections = true);
// The same for surface points (computeTransportAtPoints): the offset along each point's own
// face normal, the frame's rotation from the point's index; ε and the ray length from `mesh`.
RaySetup makePointRaySetup(const Mesh& mesh, const SurfacePoints& points, const TransportOptions& options);
// The packet width that the options' `requested` width (TransportOptions::packetWidth,
// ProbeOptions::packetWidth) comes to on `device`: a width ≥ 0 as it is; −1 (the
// default) 16 on a CPU device, whose vector units run a packet's lanes side by side, and 0
// (the scalar kernels: a work-item's rays one at a time) on any other: a GPU's compiler runs
// a packet's lanes one after another in one thread. On an H200 through NVIDIA's OpenCL the
// knot of bench_transport traced 0.22 G rays/s in packets of 16 and 0.75 G rays/s with the
// scalar kernels (bench/results/gpu.md).
int packetWidthFor(const DeviceInfo& device, int requested);
// The scalar kernels' work-items per vertex (TransportOptions::rayLanes): `requested` when
// ≥ 1; else 1 on a CPU device (its scalar kernels run a work-item's rays in turn anyway) and
// 32 on any other (a GPU's warp: a mesh of few vertices still fills the device, and a warp's
// rays are neighbours of one vertex). 1 for the packet kernels.
int rayLanesFor(const DeviceInfo& device, int packetWidth, int requested);
// Throws UsageError unless `requested` is −1 (by the device) or 1, 2, 4, 8, 16 or 32.
void checkRayLanes(int requested);
// The BVH's nodes on the device: the 4-wide tree for the packet kernels (`wide`), else
// the binary one. A BVH without nodes (every triangle of zero area) becomes one node that
// no ray enters.
cl::Buffer uploadBvhNodes(Runtime& rt, const Bvh& bvh, bool wide);
// Its triangles to match: the wide tree's blocks, else the packed leaf-ordered triangles.
cl::Buffer uploadBvhTriangles(Runtime& rt, const Bvh& bvh, bool wide);
// Flags per vertex (see unoccludableVertices in transport.h) from an existing BVH.
std::vector<uint8_t> unoccludableFromBvh(const Mesh& mesh, const Bvh& bvh, const RaySetup& setup);
// The directions (N × 4) as the packet kernels read them: x, y, z as three rows of
// paddedCount floats, N rounded up to a multiple of 16 (padding lanes are zero).
std::vector<float> packetDirections(const std::vector<float>& dirs, int& paddedCount);
void checkTransportOptions(const TransportOptions& options);
// The size of the vertex range [first, first + count) (count: the rest of the mesh when
// unset); UsageError when it leaves the mesh.
size_t vertexRangeSize(const Mesh& mesh, size_t first, const std::optional<size_t>& count);
// Albedo per vertex (override applied), V × 4.
std::vector<float> vertexAlbedo(const Mesh& mesh, const TransportOptions& options);
bool transportIsRgb(const Mesh& mesh, const TransportOptions& options);

}  // namespace prtbake::detail
