// prtbake transport: per-vertex PRT transport of a mesh (see prtbake/transport.h).
#include <cstdio>
#include <future>
#include <memory>
#include <string>
#include <utility>
#include <vector>

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

std::string sidecarPath(const std::string& npy) {
  const size_t slash = npy.find_last_of('/');
  const size_t dot = npy.find_last_of('.');
  if (dot != std::string::npos && (slash == std::string::npos || dot > slash)) return npy.substr(0, dot) + ".json";
  return npy + ".json";
}

int runTransport(const CommandLine& cl) {
  const std::string input = cl.positional.at(0);
  const std::string out = cl.get("output");
  if (out.empty()) throw UsageError("transport", "missing -o OUT.npy");
  if (cl.getChoice("transfer", "vector", {"vector", "matrix"}) == "matrix") return runGlossyTransport(cl);
  for (const char* name : {"order-out", "order-in", "dtype", "brdf", "cpca", "cpca-error", "cpca-weights"})
    if (cl.has(name)) throw UsageError(std::string("--") + name, "only applies to --transfer matrix");
  TransportOptions o;
  o.mode = parseTransportMode(cl.get("mode", "shadowed"));
  o.order = int(cl.getInt("order", 3, 1, kMaxTransportOrder));
  o.samples = int(cl.getInt("samples", 1024, 1, 1 << 24));
  if (cl.has("samples") && cl.has("tolerance"))
    throw UsageError("--tolerance", "cannot be combined with --samples (give one or the other)");
  if (cl.has("max-samples") && !cl.has("tolerance"))
    throw UsageError("--max-samples", "only applies with --tolerance");
  if (cl.has("tolerance")) o.tolerance = cl.getDouble("tolerance", 0, 1e-9, 1.0);
  o.toleranceMaxSamples = int(cl.getInt("max-samples", 65536, 2 * kTolerancePilotStart, 1 << 24));
  if (cl.has("sampler")) o.sampler = parseTransportSampler(cl.get("sampler"));
  o.seed = uint64_t(cl.getInt("seed", 0, 0, (1L << 62)));
  o.bounces = int(cl.getInt("bounces", 3, 1, 64));
  o.bounceTolerance = cl.getDouble("bounce-tolerance", 1e-4, 0, 1e30);
  if (cl.has("albedo")) {
    const double a = cl.getDouble("albedo", 1, 0, 1);
    o.albedoOverride = std::array<float, 3>{float(a), float(a), float(a)};
  }
  if (cl.has("bounces") && o.mode != TransportMode::Interreflected)
    throw UsageError("--bounces", "only applies to --mode interreflected");
  if (cl.has("gltf") && !(input.size() > 5 && (input.substr(input.size() - 5) == ".gltf" ||
                                                input.substr(input.size() - 4) == ".glb")))
    throw UsageError("--gltf", "a glTF copy needs a glTF input (" + input + " is not .gltf/.glb)");

  // The OpenCL device starts while the mesh loads.
  auto device = std::async(std::launch::async, [&cl]() -> Runtime* { return &jobs::processRuntime(cl.device()); });
  Mesh mesh = loadMesh(input);
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
    {{"output", true, "the .npy output (-o); the JSON sidecar goes beside it"},
     {"mode", true, "unshadowed | shadowed | interreflected (default shadowed)"},
     {"bounces", true, "interreflection bounces, 1..64 (default 3)"},
     {"bounce-tolerance", true, "stop when a bounce adds less than this (default 1e-4; 0: never)"},
     {"order", true, "SH order 1..8 (default 3)"},
     {"samples", true, "directions per vertex (default 1024)"},
     {"tolerance", true, "the samples per vertex that bring 95 % of the vertices within E, predicted from a pilot "
                       "(docs/accuracy.md)"},
     {"max-samples", true, "with --tolerance: the most samples per vertex (default 65536)"},
     {"sampler", true, "hammersley (default) | stratified | random"},
     {"seed", true, "sample set seed (default 0)"},
     {"albedo", true, "grey albedo for every vertex, overriding the file's"},
     {"gltf", true, "write a copy of the glTF input with _PRT_T* vertex attributes"},
     {"games202", true, "write a GAMES202 transport.txt"},
     {"transfer", true, "vector (diffuse transport, default) | matrix (glossy transfer matrices)"},
     {"order-out", true, "matrix: SH order of the transferred radiance, 2..6 (default --order)"},
     {"order-in", true, "matrix: SH order of the environment, 2..6 (default --order)"},
     {"dtype", true, "matrix: float32 (default) | float16"},
     {"brdf", true, "matrix: write exit-radiance matrices for ggx:R[:F0] or lambertian[:A]"},
     {"cpca", true, "matrix: also compress with K,P (clusters, PCA vectors) into OUT.cpca.npz"},
     {"cpca-error", true, "matrix: also compress, choosing K and P for this relative RMS error"},
     {"cpca-weights", true, "matrix: CPCA weights float32 (default) | int8 (with a scale per cluster and vector)"}},
    1, 1, runTransport});

}  // namespace
}  // namespace prtbake::cli
