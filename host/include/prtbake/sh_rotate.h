// prtbake/sh_rotate.h: rotating SH coefficient sets of any order.
//
// Rotating an environment by R gives L'(ω) = L(Rᵀω); its coefficients are
// c' = M c with M block-diagonal, one (2l+1)² block per band. Two ways to build M:
// - exact: the Ivanic–Ruedenberg recurrence (J. Phys. Chem. 1996, with the 1998
//   errata), band l from band l−1 and the 3×3 rotation; exact to rounding.
// - projection (taught with GAMES202): pick 2l+1 directions n_k, A = [Y_l(n_k)],
//   S = [Y_l(R n_k)], and M_l = S A⁻¹ (a delta at n_k rotates to a delta at R n_k).
//   Its accuracy depends on cond(A): the call refuses (throws) when A is
//   ill-conditioned instead of returning garbage.
#pragma once

#include <array>
#include <vector>

#include "prtbake/sh.h"

namespace prtbake {

// A 3×3 rotation, row-major; it maps a direction d to R·d.
struct Rotation {
  std::array<double, 9> m{1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::array<double, 3> apply(const std::array<double, 3>& d) const;
};

// R = Rz(α)·Ry(β)·Rz(γ), angles in degrees.
Rotation rotationFromEulerZYZ(double alphaDeg, double betaDeg, double gammaDeg);
// Unit quaternion (w, x, y, z); normalised here; a zero quaternion is a UsageError.
Rotation rotationFromQuaternion(double w, double x, double y, double z);

// Band blocks of M (band l: (2l+1)×(2l+1), row-major, rows/cols m = −l..l).
using ShRotationBlocks = std::vector<std::vector<double>>;

ShRotationBlocks shRotationExact(const Rotation& r, int order);

// Projection method with the given directions per band (dirs[l] holds 2l+1 unit
// vectors), or, when dirs is empty, a deterministic well-spread set per band (the
// best-conditioned of several). cond(A) in the 1-norm must stay below maxCondition
// or an Error says which band is ill-conditioned. conditionOut receives the worst
// cond over the bands.
ShRotationBlocks shRotationProjection(const Rotation& r, int order,
                                      const std::vector<std::vector<std::array<double, 3>>>& dirs = {},
                                      double maxCondition = 1e8, double* conditionOut = nullptr);

ShCoeffs applyShRotation(const ShCoeffs& c, const ShRotationBlocks& m);

}  // namespace prtbake
