// The "glossy" job type (glossy transfer matrices, docs/jobs.md): its schema mirrors
// `prtbake transport --transfer matrix`, its executor streams the matrices to the "npy"
// output, and a job with "split": true runs as vertex ranges in every shard (the partial
// type below) that `prtbake merge` concatenates (mergeGlossySplit), bit-identical to a
// one-process run on the same device type.
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "jobs.h"
#include "manifest.h"
#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/glossy.h"
#include "prtbake/hash.h"
#include "prtbake/limits.h"
#include "prtbake/mesh.h"
#include "shard.h"

namespace prtbake::jobs {

GlossyOptions glossyOptionsFrom(const json& p) {
  GlossyOptions o;
  o.mode = parseTransportMode(p["mode"].get<std::string>());
  const int order = p["order"].get<int>();
  o.orderOut = p["order_out"].is_null() ? order : p["order_out"].get<int>();
  o.orderIn = p["order_in"].is_null() ? order : p["order_in"].get<int>();
  o.samples = p["samples"].get<int>();
  o.seed = p["seed"].get<uint64_t>();
  o.bounces = p["bounces"].get<int>();
  o.bounceTolerance = p["bounce_tolerance"].get<double>();
  if (!p["albedo"].is_null()) {
    const float a = p["albedo"].get<float>();
    o.albedoOverride = std::array<float, 3>{a, a, a};
  }
  return o;
}

CpcaOptions cpcaOptionsFrom(const json& p) {
  CpcaOptions c;
  if (!p["cpca_clusters"].is_null()) {
    c.clusters = p["cpca_clusters"].get<int>();
    c.vectors = p["cpca_vectors"].get<int>();
  } else if (!p["cpca_error"].is_null()) {
    c.targetError = p["cpca_error"].get<double>();
  }
  c.weightBits = p["cpca_weights"].get<std::string>() == "int8" ? 8 : 32;
  return c;
}

std::vector<double> brdfFrom(const json& p, int orderOut) {
  const std::string b = p["brdf"].get<std::string>();
  if (b == "none") return {};
  BrdfSpec s;
  s.lambertian = b == "lambertian";
  s.roughness = p["roughness"].get<double>();
  s.f0 = p["f0"].get<double>();
  s.albedo = p["brdf_albedo"].get<double>();
  return brdfMatrixLocal(s, orderOut);
}

namespace {

// The bake of vertices [first, first + count) streamed to `npyPath`; values kept when asked.
GlossyStats bake(Runtime& rt, const Mesh& mesh, const json& p, GlossyOptions o, const std::string& npyPath,
                 std::vector<float>* keep) {
  const MatrixDtype dtype = parseMatrixDtype(p["dtype"].get<std::string>());
  const int ch = glossyChannels(mesh, o);
  const std::vector<double> brdf = brdfFrom(p, o.orderOut);
  const size_t count = o.vertexCount ? *o.vertexCount : mesh.vertexCount() - o.firstVertex;
  NpyStreamWriter writer(npyPath, glossyNpyShape(count, ch, o.orderOut, o.orderIn), dtype);
  std::vector<float> block;
  const GlossyStats st = bakeGlossyTransfer(rt, mesh, o, [&](size_t f, size_t n, const float* values) {
    const size_t k = n * size_t(ch) * o.orderOut * o.orderOut * o.orderIn * o.orderIn;
    if (!brdf.empty()) {
      block.assign(values, values + k);
      exitRadianceBlock(mesh, f, n, ch, o.orderOut, o.orderIn, brdf, block.data());
      values = block.data();
    }
    writer.append(values, k);
    if (keep) keep->insert(keep->end(), values, values + k);
  });
  writer.commit();
  return st;
}

json statsReport(const GlossyStats& st) {
  return {{"vertices", st.vertexCount},
          {"channels", st.channels},
          {"order_out", st.orderOut},
          {"order_in", st.orderIn},
          {"samples", st.samples},
          {"rays", st.rays},
          {"bounces_used", st.bouncesUsed},
          {"standard_error_max", st.maxStdError},
          {"standard_error_mean", st.meanStdError},
          {"vertices_unoccludable", st.verticesUnoccludable},
          {"vertices_without_normal", st.verticesWithoutNormal},
          {"degenerate_triangles", st.degenerateTriangles},
          {"bvh_nodes", st.bvhNodes},
          {"device", st.device},
          {"timings", {{"diffuse_seconds", st.diffuseSeconds}, {"kernel_seconds", st.kernelSeconds},
                       {"total_seconds", st.totalSeconds}}}};
}

// The sidecar and the CPCA archive of a whole bake (one process or merged).
void writeExtras(const Job& job, const std::map<std::string, std::string>& paths, const Mesh& mesh, const GlossyOptions& o,
                 const GlossyStats& st, const std::vector<float>& values, json& report) {
  const json& p = job.params;
  const MatrixDtype dtype = parseMatrixDtype(p["dtype"].get<std::string>());
  json side = json::parse(glossySidecarBytes(job.input, mesh, o, st, dtype, job.outputs.front().path));
  std::vector<std::pair<std::string, std::string>> files;
  if (paths.count("cpca")) {
    const CpcaResult c = cpcaCompress(values.data(), st.vertexCount, values.size() / std::max<size_t>(st.vertexCount, 1),
                                      cpcaOptionsFrom(p));
    files.emplace_back(paths.at("cpca"), cpcaNpzBytes(c, st.orderOut, st.orderIn, st.channels));
    side["cpca"] = json::parse(cpcaSidecarJson(c, job.findOutput("cpca")->path));
    report["cpca"] = {{"clusters", c.clusters}, {"vectors", c.vectors}, {"error_total", c.totalError},
                      {"compression_ratio", c.compressionRatio()}};
  }
  if (p["brdf"] != "none") side["brdf"] = {{"brdf", p["brdf"]}, {"roughness", p["roughness"]}, {"f0", p["f0"]}};
  if (paths.count("json")) files.emplace_back(paths.at("json"), side.dump(2) + "\n");
  for (const auto& [path, bytes] : files) writeFileAtomic(path, bytes);
}

ExecResult runGlossy(const Job& job, ExecContext& ctx) {
  const json& p = job.params;
  const GlossyOptions o = glossyOptionsFrom(p);
  checkGlossyOptions(o);
  const Mesh mesh = loadMesh(job.input, meshAlbedo(o));
  const bool cpca = ctx.wants("cpca");
  const double bytes = glossyMatrixBytes(mesh.vertexCount(), glossyChannels(mesh, o), o.orderOut, o.orderIn);
  if (cpca && bytes > double(inputMemoryLimit()))
    throw UsageError("cpca", "CPCA holds the matrices in memory: " + std::to_string(int64_t(bytes / 1048576)) +
                                 " MiB, more than the memory limit of " +
                                 std::to_string(inputMemoryLimit() / 1048576) + " MiB");
  std::vector<float> values;
  const GlossyStats st = bake(ctx.runtime(), mesh, p, o, ctx.output("npy"), cpca ? &values : nullptr);
  ExecResult result;
  result.report = statsReport(st);
  writeExtras(job, ctx.outputPaths, mesh, o, st, values, result.report);
  meshInputs(job, mesh, result);
  return result;
}

// One shard's vertex range of a split glossy job (docs/scaleout.md): the partial .npy.
ExecResult runGlossyPart(const Job& job, ExecContext& ctx) {
  const json& shard = job.params.at("shard");
  const int index = shard.at("index").get<int>(), count = shard.at("count").get<int>();
  GlossyOptions o = glossyOptionsFrom(job.params);
  const Mesh mesh = loadMesh(job.input, meshAlbedo(o));
  const auto [first, n] = vertexRange(mesh.vertexCount(), index, count);
  o.firstVertex = first;
  o.vertexCount = n;
  const std::string path = ctx.output("npy");
  const GlossyStats st = bake(ctx.runtime(), mesh, job.params, o, path, nullptr);
  ExecResult result;
  meshInputs(job, mesh, result);
  result.report = statsReport(st);
  result.report["shard"] = {{"index", index}, {"count", count}};
  result.report["first_vertex"] = first;
  result.report["vertex_count"] = n;
  result.report["mesh_vertices"] = mesh.vertexCount();
  result.report["partial_sha256"] = sha256File(path);
  return result;
}

}  // namespace

JobType glossyJobType() {
  JobType t;
  t.name = "glossy";
  t.input = InputKind::File;
  t.outputKinds = {"npy", "json", "cpca"};
  t.keys = {choice("mode", "shadowed", {"unshadowed", "shadowed", "interreflected"}, "what the transfer includes"),
            integer("order", 3, kMinGlossyOrder, kMaxGlossyOrder, "SH order of both sides"),
            integer("order_out", nullptr, kMinGlossyOrder, kMaxGlossyOrder,
                    "SH order of the transferred radiance (none: order)"),
            integer("order_in", nullptr, kMinGlossyOrder, kMaxGlossyOrder, "SH order of the environment (none: order)"),
            integer("samples", 1024, 1, 1 << 24, "directions per vertex"),
            integer("seed", 0, 0, 4294967295.0, "sample set seed"),
            integer("bounces", 3, 1, 64, "interreflection bounces (interreflected only)"),
            number("bounce_tolerance", 1e-4, 0.0, 1.0, "stop when a bounce adds less than this (0: never)"),
            number("albedo", nullptr, 0.0, 1.0, "a grey albedo for every vertex, overriding the file's"),
            choice("dtype", "float32", {"float32", "float16"}, "the matrices' element type"),
            choice("brdf", "none", {"none", "ggx", "lambertian"},
                   "write exit-radiance matrices for this BRDF (command line: also ggx:R[:F0] or lambertian[:A])"),
            number("roughness", 0.5, 0.05, 1.0, "brdf ggx: perceptual roughness (alpha = r^2)"),
            number("f0", 0.04, 0.0, 1.0, "brdf ggx: reflectance at normal incidence"),
            number("brdf_albedo", 1.0, 0.0, 1.0, "brdf lambertian: its albedo"),
            integer("cpca_clusters", nullptr, 1, 65536, "CPCA clusters K (with cpca_vectors)"),
            integer("cpca_vectors", nullptr, 0, kMaxCpcaVectors, "CPCA vectors P per cluster (with cpca_clusters)"),
            number("cpca_error", nullptr, 1e-6, 0.999, "CPCA: choose K and P for this relative RMS error"),
            choice("cpca_weights", "float32", {"float32", "int8"},
                   "CPCA weights (int8: with a scale per cluster and vector)")};
  t.check = [](const json& raw, const json& p) {
    std::vector<std::pair<std::string, std::string>> problems;
    const bool outputsObject = raw.contains("outputs") && raw["outputs"].is_object();
    if (outputsObject && !raw["outputs"].contains("npy"))
      problems.push_back({"outputs", "a glossy job needs an 'npy' output (the matrices; 'json' and 'cpca' go with it)"});
    if (raw.contains("bounces") && p["mode"] != "interreflected")
      problems.push_back({"bounces", "only applies to mode 'interreflected'"});
    if (raw.contains("cpca_clusters") != raw.contains("cpca_vectors"))
      problems.push_back({"cpca_vectors", "give cpca_clusters and cpca_vectors together"});
    if (raw.contains("cpca_clusters") && raw.contains("cpca_error"))
      problems.push_back({"cpca_error", "give cpca_clusters/cpca_vectors or cpca_error, not both"});
    const bool cpcaOut = outputsObject && raw["outputs"].contains("cpca");
    if (cpcaOut != (raw.contains("cpca_clusters") || raw.contains("cpca_error")))
      problems.push_back({"cpca", "a 'cpca' output and cpca_clusters/cpca_vectors or cpca_error go together"});
    if ((raw.contains("roughness") || raw.contains("f0")) && p["brdf"] != "ggx")
      problems.push_back({"roughness", "roughness and f0 only apply to brdf 'ggx'"});
    if (raw.contains("brdf_albedo") && p["brdf"] != "lambertian")
      problems.push_back({"brdf_albedo", "only applies to brdf 'lambertian'"});
    if (raw.contains("cpca_weights") && !raw.contains("cpca_clusters") && !raw.contains("cpca_error"))
      problems.push_back({"cpca_weights", "goes with cpca_clusters/cpca_vectors or cpca_error"});
    return problems;
  };
  t.execute = runGlossy;
  t.splittable = true;
  return t;
}

const JobType& glossyPartialType() {
  static const JobType type = [] {
    JobType t;
    t.name = "glossy_shard";
    t.input = InputKind::File;
    t.outputKinds = {"npy"};
    t.execute = runGlossyPart;
    return t;
  }();
  return type;
}

std::vector<std::string> mergeGlossySplit(const Job& job, int n, const std::vector<json>& manifests, json* info) {
  const json& p = job.params;
  const GlossyOptions o = glossyOptionsFrom(p);
  const MatrixDtype dtype = parseMatrixDtype(p["dtype"].get<std::string>());
  const size_t vertices = manifestInt(manifests[0]["report"], "mesh_vertices", size_t(0));
  const int channels = manifestInt(manifests[0]["report"], "channels", 1);
  // The partials' data, in vertex order, after their headers: the merged file is the
  // one-process file byte for byte (same header, same values).
  std::vector<std::string> data;
  GlossyStats st;
  st.orderOut = o.orderOut, st.orderIn = o.orderIn, st.channels = channels, st.vertexCount = vertices;
  st.samples = manifestInt(manifests[0]["report"], "samples", 0);
  double errSum = 0;
  const size_t elem = dtype == MatrixDtype::Float16 ? 2 : 4;
  const size_t per = size_t(channels) * o.orderOut * o.orderOut * o.orderIn * o.orderIn;
  for (int i = 0; i < n; ++i) {
    const json& rep = manifests[size_t(i)]["report"];
    const std::string path = partialPath(job, i, n);
    const std::string bytes = readFile(path);
    if (bytes.size() < 10 || bytes.compare(0, 8, std::string("\x93NUMPY\x01\x00", 8)) != 0)
      throw InputError(path, "not a partial result: no .npy header");
    const size_t offset = 10 + (size_t(uint8_t(bytes[8])) | size_t(uint8_t(bytes[9])) << 8);
    const size_t rows = manifestInt(rep, "vertex_count", size_t(0));
    if (bytes.size() < offset || bytes.size() - offset != rows * per * elem ||
        manifestInt(rep, "channels", 0) != channels)
      throw InputError(path, "shape does not match the job (orders, channels or dtype)");
    data.push_back(bytes.substr(offset));
    st.bouncesUsed = std::max(st.bouncesUsed, manifestInt(rep, "bounces_used", 0));
    st.diffuseSeconds += rep["timings"].value("diffuse_seconds", 0.0);
    addShardReport(st, rep, &errSum);
  }
  st.meanStdError = vertices ? errSum / double(vertices) : 0;
  const Mesh mesh = loadMergedMesh(job, vertices);
  removeOldManifest(job);
  AtomicFile npy(job.outputs.front().path);
  npy.write(glossyNpyHeader(glossyNpyShape(vertices, channels, o.orderOut, o.orderIn), dtype));
  for (const std::string& d : data) npy.write(d);
  std::vector<float> values;
  std::map<std::string, std::string> paths;
  for (const auto& out : job.outputs)
    if (out.kind != "npy") paths[out.kind] = out.path;
  if (paths.count("cpca")) {
    values.reserve(vertices * per);
    for (const std::string& d : data) {
      const size_t k = d.size() / elem;
      for (size_t i = 0; i < k; ++i) {
        if (elem == 4) {
          float f;
          std::memcpy(&f, d.data() + 4 * i, 4);
          values.push_back(f);
        } else {
          uint16_t h;
          std::memcpy(&h, d.data() + 2 * i, 2);
          values.push_back(halfToFloat(h));
        }
      }
    }
  }
  json report = statsReport(st);
  report["shards"] = n;
  writeExtras(job, paths, mesh, o, st, values, report);
  npy.commit();
  writeMergedManifest(job, manifests[0], st.device, st.totalSeconds, report);
  *info = {{"vertices", vertices}};
  return {};
}

}  // namespace prtbake::jobs
