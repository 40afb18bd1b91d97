// The direct term over a subset of vertices, and the unoccludable-vertex test
// (see transport_direct.h and transport.h).
#include "transport_direct.h"

#include <algorithm>
#include <cmath>

#include "prtbake/error.h"

namespace prtbake {
namespace detail {
namespace {
constexpr size_t kLocalSize = 16;  // as in transport.cpp

}  // namespace

// A vertex p with unit normal n and ray origin o = p + h' (h = n·(o − p) > 0 its height
// above p's tangent plane) can be occluded only by a triangle with a point q above the
// plane n·q = n·o: a ray o + t d with n·d ≥ 0 never goes below that height. Triangles
// are the convex hulls of their corners, so it suffices that every corner satisfies
// n·q ≤ n·p + h/2 (half the offset: margin for the float origin). A BVH node whose box
// has max_{q ∈ box} n·q = Σ_c max(n_c bmin_c, n_c bmax_c) below that is skipped whole.
std::vector<uint8_t> unoccludableFromBvh(const Mesh& mesh, const Bvh& bvh, const RaySetup& setup) {
  const size_t nv = mesh.vertexCount();
  std::vector<uint8_t> out(nv, 0);
  const auto& P = mesh.positions;
  std::vector<int> stack;
  stack.reserve(128);
  for (size_t v = 0; v < nv; ++v) {
    const float* f = &setup.frames[12 * v + 8];
    const double n[3] = {f[0], f[1], f[2]};
    const double nn = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    if (!(nn > 0)) continue;  // no normal: zero transport, nothing traced anyway
    double np = 0, h = 0;
    for (int c = 0; c < 3; ++c) {
      np += n[c] * P[3 * v + c];
      h += n[c] * (double(setup.origins[4 * v + c]) - P[3 * v + c]);
    }
    if (!(h > 0)) continue;
    const double thr = np + 0.5 * h;
    bool blocked = false;
    if (!bvh.nodes.empty()) stack.assign(1, 0);
    else stack.clear();
    while (!stack.empty() && !blocked) {
      const Bvh::Node& node = bvh.nodes[size_t(stack.back())];
      const int idx = stack.back();
      stack.pop_back();
      double top = 0;
      for (int c = 0; c < 3; ++c) top += std::max(n[c] * node.bmin[c], n[c] * node.bmax[c]);
      if (top <= thr) continue;
      if (node.count > 0) {
        for (int i = 0; i < node.count && !blocked; ++i) {
          const uint32_t t = bvh.triangles[size_t(node.offset) + i];
          for (int k = 0; k < 3 && !blocked; ++k) {
            const uint32_t q = mesh.indices[3 * size_t(t) + k];
            const double d = n[0] * P[3 * q] + n[1] * P[3 * q + 1] + n[2] * P[3 * q + 2];
            if (d > thr) blocked = true;
          }
        }
      } else {
        stack.push_back(node.offset);
        stack.push_back(idx + 1);
      }
    }
    out[v] = blocked ? 0 : 1;
  }
  return out;
}

void DirectRunner::run(const RaySetup& setup, const std::vector<uint32_t>& vertices, bool visibility,
                       std::vector<float>& coeffs, std::vector<float>& visible) {
  const int nc = o_.order * o_.order;
  const int nv = int(vertices.size());
  const int ns = int(setup.dirs.size() / 4);
  coeffs.assign(size_t(nv) * nc, 0.0f);
  visible.assign(size_t(nv), 0.0f);
  if (nv == 0) return;
  std::vector<float> origins(size_t(nv) * 4), frames(size_t(nv) * 12);
  for (int i = 0; i < nv; ++i) {
    std::copy_n(&setup.origins[4 * size_t(vertices[i])], 4, &origins[4 * size_t(i)]);
    std::copy_n(&setup.frames[12 * size_t(vertices[i])], 12, &frames[12 * size_t(i)]);
  }
  const bool packet = o_.packetWidth > 0;
  int padded = 0;
  const std::vector<float> dirs = packet ? packetDirections(setup.dirs, padded) : setup.dirs;
  const std::string opts = "-DSH_ORDER=" + std::to_string(o_.order) + " -DVISIBILITY=" + (visibility ? "1" : "0") +
                           " -DCHANNELS=1 -DBVH_PACKET=" + std::to_string(o_.packetWidth);
  cl::Kernel k = rt_.kernel("transport.cl", packet ? "transport_direct_packet" : "transport_direct", opts);
  cl::Buffer ob = rt_.upload(origins), fb = rt_.upload(frames), db = rt_.upload(dirs);
  cl::Buffer cb(rt_.context(), CL_MEM_READ_WRITE, coeffs.size() * 4), vb(rt_.context(), CL_MEM_READ_WRITE, visible.size() * 4);
  k.setArg(0, nv);
  k.setArg(1, ns);
  k.setArg(2, ob);
  k.setArg(3, fb);
  k.setArg(4, db);
  k.setArg(5, nodes_);
  k.setArg(6, tris_);
  k.setArg(7, tMax_);
  k.setArg(8, cb);
  k.setArg(9, vb);
  if (packet) k.setArg(10, padded);
  auto& q = rt_.queue();
  q.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange((size_t(nv) + kLocalSize - 1) / kLocalSize * kLocalSize),
                         cl::NDRange(kLocalSize));
  q.enqueueReadBuffer(cb, CL_TRUE, 0, coeffs.size() * 4, coeffs.data());
  q.enqueueReadBuffer(vb, CL_TRUE, 0, visible.size() * 4, visible.data());
}

}  // namespace detail

std::vector<uint8_t> unoccludableVertices(const Mesh& mesh) {
  TransportOptions o;
  o.samples = 1;
  const detail::RaySetup setup = detail::makeRaySetup(mesh, o);
  return detail::unoccludableFromBvh(mesh, buildBvh(mesh), setup);
}

}  // namespace prtbake
