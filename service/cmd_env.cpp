// prtbake env: environment map → SH coefficients (JSON, GAMES202 light.txt).
#include <algorithm>
#include <map>
#include <chrono>
#include <nlohmann/json.hpp>

#include "cli.h"
#include "jobs.h"
#include "prtbake/clock.h"
#include "prtbake/env.h"
#include "prtbake/error.h"
#include "prtbake/hash.h"
#include "prtbake/runtime.h"
#include "prtbake/sh.h"

namespace prtbake::cli {
namespace {

int runEnv(const CommandLine& cl) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::string input = cl.positional.at(0);
  const std::string output = cl.get("output");
  if (output.empty()) throw UsageError("env", "missing -o OUT.json");
  nlohmann::json outputs = {{"json", output}};
  if (cl.has("games202")) outputs["games202"] = cl.get("games202");
  const nlohmann::json p = productParams(cl, "env", outputs);
  EnvProjectOptions po = jobs::envProjectOptionsFrom(p);
  const EnvLoadOptions lo = jobs::envLoadOptionsFrom(p, true);
  const double yaw = p["yaw"].get<double>();
  const bool autoOrder = p["order"] == "auto";
  auto runtime = [&]() -> Runtime& { return jobs::processRuntime(cl.device()); };
  const auto t1 = std::chrono::steady_clock::now();
  // A lat-long OpenEXR file is decoded and projected in bands: "load" is then the host's
  // share of the two (decoding, checks, sums), the rest being the device's.
  EnvMap env;
  EnvProjectResult r = projectEnvironmentFile(runtime, input, lo, yaw, po, &env);
  Runtime& rt = runtime();
  const double loadSeconds = std::max(0.0, secondsSince(t1) - r.kernelSeconds - r.uploadSeconds - rt.buildSeconds());
  nlohmann::json orderSelection;
  if (autoOrder) {
    orderSelection = jobs::selectEnvOrder(r, po, p["tolerance"]);
    const bool met = orderSelection["tolerance_met"].get<bool>();
    status(cl, "order auto: chose order " + std::to_string(po.order) + " (relative L2 " + toString(po.quantity) +
                   " error " + std::to_string(orderSelection["achieved_error"].get<double>()) + (met ? " <= " : " > ") +
                   std::to_string(orderSelection["tolerance"].get<double>()) +
                   (met ? ")" : ": the tolerance is not reachable below order " +
                                    std::to_string(jobs::kAutoMaxOrder + 1) + ")"));
  }
  const double projectSeconds = secondsSince(t1);

  nlohmann::json meta;
  meta["product"] = "environment_sh";
  meta["parameters"] = {{"input", input},
                        {"order", po.order},
                        {"layout", env.layoutName},
                        {"quantity", toString(po.quantity)},
                        {"window", toString(po.window)},
                        {"yaw_degrees", yaw},
                        {"clamp_invalid", lo.clampInvalid}};
  if (autoOrder) meta["order_selection"] = orderSelection;
  nlohmann::json hashes = nlohmann::json::object();
  for (const auto& f : env.inputFiles) hashes[f] = sha256File(f);
  meta["inputs"] = hashes;
  meta["environment"] = {{"layout", env.layout == EnvLayout::Cube ? "cube" : "latlong"},
                         {"width", env.width},
                         {"height", env.height},
                         {"texels", r.texels},
                         {"clamped_texels", env.clampedTexels}};
  meta["window"] = {{"weights_per_band", r.windowWeights}};
  if (po.window == ShWindow::Auto)
    meta["window"].update({{"laplacian_lambda", r.autoWindowLambda},
                           {"min_irradiance_before", r.minIrradianceBefore},
                           {"min_irradiance_after", r.minIrradianceAfter}});
  meta["device"] = rt.deviceLabel();
  meta["timings_seconds"] = {{"load", loadSeconds},
                             {"kernel_build", rt.buildSeconds()},
                             {"upload", r.uploadSeconds},
                             {"kernel", r.kernelSeconds},
                             {"project", projectSeconds},
                             {"total", secondsSince(t0)}};
  meta["error_estimate"] =
      "deterministic quadrature: texel-centre sampling with exact solid angles (no Monte Carlo error); "
      "float32 kernel sums are within 1e-5 of |L00| of a double reference at order 3";

  if (cl.has("games202")) {
    // GAMES202's light.txt holds radiance coefficients (its own convention), windowed as asked.
    writeGames202Light(cl.get("games202"), applyWindowAndQuantity(r.radiance, r.windowWeights, ShQuantity::Radiance));
  }
  writeShJson(output, r.coeffs, meta.dump());
  status(cl, "wrote " + output + " (order " + std::to_string(po.order) + ", " + toString(po.quantity) + ", " +
                 std::to_string(r.texels) + " texels, kernel " + std::to_string(r.kernelSeconds * 1e3) + " ms)");
  return 0;
}

PRTBAKE_COMMAND(Command{
    "env", "project an HDR environment onto SH (JSON, GAMES202 light.txt)",
    "prtbake env INPUT -o OUT.json [--order N|auto [--tolerance E]] [--layout auto|faces|cross|latlong|games202]\n"
    "       [--quantity radiance|irradiance|irradiance_over_pi] [--window none|hann|lanczos|auto]\n"
    "       [--yaw DEG] [--games202 light.txt] [--clamp-invalid]\n"
    "INPUT: an OpenEXR (cube or lat-long, envmap attribute honoured), .hdr, a cross or lat-long image,\n"
    "or a directory of six faces posx/negx/posy/negy/posz/negz (.exr .hdr .png .jpg).",
    productOptions("env", {{"output", true, "output JSON (also -o)"},
                           {"games202", true, "also write GAMES202 light.txt (radiance coefficients) to this path"}}),
    1, 1, runEnv});

}  // namespace
}  // namespace prtbake::cli
