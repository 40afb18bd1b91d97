// The lightmap preview (see preview.h): the mesh with each product read from its lightmap at
// every pixel's UV, as an engine samples it, beside the flat atlas.
#include <algorithm>
#include <cmath>

#include "core/constants.h"
#include "preview/preview_camera.h"
#include "prtbake/error.h"
#include "prtbake/lightmap.h"
#include "prtbake/preview.h"
#include "prtbake/sh.h"

namespace prtbake {
namespace {

struct Product {
  LightmapProduct id;
  const char* label;
  const std::vector<float>* plane;
  size_t stride;  // floats per texel
};

// The display colour of `stride` interpolated floats: ao grey; bent as a normal map's colour
// (0.5 + b/2, stored so that the sRGB curve gives those bytes back); irradiance E/π; sh
// E/π = Σ_j D_j Y_j(n) along n (null: the L0 term alone, for the atlas); transport under a
// white sky (l_0 = √(4π): √(4π) T_0 per channel).
std::array<float, 3> shade(const Product& p, const LightmapResult& lm, const float* v, const double* n) {
  auto srgbToLinear = [](double s) {
    s = std::clamp(s, 0.0, 1.0);
    return float(s <= 0.04045 ? s / 12.92 : std::pow((s + 0.055) / 1.055, 2.4));
  };
  switch (p.id) {
    case kLightmapAo: return {v[0], v[0], v[0]};
    case kLightmapBent:
    case kLightmapBentTangent:
      return {srgbToLinear(0.5 + 0.5 * v[0]), srgbToLinear(0.5 + 0.5 * v[1]), srgbToLinear(0.5 + 0.5 * v[2])};
    case kLightmapIrradiance: return {v[0], v[1], v[2]};
    case kLightmapSh: {
      double y[9] = {0};
      const int count = lm.shOrder * lm.shOrder;
      if (n) shEval(lm.shOrder, n[0], n[1], n[2], y);
      else y[0] = 0.5 / std::sqrt(kPi);
      std::array<float, 3> e{};
      for (int j = 0; j < count; ++j)
        for (int c = 0; c < 3; ++c) e[size_t(c)] += float(v[3 * j + c] * y[j]);
      return e;
    }
    case kLightmapTransport: {
      const size_t nc = size_t(lm.order) * size_t(lm.order);
      const float s = float(std::sqrt(4 * kPi));
      if (lm.transportChannels == 3) return {s * v[0], s * v[nc], s * v[2 * nc]};
      return {s * v[0], s * v[0], s * v[0]};
    }
  }
  return {0, 0, 0};
}

// Bilinear lookup of a texel-major plane at UV (u, v) in glTF's convention (texel (x, y) covers
// u ∈ [x, x + 1]/W, v ∈ [y, y + 1]/H), clamped to the edge, as a sampler with linear filtering reads it.
void bilinear(const Product& p, int W, int H, double u, double v, float* out) {
  const double fx = std::clamp(u * W - 0.5, 0.0, double(W - 1)), fy = std::clamp(v * H - 0.5, 0.0, double(H - 1));
  const int x0 = int(fx), y0 = int(fy), x1 = std::min(x0 + 1, W - 1), y1 = std::min(y0 + 1, H - 1);
  const double ax = fx - x0, ay = fy - y0;
  const float* t[4] = {&(*p.plane)[(size_t(y0) * W + x0) * p.stride], &(*p.plane)[(size_t(y0) * W + x1) * p.stride],
                       &(*p.plane)[(size_t(y1) * W + x0) * p.stride], &(*p.plane)[(size_t(y1) * W + x1) * p.stride]};
  const double w[4] = {(1 - ax) * (1 - ay), ax * (1 - ay), (1 - ax) * ay, ax * ay};
  for (size_t c = 0; c < p.stride; ++c) out[c] = float(w[0] * t[0][c] + w[1] * t[1][c] + w[2] * t[2][c] + w[3] * t[3][c]);
}

}  // namespace

LinearImage renderLightmapPreview(Runtime& rt, const Mesh& mesh, const LightmapResult& lm, const MeshPreviewOptions& view) {
  if (!mesh.hasUvSet(lm.uvSet))
    throw InputError(mesh.sourcePath.empty() ? "mesh" : mesh.sourcePath,
                     "has no UV set " + std::to_string(lm.uvSet) + " (TEXCOORD_" + std::to_string(lm.uvSet) + "), the lightmap's");
  const int W = lm.width, H = lm.height;
  std::vector<Product> products;
  auto add = [&](LightmapProduct id, const char* label, const std::vector<float>& plane) {
    if (!(lm.products & id) || plane.empty()) return;
    if (W < 1 || H < 1 || plane.size() % lm.texels() != 0) throw UsageError("preview", std::string("the lightmap's ") + label + " does not match its size");
    products.push_back({id, label, &plane, plane.size() / lm.texels()});
  };
  add(kLightmapAo, "ao", lm.ao);
  add(kLightmapBent, "bent (object space, 0.5 + b/2)", lm.bent);
  add(kLightmapBentTangent, "bent_tangent (tangent space, 0.5 + b/2)", lm.bentTangent);
  add(kLightmapIrradiance, "irradiance (E/pi)", lm.irradiance);
  add(kLightmapSh, "sh: E/pi along n (atlas: L0)", lm.sh);
  add(kLightmapTransport, "transport under a white sky", lm.transport);
  if (products.empty()) throw UsageError("preview", "the lightmap holds no product");
  if (lm.state.size() != lm.texels()) throw UsageError("preview", "the lightmap's state does not match its size");

  // Which triangle each pixel sees: the mesh preview's camera and BVH, shaded white.
  TransportCoeffs unit;
  unit.order = 1, unit.channels = 1, unit.vertexCount = mesh.vertexCount();
  unit.coeffs.assign(mesh.vertexCount(), 1.0f);
  ShCoeffs white;
  white.order = 1;
  white.rgb = {Rgb{1, 1, 1}};
  const MeshPreviewResult seen = renderMeshPreview(rt, mesh, unit, white, view);
  const detail::Camera cam = detail::frameCamera(mesh, view);
  const int vw = view.width, vh = view.height, aw = vh;  // the atlas: a square as tall as the view
  const std::vector<float>& uv = mesh.uvs[size_t(lm.uvSet)];

  // Per pixel: the barycentrics of the camera ray's hit (Möller–Trumbore in double on the
  // triangle the kernel found), then the UV and the shading normal there.
  struct Hit { double u, v, n[3]; };
  std::vector<Hit> hits(size_t(vw) * vh);
  for (int y = 0; y < vh; ++y)
    for (int x = 0; x < vw; ++x) {
      const int t = seen.hitTriangle[size_t(y) * vw + x];
      if (t < 0) continue;
      const double px = 2.0 * (x + 0.5) / vw - 1.0, py = 1.0 - 2.0 * (y + 0.5) / vh;
      double d[3], p[3][3];
      for (int a = 0; a < 3; ++a) d[a] = cam.forward[a] + px * cam.right[a] + py * cam.up[a];
      const uint32_t* idx = &mesh.indices[3 * size_t(t)];
      for (int k = 0; k < 3; ++k)
        for (int a = 0; a < 3; ++a) p[k][a] = mesh.positions[3 * size_t(idx[k]) + a];
      double e1[3], e2[3], s[3];
      for (int a = 0; a < 3; ++a) e1[a] = p[1][a] - p[0][a], e2[a] = p[2][a] - p[0][a], s[a] = cam.eye[a] - p[0][a];
      auto cross = [](const double* a, const double* b, double* o) {
        o[0] = a[1] * b[2] - a[2] * b[1], o[1] = a[2] * b[0] - a[0] * b[2], o[2] = a[0] * b[1] - a[1] * b[0];
      };
      double pv[3], qv[3];
      cross(d, e2, pv);
      cross(s, e1, qv);
      const double det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
      double b1 = 0, b2 = 0;
      if (std::abs(det) > 0) {
        b1 = (s[0] * pv[0] + s[1] * pv[1] + s[2] * pv[2]) / det;
        b2 = (d[0] * qv[0] + d[1] * qv[1] + d[2] * qv[2]) / det;
      }
      b1 = std::clamp(b1, 0.0, 1.0), b2 = std::clamp(b2, 0.0, 1.0 - b1);
      const double w[3] = {1 - b1 - b2, b1, b2};
      Hit& h = hits[size_t(y) * vw + x];
      h.u = h.v = h.n[0] = h.n[1] = h.n[2] = 0;
      for (int k = 0; k < 3; ++k) {
        h.u += w[k] * uv[2 * size_t(idx[k])], h.v += w[k] * uv[2 * size_t(idx[k]) + 1];
        for (int a = 0; a < 3; ++a) h.n[a] += w[k] * mesh.normals[3 * size_t(idx[k]) + a];
      }
      const double len = std::sqrt(h.n[0] * h.n[0] + h.n[1] * h.n[1] + h.n[2] * h.n[2]);
      for (double& c : h.n) c = len > 0 ? c / len : 0;
    }

  // One row per product: the mesh (background mid grey), then the atlas (nearest texel; empty
  // texels dark blue), each labelled.
  LinearImage out;
  out.width = vw + aw;
  out.height = vh * int(products.size());
  out.rgb.assign(size_t(out.width) * out.height * 3, 0.0f);
  std::vector<float> value;
  for (size_t r = 0; r < products.size(); ++r) {
    const Product& p = products[r];
    value.assign(p.stride, 0.0f);
    auto put = [&](int x, int y, const std::array<float, 3>& c) {
      float* px = &out.rgb[3 * (size_t(int(r) * vh + y) * out.width + x)];
      px[0] = c[0], px[1] = c[1], px[2] = c[2];
    };
    for (int y = 0; y < vh; ++y)
      for (int x = 0; x < vw; ++x) {
        if (seen.hitTriangle[size_t(y) * vw + x] < 0) {
          put(x, y, {0.18f, 0.18f, 0.18f});
          continue;
        }
        const Hit& h = hits[size_t(y) * vw + x];
        bilinear(p, W, H, h.u, h.v, value.data());
        put(x, y, shade(p, lm, value.data(), h.n));
      }
    for (int y = 0; y < vh; ++y)
      for (int x = 0; x < aw; ++x) {
        const size_t tx = std::min(size_t(W) - 1, size_t(double(x) / aw * W)), ty = std::min(size_t(H) - 1, size_t(double(y) / vh * H));
        const size_t i = ty * size_t(W) + tx;
        put(vw + x, y, TexelState(lm.state[i]) == TexelState::Empty ? std::array<float, 3>{0.0f, 0.0f, 0.08f}
                                                                   : shade(p, lm, &(*p.plane)[i * p.stride], nullptr));
      }
    const std::string atlas = "atlas " + std::to_string(W) + "x" + std::to_string(H) + ", UV set " + std::to_string(lm.uvSet);
    for (int shadow : {1, 0}) {  // white on a black shadow: readable on white AO too
      drawText(out, 6 + shadow, int(r) * vh + 6 + shadow, p.label, shadow ? 0.0f : 1.0f, 2);
      drawText(out, vw + 6 + shadow, int(r) * vh + 6 + shadow, atlas, shadow ? 0.0f : 1.0f, 2);
    }
  }
  return out;
}

}  // namespace prtbake
