// Preview images: orientation of the lat-long panels, the LUT axes, PNG output
// (decodable, tone map stated, deterministic bytes).
#include <algorithm>
#include <catch2/catch.hpp>

#include <stb/stb_image.h>

#include <cmath>
#include <fstream>

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>

#include "prtbake/env.h"
#include "prtbake/exr.h"
#include "prtbake/preview.h"
#include "prtbake/sh.h"
#include "test_common.h"

using namespace prtbake;

namespace {
std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}
}  // namespace

TEST_CASE("Environment preview: +Y at the top, +Z at the centre column, reconstruction follows", "[preview]") {
  // A lat-long environment bright toward +Z only (a lobe), as radiance SH of order 4.
  EnvMap env;
  env.layout = EnvLayout::LatLong;
  env.width = 128, env.height = 64;
  env.rgb.resize(env.texelCount() * 3);
  for (size_t t = 0; t < env.texelCount(); ++t) {
    double d[3];
    texelDirection(env, t, d, nullptr);
    const float v = float(std::exp(4 * (d[2] - 1)));
    env.rgb[3 * t] = env.rgb[3 * t + 1] = env.rgb[3 * t + 2] = v;
  }
  const ShCoeffs sh = projectEnvironmentReference(env, 4);
  const LinearImage img = renderEnvPreview(&env, sh, 64);
  REQUIRE(img.width == 3 * 64);
  REQUIRE(img.height == 32);
  for (int panel = 0; panel < 3; ++panel) {
    const float centre = img.at(panel * 64 + 32, 16)[0];  // looks along +Z
    const float edge = img.at(panel * 64 + 1, 16)[0];     // looks along −Z
    const float side = img.at(panel * 64 + 16, 16)[0];    // λ = +π/2: looks along +X
    INFO("panel " << panel << ": centre " << centre << " edge " << edge << " side " << side);
    REQUIRE(centre > 2 * side);
    REQUIRE(side > edge);
  }
  // A lobe toward +Y lights the top rows.
  for (size_t t = 0; t < env.texelCount(); ++t) {
    double d[3];
    texelDirection(env, t, d, nullptr);
    env.rgb[3 * t] = env.rgb[3 * t + 1] = env.rgb[3 * t + 2] = float(std::exp(4 * (d[1] - 1)));
  }
  const LinearImage up = renderEnvPreview(&env, projectEnvironmentReference(env, 4), 64);
  for (int panel = 0; panel < 3; ++panel) REQUIRE(up.at(panel * 64 + 10, 1)[0] > 4 * up.at(panel * 64 + 10, 30)[0]);
}

TEST_CASE("Irradiance panel of a white environment is 1 (irradiance/π of radiance 1)", "[preview]") {
  ShCoeffs sh;
  sh.order = 3;
  sh.rgb.assign(9, Rgb{0, 0, 0});
  sh.rgb[0] = {std::sqrt(4 * 3.14159265358979323846), 0.5, 2.0};
  const LinearImage img = renderEnvPreview(nullptr, sh, 32);
  REQUIRE(img.width == 64);
  for (int x = 32; x < 64; x += 5) REQUIRE(img.at(x, 7)[0] == Approx(1.0).epsilon(1e-6));
}

TEST_CASE("LUT preview: row 0 at the bottom, column 0 at the left", "[preview]") {
  const int n = 16;
  std::vector<float> a(n * n), b(n * n);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) a[r * n + c] = float(c) / (n - 1), b[r * n + c] = float(r) / (n - 1);
  const LinearImage img = renderLutPreview(n, {{"A", a.data()}, {"B", b.data()}}, "N.V", "rough", 0, 1, 64);
  // Panel 0 (A grows to the right), panel 1 (B grows upward); panels start at x = 40 and 40+64+80, y = 24.
  REQUIRE(img.at(40 + 60, 24 + 32)[0] > img.at(40 + 2, 24 + 32)[0]);
  const int ox = 40 + 64 + 80;
  REQUIRE(img.at(ox + 32, 24 + 2)[0] > img.at(ox + 32, 24 + 61)[0]);
}

TEST_CASE("drawText: bytes outside printable ASCII draw as '?'", "[preview]") {
  // Labels can come from files (a LUT's channel names). stb_easy_font indexes its glyph table by
  // (char - 32), so a byte >= 128 read as a negative char indexed before the table (a fuzzing
  // finding, UBSan). Seen failing before the fix: UBSan's report under the sanitizer build.
  LinearImage a, b;
  a.width = b.width = 40, a.height = b.height = 16;
  a.rgb.assign(size_t(a.width) * a.height * 3, 0.0f);
  b.rgb = a.rgb;
  drawText(a, 2, 2, std::string("x\x91\x01y"), 1.0f);
  drawText(b, 2, 2, "x??y", 1.0f);
  REQUIRE(a.rgb == b.rgb);
  REQUIRE(std::count(a.rgb.begin(), a.rgb.end(), 1.0f) > 0);
}

TEST_CASE("readExr: a data window away from the origin reads back pixel for pixel", "[preview][exr]") {
  // The OpenEXR library is given the buffer through Slice::Make with the data window (a base
  // pointer computed by hand for a window far from the origin lies outside the allocation:
  // a fuzzing finding). Seen failing: reading the window as if it started at (0, 0).
  const std::string dir = test::tempDir("readexr_window");
  const Imath::Box2i window(Imath::V2i(-7, 1000), Imath::V2i(-7 + 4, 1000 + 2));  // 5 × 3 at (−7, 1000)
  Imf::Header header(Imath::Box2i(Imath::V2i(0, 0), Imath::V2i(1, 1)), window);
  header.channels().insert("R", Imf::Channel(Imf::FLOAT));
  std::vector<float> r(15);
  for (size_t i = 0; i < r.size(); ++i) r[i] = float(i) * 0.5f + 1;
  {
    Imf::OutputFile file((dir + "/w.exr").c_str(), header);
    Imf::FrameBuffer fb;
    fb.insert("R", Imf::Slice::Make(Imf::FLOAT, r.data(), window));
    file.setFrameBuffer(fb);
    file.writePixels(3);
  }
  const ExrImage img = readExr(dir + "/w.exr");
  REQUIRE((img.width == 5 && img.height == 3));
  REQUIRE(img.channel("R"));
  CHECK(*img.channel("R") == r);
}

TEST_CASE("PNG output: decodable, states the tone map, identical bytes on rerun", "[preview]") {
  const std::string dir = test::tempDir("previewpng");
  LinearImage img;
  img.width = 20, img.height = 10;
  img.rgb.assign(600, 0.0f);
  for (size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = float(i % 7) / 7.0f;
  writePreviewPng(dir + "/a.png", img, ToneMap{-1.0}, {{"Description", "test"}});
  writePreviewPng(dir + "/b.png", img, ToneMap{-1.0}, {{"Description", "test"}});
  const std::string a = slurp(dir + "/a.png");
  REQUIRE(a == slurp(dir + "/b.png"));
  REQUIRE(a.find("tEXtToneMap") != std::string::npos);
  REQUIRE(a.find("sRGB") != std::string::npos);
  int w, h, c;
  unsigned char* px = stbi_load((dir + "/a.png").c_str(), &w, &h, &c, 3);
  REQUIRE(px != nullptr);
  REQUIRE((w == 20 && h == 10));
  // Pixel 1 (value 3/7 · 2^-1 = 0.2143 → sRGB 0.5035 → 128).
  CHECK(int(px[3]) == 128);
  stbi_image_free(px);
}

TEST_CASE("CLI preview: env and lut, errors", "[preview][cli]") {
  const std::string dir = test::tempDir("previewcli");
  ShCoeffs sh;
  sh.order = 2;
  sh.rgb = {{1, 1, 1}, {0, 0, 0}, {0.2, 0.2, 0.2}, {0, 0, 0}};
  writeShJson(dir + "/sh.json", sh, "{}");
  auto r = test::runCli("preview env '" + dir + "/sh.json' -o '" + dir + "/env.png' --size 64 --quiet");
  REQUIRE(r.exitCode == 0);
  REQUIRE(test::fileExists(dir + "/env.png"));
  r = test::runCli("preview env '" + dir + "/missing.json' -o '" + dir + "/x.png'");
  REQUIRE(r.exitCode == 1);
  REQUIRE_FALSE(test::fileExists(dir + "/x.png"));
  r = test::runCli("preview teapot '" + dir + "/sh.json' -o '" + dir + "/x.png'");
  REQUIRE(r.exitCode == 2);
  r = test::runCli("preview lut '" + dir + "/sh.json' -o '" + dir + "/x.png'");
  REQUIRE(r.exitCode == 1);
  REQUIRE_FALSE(test::fileExists(dir + "/x.png"));
}
