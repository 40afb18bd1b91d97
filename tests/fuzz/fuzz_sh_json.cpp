// Fuzz target: SH coefficient JSON through readShJson, as `prtbake rotate IN.json` and
// `prtbake preview env|mesh --env SH.json` read it. Input: the file.
#include <cmath>

#include "fuzz_target.h"
#include "prtbake/env.h"

using namespace prtbake;

PRTBAKE_FUZZ_TARGET(sh_json) {
  fuzz::clearScratch();
  const std::string path = fuzz::writeScratch("sh.json", std::string(reinterpret_cast<const char*>(data), size));
  ShCoeffs c;
  std::string meta;
  if (!fuzz::expectCleanFailure(path, [&] { c = readShJson(path, &meta); })) return 0;
  if (c.order < 1 || c.order > 32 || c.rgb.size() != size_t(c.order) * size_t(c.order))
    fuzz::fail("inconsistent ShCoeffs");
  for (const auto& v : c.rgb)
    for (double x : v)
      if (!std::isfinite(x)) fuzz::fail("non-finite coefficient read");
  return 0;
}
