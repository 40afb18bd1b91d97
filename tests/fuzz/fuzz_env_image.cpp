// Fuzz target: one environment image (OpenEXR, Radiance .hdr, PNG, JPEG; lat-long,
// crosses, strips, OpenEXR cubes) through loadEnvironment, as `prtbake env FILE` and
// `prtbake preview env FILE` read it.
// Input: byte 0 picks the options (bits 0-1: layout auto|latlong|cross|auto; bit 2:
// --clamp-invalid; bit 3: compact storage, as `prtbake env` loads); the rest is the file.
// Formats are told by content, not by name. A lat-long OpenEXR file is also read in bands
// (forEachLatLongBand) and compared with the whole map.
#include <cmath>
#include <vector>

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
  const bool whole = fuzz::expectCleanFailure(path, [&] { env = loadEnvironment(path, options); });
  // The file read a row at a time, as `prtbake env` reads a lat-long OpenEXR file: where the
  // whole read succeeds, the same texels (or not a banded map).
  EnvMap bands;
  bool banded = false;
  const bool bandsRead = fuzz::expectCleanFailure(path, [&] {
    banded = forEachLatLongBand(
        path, options, 1,
        [&](EnvMap& band, int) {
          bands.rgb.insert(bands.rgb.end(), band.rgb.begin(), band.rgb.end());
          bands.halfRgb.insert(bands.halfRgb.end(), band.halfRgb.begin(), band.halfRgb.end());
        },
        &bands);
  });
  if (!whole) return 0;
  if (!bandsRead) fuzz::fail("reading in bands failed where the whole read succeeded");
  if (banded && (bands.width != env.width || bands.height != env.height || bands.clampedTexels != env.clampedTexels ||
                 std::vector<float>(bands.rgb.begin(), bands.rgb.end()) != std::vector<float>(env.rgb.begin(), env.rgb.end()) ||
                 std::vector<uint16_t>(bands.halfRgb.begin(), bands.halfRgb.end()) !=
                     std::vector<uint16_t>(env.halfRgb.begin(), env.halfRgb.end())))
    fuzz::fail("the bands differ from the whole map");
  if (env.width <= 0 || env.height <= 0 || env.texelCount() == 0 ||
      env.rgb.size() + env.halfRgb.size() + env.codes.size() != 3 * env.texelCount())
    fuzz::fail("inconsistent EnvMap sizes");
  for (size_t t = 0; t < env.texelCount(); ++t)
    for (float v : env.texel(t))
      if (!std::isfinite(v) || v < 0) fuzz::fail("a loaded environment holds a negative or non-finite texel");
  return 0;
}
