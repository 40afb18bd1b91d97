// The probe grid preview: the scene lit by the grid as three.js's shader lights it, with a
// sphere at every probe shaded by that probe alone, beside a horizontal slice of the grid
// (see preview.h).
#include <algorithm>
#include <cmath>

#include "prtbake/error.h"
#include "prtbake/preview.h"
#include "prtbake/probes.h"
#include "prtbake/sh.h"

namespace prtbake {
namespace {

// E/π of one probe's coefficients at normal n (Σ_i Â_l/π P_i Y_i(n)).
std::array<double, 3> probeIrradianceOverPi(const ProbeGridResult& g, size_t probe, const double n[3]) {
  double y[9];
  shEval(g.order, n[0], n[1], n[2], y);
  std::array<double, 3> e{};
  for (int l = 0, i = 0; l < g.order; ++l)
    for (int m = -l; m <= l; ++m, ++i)
      for (int c = 0; c < 3; ++c) e[c] += clampedCosineFactor(l) / 3.14159265358979323846 * g.probe(probe)[3 * i + c] * y[i];
  return e;
}

}  // namespace

LinearImage renderProbeGridPreview(Runtime& rt, const Mesh& scene, const ProbeGridResult& g,
                                   const MeshPreviewOptions& view, int maxSpheres) {
  if (g.probeCount != g.layout.count() || g.coeffs.size() != g.probeCount * size_t(g.order) * g.order * 3)
    throw UsageError("preview", "the probe preview needs a whole grid");
  const auto cell = g.layout.cell();
  // The scene's vertices: E/π from the grid at three's sample point, half a cell out along the normal.
  Mesh m = scene;
  std::vector<float> t;
  t.reserve((scene.vertexCount() + 64) * 3);
  for (size_t v = 0; v < scene.vertexCount(); ++v) {
    std::array<double, 3> x, n;
    for (int a = 0; a < 3; ++a) n[a] = scene.normals[3 * v + a], x[a] = scene.positions[3 * v + a] + n[a] * cell[a] / 2;
    const auto e = probeGridIrradianceOverPi(g, x, n);
    t.insert(t.end(), {float(std::max(0.0, e[0])), float(std::max(0.0, e[1])), float(std::max(0.0, e[2]))});
  }
  // A white sphere per probe (every k-th along each axis beyond maxSpheres), shaded by that probe;
  // invalid probes' spheres red, so that a filled probe is seen as one.
  const auto& res = g.layout.resolution;
  int stride = 1;
  while (size_t((res[0] + stride - 1) / stride) * ((res[1] + stride - 1) / stride) * ((res[2] + stride - 1) / stride) >
         size_t(std::max(1, maxSpheres)))
    ++stride;
  const double radius = 0.15 * std::min({cell[0], cell[1], cell[2]});
  const Mesh ball = makeUvSphere(radius, 8, 16);
  for (int z = 0; z < res[2]; z += stride)
    for (int y = 0; y < res[1]; y += stride)
      for (int x = 0; x < res[0]; x += stride) {
        const size_t i = (size_t(z) * res[1] + y) * res[0] + x;
        Mesh b = ball;
        for (size_t v = 0; v < b.vertexCount(); ++v) {
          for (int a = 0; a < 3; ++a) b.positions[3 * v + a] += g.positions[3 * i + a];
          const double n[3] = {b.normals[3 * v], b.normals[3 * v + 1], b.normals[3 * v + 2]};
          const auto e = probeIrradianceOverPi(g, i, n);
          t.insert(t.end(), {float(std::max(0.0, e[0])), float(std::max(0.0, e[1])), float(std::max(0.0, e[2]))});
          if (g.state[i] == 2) b.albedo[3 * v + 1] = b.albedo[3 * v + 2] = 0.25f;
        }
        appendMesh(m, b);
      }
  TransportCoeffs tc;
  tc.order = 1;
  tc.channels = 3;
  tc.vertexCount = m.vertexCount();
  tc.coeffs = std::move(t);
  ShCoeffs white;  // L_o = ρ · 1 · T_0 = ρ E/π
  white.order = 1;
  white.rgb = {Rgb{1, 1, 1}};
  const MeshPreviewResult scenePanel = renderMeshPreview(rt, m, tc, white, view);

  // The slice: E/π for an upward normal over x (right) and z (down) at the grid's middle height,
  // as tall as the scene panel.
  const int h = scenePanel.image.height;
  const double sx = g.layout.boundsMax[0] - g.layout.boundsMin[0], sz = g.layout.boundsMax[2] - g.layout.boundsMin[2];
  const int w = std::max(1, int(std::lround(h * sx / sz)));
  LinearImage out;
  out.width = scenePanel.image.width + w;
  out.height = h;
  out.rgb.assign(size_t(out.width) * h * 3, 0.0f);
  for (int y = 0; y < h; ++y) {
    std::copy_n(&scenePanel.image.rgb[size_t(y) * scenePanel.image.width * 3], size_t(scenePanel.image.width) * 3,
                &out.rgb[size_t(y) * out.width * 3]);
    for (int x = 0; x < w; ++x) {
      const std::array<double, 3> p = {g.layout.boundsMin[0] + (x + 0.5) / w * sx,
                                       0.5 * (g.layout.boundsMin[1] + g.layout.boundsMax[1]),
                                       g.layout.boundsMin[2] + (y + 0.5) / h * sz};
      const auto e = probeGridIrradianceOverPi(g, p, {0, 1, 0});
      float* px = &out.rgb[(size_t(y) * out.width + scenePanel.image.width + x) * 3];
      for (int c = 0; c < 3; ++c) px[c] = float(std::max(0.0, e[c]));
    }
  }
  return out;
}

}  // namespace prtbake
