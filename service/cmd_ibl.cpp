// prtbake ibl: environment → one directory with each engine's lighting in its own conventions.
#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "cli.h"
#include "jobs.h"
#include "prtbake/ibl.h"
#include "prtbake/error.h"
#include "prtbake/runtime.h"

namespace prtbake::cli {
namespace {

int runIbl(const CommandLine& cl) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::string input = cl.positional.at(0), output = cl.get("output");
  if (output.empty()) throw UsageError("ibl", "missing -o DIR");
  IblPackageOptions o;
  o.targets = parseEngineTargets(cl.get("target", "all"));
  o.size = int(cl.getInt("size", o.size, -(1L << 30), 1L << 30));
  o.skyboxSize = int(cl.getInt("skybox-size", 0, 1, 1L << 30));
  o.lutSize = int(cl.getInt("lut-size", o.lutSize, -(1L << 30), 1L << 30));
  o.tolerance = cl.getDouble("tolerance", o.tolerance, -1e300, 1e300);
  validateIblPackageOptions(o);
  EnvLoadOptions lo;
  lo.layout = cl.getChoice("layout", "auto", {"auto", "faces", "cross", "latlong", "games202"});
  lo.clampInvalid = cl.has("clamp-invalid");
  const double yaw = cl.getDouble("yaw", 0.0, -36000.0, 36000.0);
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
                double(bytes) / 1e6, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
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
    {{"output", true, "package directory (also -o)"},
     {"target", true, "threejs, filament, babylon, gltf, all (default) or a comma-separated list"},
     {"size", true, "base face size of the prefiltered cubes (power of two, 16..4096, default 256)"},
     {"skybox-size", true, "Filament skybox face size (default: --size)"},
     {"lut-size", true, "glTF LUT size (16..1024, default 128)"},
     {"tolerance", true, "prefilter tolerance (1e-4..0.1, default 0.01; see prtbake prefilter)"},
     {"layout", true, "environment layout, as for prtbake env (default auto)"},
     {"yaw", true, "rotate the environment about +Y by DEG degrees"},
     {"clamp-invalid", false, "replace NaN/Inf/negative texels by 0 instead of failing"}},
    1, 1, runIbl});

}  // namespace prtbake::cli
