// Fuzz target: glTF 2.0 meshes through loadMesh, as `prtbake transport` reads them
// (.gltf with data URIs or external buffers, .glb), then the _PRT_* attributes read
// back as `prtbake preview mesh --transport COPY.glb` does.
// Input: byte 0 bit 0 names the file .glb (else .gltf; the loader tells GLB by its
// magic either way), bit 1 reads the base colour textures into the albedo; then two parts: the file, and the external buffer "b.bin" that
// a .gltf may name.
#include <cmath>

#include "fuzz_target.h"
#include "prtbake/mesh.h"
#include "prtbake/preview.h"

using namespace prtbake;

PRTBAKE_FUZZ_TARGET(gltf) {
  if (size < 1) return 0;
  fuzz::clearScratch();
  const std::vector<std::string> parts = fuzz::splitParts(data + 1, size - 1, 2);
  fuzz::writeScratch("b.bin", parts[1]);
  const std::string path = fuzz::writeScratch((data[0] & 1) ? "in.glb" : "in.gltf", parts[0]);
  Mesh mesh;
  const MeshAlbedo albedo = (data[0] & 2) ? MeshAlbedo::Textures : MeshAlbedo::Factors;
  if (!fuzz::expectCleanFailure(path, [&] { mesh = loadMesh(path, albedo); })) return 0;
  const size_t nv = mesh.vertexCount();
  if (mesh.positions.size() != 3 * nv || mesh.normals.size() != 3 * nv || mesh.albedo.size() != 3 * nv ||
      mesh.indices.empty() || mesh.indices.size() % 3)
    fuzz::fail("inconsistent Mesh sizes");
  for (uint32_t i : mesh.indices)
    if (i >= nv) fuzz::fail("a loaded mesh has an index out of range");
  for (float v : mesh.positions)
    if (!std::isfinite(v)) fuzz::fail("a loaded mesh has a non-finite position");
  for (float v : mesh.albedo)
    if (!std::isfinite(v)) fuzz::fail("a loaded mesh has a non-finite albedo");
  TransportCoeffs t;
  if (fuzz::expectCleanFailure(path, [&] { t = readTransportGltf(mesh); }) &&
      t.coeffs.size() != t.vertexCount * size_t(t.channels) * size_t(t.order) * size_t(t.order))
    fuzz::fail("inconsistent transport read back from glTF");
  return 0;
}
