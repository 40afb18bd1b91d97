// The ray–triangle test of the CPU references, in double: the kernels' rays checked by brute
// force over every triangle.
#pragma once

namespace prtbake::detail {

struct TriangleHit {
  double t, u, v;  // distance along d, and barycentrics of v1 and v2
  bool ok;         // 0 < t < tMax and (u, v) on the closed triangle (edges included)
};

// Möller–Trumbore: the ray o + t·d against the triangle (v0, v1, v2).
inline TriangleHit intersectTriangle(const double* o, const double* d, const double* v0, const double* v1,
                                     const double* v2, double tMax) {
  double e1[3], e2[3], s[3];
  for (int c = 0; c < 3; ++c) e1[c] = v1[c] - v0[c], e2[c] = v2[c] - v0[c], s[c] = o[c] - v0[c];
  const double p[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2], d[0] * e2[1] - d[1] * e2[0]};
  const double det = e1[0] * p[0] + e1[1] * p[1] + e1[2] * p[2];
  if (det == 0) return {0, 0, 0, false};
  const double inv = 1 / det;
  const double u = (s[0] * p[0] + s[1] * p[1] + s[2] * p[2]) * inv;
  const double q[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2], s[0] * e1[1] - s[1] * e1[0]};
  const double v = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) * inv;
  const double t = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) * inv;
  return {t, u, v, t > 0 && t < tMax && u >= 0 && v >= 0 && u + v <= 1};
}

}  // namespace prtbake::detail
