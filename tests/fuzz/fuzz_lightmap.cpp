// Fuzz target: a mesh's UV sets and tangents as `prtbake lightmap` reads them, through the
// bake's first stage (lightmapSamples: the UV checks, charts, overlap test, conservative
// rasterisation, each texel's sample), which needs no device.
// Input: byte 0: bit 0 names the file .obj (else bit 1: .glb, else .gltf); bits 2-3 the size
// (8 << k texels); bit 4 asks for UV set 1 (else the default: 1 where the mesh has it, else 0);
// then two parts: the file, and the external buffer "b.bin" that a .gltf may name.
#include <cmath>
#include <set>

#include "fuzz_target.h"
#include "prtbake/lightmap.h"
#include "prtbake/mesh.h"

using namespace prtbake;

PRTBAKE_FUZZ_TARGET(lightmap) {
  if (size < 1) return 0;
  fuzz::clearScratch();
  const uint8_t flags = data[0];
  const std::vector<std::string> parts = fuzz::splitParts(data + 1, size - 1, 2);
  fuzz::writeScratch("b.bin", parts[1]);
  const std::string path = fuzz::writeScratch((flags & 1) ? "in.obj" : (flags & 2) ? "in.glb" : "in.gltf", parts[0]);
  Mesh mesh;
  if (!fuzz::expectCleanFailure(path, [&] { mesh = loadMesh(path); })) return 0;
  const size_t nv = mesh.vertexCount();
  for (const std::vector<float>& uv : mesh.uvs)
    if (!uv.empty() && uv.size() != 2 * nv) fuzz::fail("a UV set's size differs from the vertex count");
  if (!mesh.tangents.empty()) {
    if (mesh.tangents.size() != 4 * nv) fuzz::fail("the tangents' size differs from the vertex count");
    for (size_t v = 0; v < nv; ++v) {
      const float* t = &mesh.tangents[4 * v];
      const double len = std::sqrt(double(t[0]) * t[0] + double(t[1]) * t[1] + double(t[2]) * t[2]);
      if ((len != 0 && std::abs(len - 1) > 1e-4) || (t[3] != 1 && t[3] != -1)) fuzz::fail("a tangent that is not unit or whose w is not ±1");
    }
  }
  LightmapOptions o;
  o.size = 8 << ((flags >> 2) & 3);
  o.uvSet = (flags & 16) ? 1 : -1;
  LightmapSamples s;
  if (!fuzz::expectCleanFailure(path, [&] { s = lightmapSamples(mesh, o); })) return 0;
  const size_t texels = s.lm.texels(), n = s.points.count();
  if (s.lm.width != o.size || s.lm.height != o.size || s.lm.state.size() != texels) fuzz::fail("the lightmap's size");
  if (s.texelOf.size() != n || s.reach.size() != n || s.points.normals.size() != 3 * n ||
      s.points.faceNormals.size() != 3 * n || (!s.tangentFrames.empty() && s.tangentFrames.size() != 6 * n) ||
      s.usable.size() != mesh.triangleCount())
    fuzz::fail("the samples' arrays disagree");
  std::set<uint32_t> seen;
  for (size_t i = 0; i < n; ++i) {
    if (s.texelOf[i] >= texels || !seen.insert(s.texelOf[i]).second) fuzz::fail("a sample's texel is out of range or twice");
    if (s.lm.state[s.texelOf[i]] != uint8_t(TexelState::Baked)) fuzz::fail("a sample's texel is not marked baked");
    for (int c = 0; c < 3; ++c)
      if (!std::isfinite(s.points.positions[3 * i + c])) fuzz::fail("a sample's position is not finite");
    for (const std::vector<float>* v : {&s.points.normals, &s.points.faceNormals}) {
      const float* q = &(*v)[3 * i];
      if (std::abs(std::sqrt(double(q[0]) * q[0] + double(q[1]) * q[1] + double(q[2]) * q[2]) - 1) > 1e-3)
        fuzz::fail("a sample's normal is not unit");
    }
    if (!(s.reach[i] >= 0) || !std::isfinite(s.reach[i])) fuzz::fail("a sample's reach is not finite");
  }
  size_t baked = 0;
  for (uint8_t st : s.lm.state) baked += st == uint8_t(TexelState::Baked);
  if (baked != n) fuzz::fail("texels marked baked without a sample");
  return 0;
}
