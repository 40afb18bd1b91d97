// prtbake prefilter: environment → prefiltered specular cube mip chain (KTX2, OpenEXR, JSON sidecar).
#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "cli.h"
#include "jobs.h"
#include "prtbake/clock.h"
#include "prtbake/error.h"
#include "prtbake/prefilter.h"
#include "prtbake/preview.h"
#include "prtbake/runtime.h"

namespace prtbake::cli {

namespace {

bool endsWithText(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

int runPrefilter(const CommandLine& cl) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::string input = cl.positional.at(0), output = cl.get("output");
  if (output.empty()) throw UsageError("prefilter", "missing -o OUT.ktx2 or -o OUT.exr");
  std::string ktx2 = cl.get("ktx2"), exr = cl.get("exr");
  if (endsWithText(output, ".ktx2")) {
    if (!ktx2.empty()) throw UsageError("--ktx2", "-o already names the KTX2 output");
    ktx2 = output;
  } else if (endsWithText(output, ".exr")) {
    if (!exr.empty()) throw UsageError("--exr", "-o already names the OpenEXR output");
    exr = output;
  } else {
    throw UsageError("-o", "'" + output + "' must end in .ktx2 or .exr (the format follows the extension)");
  }
  const std::string json = cl.get("json", sidecarPath(output));
  nlohmann::json outputs = {{"json", json}};
  if (!ktx2.empty()) outputs["ktx2"] = ktx2;
  if (!exr.empty()) outputs["exr"] = exr;
  const nlohmann::json p = productParams(cl, "prefilter", outputs);
  const PrefilterOptions o = jobs::prefilterOptionsFrom(p);
  const EnvLoadOptions lo = jobs::envLoadOptionsFrom(p, false);
  const double yaw = p["yaw"].get<double>();

  // A lat-long OpenEXR file is read in bands: load then counts everything before the device
  // starts, the bands' bin sums and resampling (the sidecar's bins and resample) included.
  EnvMap env;
  double loadSeconds = 0;
  const PrefilterResult r = prefilterEnvironmentFile(
      [&]() -> Runtime& {
        loadSeconds = secondsSince(t0);
        return jobs::processRuntime(cl.device());
      },
      input, lo, yaw, o, &env);
  nlohmann::json meta;
  meta["parameters"] = {{"input", input},
                        {"lobe", toString(o.lobe)},
                        {"schedule", toString(o.schedule)},
                        {"size", o.baseSize},
                        {"levels", r.levels.size()},
                        {"tolerance", o.tolerance},
                        {"method", toString(o.method)},
                        {"layout", env.layoutName},
                        {"yaw_degrees", yaw},
                        {"clamp_invalid", lo.clampInvalid}};
  if (o.method == PrefilterMethod::Sampled) meta["parameters"]["samples"] = o.samples;
  meta["timings_seconds"] = {{"load", loadSeconds}, {"command_before_writing", secondsSince(t0)}};
  writePrefilterFiles(r, env, json, ktx2, cl.has("float32"), exr, cl.has("half"), meta.dump());
  double worst = 0;
  for (const auto& l : r.levels) worst = std::max(worst, l.error.p99);
  char line[256];
  std::snprintf(line, sizeof line, "prefilter %s, %zu levels from %d, %s schedule: estimated p99 error %.2g; %.2f s",
                toString(o.lobe), r.levels.size(), o.baseSize, toString(o.schedule), worst, secondsSince(t0));
  status(cl, std::string(line) + " -> " + (ktx2.empty() ? "" : ktx2 + " ") + (exr.empty() ? "" : exr + " ") + json);
  return 0;
}

}  // namespace

PRTBAKE_COMMAND(Command{
    "prefilter", "prefiltered specular environment: a cube mip chain (KTX2, OpenEXR) + JSON sidecar",
    "prtbake prefilter INPUT -o OUT.ktx2|OUT.exr [--ktx2 PATH] [--exr PATH] [--json PATH]\n"
    "       [--lobe ggx|charlie|lambertian] [--schedule linear|filament|babylon | --roughness R0,R1,...]\n"
    "       [--size N] [--levels N] [--tolerance E] [--float32] [--half] [--layout L] [--yaw DEG] [--clamp-invalid]\n"
    "       [--method cut|sampled [--samples N]] [--no-estimate]\n"
    "Level i holds P(R) = integral L(l) k(R.l) dl / integral k dl, k = D(h) max(0, R.l) (GGX, Charlie) or\n"
    "max(0, R.l) (lambertian); its roughness and size come from the schedule (size_i = max(1, N >> i)).\n"
    "INPUT: anything prtbake env reads. The sidecar (default OUT.json) lists each level's roughness, size and\n"
    "estimated error. See docs/prefilter.md.",
    productOptions("prefilter", {{"output", true, "output path (also -o): .ktx2 or .exr"},
                                 {"ktx2", true, "also write a KTX2 cube with every level"},
                                 {"exr", true, "also write a mip-mapped OpenEXR cube (power-of-two --size)"},
                                 {"json", true, "sidecar path (default: OUT with .json)"}}),
    1, 1, runPrefilter});

}  // namespace prtbake::cli
