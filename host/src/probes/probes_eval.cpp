// Evaluating a probe grid at a point and a normal: the grid's layout (cell, probe centres) and
// the irradiance over π that a renderer of the grid shows on a white diffuse surface.
//
// Interpolation. Probe (i, j, k) sits at min + ((i + ½) s_x, (j + ½) s_y, (k + ½) s_z), s the
// cell. A point x has the continuous probe index, per axis a,
//   u_a = clamp((x_a − min_a) / s_a − ½, 0, N_a − 1),
// so that outside the outermost probes' centres the grid is constant along that axis; with
// i_a = min(⌊u_a⌋, N_a − 2) (0 for N_a = 1) and f_a = u_a − i_a, the coefficients at x are the
// trilinear blend
//   P(x) = Σ_{corners c ∈ {0,1}³} Π_a (c_a ? f_a : 1 − f_a) · P(i + c),
// which is what a GPU's linear filter computes between texel centres with clamp-to-edge
// (three.js's LightProbeGrid: uvw clamped to [½/N, 1 − ½/N]).
//
// Irradiance. Funk–Hecke: the clamped cosine max(0, n·ω) scales band l by Â_l
// (clampedCosineFactor), so E(n) = Σ_i Â_l P_i(x) Y_i(n) and the diffuse exit radiance of albedo 1
// is the estimator
//   E(n)/π = Σ_{l,m} (Â_l/π) P_lm(x) Y_lm(n),
// in double, not clamped at 0 (a renderer clamps a negative ringing lobe to black).
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "core/constants.h"
#include "probes/probe_grid_check.h"
#include "prtbake/error.h"
#include "prtbake/probes.h"

namespace prtbake {

std::array<double, 3> ProbeGridLayout::cell() const {
  std::array<double, 3> s{};
  for (size_t a = 0; a < 3; ++a) s[a] = (boundsMax[a] - boundsMin[a]) / resolution[a];
  return s;
}

std::array<double, 3> ProbeGridLayout::probePosition(int i, int j, int k) const {
  const std::array<double, 3> s = cell();
  const int index[3] = {i, j, k};
  std::array<double, 3> p{};
  for (size_t a = 0; a < 3; ++a) p[a] = boundsMin[a] + (index[a] + 0.5) * s[a];
  return p;
}

void checkProbeGridShape(const ProbeGridResult& grid) {
  const ProbeGridLayout& layout = grid.layout;
  const int order = grid.order;
  if (order < 1 || order > kMaxShOrder)
    throw UsageError("probe grid", "order " + std::to_string(order) + " is not 1.." + std::to_string(kMaxShOrder));
  for (size_t a = 0; a < 3; ++a) {
    if (layout.resolution[a] < 1 || layout.resolution[a] > kMaxProbesPerAxis)
      throw UsageError("probe grid", "a resolution of " + std::to_string(layout.resolution[a]) + " probes");
    if (!(layout.boundsMax[a] > layout.boundsMin[a]) || !std::isfinite(layout.boundsMax[a] - layout.boundsMin[a]))
      throw UsageError("probe grid", "empty or inverted bounds");
  }
  const size_t perProbe = size_t(shCount(order)) * 3;
  if (grid.coeffs.size() != layout.count() * perProbe)
    throw UsageError("probe grid", std::to_string(grid.coeffs.size()) + " coefficients where " +
                                       std::to_string(layout.count()) + " probes of order " + std::to_string(order) +
                                       " need " + std::to_string(layout.count() * perProbe));
}

std::array<double, 3> probeGridIrradianceOverPi(const ProbeGridResult& grid, const std::array<double, 3>& x,
                                                const std::array<double, 3>& n) {
  checkProbeGridShape(grid);
  const ProbeGridLayout& layout = grid.layout;
  const int order = grid.order;
  const size_t perProbe = size_t(shCount(order)) * 3;
  const double length = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  if (!(length > 0) || !std::isfinite(length)) throw UsageError("normal", "not a direction (zero or non-finite length)");

  // The lower corner and the weights along each axis.
  const std::array<double, 3> s = layout.cell();
  int lower[3];
  double frac[3];
  for (size_t a = 0; a < 3; ++a) {
    const int count = layout.resolution[a];
    const double u = std::clamp((x[a] - layout.boundsMin[a]) / s[a] - 0.5, 0.0, double(count - 1));
    lower[a] = count == 1 ? 0 : std::min(int(std::floor(u)), count - 2);
    frac[a] = count == 1 ? 0.0 : u - lower[a];
  }
  std::vector<double> blended(perProbe, 0.0);
  for (int corner = 0; corner < 8; ++corner) {
    double w = 1;
    size_t index[3];
    for (size_t a = 0; a < 3; ++a) {
      const int up = (corner >> a) & 1;
      w *= up ? frac[a] : 1 - frac[a];
      index[a] = size_t(lower[a] + (layout.resolution[a] == 1 ? 0 : up));
    }
    if (w == 0) continue;
    const size_t probe = (index[2] * size_t(layout.resolution[1]) + index[1]) * size_t(layout.resolution[0]) + index[0];
    const float* c = grid.probe(probe);
    for (size_t i = 0; i < perProbe; ++i) blended[i] += w * c[i];
  }

  std::vector<double> y(size_t(shCount(order)));
  shEval(order, n[0] / length, n[1] / length, n[2] / length, y.data());
  std::array<double, 3> e{};
  for (int l = 0; l < order; ++l) {
    const double scale = clampedCosineFactor(l) / kPi;
    for (int m = -l; m <= l; ++m) {
      const size_t i = size_t(shIndex(l, m));
      for (size_t c = 0; c < 3; ++c) e[c] += scale * blended[3 * i + c] * y[i];
    }
  }
  return e;
}

}  // namespace prtbake
