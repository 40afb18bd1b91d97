// prtbake lightmap: per-texel lighting data on a mesh's lightmap UVs (see prtbake/lightmap.h,
// docs/lightmap.md).
#include <cstdio>
#include <future>

#include "cli.h"
#include "jobs.h"
#include "prtbake/error.h"
#include "prtbake/lightmap.h"
#include "prtbake/mesh.h"

namespace prtbake::cli {
namespace {

int runLightmap(const CommandLine& cl) {
  const std::string input = cl.positional.at(0);
  const std::string dir = cl.get("output");
  if (dir.empty()) throw UsageError("lightmap", "missing -o DIR");
  const std::string format = cl.getChoice("format", "exr", {"exr", "ktx2", "both"});
  // The outputs: every product asked for as OpenEXR and/or KTX2 (the transport: OpenEXR only),
  // the AO also as PNG, and the sidecar.
  // bent also in tangent space where the mesh has tangents.
  const unsigned products = parseLightmapProducts(cl.has("products") ? cl.get("products") : "ao");
  auto device = std::async(std::launch::async, [&cl]() -> Runtime* { return &jobs::processRuntime(cl.device()); });
  Mesh mesh = loadMesh(input);
  nlohmann::json outputs = {{"json", dir + "/lightmap.json"}};
  for (const std::string name : {"ao", "bent", "bent_tangent", "irradiance", "transport", "sh"}) {
    if (!(products & parseLightmapProducts(name.substr(0, name.find('_'))))) continue;
    if (name == "bent_tangent" && mesh.tangents.empty()) continue;
    const std::string base = dir + "/" + name;
    const bool exrOnly = name == "transport";
    if (format != "ktx2" || exrOnly) outputs[name + "_exr"] = base + ".exr";
    if (format != "exr" && !exrOnly) outputs[name + "_ktx2"] = base + ".ktx2";
    if (name == "ao") outputs["ao_png"] = base + ".png";
  }
  if (cl.has("gltf")) outputs["gltf"] = cl.get("gltf");
  const nlohmann::json p = productParams(cl, "lightmap", outputs);
  const LightmapOptions o = jobs::lightmapOptionsFrom(p);
  if (meshAlbedo(o) == MeshAlbedo::Textures) mesh = loadMesh(input, MeshAlbedo::Textures);  // for the bounces

  const ShCoeffs env = jobs::probeEnvironment(p, [&]() -> Runtime& { return *device.get(); }, nullptr);
  Runtime& rt = jobs::processRuntime(cl.device());
  const int size = lightmapSize(mesh, o);
  status(cl, "lightmap: " + input + ": " + std::to_string(mesh.triangleCount()) + " triangles, " + std::to_string(size) +
                 "x" + std::to_string(size) + " texels, " + lightmapProductsName(o.products) + ", " +
                 std::to_string(o.samples) + " rays per texel");
  const LightmapResult lm = computeLightmap(rt, mesh, env, o);

  // Every output's bytes first; then the directory and the writes, committed together.
  std::map<std::string, std::string> paths;
  for (const auto& [kind, path] : outputs.items()) paths[kind] = path.get<std::string>();
  const auto files = jobs::lightmapOutputBytes(paths, input, mesh, p, o, lm);
  writeOutputsTogether(dir, files);
  char line[256];
  std::snprintf(line, sizeof line, "lightmap: %.3f s (bake %.3f s), %.3g rays; %zu texels baked, %zu moved, %zu buried, %zu dilated",
                lm.totalSeconds, lm.bakeSeconds, double(lm.rays), lm.baked, lm.moved, lm.buried, lm.dilated);
  status(cl, line);
  return 0;
}

PRTBAKE_COMMAND(Command{
    "lightmap", "per-texel AO, bent normals, irradiance, directional (SH) irradiance or transport on a mesh's lightmap UVs",
    "prtbake lightmap MESH -o DIR [--uv N] [--size N | --texels-per-unit D] [--products LIST]\n"
    "       [--samples N | --tolerance E] [--env SH.json|ENVMAP] [--order N] [--sh-order 2|3]\n"
    "       [--max-distance D] [--bounces B] [--format exr|ktx2|both] [--gltf OUT.glb|OUT.gltf]\n"
    "Writes DIR/<product>.exr (or .ktx2, RGBA16F, sh an array of a layer per coefficient; transport:\n"
    "OpenEXR only) for each product asked for (default ao; alpha: the texel's validity; bent also as\n"
    "bent_tangent, in tangent space, where the mesh has tangents), DIR/ao.png (linear, 8 or 16 bits)\n"
    "with ao, and\n"
    "DIR/lightmap.json (counts, samples, timings); --gltf also a copy of the glTF whose materials use the\n"
    "AO as occlusionTexture on the lightmap's UV set.",
    productOptions("lightmap", {{"output", true, "the output directory (-o)"},
                                {"format", true, "exr (default) | ktx2 | both: the products' image format"},
                                {"gltf", true, "also a copy of the glTF input with the AO as its occlusionTexture (.glb or .gltf)"}}),
    1, 1, runLightmap});

}  // namespace
}  // namespace prtbake::cli
