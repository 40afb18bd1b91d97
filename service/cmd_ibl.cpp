// prtbake ibl: environment → one directory with each engine's lighting in its own conventions.
#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "cli.h"
#include "jobs.h"
#include "prtbake/clock.h"
#include "prtbake/error.h"
#include "prtbake/ibl.h"
#include "prtbake/runtime.h"

namespace prtbake::cli {
namespace {

int runIbl(const CommandLine& cl) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::string input = cl.positional.at(0), output = cl.get("output");
  if (output.empty()) throw UsageError("ibl", "missing -o DIR");
  const nlohmann::json p = productParams(cl, "ibl", {{"dir", output}});
  const IblPackageOptions o = jobs::iblOptionsFrom(p);
  const EnvLoadOptions lo = jobs::envLoadOptionsFrom(p, false);
  const double yaw = p["yaw"].get<double>();
  EnvMap env = loadEnvironment(input, lo);
  env.yawDegrees = yaw;
  Runtime& rt = jobs::processRuntime(cl.device());
  std::string targets;
  for (EngineTarget t : o.targets) targets += std::string(targets.empty() ? "" : ",") + toString(t);
  nlohmann::json meta;
  meta["parameters"] = {{"input", input},       {"targets", targets},       {"size", o.size},
                        {"skybox_size", o.skyboxSize}, {"lut_size", o.lutSize}, {"tolerance", o.tolerance},
                        {"yaw_degrees", yaw},   {"clamp_invalid", lo.clampInvalid}};
  const IblPackageResult r = writeIblPackage(rt, env, output, o, meta.dump());
  size_t bytes = 0;
  for (const auto& f : r.files) bytes += f.bytes;
  char line[256];
  std::snprintf(line, sizeof line, "ibl %s: %zu files, %.1f MB; %.2f s -> %s", targets.c_str(), r.files.size(),
                double(bytes) / 1e6, secondsSince(t0),
                output.c_str());
  status(cl, line);
  return 0;
}

}  // namespace

PRTBAKE_COMMAND(Command{
    "ibl", "engine lighting packages: three.js, Filament, Babylon.js and glTF/Khronos files in each engine's conventions",
    "prtbake ibl INPUT -o DIR [--target threejs|filament|babylon|gltf|all|LIST] [--size N] [--skybox-size N]\n"
    "       [--lut-size N] [--tolerance E] [--layout L] [--yaw DEG] [--clamp-invalid]\n"
    "Bakes into DIR, per target, the SH, prefiltered cubes and tables that engine loads, in its conventions,\n"
    "with a README.txt saying how to load them, and DIR/ibl.json (every parameter, convention, file and\n"
    "timing). DIR appears whole or not at all; an existing DIR is replaced only if it holds a package.\n"
    "  threejs   threejs/light_probe.json (ObjectLoader JSON of a LightProbe)\n"
    "  filament  filament/ibl.ktx, skybox.ktx (KTX1, R11F_G11F_B10F), sh.txt\n"
    "  babylon   babylon/environment.env, environment.glb (EXT_lights_image_based)\n"
    "  gltf      gltf/lambertian/diffuse.ktx2, ggx/specular.ktx2, charlie/sheen.ktx2, lut_ggx.png, lut_charlie.png\n"
    "INPUT: anything prtbake env reads. See docs/engines.md.",
    productOptions("ibl", {{"output", true, "package directory (also -o)"}}),
    1, 1, runIbl});

}  // namespace prtbake::cli
