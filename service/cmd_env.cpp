// prtbake env: environment map → SH coefficients (JSON, GAMES202 light.txt).
#include <algorithm>
#include <chrono>
#include <nlohmann/json.hpp>

#include "cli.h"
#include "jobs.h"
#include "prtbake/env.h"
#include "prtbake/error.h"
#include "prtbake/hash.h"
#include "prtbake/runtime.h"
#include "prtbake/sh.h"

namespace prtbake::cli {
namespace {

double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

int runEnv(const CommandLine& cl) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::string input = cl.positional.at(0);
  const std::string output = cl.get("output");
  if (output.empty()) throw UsageError("env", "missing -o OUT.json");
  EnvProjectOptions po;
  // --order auto: project once at kAutoReferenceOrder, keep the smallest order
  // up to kAutoMaxOrder whose truncation error (relative L2 over the sphere, in
  // the requested quantity, against that reference) is within --tolerance.
  constexpr int kAutoReferenceOrder = 24, kAutoMaxOrder = 20;
  const bool autoOrder = cl.get("order") == "auto";
  const double tolerance = cl.getDouble("tolerance", 0.01, 1e-9, 1.0);
  if (cl.has("tolerance") && !autoOrder) throw UsageError("--tolerance", "only meaningful with --order auto");
  po.order = autoOrder ? kAutoReferenceOrder : int(cl.getInt("order", 3, 1, kMaxShOrder));
  po.quantity = parseQuantity(cl.get("quantity", "radiance"));
  po.window = parseWindow(cl.get("window", "none"));
  EnvLoadOptions lo;
  lo.layout = cl.getChoice("layout", "auto", {"auto", "faces", "cross", "latlong", "games202"});
  lo.clampInvalid = cl.has("clamp-invalid");
  lo.compact = true;
  const double yaw = cl.getDouble("yaw", 0.0, -36000.0, 36000.0);

  nlohmann::json autoCurve;
  bool autoMet = true;
  auto runtime = [&]() -> Runtime& { return jobs::processRuntime(cl.device()); };
  const auto t1 = std::chrono::steady_clock::now();
  // A lat-long OpenEXR file is decoded and projected in bands: "load" is then the host's
  // share of the two (decoding, checks, sums), the rest being the device's.
  EnvMap env;
  EnvProjectResult r = projectEnvironmentFile(runtime, input, lo, yaw, po, &env);
  Runtime& rt = runtime();
  const double loadSeconds = std::max(0.0, secondsSince(t1) - r.kernelSeconds - r.uploadSeconds - rt.buildSeconds());
  double autoError = 0;
  if (autoOrder) {
    const ShCoeffs high = r.radiance;
    int chosen = chooseShOrder(high, po.quantity, tolerance, &autoError);
    if (chosen > kAutoMaxOrder) {
      chosen = kAutoMaxOrder;
      autoError = truncationError(high, po.quantity, chosen);
    }
    po.order = chosen;
    r.radiance = truncateSh(high, chosen);
    if (po.window == ShWindow::Auto)
      r.windowWeights = deringingWindow(r.radiance, &r.autoWindowLambda, &r.minIrradianceBefore, &r.minIrradianceAfter);
    else
      r.windowWeights = windowWeights(po.window, chosen);
    r.coeffs = applyWindowAndQuantity(r.radiance, r.windowWeights, po.quantity);
    nlohmann::json curve = nlohmann::json::array();
    for (int n = 1; n <= kAutoMaxOrder; ++n) curve.push_back(truncationError(high, po.quantity, n));
    autoMet = autoError <= tolerance;
    status(cl, "order auto: chose order " + std::to_string(chosen) + " (relative L2 " + toString(po.quantity) +
                   " error " + std::to_string(autoError) + (autoMet ? " <= " : " > ") + std::to_string(tolerance) +
                   (autoMet ? ")" : ": the tolerance is not reachable below order " + std::to_string(kAutoMaxOrder + 1) + ")"));
    autoCurve = curve;
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
  if (autoOrder)
    meta["order_selection"] = {
        {"method", "smallest order whose truncation error is within the tolerance"},
        {"error_definition", "relative L2 error over the sphere of the " + std::string(toString(po.quantity)) +
                                 ", against the order-24 projection (Parseval), all channels"},
        {"tolerance", tolerance},
        {"tolerance_met", autoMet},
        {"chosen_order", po.order},
        {"achieved_error", autoError},
        {"error_by_order_1_to_20", autoCurve}};
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
    {{"output", true, "output JSON (also -o)"},
     {"order", true, "SH order n: bands 0..n-1, n² coefficients (1..32, default 3), or auto"},
     {"tolerance", true, "with --order auto: largest relative L2 error of the quantity (default 0.01)"},
     {"layout", true, "auto|faces|cross|latlong|games202 (default auto)"},
     {"quantity", true, "radiance|irradiance|irradiance_over_pi (default radiance)"},
     {"window", true, "none|hann|lanczos|auto (auto: weakest deringing window keeping irradiance >= 0)"},
     {"yaw", true, "rotate the environment about +Y by DEG degrees before projecting"},
     {"games202", true, "also write GAMES202 light.txt (radiance coefficients) to this path"},
     {"clamp-invalid", false, "replace NaN/Inf/negative texels by 0 (counted in the JSON) instead of failing"}},
    1, 1, runEnv});

}  // namespace
}  // namespace prtbake::cli
