// The "lightmap" job type (per-texel lighting data on a mesh's lightmap UVs, docs/lightmap.md):
// its keys are the options of `prtbake lightmap`, declared once here; the executor bakes the
// products asked for and writes the outputs named (one image per product and format, the AO's
// PNG, the sidecar).
#include <cmath>

#include "jobs.h"
#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/glossy.h"
#include "prtbake/lightmap.h"
#include "prtbake/mesh.h"

namespace prtbake::jobs {

LightmapOptions lightmapOptionsFrom(const json& p) {
  LightmapOptions o;
  if (!p["uv"].is_null()) o.uvSet = p["uv"].get<int>();
  if (!p["size"].is_null()) o.size = p["size"].get<int>();
  if (!p["texels_per_unit"].is_null()) o.texelsPerUnit = p["texels_per_unit"].get<double>();
  o.products = parseLightmapProducts(p["products"].get<std::string>());
  o.samples = p["samples"].get<int>();
  if (!p["tolerance"].is_null()) o.tolerance = p["tolerance"].get<double>();
  o.toleranceMaxSamples = p["max_samples"].get<int>();
  o.seed = p["seed"].get<uint64_t>();
  o.order = p["order"].get<int>();
  o.shOrder = p["sh_order"].get<int>();
  if (!p["max_distance"].is_null()) o.maxDistance = p["max_distance"].get<double>();
  o.bounces = p["bounces"].get<int>();
  if (!p["albedo"].is_null()) {
    const float a = p["albedo"].get<float>();
    o.albedoOverride = std::array<float, 3>{a, a, a};
  }
  o.dilation = p["dilation"].get<int>();
  o.unocclude = !p["no_unocclude"].get<bool>();
  o.stitchSeams = !p["no_stitch"].get<bool>();
  return o;
}

std::vector<std::pair<std::string, std::string>> lightmapOutputBytes(const std::map<std::string, std::string>& outputs,
                                                                     const std::string& input, const Mesh& mesh,
                                                                     const json& p, const LightmapOptions& o,
                                                                     const LightmapResult& lm) {
  const bool half = p["half"].get<bool>();
  std::vector<std::pair<std::string, std::string>> files;
  const std::pair<const char*, LightmapProduct> products[] = {
      {"ao", kLightmapAo}, {"bent", kLightmapBent}, {"irradiance", kLightmapIrradiance}, {"transport", kLightmapTransport},
      {"sh", kLightmapSh}, {"bent_tangent", kLightmapBentTangent}};
  for (const auto& [kind, path] : outputs) {
    for (const auto& [name, bit] : products) {
      if (kind == std::string(name) + "_exr") files.emplace_back(path, lightmapExrBytes(lm, bit, half));
      if (kind == std::string(name) + "_ktx2") files.emplace_back(path, lightmapKtx2Bytes(lm, bit));
    }
    if (kind == "ao_png") files.emplace_back(path, lightmapAoPngBytes(lm, p["png_bits"].get<int>()));
    if (kind == "json") files.emplace_back(path, lightmapSidecarBytes(input, o, lm));
    if (kind == "gltf") files.emplace_back(path, lightmapGltfBytes(path, mesh, lm));
  }
  return files;
}

json lightmapReport(const LightmapResult& lm) {
  return {{"size", lm.width}, {"uv_set", lm.uvSet}, {"baked", lm.baked}, {"moved", lm.moved}, {"buried", lm.buried},
          {"dilated", lm.dilated}, {"charts", lm.charts}, {"samples_per_texel", lm.samples}, {"rays", lm.rays},
          {"device", lm.device},
          {"timings", {{"total_seconds", lm.totalSeconds}, {"bake_seconds", lm.bakeSeconds},
                       {"unocclude_seconds", lm.unoccludeSeconds}, {"raster_seconds", lm.rasterSeconds},
                       {"repair_seconds", lm.repairSeconds}}}};
}

namespace {

ExecResult runLightmap(const Job& job, ExecContext& ctx) {
  const json& p = job.params;
  const LightmapOptions o = lightmapOptionsFrom(p);
  const Mesh mesh = loadMesh(job.input);
  for (const auto& [kind, path] : ctx.outputPaths)
    if (kind.rfind("bent_tangent", 0) == 0 && mesh.tangents.empty())
      throw InputError(job.input, "has no tangents for " + kind + ": " +
                                      (mesh.tangentMissing.empty() ? "tangents come from glTF's TANGENT attribute"
                                                                   : mesh.tangentMissing));
  std::vector<std::string> read = mesh.inputFiles;
  const ShCoeffs env = probeEnvironment(p, ctx.runtime, &read);
  const LightmapResult lm = computeLightmap(ctx.runtime(), mesh, env, o);
  for (const auto& [path, bytes] : lightmapOutputBytes(ctx.outputPaths, job.input, mesh, p, o, lm)) writeFileAtomic(path, bytes);
  ExecResult result;
  result.inputFiles = filesRead(job, read);
  result.report = lightmapReport(lm);
  return result;
}

}  // namespace

JobType lightmapJobType() {
  JobType t;
  t.name = "lightmap";
  t.input = InputKind::File;
  t.outputKinds = {"ao_exr", "ao_ktx2", "ao_png", "bent_exr", "bent_ktx2", "bent_tangent_exr", "bent_tangent_ktx2", "irradiance_exr", "irradiance_ktx2",
                   "transport_exr", "sh_exr", "gltf", "json"};
  t.keys = {integer("uv", nullptr, 0, 7, "the UV set (TEXCOORD_n) of the lightmap (none: 1 where the mesh has it, else 0)"),
            integer("size", nullptr, 1, kMaxLightmapSize, "the lightmap's width and height in texels (none: 512, or from texels_per_unit)"),
            number("texels_per_unit", nullptr, 1e-9, 1e9,
                   "texels per world unit: the size that gives the mesh's surface this density (rounded up to a multiple of 4)"),
            {"products", ValueKind::ChoiceList, "ao", 0, 0, {"ao", "bent", "irradiance", "transport", "sh"},
             "what to bake: ao, bent (normals), irradiance (E/pi), transport (per-texel PRT), sh (directional "
             "irradiance), or a comma-separated list"},
            integer("samples", 256, 1, 1 << 20, "rays per texel"),
            number("tolerance", nullptr, 1e-6, 1.0,
                   "the rays per texel that bring 95 % of the texels' transport within this error, predicted from a pilot "
                   "(prtbake/tolerance.h); excludes samples"),
            integer("max_samples", 65536, 64, 1 << 20, "with tolerance: the most rays per texel"),
            integer("seed", 0, 0, 4294967295.0, "the sample set"),
            integer("order", 3, 1, 8, "SH order of the transport and of the environment in irradiance and sh (sh: up to 6)"),
            integer("sh_order", 3, 2, 3, "sh: 2 (L1, 4 coefficients per channel) or 3 (L2, 9)"),
            number("max_distance", nullptr, 1e-9, 1e9, "ao and bent: only occluders within this distance count (none: all)"),
            integer("bounces", 0, 0, 16, "irradiance and transport: interreflections (0: shadowed)"),
            number("albedo", nullptr, 0.0, 1.0, "a grey albedo for every vertex, overriding the file's (bounces)"),
            integer("dilation", 8, 0, 4096, "rings of texels filled around the charts for bilinear and mip lookups (0: none)"),
            boolean("no_unocclude", "keep samples that lie inside closed geometry where they are (marked buried only)"),
            boolean("no_stitch", "leave the UV seams as baked (no least-squares stitching)"),
            boolean("half", "OpenEXR outputs in 16-bit half instead of float"),
            integer("png_bits", 8, 8, 16, "bits per sample of the AO's PNG (8 or 16)"),
            {"env", ValueKind::Path, nullptr, 0, 0, {},
             "the lighting of irradiance and sh: a radiance SH JSON (prtbake env) or an environment map (none: constant white)"},
            integer("env_order", 8, 1, 8, "SH order an environment map is projected to")};
  t.check = [](const json& raw, const json& p) {
    KeyProblems problems;
    if (raw.contains("tolerance") && raw.contains("samples"))
      problems.push_back({"tolerance", "cannot be combined with samples (give one or the other)"});
    if (raw.contains("max_samples") && !raw.contains("tolerance"))
      problems.push_back({"max_samples", "only applies with tolerance"});
    if (raw.contains("size") && raw.contains("texels_per_unit"))
      problems.push_back({"texels_per_unit", "cannot be combined with size"});
    if (p["png_bits"] != 8 && p["png_bits"] != 16) problems.push_back({"png_bits", "must be 8 or 16"});
    unsigned products = 0;
    try {
      products = parseLightmapProducts(p["products"].get<std::string>());
    } catch (const std::exception&) {
      return problems;  // the key's own check reports it
    }
    if (raw.contains("outputs") && raw["outputs"].is_object())
      for (const auto& [kind, path] : raw["outputs"].items()) {
        (void)path;
        if (kind == "json") continue;
        const std::string name = kind == "gltf" ? "ao" : kind.substr(0, kind.find('_'));
        if ((products & parseLightmapProducts(name)) == 0)
          problems.push_back({"outputs", "a " + kind + " output needs the product " + name + " (products)"});
      }
    if (raw.contains("max_distance") && !(products & (kLightmapAo | kLightmapBent)))
      problems.push_back({"max_distance", "only applies to ao and bent"});
    if (raw.contains("env") && !(products & (kLightmapIrradiance | kLightmapSh)))
      problems.push_back({"env", "only applies to irradiance and sh"});
    if (raw.contains("bounces") && !(products & (kLightmapIrradiance | kLightmapTransport | kLightmapSh)))
      problems.push_back({"bounces", "only applies to irradiance, transport and sh"});
    if (raw.contains("sh_order") && !(products & kLightmapSh)) problems.push_back({"sh_order", "only applies to sh"});
    if ((products & kLightmapSh) && p["order"].get<int>() > kMaxGlossyOrder)
      problems.push_back({"order", "the sh product takes orders up to " + std::to_string(kMaxGlossyOrder)});
    if (raw.contains("albedo") && p["bounces"] == 0) problems.push_back({"albedo", "only applies with bounces >= 1"});
    if (raw.contains("env_order") && !raw.contains("env")) problems.push_back({"env_order", "only applies to an environment map"});
    return problems;
  };
  t.execute = runLightmap;
  return t;
}

}  // namespace prtbake::jobs
