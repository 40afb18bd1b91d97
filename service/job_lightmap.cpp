// The "lightmap" job type (per-texel lighting data on a mesh's lightmap UVs, docs/lightmap.md):
// its keys are the options of `prtbake lightmap`, declared once here; the executor bakes the
// products asked for and writes the outputs named (one image per product and format, the AO's
// PNG, the sidecar).
#include <algorithm>
#include <cmath>

#include "jobs.h"
#include "prtbake/hash.h"
#include "shard.h"
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
          {"standard_error_max", lm.maxStdError}, {"standard_error_mean", lm.meanStdError},
          {"device", lm.device},
          {"timings", {{"total_seconds", lm.totalSeconds}, {"bake_seconds", lm.bakeSeconds},
                       {"unocclude_seconds", lm.unoccludeSeconds}, {"raster_seconds", lm.rasterSeconds},
                       {"repair_seconds", lm.repairSeconds}}}};
}

namespace {

ExecResult runLightmap(const Job& job, ExecContext& ctx) {
  const json& p = job.params;
  const LightmapOptions o = lightmapOptionsFrom(p);
  const Mesh mesh = loadMesh(job.input, meshAlbedo(o));
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

// One shard's sample range of a split lightmap job: the samples' rows, not repaired.
ExecResult runLightmapPart(const Job& job, ExecContext& ctx) {
  const json& p = job.params;
  const int index = p.at("shard").at("index").get<int>(), count = p.at("shard").at("count").get<int>();
  LightmapOptions o = lightmapOptionsFrom(p);
  const Mesh mesh = loadMesh(job.input, meshAlbedo(o));
  std::vector<std::string> read = mesh.inputFiles;
  const ShCoeffs env = probeEnvironment(p, ctx.runtime, &read);
  const LightmapSamples samples = lightmapSamples(mesh, o);
  const size_t total = samples.texelOf.size();
  const auto [first, n] = vertexRange(total, index, count);
  o.sampleRange = {first, n};
  const LightmapResult lm = computeLightmap(ctx.runtime(), mesh, env, o);
  const std::string bytes = lightmapRangeNpyBytes(lm, samples.texelOf, first, n);
  writeFileAtomic(ctx.output("npy"), bytes);
  ExecResult result;
  result.inputFiles = filesRead(job, read);
  result.report = lightmapReport(lm);
  result.report["shard"] = {{"index", index}, {"count", count}};
  result.report["first_sample"] = first;
  result.report["sample_count"] = n;
  result.report["lightmap_samples"] = total;
  result.report["order"] = lm.order;
  result.report["transport_channels"] = lm.transportChannels;
  result.report["partial_sha256"] = sha256Hex(bytes.data(), bytes.size());
  return result;
}

}  // namespace

const JobType& lightmapPartialType() {
  static const JobType type = [] {
    JobType t;
    t.name = "lightmap_shard";
    t.input = InputKind::File;
    t.outputKinds = {"npy"};
    t.execute = runLightmapPart;
    return t;
  }();
  return type;
}

std::vector<std::string> mergeLightmapSplit(const Job& job, int n, const std::vector<json>& manifests, json* info) {
  const json& p = job.params;
  const LightmapOptions o = lightmapOptionsFrom(p);
  const Mesh mesh = loadMesh(job.input);
  LightmapSamples samples = lightmapSamples(mesh, o);
  const size_t total = samples.texelOf.size();
  const json& first = manifests[0]["report"];
  if (manifestInt(first, "lightmap_samples", size_t(0)) != total)
    throw InputError(job.input, "gives " + std::to_string(total) + " samples; the shards saw " +
                                    std::to_string(manifestInt(first, "lightmap_samples", size_t(0))));
  LightmapResult& lm = samples.lm;
  lm.order = first.value("order", o.order);
  lm.transportChannels = first.value("transport_channels", 1);
  lm.shOrder = o.shOrder;
  const size_t texels = lm.texels(), nc = size_t(lm.order) * lm.order;
  if (o.products & kLightmapAo) lm.ao.assign(texels, 0.0f);
  if (o.products & kLightmapBent) lm.bent.assign(texels * 3, 0.0f);
  if ((o.products & kLightmapBent) && !mesh.tangents.empty()) lm.bentTangent.assign(texels * 3, 0.0f);
  if (o.products & kLightmapIrradiance) lm.irradiance.assign(texels * 3, 0.0f);
  if (o.products & kLightmapTransport) lm.transport.assign(texels * size_t(lm.transportChannels) * nc, 0.0f);
  if (o.products & kLightmapSh) lm.sh.assign(texels * 3 * size_t(o.shOrder) * o.shOrder, 0.0f);
  lm.state.assign(texels, uint8_t(TexelState::Empty));
  double seconds = 0;
  for (int i = 0; i < n; ++i) {
    const json& rep = manifests[size_t(i)]["report"];
    const std::string path = partialPath(job, i, n);
    size_t rows = 0, columns = 0;
    const std::vector<float> part = readPartialNpy(path, &rows, &columns);
    if (manifestInt(rep, "lightmap_samples", size_t(0)) != total || rows != manifestInt(rep, "sample_count", size_t(0)))
      throw InputError(path, "holds another range than the job's " + std::to_string(total) + " samples give shard " +
                                 ShardSpec{i, n}.name());
    addLightmapRange(lm, samples.texelOf, manifestInt(rep, "first_sample", size_t(0)), part, rows, columns, path);
    lm.rays += manifestInt(rep, "rays", uint64_t(0));
    lm.maxStdError = std::max(lm.maxStdError, rep.value("standard_error_max", 0.0));
    lm.meanStdError += rep.value("standard_error_mean", 0.0) * double(rows) / double(std::max<size_t>(total, 1));
    const json& t = rep["timings"];
    lm.rasterSeconds += t.value("raster_seconds", 0.0), lm.unoccludeSeconds += t.value("unocclude_seconds", 0.0);
    lm.bakeSeconds += t.value("bake_seconds", 0.0);
    seconds += t.value("total_seconds", 0.0);
  }
  for (uint32_t t : samples.texelOf) {
    const auto st = TexelState(lm.state[t]);
    if (st == TexelState::Empty) return {"the shards hold no row for texel " + std::to_string(t)};
    lm.baked += st == TexelState::Baked, lm.moved += st == TexelState::Moved, lm.buried += st == TexelState::Buried;
  }
  lm.samples = first.value("samples_per_texel", o.samples);
  lm.device = first.value("device", std::string());
  repairLightmap(mesh, o, samples.usable, lm);
  lm.totalSeconds = seconds + lm.repairSeconds;
  std::map<std::string, std::string> outputs;
  for (const auto& out : job.outputs) outputs[out.kind] = out.path;
  removeOldManifest(job);
  for (const auto& [path, bytes] : lightmapOutputBytes(outputs, job.input, mesh, p, o, lm)) writeFileAtomic(path, bytes);
  writeMergedManifest(job, manifests[0], lm.device, seconds, lightmapReport(lm));
  *info = {{"texels", lm.baked + lm.moved + lm.buried}};
  return {};
}

JobType lightmapJobType() {
  JobType t;
  t.name = "lightmap";
  t.input = InputKind::File;
  t.outputKinds = {"ao_exr", "ao_ktx2", "ao_png", "bent_exr", "bent_ktx2", "bent_tangent_exr", "bent_tangent_ktx2", "irradiance_exr", "irradiance_ktx2",
                   "transport_exr", "sh_exr", "sh_ktx2", "gltf", "json"};
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
    if (raw.contains("split") && raw["split"] == json(true) && raw.contains("tolerance"))
      problems.push_back({"split", "a split bake takes a fixed number of samples (each shard's pilot would see other texels): "
                                   "give samples, or remove split"});
    return problems;
  };
  t.execute = runLightmap;
  t.splittable = true;
  return t;
}

}  // namespace prtbake::jobs
