// prtbake prefilter: environment → prefiltered specular cube mip chain (KTX2, OpenEXR, JSON sidecar).
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <nlohmann/json.hpp>

#include "cli.h"
#include "jobs.h"
#include "prtbake/error.h"
#include "prtbake/prefilter.h"
#include "prtbake/preview.h"
#include "prtbake/runtime.h"

namespace prtbake::cli {

bool endsWithText(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// The prefilter options shared by `prtbake prefilter` and `prtbake preview prefilter`
// (`sizeOption` names the base-size option). Validated.
PrefilterOptions prefilterOptionsFromCli(const CommandLine& cl, const std::string& sizeOption, int defaultSize) {
  PrefilterOptions o;
  o.lobe = parsePrefilterLobe(cl.get("lobe", "ggx"));
  if (cl.has("roughness")) {
    if (cl.has("schedule"))
      throw UsageError("--roughness", "a roughness list is its own schedule; it cannot be combined with --schedule");
    o.schedule = PrefilterSchedule::Explicit;
    const std::string text = cl.get("roughness");
    size_t start = 0;
    while (true) {
      const size_t comma = text.find(',', start);
      const std::string part = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
      char* end = nullptr;
      const double v = std::strtod(part.c_str(), &end);
      if (part.empty() || *end != '\0') throw UsageError("--roughness", "expected comma-separated numbers, got '" + text + "'");
      o.roughness.push_back(v);
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
  } else {
    o.schedule = parsePrefilterSchedule(cl.get("schedule", "linear"));
  }
  // Ranges are checked by validatePrefilterOptions so that the library and the CLI say the same.
  o.baseSize = int(cl.getInt(sizeOption, defaultSize, -(1L << 30), 1L << 30));
  o.levels = int(cl.getInt("levels", 0, 1, 1L << 30));
  o.tolerance = cl.getDouble("tolerance", o.tolerance, -1e300, 1e300);
  o.method = parsePrefilterMethod(cl.get("method", "cut"));
  if (cl.has("samples") && o.method != PrefilterMethod::Sampled)
    throw UsageError("--samples", "only applies with --method sampled");
  o.samples = int(cl.getInt("samples", o.samples, -(1L << 30), 1L << 30));
  o.errorEstimate = !cl.has("no-estimate");
  validatePrefilterOptions(o);
  return o;
}

namespace {

double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

std::string sidecarFor(const std::string& path) {
  const size_t slash = path.find_last_of('/'), dot = path.find_last_of('.');
  if (dot != std::string::npos && (slash == std::string::npos || dot > slash)) return path.substr(0, dot) + ".json";
  return path + ".json";
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
  const std::string json = cl.get("json", sidecarFor(output));
  if (json == ktx2 || json == exr || (!ktx2.empty() && ktx2 == exr))
    throw UsageError("prefilter", "two outputs have the same path");
  if (cl.has("float32") && ktx2.empty()) throw UsageError("--float32", "only applies to a KTX2 output");
  if (cl.has("half") && exr.empty()) throw UsageError("--half", "only applies to an OpenEXR output");
  const PrefilterOptions o = prefilterOptionsFromCli(cl, "size", 256);
  if (!exr.empty() && (o.baseSize & (o.baseSize - 1)))
    throw UsageError("--size", "an OpenEXR output (one mip-mapped cube) needs a power-of-two size, got " +
                                   std::to_string(o.baseSize) + " (KTX2 takes any size)");
  EnvLoadOptions lo;
  lo.layout = cl.getChoice("layout", "auto", {"auto", "faces", "cross", "latlong", "games202"});
  lo.clampInvalid = cl.has("clamp-invalid");
  const double yaw = cl.getDouble("yaw", 0.0, -36000.0, 36000.0);

  EnvMap env = loadEnvironment(input, lo);
  env.yawDegrees = yaw;
  const double loadSeconds = secondsSince(t0);
  Runtime& rt = jobs::processRuntime(cl.device());
  const PrefilterResult r = prefilterEnvironment(rt, env, o);
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
    {{"output", true, "output path (also -o): .ktx2 or .exr"},
     {"ktx2", true, "also write a KTX2 cube with every level"},
     {"exr", true, "also write a mip-mapped OpenEXR cube (power-of-two --size)"},
     {"json", true, "sidecar path (default: OUT with .json)"},
     {"lobe", true, "ggx (default), charlie or lambertian (irradiance/pi)"},
     {"schedule", true, "linear (default), filament or babylon"},
     {"roughness", true, "explicit roughness per level, e.g. 0,0.25,0.5,1 (instead of --schedule)"},
     {"size", true, "base face size N (1..8192, default 256); the source is resampled to it"},
     {"levels", true, "level count (default: down to 16x16, or to 1x1 for N <= 16; lambertian: 1)"},
     {"tolerance", true, "target of each level's estimated 99th-percentile relative error (1e-4..0.1, default 0.01)"},
     {"float32", false, "KTX2 as RGBA32F (default RGBA16F; values above 65504 are clamped and counted)"},
     {"half", false, "OpenEXR as half (default float32)"},
     {"layout", true, "environment layout, as for prtbake env (default auto)"},
     {"yaw", true, "rotate the environment about +Y by DEG degrees"},
     {"clamp-invalid", false, "replace NaN/Inf/negative texels by 0 (counted in the sidecar) instead of failing"},
     {"method", true, "cut (default) or sampled (the anchors' 1024-sample estimator, for comparison; GGX only)"},
     {"samples", true, "with --method sampled: samples per texel (default 1024)"},
     {"no-estimate", false, "skip the per-level error estimate (one pass at 2 x tolerance per bin)"}},
    1, 1, runPrefilter});

}  // namespace prtbake::cli
