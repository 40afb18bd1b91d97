// The probe grid for three.js r187's LightProbeGridWebGL: its atlas as a KTX 2.0 3D texture and
// an ES module that loads it (probes.h "three.js", docs/probes.md "three.js").
//
// What three reads (examples/jsm/lighting/LightProbeGridWebGL.js, ShaderChunk/
// lightprobes_pars_fragment.glsl.js): its bake projects radiance onto the basis 0.282095,
// 0.488603 (y, z, x), 1.092548 (xy, yz), 0.315392 (3z² − 1), 1.092548 xz, 0.546274 (x² − y²), the
// orthonormal real SH without the Condon–Shortley phase, and its repack pass writes the 27
// numbers k_0.rgb … k_8.rgb four at a time into seven RGBA sub-volumes (t = 0: k0.rgb k1.r;
// t = 1: k1.gb k2.rg; … t = 6: k8.rgb 0). The shader samples each sub-volume with the linear filter
// at the clamped probe coordinate and evaluates E(n) = Σ Â_l k_i Y'_i(n) (0.886227 = π · 0.282095,
// 2 · 0.511664 = 2π/3 · 0.488603, …). So the file holds k_lm = c_lm (−1)^m, unscaled radiance.
#include <algorithm>
#include <array>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "io/ktx2.h"
#include "probes/probe_grid_check.h"
#include "prtbake/error.h"
#include "prtbake/probes.h"

namespace prtbake {
namespace {

constexpr int kThreeOrder = 3;        // LightProbeGridWebGL holds L2 SH: 9 coefficients
constexpr int kSubVolumes = 7;        // ⌈27 / 4⌉ RGBA sub-volumes
constexpr int kAtlasPadding = 1;      // copies of the edge slice at each end of a sub-volume

void checkThreejsGrid(const ProbeGridResult& grid) {
  if (grid.order != kThreeOrder)
    throw UsageError("--target", "three.js's LightProbeGrid holds L2 SH (order 3); this grid has order " +
                                     std::to_string(grid.order));
  checkProbeGridShape(grid);
}

// The atlas, RGBA floats, x fastest, then y, then the 7 (NZ + 2) slices.
std::vector<float> threejsAtlas(const ProbeGridResult& grid) {
  const auto [nx, ny, nz] = grid.layout.resolution;
  const int padded = nz + 2 * kAtlasPadding;
  const size_t sliceTexels = size_t(nx) * size_t(ny);
  std::vector<float> atlas(sliceTexels * size_t(kSubVolumes * padded) * 4);
  // The 27 numbers in three's basis, per probe: sign (−1)^m on coefficient (l, m).
  std::array<float, 9> sign{};
  for (int l = 0; l < kThreeOrder; ++l)
    for (int m = -l; m <= l; ++m) sign[size_t(shIndex(l, m))] = float(shCondonShortleyPhase(m));
  for (int t = 0; t < kSubVolumes; ++t)
    for (int slice = 0; slice < padded; ++slice) {
      const int k = std::clamp(slice - kAtlasPadding, 0, nz - 1);  // the probe slice it holds (padding: the edge's)
      float* out = atlas.data() + (size_t(t * padded + slice) * sliceTexels) * 4;
      for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) {
          const float* c = grid.probe((size_t(k) * size_t(ny) + size_t(j)) * size_t(nx) + size_t(i));
          for (int comp = 0; comp < 4; ++comp) {
            const int f = 4 * t + comp;  // 0 … 27: coefficient f / 3, channel f % 3 (27: the unused alpha)
            *out++ = f < 27 ? sign[size_t(f / 3)] * c[f] : 0.0f;
          }
        }
    }
  return atlas;
}

std::string jsNumber(double v) { return nlohmann::json(v).dump(); }

}  // namespace

std::string probeGridThreejsKtx2Bytes(const ProbeGridResult& grid) {
  checkThreejsGrid(grid);
  const ProbeGridLayout& g = grid.layout;
  const std::vector<float> atlas = threejsAtlas(grid);
  ktx2::Layout layout;
  layout.width = uint32_t(g.resolution[0]);
  layout.height = uint32_t(g.resolution[1]);
  layout.depth = uint32_t(kSubVolumes * (g.resolution[2] + 2 * kAtlasPadding));
  const nlohmann::json meta = {
      {"layout", "three.js r187 LightProbeGridWebGL atlas: 7 sub-volumes of NZ + 2 slices along z (docs/probes.md)"},
      {"resolution", g.resolution},
      {"bounds_min", g.boundsMin},
      {"bounds_max", g.boundsMax},
      {"quantity", "radiance SH, order 3, real orthonormal basis without the Condon-Shortley phase (three.js)"}};
  return ktx2::rgbaFloatBytes(layout, {{atlas.data(), 4, atlas.size() / 4}}, {{"prtbake.probes", meta.dump()}});
}

std::string probeGridThreejsLoaderBytes(const ProbeGridResult& grid, const std::string& ktx2Name) {
  checkThreejsGrid(grid);
  const ProbeGridLayout& g = grid.layout;
  std::string size, centre;
  for (size_t a = 0; a < 3; ++a) {
    size += (a ? ", " : "") + jsNumber(g.boundsMax[a] - g.boundsMin[a]);
    centre += (a ? ", " : "") + jsNumber(0.5 * (g.boundsMin[a] + g.boundsMax[a]));
  }
  const std::string resolution = std::to_string(g.resolution[0]) + ", " + std::to_string(g.resolution[1]) + ", " +
                                 std::to_string(g.resolution[2]);
  const std::string probes = std::to_string(g.resolution[0]) + " x " + std::to_string(g.resolution[1]) + " x " +
                             std::to_string(g.resolution[2]);
  return "// A prtbake light probe grid for three.js r187 (docs/probes.md \"three.js\"): " + probes +
         " probes over the box of size (" + size + ") centred at (" + centre + "),\n"
         "// L2 radiance SH in the atlas " + ktx2Name + ". Needs an import map for 'three' and 'three/addons/'.\n"
         "//   const grid = await loadProbeGrid(renderer, scene);\n"
         "// The grid lights meshes whose materials take lights (Lambert, Phong, Standard, Physical) inside the box;\n"
         "// keep it a child of the scene itself (three takes its bounds from its position, not its world matrix).\n"
         "import { LinearFilter } from 'three';\n"
         "import { KTX2Loader } from 'three/addons/loaders/KTX2Loader.js';\n"
         "import { LightProbeGridWebGL } from 'three/addons/lighting/LightProbeGridWebGL.js';\n"
         "\n"
         "export async function loadProbeGrid(renderer, scene, url = new URL(" + nlohmann::json(ktx2Name).dump() +
         ", import.meta.url).href) {\n"
         "  const texture = await new KTX2Loader().detectSupport(renderer).loadAsync(url);\n"
         "  // KTX2Loader filters raw textures with NEAREST; the shader blends neighbouring probes with LINEAR.\n"
         "  texture.minFilter = LinearFilter;\n"
         "  texture.magFilter = LinearFilter;\n"
         "  texture.needsUpdate = true;\n"
         "  const grid = new LightProbeGridWebGL(" + size + ", " + resolution + ");\n"
         "  grid.position.set(" + centre + ");\n"
         "  grid.updateBoundingBox();  // the bounds the shader reads (bake() would set them; it is not called)\n"
         "  grid.texture = texture;\n"
         "  scene.add(grid);\n"
         "  return grid;\n"
         "}\n";
}

}  // namespace prtbake
