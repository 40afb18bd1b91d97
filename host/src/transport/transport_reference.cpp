// Double-precision CPU reference of the transport kernels: the same rays (origins,
// frames, directions), brute force over every triangle, exact inclusive edges.
#include <algorithm>
#include <cmath>
#include <vector>

#include "geometry/ray_triangle.h"
#include "prtbake/error.h"
#include "prtbake/sh.h"
#include "prtbake/transport.h"
#include "transport/transport_setup.h"

namespace prtbake {
namespace {

// The kernels' rays over every triangle in double: the rays from the float set-up the
// kernels read, each tested against every triangle.
class BruteForce {
 public:
  BruteForce(const Mesh& mesh, const detail::RaySetup& setup) : mesh_(mesh), setup_(setup) {
    const size_t nt = mesh.triangleCount();
    tri_.resize(nt * 9);
    for (size_t t = 0; t < nt; ++t)
      for (int k = 0; k < 3; ++k)
        for (int c = 0; c < 3; ++c) tri_[9 * t + 3 * k + c] = mesh.positions[3 * size_t(mesh.indices[3 * t + k]) + c];
  }

  bool hasNormal(size_t v) const {
    const float* n = &setup_.frames[12 * v + 8];
    return n[0] != 0 || n[1] != 0 || n[2] != 0;
  }

  // T^(0): the mean of the SH of the unblocked directions; each ray's visibility and its
  // nearest edge in *rays when asked.
  std::vector<double> direct(const TransportOptions& o, bool visibility, ReferenceRays* rays) const {
    const int nc = o.order * o.order, ns = o.samples;
    const size_t nv = mesh_.vertexCount(), nt = mesh_.triangleCount();
    std::vector<double> t0(nv * nc, 0.0), y(nc);
    for (size_t v = 0; v < nv; ++v) {
      if (!hasNormal(v)) continue;
      for (int s = 0; s < ns; ++s) {
        double org[3], dir[3];
        ray(v, s, org, dir);
        bool blocked = false;
        double nearEdge = 1.0;
        if (visibility)
          for (size_t t = 0; t < nt; ++t) {
            const detail::TriangleHit h = hit(org, dir, t, setup_.tMax);
            if (h.t > 0 && h.t < setup_.tMax && std::isfinite(h.u))
              nearEdge = std::min(nearEdge, std::abs(std::min({h.u, h.v, 1 - h.u - h.v})));
            if (h.ok) {
              blocked = true;
              if (!rays) break;
            }
          }
        if (rays) {
          rays->visible[v * ns + s] = blocked ? 0 : 1;
          rays->edgeDistance[v * ns + s] = nearEdge;
        }
        if (blocked) continue;
        shEval(o.order, dir[0], dir[1], dir[2], y.data());
        for (int k = 0; k < nc; ++k) t0[v * nc + k] += y[k];
      }
      for (int k = 0; k < nc; ++k) t0[v * nc + k] /= ns;
    }
    return t0;
  }

  // One bounce: next = the albedo-weighted previous bounce at each ray's nearest hit, averaged
  // (ch channels of nc coefficients per vertex); returns the largest per-vertex norm.
  double bounce(const TransportOptions& o, const std::vector<float>& albedo, int ch, const std::vector<double>& prev,
                std::vector<double>& next) const {
    const int nc = o.order * o.order, ns = o.samples, stride = ch * nc;
    const size_t nv = mesh_.vertexCount(), nt = mesh_.triangleCount();
    std::fill(next.begin(), next.end(), 0.0);
    double maxNorm = 0;
    for (size_t v = 0; v < nv; ++v) {
      if (!hasNormal(v)) continue;
      for (int s = 0; s < ns; ++s) {
        double org[3], dir[3];
        ray(v, s, org, dir);
        detail::TriangleHit best{setup_.tMax, 0, 0, false};
        size_t bestTri = 0;
        for (size_t t = 0; t < nt; ++t) {
          const detail::TriangleHit h = hit(org, dir, t, best.t);
          if (h.ok) best = h, bestTri = t;
        }
        if (!best.ok) continue;
        const uint32_t* id = &mesh_.indices[3 * bestTri];
        const double w[3] = {1 - best.u - best.v, best.u, best.v};
        for (int c = 0; c < ch; ++c) {
          double rho = 0;
          for (int k = 0; k < 3; ++k) rho += w[k] * albedo[4 * size_t(id[k]) + c];
          for (int k = 0; k < nc; ++k) {
            double tq = 0;
            for (int j = 0; j < 3; ++j) tq += w[j] * prev[size_t(id[j]) * stride + c * nc + k];
            next[v * stride + c * nc + k] += rho * tq / ns;
          }
        }
      }
      double n2 = 0;
      for (int k = 0; k < stride; ++k) n2 += next[v * stride + k] * next[v * stride + k];
      maxNorm = std::max(maxNorm, std::sqrt(n2));
    }
    return maxNorm;
  }

 private:
  // Ray s of vertex v in double.
  void ray(size_t v, int s, double* org, double* dir) const {
    for (int c = 0; c < 3; ++c) {
      org[c] = setup_.origins[4 * v + c];
      dir[c] = double(setup_.frames[12 * v + c]) * setup_.dirs[4 * s] +
               double(setup_.frames[12 * v + 4 + c]) * setup_.dirs[4 * s + 1] +
               double(setup_.frames[12 * v + 8 + c]) * setup_.dirs[4 * s + 2];
    }
  }

  detail::TriangleHit hit(const double* org, const double* dir, size_t t, double tMax) const {
    return detail::intersectTriangle(org, dir, &tri_[9 * t], &tri_[9 * t + 3], &tri_[9 * t + 6], tMax);
  }

  const Mesh& mesh_;
  const detail::RaySetup& setup_;
  std::vector<double> tri_;
};

}  // namespace

TransportResult computeTransportReference(const Mesh& mesh, const TransportOptions& o, ReferenceRays* rays) {
  detail::checkTransportOptions(o);
  validateMesh(mesh, mesh.sourcePath.empty() ? "mesh" : mesh.sourcePath);
  const detail::RaySetup setup = detail::makeRaySetup(mesh, o);
  TransportResult r;
  r.order = o.order;
  r.samples = o.samples;
  r.vertexCount = mesh.vertexCount();
  r.device = "CPU reference (double)";
  r.channels = detail::transportIsRgb(mesh, o) ? 3 : 1;
  const int nc = o.order * o.order;
  const size_t nv = mesh.vertexCount();
  if (rays) {
    rays->visible.assign(nv * size_t(o.samples), 1);
    rays->edgeDistance.assign(nv * size_t(o.samples), 1.0);
  }
  const BruteForce brute(mesh, setup);
  const std::vector<double> t0 = brute.direct(o, o.mode != TransportMode::Unshadowed, rays);
  const int ch = r.channels, stride = ch * nc;
  std::vector<double> prev(nv * stride);
  for (size_t v = 0; v < nv; ++v)
    for (int c = 0; c < ch; ++c)
      for (int k = 0; k < nc; ++k) prev[v * stride + c * nc + k] = t0[v * nc + k];
  std::vector<double> total = prev;
  if (o.mode == TransportMode::Interreflected) {
    const std::vector<float> albedo = detail::vertexAlbedo(mesh, o);
    std::vector<double> next(nv * stride);
    for (int b = 1; b <= o.bounces; ++b) {
      const double maxNorm = brute.bounce(o, albedo, ch, prev, next);
      for (size_t i = 0; i < total.size(); ++i) total[i] += next[i];
      r.bounceMaxNorm.push_back(maxNorm);
      r.bouncesUsed = b;
      if (maxNorm < o.bounceTolerance) break;
      prev.swap(next);
    }
  }
  r.coeffs.assign(total.begin(), total.end());
  return r;
}

}  // namespace prtbake
