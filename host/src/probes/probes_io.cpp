// The probe grid's raw outputs: the .npy of coefficients and the sidecar JSON (see probes.h).
#include <algorithm>

#include <nlohmann/json.hpp>

#include "core/tolerance_pilot.h"
#include "io/npy.h"
#include "prtbake/probes.h"
#include "prtbake/atomic_file.h"
#include "prtbake/error.h"

namespace prtbake {

std::string probeGridNpyBytes(const ProbeGridResult& g) {
  npy::checkLittleEndian();
  const auto& r = g.layout.resolution;
  if (g.coeffs.size() != g.layout.count() * size_t(g.order) * g.order * 3)
    throw UsageError("probes", "the .npy holds a whole grid (" + std::to_string(g.layout.count()) + " probes)");
  std::string out = npy::header("<f4", {size_t(r[2]), size_t(r[1]), size_t(r[0]), size_t(g.order) * g.order, 3});
  out.append(reinterpret_cast<const char*>(g.coeffs.data()), g.coeffs.size() * sizeof(float));
  return out;
}

std::string probeRangeNpyBytes(const ProbeGridResult& g) {
  npy::checkLittleEndian();
  const size_t n = g.probeCount, nc = size_t(g.order) * g.order * 3, columns = nc + kProbeRangeExtraColumns;
  std::vector<float> rows(n * columns);
  for (size_t i = 0; i < n; ++i) {
    float* r = &rows[i * columns];
    std::copy(g.probe(i), g.probe(i) + nc, r);
    std::copy(&g.positions[3 * i], &g.positions[3 * i] + 3, r + nc);
    r[nc + 3] = float(g.state[i]);
    r[nc + 4] = g.backfaceFraction[i];
  }
  std::string out = npy::header("<f4", {n, columns});
  out.append(reinterpret_cast<const char*>(rows.data()), rows.size() * sizeof(float));
  return out;
}

void appendProbeRange(ProbeGridResult& g, const std::vector<float>& rows, size_t count) {
  const size_t nc = size_t(g.order) * g.order * 3, columns = nc + kProbeRangeExtraColumns;
  if (rows.size() != count * columns) throw UsageError("probes", "a probe range's rows do not match its order");
  for (size_t r = 0; r < count; ++r) {
    const float* row = &rows[r * columns];
    g.coeffs.insert(g.coeffs.end(), row, row + nc);
    g.positions.insert(g.positions.end(), row + nc, row + nc + 3);
    g.state.push_back(uint8_t(row[nc + 3]));
    g.backfaceFraction.push_back(row[nc + 4]);
  }
}

std::string probeGridSidecarBytes(const std::string& inputPath, const ProbeOptions& o, const ShCoeffs& env,
                                  const std::string& envPath, const ProbeGridResult& g) {
  using nlohmann::json;
  const auto& L = g.layout;
  json j;
  j["tool"] = {{"name", "prtbake"}, {"version", version()}};
  j["product"] = "probes";
  j["parameters"] = {{"order", o.order}, {"samples", o.samples}, {"seed", o.seed}, {"bounces", o.bounces},
                     {"transport_samples", o.transportSamples}, {"backface_limit", o.backfaceLimit},
                     {"relocate", o.relocateFraction}};
  if (o.albedoOverride) j["parameters"]["albedo"] = {(*o.albedoOverride)[0], (*o.albedoOverride)[1], (*o.albedoOverride)[2]};
  j["input"] = {{"path", inputPath}};
  j["environment"] = {{"path", envPath.empty() ? "constant white (L = 1)" : envPath},
                      {"order", env.order},
                      {"order_used", g.environmentOrder}};
  j["grid"] = {{"resolution", {L.resolution[0], L.resolution[1], L.resolution[2]}},
               {"bounds_min", {L.boundsMin[0], L.boundsMin[1], L.boundsMin[2]}},
               {"bounds_max", {L.boundsMax[0], L.boundsMax[1], L.boundsMax[2]}},
               {"cell", {L.cell()[0], L.cell()[1], L.cell()[2]}},
               {"probes", L.count()},
               {"placement", "probe (i, j, k) at bounds_min + (i + 1/2, j + 1/2, k + 1/2) * cell, as three.js's "
                             "LightProbeGrid places them"}};
  j["conventions"] = {
      {"basis", "real orthonormal SH with the Condon-Shortley phase"},
      {"index", "i = l(l+1)+m"},
      {"quantity", "radiance arriving at the probe, P_i = integral of L(p, w) Y_i(w) dw, linear RGB"},
      {"layout", "[NZ, NY, NX, n^2, 3] float32, x fastest"},
      {"shade", "irradiance/pi at normal n: sum_i A_l/pi P_i Y_i(n), A_l = pi, 2pi/3, pi/4"}};
  json moved = json::array(), invalid = json::array();
  for (size_t i = 0; i < g.state.size(); ++i) {
    if (g.state[i] == 0) continue;
    const int x = int(i % L.resolution[0]), y = int(i / L.resolution[0] % L.resolution[1]),
              z = int(i / (size_t(L.resolution[0]) * L.resolution[1]));
    json e = {{"index", {x, y, z}}, {"backface_fraction", g.backfaceFraction[i]}};
    if (g.state[i] == 1) {
      e["position"] = {g.positions[3 * i], g.positions[3 * i + 1], g.positions[3 * i + 2]};
      moved.push_back(e);
    } else {
      invalid.push_back(e);
    }
  }
  j["validity"] = {{"backface_limit", o.backfaceLimit},
                   {"moved", g.moved},
                   {"invalid", g.invalid},
                   {"fill_passes", g.fillPasses},
                   {"moved_probes", moved},
                   {"invalid_probes", invalid},
                   {"meaning", "moved: baked at 'position' instead of its grid point; invalid: no free point within "
                               "reach, filled with the mean of its valid face neighbours"}};
  if (o.tolerance > 0) {
    j["parameters"]["tolerance"] = o.tolerance;
    j["parameters"]["max_samples"] = o.toleranceMaxSamples;
  }
  if (!g.tolerance.empty())
    j["tolerance"] = {{"pilot", detail::toleranceJson(g.tolerance.front())},
                      {"meaning", "the rays per probe predicted to bring 95 % of the probes' coefficients within the "
                                  "tolerance times the environment's l_0 (docs/probes.md)"}};
  j["samples"] = {{"per_probe", g.samples}, {"rings", g.rings}, {"segments", g.segments}, {"rays", g.rays},
                  {"quadrature", "Gauss-Legendre in cos(theta) x uniform phi, a random rotation per probe"}};
  j["timings_seconds"] = {{"bvh", g.bvhSeconds}, {"surfaces", g.surfaceSeconds}, {"trace", g.traceSeconds},
                          {"relocation", g.relocateSeconds}, {"total", g.totalSeconds}};
  j["device"] = g.device;
  return j.dump(2) + "\n";
}

}  // namespace prtbake
