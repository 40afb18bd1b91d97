// prtbake preview: PNG images of baked products (environment SH, LUTs).
#include <nlohmann/json.hpp>

#include "cli.h"
#include "prtbake/env_sh.h"
#include "prtbake/error.h"
#include "prtbake/exr.h"
#include "prtbake/preview.h"
#include "prtbake/runtime.h"
#include "prtbake/sh.h"

namespace prtbake::cli {
namespace {

bool endsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// --size WxH or W: the width of one panel (heights follow each preview's shape).
int panelWidth(const CommandLine& cl, int fallback) {
  const std::string s = cl.get("size");
  if (s.empty()) return fallback;
  char* end = nullptr;
  const long w = std::strtol(s.c_str(), &end, 10);
  if (end == s.c_str() || (*end != '\0' && *end != 'x') || w < 8 || w > 16384)
    throw UsageError("--size", "expected W or WxH with W in [8, 16384], got '" + s + "'");
  return int(w);
}

int previewEnv(const CommandLine& cl, const std::string& input, const std::string& output) {
  ToneMap tm;
  tm.exposureStops = cl.getDouble("exposure", 0.0, -40.0, 40.0);
  const int width = panelWidth(cl, 512);
  ShCoeffs radiance;
  EnvMap env;
  bool haveEnv = false;
  std::string what;
  if (endsWith(input, ".json")) {
    radiance = readShJson(input);
    if (radiance.quantity != ShQuantity::Radiance)
      throw InputError(input, "preview needs radiance coefficients (this file holds " +
                                  std::string(toString(radiance.quantity)) + ")");
    what = "SH radiance reconstruction | irradiance/pi (order " + std::to_string(radiance.order) + ")";
  } else {
    EnvLoadOptions lo;
    lo.layout = cl.getChoice("layout", "auto", {"auto", "faces", "cross", "latlong", "games202"});
    env = loadEnvironment(input, lo);
    env.yawDegrees = cl.getDouble("yaw", 0.0, -36000.0, 36000.0);
    EnvProjectOptions po;
    po.order = int(cl.getInt("order", 3, 1, kMaxShOrder));
    po.window = parseWindow(cl.get("window", "none"));
    Runtime rt(cl.device());
    const EnvProjectResult r = projectEnvironment(rt, env, po);
    radiance = applyWindowAndQuantity(r.radiance, r.windowWeights, ShQuantity::Radiance);
    haveEnv = true;
    what = "environment | SH radiance reconstruction | irradiance/pi (order " + std::to_string(po.order) +
           ", window " + toString(po.window) + ")";
  }
  const LinearImage img = renderEnvPreview(haveEnv ? &env : nullptr, radiance, width);
  writePreviewPng(output, img, tm, {{"Description", "prtbake environment preview, lat-long panels (+Y up, centre column looks along +Z): " + what},
                                    {"Source", input}});
  status(cl, "wrote " + output + " (" + what + ")");
  return 0;
}

int previewLut(const CommandLine& cl, const std::string& input, const std::string& output) {
  const ExrImage lut = readExr(input);
  if (lut.width != lut.height) throw InputError(input, "a LUT must be square");
  std::vector<LutChannel> channels;
  const char* names[] = {"R", "G", "B"};
  const char* labels[] = {"R = A (scale)", "G = B (bias)", "B = third table"};
  for (int k = 0; k < 3; ++k)
    if (const auto* c = lut.channel(names[k])) channels.push_back({labels[k], c->data()});
  for (size_t i = 0; i < lut.channelNames.size(); ++i) {
    const auto& n = lut.channelNames[i];
    if (n != "R" && n != "G" && n != "B" && n != "A") channels.push_back({n, lut.channels[i].data()});
  }
  if (channels.empty()) throw InputError(input, "no channels to show");
  const LinearImage img = renderLutPreview(lut.width, channels, "N.V", "rough", 0.0f, 1.0f, panelWidth(cl, 256));
  writePreviewPng(output, img, ToneMap{}, {{"Description", "prtbake LUT preview: x = N.V (0..1, left to right), y = roughness (0..1, bottom to top), grey = value in [0,1]"},
                                           {"Source", input}});
  status(cl, "wrote " + output);
  return 0;
}

int runPreview(const CommandLine& cl) {
  const std::string kind = cl.positional.at(0), input = cl.positional.at(1), output = cl.get("output");
  if (output.empty()) throw UsageError("preview", "missing -o OUT.png");
  if (kind == "env") return previewEnv(cl, input, output);
  if (kind == "lut") return previewLut(cl, input, output);
  throw UsageError("preview", "unknown kind '" + kind + "' (expected env or lut)");
}

PRTBAKE_COMMAND(Command{
    "preview", "render PNG previews of products (env, lut)",
    "prtbake preview env (ENVMAP | SH.json) -o OUT.png [--order N] [--window W] [--size W] [--exposure EV]\n"
    "       prtbake preview lut LUT.exr -o OUT.png [--size S]\n"
    "env: lat-long panels: the environment, its SH radiance reconstruction, and irradiance/pi.\n"
    "lut: each channel over N.V (x) and roughness (y, upward) with labelled axes.",
    {{"output", true, "output PNG (also -o)"},
     {"order", true, "SH order of the reconstruction (env map input; default 3)"},
     {"window", true, "none|hann|lanczos|auto (env map input)"},
     {"layout", true, "environment layout, as for prtbake env"},
     {"yaw", true, "rotate the environment about +Y (degrees)"},
     {"size", true, "panel width in pixels (W or WxH)"},
     {"exposure", true, "exposure in stops before the sRGB curve (default 0)"}},
    2, 2, runPreview});

}  // namespace
}  // namespace prtbake::cli
