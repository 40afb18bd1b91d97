// The "probes" job type (light probe grids, docs/probes.md): its keys are the options of
// `prtbake probes`, declared once here; the executor bakes the grid and produces the outputs
// asked for (npy, json; ktx2 and js for three.js).
#include <cmath>

#include "jobs.h"
#include "prtbake/atomic_file.h"
#include "prtbake/env.h"
#include "prtbake/error.h"
#include "prtbake/mesh.h"
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

ExecResult runProbes(const Job& job, ExecContext& ctx) {
  const json& p = job.params;
  const ProbeOptions o = probeOptionsFrom(p);
  const Mesh mesh = loadMesh(job.input);
  std::vector<std::string> read = mesh.inputFiles;
  const ShCoeffs env = probeEnvironment(p, ctx.runtime, &read);
  const ProbeGridResult g = computeProbeGrid(ctx.runtime(), mesh, env, o);
  const std::string envPath = p["env"].is_null() ? "" : p["env"].get<std::string>();
  std::vector<std::pair<std::string, std::string>> files;
  if (ctx.wants("npy")) files.emplace_back(ctx.output("npy"), probeGridNpyBytes(g));
  if (ctx.wants("json")) files.emplace_back(ctx.output("json"), probeGridSidecarBytes(job.input, o, env, envPath, g));
  if (ctx.wants("ktx2")) files.emplace_back(ctx.output("ktx2"), probeGridThreejsKtx2Bytes(g));
  if (ctx.wants("js")) {  // the loader names the atlas by its file name, beside it
    const std::string atlas = ctx.output("ktx2");
    files.emplace_back(ctx.output("js"), probeGridThreejsLoaderBytes(g, atlas.substr(atlas.find_last_of('/') + 1)));
  }
  for (const auto& [path, bytes] : files) writeFileAtomic(path, bytes);
  ExecResult result;
  result.inputFiles = filesRead(job, read);
  result.report = {{"probes", g.layout.count()}, {"moved", g.moved}, {"invalid", g.invalid},
                   {"samples_per_probe", g.samples}, {"rays", g.rays},
                   {"timings", {{"total_seconds", g.totalSeconds}, {"trace_seconds", g.traceSeconds}}}};
  return result;
}

}  // namespace

JobType probesJobType() {
  JobType t;
  t.name = "probes";
  t.input = InputKind::File;
  t.outputKinds = {"npy", "json", "ktx2", "js"};
  t.keys = {{"resolution", ValueKind::NumberList, nullptr, 1, kMaxProbesPerAxis, {},
             "probes along x, y and z (3 integers; none: from spacing)"},
            number("spacing", nullptr, 1e-6, 1e9, "the probes' spacing: NX = round(size_x / spacing), ... (none: 1/8 of the largest side)"),
            {"bounds", ValueKind::NumberList, nullptr, -1e9, 1e9, {},
             "the grid's box: min x, y, z then max x, y, z (none: the scene's bounding box)"},
            integer("order", 3, 2, 3, "SH order of the probes: 2 (L1, 4 coefficients) or 3 (L2, 9)"),
            integer("samples", 256, 1, 65536, "rays per probe"),
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
  return t;
}

}  // namespace prtbake::jobs
