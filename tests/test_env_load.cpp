// Environment loading: every layout and format round-trips a direction-coded
// image (each pixel stores its own direction d as 1 + d, so any flip, transpose,
// rotation or face swap shows), cross seams are continuous, the OpenEXR cube and
// lat-long follow ImfEnvmap.h, the GAMES202 preset follows that framework's
// table, real files load, and bad input is an InputError naming the file.
#include <catch2/catch.hpp>

#include <ImfChannelList.h>
#include <ImfEnvmap.h>
#include <ImfEnvmapAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfRgbaFile.h>
#include <ImfTiledOutputFile.h>
#include <stb/stb_image_write.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <new>
#include <string>
#include <vector>

#include "io/image_read.h"
#include "prtbake/env.h"
#include "prtbake/envmap.h"
#include "prtbake/error.h"
#include "prtbake/exr.h"
#include "prtbake/raw_vector.h"
#include "test_common.h"

// The deflate of the system's stb library (stb_image_write.c), which its header declares only
// under STB_IMAGE_WRITE_IMPLEMENTATION.
extern "C" unsigned char* stbi_zlib_compress(unsigned char* data, int data_len, int* out_len, int quality);

using namespace prtbake;

namespace {
const double kPi = 3.14159265358979323846;

// A float32 EXR stores 1 + d (in [0, 2]) to half an ulp of 2: 1.2e-7; d itself is
// computed in double on both sides.
constexpr double kFloatDirTol = 1e-6;
// Half floats in [1, 2) have a step of 2^-10 ≈ 9.8e-4; rounding is half of that.
constexpr double kHalfDirTol = 6e-4;
// 8-bit PNG faces store (1 + d)/2 as a code 0..255, so one code is 2/255 in d and
// rounding to the nearest code costs up to 1/255 = 3.92e-3 (plus float error in the
// sRGB round trip, < 1e-6).
constexpr double kPngDirTol = 3.93e-3;
// Radiance RGBE keeps 8 mantissa bits under a shared exponent: for 1 + d in [0, 2]
// stb_image_write truncates to steps of 2^-7 = 7.8e-3.
constexpr double kRgbeDirTol = 8e-3;
// The exact sRGB EOTF computed in double and stored in float: within float rounding.
constexpr double kSrgbTol = 1e-7;

using Dir = std::array<double, 3>;

Dir normalized(double x, double y, double z) {
  const double r = std::sqrt(x * x + y * y + z * z);
  return {x / r, y / r, z / r};
}

// docs/conventions.md "Cube faces", typed in from the text (independent of standardCubeBases):
// +X (1, −v, −u) · −X (−1, −v, u) · +Y (u, 1, v) · −Y (u, −1, −v) · +Z (u, −v, 1) · −Z (−u, −v, −1).
Dir designFaceDirection(int face, int row, int col, int n) {
  const double u = 2.0 * (col + 0.5) / n - 1.0, v = 2.0 * (row + 0.5) / n - 1.0;
  switch (face) {
    case 0: return normalized(1, -v, -u);
    case 1: return normalized(-1, -v, u);
    case 2: return normalized(u, 1, v);
    case 3: return normalized(u, -1, -v);
    case 4: return normalized(u, -v, 1);
    default: return normalized(-u, -v, -1);
  }
}

Dir texelDir(const EnvMap& env, size_t index) {
  Dir d;
  texelDirection(env, index, d.data(), nullptr);
  return d;
}

// Largest component error between each texel's stored direction (decoded from its
// RGB by `decode`) and texelDirection.
double maxDirectionError(const EnvMap& env, const std::function<Dir(const float*)>& decode) {
  double worst = 0;
  for (size_t i = 0; i < env.texelCount(); ++i) {
    const std::array<float, 3> t = env.texel(i);
    const Dir want = texelDir(env, i), got = decode(t.data());
    for (int k = 0; k < 3; ++k) worst = std::max(worst, std::abs(want[k] - got[k]));
  }
  return worst;
}

Dir decodeFloat(const float* p) { return {p[0] - 1.0, p[1] - 1.0, p[2] - 1.0}; }

double linearToSrgb(double l) { return l <= 0.0031308 ? 12.92 * l : 1.055 * std::pow(l, 1 / 2.4) - 0.055; }
Dir decodePng(const float* p) {
  Dir d;
  for (int k = 0; k < 3; ++k) d[k] = 2.0 * linearToSrgb(p[k]) - 1.0;
  return d;
}

// An RGB image being built by a test, row 0 at the top.
struct Picture {
  int w, h;
  std::vector<float> rgb;
  Picture(int w_, int h_) : w(w_), h(h_), rgb(3 * size_t(w_) * size_t(h_), 0.5f) {}
  void set(int x, int y, const Dir& d) {
    for (int k = 0; k < 3; ++k) rgb[3 * (size_t(y) * w + x) + k] = float(1.0 + d[k]);
  }
};

void writeExrPicture(const std::string& path, const Picture& p, ExrWriteOptions opt = {}) {
  std::vector<std::vector<float>> planes(3, std::vector<float>(size_t(p.w) * p.h));
  for (size_t i = 0; i < planes[0].size(); ++i)
    for (int k = 0; k < 3; ++k) planes[k][i] = p.rgb[3 * i + k];
  writeExr(path, p.w, p.h, {{"R", planes[0].data()}, {"G", planes[1].data()}, {"B", planes[2].data()}}, opt);
}

// 8-bit PNG of (1 + d)/2 as a plain code value (the loader applies the sRGB EOTF).
void writePngPicture(const std::string& path, const Picture& p) {
  std::vector<unsigned char> codes(p.rgb.size());
  for (size_t i = 0; i < codes.size(); ++i) codes[i] = (unsigned char)std::lround(255.0 * p.rgb[i] / 2.0);
  REQUIRE(stbi_write_png(path.c_str(), p.w, p.h, 3, codes.data(), 3 * p.w) != 0);
}

void writeHdrPicture(const std::string& path, const Picture& p) {
  REQUIRE(stbi_write_hdr(path.c_str(), p.w, p.h, 3, p.rgb.data()) != 0);
}

void writeBytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

std::string readBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

const char* kFaceNames[6] = {"posx", "negx", "posy", "negy", "posz", "negz"};

// Six direction-coded faces of size n in `dir`, written by `write` with extension `ext`.
void writeFaceDir(const std::string& dir, int n, const std::string& ext,
                  const std::function<void(const std::string&, const Picture&)>& write) {
  for (int f = 0; f < 6; ++f) {
    Picture p(n, n);
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) p.set(c, r, designFaceDirection(f, r, c, n));
    write(dir + "/" + kFaceNames[f] + ext, p);
  }
}

// Where face f's cell lies in a cross (in face units) and whether it is turned 180°:
// the layouts as README and docs/conventions.md ("Environment inputs") describe them.
struct Cell {
  int col, row;
  bool rotate180;
};
const Cell kHorizontalCross[6] = {{2, 1, false}, {0, 1, false}, {1, 0, false}, {1, 2, false}, {1, 1, false}, {3, 1, false}};
const Cell kVerticalCross[6] = {{2, 1, false}, {0, 1, false}, {1, 0, false}, {1, 2, false}, {1, 1, false}, {1, 3, true}};

Picture crossPicture(int n, const Cell* cells, int cols, int rows) {
  Picture p(cols * n, rows * n);
  for (int f = 0; f < 6; ++f)
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) {
        const int ir = cells[f].rotate180 ? n - 1 - r : r, ic = cells[f].rotate180 ? n - 1 - c : c;
        p.set(cells[f].col * n + ic, cells[f].row * n + ir, designFaceDirection(f, r, c, n));
      }
  return p;
}

double angleBetween(const Dir& a, const Dir& b) {
  const double dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  return std::acos(std::max(-1.0, std::min(1.0, dot)));
}

// Σ L·Ω over the sphere per channel (and the total solid angle), in double.
std::array<double, 4> integrate(const EnvMap& env) {
  std::array<double, 4> s{0, 0, 0, 0};
  for (size_t i = 0; i < env.texelCount(); ++i) {
    double d[3], omega;
    texelDirection(env, i, d, &omega);
    for (int k = 0; k < 3; ++k) s[k] += env.rgb[3 * i + k] * omega;
    s[3] += omega;
  }
  return s;
}

// Radiance-weighted mean direction of one channel, Σ L_k·d·Ω.
Dir firstMoment(const EnvMap& env, int k) {
  Dir m{0, 0, 0};
  for (size_t i = 0; i < env.texelCount(); ++i) {
    double d[3], omega;
    texelDirection(env, i, d, &omega);
    for (int j = 0; j < 3; ++j) m[j] += env.rgb[3 * i + k] * d[j] * omega;
  }
  return m;
}

double length(const Dir& d) { return std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]); }

// The lat-long texel that contains direction d (docs/conventions.md "Lat-long" inverted:
// λ = atan2(x, z), φ = asin(y)); mirror = true negates λ (a wrong orientation).
size_t latLongTexelOf(const EnvMap& ll, const Dir& d, bool mirror = false) {
  const double lambda = (mirror ? -1 : 1) * std::atan2(d[0], d[2]), phi = std::asin(std::max(-1.0, std::min(1.0, d[1])));
  const int col = std::min(ll.width - 1, std::max(0, int(std::floor(ll.width * (0.5 - lambda / (2 * kPi))))));
  const int row = std::min(ll.height - 1, std::max(0, int(std::floor(ll.height * (0.5 - phi / kPi)))));
  return size_t(row) * size_t(ll.width) + size_t(col);
}

// Mean |cube texel − lat-long texel in the same direction| over the cube, relative
// to the mean cube value (all channels), weighted by solid angle.
double relativeMismatch(const EnvMap& cube, const EnvMap& ll, bool mirror) {
  double diff = 0, sum = 0;
  for (size_t i = 0; i < cube.texelCount(); ++i) {
    double d[3], omega;
    texelDirection(cube, i, d, &omega);
    const size_t j = latLongTexelOf(ll, {d[0], d[1], d[2]}, mirror);
    for (int k = 0; k < 3; ++k) {
      diff += std::abs(double(cube.rgb[3 * i + k]) - ll.rgb[3 * j + k]) * omega;
      sum += cube.rgb[3 * i + k] * omega;
    }
  }
  return diff / sum;
}

// Runs f, which must throw InputError; returns its message.
template <class F>
std::string inputErrorOf(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  FAIL("no InputError thrown");
  return {};
}
}  // namespace

// ---------------------------------------------------------------- layouts

TEST_CASE("Face directories load in docs/conventions.md orientation from EXR, half EXR, PNG and HDR", "[env_load]") {
  const int n = 8;
  const std::string base = test::tempDir("env-faces");
  struct Variant {
    const char* name;
    const char* ext;
    std::function<void(const std::string&, const Picture&)> write;
    std::function<Dir(const float*)> decode;
    double tol;
  };
  const std::vector<Variant> variants = {
      {"exr", ".exr", [](const std::string& p, const Picture& pic) { writeExrPicture(p, pic); }, decodeFloat, kFloatDirTol},
      {"half", ".exr",
       [](const std::string& p, const Picture& pic) {
         ExrWriteOptions o;
         o.half = true;
         writeExrPicture(p, pic, o);
       },
       decodeFloat, kHalfDirTol},
      {"png", ".png", writePngPicture, decodePng, kPngDirTol},
      {"hdr", ".hdr", writeHdrPicture, decodeFloat, kRgbeDirTol},
  };
  for (const auto& v : variants) {
    INFO(v.name);
    const std::string dir = base + "/" + v.name;
    REQUIRE(::mkdir(dir.c_str(), 0755) == 0);
    writeFaceDir(dir, n, v.ext, v.write);
    const EnvMap env = loadEnvironment(dir);
    REQUIRE(env.layout == EnvLayout::Cube);
    REQUIRE(env.width == n);
    CHECK(env.layoutName == "faces");
    CHECK(env.source == dir);
    REQUIRE(env.inputFiles.size() == 6);
    CHECK(env.inputFiles[3] == dir + "/negy" + v.ext);
    CHECK(maxDirectionError(env, v.decode) < v.tol);
    // The same with the layout forced.
    EnvLoadOptions forced;
    forced.layout = "faces";
    CHECK(loadEnvironment(dir, forced).rgb == env.rgb);
    // Compact storage keeps 8-bit codes and halves; each texel decodes to exactly
    // the float the default load holds, and the kernel projects the same sums.
    EnvLoadOptions compact;
    compact.compact = true;
    const EnvMap small = loadEnvironment(dir, compact);
    const EnvStorage expected = v.ext == std::string(".png") ? EnvStorage::Code8
                                : std::string(v.name) == "half" ? EnvStorage::Half
                                                                : EnvStorage::Float;
    CHECK(small.storage() == expected);
    size_t mismatches = 0;
    for (size_t i = 0; i < env.texelCount(); ++i) {
      const auto t = small.texel(i);
      for (int c = 0; c < 3; ++c) mismatches += t[size_t(c)] != env.rgb[3 * i + size_t(c)];
    }
    CHECK(mismatches == 0);
    EnvProjectOptions po;
    po.order = 4;
    const ShCoeffs a = projectEnvironment(test::runtime(), env, po).coeffs;
    const ShCoeffs b = projectEnvironment(test::runtime(), small, po).coeffs;
    CHECK(a.rgb == b.rgb);
    EnvMap widened = small;
    widened.toFloat();
    CHECK(widened.rgb == env.rgb);
  }
}

TEST_CASE("The direction check fails for a face stored flipped", "[env_load]") {
  // The oracle must be able to fail: mirror posz left-right and the stored
  // directions no longer match texelDirection.
  const int n = 8;
  const std::string dir = test::tempDir("env-flipped");
  writeFaceDir(dir, n, ".exr", [](const std::string& p, const Picture& pic) { writeExrPicture(p, pic); });
  Picture p(n, n);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) p.set(n - 1 - c, r, designFaceDirection(4, r, c, n));
  writeExrPicture(dir + "/posz.exr", p);
  CHECK(maxDirectionError(loadEnvironment(dir), decodeFloat) > 0.5);
}

TEST_CASE("Crosses and strips load in docs/conventions.md orientation", "[env_load]") {
  const int n = 8;
  const std::string dir = test::tempDir("env-cross");
  struct Case {
    const char* name;
    Picture pic;
    const char* layoutName;
  };
  Picture vstrip(n, 6 * n), hstrip(6 * n, n);
  for (int f = 0; f < 6; ++f)
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) {
        vstrip.set(c, f * n + r, designFaceDirection(f, r, c, n));
        hstrip.set(f * n + c, r, designFaceDirection(f, r, c, n));
      }
  const std::vector<Case> cases = {
      {"hcross", crossPicture(n, kHorizontalCross, 4, 3), "cross"},
      {"vcross", crossPicture(n, kVerticalCross, 3, 4), "vertical-cross"},
      {"vstrip", vstrip, "strip"},
      {"hstrip", hstrip, "strip"},
  };
  for (const auto& c : cases) {
    INFO(c.name);
    const std::string path = dir + "/" + c.name + ".exr";
    writeExrPicture(path, c.pic);
    const EnvMap env = loadEnvironment(path);
    REQUIRE(env.layout == EnvLayout::Cube);
    REQUIRE(env.width == n);
    CHECK(env.layoutName == c.layoutName);
    CHECK(env.inputFiles == std::vector<std::string>{path});
    CHECK(maxDirectionError(env, decodeFloat) < kFloatDirTol);
  }
  // PNG crosses go through the same path (8-bit, sRGB).
  const std::string png = dir + "/hcross.png";
  writePngPicture(png, crossPicture(n, kHorizontalCross, 4, 3));
  EnvLoadOptions forced;
  forced.layout = "cross";
  CHECK(maxDirectionError(loadEnvironment(png, forced), decodePng) < kPngDirTol);
  forced.compact = true;
  const EnvMap codes = loadEnvironment(png, forced);
  CHECK(codes.storage() == EnvStorage::Code8);
  CHECK(maxDirectionError(codes, decodePng) < kPngDirTol);
}

TEST_CASE("Cross seams are continuous: texels along each shared image edge are one texel apart", "[env_load]") {
  // Each image pixel stores its own (x, y); after loading, every cube texel tells
  // which pixel it came from, so we know the direction of every pixel in a face
  // cell. Neighbouring pixels in different faces across a seam must be neighbours
  // on the sphere too. Texel centres half a texel either side of a cube edge are
  // at most one texel width 2/N apart in the face plane, so at most 2/N rad apart.
  const int n = 16;
  const double kSeamTol = 2.0 / n * 1.01;  // one texel width in the face plane, +1% slack
  const std::string dir = test::tempDir("env-seams");
  for (const bool horizontal : {true, false}) {
    INFO((horizontal ? "horizontal" : "vertical"));
    const int w = horizontal ? 4 * n : 3 * n, h = horizontal ? 3 * n : 4 * n;
    std::vector<float> x(size_t(w) * h), y(x.size()), one(x.size(), 1.0f);
    for (int r = 0; r < h; ++r)
      for (int c = 0; c < w; ++c) x[size_t(r) * w + c] = float(c), y[size_t(r) * w + c] = float(r);
    const std::string path = dir + (horizontal ? "/h.exr" : "/v.exr");
    writeExr(path, w, h, {{"R", x.data()}, {"G", y.data()}, {"B", one.data()}});
    const EnvMap env = loadEnvironment(path);
    REQUIRE(env.width == n);
    std::vector<int> faceOf(size_t(w) * h, -1);
    std::vector<Dir> dirOf(faceOf.size());
    for (size_t i = 0; i < env.texelCount(); ++i) {
      const size_t px = size_t(env.rgb[3 * i + 1]) * w + size_t(env.rgb[3 * i]);
      REQUIRE(faceOf[px] == -1);  // every face pixel used once
      faceOf[px] = int(i / (size_t(n) * n));
      dirOf[px] = texelDir(env, i);
    }
    int seamPairs = 0;
    for (int r = 0; r < h; ++r)
      for (int c = 0; c < w; ++c) {
        const size_t a = size_t(r) * w + c;
        if (faceOf[a] < 0) continue;
        for (const auto& [dr, dc] : {std::pair{0, 1}, std::pair{1, 0}}) {
          if (r + dr >= h || c + dc >= w) continue;
          const size_t b = size_t(r + dr) * w + c + dc;
          if (faceOf[b] < 0) continue;
          INFO("pixel (" << c << ", " << r << ") face " << faceOf[a] << " next to face " << faceOf[b]);
          if (faceOf[a] != faceOf[b]) ++seamPairs;
          REQUIRE(angleBetween(dirOf[a], dirOf[b]) <= kSeamTol);
        }
      }
    // A cross has five seams inside the image, each n pixel pairs long.
    CHECK(seamPairs == 5 * n);
  }
}

TEST_CASE("OpenEXR cube maps are re-indexed through ImfEnvmap.h", "[env_load]") {
  // The file is painted with OpenEXR's own direction of each pixel
  // (Imf::CubeMap::direction); our texel and its pixel differ only by the two
  // centre conventions: at most 1/N in face coordinates, so 1/N rad.
  for (const bool half : {false, true}) {
    const int n = 16;
    const double kConventionTol = 1.0 / n + (half ? kHalfDirTol : kFloatDirTol);
    const Imath::Box2i dw(Imath::V2i(0, 0), Imath::V2i(n - 1, 6 * n - 1));
    Picture p(n, 6 * n);
    for (int f = 0; f < 6; ++f)
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
          const Imath::V2f pif{float(i), float(j)};
          const Imath::V3f d = Imf::CubeMap::direction(Imf::CubeMapFace(f), dw, pif).normalized();
          const Imath::V2f pos = Imf::CubeMap::pixelPosition(Imf::CubeMapFace(f), dw, pif);
          p.set(int(std::lround(pos.x)), int(std::lround(pos.y)), {d.x, d.y, d.z});
        }
    const std::string path = test::tempDir("env-exrcube") + "/cube.exr";
    ExrWriteOptions opt;
    opt.envmap = 1;
    opt.half = half;
    writeExrPicture(path, p, opt);
    const EnvMap env = loadEnvironment(path);
    REQUIRE(env.layout == EnvLayout::Cube);
    REQUIRE(env.width == n);
    CHECK(env.layoutName == "openexr-cube");
    CHECK(maxDirectionError(env, decodeFloat) < kConventionTol);
    // And each face carries a constant marker: our face f is OpenEXR's face f.
    for (int f = 0; f < 6; ++f) {
      const Dir centre = texelDir(env, (size_t(f) * n + n / 2) * n + n / 2);
      const std::array<double, 3> axis = standardCubeBases()[size_t(f)].axisN;
      CHECK(angleBetween(centre, axis) < 1.5 / n);
    }
  }
}

TEST_CASE("Lat-long orientation agrees with Imf::LatLongMap up to the texel-centre convention", "[env_load]") {
  // OpenEXR puts pixel centres 0 and W−1 at longitude ±π (and rows 0, H−1 at the
  // poles); we put texel centres half a texel inside. The two differ by less than
  // one texel angle π/H on a W = 2H map.
  const int h = 32, w = 2 * h;
  const double kConventionTol = kPi / h;
  const Imath::Box2i dw(Imath::V2i(0, 0), Imath::V2i(w - 1, h - 1));
  Picture p(w, h);
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const Imath::V3f d = Imf::LatLongMap::direction(dw, Imath::V2f(float(c), float(r)));
      p.set(c, r, {d.x, d.y, d.z});
    }
  const std::string dir = test::tempDir("env-latlong");
  for (const int envmapAttr : {0, -1}) {  // with the envmap attribute, and found by the 2:1 shape
    const std::string path = dir + "/ll" + std::to_string(envmapAttr + 1) + ".exr";
    ExrWriteOptions opt;
    opt.envmap = envmapAttr;
    writeExrPicture(path, p, opt);
    const EnvMap env = loadEnvironment(path);
    REQUIRE(env.layout == EnvLayout::LatLong);
    REQUIRE(env.width == w);
    REQUIRE(env.height == h);
    CHECK(env.layoutName == "latlong");
    CHECK(maxDirectionError(env, decodeFloat) < kConventionTol);
  }
  {  // A half lat-long kept as halves (half rounding, 4.9e-4, is far inside the tolerance).
    const std::string path = dir + "/half.exr";
    ExrWriteOptions opt;
    opt.half = true;
    writeExrPicture(path, p, opt);
    EnvLoadOptions compact;
    compact.compact = true;
    const EnvMap env = loadEnvironment(path, compact);
    CHECK(env.storage() == EnvStorage::Half);
    CHECK(maxDirectionError(env, decodeFloat) < kConventionTol);
  }
  // A few landmarks, by hand: the centre column looks along +Z, a quarter to the
  // left along +X, row 0 near +Y.
  EnvMap ll;
  ll.layout = EnvLayout::LatLong;
  ll.width = w, ll.height = h;
  const double kLandmarkTol = kPi / h;  // half a texel in each of λ and φ
  CHECK(angleBetween(texelDir(ll, size_t(h / 2) * w + w / 2), {0, 0, 1}) < kLandmarkTol);
  CHECK(angleBetween(texelDir(ll, size_t(h / 2) * w + w / 4), {1, 0, 0}) < kLandmarkTol);
  CHECK(texelDir(ll, 0)[1] > std::cos(kPi / h));
  const Imath::V3f exrLeft = Imf::LatLongMap::direction(dw, Imath::V2f(float(w / 4), float(h / 2)));
  CHECK(angleBetween({exrLeft.x, exrLeft.y, exrLeft.z}, {1, 0, 0}) < kLandmarkTol);
}

TEST_CASE("Tiled mip-mapped OpenEXR with an offset data window loads level 0", "[env_load]") {
  // Level 0 holds the direction code, the coarser levels hold garbage (7), and
  // the data window starts at (5, −3).
  const int h = 8, w = 16;
  const Imath::Box2i dw(Imath::V2i(5, -3), Imath::V2i(5 + w - 1, -3 + h - 1));
  const std::string path = test::tempDir("env-tiled") + "/tiled.exr";
  {
    Imf::Header header(dw, dw);
    header.setTileDescription(Imf::TileDescription(4, 4, Imf::MIPMAP_LEVELS));
    for (const char* c : {"R", "G", "B"}) header.channels().insert(c, Imf::Channel(Imf::FLOAT));
    Imf::TiledOutputFile out(path.c_str(), header);
    for (int level = 0; level < out.numLevels(); ++level) {
      const Imath::Box2i lw = out.dataWindowForLevel(level);
      const int lwid = lw.max.x - lw.min.x + 1, lhei = lw.max.y - lw.min.y + 1;
      std::vector<float> px(3 * size_t(lwid) * lhei, 7.0f);
      if (level == 0) {
        EnvMap ll;
        ll.layout = EnvLayout::LatLong;
        ll.width = w, ll.height = h;
        for (size_t i = 0; i < ll.texelCount(); ++i) {
          const Dir d = texelDir(ll, i);
          for (int k = 0; k < 3; ++k) px[3 * i + k] = float(1.0 + d[k]);
        }
      }
      Imf::FrameBuffer fb;
      for (int k = 0; k < 3; ++k)
        fb.insert(k == 0 ? "R" : k == 1 ? "G" : "B",
                  Imf::Slice::Make(Imf::FLOAT, px.data() + k, lw, 3 * sizeof(float), 3 * sizeof(float) * lwid));
      out.setFrameBuffer(fb);
      out.writeTiles(0, out.numXTiles(level) - 1, 0, out.numYTiles(level) - 1, level);
    }
  }
  const EnvMap env = loadEnvironment(path);
  REQUIRE(env.width == w);
  REQUIRE(env.height == h);
  CHECK(maxDirectionError(env, decodeFloat) < kFloatDirTol);
}

TEST_CASE("Grey (Y) and luminance/chroma OpenEXR files become RGB", "[env_load]") {
  const int h = 8, w = 16;
  const std::string dir = test::tempDir("env-yc");
  std::vector<float> y(size_t(w) * h);
  for (size_t i = 0; i < y.size(); ++i) y[i] = 0.1f * float(i);
  writeExr(dir + "/grey.exr", w, h, {{"Y", y.data()}});
  const EnvMap g = loadEnvironment(dir + "/grey.exr");
  for (size_t i = 0; i < y.size(); ++i)
    for (int k = 0; k < 3; ++k) REQUIRE(g.rgb[3 * i + k] == y[i]);
  // A constant colour through Y, RY, BY (chroma subsampled 2×2, stored in half).
  // The RGB → YC → RGB round trip in half precision: within 1%.
  const double kYcRelTol = 1e-2;
  {
    std::vector<Imf::Rgba> px(size_t(w) * h, Imf::Rgba(0.25f, 0.5f, 1.0f, 1.0f));
    Imf::RgbaOutputFile out((dir + "/yc.exr").c_str(), w, h, Imf::WRITE_YC);
    out.setFrameBuffer(px.data(), 1, size_t(w));
    out.writePixels(h);
  }
  const EnvMap c = loadEnvironment(dir + "/yc.exr");
  const double want[3] = {0.25, 0.5, 1.0};
  for (size_t i = 0; i < c.texelCount(); ++i)
    for (int k = 0; k < 3; ++k) REQUIRE(std::abs(c.rgb[3 * i + k] - want[k]) < kYcRelTol * want[k]);
}

TEST_CASE("Lat-long OpenEXR files read in bands give the whole map's texels, checks and coefficients", "[env_load]") {
  const std::string dir = test::tempDir("env-bands");
  const int w = 64, h = 32;
  std::vector<float> r(size_t(w) * h), g(r.size()), b(r.size());
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const size_t i = size_t(y) * w + size_t(x);
      r[i] = 1.0f + std::sin(0.3f * float(x)) * 0.5f, g[i] = 0.2f + 0.05f * float(y), b[i] = 0.5f + 0.01f * float(x + y);
    }
  r[5 * w + 7] = g[5 * w + 7] = b[5 * w + 7] = 1e4f;  // a sun
  ExrWriteOptions latlong;
  latlong.envmap = 0;
  writeExr(dir + "/ll.exr", w, h, {{"R", r.data()}, {"G", g.data()}, {"B", b.data()}}, latlong);
  latlong.half = true;
  writeExr(dir + "/half.exr", w, h, {{"R", r.data()}, {"G", g.data()}, {"B", b.data()}}, latlong);
  writeExr(dir + "/grey.exr", w, h, {{"Y", r.data()}});  // no envmap attribute: lat-long by its shape
  std::vector<float> bad = r;
  bad[3] = std::numeric_limits<float>::quiet_NaN(), bad[100] = -1.0f, bad[size_t(w) * h - 1] = INFINITY;
  writeExr(dir + "/bad.exr", w, h, {{"R", bad.data()}, {"G", g.data()}, {"B", b.data()}});

  // Bands of 5 rows: 7 bands, the last of 2 rows.
  const size_t fiveRows = 12 * size_t(w) * 5;
  auto banded = [&](const std::string& path, const EnvLoadOptions& lo) {
    EnvMap all;
    std::vector<int> firsts;
    REQUIRE(forEachLatLongBand(
        path, lo, fiveRows,
        [&](EnvMap& band, int first) {
          firsts.push_back(first);
          all.rgb.insert(all.rgb.end(), band.rgb.begin(), band.rgb.end());
          all.halfRgb.insert(all.halfRgb.end(), band.halfRgb.begin(), band.halfRgb.end());
        },
        &all));
    CHECK(firsts == std::vector<int>{0, 5, 10, 15, 20, 25, 30});
    return all;
  };
  EnvProjectOptions po;
  po.order = 4;
  const double yaw = 30.0;
  for (const std::string name : {"ll.exr", "half.exr", "grey.exr", "bad.exr"})
    for (const bool compact : {false, true}) {
      INFO(name << (compact ? " compact" : ""));
      EnvLoadOptions lo;
      lo.compact = compact;
      lo.clampInvalid = name == "bad.exr";
      const EnvMap whole = loadEnvironment(dir + "/" + name, lo);
      const EnvMap parts = banded(dir + "/" + name, lo);
      CHECK(parts.width == whole.width);
      CHECK(parts.height == whole.height);
      CHECK(parts.layoutName == whole.layoutName);
      CHECK(parts.clampedTexels == whole.clampedTexels);
      REQUIRE(parts.storage() == whole.storage());
      CHECK(std::vector<float>(parts.rgb.begin(), parts.rgb.end()) == std::vector<float>(whole.rgb.begin(), whole.rgb.end()));
      CHECK(std::vector<uint16_t>(parts.halfRgb.begin(), parts.halfRgb.end()) ==
            std::vector<uint16_t>(whole.halfRgb.begin(), whole.halfRgb.end()));
      // The projection, band by band and whole: the same bits (row sums added in row order).
      EnvMap rotated = whole, description;
      rotated.yawDegrees = yaw;
      const ShCoeffs a = projectEnvironment(test::runtime(), rotated, po).radiance;
      const ShCoeffs c = projectEnvironmentFile(test::runtime, dir + "/" + name, lo, yaw, po, &description, fiveRows).radiance;
      CHECK(description.texelCount() == whole.texelCount());
      CHECK(description.rgb.empty());
      CHECK(a.rgb == c.rgb);
    }
  // Invalid values without the clamp option: the whole map's count, in the same words.
  std::string wholeError, bandError;
  try {
    loadEnvironment(dir + "/bad.exr");
  } catch (const InputError& e) {
    wholeError = e.what();
  }
  EnvMap header;
  CHECK_THROWS_AS(forEachLatLongBand(dir + "/bad.exr", {}, fiveRows, [](EnvMap&, int) {}, &header), InputError);
  try {
    EnvMap description;
    projectEnvironmentFile(test::runtime, dir + "/bad.exr", {}, 0.0, po, &description, fiveRows);
  } catch (const InputError& e) {
    bandError = e.what();
  }
  CHECK_THAT(wholeError, Catch::Contains("3 invalid values (2 NaN/Inf, 1 negative)"));
  CHECK(bandError == wholeError);
  // Other maps are not read in bands.
  const std::vector<float> cross(size_t(4 * 8) * 3 * 8 * 3, 1.0f);
  REQUIRE(stbi_write_hdr((dir + "/ll.hdr").c_str(), w, h, 3, cross.data()) != 0);
  writeExr(dir + "/cross.exr", 32, 24, {{"R", cross.data()}});
  EnvLoadOptions forced;
  forced.layout = "cross";
  int calls = 0;
  auto count = [&](EnvMap&, int) { ++calls; };
  CHECK_FALSE(forEachLatLongBand(dir + "/ll.hdr", {}, fiveRows, count, &header));
  CHECK_FALSE(forEachLatLongBand(dir + "/cross.exr", {}, fiveRows, count, &header));
  CHECK_FALSE(forEachLatLongBand(dir + "/ll.exr", forced, fiveRows, count, &header));
  CHECK(calls == 0);
}

TEST_CASE("8-bit images use the exact sRGB EOTF, grey and alpha become RGB", "[env_load]") {
  const int h = 16, w = 32;
  const std::string dir = test::tempDir("env-srgb");
  std::vector<unsigned char> grey(size_t(w) * h), rgba(4 * size_t(w) * h);
  for (size_t i = 0; i < grey.size(); ++i) {
    grey[i] = (unsigned char)(i % 256);
    for (int k = 0; k < 3; ++k) rgba[4 * i + k] = (unsigned char)((i + 85 * k) % 256);
    rgba[4 * i + 3] = (unsigned char)(i * 7 % 256);
  }
  REQUIRE(stbi_write_png((dir + "/grey.png").c_str(), w, h, 1, grey.data(), w) != 0);
  REQUIRE(stbi_write_png((dir + "/rgba.png").c_str(), w, h, 4, rgba.data(), 4 * w) != 0);
  auto srgb = [](int code) {
    const double c = code / 255.0;
    return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
  };
  const EnvMap g = loadEnvironment(dir + "/grey.png");
  REQUIRE(g.layout == EnvLayout::LatLong);
  for (size_t i = 0; i < grey.size(); ++i)
    for (int k = 0; k < 3; ++k) REQUIRE(std::abs(g.rgb[3 * i + k] - srgb(grey[i])) < kSrgbTol);
  const EnvMap c = loadEnvironment(dir + "/rgba.png");
  for (size_t i = 0; i < grey.size(); ++i)
    for (int k = 0; k < 3; ++k) REQUIRE(std::abs(c.rgb[3 * i + k] - srgb(rgba[4 * i + k])) < kSrgbTol);
  // Not stbi_loadf's 2.2 gamma: at code 128 the two differ by 3.7e-3.
  CHECK(std::abs(g.rgb[3 * 128] - std::pow(128 / 255.0, 2.2)) > 3e-3);
  CHECK(detail::srgbToLinear(1.0) == 1.0);
}

TEST_CASE("The games202 preset reproduces the framework's face order, table and 2.2 gamma", "[env_load]") {
  // Each file is a constant code (10·(k + 1) for the file of face k in
  // docs/conventions.md "Cube faces") so we can see which file landed in which face.
  const int n = 4;
  const std::string dir = test::tempDir("env-g202");
  for (int f = 0; f < 6; ++f) {
    std::vector<unsigned char> px(3 * n * n, (unsigned char)(10 * (f + 1)));
    REQUIRE(stbi_write_png((dir + "/" + kFaceNames[f] + ".png").c_str(), n, n, 3, px.data(), 3 * n) != 0);
  }
  EnvLoadOptions opt;
  opt.layout = "games202";
  const EnvMap env = loadEnvironment(dir, opt);
  CHECK(env.layoutName == "games202");
  REQUIRE(env.width == n);
  // Load order negx, posx, posy, negy, posz, negz = docs/conventions.md face indices 1, 0, 2, 3, 4, 5.
  const int fileOfFace[6] = {1, 0, 2, 3, 4, 5};
  const double kGammaTol = 1e-6;  // pow in double, stored as float
  for (int k = 0; k < 6; ++k) {
    INFO("face " << k);
    CHECK(env.inputFiles[size_t(k)] == dir + "/" + kFaceNames[fileOfFace[k]] + ".png");
    const double want = std::pow(10.0 * (fileOfFace[k] + 1) / 255.0, 2.2);
    CHECK(std::abs(env.rgb[3 * size_t(k) * n * n] - want) < kGammaTol);
  }
  // Directions: docs/conventions.md "GAMES202 compatibility" table, (X; Y; Z) per load index,
  // u from the column, v from the row. Same formula in double on both sides: a few ulps.
  const double kSameFormulaTol = 1e-14;
  const double table[6][3][3] = {
      {{0, 0, 1}, {0, -1, 0}, {-1, 0, 0}}, {{0, 0, 1}, {0, -1, 0}, {1, 0, 0}},
      {{1, 0, 0}, {0, 0, -1}, {0, -1, 0}}, {{1, 0, 0}, {0, 0, 1}, {0, 1, 0}},
      {{-1, 0, 0}, {0, -1, 0}, {0, 0, -1}}, {{1, 0, 0}, {0, -1, 0}, {0, 0, 1}},
  };
  for (int k = 0; k < 6; ++k)
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) {
        const double u = 2.0 * (c + 0.5) / n - 1, v = 2.0 * (r + 0.5) / n - 1;
        const Dir want = normalized(table[k][0][0] * u + table[k][1][0] * v + table[k][2][0],
                                    table[k][0][1] * u + table[k][1][1] * v + table[k][2][1],
                                    table[k][0][2] * u + table[k][1][2] * v + table[k][2][2]);
        const Dir got = texelDir(env, (size_t(k) * n + r) * n + c);
        for (int i = 0; i < 3; ++i) CHECK(std::abs(got[i] - want[i]) < kSameFormulaTol);
      }
}

// ---------------------------------------------------------------- real files

TEST_CASE("OpenEXR Cube and LatLong pairs describe the same environment", "[env_load][data]") {
  // The openexr-images authors made each pair from one scene. Weighted by solid
  // angle, the mean radiance of the two agrees within resampling error (the cube
  // and lat-long grids filter the scene differently): 3%. The radiance-weighted
  // mean direction of each channel must agree too, which checks the orientation of
  // both mappings against each other: within 1° (a face turned by 90° or a mirrored
  // longitude moves it by tens of degrees). Channels whose moment is under 2% of
  // their integral (|Σ L d Ω| < 0.02 Σ L Ω: nearly uniform) carry no direction.
  const double kMeanRelTol = 0.03;
  const double kMomentAngleTol = 1.0 * kPi / 180.0;
  const double kMinMoment = 0.02;
  int momentsCompared = 0;
  for (const char* scene : {"KernerEnv", "Orientation", "StageEnv", "WavyLines"}) {
    INFO(scene);
    const std::string cubePath = test::dataFile(std::string("envmaps/openexr/") + scene + "Cube.exr");
    const std::string llPath = test::dataFile(std::string("envmaps/openexr/") + scene + "LatLong.exr");
    PRTBAKE_SKIP_IF_NO_DATA(cubePath);
    PRTBAKE_SKIP_IF_NO_DATA(llPath);
    const EnvMap cube = loadEnvironment(cubePath), ll = loadEnvironment(llPath);
    CHECK(cube.layoutName == "openexr-cube");
    CHECK(ll.layoutName == "latlong");
    CHECK(cube.width >= 16);
    CHECK(ll.width == 2 * ll.height);
    const auto a = integrate(cube), b = integrate(ll);
    CHECK(a[3] == Approx(4 * kPi).epsilon(1e-9));
    CHECK(b[3] == Approx(4 * kPi).epsilon(1e-9));
    for (int k = 0; k < 3; ++k) {
      INFO("channel " << k << ": cube " << a[k] / a[3] << " lat-long " << b[k] / b[3]);
      CHECK(std::abs(a[k] / a[3] - b[k] / b[3]) <= kMeanRelTol * (b[k] / b[3]));
    }
    for (int k = 0; k < 3; ++k) {
      const Dir ma = firstMoment(cube, k), mb = firstMoment(ll, k);
      const double lenA = length(ma), lenB = length(mb);
      INFO("channel " << k << " moments: cube (" << ma[0] << ", " << ma[1] << ", " << ma[2] << ") lat-long ("
                      << mb[0] << ", " << mb[1] << ", " << mb[2] << ")");
      // The direction is only meaningful where the channel is far from uniform.
      if (lenB < kMinMoment * b[k]) continue;
      ++momentsCompared;
      CHECK(angleBetween({ma[0] / lenA, ma[1] / lenA, ma[2] / lenA}, {mb[0] / lenB, mb[1] / lenB, mb[2] / lenB}) <
            kMomentAngleTol);
    }
  }
  CHECK(momentsCompared >= 6);
}

TEST_CASE("OpenEXR Cube and LatLong pairs agree texel by texel in the same direction", "[env_load][data]") {
  // Each cube texel against the lat-long texel holding its direction (nearest, no
  // filtering). The grids differ, so sharp detail (WavyLines' thin lines, Kerner's
  // window frames) leaves a residual: 0.02 to 0.19 of the mean radiance on these
  // files. A mirrored longitude is at least 2.4 times worse on every pair (1.0 and
  // 1.7 on the photographs), so the check can fail.
  const double kTexelMismatchTol = 0.25;
  const double kMirroredFactor = 2.0;
  for (const char* scene : {"KernerEnv", "Orientation", "StageEnv", "WavyLines"}) {
    INFO(scene);
    const std::string cubePath = test::dataFile(std::string("envmaps/openexr/") + scene + "Cube.exr");
    const std::string llPath = test::dataFile(std::string("envmaps/openexr/") + scene + "LatLong.exr");
    PRTBAKE_SKIP_IF_NO_DATA(cubePath);
    PRTBAKE_SKIP_IF_NO_DATA(llPath);
    const EnvMap cube = loadEnvironment(cubePath), ll = loadEnvironment(llPath);
    const double good = relativeMismatch(cube, ll, false), mirrored = relativeMismatch(cube, ll, true);
    INFO("mismatch " << good << ", with the longitude mirrored " << mirrored);
    CHECK(good < kTexelMismatchTol);
    CHECK(mirrored > kMirroredFactor * good);
  }
}

TEST_CASE("GAMES202 faces load with the games202 preset and as plain faces", "[env_load][data]") {
  for (const char* scene : {"CornellBox", "GraceCathedral", "Indoor", "Skybox"}) {
    INFO(scene);
    const std::string dir = test::dataFile(std::string("envmaps/games202/") + scene);
    PRTBAKE_SKIP_IF_NO_DATA(dir);
    EnvLoadOptions g;
    g.layout = "games202";
    const EnvMap a = loadEnvironment(dir, g), b = loadEnvironment(dir);
    CHECK(a.layoutName == "games202");
    CHECK(b.layoutName == "faces");
    REQUIRE(a.width == b.width);
    CHECK(a.width >= 128);
    REQUIRE(a.inputFiles.size() == 6);
    CHECK(a.inputFiles[0] == dir + "/negx.jpg");
    // Same decoded codes, two transfer functions: games202 face 1 (posx) is faces'
    // face 0 with (c/255)^2.2 instead of sRGB. Recover c from the sRGB value.
    const double kCodeTol = 1e-3;  // the code recovered through float sRGB is within 1e-3 of an integer
    const size_t nn = size_t(a.width) * a.width;
    for (size_t i = 0; i < nn; i += 97) {
      const double code = 255.0 * linearToSrgb(b.rgb[3 * i]);
      REQUIRE(std::abs(code - std::round(code)) < kCodeTol);
      REQUIRE(std::abs(a.rgb[3 * (nn + i)] - std::pow(std::round(code) / 255.0, 2.2)) < 1e-6);
    }
  }
}

TEST_CASE("Radiance .hdr and the Grace lat-long load", "[env_load][data]") {
  for (const char* name : {"studio_small_03_1k.hdr", "venice_sunset_1k.hdr", "potsdamer_platz_1k.hdr",
                           "grace_latlong.exr"}) {
    INFO(name);
    const std::string path = test::dataFile(std::string("envmaps/hdr/") + name);
    PRTBAKE_SKIP_IF_NO_DATA(path);
    const EnvMap env = loadEnvironment(path);
    CHECK(env.layout == EnvLayout::LatLong);
    CHECK(env.width == 1024);
    CHECK(env.height == 512);
    const auto s = integrate(env);
    for (int k = 0; k < 3; ++k) CHECK(s[k] > 0.0);
  }
}

// ---------------------------------------------------------------- bad input

TEST_CASE("A header that claims more than its file can hold is refused from the header and the size", "[env_load][bounds]") {
  // Each file below is a few hundred bytes to a few KiB whose header claims an image of tens
  // of millions of pixels. `prtbake env` must refuse it before anything of the image's size
  // is allocated: within kSeconds and kPeakMiB (the whole process: its libraries take about
  // 10 MiB; the first case, the one fuzzing found, took 2.35 GB and 3.5 s before the
  // Radiance header check), naming the file and the shortfall. Each message is the check's
  // own, so each case fails without its check.
  // Under AddressSanitizer the executable alone takes 0.4-0.5 s to start and exit (`prtbake
  // --version`: 0.48-0.49 s, the refusals 0.50-0.57 s on a quiet machine, 0.68 s once in CI)
  // and holds its shadow memory (test_jobs.cpp measures the same): there the sanitized build
  // checks memory errors, the release build the time and the peak.
#if defined(__SANITIZE_ADDRESS__)
  constexpr double kSeconds = 0.1 + 1.0, kPeakMiB = 64 + 192;
#else
  constexpr double kSeconds = 0.1, kPeakMiB = 64;
#endif
  const std::string dir = test::tempDir("env-bounds");
  struct Case {
    std::string name, bytes, message;
  };
  std::vector<Case> cases;
  auto be32 = [](uint32_t v) { return std::string{char(v >> 24), char(v >> 16 & 255), char(v >> 8 & 255), char(v & 255)}; };
  auto binary = [](size_t n) {
    std::string b(n, '\0');
    for (size_t i = 0; i < n; ++i) b[i] = char((i * 37 + 11) % 251 + 1);  // no newline (10) before byte 251 or so
    for (char& c : b) c = c == '\n' ? '\x0b' : c;
    return b;
  };
  // The fuzzing finding: 50,000 x 2,000 pixels, the resolution line not ended by a newline.
  cases.push_back({"resolution.hdr", "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 050000 +X 2000@" + binary(500),
                   "cannot decode Radiance HDR image: the resolution line (-Y 050000 +X 2000@) is not ended by a newline"});
  // A proper resolution line over 500 bytes of run-length scanlines: 6.6 MB are the least.
  cases.push_back({"short.hdr", "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 50000 +X 2000\n" + binary(500),
                   "cannot decode Radiance HDR image: truncated: a 2000x50000 image needs at least 6600000 bytes"});
  // Flat pixels (width below 8): 4 bytes each.
  cases.push_back({"flat.hdr", "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 10000000 +X 4\n" + binary(500),
                   "cannot decode Radiance HDR image: truncated: a 4x10000000 image needs at least 160000000 bytes"});
  // PNG: 8192 x 4096 RGB behind 200 bytes of IDAT (100 MB of rows; deflate reaches 206 KB).
  auto chunk = [&](const std::string& type, const std::string& data) { return be32(uint32_t(data.size())) + type + data + std::string(4, '\0'); };
  const std::string png = std::string("\x89PNG\r\n\x1a\n", 8) + chunk("IHDR", be32(8192) + be32(4096) + std::string("\x08\x02\0\0\0", 5));
  cases.push_back({"small-idat.png", png + chunk("IDAT", "x^" + binary(198)) + chunk("IEND", ""),
                   "cannot decode image: truncated: its 200 bytes of image data cannot hold a 8192x4096 image of 24 bits a pixel"});
  // JPEG: a baseline frame of 8192 x 4096 (524,288 blocks: at least 64 KiB of scan data).
  std::vector<unsigned char> rgb(3 * 16 * 16, 90);
  const std::string small = dir + "/small.jpg";
  REQUIRE(stbi_write_jpg(small.c_str(), 16, 16, 3, rgb.data(), 90) != 0);
  std::string jpg = readBytes(small);
  const size_t sof = jpg.find("\xff\xc0");
  REQUIRE(sof != std::string::npos);
  jpg.replace(sof + 5, 4, std::string{'\x10', '\x00', '\x20', '\x00'});  // height 4096, width 8192
  cases.push_back({"frame.jpg", jpg,
                   "cannot decode image: truncated: its 6 bytes of entropy-coded data cannot hold a 8192x4096 image"});
  // OpenEXR: a tiled file (no line offset table to check) and a scanline file whose offset
  // table fits, each claiming 16384 x 8192 float RGB (1.5 GiB) in a few KiB.
  Picture pic(64, 32);
  for (int r = 0; r < 32; ++r)
    for (int c = 0; c < 64; ++c) pic.set(c, r, normalized(1, 0.1 * r, 0.05 * c));
  auto claimWindow = [&](const std::string& path, int width, int height) {
    std::string bytes = readBytes(path);
    const std::string attr("dataWindow\0box2i\0", 17);
    const size_t at = bytes.find(attr);
    REQUIRE(at != std::string::npos);
    const int32_t box[4] = {0, 0, width - 1, height - 1};
    bytes.replace(at + attr.size() + 4, 16, std::string(reinterpret_cast<const char*>(box), 16));
    return bytes;
  };
  {
    const std::string tiled = dir + "/tiled.exr";
    Imf::Header header(64, 32);
    header.compression() = Imf::ZIP_COMPRESSION;
    header.setTileDescription(Imf::TileDescription(32, 32, Imf::ONE_LEVEL));
    for (const char* c : {"R", "G", "B"}) header.channels().insert(c, Imf::Channel(Imf::FLOAT));
    Imf::TiledOutputFile out(tiled.c_str(), header);
    Imf::FrameBuffer fb;
    for (int k = 0; k < 3; ++k)
      fb.insert(std::string(1, "RGB"[k]),
                Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(&pic.rgb[size_t(k)]), 3 * sizeof(float), 3 * sizeof(float) * 64));
    out.setFrameBuffer(fb);
    out.writeTiles(0, out.numXTiles() - 1, 0, out.numYTiles() - 1);
  }
  REQUIRE(loadEnvironment(dir + "/tiled.exr", EnvLoadOptions{}).width == 64);
  cases.push_back({"tiled.exr", claimWindow(dir + "/tiled.exr", 16384, 8192),
                   "truncated OpenEXR file: its 16384x8192 data window holds 1610612736 bytes of pixels"});
  writeExrPicture(dir + "/lines.exr", pic);
  // ZIP: 16 lines a chunk, 512 chunks: a table of 4 KiB, padded so that it fits.
  cases.push_back({"lines.exr", claimWindow(dir + "/lines.exr", 16384, 8192) + binary(8192),
                   "truncated OpenEXR file: its 16384x8192 data window holds 1610612736 bytes of pixels"});
  for (const Case& c : cases) {
    const std::string p = dir + "/" + c.name;
    writeBytes(p, c.bytes);
    const test::MeasuredRun run = test::runCliMeasured({"env", p, "-o", dir + "/out.json"}, dir + "/log.txt");
    INFO(c.name << " (" << c.bytes.size() << " bytes): " << run.output << " in " << run.seconds << " s, peak "
                << run.peakMiB << " MiB");
    CHECK(run.exitCode == 1);
    CHECK(run.output.rfind("prtbake: error: " + p + ": " + c.message, 0) == 0);
    CHECK(std::count(run.output.begin(), run.output.end(), '\n') == 1);
    CHECK(run.seconds < kSeconds);
    CHECK(run.peakMiB < kPeakMiB);
    CHECK_FALSE(test::fileExists(dir + "/out.json"));
  }
}

TEST_CASE("Bad input is an InputError naming the file", "[env_load]") {
  const std::string dir = test::tempDir("env-bad");
  auto load = [](const std::string& p, const std::string& layout = "auto", bool clamp = false) {
    EnvLoadOptions o;
    o.layout = layout;
    o.clampInvalid = clamp;
    return loadEnvironment(p, o);
  };
  Picture good(16, 8);
  for (int r = 0; r < 8; ++r)
    for (int c = 0; c < 16; ++c) good.set(c, r, normalized(std::sin(r * 3.1 + c), std::cos(c * 1.3), 0.2 * r));

  SECTION("missing file or directory") {
    const std::string p = dir + "/nope.exr";
    CHECK(inputErrorOf([&] { load(p); }) == p + ": cannot open: No such file or directory");
  }
  SECTION("truncated OpenEXR") {
    const std::string p = dir + "/trunc.exr";
    writeExrPicture(p, good);
    const std::string bytes = readBytes(p);
    for (const size_t keep : {bytes.size() * 3 / 4, bytes.size() / 2, size_t(40)}) {
      writeBytes(p, bytes.substr(0, keep));
      const std::string msg = inputErrorOf([&] { load(p); });
      CHECK(msg.rfind(p + ": ", 0) == 0);
    }
  }
  SECTION("OpenEXR header values whose size field disagrees with their content") {
    // The library reads a channel list or a fixed-size value by its content; a size field
    // one byte off makes it read later bytes as lengths (a fuzzing finding took 14 s in a
    // 1.6 GB string). Each edit below is refused before the library runs; the unedited
    // file loads.
    const std::string p = dir + "/sizes.exr";
    writeExrPicture(p, good);
    const std::string bytes = readBytes(p);
    REQUIRE(load(p).width == 16);
    auto sizeFieldAfter = [&](const std::string& nameAndType) {
      const size_t at = bytes.find(nameAndType);
      REQUIRE(at != std::string::npos);
      return at + nameAndType.size();
    };
    for (const std::string& attr : {std::string("channels\0chlist\0", 16), std::string("dataWindow\0box2i\0", 17)}) {
      for (const int delta : {-1, +1}) {
        std::string edited = bytes;
        edited[sizeFieldAfter(attr)] = char(uint8_t(edited[sizeFieldAfter(attr)]) + delta);
        writeBytes(p, edited);
        const std::string msg = inputErrorOf([&] { load(p); });
        INFO(attr.substr(0, attr.find('\0')) << " " << delta << ": " << msg);
        CHECK(msg.rfind(p + ": corrupt OpenEXR header", 0) == 0);
      }
    }
  }
  SECTION("garbage JPG, PNG, HDR and an empty file") {
    const std::string garbage = "\xff\xd8\xff\xe0 this is not really a JPEG at all, just some bytes";
    writeBytes(dir + "/bad.jpg", garbage);
    writeBytes(dir + "/bad.png", std::string("\x89PNG\r\n\x1a\n", 8) + "broken chunk data");
    writeBytes(dir + "/bad.hdr", "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 8 +X 16\n\x02\x02");
    writeBytes(dir + "/empty.hdr", "");
    for (const char* name : {"bad.jpg", "bad.png", "bad.hdr", "empty.hdr"}) {
      const std::string p = dir + "/" + name;
      const std::string msg = inputErrorOf([&] { load(p); });
      INFO(msg);
      CHECK(msg.rfind(p + ": cannot decode", 0) == 0);
    }
  }
  SECTION("truncated HDR, PNG and JPG; an HDR run of length 0 (stb_image would loop forever)") {
    std::vector<float> hdr(3 * 64 * 32);
    std::vector<unsigned char> ldr(3 * 64 * 32);
    for (size_t i = 0; i < hdr.size(); ++i) {
      hdr[i] = float(1.0 + std::sin(0.37 * double(i)));
      ldr[i] = (unsigned char)(i * 31 % 251);
    }
    REQUIRE(stbi_write_hdr((dir + "/t.hdr").c_str(), 64, 32, 3, hdr.data()) != 0);
    REQUIRE(stbi_write_png((dir + "/t.png").c_str(), 64, 32, 3, ldr.data(), 3 * 64) != 0);
    REQUIRE(stbi_write_jpg((dir + "/t.jpg").c_str(), 64, 32, 3, ldr.data(), 90) != 0);
    for (const char* name : {"t.hdr", "t.png", "t.jpg"}) {
      const std::string p = dir + "/" + name;
      const std::string bytes = readBytes(p);
      REQUIRE(load(p).width == 64);
      writeBytes(p, bytes.substr(0, bytes.size() / 2));
      const std::string msg = inputErrorOf([&] { load(p); });
      INFO(msg);
      CHECK(msg.rfind(p + ": cannot decode", 0) == 0);
    }
    const std::string p = dir + "/zero-run.hdr";
    // One 8-pixel RLE scanline (2, 2, width 0x0008) whose first count is 0.
    writeBytes(p, std::string("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 8\n") +
                      std::string{'\x02', '\x02', '\x00', '\x08', '\x00'} + std::string(40, '\x81'));
    CHECK(inputErrorOf([&] { load(p, "latlong"); }).find("a run of length 0") != std::string::npos);
  }
  SECTION("data that claims more than its image needs: a 1 GiB PNG chunk, a deflate bomb, a JPEG Huffman table; a BMP") {
    // Chunks by hand: length, type, data, and a CRC of zeros (stb_image does not check it).
    auto chunk = [](const std::string& type, const std::string& data, uint32_t length) {
      const std::string len{char(length >> 24), char(length >> 16 & 255), char(length >> 8 & 255), char(length & 255)};
      return len + type + data + std::string(4, '\0');
    };
    // 32x16 (a lat-long map), 8-bit RGB, not interlaced: 1568 bytes of filtered rows.
    const std::string png = std::string("\x89PNG\r\n\x1a\n", 8) +
                            chunk("IHDR", std::string("\0\0\0\x20\0\0\0\x10\x08\x02\0\0\0", 13), 13);
    const std::string p = dir + "/claims.png";
    // An IDAT chunk that says 1 GiB follows in a 70-byte file: stb allocated that much first.
    writeBytes(p, png + chunk("IDAT", "x^", 1u << 30));
    std::string msg = inputErrorOf([&] { load(p); });
    INFO(msg);
    CHECK(msg.rfind(p + ": cannot decode image: its data asks for a block of 1073741824 bytes", 0) == 0);
    // 16 MiB of zeros deflated (~16 KB) behind the same header: stb doubled its buffer
    // up to 16 MiB and then decoded the first 1568 bytes. Refused at the first block past
    // the bound (16 * 64 * 48 + 1 MiB + twice the file, about 1.1 MB).
    std::vector<unsigned char> zeros(16 << 20);
    int zlen = 0;
    unsigned char* z = stbi_zlib_compress(zeros.data(), int(zeros.size()), &zlen, 8);
    REQUIRE(z);
    const std::string idat(reinterpret_cast<const char*>(z), size_t(zlen));
    std::free(z);
    writeBytes(p, png + chunk("IDAT", idat, uint32_t(idat.size())) + chunk("IEND", "", 0));
    msg = inputErrorOf([&] { load(p); });
    CHECK(msg.rfind(p + ": cannot decode image: its data asks for a block of", 0) == 0);
    CHECK(msg.find("more than the image needs") != std::string::npos);
    // The same header with its 1568 bytes decodes: the bound is not the refusal.
    std::vector<unsigned char> rows(1568);
    z = stbi_zlib_compress(rows.data(), int(rows.size()), &zlen, 8);
    REQUIRE(z);
    writeBytes(p, png + chunk("IDAT", std::string(reinterpret_cast<const char*>(z), size_t(zlen)), uint32_t(zlen)) +
                      chunk("IEND", "", 0));
    std::free(z);
    CHECK(load(p, "latlong").width == 32);
    // A JPEG whose first Huffman table counts 255 more 16-bit codes: stb_image 2.27 wrote
    // them past the table (and then reported "bad code lengths").
    const std::string jpg = dir + "/huffman.jpg";
    std::vector<unsigned char> rgb(3 * 32 * 16, 90);
    REQUIRE(stbi_write_jpg(jpg.c_str(), 32, 16, 3, rgb.data(), 90) != 0);
    REQUIRE(load(jpg, "latlong").width == 32);
    std::string bytes = readBytes(jpg);
    const size_t dht = bytes.find("\xff\xc4");
    REQUIRE(dht != std::string::npos);
    bytes[dht + 20] = char(255);  // the count of 16-bit codes of the segment's first table
    writeBytes(jpg, bytes);
    msg = inputErrorOf([&] { load(jpg); });
    INFO(msg);
    CHECK(msg.rfind(jpg + ": cannot decode image: a Huffman table of", 0) == 0);
    CHECK(msg.find("codes (at most 256)") != std::string::npos);
    // Scans that use a table no segment before them defined: stb_image 2.27 decoded them
    // with whatever its decoder's memory held (an AC table's slow path then read far past the
    // table). The selectors of a scan's first component sit 6 bytes after its marker; the
    // first component's quantization table 12 bytes after the frame's.
    REQUIRE(stbi_write_jpg(jpg.c_str(), 32, 16, 3, rgb.data(), 90) != 0);
    const std::string baseline = readBytes(jpg);
    auto errorWith = [&](std::string b, size_t at, char value) {
      b[at] = value;
      writeBytes(jpg, b);
      return inputErrorOf([&] { load(jpg); });
    };
    const std::string cannot = jpg + ": cannot decode image: ";
    const std::string undefined = ", which no segment before it defines";
    const size_t sos = baseline.find("\xff\xda"), sof = baseline.find("\xff\xc0");
    REQUIRE((sos != std::string::npos && sof != std::string::npos));
    const std::string scan = "a scan (at byte " + std::to_string(sos) + ") uses ";
    CHECK(errorWith(baseline, sos + 6, 0x20) == cannot + scan + "DC Huffman table 2" + undefined);
    CHECK(errorWith(baseline, sos + 6, 0x03) == cannot + scan + "AC Huffman table 3" + undefined);
    CHECK(errorWith(baseline, sof + 12, 0x02) == cannot + scan + "quantization table 2" + undefined);
    // A progressive file uses only some of the tables its scans name (tests/images/README.md):
    // its first DC scan names AC table 0, defined only after it, and loads; a DC
    // refinement scan uses no Huffman table; an AC scan uses its AC table.
    const std::string prog = readBytes(std::string(PRTBAKE_TEST_SOURCE_DIR) + "/images/progressive.jpg");
    std::vector<size_t> scans;
    for (size_t at = prog.find("\xff\xda"); at != std::string::npos; at = prog.find("\xff\xda", at + 2)) scans.push_back(at);
    REQUIRE(scans.size() == 10);
    auto field = [&](size_t scan, size_t k) { return int(uint8_t(prog[scans[scan] + k])); };
    // Scan 0: 3 components, Ss 0, Ah 0; scan 1: 1 component, Ss 1; scan 6: 3 components, Ss 0, Ah 1.
    REQUIRE((field(0, 4) == 3 && field(0, 11) == 0 && field(0, 13) >> 4 == 0));
    REQUIRE((field(1, 4) == 1 && field(1, 7) == 1));
    REQUIRE((field(6, 4) == 3 && field(6, 11) == 0 && field(6, 13) >> 4 == 1));
    writeBytes(jpg, prog);
    CHECK(load(jpg, "latlong").width == 32);
    writeBytes(jpg, prog.substr(0, scans[6] + 6) + "\x33" + prog.substr(scans[6] + 7));
    CHECK(load(jpg, "latlong").width == 32);
    const std::string progScan = [&](size_t i) { return "a scan (at byte " + std::to_string(scans[i]) + ") uses "; }(1);
    CHECK(errorWith(prog, scans[1] + 6, 0x02) == cannot + progScan + "AC Huffman table 2" + undefined);
    CHECK(errorWith(prog, scans[0] + 6, 0x20) ==
          cannot + "a scan (at byte " + std::to_string(scans[0]) + ") uses DC Huffman table 2" + undefined);
    // A restart interval of 1 MCU with no restart marker in the data: stb_image ends the scan
    // after the first MCU and leaves the rest of each plane as allocated. Decoded after two
    // different images whose freed planes it may reuse, the pixels must not differ.
    const std::string restart = baseline.substr(0, sos) + std::string("\xff\xdd\x00\x04\x00\x01", 6) + baseline.substr(sos);
    std::vector<std::vector<float>> decoded;
    for (const unsigned char fill : {30, 220}) {
      std::vector<unsigned char> other(3 * 32 * 16, fill);
      REQUIRE(stbi_write_jpg(jpg.c_str(), 32, 16, 3, other.data(), 90) != 0);
      REQUIRE(load(jpg, "latlong").width == 32);
      writeBytes(jpg, restart);
      const EnvMap env = load(jpg, "latlong");
      decoded.emplace_back(env.rgb.begin(), env.rgb.end());
    }
    CHECK(decoded[0] == decoded[1]);
    // stb_image's other formats are not read.
    const std::string bmp = dir + "/t.bmp";
    const std::vector<unsigned char> px(3 * 8 * 4, 100);
    REQUIRE(stbi_write_bmp(bmp.c_str(), 8, 4, 3, px.data()) != 0);
    CHECK(inputErrorOf([&] { load(bmp); }).rfind(bmp + ": cannot decode image: unknown image type", 0) == 0);
  }
  SECTION("faces: missing, different sizes, not square") {
    const std::string d = dir + "/faces";
    REQUIRE(::mkdir(d.c_str(), 0755) == 0);
    writeFaceDir(d, 4, ".exr", [](const std::string& p, const Picture& pic) { writeExrPicture(p, pic); });
    ::unlink((d + "/negy.exr").c_str());
    ::unlink((d + "/posz.exr").c_str());
    CHECK(inputErrorOf([&] { load(d); }).find("missing cube faces negy, posz") != std::string::npos);
    Picture big(8, 8), wide(8, 4);
    writeExrPicture(d + "/negy.exr", big);
    writeExrPicture(d + "/posz.exr", Picture(4, 4));
    std::string msg = inputErrorOf([&] { load(d); });
    CHECK(msg.find(d + "/negy.exr: face is 8x8") == 0);
    CHECK(msg.find("same size") != std::string::npos);
    writeExrPicture(d + "/negy.exr", wide);
    msg = inputErrorOf([&] { load(d); });
    CHECK(msg == d + "/negy.exr: a cube face must be square (got 8x4)");
    writeExrPicture(d + "/negy.png", Picture(4, 4));
    CHECK(inputErrorOf([&] { load(d); }).find("ambiguous") != std::string::npos);
  }
  SECTION("shapes: lat-long not 2:1, unknown aspect, cube attribute on a wrong size") {
    const std::string p = dir + "/odd.exr";
    writeExrPicture(p, Picture(1000, 700));
    CHECK(inputErrorOf([&] { load(p); }) ==
          p + ": cannot tell the layout of a 1000x700 image; expected 2:1 lat-long, 4:3 or 3:4 cross, 6:1 or 1:6 strip");
    CHECK(inputErrorOf([&] { load(p, "latlong"); }) ==
          p + ": a lat-long map must be twice as wide as high (got 1000x700)");
    ExrWriteOptions ll;
    ll.envmap = 0;
    writeExrPicture(p, Picture(30, 20), ll);
    CHECK(inputErrorOf([&] { load(p); }).find("twice as wide as high (got 30x20)") != std::string::npos);
    ExrWriteOptions cube;
    cube.envmap = 1;
    writeExrPicture(p, Picture(8, 40), cube);
    CHECK(inputErrorOf([&] { load(p); }).find("N wide and 6N high (got 8x40)") != std::string::npos);
    CHECK_THROWS_AS(load(p, "sideways"), UsageError);
    CHECK_THROWS_AS(load(dir, "cross"), InputError);
    CHECK_THROWS_AS(load(p, "games202"), InputError);
  }
  SECTION("NaN and negative texels: an error, or clamped and counted") {
    Picture bad = good;
    bad.rgb[3 * 17] = std::numeric_limits<float>::quiet_NaN();
    bad.rgb[3 * 40 + 1] = -2.0f;
    const std::string p = dir + "/nan.exr";
    writeExrPicture(p, bad);
    const std::string msg = inputErrorOf([&] { load(p); });
    CHECK(msg.rfind(p + ": 2 invalid values", 0) == 0);
    const EnvMap env = load(p, "auto", true);
    CHECK(env.clampedTexels == 2);
    CHECK(env.rgb[3 * 17] == 0.0f);
    CHECK(env.rgb[3 * 40 + 1] == 0.0f);
  }
}

// allocateLarge backs RawVector (the decoded images) and the prtbake executable's every
// large C++ block (service/huge_pages.cpp): huge-page blocks start on a 2 MiB boundary (so
// that they can be whole huge pages), small ones on 128 bytes (CL_MEM_USE_HOST_PTR), and a
// size that cannot be rounded up to its alignment is refused, not wrapped to a small block.
TEST_CASE("allocateLarge aligns large and small blocks and refuses sizes it cannot round", "[env_load]") {
  for (size_t bytes : {size_t(1), size_t(1000), kHugePageBlock - 1, kHugePageBlock, kHugePageBlock + 12345}) {
    void* p = allocateLarge(bytes);
    const size_t align = bytes >= kHugePageBlock ? (size_t(2) << 20) : 128;
    CHECK(reinterpret_cast<uintptr_t>(p) % align == 0);
    std::memset(p, 1, bytes);  // the whole block is usable (ASan checks the bounds)
    freeLarge(p);
  }
  CHECK_THROWS_AS(allocateLarge(SIZE_MAX), std::bad_alloc);
  CHECK_THROWS_AS(allocateLarge(SIZE_MAX - (size_t(1) << 20)), std::bad_alloc);
}
