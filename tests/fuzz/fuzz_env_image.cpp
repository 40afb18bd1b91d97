// Fuzz target: one environment image (OpenEXR, Radiance .hdr, PNG, JPEG; lat-long,
// crosses, strips, OpenEXR cubes) through loadEnvironment, as `prtbake env FILE` and
// `prtbake preview env FILE` read it.
// Input: byte 0 picks the options (bits 0-1: layout auto|latlong|cross|auto; bit 2:
// --clamp-invalid; bit 3: compact storage, as `prtbake env` loads); the rest is the file.
// Formats are told by content, not by name.
#include <cmath>

#include "fuzz_target.h"
#include "prtbake/envmap.h"

using namespace prtbake;

PRTBAKE_FUZZ_TARGET(env_image) {
  if (size < 1) return 0;
  fuzz::clearScratch();
  const std::string path = fuzz::writeScratch("env", std::string(reinterpret_cast<const char*>(data) + 1, size - 1));
  EnvLoadOptions options;
  options.layout = (const char* const[]){"auto", "latlong", "cross", "auto"}[data[0] & 3];
  options.clampInvalid = (data[0] & 4) != 0;
  options.compact = (data[0] & 8) != 0;
  EnvMap env;
  if (!fuzz::expectCleanFailure(path, [&] { env = loadEnvironment(path, options); })) return 0;
  if (env.width <= 0 || env.height <= 0 || env.texelCount() == 0 ||
      env.rgb.size() + env.halfRgb.size() + env.codes.size() != 3 * env.texelCount())
    fuzz::fail("inconsistent EnvMap sizes");
  for (size_t t = 0; t < env.texelCount(); ++t)
    for (float v : env.texel(t))
      if (!std::isfinite(v) || v < 0) fuzz::fail("a loaded environment holds a negative or non-finite texel");
  return 0;
}
