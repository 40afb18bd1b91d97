// SH rotation: Ivanic–Ruedenberg recurrence and the projection method.
#include "prtbake/sh_rotate.h"

#include <cmath>
#include <cstdint>
#include <string>

#include "core/constants.h"
#include "prtbake/error.h"
#include "prtbake/sh.h"

namespace prtbake {
namespace {

std::array<double, 9> mul(const std::array<double, 9>& a, const std::array<double, 9>& b) {
  std::array<double, 9> c{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) c[size_t(3 * i + j)] += a[size_t(3 * i + k)] * b[size_t(3 * k + j)];
  return c;
}

std::array<double, 9> rotZ(double rad) {
  const double c = std::cos(rad), s = std::sin(rad);
  return {c, -s, 0, s, c, 0, 0, 0, 1};
}
std::array<double, 9> rotY(double rad) {
  const double c = std::cos(rad), s = std::sin(rad);
  return {c, 0, s, 0, 1, 0, -s, 0, c};
}

void checkOrder(int order) {
  if (order < 1 || order > kMaxShOrder)
    throw UsageError("order", std::to_string(order) + " is out of range [1, " + std::to_string(kMaxShOrder) + "]");
}

// Band-l block accessor with m, m' in −l..l.
struct Block {
  int l;
  std::vector<double>* data;
  double& operator()(int m, int mp) const { return (*data)[size_t((m + l) * (2 * l + 1) + (mp + l))]; }
};

}  // namespace

std::array<double, 3> Rotation::apply(const std::array<double, 3>& d) const {
  return {m[0] * d[0] + m[1] * d[1] + m[2] * d[2], m[3] * d[0] + m[4] * d[1] + m[5] * d[2],
          m[6] * d[0] + m[7] * d[1] + m[8] * d[2]};
}

Rotation rotationFromEulerZYZ(double a, double b, double g) {
  const double k = kPi / 180.0;
  Rotation r;
  r.m = mul(mul(rotZ(a * k), rotY(b * k)), rotZ(g * k));
  return r;
}

Rotation rotationFromQuaternion(double w, double x, double y, double z) {
  const double n = std::sqrt(w * w + x * x + y * y + z * z);
  if (!(n > 1e-12) || !std::isfinite(n)) throw UsageError("--quat", "the quaternion must be non-zero and finite");
  w /= n, x /= n, y /= n, z /= n;
  Rotation r;
  r.m = {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
         2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
         2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};
  return r;
}

// Ivanic & Ruedenberg, "Rotation matrices for real spherical harmonics. Direct
// determination by recursion", J. Phys. Chem. 100 (1996) 6342, and the errata in
// J. Phys. Chem. A 102 (1998) 9099. Their real basis has no Condon–Shortley
// phase; ours differs by the sign (−1)^m on every function, so M = S·M_IR·S with
// S = diag((−1)^m), applied at the end of each band.
ShRotationBlocks shRotationExact(const Rotation& rot, int order) {
  checkOrder(order);
  ShRotationBlocks out(static_cast<size_t>(order));
  out[0] = {1.0};
  if (order == 1) return out;
  // Band 1 in the IR basis (y, z, x): R1(m, m') = R[axis(m)][axis(m')].
  const int axis[3] = {1, 2, 0};  // m = −1 → y, 0 → z, 1 → x
  std::vector<std::vector<double>> ir(static_cast<size_t>(order));
  ir[1].resize(9);
  for (int m = -1; m <= 1; ++m)
    for (int mp = -1; mp <= 1; ++mp) ir[1][size_t((m + 1) * 3 + mp + 1)] = rot.m[size_t(3 * axis[m + 1] + axis[mp + 1])];
  const Block r1{1, &ir[1]};
  for (int l = 2; l < order; ++l) {
    ir[size_t(l)].assign(size_t((2 * l + 1) * (2 * l + 1)), 0.0);
    const Block prev{l - 1, &ir[size_t(l - 1)]}, cur{l, &ir[size_t(l)]};
    auto P = [&](int i, int a, int b) {
      if (b == l) return r1(i, 1) * prev(a, l - 1) - r1(i, -1) * prev(a, -l + 1);
      if (b == -l) return r1(i, 1) * prev(a, -l + 1) + r1(i, -1) * prev(a, l - 1);
      return r1(i, 0) * prev(a, b);
    };
    for (int m = -l; m <= l; ++m)
      for (int mp = -l; mp <= l; ++mp) {
        const double d = m == 0 ? 1.0 : 0.0;
        const double denom = std::abs(mp) < l ? double(l + mp) * (l - mp) : double(2 * l) * (2 * l - 1);
        const int am = std::abs(m);
        const double u = std::sqrt(double(l + m) * (l - m) / denom);
        const double v = 0.5 * std::sqrt((1 + d) * double(l + am - 1) * (l + am) / denom) * (1 - 2 * d);
        const double w = -0.5 * std::sqrt(double(l - am - 1) * (l - am) / denom) * (1 - d);
        double sum = 0;
        if (u != 0) sum += u * P(0, m, mp);
        if (v != 0) {
          double V;
          if (m == 0)
            V = P(1, 1, mp) + P(-1, -1, mp);
          else if (m > 0)
            V = P(1, m - 1, mp) * std::sqrt(1 + (m == 1)) - P(-1, -m + 1, mp) * (1 - (m == 1));
          else
            V = P(1, m + 1, mp) * (1 - (m == -1)) + P(-1, -m - 1, mp) * std::sqrt(1 + (m == -1));
          sum += v * V;
        }
        if (w != 0) {
          const double W = m > 0 ? P(1, m + 1, mp) + P(-1, -m - 1, mp) : P(1, m - 1, mp) - P(-1, -m + 1, mp);
          sum += w * W;
        }
        cur(m, mp) = sum;
      }
  }
  for (int l = 1; l < order; ++l) {
    out[size_t(l)] = ir[size_t(l)];
    const Block b{l, &out[size_t(l)]};
    for (int m = -l; m <= l; ++m)
      for (int mp = -l; mp <= l; ++mp)
        if ((m + mp) % 2 != 0) b(m, mp) = -b(m, mp);
  }
  return out;
}

namespace {

// Inverse by Gauss–Jordan with partial pivoting; returns false when singular.
bool invert(std::vector<double> a, int n, std::vector<double>& inv) {
  inv.assign(size_t(n * n), 0.0);
  for (int i = 0; i < n; ++i) inv[size_t(i * n + i)] = 1.0;
  for (int c = 0; c < n; ++c) {
    int piv = c;
    for (int r = c + 1; r < n; ++r)
      if (std::abs(a[size_t(r * n + c)]) > std::abs(a[size_t(piv * n + c)])) piv = r;
    if (std::abs(a[size_t(piv * n + c)]) < 1e-300) return false;
    if (piv != c)
      for (int k = 0; k < n; ++k) {
        std::swap(a[size_t(c * n + k)], a[size_t(piv * n + k)]);
        std::swap(inv[size_t(c * n + k)], inv[size_t(piv * n + k)]);
      }
    const double p = a[size_t(c * n + c)];
    for (int k = 0; k < n; ++k) a[size_t(c * n + k)] /= p, inv[size_t(c * n + k)] /= p;
    for (int r = 0; r < n; ++r) {
      if (r == c) continue;
      const double f = a[size_t(r * n + c)];
      if (f == 0) continue;
      for (int k = 0; k < n; ++k) a[size_t(r * n + k)] -= f * a[size_t(c * n + k)], inv[size_t(r * n + k)] -= f * inv[size_t(c * n + k)];
    }
  }
  return true;
}

double norm1(const std::vector<double>& a, int n) {
  double best = 0;
  for (int c = 0; c < n; ++c) {
    double s = 0;
    for (int r = 0; r < n; ++r) s += std::abs(a[size_t(r * n + c)]);
    best = std::max(best, s);
  }
  return best;
}

// Band-l values at the directions: A[i][k] = Y_{l, i−l}(n_k).
std::vector<double> bandMatrix(int l, const std::vector<std::array<double, 3>>& dirs) {
  const int n = 2 * l + 1;
  std::vector<double> y(size_t((l + 1) * (l + 1))), a(size_t(n * n));
  for (int k = 0; k < n; ++k) {
    shEval(l + 1, dirs[size_t(k)][0], dirs[size_t(k)][1], dirs[size_t(k)][2], y.data());
    for (int i = 0; i < n; ++i) a[size_t(i * n + k)] = y[size_t(l * l + i)];
  }
  return a;
}

// Deterministic candidate direction sets: 2l+1 points drawn uniformly on the
// sphere from a fixed-seed generator (a different stream per variant); the
// best-conditioned of several variants is used.
std::vector<std::array<double, 3>> candidateDirs(int l, int variant) {
  const int n = 2 * l + 1;
  uint64_t state = 0x9E3779B97F4A7C15ull * uint64_t(variant + 1) + uint64_t(l);
  auto next = [&state] {  // splitmix64 → [0, 1)
    uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return double((z ^ (z >> 31)) >> 11) * (1.0 / 9007199254740992.0);
  };
  std::vector<std::array<double, 3>> dirs;
  for (int k = 0; k < n; ++k) {
    const double z = 1.0 - 2.0 * next(), r = std::sqrt(std::max(0.0, 1.0 - z * z)), phi = 2.0 * kPi * next();
    dirs.push_back({r * std::cos(phi), r * std::sin(phi), z});
  }
  return dirs;
}

}  // namespace

ShRotationBlocks shRotationProjection(const Rotation& rot, int order,
                                      const std::vector<std::vector<std::array<double, 3>>>& dirsIn,
                                      double maxCondition, double* conditionOut) {
  checkOrder(order);
  ShRotationBlocks out(static_cast<size_t>(order));
  double worst = 1.0;
  for (int l = 0; l < order; ++l) {
    const int n = 2 * l + 1;
    std::vector<std::array<double, 3>> dirs;
    std::vector<double> a, ainv;
    double cond = 1e300;
    if (!dirsIn.empty()) {
      if (dirsIn.size() < size_t(order) || dirsIn[size_t(l)].size() != size_t(n))
        throw UsageError("rotation directions", "band " + std::to_string(l) + " needs " + std::to_string(n) + " directions");
      dirs = dirsIn[size_t(l)];
      a = bandMatrix(l, dirs);
      if (invert(a, n, ainv)) cond = norm1(a, n) * norm1(ainv, n);
    } else {
      for (int variant = 0; variant < 16; ++variant) {
        auto cand = candidateDirs(l, variant);
        auto ca = bandMatrix(l, cand);
        std::vector<double> cinv;
        if (!invert(ca, n, cinv)) continue;
        const double c = norm1(ca, n) * norm1(cinv, n);
        if (c < cond) cond = c, dirs = cand, a = ca, ainv = cinv;
      }
    }
    if (!(cond <= maxCondition))
      throw Error("SH rotation (projection method)",
                  "band " + std::to_string(l) + ": the direction matrix A is ill-conditioned (cond₁ = " +
                      (cond >= 1e300 ? std::string("inf") : std::to_string(cond)) +
                      "); choose other directions or use the exact method");
    worst = std::max(worst, cond);
    std::vector<std::array<double, 3>> rotated;
    for (const auto& d : dirs) rotated.push_back(rot.apply(d));
    const std::vector<double> s = bandMatrix(l, rotated);
    std::vector<double> m(size_t(n * n), 0.0);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j)
        for (int k = 0; k < n; ++k) m[size_t(i * n + j)] += s[size_t(i * n + k)] * ainv[size_t(k * n + j)];
    out[size_t(l)] = m;
  }
  if (conditionOut) *conditionOut = worst;
  return out;
}

ShCoeffs applyShRotation(const ShCoeffs& c, const ShRotationBlocks& m) {
  if (m.size() < size_t(c.order)) throw UsageError("rotation", "rotation blocks do not cover the coefficients' order");
  ShCoeffs out = c;
  for (int l = 0; l < c.order; ++l) {
    const int n = 2 * l + 1;
    for (int i = 0; i < n; ++i) {
      Rgb s{0, 0, 0};
      for (int j = 0; j < n; ++j)
        for (int ch = 0; ch < 3; ++ch) s[size_t(ch)] += m[size_t(l)][size_t(i * n + j)] * c.rgb[size_t(l * l + j)][size_t(ch)];
      out.rgb[size_t(l * l + i)] = s;
    }
  }
  return out;
}

}  // namespace prtbake
