// prtbake/ibl.h: lighting in the conventions of the engines that load it.
//
// prtbake's own SH are radiance coefficients c_i = ∫ L Y_i dω of the real orthonormal basis with
// the Condon–Shortley phase, index i = l(l+1)+m, in the environment's world frame
// (docs/conventions.md "SH basis"). Each engine wants something else (docs/conventions.md
// "Engine SH conventions"); the conversions below
// take order-3 radiance coefficients (higher orders are truncated) and give the 27 numbers the
// engine reads, coefficient-major ([c0.r, c0.g, c0.b, c1.r, …]). Â_l = (π, 2π/3, π/4) are the
// clamped-cosine factors (sh.h), E_i = Â_l c_i the irradiance coefficients.
//   three.js   SphericalHarmonics3 / LightProbe.sh: radiance, basis without the Condon–Shortley
//              phase: k_i = c_i, negated for i = 1, 3, 5, 7 (m odd). getIrradianceAt gives E.
//   Filament   IndirectLight.irradiance(3, sh) / sh.txt / the KTX "sh" key: irradiance over π
//              pre-multiplied by each basis function's signed constant, so that the shader's bare
//              polynomial (1, y, z, x, xy, yz, 3z²−1, xz, x²−y²) gives E/π: f_i = E_i K_i / π.
//   glTF       E_i (Condon–Shortley): irradiance coefficients in the environment's frame.
//   Babylon.js EXT_lights_image_based irradianceCoefficients: E_i in Babylon's frame; the .env
//              file's "irradiance": the spherical polynomial from which Babylon's
//              SphericalHarmonics.FromPolynomial recovers E_i / π in Babylon's frame.
// Frames: three.js and Filament evaluate SH at world normals of a right-handed, +Y up world, as
// glTF does, and their files are written so that world direction d shows the environment's d.
// Babylon's scenes are left-handed: its glTF loader puts glTF (x, y, z) at Babylon (−x, y, z),
// and its cubes and SH are looked up with Babylon directions, so its files hold the environment
// mirrored in x (E_i negated for i = 3, 4, 7; cube faces ±X swapped and each face mirrored).
// tests/js prove each of these with the engine's own code.
#pragma once
#include <array>
#include <string>
#include <vector>

#include "prtbake/env.h"
#include "prtbake/envmap.h"
#include "prtbake/prefilter.h"
#include "prtbake/runtime.h"

namespace prtbake {

using EngineSh = std::array<double, 27>;

EngineSh threejsSh(const ShCoeffs& radiance);
EngineSh filamentSh(const ShCoeffs& radiance);
EngineSh gltfIrradianceSh(const ShCoeffs& radiance);

// three.js Object JSON (ObjectLoader.parse gives a LightProbe; its "object.sh" is the array
// that SphericalHarmonics3.fromArray takes). `extra` (a JSON object as text) goes into
// "userData".
std::string threejsLightProbeJson(const EngineSh& sh, const std::string& extra);
// Filament's sh.txt, as cmgen --sh-shader writes it: 9 lines "(r, g, b); // L<l><m>, ...".
std::string filamentShText(const EngineSh& sh);

// KTX 1.1 cube with every level of `levels` (each 6 × size² RGB, faces +X … −Z, row 0 on top:
// docs/conventions.md "Cube faces", which is Filament's), GL_R11F_G11F_B10F packed
// (GL_UNSIGNED_INT_10F_11F_11F_REV) as cmgen writes it; key "sh" (when `sh` is given) holds the
// 27 numbers as Filament's createIblFromKtx1 parses them. Values above the format's maximum
// (65024 red/green, 64512 blue) are clamped and counted in *clamped; negatives become 0.
struct CubeLevel {
  int size = 0;
  const std::vector<float>* rgb = nullptr;
};
std::string filamentKtx1Bytes(const std::vector<CubeLevel>& levels, const EngineSh* sh, long long* clamped = nullptr);
// The packed GL_UNSIGNED_INT_10F_11F_11F_REV texel of an RGB value (round to nearest).
uint32_t packR11G11B10(float r, float g, float b, bool* clamped = nullptr);

// A PNG of 16-bit (8-bit) channels, 1 to 4, rows top first, no colour-space chunks (the values
// are data).
std::string png16Bytes(int width, int height, int channels, const std::vector<uint16_t>& samples);
std::string png8Bytes(int width, int height, int channels, const std::vector<uint8_t>& samples);

// Babylon.js. Irradiance SH for EXT_lights_image_based (Babylon's frame) and the .env
// polynomial (fields x, y, z, xx, yy, zz, yz, zx, xy, each RGB).
EngineSh babylonIrradianceSh(const ShCoeffs& radiance);
EngineSh babylonEnvPolynomial(const ShCoeffs& radiance);
// One level of a cube (6 × n² RGB, docs/conventions.md "Cube faces") as the six RGBD 8-bit
// PNGs Babylon reads
// (faces +X … −Z of its frame, bottom row first): rgb^(1/2.2) · D with D = ⌊255 / max⌋ / 255 in
// alpha, so values up to 255 are kept; channels above are clamped and counted in *clamped.
std::vector<std::string> babylonRgbdFaces(int n, const std::vector<float>& rgb, long long* clamped = nullptr);
// A version 2 .env: magic, JSON manifest, NUL, then the PNGs of every level (levels from
// `width` down to 1, faces in order). Babylon looks level i up at
// lod = log2(width · α_G) · lodGenerationScale.
std::string babylonEnvBytes(const std::vector<std::vector<std::string>>& facePngs, int width,
                            const EngineSh& polynomial, double lodGenerationScale);
// A .glb whose scene carries one EXT_lights_image_based light with these specular images
// (level-major, faces in order) and irradiance coefficients, intensity 1.
std::string babylonIblGlbBytes(const std::vector<std::vector<std::string>>& facePngs, int width,
                               const EngineSh& irradiance);

// `prtbake ibl`: everything an engine needs, in its conventions, in one directory.
enum class EngineTarget { Threejs, Filament, Babylon, Gltf };
const char* toString(EngineTarget t);
// "threejs" | "filament" | "babylon" | "gltf" | "all" (a comma-separated list is also accepted); throws
// UsageError naming `subject` otherwise.
std::vector<EngineTarget> parseEngineTargets(const std::string& text, const std::string& subject = "--target");

struct IblPackageOptions {
  std::vector<EngineTarget> targets = {EngineTarget::Threejs, EngineTarget::Filament, EngineTarget::Babylon,
                                      EngineTarget::Gltf};
  int size = 256;        // base face size of the prefiltered cubes (a power of two, 16..4096)
  int skyboxSize = 0;    // Filament skybox face size (0: the base size)
  int lutSize = 128;     // the glTF target's LUTs (N × N)
  double tolerance = 0.01;  // prefilter cut tolerance (prefilter.h)
};

struct IblFile {
  std::string path;      // relative to the package directory
  std::string what;
  size_t bytes = 0;
};
struct IblPackageResult {
  std::vector<IblFile> files;
  ShCoeffs radiance;     // order 3, the coefficients every SH export is made from
  double seconds = 0;
};

// Bakes the package for `env` into directory `dir`: built in a temporary sibling directory and
// renamed into place, so `dir` appears whole or not at all. An existing `dir` is replaced only
// when it holds a previous package (its ibl.json); anything else there is an OutputError.
// `metaJson` (an object as text) is merged into ibl.json.
IblPackageResult writeIblPackage(Runtime& rt, const EnvMap& env, const std::string& dir, const IblPackageOptions& options,
                                 const std::string& metaJson);
void validateIblPackageOptions(const IblPackageOptions& options);

}  // namespace prtbake
