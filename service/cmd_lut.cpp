// prtbake lut: split-sum BRDF lookup tables (OpenEXR + JSON sidecar).
#include <chrono>
#include <cstdio>
#include <string>

#include <nlohmann/json.hpp>

#include "cli.h"
#include "jobs.h"
#include "prtbake/clock.h"
#include "prtbake/error.h"
#include "prtbake/lut.h"
#include "prtbake/runtime.h"

namespace prtbake::cli {
namespace {

int runLut(const CommandLine& cl) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::string out = cl.get("output");
  if (out.empty()) throw UsageError("lut", "missing -o OUT.exr");
  const nlohmann::json p = productParams(cl, "lut", {{"exr", out}, {"json", out + ".json"}});
  const LutOptions o = jobs::lutOptionsFrom(p);

  Runtime& rt = jobs::processRuntime(cl.device());
  const LutResult lut = computeLut(rt, o);
  const double seconds = secondsSince(t0);
  writeLut(lut, out, p["half"].get<bool>(), seconds);
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
    productOptions("lut", {{"output", true, "output OpenEXR path (also -o); the sidecar is OUT.json"}}),
    0, 0, runLut});

}  // namespace
}  // namespace prtbake::cli
