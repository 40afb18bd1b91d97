// prtbake transport --transfer matrix (glossy transfer matrices), prtbake cpca, and the
// glossy mesh preview (see prtbake/glossy.h, docs/glossy.md).
#include <sys/stat.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>

#include <nlohmann/json.hpp>

#include "glossy_cli.h"
#include "jobs.h"
#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/glossy.h"
#include "prtbake/preview.h"
#include "prtbake/limits.h"
#include "prtbake/mesh.h"
#include "prtbake/runtime.h"

namespace prtbake::cli {
namespace {

std::string mib(double bytes) {
  char b[64];
  std::snprintf(b, sizeof b, "%.0f MiB", bytes / (1024.0 * 1024.0));
  return b;
}

// --cpca-weights / --weights float32|int8.
int cpcaWeightBits(const CommandLine& cl, const std::string& name) {
  return cl.getChoice(name, "float32", {"float32", "int8"}) == "int8" ? 8 : 32;
}

// The glossy keys of the command line, with its two shorthands written out:
// --brdf ggx:R[:F0] | lambertian[:A] (brdf, roughness, f0, brdf_albedo) and
// --cpca K,P (cpca_clusters, cpca_vectors).
std::map<std::string, std::string> glossyTexts(const CommandLine& cl) {
  std::map<std::string, std::string> texts = keyTexts(cl);
  const std::string brdf = cl.get("brdf");
  if (const size_t colon = brdf.find(':'); colon != std::string::npos) {
    for (const char* key : {"roughness", "f0", "brdf-albedo"})
      if (cl.has(key)) throw UsageError("--" + std::string(key), "give it or --brdf " + brdf + ", not both");
    const std::string name = brdf.substr(0, colon), rest = brdf.substr(colon + 1);
    const size_t second = rest.find(':');
    texts["brdf"] = name;
    if (name == "ggx") {
      texts["roughness"] = rest.substr(0, second);
      if (second != std::string::npos) texts["f0"] = rest.substr(second + 1);
    } else if (name == "lambertian" && second == std::string::npos) {
      texts["brdf_albedo"] = rest;
    } else {
      throw UsageError("--brdf", "expected ggx:R[:F0] or lambertian[:A], got '" + brdf + "'");
    }
  }
  if (cl.has("cpca")) {
    if (cl.has("cpca-clusters") || cl.has("cpca-vectors"))
      throw UsageError("--cpca", "give --cpca K,P or --cpca-clusters K --cpca-vectors P, not both");
    const std::string kp = cl.get("cpca");
    const size_t comma = kp.find(',');
    if (comma == std::string::npos) throw UsageError("--cpca", "expected K,P (clusters, vectors), got '" + kp + "'");
    texts["cpca_clusters"] = kp.substr(0, comma);
    texts["cpca_vectors"] = kp.substr(comma + 1);
    texts.erase("cpca");
  }
  return texts;
}

std::string cpcaLine(const CpcaResult& c) {
  char line[256];
  std::snprintf(line, sizeof line,
                "cpca: K = %d clusters, P = %d vectors, relative RMS error %.4f total (per vertex: RMS %.4f, max %.4f), "
                "%.1fx smaller than float32 matrices (%s weights), %d iterations, %.2f s",
                c.clusters, c.vectors, c.totalError, c.rmsVertexError, c.maxVertexError, c.compressionRatio(),
                c.weightBits == 8 ? "int8" : "float32", c.iterations, c.seconds);
  return line;
}

}  // namespace

int runGlossyTransport(const CommandLine& cl) {
  const std::string input = cl.positional.at(0), out = cl.get("output");
  if (out.empty()) throw UsageError("transport", "missing -o OUT.npy");
  std::vector<std::string> vectorOnly = optionsOnlyOf("transport", "glossy");
  vectorOnly.insert(vectorOnly.end(), {"gltf", "games202"});
  for (const std::string& name : vectorOnly)
    if (cl.has(name)) throw UsageError("--" + name, "only applies to --transfer vector");
  const std::map<std::string, std::string> texts = glossyTexts(cl);
  const bool cpca = texts.count("cpca_clusters") || texts.count("cpca_error");
  nlohmann::json outputs = {{"npy", out}, {"json", sidecarPath(out)}};
  if (cpca) outputs["cpca"] = stem(out) + ".cpca.npz";
  const nlohmann::json p = productParams("glossy", texts, outputs, {input});
  GlossyOptions o = jobs::glossyOptionsFrom(p);
  const MatrixDtype dtype = parseMatrixDtype(p["dtype"].get<std::string>());
  const bool brdf = p["brdf"] != "none";
  const CpcaOptions co = jobs::cpcaOptionsFrom(p);
  checkGlossyOptions(o);  // orders and counts before anything is read

  const Mesh mesh = loadMesh(input, meshAlbedo(o));
  const size_t nv = mesh.vertexCount();
  const int channels = glossyChannels(mesh, o);
  const double bytes = glossyMatrixBytes(nv, channels, o.orderOut, o.orderIn);
  const int dim = channels * o.orderOut * o.orderOut * o.orderIn * o.orderIn;
  if (cpca && co.vectors > dim)  // before the bake (symmetric matrices are checked after it)
    throw UsageError("--cpca", "more PCA vectors (" + std::to_string(co.vectors) + ") than values per vertex (" +
                                   std::to_string(dim) + ")");
  if (cpca && bytes > double(inputMemoryLimit()))
    throw UsageError("--cpca", "CPCA holds the matrices in memory: " + std::to_string(nv) + " vertices at orders " +
                                   std::to_string(o.orderOut) + " x " + std::to_string(o.orderIn) + " need " + mib(bytes) +
                                   ", more than the memory limit of " + mib(double(inputMemoryLimit())) +
                                   " (set PRTBAKE_INPUT_LIMIT_MB, or run prtbake cpca on a vertex range)");
  status(cl, "transport: " + input + ": " + std::to_string(nv) + " vertices, " + std::to_string(mesh.triangleCount()) +
                 " triangles, transfer matrices " + std::to_string(o.orderOut * o.orderOut) + " x " +
                 std::to_string(o.orderIn * o.orderIn) + ", " + transportModeName(o.mode) + ", " +
                 std::to_string(o.samples) + " samples, " + mib(bytes) + " of float32 streamed to " + out);
  Runtime& rt = jobs::processRuntime(cl.device());
  const std::vector<double> b = jobs::brdfFrom(p, o.orderOut);
  NpyStreamWriter writer(out, glossyNpyShape(nv, channels, o.orderOut, o.orderIn), dtype);
  std::vector<float> kept, block;
  if (cpca) kept.reserve(size_t(bytes / 4));
  const GlossyStats st = bakeGlossyTransfer(rt, mesh, o, [&](size_t f, size_t n, const float* values) {
    const size_t count = n * size_t(channels) * o.orderOut * o.orderOut * o.orderIn * o.orderIn;
    if (brdf) {
      block.assign(values, values + count);
      exitRadianceBlock(mesh, f, n, channels, o.orderOut, o.orderIn, b, block.data());
      values = block.data();
    }
    writer.append(values, count);
    if (cpca) kept.insert(kept.end(), values, values + count);
  });
  nlohmann::json side = nlohmann::json::parse(glossySidecarBytes(input, mesh, o, st, dtype, out));
  if (brdf)
    side["brdf"] = {{"spec", cl.get("brdf")},
                    {"quantity", "exit-radiance matrices E = S B S^T M: environment SH -> SH of the exit radiance over "
                                 "the outgoing direction (docs/glossy.md)"}};
  std::vector<std::pair<std::string, std::string>> extra;
  CpcaResult c;
  if (cpca) {
    c = cpcaCompress(kept.data(), nv, kept.size() / std::max<size_t>(nv, 1), co);
    const std::string npz = stem(out) + ".cpca.npz";
    extra.emplace_back(npz, cpcaNpzBytes(c, o.orderOut, o.orderIn, channels));
    side["cpca"] = nlohmann::json::parse(cpcaSidecarJson(c, npz));
  }
  extra.emplace_back(sidecarPath(out), side.dump(2) + "\n");
  std::vector<std::unique_ptr<AtomicFile>> files;
  for (const auto& [path, data] : extra) {
    files.push_back(std::make_unique<AtomicFile>(path));
    files.back()->write(data);
  }
  writer.commit();
  for (auto& f : files) f->commit();
  char line[256];
  std::snprintf(line, sizeof line, "transport: %.3f s (kernels %.3f s), %.3g rays, std. error max %.3g mean %.3g%s",
                st.totalSeconds, st.kernelSeconds, double(st.rays), st.maxStdError, st.meanStdError,
                o.mode == TransportMode::Interreflected ? (", " + std::to_string(st.bouncesUsed) + " bounces").c_str() : "");
  status(cl, line);
  if (cpca) status(cl, cpcaLine(c));
  return 0;
}

int previewGlossyMesh(const CommandLine& cl, const std::string& input, const std::string& output) {
  const std::string envPath = cl.get("env");
  if (envPath.empty()) throw UsageError("preview", "mesh previews need --env SH.json (radiance coefficients)");
  if (cl.has("transport")) throw UsageError("--transport", "give --transport (diffuse) or --matrices/--cpca (glossy), not both");
  if (cl.has("matrices") && cl.has("cpca")) throw UsageError("--cpca", "give --matrices M.npy or --cpca C.npz, not both");
  GlossyPreviewOptions go;
  MeshPreviewOptions& o = go.view;
  meshViewFromCli(cl, o);  // size, view and light rotation as the diffuse preview reads them
  go.normalised = !cl.has("unnormalised");
  ToneMap tm;
  tm.exposureStops = cl.getDouble("exposure", 0.0, -40.0, 40.0);
  const std::string lobeText = cl.get("lobe", "phong:16");
  const Mesh mesh = loadMesh(input, MeshAlbedo::Textures);  // shaded with its albedo
  GlossyMatrices g;
  CpcaResult c;
  const bool cpca = cl.has("cpca");
  if (cpca) {
    c = readCpcaNpz(cl.get("cpca"), &g.orderOut, &g.orderIn, &g.channels);
    g.vertexCount = c.vertexCount;
  } else {
    g = readGlossyNpy(cl.get("matrices"), mesh.vertexCount());
  }
  const GlossyLobe lobe = parseGlossyLobe(lobeText, g.orderOut);
  const ShCoeffs radiance = readShJson(envPath);
  if (radiance.quantity != ShQuantity::Radiance)
    throw InputError(envPath, "the mesh preview needs radiance coefficients (this file holds " +
                                  std::string(toString(radiance.quantity)) + ")");
  EnvMap background;
  if (cl.has("background")) {
    EnvLoadOptions lo;
    lo.layout = cl.getChoice("layout", "auto", {"auto", "faces", "cross", "latlong", "games202"});
    background = loadEnvironment(cl.get("background"), lo);
    o.background = &background;
  }
  Runtime& rt = jobs::processRuntime(cl.device());
  const MeshPreviewResult r = renderGlossyPreview(rt, mesh, g, cpca ? &c : nullptr, radiance, lobe, go);
  char what[512];
  std::snprintf(what, sizeof what,
                "prtbake glossy preview: L = albedo * sum_lm g_l (M l)_lm Y_lm(R)%s, lobe %s, transfer %dx%d%s; camera "
                "%s; lighting rotated by %g deg about +Y",
                go.normalised ? " / D (horizon-normalised)" : "", lobe.name.c_str(), g.orderOut * g.orderOut,
                g.orderIn * g.orderIn, cpca ? " (CPCA)" : "", r.camera.c_str(), o.lightRotationDeg);
  writePreviewPng(output, r.image, tm,
                  {{"Description", what}, {"Source", input}, {"Transfer", cl.get(cpca ? "cpca" : "matrices")},
                   {"Environment", envPath}});
  char timing[160];
  std::snprintf(timing, sizeof timing, " (%zu triangles, BVH %.3f s, kernel %.3f s)", r.triangles, r.bvhSeconds,
                r.kernelSeconds);
  status(cl, "wrote " + output + timing);
  return 0;
}

namespace {

int runCpca(const CommandLine& cl) {
  const std::string input = cl.positional.at(0), out = cl.get("output");
  if (out.empty()) throw UsageError("cpca", "missing -o OUT.npz");
  const std::string sidecar = sidecarPath(out), inputSide = sidecarPath(input);
  if (jobs::sameFile(out, sidecar)) throw UsageError(out, "is both the npz and the json output");
  jobs::checkOutputsSpareInputs({input}, {out, sidecar});
  struct stat st {};
  if (::stat(inputSide.c_str(), &st) == 0 && jobs::sameFile(sidecar, inputSide))
    throw UsageError(out, "its sidecar would replace " + inputSide + ", the sidecar of the input (name it otherwise, such as " +
                              stem(input) + ".cpca.npz)");
  CpcaOptions co;
  if (cl.has("clusters") != cl.has("vectors")) throw UsageError("cpca", "give both --clusters K and --vectors P");
  if (cl.has("clusters") && cl.has("target-error"))
    throw UsageError("--target-error", "give --clusters/--vectors or --target-error, not both");
  if (cl.has("clusters")) {
    co.clusters = int(cl.getInt("clusters", 16, 1, 65536));
    co.vectors = int(cl.getInt("vectors", 8, 0, kMaxCpcaVectors));
  } else {
    co.targetError = cl.getDouble("target-error", 0.02, 1e-6, 0.999);
  }
  co.iterations = int(cl.getInt("iterations", 10, 1, 1000));
  co.weightBits = cpcaWeightBits(cl, "weights");
  co.threads = int(cl.getInt("threads", 0, 0, 1024));
  // float32 bakes are mapped in place (no copy); float16 ones are read and widened.
  std::unique_ptr<GlossyNpyMap> map;
  GlossyMatrices g;
  const float* values = nullptr;
  try {
    map = std::make_unique<GlossyNpyMap>(input);
    g = map->info();
    values = map->data();
  } catch (const InputError&) {
    g = readGlossyNpy(input);  // a float16 file, or the reader's own error
    values = g.values.data();
  }
  const size_t dim = size_t(g.channels) * g.orderOut * g.orderOut * g.orderIn * g.orderIn;
  status(cl, "cpca: " + input + ": " + std::to_string(g.vertexCount) + " matrices of " + std::to_string(dim) + " values");
  const CpcaResult c = cpcaCompress(values, g.vertexCount, dim, co);
  nlohmann::json side = {{"tool", {{"name", "prtbake"}, {"version", version()}}},
                         {"product", "glossy_transfer_cpca"},
                         {"input", {{"path", input}}},
                         {"order_out", g.orderOut},
                         {"order_in", g.orderIn},
                         {"channels", g.channels},
                         {"cpca", nlohmann::json::parse(cpcaSidecarJson(c, out))}};
  AtomicFile npz(out), json(sidecar);
  npz.write(cpcaNpzBytes(c, g.orderOut, g.orderIn, g.channels));
  json.write(side.dump(2) + "\n");
  npz.commit();
  json.commit();
  status(cl, cpcaLine(c));
  return 0;
}

PRTBAKE_COMMAND(Command{
    "cpca", "compress glossy transfer matrices with clustered PCA",
    "prtbake cpca MATRICES.npy -o OUT.npz (--clusters K --vectors P | --target-error E) [--iterations N]\n"
    "       [--weights float32|int8] [--threads N]\n"
    "Clusters the vertices' matrices (Sloan et al. 2003): K clusters of P PCA vectors each; per vertex a\n"
    "cluster id and P weights. --target-error E picks the (K, P) of a fixed ladder with the fewest bytes\n"
    "whose total relative RMS error is at most E. Writes OUT.npz (means, basis, clusters, weights, error,\n"
    "orders; weight_scales with int8 weights) and OUT.json (K, P, errors, compression). See docs/glossy.md.",
    {{"output", true, "the .npz output (-o); the JSON sidecar goes beside it"},
     {"clusters", true, "K clusters"},
     {"vectors", true, "P PCA vectors per cluster"},
     {"target-error", true, "the largest total relative RMS error (default 0.02)"},
     {"iterations", true, "the most clustering iterations (default 10)"},
     {"weights", true, "float32 (default) | int8: one byte per weight, a float32 scale per cluster and vector"},
     {"threads", true, "host threads (default: all cores)"}},
    1, 1, runCpca});

}  // namespace
}  // namespace prtbake::cli
