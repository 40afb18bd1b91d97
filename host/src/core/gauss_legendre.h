// Private: Gauss–Legendre rules on [0, 1] (lut_reference.cpp, transport_quadtree.cpp).
#pragma once

#include <cmath>
#include <vector>

namespace prtbake::detail {

struct GaussRule {
  std::vector<double> x, w;  // nodes and weights on [0, 1]
};

// The n-point rule (exact for polynomials of degree 2n − 1), by Newton's method on P_n.
inline GaussRule gaussLegendre(int n) {
  const double pi = 3.14159265358979323846;
  GaussRule g;
  g.x.resize(n), g.w.resize(n);
  for (int i = 0; i < n; ++i) {
    double z = std::cos(pi * (i + 0.75) / (n + 0.5)), pp = 0;
    for (int it = 0; it < 100; ++it) {
      double p1 = 1, p2 = 0;
      for (int j = 1; j <= n; ++j) {
        const double p3 = p2;
        p2 = p1;
        p1 = ((2 * j - 1) * z * p2 - (j - 1) * p3) / j;
      }
      pp = n * (z * p1 - p2) / (z * z - 1);
      const double dz = p1 / pp;
      z -= dz;
      if (std::abs(dz) < 1e-16) break;
    }
    g.x[i] = 0.5 * (1 - z);
    g.w[i] = 1.0 / ((1 - z * z) * pp * pp);  // 2/((1−z²)p'²) halved for [0, 1]
  }
  return g;
}

}  // namespace prtbake::detail
