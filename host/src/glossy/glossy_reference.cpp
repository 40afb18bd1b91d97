// Double-precision references of the glossy transfer: the CPU reference on the kernel's
// rays, and the closed forms (visible cone, hemisphere, Gaunt coefficients, truncation).
#include <algorithm>
#include <cmath>

#include "core/constants.h"
#include "core/gauss_legendre.h"
#include "geometry/ray_triangle.h"
#include "glossy/glossy_detail.h"
#include "prtbake/error.h"
#include "prtbake/sh.h"
#include "prtbake/sh_rotate.h"
#include "transport/transport_setup.h"

namespace prtbake {
namespace {

// A rotation taking +z to the unit vector n (columns t, b, n; right-handed).
Rotation frameOf(const std::array<double, 3>& n) {
  const double sign = std::copysign(1.0, n[2]);
  const double a = -1.0 / (sign + n[2]), b = n[0] * n[1] * a;
  const double t[3] = {1 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]};
  const double bb[3] = {b, sign + n[1] * n[1] * a, -n[1]};
  Rotation r;
  for (int c = 0; c < 3; ++c) {
    r.m[3 * c + 0] = t[c];
    r.m[3 * c + 1] = bb[c];
    r.m[3 * c + 2] = n[c];
  }
  return r;
}

}  // namespace

GlossyResult computeGlossyReference(const Mesh& mesh, const GlossyOptions& o, const std::vector<float>* diffuse,
                                    int diffuseChannels) {
  checkGlossyOptions(o);
  validateMesh(mesh, mesh.sourcePath.empty() ? "mesh" : mesh.sourcePath);
  const TransportOptions to = detail::glossyTransportOptions(o);
  const detail::RaySetup setup = detail::makeRaySetup(mesh, to, false);
  const bool visibility = o.mode != TransportMode::Unshadowed, bounce = o.mode == TransportMode::Interreflected;
  const int nmax = std::max(o.orderIn, o.orderOut), no2 = o.orderOut * o.orderOut, ni2 = o.orderIn * o.orderIn;
  GlossyResult r;
  GlossyStats& st = r.stats;
  st.orderOut = o.orderOut, st.orderIn = o.orderIn;
  st.channels = detail::glossyChannels(mesh, o);
  const size_t nv = mesh.vertexCount(), first = o.firstVertex, count = o.vertexCount ? *o.vertexCount : nv - first;
  st.vertexCount = count, st.firstVertex = first, st.samples = visibility ? o.samples : 0;
  st.device = "CPU reference (double)";
  if (bounce && (!diffuse || diffuse->size() != nv * size_t(diffuseChannels) * ni2))
    throw UsageError("reference", "interreflection needs the diffuse transport of every vertex");
  // The kernel's directions: every chunk of the seed's set (weights 1, scaled by 2π/N),
  // or the product rule.
  std::vector<float> dirs;
  double scale = 1;
  if (!visibility) {
    dirs = detail::productRuleDirections(nmax);
  } else {
    for (int f = 0; f < o.samples; f += 1024) {
      const std::vector<float> c = glossyDirectionChunk(o.samples, f, std::min(1024, o.samples - f), o.seed);
      dirs.insert(dirs.end(), c.begin(), c.end());
    }
    scale = 2 * kPi / o.samples;
  }
  const size_t ns = dirs.size() / 4, nt = mesh.triangleCount();
  std::vector<double> tri(nt * 9);
  for (size_t t = 0; t < nt; ++t)
    for (int k = 0; k < 3; ++k)
      for (int c = 0; c < 3; ++c) tri[9 * t + 3 * k + c] = mesh.positions[3 * size_t(mesh.indices[3 * t + k]) + c];
  const std::vector<float> albedo = detail::vertexAlbedo(mesh, to);
  const int ch = st.channels;
  const size_t per = st.valuesPerVertex();
  r.matrices.assign(count * per, 0.0f);
  std::vector<double> m(size_t(ch) * no2 * ni2), y(size_t(nmax) * nmax);
  for (size_t i = 0; i < count; ++i) {
    const size_t v = first + i;
    const float* n = &setup.frames[12 * v + 8];
    if (n[0] == 0 && n[1] == 0 && n[2] == 0) continue;
    std::fill(m.begin(), m.end(), 0.0);
    for (size_t s = 0; s < ns; ++s) {
      double org[3], dir[3];
      for (int c = 0; c < 3; ++c) {
        org[c] = setup.origins[4 * v + c];
        dir[c] = double(setup.frames[12 * v + c]) * dirs[4 * s] + double(setup.frames[12 * v + 4 + c]) * dirs[4 * s + 1] +
                 double(setup.frames[12 * v + 8 + c]) * dirs[4 * s + 2];
      }
      const double w = dirs[4 * s + 3];
      shEval(nmax, dir[0], dir[1], dir[2], y.data());
      detail::TriangleHit best{setup.tMax, 0, 0, false};
      size_t bestTri = 0;
      if (visibility)
        for (size_t t = 0; t < nt; ++t) {
          const detail::TriangleHit h = detail::intersectTriangle(
              org, dir, &tri[9 * t], &tri[9 * t + 3], &tri[9 * t + 6], best.t);
          if (h.ok) {
            best = h, bestTri = t;
            if (!bounce) break;
          }
        }
      if (!best.ok) {
        for (int c = 0; c < ch; ++c)
          for (int a = 0; a < no2; ++a)
            for (int b = 0; b < ni2; ++b) m[(size_t(c) * no2 + a) * ni2 + b] += w * y[a] * y[b];
      } else if (bounce) {
        const uint32_t* id = &mesh.indices[3 * bestTri];
        const double bw[3] = {1 - best.u - best.v, best.u, best.v};
        for (int c = 0; c < ch; ++c) {
          double rho = 0;
          for (int k = 0; k < 3; ++k) rho += bw[k] * albedo[4 * size_t(id[k]) + c];
          const int tc = diffuseChannels == 3 ? c : 0;
          for (int b = 0; b < ni2; ++b) {
            double tq = 0;
            for (int k = 0; k < 3; ++k) tq += bw[k] * (*diffuse)[(size_t(id[k]) * diffuseChannels + tc) * ni2 + b];
            for (int a = 0; a < no2; ++a) m[(size_t(c) * no2 + a) * ni2 + b] += w * y[a] * rho * tq;
          }
        }
      }
    }
    for (size_t k = 0; k < m.size(); ++k) r.matrices[i * per + k] = float(m[k] * scale);
  }
  return r;
}

std::vector<double> coneGramMatrix(int order, const std::array<double, 3>& n, double halfAngle) {
  // In the frame of n (z = n) the cone is zonal: with Y_lm = √2 K_l^|m| P_l^|m|(z) cos(mφ)
  // (sin for m < 0) or K_l^0 P_l(z), only equal m couple and
  //   M_z[(l,m),(l',m)] = 2π K_l^|m| K_l'^|m| ∫_{cos α}^1 P_l^|m| P_l'^|m| dz
  //                     = c_m ∫_{cos α}^1 Y_lm(z, φ=0) Y_l'm(z, φ=0) dz,  c_0 = 2π, c_m = π,
  // for |m| taken at φ = 0 (Y at azimuth 0 holds √2 K P for m > 0). P_l^m P_l'^m is
  // (1 − z²)^m times a polynomial of degree l + l' − 2m: degree ≤ 2(order − 1), which the
  // (order + 1)-point Gauss–Legendre rule integrates exactly. Then M(n) = S M_z Sᵀ with S
  // the exact SH rotation of R (R z = n): Y_j(Rω) = Σ_k S_jk Y_k(ω).
  const int nc = order * order;
  const double c0 = std::cos(halfAngle);
  const detail::GaussRule g = detail::gaussLegendre(order + 1);
  std::vector<double> mz(size_t(nc) * nc, 0.0), y(static_cast<size_t>(nc));
  for (size_t q = 0; q < g.x.size(); ++q) {
    const double z = c0 + (1 - c0) * g.x[q], w = (1 - c0) * g.w[q];
    shEval(order, std::sqrt(std::max(0.0, 1 - z * z)), 0.0, z, y.data());
    for (int l = 0; l < order; ++l)
      for (int l2 = 0; l2 < order; ++l2)
        for (int m = 0; m <= std::min(l, l2); ++m) {
          const double v = (m == 0 ? 2 * kPi : kPi) * w * y[size_t(shIndex(l, m))] * y[size_t(shIndex(l2, m))];
          mz[size_t(shIndex(l, m)) * nc + size_t(shIndex(l2, m))] += v;
          if (m > 0) mz[size_t(shIndex(l, -m)) * nc + size_t(shIndex(l2, -m))] += v;
        }
  }
  const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  const ShRotationBlocks blocks = shRotationExact(frameOf({n[0] / len, n[1] / len, n[2] / len}), order);
  std::vector<double> s(size_t(nc) * nc, 0.0);
  for (int l = 0; l < order; ++l)
    for (int a = 0; a < 2 * l + 1; ++a)
      for (int b = 0; b < 2 * l + 1; ++b)
        s[size_t(l * l + a) * nc + size_t(l * l + b)] = blocks[size_t(l)][size_t(a) * (2 * l + 1) + b];
  std::vector<double> tmp(size_t(nc) * nc, 0.0), out(size_t(nc) * nc, 0.0);
  for (int i = 0; i < nc; ++i)
    for (int k = 0; k < nc; ++k)
      for (int j = 0; j < nc; ++j) tmp[size_t(i) * nc + j] += s[size_t(i) * nc + k] * mz[size_t(k) * nc + j];
  for (int i = 0; i < nc; ++i)
    for (int k = 0; k < nc; ++k)
      for (int j = 0; j < nc; ++j) out[size_t(i) * nc + j] += tmp[size_t(i) * nc + k] * s[size_t(j) * nc + k];
  return out;
}

std::vector<double> gauntCoefficients(int order, int kOrder) {
  // Exact product rule over the sphere: Y_i Y_j Y_k has degree ≤ D = 2(order−1) + kOrder−1;
  // D + 1 azimuths and ⌈(D+1)/2⌉ Gauss–Legendre nodes in z ∈ [−1, 1].
  const int nc = order * order, kc = kOrder * kOrder, deg = 2 * (order - 1) + kOrder - 1;
  const int nphi = deg + 2, nz = deg / 2 + 2, nmax = std::max(order, kOrder);
  const detail::GaussRule g = detail::gaussLegendre(nz);
  std::vector<double> out(size_t(nc) * nc * kc, 0.0), y(size_t(nmax) * nmax);
  for (int q = 0; q < nz; ++q)
    for (int p = 0; p < nphi; ++p) {
      const double z = 2 * g.x[q] - 1, w = 2 * g.w[q] * 2 * kPi / nphi, r = std::sqrt(std::max(0.0, 1 - z * z));
      const double phi = 2 * kPi * (p + 0.5) / nphi;
      shEval(nmax, r * std::cos(phi), r * std::sin(phi), z, y.data());
      for (int i = 0; i < nc; ++i)
        for (int j = 0; j < nc; ++j) {
          const double a = w * y[size_t(i)] * y[size_t(j)];
          for (int k = 0; k < kc; ++k) out[(size_t(i) * nc + j) * kc + k] += a * y[size_t(k)];
        }
    }
  return out;
}

double clampedCosineTruncationBound(int orderOut) {
  // Â_l² ~ l^−5: the terms fall like l^−4; the tail past 4000 is below 1e-12 of the sum.
  double s = 0;
  for (int l = orderOut; l < 4000; ++l) {
    const double a = clampedCosineFactor(l) / kPi;
    s += (2 * l + 1) / (4 * kPi) * a * a;
  }
  return std::sqrt(s);
}

}  // namespace prtbake
