// Fuzz target: transport .npy files through readTransportNpy, as `prtbake preview mesh
// --transport T.npy` reads them. Input: byte 0 is the vertex count the mesh expects
// (0: any); the rest is the file.
#include <cmath>

#include "fuzz_target.h"
#include "prtbake/preview.h"

using namespace prtbake;

PRTBAKE_FUZZ_TARGET(npy) {
  if (size < 1) return 0;
  fuzz::clearScratch();
  const std::string path = fuzz::writeScratch("t.npy", std::string(reinterpret_cast<const char*>(data) + 1, size - 1));
  TransportCoeffs t;
  if (!fuzz::expectCleanFailure(path, [&] { t = readTransportNpy(path, data[0]); })) return 0;
  if ((data[0] && t.vertexCount != data[0]) || (t.channels != 1 && t.channels != 3) || t.order < 1 || t.order > 32 ||
      t.coeffs.size() != t.vertexCount * size_t(t.channels) * size_t(t.order) * size_t(t.order))
    fuzz::fail("inconsistent TransportCoeffs");
  for (float v : t.coeffs)
    if (!std::isfinite(v)) fuzz::fail("non-finite coefficient read");
  return 0;
}
