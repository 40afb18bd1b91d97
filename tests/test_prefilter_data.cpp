// Prefiltered chains of real HDR maps against the double-precision brute force (every source
// texel, exact solid angles), seams on a real map, and the orientation of the OpenEXR and
// KTX2 outputs read back by OpenEXR's own cube functions and by ktx-parse.
#include <catch2/catch.hpp>

#include <ImfChannelList.h>
#include <ImfEnvmap.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfStandardAttributes.h>
#include <ImfTiledInputFile.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <random>

#include "prtbake/prefilter.h"
#include "test_common.h"

using namespace prtbake;

namespace {

const double kPi = 3.14159265358979323846;

// The issue's bounds for levels with r ≥ 0.1, and a bound on the worst texel that a firefly
// (a sample landing on the sun) would break by orders of magnitude; measured worst 1.1 % on
// the four maps (docs/prefilter.md).
constexpr double kMeanTol = 5e-3;
constexpr double kP99Tol = 2e-2;
constexpr double kMaxTol = 3e-2;

struct Stats {
  double mean = 0, p99 = 0, max = 0;
};

// Uniform texels (fixed seed) plus the 48 nearest the brightest source texel (the sun).
Stats againstBruteForce(const EnvMap& env, const PrefilterLevel& l, PrefilterLobe lobe, int uniform) {
  const int n = l.spec.size;
  std::mt19937_64 rng(2024);
  std::vector<size_t> idx;
  const size_t total = 6 * size_t(n) * size_t(n);
  for (int i = 0; i < uniform; ++i) idx.push_back(size_t(rng() % total));
  size_t bright = 0;
  for (size_t t = 0; t < env.texelCount(); ++t)
    if (env.rgb[3 * t] + env.rgb[3 * t + 1] > env.rgb[3 * bright] + env.rgb[3 * bright + 1]) bright = t;
  double sun[3];
  texelDirection(env, bright, sun, nullptr);
  std::vector<std::pair<double, size_t>> near;
  for (size_t t = 0; t < total; ++t) {
    double d[3];
    cubeTexelCenter(n, int(t / (size_t(n) * n)), int((t / n) % n), int(t % n), d);
    near.push_back({-(d[0] * sun[0] + d[1] * sun[1] + d[2] * sun[2]), t});
  }
  std::partial_sort(near.begin(), near.begin() + 48, near.end());
  for (int i = 0; i < 48; ++i) idx.push_back(near[size_t(i)].second);
  std::vector<double> dirs;
  for (size_t t : idx) {
    double d[3];
    cubeTexelCenter(n, int(t / (size_t(n) * n)), int((t / n) % n), int(t % n), d);
    dirs.insert(dirs.end(), d, d + 3);
  }
  const std::vector<double> ref = prefilterBruteForce(env, lobe, l.alphaUsed, dirs);
  std::vector<double> rel;
  Stats s;
  for (size_t i = 0; i < idx.size(); ++i) {
    double e = 0;
    for (int c = 0; c < 3; ++c)
      e = std::max(e, std::abs(l.rgb[3 * idx[i] + size_t(c)] - ref[3 * i + size_t(c)]) / std::max(ref[3 * i + size_t(c)], 1e-12));
    if (i < size_t(uniform)) rel.push_back(e);
    s.max = std::max(s.max, e);
  }
  std::sort(rel.begin(), rel.end());
  for (double x : rel) s.mean += x / double(rel.size());
  s.p99 = rel[size_t(0.99 * double(rel.size()))];
  return s;
}

void checkMap(const char* name) {
  const std::string path = test::dataFile(std::string("envmaps/hdr/") + name);
  PRTBAKE_SKIP_IF_NO_DATA(path);
  const EnvMap env = loadEnvironment(path);
  PrefilterOptions o;
  o.schedule = PrefilterSchedule::Filament;  // 256 → 16, r = 0, 0.134, 0.293, 0.5, 1
  const PrefilterResult r = prefilterEnvironment(test::runtime(), env, o);
  for (const PrefilterLevel& l : r.levels) {
    if (l.spec.roughness < 0.1) continue;
    const Stats s = againstBruteForce(env, l, o.lobe, 250);
    INFO(name << " level " << l.spec.size << " r = " << l.spec.roughness << ": mean " << s.mean << " p99 " << s.p99
              << " max " << s.max << " (estimated p99 " << l.error.p99 << ")");
    CHECK(s.mean <= kMeanTol);
    CHECK(s.p99 <= kP99Tol);
    CHECK(s.max <= kMaxTol);
    for (float v : l.rgb) REQUIRE((std::isfinite(v) && v >= 0));
  }
}

}  // namespace

TEST_CASE("Real maps against the brute force: venice_sunset (a low sun)", "[prefilter][data]") { checkMap("venice_sunset_1k.hdr"); }
TEST_CASE("Real maps against the brute force: potsdamer_platz", "[prefilter][data]") { checkMap("potsdamer_platz_1k.hdr"); }
TEST_CASE("Real maps against the brute force: studio_small_03 (small lamps)", "[prefilter][data]") {
  checkMap("studio_small_03_1k.hdr");
}
TEST_CASE("Real maps against the brute force: grace cathedral", "[prefilter][data]") { checkMap("grace_latlong.exr"); }

namespace {

// An OpenEXR file's level `level` as RGB floats with its data window and envmap attribute.
struct ExrLevel {
  Imath::Box2i dw;
  int width = 0, height = 0;
  bool latlong = false;
  std::vector<float> px;
  const float* at(int x, int y) const { return &px[3 * (size_t(y - dw.min.y) * size_t(width) + size_t(x - dw.min.x))]; }
};

ExrLevel readLevel(const std::string& path, int level) {
  Imf::TiledInputFile in(path.c_str());
  ExrLevel l;
  l.dw = in.dataWindowForLevel(level);
  l.width = l.dw.max.x - l.dw.min.x + 1, l.height = l.dw.max.y - l.dw.min.y + 1;
  l.latlong = Imf::envmap(in.header()) == Imf::ENVMAP_LATLONG;
  l.px.resize(size_t(l.width) * size_t(l.height) * 3);
  Imf::FrameBuffer fb;
  const char* names[3] = {"R", "G", "B"};
  char* base = reinterpret_cast<char*>(l.px.data()) - (size_t(l.dw.min.y) * size_t(l.width) + size_t(l.dw.min.x)) * 12;
  for (int c = 0; c < 3; ++c) fb.insert(names[c], Imf::Slice(Imf::FLOAT, base + 4 * c, 12, 12 * size_t(l.width)));
  in.setFrameBuffer(fb);
  in.readTiles(0, in.numXTiles(level) - 1, 0, in.numYTiles(level) - 1, level);
  return l;
}

// The pixel OpenEXR's ImfEnvmap.h puts in direction d (nearest): nothing of prtbake's mapping.
const float* lookup(const ExrLevel& l, const Imath::V3f& d) {
  Imath::V2f pos;
  if (l.latlong) {
    pos = Imf::LatLongMap::pixelPosition(l.dw, d);
  } else {
    Imf::CubeMapFace face;
    Imath::V2f pif;
    Imf::CubeMap::faceAndPixelPosition(d, l.dw, face, pif);
    pos = Imf::CubeMap::pixelPosition(face, l.dw, pif);
  }
  const int x = std::clamp(int(std::lround(pos.x)), l.dw.min.x, l.dw.max.x);
  const int y = std::clamp(int(std::lround(pos.y)), l.dw.min.y, l.dw.max.y);
  return l.at(x, y);
}

// Σ |out − source| / Σ |source − its mean| over (direction, rgb) samples, the source looked
// up by OpenEXR: 0 for a perfect match, about 2 for a map whose detail is all misplaced.
double mismatch(const ExrLevel& source, const std::vector<std::array<double, 6>>& samples) {
  std::vector<std::array<float, 3>> src;
  double mean[3] = {0, 0, 0};
  for (const auto& s : samples) {
    const float* v = lookup(source, Imath::V3f(float(s[0]), float(s[1]), float(s[2])));
    src.push_back({v[0], v[1], v[2]});
    for (int c = 0; c < 3; ++c) mean[c] += v[c] / double(samples.size());
  }
  double diff = 0, spread = 0;
  for (size_t i = 0; i < samples.size(); ++i)
    for (int c = 0; c < 3; ++c)
      diff += std::abs(samples[i][size_t(3 + c)] - src[i][size_t(c)]), spread += std::abs(src[i][size_t(c)] - mean[c]);
  return diff / spread;
}

// Samples of level `level` of a cube OpenEXR file, every `stride`-th pixel of each face, with
// the direction ImfEnvmap.h gives the pixel.
std::vector<std::array<double, 6>> exrSamples(const std::string& path, int level, int stride) {
  const ExrLevel l = readLevel(path, level);
  std::vector<std::array<double, 6>> out;
  const int s = Imf::CubeMap::sizeOfFace(l.dw);
  for (int f = 0; f < 6; ++f)
    for (int j = stride / 2; j < s; j += stride)
      for (int i = stride / 2; i < s; i += stride) {
        const Imath::V2f pif{float(i), float(j)};
        const Imath::V2f pos = Imf::CubeMap::pixelPosition(Imf::CubeMapFace(f), l.dw, pif);
        const Imath::V3f d = Imf::CubeMap::direction(Imf::CubeMapFace(f), l.dw, pif).normalized();
        const float* v = l.at(int(std::lround(pos.x)), int(std::lround(pos.y)));
        out.push_back({d.x, d.y, d.z, v[0], v[1], v[2]});
      }
  return out;
}

bool nodeReady() {
  return test::runShell("command -v node").exitCode == 0 &&
         test::fileExists(std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/node_modules/ktx-parse/package.json");
}

// Samples of a KTX2 level read by ktx-parse, directions from the KTX 2.0 addressing (ktx2_read.mjs).
std::vector<std::array<double, 6>> ktxSamples(const std::string& path, int level, int stride, nlohmann::json* header) {
  const test::CliResult r = test::runShell("node '" + std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/ktx2_read.mjs' '" + path +
                                           "' --texels " + std::to_string(level) + " " + std::to_string(stride));
  INFO(r.output.substr(0, 2000));
  REQUIRE(r.exitCode == 0);
  nlohmann::json j = nlohmann::json::parse(r.output);
  std::vector<std::array<double, 6>> out;
  for (const auto& t : j["texels"]) out.push_back({t[0], t[1], t[2], t[3], t[4], t[5]});
  j.erase("texels");
  if (header) *header = j;
  return out;
}

}  // namespace

namespace {

void checkOrientation(const char* name) {
  // The r = 0 level (base 512), read back from the OpenEXR output with the directions
  // OpenEXR's ImfEnvmap.h gives its pixels, and from the KTX2 output with ktx-parse and the
  // KTX 2.0 cube-map addressing (tests/js/ktx2_read.mjs), against the source file looked up in
  // the same directions by ImfEnvmap.h (nearest pixel). The maps are white with black axis
  // labels, so a wrong orientation moves text onto white; mismatch() is 0 for a perfect match
  // and about 2 when all detail is misplaced. Measured: 0 for OrientationCube (512² faces: the
  // r = 0 level is the source, texel for texel, half to half), 0.19 (KTX2) and 0.21 (EXR) for
  // OrientationLatLong (resampled onto the cube grid, then looked up nearest); every face
  // mirrored left to right gives 0.67 and 0.71.
  constexpr double kCubeMismatchTol = 1e-6;
  constexpr double kLatLongMismatchTol = 0.28;
  constexpr int kStride = 7;
  const bool node = nodeReady();
  if (!node) test::skipPart("node or tests/js/node_modules (npm ci in tests/js) absent: KTX2 not read back with ktx-parse");
  {
    const std::string path = test::dataFile(std::string("envmaps/openexr/") + name);
    PRTBAKE_SKIP_IF_NO_DATA(path);
    INFO(name);
    const double kMismatchTol = std::string(name) == "OrientationCube.exr" ? kCubeMismatchTol : kLatLongMismatchTol;
    const ExrLevel source = readLevel(path, 0);
    const EnvMap env = loadEnvironment(path);
    PrefilterOptions o;
    o.schedule = PrefilterSchedule::Explicit;
    o.roughness = {0.0, 1.0};
    o.baseSize = 512;
    o.errorEstimate = false;
    PrefilterResult r = prefilterEnvironment(test::runtime(), env, o);
    const std::string dir = test::tempDir("prefilter-orientation");
    const std::string exr = dir + "/chain.exr", ktx = dir + "/chain.ktx2";
    writePrefilterFiles(r, env, "", ktx, false, exr, true, "");
    const double fromExr = mismatch(source, exrSamples(exr, 0, kStride));
    INFO("EXR output: mismatch " << fromExr);
    CHECK(fromExr <= kMismatchTol);
    if (!node) return;
    nlohmann::json header;
    const double fromKtx = mismatch(source, ktxSamples(ktx, 0, kStride, &header));
    INFO("KTX2 output: mismatch " << fromKtx);
    CHECK(fromKtx <= kMismatchTol);
    CHECK(header["faceCount"] == 6);
    CHECK(header["levelCount"] == 2);
    CHECK(header["vkFormat"] == 97);
    // The r = 1 level: the two files hold the same values in the same directions.
    const ExrLevel exr1 = readLevel(exr, 1);
    const double between = mismatch(exr1, ktxSamples(ktx, 1, 2, nullptr));
    INFO("level 1, KTX2 against EXR: mismatch " << between);
    CHECK(between <= 1e-6);  // both half, the same values: measured 0
    // Negative control: the same chain with every face mirrored left to right (what glTF's
    // EXT_lights_image_based images are, and a classic exporter bug).
    for (auto& l : r.levels) {
      const int n = l.spec.size;
      for (int f = 0; f < 6; ++f)
        for (int row = 0; row < n; ++row)
          for (int col = 0; col < n / 2; ++col)
            for (int c = 0; c < 3; ++c)
              std::swap(l.rgb[3 * ((size_t(f) * n + row) * n + col) + c], l.rgb[3 * ((size_t(f) * n + row) * n + n - 1 - col) + c]);
    }
    writePrefilterFiles(r, env, "", ktx, false, "", false, "");
    const double mirrored = mismatch(source, ktxSamples(ktx, 0, kStride, nullptr));
    INFO("mirrored faces: mismatch " << mirrored);
    CHECK(mirrored > 2 * kLatLongMismatchTol);
  }
}

}  // namespace

TEST_CASE("Orientation: OrientationCube keeps its orientation through EXR and KTX2", "[prefilter][data]") {
  checkOrientation("OrientationCube.exr");
}
TEST_CASE("Orientation: OrientationLatLong keeps its orientation through EXR and KTX2", "[prefilter][data]") {
  checkOrientation("OrientationLatLong.exr");
}

TEST_CASE("Seams on a real map: the step across each edge against the step inside", "[prefilter][data]") {
  // On venice_sunset the steps across the edges measure 0.88 to 0.94 of those inside on every
  // prefiltered level (texel centres at an edge are 5 % closer across it). Bound 1. The r = 0
  // level is the source itself, whose content decides: 1.02 here, and point samples of the
  // exact definition (α = 0.002) give 1.13 at 32² and 1.18 at 64² on this map, so no chain can
  // promise less there; test_prefilter.cpp checks that the chain adds no step of its own.
  const std::string path = test::dataFile("envmaps/hdr/venice_sunset_1k.hdr");
  PRTBAKE_SKIP_IF_NO_DATA(path);
  const EnvMap env = loadEnvironment(path);
  PrefilterOptions o;
  o.schedule = PrefilterSchedule::Filament;
  o.baseSize = 128;
  const PrefilterResult r = prefilterEnvironment(test::runtime(), env, o);
  for (const PrefilterLevel& l : r.levels) {
    const int n = l.spec.size;
    const auto bases = standardCubeBases();
    double across = 0, inside = 0;
    auto lum = [&](size_t t) { return double(l.rgb[3 * t] + l.rgb[3 * t + 1] + l.rgb[3 * t + 2]); };
    for (int f = 0; f < 6; ++f)
      for (int side = 0; side < 4; ++side)
        for (int i = 0; i < n; ++i) {
          const int row = side == 0 ? 0 : side == 1 ? n - 1 : i, col = side == 2 ? 0 : side == 3 ? n - 1 : i;
          const int dr = side == 0 ? 1 : side == 1 ? -1 : 0, dc = side == 2 ? 1 : side == 3 ? -1 : 0;
          const double u = 2.0 * (col - dc + 0.5) / n - 1.0, v = 2.0 * (row - dr + 0.5) / n - 1.0;
          double d[3];
          for (int k = 0; k < 3; ++k) d[k] = u * bases[size_t(f)].axisU[size_t(k)] + v * bases[size_t(f)].axisV[size_t(k)] + bases[size_t(f)].axisN[size_t(k)];
          const size_t t = (size_t(f) * size_t(n) + size_t(row)) * size_t(n) + size_t(col);
          across += std::abs(lum(t) - lum(cubeTexelIndex(n, d)));
          inside += std::abs(lum(t) - lum((size_t(f) * size_t(n) + size_t(row + dr)) * size_t(n) + size_t(col + dc)));
        }
    INFO("level " << n << " r = " << l.spec.roughness << ": across / inside = " << across / inside);
    if (l.spec.roughness > 0) CHECK(across <= inside);
  }
}
