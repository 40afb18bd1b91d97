// prtbake preview: PNG images of baked products (environment SH, LUTs, the mesh lit by its transport).
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include <nlohmann/json.hpp>

#include "cli.h"
#include "glossy_cli.h"
#include "jobs.h"
#include "prtbake/env.h"
#include "prtbake/error.h"
#include "prtbake/exr.h"
#include "prtbake/lightmap.h"
#include "prtbake/mesh.h"
#include "prtbake/prefilter.h"
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
    lo.compact = true;
    env = loadEnvironment(input, lo);
    env.yawDegrees = cl.getDouble("yaw", 0.0, -jobs::kMaxYawDegrees, jobs::kMaxYawDegrees);
    EnvProjectOptions po;
    po.order = int(cl.getInt("order", 3, 1, kMaxShOrder));
    po.window = parseWindow(cl.get("window", "none"));
    Runtime& rt = jobs::processRuntime(cl.device());
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

// --view front|side|top|YAW,PITCH (degrees).
void parseView(const std::string& s, MeshPreviewOptions& o) {
  if (s.empty() || s == "front") o.yawDeg = 0, o.pitchDeg = 0;
  else if (s == "side") o.yawDeg = 90, o.pitchDeg = 0;
  else if (s == "top") o.yawDeg = 0, o.pitchDeg = 90;
  else {
    char* end = nullptr;
    o.yawDeg = std::strtod(s.c_str(), &end);
    if (end == s.c_str() || *end != ',') throw UsageError("--view", "expected front, side, top or YAW,PITCH, got '" + s + "'");
    const char* p = end + 1;
    o.pitchDeg = std::strtod(p, &end);
    if (end == p || *end != '\0' || !std::isfinite(o.yawDeg) || !(o.pitchDeg >= -90 && o.pitchDeg <= 90))
      throw UsageError("--view", "expected YAW,PITCH in degrees with PITCH in [-90, 90], got '" + s + "'");
  }
}

// --size WxH (or W: height 3/4 of it).
void parseImageSize(const std::string& s, MeshPreviewOptions& o) {
  if (s.empty()) return;
  char* end = nullptr;
  const long w = std::strtol(s.c_str(), &end, 10);
  long h = w * 3 / 4;
  if (end != s.c_str() && *end == 'x') {
    const char* p = end + 1;
    h = std::strtol(p, &end, 10);
    if (end == p) h = -1;
  }
  if (end == s.c_str() || *end != '\0' || w < 8 || w > 16384 || h < 8 || h > 16384)
    throw UsageError("--size", "expected WxH with W and H in [8, 16384], got '" + s + "'");
  o.width = int(w), o.height = int(h);
}

}  // namespace

void meshViewFromCli(const CommandLine& cl, MeshPreviewOptions& o) {
  parseImageSize(cl.get("size"), o);
  parseView(cl.get("view"), o);
  o.lightRotationDeg = cl.getDouble("rotate-light", 0.0, -jobs::kMaxYawDegrees, jobs::kMaxYawDegrees);
}

namespace {

// The environment's radiance SH: a JSON written by prtbake env (must hold radiance).
ShCoeffs readRadianceJson(const std::string& path) {
  ShCoeffs sh = readShJson(path);
  if (sh.quantity != ShQuantity::Radiance)
    throw InputError(path, "the mesh preview needs radiance coefficients (this file holds " +
                               std::string(toString(sh.quantity)) + "); run prtbake env with --quantity radiance");
  return sh;
}

int previewMesh(const CommandLine& cl, const std::string& input, const std::string& output) {
  if (cl.has("matrices") || cl.has("cpca")) return previewGlossyMesh(cl, input, output);
  for (const char* name : {"lobe", "unnormalised"})
    if (cl.has(name)) throw UsageError(std::string("--") + name, "only applies with --matrices or --cpca");
  const std::string transportPath = cl.get("transport"), envPath = cl.get("env"), bgPath = cl.get("background");
  const bool gltfInput = endsWith(input, ".gltf") || endsWith(input, ".glb");
  if (transportPath.empty() && !gltfInput)
    throw UsageError("preview", "mesh previews need --transport T.npy (or a glTF copy with _PRT_* attributes)");
  if (envPath.empty()) throw UsageError("preview", "mesh previews need --env SH.json (radiance coefficients)");
  MeshPreviewOptions o;
  meshViewFromCli(cl, o);
  ToneMap tm;
  tm.exposureStops = cl.getDouble("exposure", 0.0, -40.0, 40.0);
  // Everything is read and checked before the device starts.
  const Mesh mesh = loadMesh(input, MeshAlbedo::Textures);  // shaded with its albedo
  const TransportCoeffs t =
      transportPath.empty() ? readTransportGltf(mesh) : readTransportNpy(transportPath, mesh.vertexCount());
  const ShCoeffs radiance = readRadianceJson(envPath);
  EnvMap background;
  if (!bgPath.empty()) {
    EnvLoadOptions lo;
    lo.layout = cl.getChoice("layout", "auto", {"auto", "faces", "cross", "latlong", "games202"});
    lo.compact = true;
    background = loadEnvironment(bgPath, lo);
    o.background = &background;
  }
  Runtime& rt = jobs::processRuntime(cl.device());
  const MeshPreviewResult r = renderMeshPreview(rt, mesh, t, radiance, o);
  char light[160];
  std::snprintf(light, sizeof light, "lighting rotated by %g deg about +Y (right-handed)", o.lightRotationDeg);
  const std::string what = "prtbake mesh preview: L = albedo * sum_i l_i T_i (transport order " +
                           std::to_string(t.order) + ", " + (t.channels == 3 ? "RGB" : "grey") +
                           ", interpolated per pixel), background = " +
                           (bgPath.empty() ? "SH radiance reconstruction (order " + std::to_string(radiance.order) + ")"
                                           : "environment map") +
                           "; camera " + r.camera + "; " + light;
  std::vector<std::pair<std::string, std::string>> text = {
      {"Description", what}, {"Source", input}, {"Transport", transportPath.empty() ? input : transportPath},
      {"Environment", envPath}};
  if (!bgPath.empty()) text.push_back({"Background", bgPath});
  writePreviewPng(output, r.image, tm, text);
  char timing[160];
  std::snprintf(timing, sizeof timing, " (%zu triangles, BVH %.3f s, kernel %.3f s)", r.triangles, r.bvhSeconds,
                r.kernelSeconds);
  status(cl, "wrote " + output + timing);
  return 0;
}

int previewPrefilter(const CommandLine& cl, const std::string& input, const std::string& output) {
  // The chain's options are prefilter's (declared there), the base size named --base here.
  std::map<std::string, std::string> texts;
  for (const auto& [key, text] : keyTexts(cl))
    if (key != "size" && key != "base") texts[key] = text;
  texts["size"] = cl.get("base", "128");
  PrefilterOptions o = jobs::prefilterOptionsFrom(productParams("prefilter", texts, nullptr));
  const int width = panelWidth(cl, 256);
  EnvLoadOptions lo;
  lo.layout = cl.getChoice("layout", "auto", {"auto", "faces", "cross", "latlong", "games202"});
  EnvMap env = loadEnvironment(input, lo);
  env.yawDegrees = cl.getDouble("yaw", 0.0, -jobs::kMaxYawDegrees, jobs::kMaxYawDegrees);
  Runtime& rt = jobs::processRuntime(cl.device());
  const PrefilterResult r = prefilterEnvironment(rt, env, o);
  writePrefilterPreviewPng(output, rt, r, width, input);
  status(cl, "wrote " + output + " (" + std::to_string(r.levels.size()) + " levels of a " + toString(o.lobe) + " chain, " +
                 toString(o.schedule) + " schedule, base " + std::to_string(o.baseSize) + ")");
  return 0;
}

int previewLightmap(const CommandLine& cl, const std::string& input, const std::string& output) {
  const std::string dir = cl.get("lightmap");
  if (dir.empty()) throw UsageError("preview", "lightmap previews need --lightmap DIR (the directory prtbake lightmap wrote)");
  MeshPreviewOptions o;
  parseImageSize(cl.get("size"), o);
  parseView(cl.get("view"), o);
  ToneMap tm;
  tm.exposureStops = cl.getDouble("exposure", 0.0, -40.0, 40.0);
  const Mesh mesh = loadMesh(input);
  const LightmapResult lm = readLightmap(dir);
  Runtime& rt = jobs::processRuntime(cl.device());
  const LinearImage img = renderLightmapPreview(rt, mesh, lm, o);
  writePreviewPng(output, img, tm,
                  {{"Description", "prtbake lightmap preview: each product on the mesh (bilinear at UV set " +
                                       std::to_string(lm.uvSet) + ") and as the atlas (" + lightmapProductsName(lm.products) + ")"},
                   {"Source", input},
                   {"Lightmap", dir}});
  status(cl, "wrote " + output + " (" + lightmapProductsName(lm.products) + ", " + std::to_string(lm.width) + "x" +
                 std::to_string(lm.height) + " texels)");
  return 0;
}

int runPreview(const CommandLine& cl) {
  const std::string kind = cl.positional.at(0), input = cl.positional.at(1), output = cl.get("output");
  if (output.empty()) throw UsageError("preview", "missing -o OUT.png");
  jobs::checkOutputsSpareInputs({input, cl.get("transport"), cl.get("env"), cl.get("background"), cl.get("lightmap")},
                          {output});
  if (kind == "env") return previewEnv(cl, input, output);
  if (kind == "lut") return previewLut(cl, input, output);
  if (kind == "mesh") return previewMesh(cl, input, output);
  if (kind == "prefilter") return previewPrefilter(cl, input, output);
  if (kind == "lightmap") return previewLightmap(cl, input, output);
  throw UsageError("preview", "unknown kind '" + kind + "' (expected env, lut, mesh, prefilter or lightmap)");
}

PRTBAKE_COMMAND(Command{
    "preview", "render PNG previews of products (env, lut, mesh, prefilter, lightmap)",
    "prtbake preview env (ENVMAP | SH.json) -o OUT.png [--order N] [--window W] [--size W] [--exposure EV]\n"
    "       prtbake preview lut LUT.exr -o OUT.png [--size S]\n"
    "       prtbake preview mesh MESH (--transport T.npy | a glTF copy with _PRT_* attributes) --env SH.json\n"
    "               -o OUT.png [--size WxH]\n"
    "               [--view front|side|top|YAW,PITCH] [--rotate-light DEG] [--exposure EV] [--background ENVMAP]\n"
    "       prtbake preview mesh MESH (--matrices M.npy | --cpca C.npz) --env SH.json -o OUT.png\n"
    "               [--lobe cosine|phong:S|ggx:R] [--unnormalised] [--size WxH] [--view V] [--rotate-light DEG]\n"
    "       prtbake preview prefilter ENVMAP -o OUT.png [--size W] [--base N] [--lobe L] [--schedule S | --roughness R,...]\n"
    "               [--levels N] [--tolerance E]\n"
    "       prtbake preview lightmap MESH --lightmap DIR -o OUT.png [--size WxH] [--view V] [--exposure EV]\n"
    "env: lat-long panels: the environment, its SH radiance reconstruction, and irradiance/pi.\n"
    "lut: each channel over N.V (x) and roughness (y, upward) with labelled axes.\n"
    "mesh: the mesh shaded with its baked transport under the environment's radiance SH\n"
    "      (L = albedo * sum_i l_i T_i), the environment as background; --rotate-light turns\n"
    "      the lighting about +Y (right-handed, degrees) with the exact SH rotation.\n"
    "prefilter: every level of the chain prtbake prefilter makes (base --base, default 128) as a lat-long\n"
    "      panel, and spheres r = 0 ... 1 shaded with the split sum (this chain times prtbake's GGX LUT).\n"
    "lightmap: per product in DIR (the OpenEXR outputs of prtbake lightmap), a row: the mesh with the\n"
    "      product sampled bilinearly at each pixel's lightmap UV, beside the atlas.",
    {{"output", true, "output PNG (also -o)"},
     {"order", true, "SH order of the reconstruction (env map input; default 3)"},
     {"window", true, "none|hann|lanczos|auto (env map input)"},
     {"layout", true, "environment layout, as for prtbake env"},
     {"yaw", true, "rotate the environment about +Y (degrees)"},
     {"size", true, "panel width in pixels (W or WxH); mesh: image size WxH (default 800x600)"},
     {"transport", true, "mesh: the transport .npy written by prtbake transport (not needed for a glTF copy written by --gltf)"},
     {"env", true, "mesh: the environment's radiance SH JSON written by prtbake env"},
     {"background", true, "mesh: an environment map to show behind the mesh (default: the SH reconstruction)"},
     {"view", true, "mesh: front|side|top|YAW,PITCH in degrees (default front)"},
     {"rotate-light", true, "mesh: rotate the lighting about +Y by DEG degrees"},
     {"exposure", true, "exposure in stops before the sRGB curve (default 0)"},
     {"matrices", true, "mesh: glossy transfer matrices (.npy of prtbake transport --transfer matrix)"},
     {"cpca", true, "mesh: CPCA-compressed glossy transfer (.npz)"},
     {"lobe", true, "mesh, glossy: cosine | phong:S | ggx:R (default phong:16); prefilter: ggx (default), charlie or lambertian"},
     {"unnormalised", false, "mesh, glossy: do not divide by the lobe's unoccluded white-sky response"},
     {"base", true, "prefilter: base face size of the chain (default 128)"},
     {"schedule", true, "prefilter: linear (default), filament or babylon"},
     {"roughness", true, "prefilter: explicit roughness per level"},
     {"levels", true, "prefilter: level count"},
     {"tolerance", true, "prefilter: error target (default 0.01)"},
     {"method", true, "prefilter: cut (default) or sampled"},
     {"samples", true, "prefilter: samples per texel with --method sampled"},
     {"no-estimate", false, "prefilter: skip the error estimate"},
     {"lightmap", true, "lightmap: the directory prtbake lightmap wrote (its lightmap.json and .exr products)"}},
    2, 2, runPreview});

}  // namespace
}  // namespace prtbake::cli
