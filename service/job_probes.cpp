// The "probes" job type (light probe grids, docs/probes.md): its keys are the options of
// `prtbake probes`, declared once here; the executor bakes the grid and produces the outputs
// asked for (npy, json; ktx2 and js for three.js).
#include <algorithm>
#include <cmath>

#include "jobs.h"
#include "prtbake/atomic_file.h"
#include "prtbake/hash.h"
#include "shard.h"
#include "prtbake/env.h"
#include "prtbake/error.h"
#include "prtbake/mesh.h"
#include "prtbake/preview.h"
#include "prtbake/probes.h"

namespace prtbake::jobs {

ProbeOptions probeOptionsFrom(const json& p) {
  ProbeOptions o;
  if (!p["resolution"].is_null()) {
    const auto& r = p["resolution"];
    o.resolution = std::array<int, 3>{r[0].get<int>(), r[1].get<int>(), r[2].get<int>()};
  }
  if (!p["spacing"].is_null()) o.spacing = p["spacing"].get<double>();
  if (!p["bounds"].is_null()) {
    const auto& b = p["bounds"];
    o.boundsMin = std::array<double, 3>{b[0].get<double>(), b[1].get<double>(), b[2].get<double>()};
    o.boundsMax = std::array<double, 3>{b[3].get<double>(), b[4].get<double>(), b[5].get<double>()};
  }
  o.order = p["order"].get<int>();
  o.samples = p["samples"].get<int>();
  if (!p["tolerance"].is_null()) o.tolerance = p["tolerance"].get<double>();
  o.toleranceMaxSamples = p["max_samples"].get<int>();
  o.seed = p["seed"].get<uint64_t>();
  o.bounces = p["bounces"].get<int>();
  o.transportSamples = p["transport_samples"].get<int>();
  if (!p["albedo"].is_null()) {
    const float a = p["albedo"].get<float>();
    o.albedoOverride = std::array<float, 3>{a, a, a};
  }
  o.backfaceLimit = p["backface_limit"].get<double>();
  o.relocateFraction = p["relocate"].get<double>();
  return o;
}

ShCoeffs probeEnvironment(const json& p, const std::function<Runtime&()>& runtime, std::vector<std::string>* files) {
  if (p["env"].is_null()) {  // a constant white environment: L = 1, l_0 = √(4π)
    ShCoeffs white;
    white.order = 1;
    const double l0 = std::sqrt(4 * 3.14159265358979323846);
    white.rgb = {Rgb{l0, l0, l0}};
    return white;
  }
  const std::string path = p["env"].get<std::string>();
  if (path.size() > 5 && path.substr(path.size() - 5) == ".json") {
    ShCoeffs sh = readShJson(path);
    if (sh.quantity != ShQuantity::Radiance)
      throw InputError(path, std::string("the probes need radiance coefficients (this file holds ") +
                                 toString(sh.quantity) + "); run prtbake env with --quantity radiance");
    if (files) files->push_back(path);
    return sh;
  }
  EnvProjectOptions po;
  po.order = p["env_order"].get<int>();
  EnvLoadOptions lo;
  lo.compact = true;
  EnvMap env;
  const EnvProjectResult r = projectEnvironmentFile(runtime, path, lo, 0.0, po, &env);
  if (files) files->insert(files->end(), env.inputFiles.begin(), env.inputFiles.end());
  return r.radiance;
}

namespace {

// The outputs a probes job asks for, from a whole grid (`outputs`: kind → path; the png needs
// the scene and the device).
void writeProbeOutputs(const std::map<std::string, std::string>& outputs, const std::string& input,
                       const ProbeOptions& o, const ShCoeffs& env, const std::string& envPath, const ProbeGridResult& g,
                       const Mesh& mesh, Runtime& rt) {
  std::vector<std::pair<std::string, std::string>> files;
  for (const auto& [kind, path] : outputs) {
    if (kind == "npy") files.emplace_back(path, probeGridNpyBytes(g));
    if (kind == "json") files.emplace_back(path, probeGridSidecarBytes(input, o, env, envPath, g));
    if (kind == "ktx2") files.emplace_back(path, probeGridThreejsKtx2Bytes(g));
    if (kind == "png") files.emplace_back(path, probeGridPreviewPngBytes(mesh, g, rt));
    if (kind == "js") {  // the loader names the atlas by its file name, beside it
      const std::string atlas = outputs.at("ktx2");
      files.emplace_back(path, probeGridThreejsLoaderBytes(g, atlas.substr(atlas.find_last_of('/') + 1)));
    }
  }
  for (const auto& [path, bytes] : files) writeFileAtomic(path, bytes);
}

json probeReport(const ProbeGridResult& g) {
  return {{"probes", g.probeCount}, {"moved", g.moved}, {"invalid", g.invalid}, {"fill_passes", g.fillPasses},
          {"samples_per_probe", g.samples}, {"rings", g.rings}, {"segments", g.segments}, {"rays", g.rays},
          {"environment_order", g.environmentOrder}, {"device", g.device},
          {"timings", {{"total_seconds", g.totalSeconds}, {"trace_seconds", g.traceSeconds},
                       {"surfaces_seconds", g.surfaceSeconds}, {"relocation_seconds", g.relocateSeconds},
                       {"bvh_seconds", g.bvhSeconds}}}};
}

std::string envPathOf(const json& p) { return p["env"].is_null() ? "" : p["env"].get<std::string>(); }

ExecResult runProbes(const Job& job, ExecContext& ctx) {
  const json& p = job.params;
  const ProbeOptions o = probeOptionsFrom(p);
  const Mesh mesh = loadMesh(job.input, meshAlbedo(o));
  std::vector<std::string> read = mesh.inputFiles;
  const ShCoeffs env = probeEnvironment(p, ctx.runtime, &read);
  const ProbeGridResult g = computeProbeGrid(ctx.runtime(), mesh, env, o);
  writeProbeOutputs(ctx.outputPaths, job.input, o, env, envPathOf(p), g, mesh, ctx.runtime());
  ExecResult result;
  result.inputFiles = filesRead(job, read);
  result.report = probeReport(g);
  return result;
}

// One shard's probe range of a split probes job (docs/scaleout.md): the partial .npy, probes
// traced and relocated but not filled (the merge fills the whole grid).
ExecResult runProbesPart(const Job& job, ExecContext& ctx) {
  const json& p = job.params;
  const int index = p.at("shard").at("index").get<int>(), count = p.at("shard").at("count").get<int>();
  ProbeOptions o = probeOptionsFrom(p);
  const Mesh mesh = loadMesh(job.input, meshAlbedo(o));
  std::vector<std::string> read = mesh.inputFiles;
  const ShCoeffs env = probeEnvironment(p, ctx.runtime, &read);
  const size_t total = probeGridLayout(mesh, o).count();
  const auto [first, n] = vertexRange(total, index, count);
  o.firstProbe = first;
  o.probeCount = n;
  const ProbeGridResult g = computeProbeGrid(ctx.runtime(), mesh, env, o);
  const std::string bytes = probeRangeNpyBytes(g);
  writeFileAtomic(ctx.output("npy"), bytes);
  ExecResult result;
  result.inputFiles = filesRead(job, read);
  result.report = probeReport(g);
  result.report["shard"] = {{"index", index}, {"count", count}};
  result.report["first_probe"] = first;
  result.report["probe_count"] = n;
  result.report["grid_probes"] = total;
  result.report["partial_sha256"] = sha256Hex(bytes.data(), bytes.size());
  return result;
}

}  // namespace

std::string probeGridPreviewPngBytes(const Mesh& mesh, const ProbeGridResult& g, Runtime& rt) {
  MeshPreviewOptions view;
  view.yawDeg = 30, view.pitchDeg = 25;
  view.width = 640, view.height = 480;
  const LinearImage image = renderProbeGridPreview(rt, mesh, g, view);
  // Exposure: the 95th percentile of the pixels' largest channel at 0.8 (a sky with a sun lights
  // the scene far above 1).
  std::vector<float> peak(image.rgb.size() / 3);
  for (size_t i = 0; i < peak.size(); ++i)
    peak[i] = std::max({image.rgb[3 * i], image.rgb[3 * i + 1], image.rgb[3 * i + 2]});
  std::nth_element(peak.begin(), peak.begin() + ptrdiff_t(peak.size() * 95 / 100), peak.end());
  const float p95 = peak[peak.size() * 95 / 100];
  ToneMap tone;
  tone.exposureStops = p95 > 0 ? std::log2(0.8 / p95) : 0.0;
  return previewPngBytes(image, tone,
                         {{"Description", "prtbake probe grid preview: the scene lit by the grid (E/pi at each vertex "
                                          "half a cell out along its normal), a sphere per probe shaded by it (red: "
                                          "invalid, filled), and the grid's horizontal slice at mid-height (E/pi, up)"}});
}

const JobType& probesPartialType() {
  static const JobType type = [] {
    JobType t;
    t.name = "probes_shard";
    t.input = InputKind::File;
    t.outputKinds = {"npy"};
    t.execute = runProbesPart;
    return t;
  }();
  return type;
}

std::vector<std::string> mergeProbesSplit(const Job& job, int n, const std::vector<json>& manifests, json* info) {
  const json& p = job.params;
  const ProbeOptions o = probeOptionsFrom(p);
  const size_t total = manifestInt(manifests[0]["report"], "grid_probes", size_t(0));
  ProbeGridResult g;
  g.order = o.order;
  g.probeCount = total;
  const size_t nc = size_t(g.order) * g.order * 3;
  double seconds = 0;
  for (int i = 0; i < n; ++i) {
    const json& rep = manifests[size_t(i)]["report"];
    const std::string path = partialPath(job, i, n);
    size_t rows = 0, columns = 0;
    const std::vector<float> part = readPartialNpy(path, &rows, &columns);
    if (manifestInt(rep, "grid_probes", size_t(0)) != total || rows != manifestInt(rep, "probe_count", size_t(0)) ||
        columns != nc + kProbeRangeExtraColumns)
      throw InputError(path, "shape does not match the job's grid (" + std::to_string(total) + " probes of order " +
                                 std::to_string(g.order) + ")");
    appendProbeRange(g, part, rows);
    g.rays += manifestInt(rep, "rays", uint64_t(0));
    seconds += rep["timings"].value("total_seconds", 0.0);
  }
  if (g.state.size() != total) return {"the shards hold " + std::to_string(g.state.size()) + " probes of " + std::to_string(total)};
  const json& first = manifests[0]["report"];
  g.samples = first.value("samples_per_probe", 0);
  g.rings = first.value("rings", 0);
  g.segments = first.value("segments", 0);
  g.environmentOrder = first.value("environment_order", 0);
  g.device = first.value("device", std::string());
  g.totalSeconds = seconds;
  for (uint8_t s : g.state) g.moved += s == 1, g.invalid += s == 2;
  const Mesh mesh = loadMesh(job.input);  // the layout's bounds come from the scene
  g.layout = probeGridLayout(mesh, o);
  if (g.layout.count() != total) throw InputError(job.input, "gives another grid than the shards saw");
  fillInvalidProbes(g);
  // The sidecar names the environment and its order; the coefficients are already in the grid.
  ShCoeffs env;
  env.order = first.value("environment_order", 1);
  std::map<std::string, std::string> outputs;
  for (const auto& out : job.outputs) outputs[out.kind] = out.path;
  removeOldManifest(job);
  writeProbeOutputs(outputs, job.input, o, env, envPathOf(p), g, mesh, processRuntime(""));
  writeMergedManifest(job, manifests[0], g.device, seconds, probeReport(g));
  *info = {{"probes", total}};
  return {};
}

JobType probesJobType() {
  JobType t;
  t.name = "probes";
  t.input = InputKind::File;
  t.outputKinds = {"npy", "json", "ktx2", "js", "png"};
  t.keys = {{"resolution", ValueKind::NumberList, nullptr, 1, kMaxProbesPerAxis, {},
             "probes along x, y and z (3 integers; none: from spacing)"},
            number("spacing", nullptr, 1e-6, 1e9, "the probes' spacing: NX = round(size_x / spacing), ... (none: 1/8 of the largest side)"),
            {"bounds", ValueKind::NumberList, nullptr, -1e9, 1e9, {},
             "the grid's box: min x, y, z then max x, y, z (none: the scene's bounding box)"},
            integer("order", 3, 2, 3, "SH order of the probes: 2 (L1, 4 coefficients) or 3 (L2, 9)"),
            integer("samples", 256, 1, 65536, "rays per probe"),
            number("tolerance", nullptr, 1e-6, 1.0,
                   "the rays per probe that bring 95 % of the probes' coefficients within this fraction of the "
                   "environment's l_0, predicted from a pilot (docs/probes.md); excludes samples"),
            integer("max_samples", 65536, 64, 65536, "with tolerance: the most rays per probe"),
            integer("bounces", 1, 0, 16, "light bounced off the surfaces (0: surfaces black; B: B - 1 interreflections)"),
            integer("transport_samples", 256, 1, 1 << 20, "rays per vertex of the surfaces' transport (bounces >= 1)"),
            integer("seed", 0, 0, 4294967295.0, "the probes' quadrature rotations"),
            number("albedo", nullptr, 0.0, 1.0, "a grey albedo for every vertex, overriding the file's"),
            number("backface_limit", 0.25, 1e-6, 1.0, "fraction of back-face hits that marks a probe inside geometry"),
            number("relocate", 0.45, 0.0, 1.0, "the farthest move of a probe inside geometry, in cells (0: none)"),
            {"env", ValueKind::Path, nullptr, 0, 0, {},
             "the lighting: a radiance SH JSON (prtbake env) or an environment map (none: constant white)"},
            integer("env_order", 8, 1, 8, "SH order an environment map is projected to")};
  t.check = [](const json& raw, const json& p) {
    KeyProblems problems;
    if (raw.contains("resolution") && p["resolution"].size() != 3)
      problems.push_back({"resolution", "expected 3 integers (NX, NY, NZ)"});
    if (raw.contains("resolution"))
      for (const auto& v : p["resolution"])
        if (v.get<double>() != std::floor(v.get<double>())) problems.push_back({"resolution", "expected integers"});
    if (raw.contains("bounds") && p["bounds"].size() != 6)
      problems.push_back({"bounds", "expected 6 numbers (min x, y, z, max x, y, z)"});
    if (raw.contains("tolerance") && raw.contains("samples"))
      problems.push_back({"tolerance", "cannot be combined with samples (give one or the other)"});
    if (raw.contains("max_samples") && !raw.contains("tolerance"))
      problems.push_back({"max_samples", "only applies with tolerance"});
    if (raw.contains("resolution") && raw.contains("spacing"))
      problems.push_back({"spacing", "cannot be combined with resolution"});
    if (raw.contains("env_order") && (!raw.contains("env") || (p["env"].is_string() &&
                                                                p["env"].get<std::string>().size() > 5 &&
                                                                p["env"].get<std::string>().substr(p["env"].get<std::string>().size() - 5) == ".json")))
      problems.push_back({"env_order", "only applies to an environment map"});
    const bool ktx2 = raw.contains("outputs") && raw["outputs"].is_object() && raw["outputs"].contains("ktx2");
    const bool js = raw.contains("outputs") && raw["outputs"].is_object() && raw["outputs"].contains("js");
    if (js && !ktx2) problems.push_back({"outputs", "a js output (the three.js loader) needs the ktx2 output it loads"});
    if (ktx2 && p["order"] != 3)
      problems.push_back({"order", "three.js's LightProbeGridWebGL holds L2 probes: a ktx2 output needs order 3"});
    if (raw.contains("transport_samples") && p["bounces"] == 0)
      problems.push_back({"transport_samples", "only applies with bounces >= 1"});
    if (problems.empty() && raw.contains("bounds")) {
      const auto& b = p["bounds"];
      for (int a = 0; a < 3; ++a)
        if (!(b[a + 3].get<double>() > b[a].get<double>()))
          problems.push_back({"bounds", std::string("empty or inverted along ") + "xyz"[a]});
    }
    return problems;
  };
  t.execute = runProbes;
  t.splittable = true;
  return t;
}

}  // namespace prtbake::jobs
