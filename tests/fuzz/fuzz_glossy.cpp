// Fuzz target: the glossy transfer files read back by `prtbake preview mesh --matrices M.npy`
// and `--cpca C.npz` and by `prtbake cpca`. Input: byte 0 selects the reader (0: the
// .npy read as float32, 1: the float32 .npy mapped in place, 2: the CPCA .npz); the
// rest is the file.
#include <cmath>
#include <memory>

#include "fuzz_target.h"
#include "prtbake/glossy.h"

using namespace prtbake;

namespace {
void checkMatrices(const GlossyMatrices& g, bool values) {
  if (g.orderOut < kMinGlossyOrder || g.orderOut > kMaxGlossyOrder || g.orderIn < kMinGlossyOrder ||
      g.orderIn > kMaxGlossyOrder || (g.channels != 1 && g.channels != 3))
    fuzz::fail("glossy .npy with orders or channels out of range");
  if (values && g.values.size() != g.vertexCount * size_t(g.channels) * size_t(g.orderOut * g.orderOut) *
                                         size_t(g.orderIn * g.orderIn))
    fuzz::fail("glossy .npy values disagree with the shape");
  for (float v : g.values)
    if (!std::isfinite(v)) fuzz::fail("non-finite matrix value read");
}
}  // namespace

PRTBAKE_FUZZ_TARGET(glossy) {
  if (size < 1) return 0;
  fuzz::clearScratch();
  const int mode = data[0] % 3;
  const std::string path = fuzz::writeScratch(mode == 2 ? "c.npz" : "m.npy",
                                              std::string(reinterpret_cast<const char*>(data) + 1, size - 1));
  if (mode == 0) {
    GlossyMatrices g;
    if (fuzz::expectCleanFailure(path, [&] { g = readGlossyNpy(path); })) checkMatrices(g, true);
  } else if (mode == 1) {
    std::unique_ptr<GlossyNpyMap> map;
    if (!fuzz::expectCleanFailure(path, [&] { map = std::make_unique<GlossyNpyMap>(path); })) return 0;
    const GlossyMatrices& g = map->info();
    checkMatrices(g, false);
    const size_t n = g.vertexCount * size_t(g.channels) * size_t(g.orderOut * g.orderOut) * size_t(g.orderIn * g.orderIn);
    double sum = 0;  // every mapped value is readable and finite
    for (size_t i = 0; i < n; ++i) sum += map->data()[i];
    if (!std::isfinite(sum) && n < (size_t(1) << 20)) fuzz::fail("mapped values not finite");
  } else {
    int no = 0, ni = 0, ch = 0;
    CpcaResult c;
    if (!fuzz::expectCleanFailure(path, [&] { c = readCpcaNpz(path, &no, &ni, &ch); })) return 0;
    const size_t dim = size_t(ch) * size_t(no * no) * size_t(ni * ni), k = size_t(c.clusters), p = size_t(c.vectors);
    if (c.dim != dim || c.means.size() != k * dim || c.basis.size() != k * p * dim ||
        c.clusterOf.size() != c.vertexCount || c.weights.size() != c.vertexCount * p ||
        (c.weightBits == 8 && (c.weightScales.size() != k * p || c.vertexScales.size() != c.vertexCount)))
      fuzz::fail("CPCA arrays disagree with each other");
    for (int32_t id : c.clusterOf)
      if (id < 0 || id >= c.clusters) fuzz::fail("cluster id out of range");
    std::vector<float> x(dim);
    for (size_t v = 0; v < c.vertexCount && v < 64; ++v) cpcaReconstruct(c, v, x.data());  // in bounds
  }
  return 0;
}
