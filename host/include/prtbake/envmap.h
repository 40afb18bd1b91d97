// prtbake/envmap.h: HDR environments in memory and their loaders.
//
// An EnvMap holds linear float RGB radiance either as a cube (six N×N faces) or
// as a lat-long image, plus everything needed to give each texel its world
// direction and exact solid angle:
//
// Cube: face f, row r (0 = top), column c; u = 2(c+0.5)/N − 1, v = 2(r+0.5)/N − 1;
//   dirWorld = normalize(u·axisU[f] + v·axisV[f] + axisN[f]). The default bases are
//   those of docs/conventions.md "Cube faces" (+X (1,−v,−u), −X (−1,−v,u), +Y (u,1,v),
//   −Y (u,−1,−v), +Z (u,−v,1), −Z (−u,−v,−1)); the games202 preset carries that
//   framework's own table. The texel [u0,u1]×[v0,v1] subtends
//   f(u0,v0) − f(u0,v1) − f(u1,v0) + f(u1,v1) sr with f(a,b) = atan2(ab, √(a²+b²+1)),
//   for any orthonormal basis.
// Lat-long: W×H, row 0 at the top; texel centre λ = −2π((c+0.5)/W − 0.5),
//   φ = π(0.5 − (r+0.5)/H); dirWorld = (sin λ cos φ, sin φ, cos λ cos φ) (OpenEXR's
//   LatLongMap axes); solid angle (2π/W)(sin φ_top − sin φ_bottom).
// Both: the environment is rotated about +Y by yawDegrees before projection
//   (a direction d of the map is seen at Ry(yaw)·d).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "prtbake/raw_vector.h"

namespace prtbake {

enum class EnvLayout { Cube, LatLong };

// How an EnvMap holds its texels: 32-bit floats (rgb), IEEE half floats (halfRgb, as
// OpenEXR half files store them: half the memory), or 8-bit codes (codes, as PNG and
// JPEG store them: a quarter) with the linear radiance of each code in codeToLinear.
// The projection kernel reads every storage; texel() and toFloat() serve the host.
enum class EnvStorage { Float, Half, Code8 };

struct CubeFaceBasis {
  std::array<double, 3> axisU, axisV, axisN;
};

// The face order +X, −X, +Y, −Y, +Z, −Z and orientation of docs/conventions.md "Cube faces".
std::array<CubeFaceBasis, 6> standardCubeBases();

struct EnvMap {
  EnvLayout layout = EnvLayout::Cube;
  int width = 0, height = 0;  // cube: N and N (per face); lat-long: W and H (W = 2H)
  // Linear radiance, interleaved RGB. Cube: 6 faces × N rows × N columns, face-major.
  // Lat-long: H rows × W columns. Exactly one of the three is filled (see EnvStorage);
  // loadEnvironment fills rgb unless asked to keep the file's compact storage.
  RawVector<float> rgb;
  RawVector<uint16_t> halfRgb;
  RawVector<uint8_t> codes;
  // Float texels that the caller holds (an array of the Python module, read in place): used
  // instead of `rgb`, which is then empty, by the projection, validateEnvironment and texel();
  // ownTexels() copies them into `rgb` for the code that reads `rgb` itself. The caller keeps
  // them alive and unchanged while the map is in use.
  const float* rgbView = nullptr;
  std::array<float, 256> codeToLinear{};
  std::array<CubeFaceBasis, 6> faces = standardCubeBases();  // cube only
  double yawDegrees = 0.0;
  std::string source;                    // the path it was loaded from (for messages)
  std::vector<std::string> inputFiles;   // every file read (for hashes in sidecars)
  std::string layoutName;                // "faces", "cross", "vertical-cross", "strip", "latlong",
                                         // "openexr-cube" or "games202"
  long long clampedTexels = 0;           // non-finite/negative texels replaced by 0 (clamp option)

  size_t texelCount() const { return layout == EnvLayout::Cube ? 6 * size_t(width) * width : size_t(width) * height; }
  EnvStorage storage() const { return !codes.empty() ? EnvStorage::Code8 : !halfRgb.empty() ? EnvStorage::Half : EnvStorage::Float; }
  // Linear RGB of texel `index` (the index of texelDirection), whatever the storage.
  std::array<float, 3> texel(size_t index) const;
  // Converts the texels to float storage (a no-op when they are).
  void toFloat();
  // The float texels: the caller's (rgbView) or rgb's.
  const float* floatTexels() const { return rgbView ? rgbView : rgb.data(); }
  // Copies the caller's texels (rgbView) into rgb, so that the map owns them.
  void ownTexels();
};

struct EnvLoadOptions {
  // auto: from the input (a directory of six faces, or the image's shape and
  // OpenEXR envmap attribute: 6:1 or 1:6 cube strip... see README), or force one of
  // faces | cross | latlong | games202.
  std::string layout = "auto";
  // NaN/Inf/negative texels: an InputError by default; with clamp they become 0 and
  // are counted in EnvMap::clampedTexels.
  bool clampInvalid = false;
  // Keep 8-bit images as 8-bit codes and OpenEXR half images as halves (EnvStorage)
  // instead of converting them to floats: a 6 × 2048² JPEG cube takes 75 MB instead of
  // 302 MB. Faces of mixed storage become floats.
  bool compact = false;
};

// Loads an environment from a file (OpenEXR, Radiance .hdr, .png/.jpg cross or
// lat-long) or a directory holding posx/negx/posy/negy/posz/negz faces.
// Throws InputError naming the file and what is wrong.
EnvMap loadEnvironment(const std::string& path, const EnvLoadOptions& options = {});

// A lat-long OpenEXR file (by its envmap attribute, or by its 2:1 shape when options.layout
// is auto or latlong) read a band of rows at a time, so that its texels are never all in
// memory: calls band(texels, firstRow) for consecutive bands of about bandBytes, each an
// EnvMap of the full width holding rows firstRow.. of the map (texelDirection does not
// apply to it). Bands are checked as loadEnvironment checks a map; invalid values without
// options.clampInvalid throw after the last band, counted over the whole map. Fills
// *header (layout, size, source, files, clamped texels; no texels). Returns false without
// calling `band` when the file is not such a map (loadEnvironment then reads it, or says
// what is wrong with it).
bool forEachLatLongBand(const std::string& path, const EnvLoadOptions& options, size_t bandBytes,
                        const std::function<void(EnvMap& band, int firstRow)>& band, EnvMap* header);

// World direction (unit) and exact solid angle (sr) of one texel, in double.
// For a cube `index` = (face·N + row)·N + col; for lat-long row·W + col.
// yawDegrees is applied.
void texelDirection(const EnvMap& env, size_t index, double dirWorld[3], double* solidAngleSr);

// Exact solid angle of cube texel (row, col) of an N×N face.
double cubeTexelSolidAngle(int n, int row, int col);

// Checks sizes and values (finite, non-negative); throws InputError naming
// env.source, or clamps and counts when clampInvalid.
void validateEnvironment(EnvMap& env, bool clampInvalid);

}  // namespace prtbake
