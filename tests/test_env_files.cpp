// The environment product end to end, from files: a band-limited environment
// written as six faces, as an OpenEXR cube and as a lat-long is recovered (and a
// flipped face is caught); white furnace in every layout; kernel vs the double
// reference on the shared maps; the OpenEXR cube/lat-long pairs agree; the CLI's
// bad-input behaviour (one error line, exit 1 or 2, no output file).
#include <catch2/catch.hpp>

#include <ImfEnvmap.h>
#include <stb/stb_image_write.h>

#include <cmath>
#include <fstream>
#include <functional>

#include "prtbake/env.h"
#include "prtbake/error.h"
#include "prtbake/exr.h"
#include "prtbake/sh.h"
#include "env_test_helpers.h"
#include "test_common.h"

using namespace prtbake;
using test::knownCoeffs;
using test::maxAbsDiff;

namespace {

const double kPi = 3.14159265358979323846;
using Fn = std::function<Rgb(const double*)>;

// Pixels in the file's own layout, written with the direction each format
// defines: docs/conventions.md "Cube faces" for face images, ImfEnvmap.h for OpenEXR
// envmaps (evaluated at texel centres). Nothing here calls the loader's code.
struct Planes {
  int w, h;
  std::vector<float> r, g, b;
  Planes(int w_, int h_) : w(w_), h(h_), r(size_t(w_) * h_), g(r.size()), b(r.size()) {}
  void set(int x, int y, const Rgb& v) {
    const size_t i = size_t(y) * w + x;
    r[i] = float(v[0]), g[i] = float(v[1]), b[i] = float(v[2]);
  }
  void write(const std::string& path, int envmap = -1) const {
    ExrWriteOptions o;
    o.envmap = envmap;
    writeExr(path, w, h, {{"R", r.data()}, {"G", g.data()}, {"B", b.data()}}, o);
  }
};

void designDir(int face, double u, double v, double* d) {
  double x, y, z;
  switch (face) {
    case 0: x = 1, y = -v, z = -u; break;
    case 1: x = -1, y = -v, z = u; break;
    case 2: x = u, y = 1, z = v; break;
    case 3: x = u, y = -1, z = -v; break;
    case 4: x = u, y = -v, z = 1; break;
    default: x = -u, y = -v, z = -1; break;
  }
  const double n = std::sqrt(x * x + y * y + z * z);
  d[0] = x / n, d[1] = y / n, d[2] = z / n;
}

void writeFacesDir(const std::string& dir, int n, const Fn& f, bool flipPosX = false) {
  const char* names[6] = {"posx", "negx", "posy", "negy", "posz", "negz"};
  for (int face = 0; face < 6; ++face) {
    Planes p(n, n);
    for (int row = 0; row < n; ++row)
      for (int col = 0; col < n; ++col) {
        double d[3];
        designDir(face, 2 * (col + 0.5) / n - 1, 2 * (row + 0.5) / n - 1, d);
        const int x = (flipPosX && face == 0) ? n - 1 - col : col;
        p.set(x, row, f(d));
      }
    p.write(dir + "/" + names[face] + ".exr");
  }
}

void writeExrCube(const std::string& path, int n, const Fn& f) {
  Planes p(n, 6 * n);
  const IMATH_NAMESPACE::Box2i dw(IMATH_NAMESPACE::V2i(0, 0), IMATH_NAMESPACE::V2i(n - 1, 6 * n - 1));
  for (int face = 0; face < 6; ++face)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const auto cf = Imf::CubeMapFace(face);
        const IMATH_NAMESPACE::V2f pix = Imf::CubeMap::pixelPosition(cf, dw, IMATH_NAMESPACE::V2f(float(x), float(y)));
        // ImfEnvmap.h spans [−1, 1] from the first to the last pixel; the texel-centre
        // direction of pixel x is at (x + 0.5)(n − 1)/n on that scale.
        const float s = float(n - 1) / float(n);
        const IMATH_NAMESPACE::V3f dir = Imf::CubeMap::direction(cf, dw, IMATH_NAMESPACE::V2f((x + 0.5f) * s, (y + 0.5f) * s));
        const double len = std::sqrt(double(dir.x) * dir.x + double(dir.y) * dir.y + double(dir.z) * dir.z);
        const double d[3] = {dir.x / len, dir.y / len, dir.z / len};
        p.set(int(std::lround(pix.x)), int(std::lround(pix.y)), f(d));
      }
  p.write(path, 1);
}

void writeExrLatLong(const std::string& path, int h, const Fn& f) {
  const int w = 2 * h;
  Planes p(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      // Texel centres on LatLongMap's axes: λ = −2π((x+0.5)/w − 0.5), φ = π(0.5 − (y+0.5)/h).
      const double lam = -2 * kPi * ((x + 0.5) / w - 0.5), phi = kPi * (0.5 - (y + 0.5) / h);
      const double d[3] = {std::sin(lam) * std::cos(phi), std::sin(phi), std::cos(lam) * std::cos(phi)};
      p.set(x, y, f(d));
    }
  p.write(path, 0);
}

ShCoeffs projectFile(const std::string& path, int order, const std::string& layout = "auto") {
  EnvLoadOptions lo;
  lo.layout = layout;
  const EnvMap env = loadEnvironment(path, lo);
  EnvProjectOptions o;
  o.order = order;
  return projectEnvironment(test::runtime(), env, o).coeffs;
}

}  // namespace

TEST_CASE("Band-limited environment from six faces, an OpenEXR cube and a lat-long file", "[env][files]") {
  // Same bound and reason as the in-memory test: centre sampling of a quadratic
  // leaves O(h²) (7e-6 at N = 128, 4e-5 at H = 256); float32 EXR storage adds
  // 1e-7 relative. Any flip or face swap moves coefficients by > 0.05.
  constexpr double kRecoverTol = 5e-4;
  const ShCoeffs truth = knownCoeffs();
  const Fn f = [&](const double* d) { return evalSh(truth, d[0], d[1], d[2]); };
  const std::string dir = test::tempDir("bandlimited");
  std::system(("mkdir -p " + dir + "/faces " + dir + "/flipped").c_str());
  writeFacesDir(dir + "/faces", 128, f);
  writeExrCube(dir + "/cube.exr", 128, f);
  writeExrLatLong(dir + "/latlong.exr", 256, f);
  for (const char* p : {"/faces", "/cube.exr", "/latlong.exr"}) {
    const ShCoeffs got = projectFile(dir + p, 3);
    INFO(p << ": max |Δ| = " << maxAbsDiff(got, truth));
    REQUIRE(maxAbsDiff(got, truth) < kRecoverTol);
  }
  // Negative control: +X written mirrored left–right must be caught.
  writeFacesDir(dir + "/flipped", 128, f, true);
  const ShCoeffs bad = projectFile(dir + "/flipped", 3);
  INFO("flipped +X: max |Δ| = " << maxAbsDiff(bad, truth));
  REQUIRE(maxAbsDiff(bad, truth) > 10 * kRecoverTol);
}

TEST_CASE("White furnace in every file layout", "[env][files]") {
  // L00 = √(4π) to 1e-5 relative and the rest below 1e-5 (issue bounds). Lat-long
  // needs H = 1024 for its centre-sampling error to fall under 1e-5 (see
  // test_env_project.cpp); 8-bit faces of 255 decode to exactly 1.0.
  constexpr double kTol = 1e-5;
  const std::string dir = test::tempDir("furnace");
  const Fn white = [](const double*) { return Rgb{1, 1, 1}; };
  std::system(("mkdir -p " + dir + "/faces " + dir + "/png").c_str());
  writeFacesDir(dir + "/faces", 32, white);
  writeExrCube(dir + "/cube.exr", 32, white);
  writeExrLatLong(dir + "/latlong.exr", 1024, white);
  Planes cross(4 * 16, 3 * 16);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) cross.set(x, y, {1, 1, 1});
  cross.write(dir + "/cross.exr");
  std::vector<unsigned char> px(16 * 16 * 3, 255);
  for (const char* n : {"posx", "negx", "posy", "negy", "posz", "negz"})
    stbi_write_png((dir + "/png/" + n + ".png").c_str(), 16, 16, 3, px.data(), 16 * 3);
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"/faces", "auto"}, {"/cube.exr", "auto"}, {"/latlong.exr", "auto"}, {"/cross.exr", "auto"},
      {"/png", "faces"},  {"/png", "games202"}};
  for (const auto& [p, layout] : cases) {
    const ShCoeffs c = projectFile(dir + p, 3, layout);
    INFO(p << " as " << layout << ": L00 = " << c.rgb[0][0]);
    REQUIRE(std::abs(c.rgb[0][0] / std::sqrt(4 * kPi) - 1) < kTol);
    for (size_t k = 1; k < 9; ++k)
      for (int ch = 0; ch < 3; ++ch) REQUIRE(std::abs(c.rgb[k][size_t(ch)]) < kTol);
  }
}

TEST_CASE("Kernel vs double reference on the shared environment maps", "[env][files][data]") {
  // Issue bounds: max |Δ|/|L00| < 1e-5 at order 3 and < 1e-4 at order 8.
  const std::vector<std::string> files = {"envmaps/openexr/StageEnvCube.exr", "envmaps/openexr/StageEnvLatLong.exr",
                                          "envmaps/hdr/grace_latlong.exr", "envmaps/games202/GraceCathedral",
                                          "envmaps/hdr/venice_sunset_1k.hdr"};
  const std::string first = test::dataFile(files[0]);
  PRTBAKE_SKIP_IF_NO_DATA(first);
  for (const auto& rel : files) {
    const std::string path = test::dataFile(rel);
    if (path.empty()) continue;
    const EnvMap env = loadEnvironment(path);
    for (const auto& [order, tol] : std::vector<std::pair<int, double>>{{3, 1e-5}, {8, 1e-4}}) {
      const ShCoeffs ref = projectEnvironmentReference(env, order);
      EnvProjectOptions o;
      o.order = order;
      const ShCoeffs k = projectEnvironment(test::runtime(), env, o).coeffs;
      double l00 = 0;
      for (int ch = 0; ch < 3; ++ch) l00 = std::max(l00, std::abs(ref.rgb[0][size_t(ch)]));
      INFO(rel << " order " << order << ": max|Δ|/|L00| = " << maxAbsDiff(k, ref) / l00);
      REQUIRE(maxAbsDiff(k, ref) / l00 < tol);
    }
  }
}

TEST_CASE("The OpenEXR cube and lat-long versions of a scene agree at order 3", "[env][files][data]") {
  // Issue bound: within 1% of L00. The two files are independent resamplings of one
  // scene, so they differ by filtering, not by orientation (a flipped axis would
  // move band-1 terms by tens of percent).
  constexpr double kPairTol = 0.01;
  const std::string probe = test::dataFile("envmaps/openexr/StageEnvCube.exr");
  PRTBAKE_SKIP_IF_NO_DATA(probe);
  for (const char* scene : {"StageEnv", "KernerEnv", "WavyLines", "Orientation"}) {
    const std::string cube = test::dataFile(std::string("envmaps/openexr/") + scene + "Cube.exr");
    const std::string ll = test::dataFile(std::string("envmaps/openexr/") + scene + "LatLong.exr");
    if (cube.empty() || ll.empty()) continue;
    const ShCoeffs a = projectFile(cube, 3), b = projectFile(ll, 3);
    double l00 = std::max({a.rgb[0][0], a.rgb[0][1], a.rgb[0][2]});
    INFO(scene << ": max |Δ|/L00 = " << maxAbsDiff(a, b) / l00);
    CHECK(maxAbsDiff(a, b) / l00 < kPairTol);
  }
}

TEST_CASE("CLI: bad input gives one error line, exit 1 or 2, and no output", "[env][files][cli]") {
  const std::string dir = test::tempDir("badinput");
  const Fn white = [](const double*) { return Rgb{1, 1, 1}; };
  // Truncated EXR: a good file cut in half.
  writeExrLatLong(dir + "/good.exr", 32, white);
  {
    std::ifstream in(dir + "/good.exr", std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(dir + "/truncated.exr", std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  }
  std::ofstream(dir + "/garbage.jpg", std::ios::binary) << "\xFF\xD8\xFF\xE0 this is not a JPEG at all";
  // Faces of different sizes; non-square faces.
  std::system(("mkdir -p " + dir + "/mixed " + dir + "/nonsquare").c_str());
  writeFacesDir(dir + "/mixed", 8, white);
  Planes big(16, 16);
  big.write(dir + "/mixed/negz.exr");
  writeFacesDir(dir + "/nonsquare", 8, white);
  Planes rect(8, 6);
  rect.write(dir + "/nonsquare/posy.exr");
  // A lat-long that is not 2:1 (declared lat-long through the envmap attribute).
  {
    Planes p(30, 20);
    p.write(dir + "/notwotoone.exr", 0);
  }
  struct Case {
    std::string args, mustMention;
    int exit;
  };
  const std::vector<Case> cases = {
      {"'" + dir + "/missing.exr'", "missing.exr", 1},
      {"'" + dir + "/truncated.exr'", "truncated.exr", 1},
      {"'" + dir + "/garbage.jpg'", "garbage.jpg", 1},
      {"'" + dir + "/mixed'", "negz", 1},
      {"'" + dir + "/nonsquare'", "posy", 1},
      {"'" + dir + "/notwotoone.exr'", "notwotoone.exr", 1},
      {"'" + dir + "/good.exr' --order 0", "--order", 2},
      {"'" + dir + "/good.exr' --order 100", "--order", 2},
      {"'" + dir + "/good.exr' --window sinc", "--window", 2},
      {"'" + dir + "/good.exr' --quantity lux", "--quantity", 2},
  };
  for (const auto& c : cases) {
    const std::string out = dir + "/out.json";
    const auto r = test::runCli("env " + c.args + " -o '" + out + "' --device cpu");
    INFO("prtbake env " << c.args << "\n" << r.output);
    REQUIRE(r.exitCode == c.exit);
    REQUIRE(r.output.find("prtbake: error: ") == 0);
    REQUIRE(std::count(r.output.begin(), r.output.end(), '\n') == 1);
    REQUIRE(r.output.find(c.mustMention) != std::string::npos);
    REQUIRE_FALSE(test::fileExists(out));
  }
  // And a good run writes both files, the JSON stating its conventions.
  const auto ok = test::runCli("env '" + dir + "/good.exr' -o '" + dir + "/ok.json' --games202 '" + dir +
                               "/light.txt' --device cpu --quiet");
  REQUIRE(ok.exitCode == 0);
  std::ifstream light(dir + "/light.txt");
  std::string line;
  int lines = 0;
  while (std::getline(light, line)) {
    ++lines;
    REQUIRE(line.back() != ' ');
    REQUIRE(std::count(line.begin(), line.end(), ' ') == 2);
  }
  REQUIRE(lines == 9);
  std::ifstream js(dir + "/ok.json");
  std::string text((std::istreambuf_iterator<char>(js)), std::istreambuf_iterator<char>());
  REQUIRE(text.find("Condon-Shortley") != std::string::npos);
  REQUIRE(text.find("\"quantity\": \"radiance\"") != std::string::npos);
}
