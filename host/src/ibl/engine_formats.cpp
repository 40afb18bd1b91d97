// Engine conventions (prtbake/engine.h): the SH conversions and the engine file formats
// (three.js Object JSON, Filament sh.txt and KTX 1.1 cubes, Babylon.js .env and the
// EXT_lights_image_based .glb, PNG images).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <nlohmann/json.hpp>

#include "core/constants.h"
#include "io/png_chunks.h"
#include "prtbake/atomic_file.h"
#include "prtbake/ibl.h"
#include "prtbake/error.h"
#include "prtbake/sh.h"

namespace prtbake {
namespace {

constexpr int kEngineShCount = 9;

// c_i of the first 9 coefficients (missing ones are 0), channel-minor.
EngineSh radianceOf(const ShCoeffs& c) {
  if (c.quantity != ShQuantity::Radiance) throw UsageError("sh", "engine exports take radiance coefficients");
  EngineSh out{};
  for (int i = 0; i < kEngineShCount && size_t(i) < c.rgb.size(); ++i)
    for (int k = 0; k < 3; ++k) out[size_t(3 * i + k)] = c.rgb[size_t(i)][size_t(k)];
  return out;
}

int bandOf(int i) { return i == 0 ? 0 : i < 4 ? 1 : 2; }

void put32(std::string& s, uint32_t v) { s.append(reinterpret_cast<const char*>(&v), 4); }

// An unsigned float of `mantissaBits` mantissa bits and a 5-bit exponent (bias 15), rounded to
// nearest: the channels of GL_R11F_G11F_B10F.
uint32_t unsignedSmallFloat(float v, int mantissaBits, bool* clamped) {
  const uint32_t maxBits = (30u << mantissaBits) | ((1u << mantissaBits) - 1);  // exponent 30, mantissa all ones
  if (!(v > 0)) return 0;                                                         // negatives, zero and NaN
  const double maxValue = std::ldexp(2.0 - std::ldexp(1.0, -mantissaBits), 15);
  if (v >= maxValue) {
    if (v > maxValue && clamped) *clamped = true;
    return maxBits;
  }
  int e = 0;
  const double m = std::frexp(double(v), &e);  // v = m · 2^e, m ∈ [0.5, 1)
  int exponent = e - 1 + 15;
  uint32_t mantissa;
  if (exponent <= 0) {  // denormal: v = mantissa / 2^bits · 2^−14
    exponent = 0;
    mantissa = uint32_t(std::nearbyint(std::ldexp(double(v), 14 + mantissaBits)));
  } else {
    mantissa = uint32_t(std::nearbyint((2 * m - 1) * double(1u << mantissaBits)));
  }
  if (mantissa >> mantissaBits) mantissa = 0, ++exponent;  // rounded up into the next binade
  return std::min(maxBits, (uint32_t(exponent) << mantissaBits) | mantissa);
}

// The texel of an n × n cube (docs/conventions.md "Cube faces") whose cell holds unit-ish
// direction d: face by the major axis, then (u, v) on that face's basis.
size_t cubeTexelOf(const std::array<CubeFaceBasis, 6>& faces, int n, const double d[3]) {
  int face = 0;
  double best = -1;
  for (int f = 0; f < 6; ++f) {
    const auto& a = faces[size_t(f)].axisN;
    const double dn = a[0] * d[0] + a[1] * d[1] + a[2] * d[2];
    if (dn > best) best = dn, face = f;
  }
  const auto& b = faces[size_t(face)];
  const double u = (b.axisU[0] * d[0] + b.axisU[1] * d[1] + b.axisU[2] * d[2]) / best;
  const double v = (b.axisV[0] * d[0] + b.axisV[1] * d[1] + b.axisV[2] * d[2]) / best;
  const int col = std::clamp(int(std::floor((u + 1) / 2 * n)), 0, n - 1);
  const int row = std::clamp(int(std::floor((v + 1) / 2 * n)), 0, n - 1);
  return (size_t(face) * size_t(n) + size_t(row)) * size_t(n) + size_t(col);
}

}  // namespace

EngineSh threejsSh(const ShCoeffs& radiance) {
  EngineSh k = radianceOf(radiance);
  for (int l = 0; l < 3; ++l)
    for (int m = -l; m <= l; ++m)
      for (int c = 0; c < 3; ++c) k[size_t(3 * shIndex(l, m) + c)] *= shCondonShortleyPhase(m);
  return k;
}

EngineSh gltfIrradianceSh(const ShCoeffs& radiance) {
  EngineSh e = radianceOf(radiance);
  for (int i = 0; i < kEngineShCount; ++i)
    for (int c = 0; c < 3; ++c) e[size_t(3 * i + c)] *= clampedCosineFactor(bandOf(i));
  return e;
}

EngineSh filamentSh(const ShCoeffs& radiance) {
  // K_i: Y_i(n) = K_i · P_i(n) with P = (1, y, z, x, xy, yz, 3z² − 1, xz, x² − y²), the
  // polynomial Filament's shader evaluates; the signs are the Condon–Shortley phase.
  const double s = 1.0 / std::sqrt(kPi);
  const double K[kEngineShCount] = {0.5 * s,
                                    -std::sqrt(3.0) / 2 * s,
                                    std::sqrt(3.0) / 2 * s,
                                    -std::sqrt(3.0) / 2 * s,
                                    std::sqrt(15.0) / 2 * s,
                                    -std::sqrt(15.0) / 2 * s,
                                    std::sqrt(5.0) / 4 * s,
                                    -std::sqrt(15.0) / 2 * s,
                                    std::sqrt(15.0) / 4 * s};
  EngineSh f = gltfIrradianceSh(radiance);
  for (int i = 0; i < kEngineShCount; ++i)
    for (int c = 0; c < 3; ++c) f[size_t(3 * i + c)] *= K[i] / kPi;
  return f;
}

std::string threejsLightProbeJson(const EngineSh& sh, const std::string& extra) {
  nlohmann::json j;
  j["metadata"] = {{"version", 4.7}, {"type", "Object"}, {"generator", std::string("prtbake ") + version()}};
  j["object"] = {{"type", "LightProbe"},
                 {"name", "prtbake"},
                 {"layers", 1},
                 {"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}},
                 {"up", {0, 1, 0}},
                 {"color", 0xffffff},
                 {"intensity", 1},
                 {"sh", std::vector<double>(sh.begin(), sh.end())}};
  if (!extra.empty()) j["object"]["userData"] = nlohmann::json::parse(extra);
  return j.dump(2) + "\n";
}

std::string filamentShText(const EngineSh& sh) {
  std::string out;
  char line[160];
  for (int l = 0, i = 0; l < 3; ++l)
    for (int m = -l; m <= l; ++m, ++i) {
      std::snprintf(line, sizeof line, "(%18.15f, %18.15f, %18.15f); // L%d%d, irradiance, pre-scaled base\n",
                    sh[size_t(3 * i)], sh[size_t(3 * i + 1)], sh[size_t(3 * i + 2)], l, m);
      out += line;
    }
  return out;
}

uint32_t packR11G11B10(float r, float g, float b, bool* clamped) {
  return unsignedSmallFloat(r, 6, clamped) | (unsignedSmallFloat(g, 6, clamped) << 11) |
         (unsignedSmallFloat(b, 5, clamped) << 22);
}

std::string filamentKtx1Bytes(const std::vector<CubeLevel>& levels, const EngineSh* sh, long long* clamped) {
  if (levels.empty()) throw OutputError("ktx", "nothing to write");
  constexpr uint32_t kR11fG11fB10f = 0x8C3A, kRgb = 0x1907;
  std::string out;
  const unsigned char id[12] = {0xAB, 'K', 'T', 'X', ' ', '1', '1', 0xBB, '\r', '\n', 0x1A, '\n'};
  out.append(reinterpret_cast<const char*>(id), 12);
  std::string kvd;
  auto keyValue = [&kvd](const std::string& key, const std::string& value) {
    const std::string kv = key + std::string(1, '\0') + value + std::string(1, '\0');
    put32(kvd, uint32_t(kv.size()));
    kvd += kv;
    while (kvd.size() % 4) kvd.push_back('\0');
  };
  keyValue("KTXwriter", std::string("prtbake ") + version());
  if (sh) {
    // Filament's createIblFromKtx1 reads "sh" with value.split(/\s/, 27).map(parseFloat):
    // single separators, 9 lines of "r g b".
    std::string text;
    char num[40];
    for (int i = 0; i < 27; ++i) {
      std::snprintf(num, sizeof num, "%.9g", (*sh)[size_t(i)]);
      text += num;
      text += (i % 3 == 2) ? "\n" : " ";
    }
    keyValue("sh", text);
  }
  put32(out, 0x04030201);              // endianness
  put32(out, kR11fG11fB10f);           // glType: cmgen's value, which Filament's Ktx1Reader maps to UINT_10F_11F_11F_REV
  put32(out, 1);                       // glTypeSize
  put32(out, kRgb);                    // glFormat
  put32(out, kR11fG11fB10f);           // glInternalFormat
  put32(out, kRgb);                    // glBaseInternalFormat
  put32(out, uint32_t(levels[0].size));  // pixelWidth
  put32(out, uint32_t(levels[0].size));  // pixelHeight
  put32(out, 0);                       // pixelDepth
  put32(out, 0);                       // numberOfArrayElements
  put32(out, 6);                       // numberOfFaces
  put32(out, uint32_t(levels.size()));   // numberOfMipmapLevels
  put32(out, uint32_t(kvd.size()));
  out += kvd;
  long long over = 0;
  for (const CubeLevel& l : levels) {
    const size_t faceTexels = size_t(l.size) * size_t(l.size);
    if (!l.rgb || l.rgb->size() != 6 * faceTexels * 3) throw OutputError("ktx", "a level has the wrong number of texels");
    put32(out, uint32_t(faceTexels * 4));  // imageSize: one face (non-array cube)
    for (size_t t = 0; t < 6 * faceTexels; ++t) {
      bool c = false;
      put32(out, packR11G11B10((*l.rgb)[3 * t], (*l.rgb)[3 * t + 1], (*l.rgb)[3 * t + 2], &c));
      over += c ? 1 : 0;
    }
    // Faces and levels of 4-byte texels need no padding.
  }
  if (clamped) *clamped = over;
  return out;
}

// ---------------------------------------------------------------- Babylon.js

EngineSh babylonIrradianceSh(const ShCoeffs& radiance) {
  EngineSh e = gltfIrradianceSh(radiance);
  for (int i : {3, 4, 7})  // the terms odd in x: Y_11 ∝ x, Y_2-2 ∝ xy, Y_21 ∝ xz
    for (int c = 0; c < 3; ++c) e[size_t(3 * i + c)] = -e[size_t(3 * i + c)];
  return e;
}

EngineSh babylonEnvPolynomial(const ShCoeffs& radiance) {
  // The shader gets H = SphericalHarmonics.FromPolynomial(p), pre-scaled, and should see the
  // irradiance harmonics over π: H_i = E_i / π in Babylon's frame. FromPolynomial is linear
  // with the constants below (Babylon 9, Maths/sphericalPolynomial); this is its exact
  // inverse, so the shader's harmonics come back to rounding.
  const EngineSh e = babylonIrradianceSh(radiance);
  const double kA = 0.376127, kAz = 0.376126, kB = 0.977204, kC = 1.16538, kD = 1.34567, kE = 0.672834;
  EngineSh p{};
  enum { X, Y, Z, XX, YY, ZZ, YZ, ZX, XY };  // the .env's field order
  for (int c = 0; c < 3; ++c) {
    auto h = [&](int i) { return e[size_t(3 * i + c)] / kPi / kPi; };  // H_i / π (FromPolynomial ends × π)
    auto set = [&](int field, double v) { p[size_t(3 * field + c)] = v; };
    set(Y, -h(1) / kB);
    set(Z, h(2) / kB);
    set(X, -h(3) / kB);
    set(XY, h(4) / kC);
    set(YZ, -h(5) / kC);
    set(ZX, -h(7) / kC);
    // l00 = kA (xx + yy) + kAz zz,  l20 = kD zz − kE (xx + yy),  l22 = kC (xx − yy)
    const double det = kA * kD + kAz * kE;
    const double sum = (kD * h(0) - kAz * h(6)) / det, zz = (kA * h(6) + kE * h(0)) / det, diff = h(8) / kC;
    set(XX, (sum + diff) / 2);
    set(YY, (sum - diff) / 2);
    set(ZZ, zz);
  }
  return p;
}

std::vector<std::string> babylonRgbdFaces(int n, const std::vector<float>& rgb, long long* clamped) {
  if (n < 1 || rgb.size() != 6 * size_t(n) * size_t(n) * 3) throw OutputError("env", "a level has the wrong number of texels");
  // Babylon's cube for world direction b (left-handed) holds the environment's (−b.x, b.y, b.z);
  // its images are stored bottom row first (its loader uploads them with UNPACK_FLIP_Y).
  const auto faces = standardCubeBases();
  std::vector<std::string> out;
  long long over = 0;
  std::vector<uint8_t> px(size_t(n) * size_t(n) * 4);
  for (int f = 0; f < 6; ++f) {
    const auto& b = faces[size_t(f)];
    for (int row = 0; row < n; ++row)
      for (int col = 0; col < n; ++col) {
        const double u = 2 * (col + 0.5) / n - 1, v = 2 * (n - 1 - row + 0.5) / n - 1;
        double d[3];
        for (int k = 0; k < 3; ++k) d[k] = u * b.axisU[size_t(k)] + v * b.axisV[size_t(k)] + b.axisN[size_t(k)];
        d[0] = -d[0];
        const float* c = &rgb[3 * cubeTexelOf(faces, n, d)];
        // toRGBD (Babylon's helperFunctions): D = saturate(floor(max(255 / max(rgb), 1)) / 255),
        // stored rgb = saturate((c · D)^(1/2.2)); fromRGBD gives rgb^2.2 / D.
        const double m = std::max({double(c[0]), double(c[1]), double(c[2]), 1e-7});
        const int dByte = int(std::clamp(std::floor(std::max(255.0 / m, 1.0)), 1.0, 255.0));
        const double D = dByte / 255.0;
        uint8_t* o = &px[(size_t(row) * size_t(n) + size_t(col)) * 4];
        for (int k = 0; k < 3; ++k) {
          const double g = std::pow(std::max(0.0, double(c[k])) * D, 1 / 2.2);
          over += g > 1 ? 1 : 0;
          o[k] = uint8_t(std::lround(std::min(g, 1.0) * 255));
        }
        o[3] = uint8_t(dByte);
      }
    out.push_back(png8Bytes(n, n, 4, px));
  }
  if (clamped) *clamped += over;
  return out;
}

std::string babylonEnvBytes(const std::vector<std::vector<std::string>>& facePngs, int width, const EngineSh& polynomial,
                            double lodGenerationScale) {
  nlohmann::json mipmaps = nlohmann::json::array();
  std::string binary;
  for (const auto& level : facePngs)
    for (const std::string& png : level) {
      mipmaps.push_back({{"length", png.size()}, {"position", binary.size()}});
      binary += png;
    }
  static const char* kFields[9] = {"x", "y", "z", "xx", "yy", "zz", "yz", "zx", "xy"};
  nlohmann::json irradiance = nlohmann::json::object();
  for (int i = 0; i < 9; ++i)
    irradiance[kFields[i]] = {polynomial[size_t(3 * i)], polynomial[size_t(3 * i + 1)], polynomial[size_t(3 * i + 2)]};
  const nlohmann::json manifest = {
      {"version", 2},
      {"width", width},
      {"imageType", "image/png"},
      {"irradiance", irradiance},
      {"specular", {{"mipmaps", mipmaps}, {"lodGenerationScale", lodGenerationScale}}},
      {"generator", std::string("prtbake ") + version()}};
  const unsigned char magic[8] = {0x86, 0x16, 0x87, 0x96, 0xf6, 0xd6, 0x96, 0x36};
  std::string out(reinterpret_cast<const char*>(magic), 8);
  out += manifest.dump();
  out.push_back('\0');  // the manifest ends at a NUL; the images' positions count from after it
  return out + binary;
}

std::string babylonIblGlbBytes(const std::vector<std::vector<std::string>>& facePngs, int width,
                               const EngineSh& irradiance) {
  nlohmann::json images = nlohmann::json::array(), views = nlohmann::json::array(), specular = nlohmann::json::array();
  std::string bin;
  for (const auto& level : facePngs) {
    nlohmann::json faces = nlohmann::json::array();
    for (const std::string& png : level) {
      faces.push_back(images.size());
      views.push_back({{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", png.size()}});
      images.push_back({{"bufferView", views.size() - 1}, {"mimeType", "image/png"}});
      bin += png;
      while (bin.size() % 4) bin.push_back('\0');
    }
    specular.push_back(faces);
  }
  nlohmann::json coeffs = nlohmann::json::array();
  for (int i = 0; i < 9; ++i) coeffs.push_back({irradiance[size_t(3 * i)], irradiance[size_t(3 * i + 1)], irradiance[size_t(3 * i + 2)]});
  const nlohmann::json light = {{"name", "prtbake"},
                                {"intensity", 1.0},  // Babylon's loader multiplies by it unconditionally
                                {"rotation", {0, 0, 0, 1}},
                                {"irradianceCoefficients", coeffs},
                                {"specularImageSize", width},
                                {"specularImages", specular}};
  const nlohmann::json gltf = {
      {"asset", {{"version", "2.0"}, {"generator", std::string("prtbake ") + version()}}},
      {"extensionsUsed", {"EXT_lights_image_based"}},
      {"extensions", {{"EXT_lights_image_based", {{"lights", {light}}}}}},
      {"scene", 0},
      {"scenes", {{{"name", "prtbake environment"}, {"extensions", {{"EXT_lights_image_based", {{"light", 0}}}}}}}},
      {"images", images},
      {"bufferViews", views},
      {"buffers", {{{"byteLength", bin.size()}}}}};
  std::string json = gltf.dump();
  while (json.size() % 4) json.push_back(' ');
  std::string out;
  const uint32_t total = uint32_t(12 + 8 + json.size() + 8 + bin.size());
  out += "glTF";
  put32(out, 2);
  put32(out, total);
  put32(out, uint32_t(json.size()));
  out += "JSON";
  out += json;
  put32(out, uint32_t(bin.size()));
  out += std::string("BIN\0", 4);
  return out + bin;
}

}  // namespace prtbake
