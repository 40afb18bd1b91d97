// Shared by the environment tests: synthetic environments from a function of
// direction, a known band-limited coefficient set, and coefficient comparison.
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>

#include "prtbake/env.h"
#include "prtbake/envmap.h"

namespace prtbake::test {

using DirFn = std::function<Rgb(const double*)>;

// Every texel holds f(its texel-centre direction).
inline EnvMap makeEnv(EnvLayout layout, int width, int height, const DirFn& f) {
  EnvMap e;
  e.layout = layout;
  e.width = width;
  e.height = height;
  e.rgb.resize(e.texelCount() * 3);
  for (size_t t = 0; t < e.texelCount(); ++t) {
    double d[3];
    texelDirection(e, t, d, nullptr);
    const Rgb v = f(d);
    for (size_t c = 0; c < 3; ++c) e.rgb[3 * t + c] = float(v[c]);
  }
  return e;
}
inline EnvMap makeCube(int n, const DirFn& f) { return makeEnv(EnvLayout::Cube, n, n, f); }
inline EnvMap makeLatLong(int h, const DirFn& f) { return makeEnv(EnvLayout::LatLong, 2 * h, h, f); }

// Known band-limited radiance (bands 0–2), positive everywhere: the constant term
// dominates the sum of |other| × max|Y|.
inline ShCoeffs knownCoeffs() {
  ShCoeffs c;
  c.order = 3;
  c.rgb = {{3.0, 2.5, 2.0},   {0.3, -0.2, 0.1},  {0.5, 0.4, -0.3}, {-0.4, 0.2, 0.25}, {0.2, 0.1, -0.1},
           {-0.15, 0.3, 0.2}, {0.25, -0.1, 0.3}, {0.1, 0.2, -0.2}, {-0.3, 0.15, 0.1}};
  return c;
}

inline double maxAbsDiff(const ShCoeffs& a, const ShCoeffs& b) {
  double worst = 0;
  for (size_t k = 0; k < a.rgb.size(); ++k)
    for (size_t c = 0; c < 3; ++c) worst = std::max(worst, std::abs(a.rgb[k][c] - b.rgb[k][c]));
  return worst;
}

}  // namespace prtbake::test
