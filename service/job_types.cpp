// The job types of this build: their schemas (the keys of the matching command
// line, with the same defaults and ranges) and their executors, each a thin
// call into the library. Adding a product = one entry in jobTypes() and one
// executor function here.
#include <chrono>

#include "jobs.h"
#include "prtbake/atomic_file.h"
#include "prtbake/env.h"
#include "prtbake/error.h"
#include "prtbake/hash.h"
#include "prtbake/lut.h"
#include "prtbake/mesh.h"
#include "prtbake/ibl.h"
#include "prtbake/prefilter.h"
#include "prtbake/preview.h"
#include "prtbake/transport.h"
#include "prtbake/sh.h"

namespace prtbake::jobs {
namespace {

// The transport job's preview: a front view turned 30° toward +X, from 20° above.
constexpr double kPreviewYawDeg = 30, kPreviewPitchDeg = 20;

bool endsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

json hashList(const std::vector<std::string>& files) {
  json inputs = json::array();
  for (const auto& f : files) inputs.push_back({{"path", f}, {"sha256", sha256File(f)}});
  return inputs;
}

// The job's input environment, with its layout, clamp_invalid and yaw keys applied; the load's
// seconds in *loadSeconds. `compact` keeps 8-bit inputs as bytes (env jobs only read texels once).
EnvLoadOptions jobLoadOptions(const Job& job, bool compact) {
  EnvLoadOptions loadOptions;
  loadOptions.layout = job.params["layout"].get<std::string>();
  loadOptions.clampInvalid = job.params["clamp_invalid"].get<bool>();
  loadOptions.compact = compact;
  return loadOptions;
}

EnvMap loadJobEnvironment(const Job& job, bool compact, double* loadSeconds) {
  const auto t0 = std::chrono::steady_clock::now();
  EnvMap env = loadEnvironment(job.input, jobLoadOptions(job, compact));
  env.yawDegrees = job.params["yaw"].get<double>();
  *loadSeconds = secondsSince(t0);
  return env;
}

// --- env: environment map → SH coefficients (prtbake env) ---
ExecResult runEnv(const Job& job, ExecContext& ctx) {
  const json& p = job.params;
  EnvProjectOptions options;
  options.order = p["order"].get<int>();
  options.quantity = parseQuantity(p["quantity"].get<std::string>());
  options.window = parseWindow(p["window"].get<std::string>());
  Runtime& rt = ctx.runtime();
  // The preview shows the texels: loaded whole for it; otherwise a lat-long OpenEXR file is
  // decoded and projected in bands (load_seconds then counts only what precedes the bands).
  double loadSeconds = 0;
  EnvMap env;
  EnvProjectResult r;
  const auto t1 = std::chrono::steady_clock::now();
  if (ctx.wants("png")) {
    env = loadJobEnvironment(job, true, &loadSeconds);
    r = projectEnvironment(rt, env, options);
  } else {
    r = projectEnvironmentFile([&]() -> Runtime& { return rt; }, job.input, jobLoadOptions(job, true),
                               p["yaw"].get<double>(), options, &env);
  }
  const double projectSeconds = secondsSince(t1) - loadSeconds;

  ExecResult result;
  result.inputFiles = filesRead(job, env.inputFiles);
  result.report = {{"texels", r.texels},
                   {"layout", env.layoutName},
                   {"clamped_texels", env.clampedTexels},
                   {"window_weights", r.windowWeights},
                   {"auto_window_lambda", r.autoWindowLambda},
                   {"min_irradiance_before_window", r.minIrradianceBefore},
                   {"min_irradiance_after_window", r.minIrradianceAfter},
                   {"timings", {{"load_seconds", loadSeconds},
                                {"project_seconds", projectSeconds},
                                {"kernel_seconds", r.kernelSeconds},
                                {"upload_seconds", r.uploadSeconds}}}};
  if (ctx.wants("json")) {
    const json meta = {{"job", job.id},
                       {"parameters", p},
                       {"inputs", hashList(result.inputFiles)},
                       {"device", rt.deviceLabel()},
                       {"product", result.report}};
    writeShJson(ctx.output("json"), r.coeffs, meta.dump());
  }
  if (ctx.wants("games202")) writeGames202Light(ctx.output("games202"), r.coeffs);
  if (ctx.wants("png")) {
    // The preview shows the (windowed) radiance whatever quantity the json holds.
    const ShCoeffs radiance = applyWindowAndQuantity(r.radiance, r.windowWeights, ShQuantity::Radiance);
    const LinearImage img = renderEnvPreview(&env, radiance, 512);
    writePreviewPng(ctx.output("png"), img, ToneMap{},
                    {{"Description", "prtbake environment preview, lat-long panels (+Y up, centre column looks along +Z): "
                                     "environment | SH radiance reconstruction | irradiance/pi (order " +
                                         std::to_string(options.order) + ", window " + toString(options.window) + ")"},
                     {"Source", job.input}});
  }
  return result;
}

// --- transport: mesh → per-vertex PRT transfer (prtbake transport) ---
}  // namespace

TransportOptions transportOptionsFrom(const json& p) {
  TransportOptions options;
  options.mode = parseTransportMode(p["mode"].get<std::string>());
  options.order = p["order"].get<int>();
  options.samples = p["samples"].get<int>();
  options.seed = p["seed"].get<uint64_t>();
  options.bounces = p["bounces"].get<int>();
  options.bounceTolerance = p["bounce_tolerance"].get<double>();
  if (!p["tolerance"].is_null()) options.tolerance = p["tolerance"].get<double>();
  return options;
}

namespace {

ExecResult runTransport(const Job& job, ExecContext& ctx) {
  const json& p = job.params;
  const TransportOptions options = transportOptionsFrom(p);
  const Mesh mesh = loadMesh(job.input);
  // The preview's environment is read before the transport runs (a bad file fails fast).
  std::vector<std::string> previewFiles;
  ShCoeffs previewRadiance;
  EnvMap previewMap;
  const bool previewFromMap = ctx.wants("png") && !endsWith(p["preview_env"].get<std::string>(), ".json");
  if (ctx.wants("png")) {
    const std::string envPath = p["preview_env"].get<std::string>();
    if (previewFromMap) {
      EnvLoadOptions compact;
      compact.compact = true;
      previewMap = loadEnvironment(envPath, compact);
      previewFiles = previewMap.inputFiles;
    } else {
      previewRadiance = readShJson(envPath);
      if (previewRadiance.quantity != ShQuantity::Radiance)
        throw InputError(envPath, std::string("preview_env must hold radiance coefficients (this file holds ") +
                                      toString(previewRadiance.quantity) + ")");
      previewFiles = {envPath};
    }
  }
  const TransportResult r = computeTransport(ctx.runtime(), mesh, options);
  LinearImage preview;
  std::string previewCamera;
  if (ctx.wants("png")) {
    if (previewFromMap) {
      EnvProjectOptions po;
      po.order = options.order;
      previewRadiance = projectEnvironment(ctx.runtime(), previewMap, po).radiance;
    }
    TransportCoeffs t;
    t.order = r.order, t.channels = r.channels, t.vertexCount = r.vertexCount, t.coeffs = r.coeffs;
    MeshPreviewOptions po;
    po.yawDeg = kPreviewYawDeg, po.pitchDeg = kPreviewPitchDeg;
    po.background = previewFromMap ? &previewMap : nullptr;
    MeshPreviewResult mp = renderMeshPreview(ctx.runtime(), mesh, t, previewRadiance, po);
    preview = std::move(mp.image);
    previewCamera = mp.camera;
  }
  // Every output's bytes first, then the writes: a failure leaves nothing behind.
  std::vector<std::pair<std::string, std::string>> files;
  if (ctx.wants("npy")) files.emplace_back(ctx.output("npy"), transportNpyBytes(r));
  if (ctx.wants("games202")) files.emplace_back(ctx.output("games202"), games202TransportBytes(mesh, r));
  if (ctx.wants("gltf")) files.emplace_back(ctx.output("gltf"), transportGltfBytes(ctx.output("gltf"), mesh, r));
  if (ctx.wants("json")) files.emplace_back(ctx.output("json"), transportSidecarBytes(job.input, mesh, options, r));
  for (const auto& [path, bytes] : files) writeFileAtomic(path, bytes);
  if (ctx.wants("png"))
    writePreviewPng(ctx.output("png"), preview, ToneMap{},
                    {{"Description", "prtbake mesh preview: L = albedo * sum_i l_i T_i (transport order " +
                                         std::to_string(r.order) + "), background = " +
                                         (previewFromMap ? "environment map" : "SH radiance reconstruction") +
                                         "; camera " + previewCamera},
                     {"Source", job.input},
                     {"Environment", p["preview_env"].get<std::string>()}});
  ExecResult result;
  meshInputs(job, mesh, result, previewFiles);
  result.report = {{"vertices", r.vertexCount},
                   {"channels", r.channels},
                   {"samples", r.samples},
                   {"rays", r.rays},
                   {"bounces_used", r.bouncesUsed},
                   {"standard_error_max", r.maxStdError},
                   {"standard_error_mean", r.meanStdError},
                   {"samples_total", r.totalSamples},
                   {"vertices_unoccludable", r.verticesUnoccludable},
                   {"timings", {{"bvh_seconds", r.bvhSeconds}, {"kernel_seconds", r.kernelSeconds},
                                {"total_seconds", r.totalSeconds}}}};
  return result;
}

// --- lut: split-sum BRDF lookup table (prtbake lut) ---
ExecResult runLut(const Job& job, ExecContext& ctx) {
  const json& p = job.params;
  LutOptions options;
  options.size = p["size"].get<int>();
  options.samples = p["samples"].get<int>();
  options.ndf = parseLutNdf(p["ndf"].get<std::string>(), "ndf");
  options.visibility = parseLutVisibility(p["visibility"].get<std::string>(), "visibility");
  options.multiscatter = p["multiscatter"].get<bool>();
  options.cloth = p["cloth"].get<bool>();
  options.kullaConty = p["kulla_conty"].get<bool>();
  options.alphaDirect = p["alpha_direct"].get<bool>();
  if (!p["tolerance"].is_null()) options.tolerance = p["tolerance"].get<double>();
  validateLutOptions(options);
  const LutResult lut = computeLut(ctx.runtime(), options);
  const std::string exr = ctx.output("exr");
  const std::string sidecar = ctx.wants("json") ? ctx.output("json") : std::string();
  writeLutFiles(lut, exr, sidecar, p["half"].get<bool>());
  if (ctx.wants("png")) {
    std::vector<LutChannel> channels = {{"R = A (scale)", lut.a.data()}, {"G = B (bias)", lut.b.data()}};
    if (!lut.third.empty()) channels.push_back({"B = third table", lut.third.data()});
    const LinearImage img = renderLutPreview(lut.size, channels, "N.V", "rough", 0.0f, 1.0f, 256);
    writePreviewPng(ctx.output("png"), img, ToneMap{},
                    {{"Description", "prtbake LUT preview: x = N.V (0..1, left to right), y = roughness (0..1, bottom "
                                     "to top), grey = value in [0,1]"}});
  }
  ExecResult result;
  result.inputFiles = {};
  result.report = {{"size", lut.size},
                   {"samples", options.samples},
                   {"samples_total", lut.totalSamples},
                   {"standard_error_max", lut.stdErrMax},
                   {"standard_error_mean", lut.stdErrMean},
                   {"timings", {{"kernel_seconds", lut.kernelSeconds}, {"build_seconds", lut.buildSeconds},
                                {"total_seconds", lut.totalSeconds}}}};
  return result;
}

// --- prefilter: environment → prefiltered specular chain (prtbake prefilter) ---
PrefilterOptions prefilterOptionsFrom(const json& p) {
  PrefilterOptions o;
  o.lobe = parsePrefilterLobe(p["lobe"].get<std::string>(), "lobe");
  o.baseSize = p["size"].get<int>();
  if (!p["levels"].is_null()) o.levels = p["levels"].get<int>();
  if (!p["roughness"].is_null()) {
    o.schedule = PrefilterSchedule::Explicit;
    o.roughness = p["roughness"].get<std::vector<double>>();
  } else {
    o.schedule = parsePrefilterSchedule(p["schedule"].get<std::string>(), "schedule");
  }
  o.tolerance = p["tolerance"].get<double>();
  o.method = parsePrefilterMethod(p["method"].get<std::string>(), "method");
  o.samples = p["samples"].get<int>();
  return o;
}

ExecResult runPrefilter(const Job& job, ExecContext& ctx) {
  const json& p = job.params;
  const PrefilterOptions options = prefilterOptionsFrom(p);
  validatePrefilterOptions(options);
  double loadSeconds = 0;
  const EnvMap env = loadJobEnvironment(job, false, &loadSeconds);
  const PrefilterResult r = prefilterEnvironment(ctx.runtime(), env, options);
  const json meta = {{"job", job.id}, {"parameters", p}, {"timings_seconds", {{"load", loadSeconds}}}};
  writePrefilterFiles(r, env, ctx.wants("json") ? ctx.output("json") : std::string(),
                      ctx.wants("ktx2") ? ctx.output("ktx2") : std::string(), p["float32"].get<bool>(),
                      ctx.wants("exr") ? ctx.output("exr") : std::string(), p["half"].get<bool>(), meta.dump());
  if (ctx.wants("png"))
    writePrefilterPreviewPng(ctx.output("png"), ctx.runtime(), r, 256, job.input);
  ExecResult result;
  result.inputFiles = filesRead(job, env.inputFiles);
  json levels = json::array();
  for (const auto& l : r.levels)
    levels.push_back({{"size", l.spec.size}, {"roughness", l.spec.roughness}, {"error_p99", l.error.p99}});
  result.report = {{"levels", levels},
                   {"timings", {{"load_seconds", loadSeconds}, {"kernel_seconds", r.kernelSeconds},
                                {"total_seconds", r.totalSeconds}}}};
  return result;
}

// --- ibl: environment → engine lighting package directory (prtbake ibl) ---
IblPackageOptions iblOptionsFrom(const json& p) {
  IblPackageOptions o;
  o.targets = parseEngineTargets(p["target"].get<std::string>(), "target");
  o.size = p["size"].get<int>();
  o.skyboxSize = p["skybox_size"].get<int>();
  o.lutSize = p["lut_size"].get<int>();
  o.tolerance = p["tolerance"].get<double>();
  validateIblPackageOptions(o);
  return o;
}

ExecResult runIbl(const Job& job, ExecContext& ctx) {
  const json& p = job.params;
  const IblPackageOptions o = iblOptionsFrom(p);
  double loadSeconds = 0;
  const EnvMap env = loadJobEnvironment(job, false, &loadSeconds);
  const json meta = {{"job", job.id}, {"parameters", p}, {"timings_seconds", {{"load", loadSeconds}}}};
  const IblPackageResult r = writeIblPackage(ctx.runtime(), env, ctx.output("dir"), o, meta.dump());
  ExecResult result;
  result.inputFiles = filesRead(job, env.inputFiles);
  json files = json::array();
  for (const auto& f : r.files) files.push_back(f.path);
  result.report = {{"files", files}, {"timings", {{"load_seconds", loadSeconds}, {"total_seconds", r.seconds}}}};
  return result;
}

KeySpec integer(const std::string& name, long long def, double lo, double hi) {
  return {name, ValueKind::Integer, def, lo, hi, {}};
}
KeySpec number(const std::string& name, json def, double lo, double hi) {
  return {name, ValueKind::Number, std::move(def), lo, hi, {}};
}
KeySpec boolean(const std::string& name, bool def) { return {name, ValueKind::Boolean, def, 0, 0, {}}; }
KeySpec choice(const std::string& name, const std::string& def, std::vector<std::string> choices) {
  return {name, ValueKind::Choice, def, 0, 0, std::move(choices)};
}

std::vector<JobType> makeJobTypes() {
  std::vector<JobType> types;

  JobType env;
  env.name = "env";
  env.input = InputKind::FileOrDirectory;
  env.outputKinds = {"json", "games202", "png"};
  env.keys = {integer("order", 3, 1, kMaxShOrder),
              choice("layout", "auto", {"auto", "faces", "cross", "latlong", "games202"}),
              choice("quantity", "radiance", {"radiance", "irradiance", "irradiance_over_pi"}),
              choice("window", "none", {"none", "hann", "lanczos", "auto"}),
              number("yaw", 0.0, -360.0, 360.0),
              boolean("clamp_invalid", false)};
  env.execute = runEnv;
  types.push_back(env);

  JobType transport;
  transport.name = "transport";
  transport.input = InputKind::File;
  transport.outputKinds = {"npy", "gltf", "games202", "json", "png"};
  transport.keys = {choice("mode", "shadowed", {"unshadowed", "shadowed", "interreflected"}),
                    integer("bounces", 3, 1, 64),
                    number("bounce_tolerance", 1e-4, 0.0, 1.0),
                    integer("order", 3, 1, kMaxShOrder),
                    integer("samples", 1024, 1, 1 << 24),
                    integer("seed", 0, 0, 4294967295.0),
                    number("tolerance", nullptr, 1e-9, 1.0),
                    {"preview_env", ValueKind::Path, nullptr, 0, 0, {}}};
  transport.check = [](const json& raw, const json& p) {
    std::vector<std::pair<std::string, std::string>> problems;
    // --samples N | --tolerance E: a tolerance picks the sample count itself.
    if (raw.contains("tolerance") && raw.contains("samples"))
      problems.push_back({"tolerance", "cannot be combined with samples (give one or the other)"});
    if (raw.contains("bounces") && p["mode"] != "interreflected")
      problems.push_back({"bounces", "only applies to mode 'interreflected'"});
    // Each bounce reads the previous bounce of every vertex: no vertex range can be
    // computed alone, so an interreflected job runs whole in one shard. (With a
    // tolerance every shard runs the same pilot over the whole mesh: the same counts.)
    if (raw.contains("split") && raw["split"] == json(true) && p["mode"] == "interreflected")
      problems.push_back({"split", "interreflected jobs cannot be split by vertices (each bounce needs every "
                                   "vertex's previous bounce); remove split to run the job whole in one shard"});
    const bool png = raw.contains("outputs") && raw["outputs"].is_object() && raw["outputs"].contains("png");
    if (png && !raw.contains("preview_env"))
      problems.push_back({"preview_env", "a png output needs preview_env (a radiance SH JSON or an environment map)"});
    if (!png && raw.contains("preview_env"))
      problems.push_back({"preview_env", "only applies with a png output"});
    return problems;
  };
  transport.execute = runTransport;
  transport.splittable = true;
  types.push_back(transport);

  JobType lut;
  lut.name = "lut";
  lut.input = InputKind::None;
  lut.outputKinds = {"exr", "json", "png"};
  lut.keys = {integer("size", 128, 1, 8192),
              integer("samples", 1024, 1, 1 << 24),
              choice("ndf", "ggx", {"ggx", "beckmann"}),
              choice("visibility", "smith-correlated", {"smith-correlated", "smith-separable", "schlick-ggx"}),
              boolean("multiscatter", false),
              boolean("cloth", false),
              boolean("kulla_conty", false),
              boolean("alpha_direct", false),
              boolean("half", false),
              number("tolerance", nullptr, 1e-9, 1.0)};
  lut.check = [](const json& raw, const json& p) {
    std::vector<std::pair<std::string, std::string>> problems;
    if (raw.contains("outputs") && raw["outputs"].is_object() && !raw["outputs"].contains("exr"))
      problems.push_back({"outputs", "a lut job needs an 'exr' output (the 'json' sidecar describes it)"});
    if (raw.contains("tolerance") && raw.contains("samples"))
      problems.push_back({"tolerance", "cannot be combined with samples (give one or the other)"});
    if (p["multiscatter"] == true && p["cloth"] == true)
      problems.push_back({"cloth", "cannot be combined with multiscatter (both use the B channel)"});
    return problems;
  };
  lut.execute = runLut;
  types.push_back(lut);
  types.push_back(glossyJobType());

  JobType prefilter;
  prefilter.name = "prefilter";
  prefilter.input = InputKind::FileOrDirectory;
  prefilter.outputKinds = {"ktx2", "exr", "json", "png"};
  prefilter.keys = {choice("lobe", "ggx", {"ggx", "charlie", "lambertian"}),
                    choice("schedule", "linear", {"linear", "filament", "babylon"}),
                    {"roughness", ValueKind::NumberList, nullptr, 0.0, 1.0, {}},
                    integer("size", 256, 1, kPrefilterMaxSize),
                    {"levels", ValueKind::Integer, nullptr, 1, kPrefilterMaxLevels, {}},
                    number("tolerance", 0.01, 1e-4, 0.1),
                    choice("method", "cut", {"cut", "sampled"}),
                    integer("samples", 1024, 1, kPrefilterMaxSamples),
                    boolean("float32", false),
                    boolean("half", false),
                    choice("layout", "auto", {"auto", "faces", "cross", "latlong", "games202"}),
                    number("yaw", 0.0, -360.0, 360.0),
                    boolean("clamp_invalid", false)};
  prefilter.check = [](const json& raw, const json& p) {
    std::vector<std::pair<std::string, std::string>> problems;
    const bool outputs = raw.contains("outputs") && raw["outputs"].is_object();
    if (outputs && !raw["outputs"].contains("ktx2") && !raw["outputs"].contains("exr"))
      problems.push_back({"outputs", "a prefilter job needs a 'ktx2' or an 'exr' output"});
    if (raw.contains("roughness") && raw.contains("schedule"))
      problems.push_back({"roughness", "a roughness list is its own schedule; it cannot be combined with schedule"});
    if (raw.contains("samples") && p["method"] != "sampled") problems.push_back({"samples", "only applies to method 'sampled'"});
    if (p["method"] == "sampled" && p["lobe"] != "ggx")
      problems.push_back({"method", "the sampled method compares with the anchors' GGX filtering; use lobe 'ggx'"});
    if (raw.contains("float32") && !(outputs && raw["outputs"].contains("ktx2")))
      problems.push_back({"float32", "only applies with a ktx2 output"});
    if (raw.contains("half") && !(outputs && raw["outputs"].contains("exr")))
      problems.push_back({"half", "only applies with an exr output"});
    const int size = p["size"].get<int>();
    if (outputs && raw["outputs"].contains("exr") && (size & (size - 1)))
      problems.push_back({"size", "an exr output (a mip-mapped OpenEXR cube) needs a power-of-two size, got " + std::to_string(size)});
    if (problems.empty()) {
      try {
        validatePrefilterOptions(prefilterOptionsFrom(p));
      } catch (const Error& e) {
        problems.push_back({e.subject().substr(e.subject().find_first_not_of('-')), e.detail()});
      }
    }
    return problems;
  };
  prefilter.execute = runPrefilter;
  types.push_back(prefilter);

  JobType ibl;
  ibl.name = "ibl";
  ibl.input = InputKind::FileOrDirectory;
  ibl.outputKinds = {"dir"};
  ibl.keys = {choice("target", "all", {"all", "threejs", "filament", "babylon", "gltf"}),
              integer("size", 256, 16, 4096),
              integer("skybox_size", 0, 0, 4096),
              integer("lut_size", 128, 16, 1024),
              number("tolerance", 0.01, 1e-4, 0.1),
              choice("layout", "auto", {"auto", "faces", "cross", "latlong", "games202"}),
              number("yaw", 0.0, -360.0, 360.0),
              boolean("clamp_invalid", false)};
  ibl.check = [](const json& raw, const json& p) {
    std::vector<std::pair<std::string, std::string>> problems;
    if (raw.contains("outputs") && raw["outputs"].is_object() && !raw["outputs"].contains("dir"))
      problems.push_back({"outputs", "an ibl job needs a 'dir' output (the package directory)"});
    try {
      iblOptionsFrom(p);
    } catch (const Error& e) {
      problems.push_back({e.subject().substr(e.subject().find_first_not_of('-')), e.detail()});
    }
    return problems;
  };
  ibl.execute = runIbl;
  types.push_back(ibl);
  return types;
}

}  // namespace

const std::vector<JobType>& jobTypes() {
  static const std::vector<JobType> types = makeJobTypes();
  return types;
}

}  // namespace prtbake::jobs
