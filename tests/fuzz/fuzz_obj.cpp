// Fuzz target: OBJ meshes through loadMesh, as `prtbake transport mesh.obj` reads them.
// Input: the file.
#include <cmath>

#include "fuzz_target.h"
#include "prtbake/mesh.h"

using namespace prtbake;

PRTBAKE_FUZZ_TARGET(obj) {
  fuzz::clearScratch();
  const std::string path = fuzz::writeScratch("in.obj", std::string(reinterpret_cast<const char*>(data), size));
  Mesh mesh;
  if (!fuzz::expectCleanFailure(path, [&] { mesh = loadMesh(path); })) return 0;
  const size_t nv = mesh.vertexCount();
  if (mesh.normals.size() != 3 * nv || mesh.albedo.size() != 3 * nv || mesh.indices.empty() || mesh.indices.size() % 3)
    fuzz::fail("inconsistent Mesh sizes");
  for (uint32_t i : mesh.indices)
    if (i >= nv) fuzz::fail("a loaded mesh has an index out of range");
  for (float v : mesh.positions)
    if (!std::isfinite(v)) fuzz::fail("a loaded mesh has a non-finite position");
  return 0;
}
