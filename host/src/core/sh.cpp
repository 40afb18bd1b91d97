// Real SH basis in double precision: the reference the kernels are held against.
#include "prtbake/sh.h"

#include <cmath>
#include <string>

#include "prtbake/error.h"

namespace prtbake {

void shEvalHardcoded(int order, double x, double y, double z, double* out) {
  PRTBAKE_CHECK(order >= 1 && order <= kHardcodedShOrder, "hard-coded SH has orders 1..4");
  out[0] = 0.28209479177387814;  // 1/(2√π)
  if (order < 2) return;
  const double c1 = 0.48860251190291992;  // √(3/(4π))
  out[1] = -c1 * y;
  out[2] = c1 * z;
  out[3] = -c1 * x;
  if (order < 3) return;
  const double c2a = 1.0925484305920792;   // √(15/(4π))
  const double c2b = 0.31539156525252005;  // √(5/(16π))
  const double c2c = 0.54627421529603959;  // √(15/(16π))
  out[4] = c2a * x * y;
  out[5] = -c2a * y * z;
  out[6] = c2b * (3 * z * z - 1);
  out[7] = -c2a * x * z;
  out[8] = c2c * (x * x - y * y);
  if (order < 4) return;
  const double c3a = 0.59004358992664352;  // √(35/(32π))
  const double c3b = 2.8906114426405538;   // √(105/(4π))
  const double c3c = 0.45704579946446572;  // √(21/(32π))
  const double c3d = 0.37317633259011540;  // √(7/(16π))
  const double c3e = 1.4453057213202769;   // √(105/(16π))
  out[9] = -c3a * y * (3 * x * x - y * y);
  out[10] = c3b * x * y * z;
  out[11] = -c3c * y * (5 * z * z - 1);
  out[12] = c3d * z * (5 * z * z - 3);
  out[13] = -c3c * x * (5 * z * z - 1);
  out[14] = c3e * z * (x * x - y * y);
  out[15] = -c3a * x * (x * x - 3 * y * y);
}

void shEvalRecurrence(int order, double x, double y, double z, double* out) {
  PRTBAKE_CHECK(order >= 1, "SH order must be at least 1");
  const double kSqrt2 = 1.4142135623730951;
  double qmm = 0.28209479177387814;  // Q_m^m, starting at m = 0
  double cm = 1.0, sm = 0.0;         // Re, Im of (x + i y)^m
  for (int m = 0; m < order; ++m) {
    if (m > 0) {
      qmm *= -std::sqrt((2.0 * m + 1.0) / (2.0 * m));
      const double c = x * cm - y * sm;
      sm = x * sm + y * cm;
      cm = c;
    }
    // Walk up l for this m: Q_m^m, Q_{m+1}^m, ...
    double qPrev2 = 0.0, qPrev = qmm;
    for (int l = m; l < order; ++l) {
      double q;
      if (l == m) {
        q = qmm;
      } else if (l == m + 1) {
        q = std::sqrt(2.0 * m + 3.0) * z * qmm;
      } else {
        const double ll = double(l), mm = double(m);
        const double a = std::sqrt((4 * ll * ll - 1) / (ll * ll - mm * mm));
        const double b = std::sqrt(((ll - 1) * (ll - 1) - mm * mm) / (4 * (ll - 1) * (ll - 1) - 1));
        q = a * (z * qPrev - b * qPrev2);
      }
      if (l > m) {
        qPrev2 = qPrev;
        qPrev = q;
      }
      if (m == 0) {
        out[shIndex(l, 0)] = q;
      } else {
        out[shIndex(l, m)] = kSqrt2 * q * cm;
        out[shIndex(l, -m)] = kSqrt2 * q * sm;
      }
    }
  }
}

void shEval(int order, double x, double y, double z, double* out) {
  if (order <= kHardcodedShOrder)
    shEvalHardcoded(order, x, y, z, out);
  else
    shEvalRecurrence(order, x, y, z, out);
}

double clampedCosineFactor(int l) {
  const double pi = 3.14159265358979323846;
  if (l == 0) return pi;
  if (l == 1) return 2.0 * pi / 3.0;
  if (l % 2 == 1) return 0.0;
  // l!/(2^l ((l/2)!)²) = C(l, l/2)/2^l, computed as a product to stay finite.
  double ratio = 1.0;
  for (int k = 1; k <= l / 2; ++k) ratio *= double(l / 2 + k) / double(4 * k);
  const double sign = ((l / 2 - 1) % 2 == 0) ? 1.0 : -1.0;
  return 2.0 * pi * sign / ((l + 2.0) * (l - 1.0)) * ratio;
}

std::vector<double> clampedCosineProjected(int order, double nx, double ny, double nz) {
  std::vector<double> out(size_t(shCount(order)));
  shEval(order, nx, ny, nz, out.data());
  const double pi = 3.14159265358979323846;
  for (int l = 0; l < order; ++l) {
    const double f = clampedCosineFactor(l) / pi;
    for (int m = -l; m <= l; ++m) out[size_t(shIndex(l, m))] *= f;
  }
  return out;
}

const char* toString(ShQuantity q) {
  switch (q) {
    case ShQuantity::Radiance: return "radiance";
    case ShQuantity::Irradiance: return "irradiance";
    case ShQuantity::IrradianceOverPi: return "irradiance_over_pi";
  }
  return "?";
}

ShQuantity parseQuantity(const std::string& s) {
  for (auto q : {ShQuantity::Radiance, ShQuantity::Irradiance, ShQuantity::IrradianceOverPi})
    if (s == toString(q)) return q;
  throw UsageError("--quantity", "unknown value '" + s + "' (expected radiance|irradiance|irradiance_over_pi)");
}

}  // namespace prtbake
