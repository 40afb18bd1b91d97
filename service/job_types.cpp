// The job types of this build: their schemas (the keys of the matching command
// line, with the same defaults and ranges) and their executors, each a thin
// call into the library. Adding a product = one entry in jobTypes() and one
// executor function here.
#include <chrono>

#include "jobs.h"
#include "prtbake/atomic_file.h"
#include "prtbake/clock.h"
#include "prtbake/env.h"
#include "prtbake/error.h"
#include "prtbake/hash.h"
#include "prtbake/ibl.h"
#include "prtbake/lut.h"
#include "prtbake/mesh.h"
#include "prtbake/prefilter.h"
#include "prtbake/preview.h"
#include "prtbake/sh.h"
#include "prtbake/transport.h"

namespace prtbake::jobs {
namespace {

// The transport job's preview: a front view turned 30° toward +X, from 20° above.
constexpr double kPreviewYawDeg = 30, kPreviewPitchDeg = 20;

bool endsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

json hashList(const std::vector<std::string>& files) {
  json inputs = json::array();
  for (const auto& f : files) inputs.push_back({{"path", f}, {"sha256", sha256File(f)}});
  return inputs;
}

EnvMap loadJobEnvironment(const Job& job, bool compact, double* loadSeconds) {
  const auto t0 = std::chrono::steady_clock::now();
  EnvMap env = loadEnvironment(job.input, envLoadOptionsFrom(job.params, compact));
  env.yawDegrees = job.params["yaw"].get<double>();
  *loadSeconds = secondsSince(t0);
  return env;
}

// --- env: environment map → SH coefficients (prtbake env) ---
ExecResult runEnv(const Job& job, ExecContext& ctx) {
  const json& p = job.params;
  EnvProjectOptions options = envProjectOptionsFrom(p);
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
    r = projectEnvironmentFile([&]() -> Runtime& { return rt; }, job.input, envLoadOptionsFrom(p, true),
                               p["yaw"].get<double>(), options, &env);
  }
  json orderSelection;
  if (p["order"] == "auto") orderSelection = selectEnvOrder(r, options, p["tolerance"]);
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
  if (!orderSelection.is_null()) result.report["order_selection"] = orderSelection;
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
  options.toleranceMaxSamples = p["max_samples"].get<int>();
  options.sampler = parseTransportSampler(p["sampler"].get<std::string>());
  if (!p["albedo"].is_null()) {
    const float a = p["albedo"].get<float>();
    options.albedoOverride = std::array<float, 3>{a, a, a};
  }
  return options;
}

EnvLoadOptions envLoadOptionsFrom(const json& p, bool compact) {
  EnvLoadOptions o;
  o.layout = p["layout"].get<std::string>();
  o.clampInvalid = p["clamp_invalid"].get<bool>();
  o.compact = compact;
  return o;
}

EnvProjectOptions envProjectOptionsFrom(const json& p) {
  EnvProjectOptions o;
  o.order = p["order"] == "auto" ? kAutoReferenceOrder : p["order"].get<int>();
  o.quantity = parseQuantity(p["quantity"].get<std::string>());
  o.window = parseWindow(p["window"].get<std::string>());
  return o;
}

json selectEnvOrder(EnvProjectResult& r, EnvProjectOptions& po, const json& toleranceKey) {
  const double tolerance = toleranceKey.is_null() ? 0.01 : toleranceKey.get<double>();
  const ShCoeffs high = r.radiance;
  double error = 0;
  int chosen = chooseShOrder(high, po.quantity, tolerance, &error);
  if (chosen > kAutoMaxOrder) {
    chosen = kAutoMaxOrder;
    error = truncationError(high, po.quantity, chosen);
  }
  po.order = chosen;
  r.radiance = truncateSh(high, chosen);
  if (po.window == ShWindow::Auto)
    r.windowWeights = deringingWindow(r.radiance, &r.autoWindowLambda, &r.minIrradianceBefore, &r.minIrradianceAfter);
  else
    r.windowWeights = windowWeights(po.window, chosen);
  r.coeffs = applyWindowAndQuantity(r.radiance, r.windowWeights, po.quantity);
  json curve = json::array();
  for (int n = 1; n <= kAutoMaxOrder; ++n) curve.push_back(truncationError(high, po.quantity, n));
  return {{"method", "smallest order whose truncation error is within the tolerance"},
          {"error_definition", "relative L2 error over the sphere of the " + std::string(toString(po.quantity)) +
                                   ", against the order-24 projection (Parseval), all channels"},
          {"tolerance", tolerance},
          {"tolerance_met", error <= tolerance},
          {"chosen_order", chosen},
          {"achieved_error", error},
          {"error_by_order_1_to_20", curve}};
}

LutOptions lutOptionsFrom(const json& p) {
  LutOptions o;
  o.size = p["size"].get<int>();
  o.samples = p["samples"].get<int>();
  o.ndf = parseLutNdf(p["ndf"].get<std::string>(), "ndf");
  o.visibility = parseLutVisibility(p["visibility"].get<std::string>(), "visibility");
  o.multiscatter = p["multiscatter"].get<bool>();
  o.cloth = p["cloth"].get<bool>();
  o.kullaConty = p["kulla_conty"].get<bool>();
  o.alphaDirect = p["alpha_direct"].get<bool>();
  o.fastMath = p["fast_math"].get<bool>();
  if (!p["tolerance"].is_null()) o.tolerance = p["tolerance"].get<double>();
  o.toleranceMaxSamples = p["max_samples"].get<int>();
  validateLutOptions(o);
  return o;
}

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
  o.errorEstimate = !p["no_estimate"].get<bool>();
  return o;
}

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

namespace {

// --- transport: mesh → per-vertex PRT transfer (prtbake transport) ---
ExecResult runTransport(const Job& job, ExecContext& ctx) {
  const json& p = job.params;
  const TransportOptions options = transportOptionsFrom(p);
  // The preview shades the mesh with its albedo, as `prtbake preview mesh` does.
  const Mesh mesh = loadMesh(job.input, ctx.wants("png") ? MeshAlbedo::Textures : meshAlbedo(options));
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
  const LutOptions options = lutOptionsFrom(p);
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
ExecResult runPrefilter(const Job& job, ExecContext& ctx) {
  const json& p = job.params;
  const PrefilterOptions options = prefilterOptionsFrom(p);
  validatePrefilterOptions(options);
  // A lat-long OpenEXR file is read in bands (load_seconds then counts what precedes the
  // device's start, the bands included).
  const auto t0 = std::chrono::steady_clock::now();
  double loadSeconds = 0;
  EnvMap env;
  const PrefilterResult r = prefilterEnvironmentFile(
      [&]() -> Runtime& {
        loadSeconds = secondsSince(t0);
        return ctx.runtime();
      },
      job.input, envLoadOptionsFrom(p, false), p["yaw"].get<double>(), options, &env);
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

// The keys every environment product reads (env, prefilter, ibl).
std::vector<KeySpec> environmentKeys() {
  return {choice("layout", "auto", {"auto", "faces", "cross", "latlong", "games202"},
                 "environment layout (auto: from the file)"),
          number("yaw", 0.0, -kMaxYawDegrees, kMaxYawDegrees, "rotate the environment about +Y by this many degrees"),
          boolean("clamp_invalid", "replace NaN/Inf/negative texels by 0 (counted) instead of failing")};
}

// "tolerance" and "samples" exclude each other: a tolerance picks the sample count itself.
void samplesOrTolerance(const json& raw, KeyProblems& problems) {
  if (raw.contains("tolerance") && raw.contains("samples"))
    problems.push_back({"tolerance", "cannot be combined with samples (give one or the other)"});
  if (raw.contains("max_samples") && !raw.contains("tolerance"))
    problems.push_back({"max_samples", "only applies with tolerance"});
}

bool hasOutput(const json& raw, const char* kind) {
  return raw.contains("outputs") && raw["outputs"].is_object() && raw["outputs"].contains(kind);
}

// The library's own check of a product's options, as a problem of the key it names.
template <typename F>
void libraryCheck(KeyProblems& problems, F&& check) {
  if (!problems.empty()) return;
  try {
    check();
  } catch (const Error& e) {
    problems.push_back({e.subject().substr(e.subject().find_first_not_of('-')), e.detail()});
  }
}

JobType envType() {
  JobType t;
  t.name = "env";
  t.input = InputKind::FileOrDirectory;
  t.outputKinds = {"json", "games202", "png"};
  t.keys = {integer("order", 3, 1, kMaxShOrder, "SH order n: bands 0..n-1, n² coefficients; or auto"),
            number("tolerance", nullptr, 1e-9, 1.0,
                   "with order auto: the largest relative L2 error of the quantity (none: 0.01)"),
            choice("quantity", "radiance", {"radiance", "irradiance", "irradiance_over_pi"}, "what the coefficients hold"),
            choice("window", "none", {"none", "hann", "lanczos", "auto"},
                   "deringing window (auto: the weakest keeping irradiance >= 0)")};
  t.keys.front().orAuto = true;
  for (auto& k : environmentKeys()) t.keys.push_back(k);
  t.check = [](const json& raw, const json& p) {
    KeyProblems problems;
    if (raw.contains("tolerance") && p["order"] != "auto") problems.push_back({"tolerance", "only applies with order auto"});
    return problems;
  };
  t.execute = runEnv;
  return t;
}

JobType transportType() {
  JobType t;
  t.name = "transport";
  t.input = InputKind::File;
  t.outputKinds = {"npy", "gltf", "games202", "json", "png"};
  t.keys = {choice("mode", "shadowed", {"unshadowed", "shadowed", "interreflected"}, "what the transport includes"),
            integer("bounces", 3, 1, 64, "interreflection bounces (interreflected only)"),
            number("bounce_tolerance", 1e-4, 0.0, 1.0, "stop when a bounce adds less than this (0: never)"),
            integer("order", 3, 1, kMaxTransportOrder, "SH order"),
            integer("samples", 1024, 1, 1 << 24, "directions per vertex"),
            number("tolerance", nullptr, 1e-9, 1.0,
                   "the samples per vertex that bring 95 % of the vertices within this, predicted from a pilot "
                   "(docs/accuracy.md); excludes samples"),
            integer("max_samples", 65536, 2 * kTolerancePilotStart, 1 << 24, "with tolerance: the most samples per vertex"),
            choice("sampler", "hammersley", {"hammersley", "stratified", "random"}, "the directions' sequence"),
            integer("seed", 0, 0, 4294967295.0, "sample set seed"),
            number("albedo", nullptr, 0.0, 1.0, "a grey albedo for every vertex, overriding the file's"),
            {"preview_env", ValueKind::Path, nullptr, 0, 0, {},
             "the png output's lighting: a radiance SH JSON or an environment map", false}};
  t.check = [](const json& raw, const json& p) {
    KeyProblems problems;
    samplesOrTolerance(raw, problems);
    if (raw.contains("bounces") && p["mode"] != "interreflected")
      problems.push_back({"bounces", "only applies to mode 'interreflected'"});
    // Each bounce reads the previous bounce of every vertex: no vertex range can be
    // computed alone, so an interreflected job runs whole in one shard. (With a
    // tolerance every shard runs the same pilot over the whole mesh: the same counts.)
    if (raw.contains("split") && raw["split"] == json(true) && p["mode"] == "interreflected")
      problems.push_back({"split", "interreflected jobs cannot be split by vertices (each bounce needs every "
                                   "vertex's previous bounce); remove split to run the job whole in one shard"});
    const bool png = hasOutput(raw, "png");
    if (png && !raw.contains("preview_env"))
      problems.push_back({"preview_env", "a png output needs preview_env (a radiance SH JSON or an environment map)"});
    if (!png && raw.contains("preview_env")) problems.push_back({"preview_env", "only applies with a png output"});
    return problems;
  };
  t.execute = runTransport;
  t.splittable = true;
  return t;
}

JobType lutType() {
  JobType t;
  t.name = "lut";
  t.input = InputKind::None;
  t.outputKinds = {"exr", "json", "png"};
  t.keys = {integer("size", 128, 1, kLutMaxSize, "table size N (N x N texels)"),
            integer("samples", 1024, 1, kLutMaxSamples, "samples per texel"),
            number("tolerance", nullptr, 1e-9, 1.0,
                   "the samples per texel that bring 95 % of the texels within this in every channel, predicted "
                   "from a pilot (docs/accuracy.md); excludes samples"),
            integer("max_samples", kLutMaxSamples, 2 * kTolerancePilotStart, kLutMaxSamples,
                    "with tolerance: the most samples per texel"),
            choice("ndf", "ggx", {"ggx", "beckmann"}, "normal distribution"),
            choice("visibility", "smith-correlated", {"smith-correlated", "smith-separable", "schlick-ggx"},
                   "visibility term (schlick-ggx: k = alpha/2)"),
            boolean("multiscatter", "B channel: E = A + B for multiple-scattering compensation (Filament)"),
            boolean("cloth", "B channel: Charlie NDF with Ashikhmin visibility; excludes multiscatter"),
            boolean("kulla_conty", "extra channels E(mu, r) and Eavg(r) (Kulla-Conty)"),
            boolean("alpha_direct", "the roughness axis is alpha itself (default alpha = r^2)"),
            boolean("half", "16-bit half floats (default float32)"),
            boolean("fast_math", "native sqrt/divide/exp and -cl-fast-relaxed-math (docs/lut.md)")};
  t.check = [](const json& raw, const json& p) {
    KeyProblems problems;
    if (raw.contains("outputs") && raw["outputs"].is_object() && !hasOutput(raw, "exr"))
      problems.push_back({"outputs", "a lut job needs an 'exr' output (the 'json' sidecar describes it)"});
    samplesOrTolerance(raw, problems);
    if (p["multiscatter"] == true && p["cloth"] == true)
      problems.push_back({"cloth", "cannot be combined with multiscatter (both use the B channel)"});
    return problems;
  };
  t.execute = runLut;
  return t;
}

JobType prefilterType() {
  JobType t;
  t.name = "prefilter";
  t.input = InputKind::FileOrDirectory;
  t.outputKinds = {"ktx2", "exr", "json", "png"};
  t.keys = {choice("lobe", "ggx", {"ggx", "charlie", "lambertian"}, "the filter (lambertian: irradiance/pi)"),
            choice("schedule", "linear", {"linear", "filament", "babylon"}, "each level's roughness"),
            {"roughness", ValueKind::NumberList, nullptr, 0.0, 1.0, {},
             "explicit roughness per level, 1 to 16 numbers (instead of schedule)"},
            integer("size", 256, 1, kPrefilterMaxSize, "base face size N; the source is resampled to it"),
            integer("levels", nullptr, 1, kPrefilterMaxLevels,
                    "level count (none: down to 16x16, or to 1x1 for N <= 16; lambertian: 1)"),
            number("tolerance", 0.01, 1e-4, 0.1, "target of each level's estimated 99th-percentile relative error"),
            choice("method", "cut", {"cut", "sampled"},
                   "cut, or sampled (the anchors' estimator, for comparison; GGX only)"),
            integer("samples", 1024, 1, kPrefilterMaxSamples, "with method sampled: samples per texel"),
            boolean("float32", "KTX2 as RGBA32F (default RGBA16F; values above 65504 are clamped and counted)"),
            boolean("half", "OpenEXR as half (default float32)"),
            boolean("no_estimate", "skip the per-level error estimate (one pass at 2 x tolerance per bin)")};
  for (auto& k : environmentKeys()) t.keys.push_back(k);
  t.check = [](const json& raw, const json& p) {
    KeyProblems problems;
    const bool outputs = raw.contains("outputs") && raw["outputs"].is_object();
    if (outputs && !hasOutput(raw, "ktx2") && !hasOutput(raw, "exr"))
      problems.push_back({"outputs", "a prefilter job needs a 'ktx2' or an 'exr' output"});
    if (raw.contains("roughness") && raw.contains("schedule"))
      problems.push_back({"roughness", "a roughness list is its own schedule; it cannot be combined with schedule"});
    if (raw.contains("samples") && p["method"] != "sampled") problems.push_back({"samples", "only applies to method 'sampled'"});
    if (p["method"] == "sampled" && p["lobe"] != "ggx")
      problems.push_back({"method", "the sampled method compares with the anchors' GGX filtering; use lobe 'ggx'"});
    if (raw.contains("float32") && !hasOutput(raw, "ktx2")) problems.push_back({"float32", "only applies with a ktx2 output"});
    if (raw.contains("half") && !hasOutput(raw, "exr")) problems.push_back({"half", "only applies with an exr output"});
    const int size = p["size"].get<int>();
    if (hasOutput(raw, "exr") && (size & (size - 1)))
      problems.push_back({"size", "an exr output (a mip-mapped OpenEXR cube) needs a power-of-two size, got " +
                                      std::to_string(size) + " (ktx2 takes any size)"});
    libraryCheck(problems, [&] { validatePrefilterOptions(prefilterOptionsFrom(p)); });
    return problems;
  };
  t.execute = runPrefilter;
  return t;
}

JobType iblType() {
  JobType t;
  t.name = "ibl";
  t.input = InputKind::FileOrDirectory;
  t.outputKinds = {"dir"};
  t.keys = {{"target", ValueKind::ChoiceList, "all", 0, 0, {"all", "threejs", "filament", "babylon", "gltf"},
             "the engines, or a comma-separated list of them"},
            integer("size", 256, 16, 4096, "base face size of the prefiltered cubes (a power of two)"),
            integer("skybox_size", 0, 0, 4096, "Filament skybox face size (0: size)"),
            integer("lut_size", 128, 16, 1024, "glTF LUT size"),
            number("tolerance", 0.01, 1e-4, 0.1, "prefilter tolerance (see prefilter)")};
  for (auto& k : environmentKeys()) t.keys.push_back(k);
  t.check = [](const json& raw, const json& p) {
    KeyProblems problems;
    if (raw.contains("outputs") && raw["outputs"].is_object() && !hasOutput(raw, "dir"))
      problems.push_back({"outputs", "an ibl job needs a 'dir' output (the package directory)"});
    libraryCheck(problems, [&] { iblOptionsFrom(p); });
    return problems;
  };
  t.execute = runIbl;
  return t;
}

std::vector<JobType> makeJobTypes() {
  return {envType(), transportType(), lutType(), glossyJobType(), prefilterType(), iblType(), probesJobType(), lightmapJobType()};
}

}  // namespace

const std::vector<JobType>& jobTypes() {
  static const std::vector<JobType> types = makeJobTypes();
  return types;
}

}  // namespace prtbake::jobs
