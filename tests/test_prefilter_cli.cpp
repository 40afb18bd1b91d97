// prtbake prefilter end to end: outputs and sidecar, bad input (one line, no partial output),
// usage errors, extreme base sizes, the job type with shards and merge, the preview, and the
// KTX2 read back by ktx-parse.
#include <catch2/catch.hpp>

#include <ImfHeader.h>
#include <ImfIntAttribute.h>
#include <ImfStandardAttributes.h>
#include <ImfTiledInputFile.h>
#include <dirent.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "job_test_helpers.h"
#include "prtbake/atomic_file.h"
#include "prtbake/exr.h"
#include "prtbake/prefilter.h"
#include "test_common.h"

using namespace prtbake;
using nlohmann::json;

namespace {

const double kPi = 3.14159265358979323846;

// A 64×32 lat-long OpenEXR sky with a small sun (envmap attribute lat-long).
void writeSky(const std::string& path, float nanAt = -1) {
  const int w = 64, h = 32;
  std::vector<float> r(size_t(w) * h), g(r.size()), b(r.size());
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double phi = kPi * (0.5 - (y + 0.5) / h);
      const size_t i = size_t(y) * w + size_t(x);
      r[i] = float(0.3 + 0.5 * std::max(0.0, std::sin(phi))), g[i] = 0.4f, b[i] = float(0.5 + 0.3 * std::cos(phi));
    }
  r[size_t(8) * w + 20] = g[size_t(8) * w + 20] = b[size_t(8) * w + 20] = 5000.0f;
  if (nanAt >= 0) r[size_t(nanAt)] = std::nanf("");
  ExrWriteOptions o;
  o.envmap = 0;
  writeExr(path, w, h, {{"R", r.data()}, {"G", g.data()}, {"B", b.data()}}, o);
}

std::vector<std::string> listDir(const std::string& dir) {
  std::vector<std::string> out;
  if (DIR* d = ::opendir(dir.c_str())) {
    while (dirent* e = ::readdir(d))
      if (std::string(e->d_name) != "." && std::string(e->d_name) != "..") out.push_back(e->d_name);
    ::closedir(d);
  }
  std::sort(out.begin(), out.end());
  return out;
}

bool nodeReady() {
  return test::runShell("command -v node").exitCode == 0 &&
         test::fileExists(std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/node_modules/ktx-parse/package.json");
}

}  // namespace

TEST_CASE("CLI prefilter: KTX2, OpenEXR and the sidecar", "[prefilter][cli]") {
  const std::string dir = test::tempDir("prefilter-cli");
  writeSky(dir + "/sky.exr");
  const auto r = test::runCli("prefilter '" + dir + "/sky.exr' -o '" + dir + "/chain.ktx2' --exr '" + dir +
                              "/chain.exr' --size 32 --schedule filament");
  INFO(r.output);
  REQUIRE(r.exitCode == 0);
  CHECK(test::countOf(r.output, "\n") == 1);  // one status line
  const json j = json::parse(readFile(dir + "/chain.json"));
  CHECK(j["product"] == "prefiltered_specular");
  CHECK(j["lobe"] == "ggx");
  CHECK(j["schedule"] == "filament");
  CHECK(j["definition"].get<std::string>().find("D_GGX") != std::string::npos);
  REQUIRE(j["levels"].size() == 2);  // 32 → 16
  CHECK(j["levels"][0]["size"] == 32);
  CHECK(j["levels"][0]["roughness"] == 0.0);
  CHECK(j["levels"][1]["size"] == 16);
  CHECK(j["levels"][1]["roughness"].get<double>() == Approx(1.0));
  CHECK(j["levels"][1]["error_estimate"]["p99"].get<double>() <= 0.01);
  CHECK(j["levels"][0]["error_estimate"].is_null());
  CHECK(j["conventions"]["faces"] == "+X, -X, +Y, -Y, +Z, -Z");
  CHECK(j["inputs"][dir + "/sky.exr"].get<std::string>().size() == 64);
  CHECK(j["outputs"]["ktx2"]["format"] == "VK_FORMAT_R16G16B16A16_SFLOAT");
  CHECK(j["outputs"]["exr"]["pixel_type"] == "float32");
  CHECK(j["timings_seconds"]["prefilter"].get<double>() > 0);
  CHECK(j["parameters"]["size"] == 32);
  // The OpenEXR file: one tiled, mip-mapped cube map, every OpenEXR level present.
  Imf::TiledInputFile exr((dir + "/chain.exr").c_str());
  CHECK(Imf::hasEnvmap(exr.header()));
  CHECK(Imf::envmap(exr.header()) == Imf::ENVMAP_CUBE);
  CHECK(exr.numLevels() == 8);  // floor(log2(6 · 32)) + 1
  CHECK(exr.dataWindowForLevel(1).max.x == 15);
  CHECK(exr.dataWindowForLevel(1).max.y == 95);
  CHECK(exr.header().typedAttribute<Imf::IntAttribute>("prtbake:prefilteredLevels").value() == 2);
  const std::string ktx = readFile(dir + "/chain.ktx2");
  CHECK(ktx.compare(0, 12, std::string("\xABKTX 20\xBB\r\n\x1A\n", 12)) == 0);
  // Nothing else in the folder (no temp files).
  CHECK(listDir(dir) == std::vector<std::string>{"chain.exr", "chain.json", "chain.ktx2", "sky.exr"});
}

TEST_CASE("CLI prefilter: bad input fails with one line and leaves nothing", "[prefilter][cli]") {
  const std::string dir = test::tempDir("prefilter-bad");
  writeSky(dir + "/nan.exr", 100);
  test::writeText(dir + "/broken.exr", "v/1\x01 not an OpenEXR file");
  test::writeText(dir + "/small.hdr", "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4 +X 8\n");  // truncated pixels
  const std::vector<std::pair<std::string, std::string>> cases = {
      {dir + "/missing.exr", "cannot open"},
      {dir + "/broken.exr", "broken.exr"},
      {dir + "/small.hdr", "small.hdr"},
      {dir + "/nan.exr", "invalid values"},
  };
  for (const auto& [input, expect] : cases) {
    INFO(input);
    const auto r = test::runCli("prefilter '" + input + "' -o '" + dir + "/out.ktx2' --exr '" + dir + "/out.exr' --size 16");
    INFO(r.output);
    CHECK(r.exitCode == 1);
    CHECK(r.output.rfind("prtbake: error: ", 0) == 0);
    CHECK(test::countOf(r.output, "\n") == 1);
    CHECK(r.output.find(expect) != std::string::npos);
    CHECK(listDir(dir) == std::vector<std::string>{"broken.exr", "nan.exr", "small.hdr"});
  }
  // --clamp-invalid replaces the NaN and says so in the sidecar.
  const auto ok = test::runCli("prefilter '" + dir + "/nan.exr' -o '" + dir + "/out.ktx2' --size 16 --clamp-invalid -q");
  INFO(ok.output);
  REQUIRE(ok.exitCode == 0);
  CHECK(json::parse(readFile(dir + "/out.json"))["environment"]["clamped_texels"] == 1);
}

TEST_CASE("CLI prefilter: a NaN in the last band of a large lat-long file fails with one line and leaves nothing",
          "[prefilter][cli][bands]") {
  // 4096 × 2048 float texels (96 MiB) come in 4 bands of 672 rows (forEachLatLongBand's 32 MiB,
  // whole chunks of 32 lines); the NaN (a grey Y channel, so one per R, G, B) is in the fourth.
  const std::string dir = test::tempDir("prefilter-bands-cli");
  const int w = 4096, h = 2048;
  std::vector<float> y(size_t(w) * h, 0.5f);
  y[size_t(2040) * w + 17] = std::nanf("");
  ExrWriteOptions o;
  o.envmap = 0;
  writeExr(dir + "/big.exr", w, h, {{"Y", y.data()}}, o);
  y = {};
  const auto r = test::runCli("prefilter '" + dir + "/big.exr' -o '" + dir + "/out.ktx2' --exr '" + dir + "/out.exr' --size 16");
  INFO(r.output);
  CHECK(r.exitCode == 1);
  CHECK(r.output.rfind("prtbake: error: ", 0) == 0);
  CHECK(test::countOf(r.output, "\n") == 1);
  CHECK(r.output.find("big.exr") != std::string::npos);
  CHECK(r.output.find("3 invalid values (3 NaN/Inf") != std::string::npos);  // Y: one value per channel
  CHECK(listDir(dir) == std::vector<std::string>{"big.exr"});
}

TEST_CASE("CLI prefilter: usage errors exit 2 before anything is read or written", "[prefilter][cli]") {
  const std::string dir = test::tempDir("prefilter-usage");
  writeSky(dir + "/sky.exr");
  const std::string in = "'" + dir + "/sky.exr' ";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {in + "-o '" + dir + "/o.ktx2' --size 0", "--size: 0 is out of range [1, 8192]"},
      {in + "-o '" + dir + "/o.ktx2' --size 1e9", "--size: 1000000000 is out of range [1, 8192]"},
      {in + "-o '" + dir + "/o.ktx2' --size 1000000000", "out of range"},
      {in + "-o '" + dir + "/o.ktx2' --size 65536", "65536 is out of range [1, 8192]"},
      {in + "-o '" + dir + "/o.ktx2' --size 64 --levels 8", "--levels: 8 is out of range [1, 7]"},
      {in + "-o '" + dir + "/o.ktx2' --lobe phong", "--lobe: unknown value 'phong'"},
      {in + "-o '" + dir + "/o.png'", "must end in .ktx2 or .exr"},
      {in + "-o '" + dir + "/o.ktx2' --schedule linear --roughness 0,0.5", "cannot be combined"},
      {in + "-o '" + dir + "/o.ktx2' --roughness 0,2", "--roughness: 2 is out of range [0, 1]"},
      {in + "-o '" + dir + "/o.exr' --size 100", "power-of-two"},
      {in + "-o '" + dir + "/o.ktx2' --samples 64", "--samples: only applies to method 'sampled'"},
      {in + "-o '" + dir + "/o.ktx2' --tolerance 5", "--tolerance"},
      {in + "-o '" + dir + "/o.ktx2' --half", "--half: only applies with an exr output"},
      {"'" + dir + "/missing.exr' -o '" + dir + "/o.ktx2' --size 0", "--size"},  // usage first
  };
  for (const auto& [args, expect] : cases) {
    const auto r = test::runCli("prefilter " + args);
    INFO(args << "\n" << r.output);
    CHECK(r.exitCode == 2);
    CHECK(r.output.rfind("prtbake: error: ", 0) == 0);
    CHECK(test::countOf(r.output, "\n") == 1);
    CHECK(r.output.find(expect) != std::string::npos);
    CHECK(listDir(dir) == std::vector<std::string>{"sky.exr"});
  }
}

TEST_CASE("CLI prefilter: base size 1, every lobe", "[prefilter][cli]") {
  const std::string dir = test::tempDir("prefilter-sizes");
  writeSky(dir + "/sky.exr");
  for (const std::string& args : {std::string("--size 1 --exr '") + dir + "/one.exr'",
                                  std::string("--size 8 --lobe charlie --levels 4"),
                                  std::string("--size 8 --lobe lambertian --schedule babylon --levels 4")}) {
    const auto r = test::runCli("prefilter '" + dir + "/sky.exr' -o '" + dir + "/out.ktx2' -q " + args);
    INFO(args << "\n" << r.output);
    REQUIRE(r.exitCode == 0);
    const json j = json::parse(readFile(dir + "/out.json"));
    const auto& levels = j["levels"];
    CHECK(levels.back()["size"].get<int>() >= 1);
    CHECK(test::fileBytes(dir + "/out.ktx2") > 80);
  }
  CHECK(test::fileExists(dir + "/one.exr"));
}

TEST_CASE("Job runner: prefilter jobs, whole and as two shards then merged", "[prefilter][jobs]") {
  const std::string dir = test::tempDir("prefilter-jobs");
  writeSky(dir + "/sky.exr");
  const std::vector<json> jobs = {
      {{"id", "spec"}, {"type", "prefilter"}, {"input", "sky.exr"}, {"size", 16}, {"schedule", "filament"},
       {"outputs", {{"ktx2", "out/spec.ktx2"}, {"exr", "out/spec.exr"}, {"json", "out/spec.json"}, {"png", "out/spec.png"}}}},
      {{"id", "sheen"}, {"type", "prefilter"}, {"input", "sky.exr"}, {"size", 8}, {"lobe", "charlie"},
       {"roughness", {0.25, 0.5, 1.0}}, {"float32", true}, {"outputs", {{"ktx2", "out/sheen.ktx2"}}}},
  };
  test::writeJobFile(dir + "/jobs.json", jobs);
  const auto whole = test::runCli("run '" + dir + "/jobs.json' --quiet");
  INFO(whole.output);
  REQUIRE(whole.exitCode == 0);
  for (const char* f : {"spec.ktx2", "spec.exr", "spec.json", "spec.png", "sheen.ktx2"}) CHECK(test::fileExists(dir + "/out/" + f));
  const json side = json::parse(readFile(dir + "/out/spec.json"));
  CHECK(side["job"] == "spec");
  CHECK(side["levels"].size() == 5);  // a base of 16 or less: the full chain
  // The same jobs in another folder, as two shards and a merge: the same bytes.
  const std::string other = test::tempDir("prefilter-jobs-sharded");
  writeSky(other + "/sky.exr");
  test::writeJobFile(other + "/jobs.json", jobs);
  for (int s = 0; s < 2; ++s) {
    const auto r = test::runCli("run '" + other + "/jobs.json' --quiet --shard " + std::to_string(s) + "/2");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
  }
  const auto merged = test::runCli("merge '" + other + "/jobs.json' --shards 2");
  INFO(merged.output);
  REQUIRE(merged.exitCode == 0);
  for (const char* f : {"spec.ktx2", "spec.exr", "sheen.ktx2"})
    CHECK(readFile(other + "/out/" + f) == readFile(dir + "/out/" + f));
  // A second run finds every job up to date.
  const auto again = test::runCli("run '" + dir + "/jobs.json'");
  CHECK(test::countOf(again.output, "[skipped]") == 2);
}

TEST_CASE("Job runner: prefilter jobs are validated like the command line", "[prefilter][jobs]") {
  const std::string dir = test::tempDir("prefilter-jobs-bad");
  writeSky(dir + "/sky.exr");
  test::writeJobFile(dir + "/jobs.json",
                     {{{"id", "a"}, {"type", "prefilter"}, {"input", "sky.exr"}, {"schedule", "linear"},
                       {"roughness", {0, 0.5}}, {"outputs", {{"ktx2", "a.ktx2"}}}},
                      {{"id", "b"}, {"type", "prefilter"}, {"input", "sky.exr"}, {"size", 100}, {"outputs", {{"exr", "b.exr"}}}},
                      {{"id", "c"}, {"type", "prefilter"}, {"input", "sky.exr"}, {"outputs", {{"json", "c.json"}}}},
                      {{"id", "d"}, {"type", "prefilter"}, {"input", "sky.exr"}, {"size", 64}, {"levels", 9},
                       {"outputs", {{"ktx2", "d.ktx2"}}}},
                      {{"id", "e"}, {"type", "prefilter"}, {"input", "sky.exr"}, {"lobe", "phong"}, {"outputs", {{"ktx2", "e.ktx2"}}}}});
  const auto r = test::runCli("run '" + dir + "/jobs.json'");
  INFO(r.output);
  CHECK(r.exitCode == 1);
  CHECK(r.output.find("job 'a': roughness: a roughness list is its own schedule") != std::string::npos);
  CHECK(r.output.find("job 'b': size: an exr output") != std::string::npos);
  CHECK(r.output.find("job 'c': outputs: a prefilter job needs a 'ktx2' or an 'exr' output") != std::string::npos);
  CHECK(r.output.find("job 'd': levels: 9 is out of range [1, 7]") != std::string::npos);
  CHECK(r.output.find("job 'e': lobe: unknown value 'phong'") != std::string::npos);
}

TEST_CASE("CLI preview prefilter: levels and split-sum spheres", "[prefilter][cli][preview]") {
  const std::string dir = test::tempDir("prefilter-preview");
  writeSky(dir + "/sky.exr");
  const auto r = test::runCli("preview prefilter '" + dir + "/sky.exr' -o '" + dir + "/p.png' --base 16 --size 64");
  INFO(r.output);
  REQUIRE(r.exitCode == 0);
  const std::string png = readFile(dir + "/p.png");
  REQUIRE(png.size() > 100);
  CHECK(png.compare(1, 3, "PNG") == 0);
  CHECK(png.find("split sum") == std::string::npos);  // the tEXt says what it shows:
  CHECK(png.find("(A + B)(N.V, r)") != std::string::npos);
}

TEST_CASE("KTX2 read back by ktx-parse: header, data format descriptor, levels, values", "[prefilter][cli]") {
  if (!nodeReady()) PRTBAKE_SKIP("node or tests/js/node_modules absent (npm ci in tests/js): KTX2 not read back with ktx-parse");
  const std::string dir = test::tempDir("prefilter-ktx-parse");
  writeSky(dir + "/sky.exr");
  const EnvMap env = loadEnvironment(dir + "/sky.exr");
  PrefilterOptions o;
  o.baseSize = 16;
  o.levels = 5;  // down to 1×1
  const PrefilterResult chain = prefilterEnvironment(test::runtime(), env, o);
  for (bool f32 : {false, true}) {
    writePrefilterFiles(chain, env, "", dir + "/c.ktx2", f32, "", false, "");
    const auto r = test::runShell("node '" + std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/ktx2_read.mjs' '" + dir + "/c.ktx2'");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    const json k = json::parse(r.output);
    CHECK(k["vkFormat"] == (f32 ? 109 : 97));
    CHECK(k["typeSize"] == (f32 ? 4 : 2));
    CHECK(k["pixelWidth"] == 16);
    CHECK(k["pixelHeight"] == 16);
    CHECK(k["pixelDepth"] == 0);
    CHECK(k["layerCount"] == 0);
    CHECK(k["faceCount"] == 6);
    CHECK(k["levelCount"] == 5);
    CHECK(k["supercompressionScheme"] == 0);
    CHECK(k["dfd"]["colorModel"] == 1);        // RGBSDA
    CHECK(k["dfd"]["colorPrimaries"] == 1);    // BT709
    CHECK(k["dfd"]["transferFunction"] == 1);  // LINEAR
    CHECK(k["dfd"]["bytesPlane"][0] == (f32 ? 16 : 8));
    REQUIRE(k["dfd"]["samples"].size() == 4);
    CHECK(k["dfd"]["samples"][3]["channelType"] == 0xCF);  // alpha, FLOAT | SIGNED
    CHECK(k["keyValue"]["KTXwriter"].get<std::string>().rfind("prtbake", 0) == 0);
    // Each level's integral over the sphere against the chain's own (texel-centre solid angles
    // on both sides; half rounding ~1e-3).
    for (size_t l = 0; l < chain.levels.size(); ++l) {
      const int n = chain.levels[l].spec.size;
      CHECK(k["levels"][l]["size"] == n);
      CHECK(k["levels"][l]["byteLength"] == 6 * n * n * (f32 ? 16 : 8));
      CHECK(k["levels"][l]["finite"] == true);
      double sum = 0;
      for (int f = 0; f < 6; ++f)
        for (int row = 0; row < n; ++row)
          for (int col = 0; col < n; ++col) {
            const double u = 2.0 * (col + 0.5) / n - 1, v = 2.0 * (row + 0.5) / n - 1, q = u * u + v * v + 1;
            sum += chain.levels[l].rgb[3 * ((size_t(f) * n + row) * n + col)] * 4.0 / (double(n) * n) / (q * std::sqrt(q));
          }
      CHECK(k["levels"][l]["moments"][0][3].get<double>() == Approx(sum).epsilon(f32 ? 1e-5 : 2e-3));
    }
  }
}
