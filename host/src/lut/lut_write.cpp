// Writing BRDF tables: OpenEXR with named channels plus a JSON sidecar.
#include <cstdio>
#include <nlohmann/json.hpp>

#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "core/tolerance_pilot.h"
#include "prtbake/exr.h"
#include "prtbake/lut.h"

namespace prtbake {
namespace {

const char* visibilityDefinition(const LutOptions& o) {
  switch (o.visibility) {
    case LutVisibility::SmithCorrelated: return "height-correlated Smith G2 = 1/(1 + Lambda(V) + Lambda(L))";
    case LutVisibility::SmithSeparable: return "separable Smith G2 = G1(V) G1(L)";
    case LutVisibility::SchlickGgx: return "Schlick-GGX G2 = G1(V) G1(L), G1(x) = x/(x(1-k)+k), k = alpha/2 (UE4)";
  }
  return "?";
}

nlohmann::json sidecar(const LutResult& lut, const std::string& exrPath, bool half, double commandSeconds) {
  const LutOptions& o = lut.options;
  nlohmann::json j;
  j["tool"] = {{"name", "prtbake"}, {"version", version()}};
  j["product"] = "brdf_lut";
  j["file"] = exrPath.substr(exrPath.find_last_of('/') + 1);
  j["parameters"] = {{"size", o.size},
                     {"samples", o.samples},
                     {"ndf", lutNdfName(o.ndf)},
                     {"visibility", lutVisibilityName(o.visibility)},
                     {"alpha", o.alphaDirect ? "alpha = axis value (--alpha-direct)" : "alpha = roughness^2"},
                     {"multiscatter", o.multiscatter},
                     {"cloth", o.cloth},
                     {"kulla_conty", o.kullaConty},
                     {"fast_math", o.fastMath},
                     {"pixel_type", half ? "half" : "float32"}};
  j["definition"] = {
      {"A", "integral of f_r (1 - Fc)/F cos(theta_l) dw_l"},
      {"B", "integral of f_r Fc/F cos(theta_l) dw_l"},
      {"brdf", "f_r = D(H) G2(V,L) F / (4 (N.V)(N.L)), Fc = (1 - V.H)^5, F = f0 (1 - Fc) + f90 Fc"},
      {"use", "specular albedo = f0 * A + f90 * B"},
      {"ndf", o.ndf == LutNdf::Ggx ? "GGX D = alpha^2 / (pi ((N.H)^2 (alpha^2 - 1) + 1)^2)"
                                   : "Beckmann D = exp(-tan^2(theta_h)/alpha^2) / (pi alpha^2 cos^4(theta_h))"},
      {"visibility", visibilityDefinition(o)}};
  j["axes"] = {{"x", "column i: mu = N.V = (i + 0.5)/size"},
               {"y", std::string("row j: roughness r = (j + 0.5)/size, ") +
                         (o.alphaDirect ? "alpha = r" : "alpha = r^2") + "; row 0 (smallest r) first"}};
  nlohmann::json ch = {{"R", "A (scale of f0)"}, {"G", "B (bias, scale of f90)"}};
  if (o.multiscatter)
    ch["B"] = "E = A + B, the single-scattering albedo (Filament DFG.y); runtime energy compensation: "
              "f_ms = f_ss * (1 + f0 * (1/E - 1))";
  if (o.cloth)
    ch["B"] = "cloth: integral of D_Charlie V_Ashikhmin cos(theta_l) dw_l, D = (2 + 1/a) sin^(1/a)(theta_h)/(2 pi), "
              "V = 1/(4 (N.L + N.V - (N.L)(N.V))), a = max(alpha, " + std::to_string(kLutClothAlphaMin) + ")";
  if (o.kullaConty) {
    ch["E"] = "Kulla-Conty E(mu, r) = A + B";
    ch["Eavg"] = "Kulla-Conty E_avg(r) = 2 * integral_0^1 E(mu, r) mu dmu (midpoint rule over the columns), "
                 "the same value along each row; f_ms = (1 - E(mu_o))(1 - E(mu_i)) / (pi (1 - E_avg))";
  }
  j["channels"] = ch;
  if (lut.reference) {
    j["method"] = "double-precision Gauss-Legendre quadrature over the half vector";
  } else {
    j["method"] = "quasi-Monte Carlo: Hammersley points, GGX visible-normal sampling (Heitz 2018); Beckmann "
                  "weighted by D_Beckmann/D_GGX; cloth by sampling D_Charlie cos(theta_h)";
  }
  j["samples"] = o.samples;
  j["error_estimate"] = {
      {"std_error_max", lut.stdErrMax},
      {"std_error_mean", lut.stdErrMean},
      {"meaning", "Monte Carlo standard error sigma/sqrt(n) per texel, max over channels; the low-discrepancy "
                  "points converge faster, so this bounds the error loosely (docs/lut.md)"}};
  if (o.tolerance > 0) {
    j["parameters"]["tolerance"] = o.tolerance;
    j["tolerance"] = detail::toleranceJson(lut.tolerance);
  }
  nlohmann::json t = {{"kernel_s", lut.kernelSeconds}, {"build_s", lut.buildSeconds}, {"compute_s", lut.totalSeconds}};
  if (commandSeconds >= 0) t["command_s"] = commandSeconds;
  j["timings"] = t;
  j["device"] = lut.device;
  return j;
}

}  // namespace

std::string lutSidecarPath(const std::string& exrPath) {
  const size_t slash = exrPath.find_last_of('/');
  const size_t dot = exrPath.find_last_of('.');
  if (dot != std::string::npos && (slash == std::string::npos || dot > slash)) return exrPath.substr(0, dot) + ".json";
  return exrPath + ".json";
}

void writeLut(const LutResult& lut, const std::string& exrPath, bool half, double commandSeconds) {
  writeLutFiles(lut, exrPath, lutSidecarPath(exrPath), half, commandSeconds);
}

void writeLutFiles(const LutResult& lut, const std::string& exrPath, const std::string& jsonPath, bool half,
                   double commandSeconds) {
  const size_t texels = size_t(lut.size) * lut.size;
  if (lut.size <= 0 || lut.a.size() != texels || lut.b.size() != texels)
    throw OutputError(exrPath, "LUT result is empty or inconsistent");
  if (jsonPath == exrPath) throw OutputError(exrPath, "the sidecar would overwrite the image");
  std::vector<float> eAvgImage;
  std::vector<ExrChannel> channels = {{"R", lut.a.data()}, {"G", lut.b.data()}};
  if (!lut.third.empty()) channels.push_back({"B", lut.third.data()});
  if (!lut.e.empty()) {
    eAvgImage.resize(texels);
    for (int j = 0; j < lut.size; ++j)
      for (int i = 0; i < lut.size; ++i) eAvgImage[size_t(j) * lut.size + i] = lut.eAvg[j];
    channels.push_back({"E", lut.e.data()});
    channels.push_back({"Eavg", eAvgImage.data()});
  }
  const std::string text = sidecar(lut, exrPath, half, commandSeconds).dump(2) + "\n";
  ExrWriteOptions wo;
  wo.half = half;
  wo.attributes = {{"prtbake:product", "brdf_lut"}, {"prtbake:version", version()}};
  if (jsonPath == lutSidecarPath(exrPath))
    wo.attributes.push_back({"prtbake:sidecar", jsonPath.substr(jsonPath.find_last_of('/') + 1)});
  if (jsonPath.empty()) {
    writeExr(exrPath, lut.size, lut.size, channels, wo);
    return;
  }
  // The sidecar goes first through its own temp file; if the image then fails,
  // the sidecar is removed again so that a failed write leaves nothing.
  writeFileAtomic(jsonPath, text);
  try {
    writeExr(exrPath, lut.size, lut.size, channels, wo);
  } catch (...) {
    std::remove(jsonPath.c_str());
    throw;
  }
}

}  // namespace prtbake
