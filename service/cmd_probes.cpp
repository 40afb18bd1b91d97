// prtbake probes: a light probe grid of a scene (see prtbake/probes.h, docs/probes.md).
#include <cstdio>
#include <future>

#include "cli.h"
#include "jobs.h"
#include "prtbake/error.h"
#include "prtbake/mesh.h"
#include "prtbake/probes.h"

namespace prtbake::cli {
namespace {

int runProbes(const CommandLine& cl) {
  const std::string input = cl.positional.at(0);
  const std::string dir = cl.get("output");
  if (dir.empty()) throw UsageError("probes", "missing -o DIR");
  const std::string target = cl.getChoice("target", "raw", {"raw", "threejs"});
  nlohmann::json outputs = {{"npy", dir + "/probes.npy"}, {"json", dir + "/probes.json"}};
  if (target == "threejs") outputs["ktx2"] = dir + "/probes.ktx2", outputs["js"] = dir + "/probes.mjs";
  if (cl.has("preview")) outputs["png"] = dir + "/probes.png";
  const nlohmann::json p = productParams(cl, "probes", outputs);
  const ProbeOptions o = jobs::probeOptionsFrom(p);

  auto device = std::async(std::launch::async, [&cl]() -> Runtime* { return &jobs::processRuntime(cl.device()); });
  const Mesh mesh = loadMesh(input, meshAlbedo(o));
  const ShCoeffs env = jobs::probeEnvironment(p, [&]() -> Runtime& { return *device.get(); }, nullptr);
  Runtime& rt = jobs::processRuntime(cl.device());
  const ProbeGridLayout layout = probeGridLayout(mesh, o);
  status(cl, "probes: " + input + ": " + std::to_string(mesh.triangleCount()) + " triangles, " +
                 std::to_string(layout.resolution[0]) + "x" + std::to_string(layout.resolution[1]) + "x" +
                 std::to_string(layout.resolution[2]) + " probes, order " + std::to_string(o.order) + ", " +
                 std::to_string(o.samples) + " rays per probe, " + std::to_string(o.bounces) + " bounces");
  const ProbeGridResult g = computeProbeGrid(rt, mesh, env, o);

  // Every output's bytes first; then the directory and the writes, committed together.
  std::vector<std::pair<std::string, std::string>> files;
  files.emplace_back(dir + "/probes.npy", probeGridNpyBytes(g));
  files.emplace_back(dir + "/probes.json",
                     probeGridSidecarBytes(input, o, env, p["env"].is_null() ? "" : p["env"].get<std::string>(), g));
  if (target == "threejs") {
    files.emplace_back(dir + "/probes.ktx2", probeGridThreejsKtx2Bytes(g));
    files.emplace_back(dir + "/probes.mjs", probeGridThreejsLoaderBytes(g, "probes.ktx2"));
  }
  if (cl.has("preview")) files.emplace_back(dir + "/probes.png", jobs::probeGridPreviewPngBytes(mesh, g, rt));
  writeOutputsTogether(dir, files);
  char line[256];
  std::snprintf(line, sizeof line, "probes: %.3f s (trace %.3f s, surfaces %.3f s), %.3g rays; %zu moved, %zu invalid",
                g.totalSeconds, g.traceSeconds, g.surfaceSeconds, double(g.rays), g.moved, g.invalid);
  status(cl, line);
  return 0;
}

PRTBAKE_COMMAND(Command{
    "probes", "a light probe grid: SH radiance at points in space, for moving objects",
    "prtbake probes SCENE -o DIR [--env SH.json|ENVMAP] [--resolution NX,NY,NZ | --spacing D]\n"
    "       [--bounds X0,Y0,Z0,X1,Y1,Z1] [--order 2|3] [--samples N] [--bounces B] [--target raw|threejs] [--preview]\n"
    "Writes DIR/probes.npy (float32 [NZ, NY, NX, n^2, 3]) and DIR/probes.json (layout, validity, timings);\n"
    "--target threejs also DIR/probes.ktx2 (LightProbeGridWebGL's 3D atlas, RGBA16F) and DIR/probes.mjs (its loader);\n"
    "--preview also DIR/probes.png.",
    productOptions("probes", {{"output", true, "the output directory (-o)"},
                              {"target", true, "raw (.npy and sidecar, default) | threejs (also the 3D atlas)"},
                              {"preview", false, "also DIR/probes.png: the scene lit by the grid, the probes, a slice"}}),
    1, 1, runProbes});

}  // namespace
}  // namespace prtbake::cli
