// prtbake/sh.h: real spherical harmonics, double-precision reference.
//
// Conventions (fixed, see docs/conventions.md "SH basis"): real, orthonormal (∫ Y_i Y_j dω = δ_ij),
// Condon–Shortley phase, evaluated on a unit direction (x, y, z) of the input's
// world frame; index i = l(l+1) + m; "order n" means bands 0..n-1, n² coefficients.
//
//   Y_l0  =    Q_l^m                with Q_l^m = K_l^m P_l^m(z) / sin^m θ
//   Y_lm  = √2 Q_l^m Re (x + i y)^m  (m > 0)
//   Y_l-m = √2 Q_l^m Im (x + i y)^m  (m > 0)
// since sin^m θ e^{imφ} = (x + i y)^m. Q follows the stable three-term
// recurrence of the normalised associated Legendre functions (no factorials):
//   Q_0^0 = 1/√(4π),  Q_m^m = −√((2m+1)/(2m)) Q_{m−1}^{m−1},  Q_{m+1}^m = √(2m+3) z Q_m^m,
//   Q_l^m = a_lm (z Q_{l−1}^m − b_lm Q_{l−2}^m),
//   a_lm = √((4l²−1)/(l²−m²)),  b_lm = √(((l−1)²−m²)/(4(l−1)²−1)).
// It is exact at the poles ((x + i y)^m = 0 for m > 0) and needs no atan2.
#pragma once

#include <array>
#include <string>
#include <vector>

namespace prtbake {

// Orders accepted by every product (1..kMaxShOrder). 32 orders = 1024 coefficients.
constexpr int kMaxShOrder = 32;
// Orders up to this one use hard-coded polynomials (bands 0..3).
constexpr int kHardcodedShOrder = 4;

constexpr int shIndex(int l, int m) { return l * (l + 1) + m; }
constexpr int shCount(int order) { return order * order; }
// (−1)^m, the Condon–Shortley phase that Y_lm and Y_l−m both carry (docs/conventions.md
// "The phase"). A basis without it (three.js's SphericalHarmonics3 and LightProbeGrid) has
// the same functions times this sign, so its coefficients are c_lm · shCondonShortleyPhase(m).
constexpr double shCondonShortleyPhase(int m) { return m % 2 != 0 ? -1.0 : 1.0; }

// All n² basis functions at the unit direction (x, y, z); picks the hard-coded
// polynomials up to order 4 and the recurrence above.
void shEval(int order, double x, double y, double z, double* out);
// Hard-coded polynomials, order 1..4.
void shEvalHardcoded(int order, double x, double y, double z, double* out);
// The recurrence, any order 1..kMaxShOrder (and beyond: it is stable).
void shEvalRecurrence(int order, double x, double y, double z, double* out);

// Â_l of the clamped cosine max(0, cos θ): its zonal coefficient times √(4π/(2l+1)),
// so that irradiance E_lm = Â_l L_lm. Â_0 = π, Â_1 = 2π/3, Â_l = 0 for odd l > 1,
// Â_l = 2π (−1)^{l/2−1} / ((l+2)(l−1)) · l! / (2^l ((l/2)!)²) for even l.
double clampedCosineFactor(int l);

// The coefficients (zonal harmonic, index l(l+1)) of max(0, n·ω)/π rotated to
// the unit normal n: T_i = Â_l/π · Y_i(n). This is the unshadowed transport of an
// unoccluded vertex (Funk–Hecke), the oracle of the transport tests.
std::vector<double> clampedCosineProjected(int order, double nx, double ny, double nz);

// What a set of SH coefficients of light holds: radiance L_i, irradiance E_i = Â_l L_i,
// or E_i/π (docs/conventions.md "Environment SH").
enum class ShQuantity { Radiance, Irradiance, IrradianceOverPi };
const char* toString(ShQuantity q);
// "radiance", "irradiance", "irradiance_over_pi"; throws UsageError naming --quantity on
// anything else.
ShQuantity parseQuantity(const std::string& s);

using Rgb = std::array<double, 3>;

// SH coefficients of an RGB quantity.
struct ShCoeffs {
  int order = 0;               // n: bands 0..n-1
  std::vector<Rgb> rgb;        // n² coefficients, index l(l+1)+m
  ShQuantity quantity = ShQuantity::Radiance;
};

}  // namespace prtbake
