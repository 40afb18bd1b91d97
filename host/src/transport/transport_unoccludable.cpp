// The unoccludable-vertex test (see unoccludableVertices in transport.h).
#include <algorithm>

#include "prtbake/bvh.h"
#include "prtbake/transport.h"
#include "bvh_types.h"
#include "core/parallel.h"
#include "transport/transport_setup.h"

namespace prtbake {
namespace detail {
// A vertex p with unit normal n and ray origin o = p + h' (h = n·(o − p) > 0 its height
// above p's tangent plane) can be occluded only by a triangle with a point q above the
// plane n·q = n·o: a ray o + t d with n·d ≥ 0 never goes below that height. Triangles
// are the convex hulls of their corners, so it suffices that every corner satisfies
// n·q ≤ n·p + h/2 (half the offset: margin for the float origin). A BVH node whose box
// has max_{q ∈ box} n·q = Σ_c max(n_c bmin_c, n_c bmax_c) below that is skipped whole.
// Vertices are independent: blocks of them on the host's threads.
std::vector<uint8_t> unoccludableFromBvh(const Mesh& mesh, const Bvh& bvh, const RaySetup& setup) {
  const size_t nv = setup.count();
  std::vector<uint8_t> out(nv, 0);
  const auto& P = setup.points;
  parallelFor(nv, hostThreads(), [&](size_t begin, size_t end, int) {
    std::vector<int> stack;
    stack.reserve(128);
    for (size_t v = begin; v < end; ++v) {
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
      // Depth first, the child reaching higher along n first: an occludable vertex (most
      // of them) meets a corner above the threshold within about one descent.
      auto top = [&](int i) {
        const Bvh::Node& b = bvh.nodes[size_t(i)];
        double t = 0;
        for (int c = 0; c < 3; ++c) t += std::max(n[c] * b.bmin[c], n[c] * b.bmax[c]);
        return t;
      };
      bool blocked = false;
      stack.clear();
      if (!bvh.nodes.empty() && top(0) > thr) stack.push_back(0);
      while (!stack.empty() && !blocked) {
        const int idx = stack.back();
        const Bvh::Node& node = bvh.nodes[size_t(idx)];
        stack.pop_back();
        if (node.count > 0) {
          for (int i = 0; i < node.count && !blocked; ++i) {
            const uint32_t t = bvh.triangles[size_t(node.offset) + i];
            for (int k = 0; k < 3 && !blocked; ++k) {
              const uint32_t q = mesh.indices[3 * size_t(t) + k];
              const float* Q = &mesh.positions[3 * size_t(q)];
              const double d = n[0] * Q[0] + n[1] * Q[1] + n[2] * Q[2];
              if (d > thr) blocked = true;
            }
          }
        } else {
          const int a = idx + 1, b = node.offset;
          const double ta = top(a), tb = top(b);
          const bool aFirst = ta >= tb;
          if ((aFirst ? tb : ta) > thr) stack.push_back(aFirst ? b : a);
          if ((aFirst ? ta : tb) > thr) stack.push_back(aFirst ? a : b);
        }
      }
      out[v] = blocked ? 0 : 1;
    }
  });
  return out;
}

cl::Buffer uploadBvhNodes(Runtime& rt, const Bvh& bvh, bool wide) {
  if (wide) {
    if (!bvh.wide.empty()) return rt.upload(bvh.wide);
    Bvh::WideNode none{};
    for (int k = 0; k < 4; ++k) {
      for (int c = 0; c < 3; ++c) none.bmin[c][k] = 1e30f, none.bmax[c][k] = -1e30f;
      none.count[k] = -1;
    }
    return rt.upload(std::vector<Bvh::WideNode>{none});
  }
  if (!bvh.nodes.empty()) return rt.upload(bvh.nodes);
  return rt.upload(std::vector<Bvh::Node>{Bvh::Node{{1, 1, 1}, 0, {-1, -1, -1}, 1}});
}

cl::Buffer uploadBvhTriangles(Runtime& rt, const Bvh& bvh, bool wide) {
  const std::vector<float>& t = wide ? bvh.blocks : bvh.packed;
  if (!t.empty()) return rt.upload(t);
  return rt.upload(std::vector<float>(wide ? 4 * BVH_BLOCK_FLOAT4S : 4 * BVH_TRI_FLOAT4S, 0.0f));
}

}  // namespace detail

std::vector<uint8_t> unoccludableVertices(const Mesh& mesh) {
  TransportOptions o;
  o.samples = 1;
  const detail::RaySetup setup = detail::makeRaySetup(mesh, o, false);
  return detail::unoccludableFromBvh(mesh, buildBvh(mesh), setup);
}

}  // namespace prtbake
