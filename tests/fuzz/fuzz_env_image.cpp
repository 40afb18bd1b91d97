// Fuzz target: one environment image (OpenEXR, Radiance .hdr, PNG, JPEG; lat-long,
// crosses, strips, OpenEXR cubes) through loadEnvironment, as `prtbake env FILE` and
// `prtbake preview env FILE` read it.
// Input: byte 0 picks the options (bits 0-1: layout auto|latlong|cross|auto; bit 2:
// --clamp-invalid; bit 3: compact storage, as `prtbake env` loads); the rest is the file.
// Formats are told by content, not by name. A lat-long OpenEXR file is also read in bands
// (forEachLatLongBand) and compared with the whole map.
#include <algorithm>
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
  if (!fuzz::expectCleanFailure(path, [&] { env = loadEnvironment(path, options); })) return 0;
  // The file read in bands, as `prtbake env` reads a lat-long OpenEXR file: the same texels (or
  // not a banded map). Bands of 3 rows in small images; in wide ones 32 rows, so that no chunk
  // of lines is decompressed more than once (1-row bands of a 8192-wide ZIP file: 16 times).
  EnvMap header;
  bool banded = false, same = true;
  const size_t bandBytes = 12 * size_t(std::max(env.width, 1)) * (env.width <= 256 ? 3 : 32);
  // Each band against the whole map's rows, in place (a copy would double a large image).
  auto matches = [&](const auto& part, const auto& whole, int firstRow) {
    const size_t at = 3 * size_t(firstRow) * size_t(env.width);
    return part.empty() || (at <= whole.size() && part.size() <= whole.size() - at &&
                            std::equal(part.begin(), part.end(), whole.begin() + std::ptrdiff_t(at)));
  };
  size_t texels = 0;
  const bool bandsRead = fuzz::expectCleanFailure(path, [&] {
    banded = forEachLatLongBand(
        path, options, bandBytes,
        [&](EnvMap& band, int firstRow) {
          texels += band.texelCount();
          same = same && band.rgb.size() + band.halfRgb.size() == 3 * band.texelCount() &&
                 band.rgb.empty() == env.rgb.empty() && matches(band.rgb, env.rgb, firstRow) &&
                 matches(band.halfRgb, env.halfRgb, firstRow);
        },
        &header);
  });
  if (!bandsRead) fuzz::fail("reading in bands failed where the whole read succeeded");
  if (banded && (!same || texels != env.texelCount() || header.width != env.width || header.height != env.height ||
                 header.clampedTexels != env.clampedTexels))
    fuzz::fail("the bands differ from the whole map");
  if (env.width <= 0 || env.height <= 0 || env.texelCount() == 0 ||
      env.rgb.size() + env.halfRgb.size() + env.codes.size() != 3 * env.texelCount())
    fuzz::fail("inconsistent EnvMap sizes");
  for (size_t t = 0; t < env.texelCount(); ++t)
    for (float v : env.texel(t))
      if (!std::isfinite(v) || v < 0) fuzz::fail("a loaded environment holds a negative or non-finite texel");
  return 0;
}
