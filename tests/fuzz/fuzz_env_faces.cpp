// Fuzz target: a directory of six cube faces through loadEnvironment, with the
// orientation of docs/conventions.md "Cube faces" (`--layout faces`) or the GAMES202
// framework's (`--layout games202`).
// Input: byte 0 picks the options (bit 0: games202; bit 1: --clamp-invalid; bits 2-3:
// the file extension, which only decides whether the face is found; bit 4: compact
// storage, as `prtbake env` loads); then six parts
// (fuzz_target.h's splitParts), the faces posx, negx, posy, negy, posz, negz.
#include <cmath>

#include "fuzz_target.h"
#include "prtbake/envmap.h"

using namespace prtbake;

PRTBAKE_FUZZ_TARGET(env_faces) {
  if (size < 1) return 0;
  fuzz::clearScratch();
  const std::vector<std::string> faces = fuzz::splitParts(data + 1, size - 1, 6);
  const char* ext = (const char* const[]){".png", ".jpg", ".hdr", ".exr"}[(data[0] >> 2) & 3];
  const char* names[6] = {"posx", "negx", "posy", "negy", "posz", "negz"};
  for (int f = 0; f < 6; ++f) fuzz::writeScratch(std::string("faces/") + names[f] + ext, faces[size_t(f)]);
  const std::string dir = fuzz::scratchDir() + "/faces";
  EnvLoadOptions options;
  options.layout = (data[0] & 1) ? "games202" : "faces";
  options.clampInvalid = (data[0] & 2) != 0;
  options.compact = (data[0] & 16) != 0;
  EnvMap env;
  if (!fuzz::expectCleanFailure(dir, [&] { env = loadEnvironment(dir, options); })) return 0;
  if (env.layout != EnvLayout::Cube || env.width <= 0 || env.texelCount() == 0 ||
      env.rgb.size() + env.halfRgb.size() + env.codes.size() != 3 * env.texelCount())
    fuzz::fail("inconsistent cube sizes");
  for (size_t t = 0; t < env.texelCount(); ++t)
    for (float v : env.texel(t))
      if (!std::isfinite(v) || v < 0) fuzz::fail("a loaded environment holds a negative or non-finite texel");
  return 0;
}
