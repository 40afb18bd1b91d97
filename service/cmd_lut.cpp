// prtbake lut: split-sum BRDF lookup tables (OpenEXR + JSON sidecar).
#include <chrono>
#include <cstdio>
#include <string>

#include "cli.h"
#include "jobs.h"
#include "prtbake/error.h"
#include "prtbake/lut.h"
#include "prtbake/runtime.h"

namespace prtbake::cli {
namespace {

int runLut(const CommandLine& cl) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::string out = cl.get("output");
  if (out.empty()) throw UsageError("lut", "missing -o OUT.exr");
  LutOptions o;
  // Ranges are checked by validateLutOptions so that the library and the CLI say the same.
  o.size = int(cl.getInt("size", o.size, -(1L << 30), 1L << 30));
  o.samples = int(cl.getInt("samples", o.samples, -(1L << 30), 1L << 30));
  o.ndf = parseLutNdf(cl.get("ndf", "ggx"));
  o.visibility = parseLutVisibility(cl.get("visibility", "smith-correlated"));
  o.multiscatter = cl.has("multiscatter");
  o.cloth = cl.has("cloth");
  o.kullaConty = cl.has("kulla-conty");
  o.alphaDirect = cl.has("alpha-direct");
  o.fastMath = cl.has("fast-math");
  if (cl.has("samples") && cl.has("tolerance"))
    throw UsageError("--tolerance", "cannot be combined with --samples (give one or the other)");
  if (cl.has("max-samples") && !cl.has("tolerance"))
    throw UsageError("--max-samples", "only applies with --tolerance");
  if (cl.has("tolerance")) o.tolerance = cl.getDouble("tolerance", 0, 1e-9, 1.0);
  o.toleranceMaxSamples = int(cl.getInt("max-samples", kLutMaxSamples, -(1L << 30), 1L << 30));
  validateLutOptions(o);

  Runtime& rt = jobs::processRuntime(cl.device());
  const LutResult lut = computeLut(rt, o);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  writeLut(lut, out, cl.has("half"), seconds);
  char line[256];
  if (o.tolerance > 0) {
    std::snprintf(line, sizeof line,
                  "lut %dx%d, --tolerance %g: %d samples per texel (pilot of %zu texels, predicted 95th-percentile "
                  "error %.2e%s); kernel %.2f ms, build %.2f s -> %s",
                  lut.size, lut.size, o.tolerance, lut.tolerance.samples, lut.tolerance.pilotItems,
                  lut.tolerance.predictedError, lut.tolerance.capped ? ", capped by --max-samples" : "",
                  lut.kernelSeconds * 1e3, lut.buildSeconds, out.c_str());
  } else {
    std::snprintf(line, sizeof line, "lut %dx%d, %d samples: kernel %.2f ms, build %.2f s, std error max %.2e -> %s",
                  lut.size, lut.size, o.samples, lut.kernelSeconds * 1e3, lut.buildSeconds, lut.stdErrMax,
                  out.c_str());
  }
  status(cl, line);
  return 0;
}

PRTBAKE_COMMAND(Command{
    "lut", "split-sum BRDF lookup tables (A, B) as OpenEXR + JSON sidecar",
    "prtbake lut -o OUT.exr [--size N] [--samples N | --tolerance E [--max-samples N]] [--ndf ggx|beckmann]\n"
    "           [--visibility smith-correlated|smith-separable|schlick-ggx] [--multiscatter | --cloth]\n"
    "           [--kulla-conty] [--alpha-direct] [--half] [--fast-math]\n"
    "Channels: R = A, G = B, B = multiscatter E or cloth; --kulla-conty adds E and Eavg.\n"
    "The sidecar OUT.json states the definition, axes, samples, error estimate and timings.",
    {
        {"output", true, "output OpenEXR path (also -o); the sidecar is OUT.json"},
        {"size", true, "table size N (N x N texels, 1..8192; default 128)"},
        {"samples", true, "samples per texel (default 1024)"},
        {"tolerance", true, "the samples per texel that bring 95 % of the texels within E in every channel, "
                            "predicted from a pilot (docs/accuracy.md)"},
        {"max-samples", true, "with --tolerance: the most samples per texel (64..2^20, default 2^20)"},
        {"ndf", true, "ggx (default) or beckmann"},
        {"visibility", true, "smith-correlated (default), smith-separable or schlick-ggx (k = alpha/2)"},
        {"multiscatter", false, "B channel: E = A + B for multiple-scattering compensation (Filament)"},
        {"cloth", false, "B channel: Charlie NDF with Ashikhmin visibility"},
        {"kulla-conty", false, "extra channels E(mu, r) and Eavg(r) (Kulla-Conty)"},
        {"alpha-direct", false, "roughness axis is alpha itself (default alpha = r^2)"},
        {"half", false, "store 16-bit half floats (default float32)"},
        {"fast-math", false, "native sqrt/divide/exp and -cl-fast-relaxed-math (see docs/lut.md)"},
    },
    0, 0, runLut});

}  // namespace
}  // namespace prtbake::cli
