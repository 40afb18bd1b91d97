// prtbake transport: per-vertex PRT transport of a mesh (see prtbake/transport.h).
#include <cstdio>
#include <future>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "cli.h"
#include "glossy_cli.h"
#include "jobs.h"
#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/mesh.h"
#include "prtbake/runtime.h"
#include "prtbake/sh.h"
#include "prtbake/transport.h"

namespace prtbake::cli {
namespace {

int runTransport(const CommandLine& cl) {
  const std::string input = cl.positional.at(0);
  const std::string out = cl.get("output");
  if (out.empty()) throw UsageError("transport", "missing -o OUT.npy");
  if (cl.getChoice("transfer", "vector", {"vector", "matrix"}) == "matrix") return runGlossyTransport(cl);
  for (const std::string& name : optionsOnlyOf("glossy", "transport"))
    if (cl.has(name)) throw UsageError("--" + name, "only applies to --transfer matrix");
  if (cl.has("gltf") && !(input.size() > 5 && (input.substr(input.size() - 5) == ".gltf" ||
                                                input.substr(input.size() - 4) == ".glb")))
    throw UsageError("--gltf", "a glTF copy needs a glTF input (" + input + " is not .gltf/.glb)");
  nlohmann::json kinds = {{"npy", out}, {"json", sidecarPath(out)}};
  for (const char* kind : {"gltf", "games202"})
    if (cl.has(kind)) kinds[kind] = cl.get(kind);
  const TransportOptions o = jobs::transportOptionsFrom(productParams(cl, "transport", kinds));

  // The OpenCL device starts while the mesh loads.
  auto device = std::async(std::launch::async, [&cl]() -> Runtime* { return &jobs::processRuntime(cl.device()); });
  Mesh mesh = loadMesh(input, meshAlbedo(o));
  status(cl, "transport: " + input + ": " + std::to_string(mesh.vertexCount()) + " vertices, " +
                 std::to_string(mesh.triangleCount()) + " triangles, " + transportModeName(o.mode) + ", order " +
                 std::to_string(o.order) + ", " +
                 (o.tolerance > 0 ? "tolerance " + cl.get("tolerance") : std::to_string(o.samples) + " samples"));
  Runtime* const rt = device.get();
  const TransportResult r = computeTransport(*rt, mesh, o);
  // Every output is produced, then written to its temp file, before any is renamed
  // into place: a failure (coloured transport for GAMES202, a full disk) leaves none.
  std::vector<std::pair<std::string, std::string>> outputs;
  if (cl.has("games202")) outputs.emplace_back(cl.get("games202"), games202TransportBytes(mesh, r));
  if (cl.has("gltf")) outputs.emplace_back(cl.get("gltf"), transportGltfBytes(cl.get("gltf"), mesh, r));
  outputs.emplace_back(out, transportNpyBytes(r));
  outputs.emplace_back(sidecarPath(out), transportSidecarBytes(input, mesh, o, r));
  std::vector<std::unique_ptr<AtomicFile>> files;
  for (const auto& [path, bytes] : outputs) {
    files.push_back(std::make_unique<AtomicFile>(path));
    files.back()->write(bytes);
  }
  for (auto& f : files) f->commit();
  char line[256];
  std::snprintf(line, sizeof line, "transport: %.3f s (BVH %.3f s), %.3g rays, std. error max %.3g mean %.3g%s",
                r.totalSeconds, r.bvhSeconds, double(r.rays), r.maxStdError, r.meanStdError,
                o.mode == TransportMode::Interreflected
                    ? (", " + std::to_string(r.bouncesUsed) + " bounces").c_str()
                    : "");
  status(cl, line);
  if (r.verticesUnoccludable > 0 || o.tolerance > 0) {
    std::snprintf(line, sizeof line, "transport: %zu unoccludable vertices; %.4g samples in all", r.verticesUnoccludable,
                  double(r.totalSamples));
    status(cl, line);
  }
  for (size_t k = 0; k < r.tolerance.size(); ++k) {
    const ToleranceReport& t = r.tolerance[k];
    std::snprintf(line, sizeof line, "transport: --tolerance, %s: %s, %d samples per vertex (predicted 95th-percentile "
                  "error %.2e of %.2e%s)", k == 0 ? "direct term" : ("bounce " + std::to_string(k)).c_str(),
                  t.strategy.c_str(), t.samples, t.predictedError, t.tolerance, t.capped ? ", capped" : "");
    status(cl, line);
  }
  return 0;
}

// The options of both transfers (transport's and glossy's keys) and the command's own.
std::vector<OptionSpec> transportOptions() {
  std::vector<OptionSpec> options = productOptions(
      "transport", {{"output", true, "the .npy output (-o); the JSON sidecar goes beside it"},
                    {"gltf", true, "write a copy of the glTF input with _PRT_T* vertex attributes"},
                    {"games202", true, "write a GAMES202 transport.txt"},
                    {"transfer", true, "vector (diffuse transport, default) | matrix (glossy transfer matrices)"},
                    {"cpca", true, "matrix: also compress with K,P (short for --cpca-clusters K --cpca-vectors P)"}});
  for (const OptionSpec& g : productOptions("glossy", {})) {
    bool known = false;
    for (const OptionSpec& t : options) known = known || t.name == g.name;
    if (!known) options.push_back({g.name, g.takesValue, "matrix: " + g.help});
  }
  return options;
}

PRTBAKE_COMMAND(Command{
    "transport", "per-vertex PRT transport in SH (unshadowed, shadowed, interreflected)",
    "prtbake transport MESH -o OUT.npy [--mode unshadowed|shadowed|interreflected] [--bounces B]\n"
    "       [--order N] [--samples N | --tolerance E [--max-samples N]] [--seed S]\n"
    "       [--sampler hammersley|stratified|random] [--gltf OUT.glb] [--games202 transport.txt]\n"
    "       [--bounce-tolerance E] [--albedo A]\n"
    "       prtbake transport MESH -o OUT.npy --transfer matrix [--mode M] [--order N | --order-out N --order-in N]\n"
    "       [--samples N] [--seed S] [--bounces B] [--dtype float32|float16] [--brdf ggx:R[:F0]|lambertian[:A]]\n"
    "       [--cpca K,P | --cpca-error E] [--cpca-weights float32|int8]\n"
    "Writes OUT.npy (float32 [V, n^2], or [V, 3, n^2] for coloured interreflection) and OUT.json.\n"
    "--transfer matrix: glossy transfer matrices [V, n_out^2, n_in^2] (docs/glossy.md), streamed to OUT.npy\n"
    "by vertex blocks; --cpca also writes OUT.cpca.npz.",
    transportOptions(), 1, 1, runTransport});

}  // namespace
}  // namespace prtbake::cli
