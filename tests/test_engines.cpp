// Engine packages (`prtbake ibl`), read back by the engines' own code: three.js, Filament,
// Babylon.js and the glTF-Sample-Viewer from npm (tests/js/engines.mjs, pinned in tests/js/package-lock.json), the KTX2 cubes by
// ktx-parse (tests/js/ktx2_read.mjs), the 16-bit tables by stb_image.
#include <stb/stb_image.h>

#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "prtbake/ibl.h"
#include "prtbake/envmap.h"
#include "prtbake/lut.h"
#include "prtbake/preview.h"
#include "prtbake/env.h"
#include "prtbake/prefilter.h"
#include "prtbake/sh.h"
#include "engine_test_helpers.h"
#include "test_common.h"

using namespace prtbake;
using json = nlohmann::json;

namespace {

using test::chromiumResult;
using test::fillPage;
using test::nodeReady;
using test::replaceAll;
using test::srgb8;

const std::string kSky = std::string(PRTBAKE_TEST_SOURCE_DIR) + "/../assets/sky.exr";
// The package the tests read: small cubes and tables so that it bakes in seconds.
const std::string kPackageArgs = " --size 32 --lut-size 32 --quiet";
constexpr int kTexelStride = 7;

std::string readText(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

// Whether node and the Khronos glTF-Validator (tests/js/node_modules) are here.
bool gltfValidatorReady() {
  return test::runShell("command -v node").exitCode == 0 &&
         test::fileExists(std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/node_modules/gltf-validator/package.json");
}

// The glTF-Validator's report on `file` (tests/js/gltf_validate.mjs): issue counts and messages.
json gltfValidate(const std::string& file) {
  const test::CliResult r =
      test::runShell("node '" + std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/gltf_validate.mjs' '" + file + "'");
  INFO(r.output.substr(0, 3000));
  REQUIRE(r.exitCode == 0);
  return json::parse(r.output);
}

// The report on transport's glTF copy `out` of `mesh` (the .npy beside it), with `options`.
json gltfCopyReport(const std::string& mesh, const std::string& out, const std::string& options) {
  const std::string npy = out.substr(0, out.find_last_of('/')) + "/t.npy";
  REQUIRE(test::runCli("transport '" + mesh + "' -o '" + npy + "' " + options + " --gltf '" + out + "' --quiet").exitCode == 0);
  return gltfValidate(out);
}

// 1200 directions of a Fibonacci sphere.
std::vector<std::array<double, 3>> sphereDirections() {
  std::vector<std::array<double, 3>> d;
  const int n = 1200;
  const double golden = 3.14159265358979323846 * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double y = 1 - 2 * (i + 0.5) / n, r = std::sqrt(1 - y * y), phi = golden * i;
    d.push_back({r * std::cos(phi), y, r * std::sin(phi)});
  }
  return d;
}

// Runs engines.mjs on a package and parses its JSON line.
json engineReadback(const std::string& dir, const std::string& dirsFile) {
  const test::CliResult r = test::runShell("node '" + std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/engines.mjs' '" + dir +
                                           "' '" + dirsFile + "' " + std::to_string(kTexelStride));
  INFO("engines.mjs exit " << r.exitCode << ": " << r.output.substr(0, 3000));
  REQUIRE(r.exitCode == 0);
  const size_t at = r.output.find("{\"package\"");
  REQUIRE(at != std::string::npos);
  return json::parse(r.output.substr(at, r.output.find('\n', at) - at));
}

// The largest |engine − prtbake| over directions and channels, relative to the value, with
// values below a tenth of the channel's largest magnitude measured against that tenth: the SH
// cross zero, and three.js's constants have 6 significant digits (0.282095, 0.488603, ...: up
// to 1.4e-6 relative each), so a value that the terms cancel down to 1 % of the peak carries
// ~3e-5 of three.js's own rounding whatever the coefficients.
double worstRelative(const json& engine, const std::vector<std::array<double, 3>>& mine) {
  double peak = 0;
  for (const auto& v : mine)
    for (double x : v) peak = std::max(peak, std::abs(x));
  double worst = 0;
  for (size_t i = 0; i < mine.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      const double e = engine[i][c].get<double>(), m = mine[i][size_t(c)];
      worst = std::max(worst, std::abs(e - m) / std::max(std::abs(m), 0.1 * peak));
    }
  return worst;
}

}  // namespace

TEST_CASE("Engines: three.js, Filament and Babylon.js evaluate the package's SH as prtbake does", "[engines]") {
  // Agreement asked of the exports: 1e-5 relative. three.js evaluates in double (measured
  // ~1e-15), Filament's getColorEstimate in float32 wasm from numbers printed with 9 (KTX "sh")
  // or 15 (sh.txt) significant digits (measured ~3e-7), Babylon in double (measured ~1e-15: the
  // .env polynomial is the exact inverse of its FromPolynomial). Seen failing: the three.js
  // coefficients with the Condon–Shortley signs kept, the Filament ones without the π, both ~1;
  // the Babylon ones without the mirror in x, 7.7 (the mirror itself is the mapping of Babylon's glTF
  // loader; a render in Babylon is what proves it).
  constexpr double kEngineTol = 1e-5;
  if (!nodeReady()) PRTBAKE_SKIP("node or tests/js/node_modules absent (npm ci in tests/js): the engines cannot run");
  const std::string dir = test::tempDir("engines");
  const test::CliResult bake = test::runCli("ibl '" + kSky + "' -o '" + dir + "/pkg'" + kPackageArgs);
  INFO(bake.output);
  REQUIRE(bake.exitCode == 0);
  const json side = json::parse(readText(dir + "/pkg/ibl.json"));
  ShCoeffs c;
  c.order = 3;
  for (const auto& v : side["radiance_sh"]["coefficients"]) c.rgb.push_back({v[0], v[1], v[2]});
  REQUIRE(c.rgb.size() == 9);

  const auto dirs = sphereDirections();
  json dj = json::array();
  for (const auto& d : dirs) dj.push_back(d);
  std::ofstream(dir + "/dirs.json") << dj.dump();
  // prtbake's own values: radiance Σ c_i Y_i(d) and irradiance Σ Â_l c_i Y_i(d).
  std::vector<std::array<double, 3>> radiance, irradiance, irradianceClamped;
  for (const auto& d : dirs) {
    double y[9];
    shEval(3, d[0], d[1], d[2], y);
    std::array<double, 3> l{}, e{};
    for (int i = 0; i < 9; ++i)
      for (int k = 0; k < 3; ++k) {
        l[size_t(k)] += c.rgb[size_t(i)][size_t(k)] * y[i];
        e[size_t(k)] += clampedCosineFactor(i == 0 ? 0 : i < 4 ? 1 : 2) * c.rgb[size_t(i)][size_t(k)] * y[i];
      }
    radiance.push_back(l);
    irradiance.push_back(e);
    irradianceClamped.push_back({std::max(e[0], 0.0), std::max(e[1], 0.0), std::max(e[2], 0.0)});
  }
  const json got = engineReadback(dir + "/pkg", dir + "/dirs.json");
  CHECK(got["three"]["type"] == "LightProbe");
  CHECK(got["three"]["isLightProbe"] == true);
  CHECK(got["three"]["intensity"] == 1);
  const double threeL = worstRelative(got["three"]["radiance"], radiance);
  const double threeE = worstRelative(got["three"]["irradiance"], irradiance);
  // Filament's SH reconstruction clamps at 0 (its shader does too).
  const double filKey = worstRelative(got["filament"]["irradianceKey"], irradianceClamped);
  const double filTxt = worstRelative(got["filament"]["irradianceTxt"], irradianceClamped);
  const double babEnv = worstRelative(got["babylon"]["env"]["irradiance"], irradiance);
  const double babGlb = worstRelative(got["babylon"]["glb"]["irradiance"], irradiance);
  INFO("three.js radiance " << threeL << ", irradiance " << threeE << "; Filament KTX sh " << filKey << ", sh.txt " << filTxt
                            << "; Babylon .env " << babEnv << ", .glb " << babGlb);
  CHECK(threeL < kEngineTol);
  CHECK(threeE < kEngineTol);
  CHECK(filKey < kEngineTol);
  CHECK(filTxt < kEngineTol);
  CHECK(babEnv < kEngineTol);
  CHECK(babGlb < kEngineTol);
  // Babylon's loader accepts the .env's layout: every level from 32² to 1², six PNGs each, read at
  // lod = log2(size · α_G) · 1; the .glb's light has the same chain.
  const json& env = got["babylon"]["env"];
  CHECK(env["version"] == 2);
  CHECK(env["width"] == 32);
  CHECK(env["levels"] == 6);
  CHECK(env["faceSizes"] == json::array({6, 6, 6, 6, 6, 6}));
  CHECK(env["allPng"] == true);
  CHECK(env["lodGenerationScale"] == 1);
  CHECK(got["babylon"]["glb"]["specularImageSize"] == 32);
  CHECK(got["babylon"]["glb"]["levels"] == 6);
  CHECK(got["babylon"]["glb"]["images"] == 36);

  // The same comparison fails on a deliberately wrong export: one coefficient's sign flipped
  // (three.js: L1,-1; Filament: L1,1 in both the KTX key and sh.txt; Babylon: the .env's x field).
  json probe = json::parse(readText(dir + "/pkg/threejs/light_probe.json"));
  for (int k = 0; k < 3; ++k) probe["object"]["sh"][3 + k] = -probe["object"]["sh"][3 + k].get<double>();
  std::ofstream(dir + "/pkg/threejs/light_probe.json") << probe.dump();
  std::string shTxt = readText(dir + "/pkg/filament/sh.txt");
  const size_t line3 = shTxt.find("// L11");
  const size_t open = shTxt.rfind('(', line3);
  shTxt.insert(open + 1, "-");  // the red value of L11 negated (it was printed with a leading space or sign)
  std::ofstream(dir + "/pkg/filament/sh.txt") << shTxt;
  // The .env: magic, manifest, NUL, images placed relative to the NUL; the red value of the
  // polynomial's x negated.
  const std::string envFile = readText(dir + "/pkg/babylon/environment.env");
  const size_t nul = envFile.find('\0', 8);
  REQUIRE(nul != std::string::npos);
  json manifest = json::parse(envFile.substr(8, nul - 8));
  manifest["irradiance"]["x"][0] = -manifest["irradiance"]["x"][0].get<double>();
  std::ofstream(dir + "/pkg/babylon/environment.env", std::ios::binary)
      << envFile.substr(0, 8) << manifest.dump() << envFile.substr(nul);
  const json wrong = engineReadback(dir + "/pkg", dir + "/dirs.json");
  const double wrongThree = worstRelative(wrong["three"]["irradiance"], irradiance);
  const double wrongFil = worstRelative(wrong["filament"]["irradianceTxt"], irradianceClamped);
  const double wrongBab = worstRelative(wrong["babylon"]["env"]["irradiance"], irradiance);
  INFO("flipped sign: three.js " << wrongThree << ", Filament sh.txt " << wrongFil << ", Babylon .env " << wrongBab);
  CHECK(wrongThree > 100 * kEngineTol);
  CHECK(wrongFil > 100 * kEngineTol);
  CHECK(wrongBab > 100 * kEngineTol);
}

TEST_CASE("Engines: Filament reads the KTX1 cubes prtbake prefiltered, face by face", "[engines]") {
  // R11F_G11F_B10F rounds to nearest: relative 2^-7 (red, green) and 2^-6 (blue), or 2^-21
  // absolute below the normal range. Seen failing: face +X mirrored (2.1 on this map).
  if (!nodeReady()) PRTBAKE_SKIP("node or tests/js/node_modules absent (npm ci in tests/js): the engines cannot run");
  const std::string dir = test::tempDir("engines_ktx1");
  REQUIRE(test::runCli("ibl '" + kSky + "' -o '" + dir + "/pkg' --target filament" + kPackageArgs).exitCode == 0);
  std::ofstream(dir + "/dirs.json") << "[[0,1,0]]";
  const json got = engineReadback(dir + "/pkg", dir + "/dirs.json");
  const json& f = got["filament"];
  CHECK(f["glInternalFormat"] == 0x8C3A);
  CHECK(f["glType"] == 0x8C3A);  // as cmgen writes it (Ktx1Reader maps it to UINT_10F_11F_11F_REV)
  CHECK(f["isCubemap"] == true);
  CHECK(f["skybox"]["isCubemap"] == true);
  CHECK(f["skybox"]["levelCount"] == 1);
  CHECK(f["skybox"]["size"] == 32);

  // The same chain in-process (deterministic: the same bits the command wrote, before packing).
  EnvLoadOptions lo;
  const EnvMap env = loadEnvironment(kSky, lo);
  PrefilterOptions o;
  o.schedule = PrefilterSchedule::Filament;
  o.baseSize = 32;
  const PrefilterResult chain = prefilterEnvironment(test::runtime(), env, o);
  REQUIRE(f["levelCount"] == chain.levels.size());
  auto worstAgainst = [&](bool mirrorFace0) {
    double worst = 0;
    for (size_t l = 0; l < chain.levels.size(); ++l) {
      const int n = chain.levels[l].spec.size;
      CHECK(f["levels"][l]["size"] == n);
      for (const auto& t : f["levels"][l]["texels"]) {
        size_t i = t[0].get<size_t>();
        const size_t face = i / (size_t(n) * n), row = (i / n) % n, col = i % n;
        if (mirrorFace0 && face == 0) i = (face * n + row) * n + (n - 1 - col);
        for (int k = 0; k < 3; ++k) {
          const double mine = chain.levels[l].rgb[3 * i + size_t(k)], theirs = t[1 + k].get<double>();
          const double step = std::max(std::abs(mine) * std::ldexp(1.0, k == 2 ? -6 : -7), std::ldexp(1.0, -21));
          worst = std::max(worst, std::abs(theirs - std::max(mine, 0.0)) / step);
        }
      }
    }
    return worst;  // in units of the format's rounding bound
  };
  const double ok = worstAgainst(false), mirrored = worstAgainst(true);
  INFO("worst texel error / rounding bound: " << ok << "; against face +X mirrored: " << mirrored);
  CHECK(ok <= 1.0001);
  CHECK(mirrored > 10);
}

// The page: Babylon.js (from tests/js/node_modules) loads __ENV__ as scene.environmentTexture
// would (CubeTexture with its .env loader: RGBD PNGs decoded and expanded into a half-float cube
// on the GPU), then reads every face of every level back with texture.readPixels.
const char* kBabylonEnvPage = R"(<!doctype html><html><body><canvas id="c" width="64" height="64"></canvas>
<script type="module">
import { Engine } from '__CORE__/Engines/engine.js';
import { Scene } from '__CORE__/scene.js';
import { CubeTexture } from '__CORE__/Materials/Textures/cubeTexture.js';
import '__CORE__/Materials/Textures/Loaders/envTextureLoader.js';
let settle;
window.result = new Promise((resolve) => { settle = resolve; });
const engine = new Engine(document.getElementById('c'), false, { preserveDrawingBuffer: true });
const scene = new Scene(engine);
const tex = new CubeTexture('file://__ENV__', scene, null, false, null, async () => {
  try {
    const size = tex.getSize().width, levels = [];
    for (let l = 0; (size >> l) >= 1; ++l) {
      const faces = [];
      for (let f = 0; f < 6; ++f) faces.push(Array.from(await tex.readPixels(f, l)));
      levels.push(faces);
    }
    settle('RESULT ' + JSON.stringify({ size, textureType: tex.textureType, levels }));
  } catch (e) { settle('ERROR ' + e); }
}, (message, e) => { settle('ERROR loading: ' + message + ' ' + e); });
</script></body></html>
)";

TEST_CASE("Engines: Babylon.js in Chromium reads the .env cube prtbake prefiltered, texel by texel", "[engines][chromium]") {
  // Babylon's texels, as its loader decodes them, against the chain prtbake prefiltered, looked up
  // where Babylon's frame puts them (x negated) in the GL orientation Babylon samples. Tolerance:
  // the RGBD byte's rounding, ((g + ½/255)^2.2 − g^2.2) / D for the stored g = (v D)^(1/2.2), plus
  // the half-float texture's 2^-11 relative. Values above RGBD's 255 are left out (clamped). Seen
  // failing: face +X mirrored, and the images stored top row first (rows flipped).
  PRTBAKE_CHROMIUM_OR_SKIP(chromium, "Babylon");
  const std::string dir = test::tempDir("engines_babylon_env");
  REQUIRE(test::runCli("ibl '" + kSky + "' -o '" + dir + "/pkg' --target babylon" + kPackageArgs).exitCode == 0);
  const std::string page = dir + "/env.html";
  std::ofstream(page) << replaceAll(replaceAll(kBabylonEnvPage, "__CORE__",
                                               std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/node_modules/@babylonjs/core"),
                                    "__ENV__", dir + "/pkg/babylon/environment.env");
  const test::CliResult res = test::chromiumPage(chromium, page);
  const size_t at = res.output.find("RESULT {");
  INFO("chromium_page.mjs exit " << res.exitCode << ": " << res.output.substr(0, 2000));
  REQUIRE(at != std::string::npos);
  const json got = json::parse(res.output.substr(at + 7, res.output.find('\n', at) - at - 7));
  CHECK(got["size"] == 32);

  EnvLoadOptions lo;
  const EnvMap env = loadEnvironment(kSky, lo);
  PrefilterOptions o;
  o.schedule = PrefilterSchedule::Babylon;
  o.baseSize = 32;
  o.levels = 6;
  const PrefilterResult chain = prefilterEnvironment(test::runtime(), env, o);
  REQUIRE(got["levels"].size() == chain.levels.size());
  const auto faces = standardCubeBases();
  // Babylon's face f, GL row r, column c shows prtbake's direction with x negated.
  auto worstAgainst = [&](bool mirrorFace0, bool flipRows) {
    double worst = 0;
    long long compared = 0;
    for (size_t l = 0; l < chain.levels.size(); ++l) {
      const int n = chain.levels[l].spec.size;
      for (int f = 0; f < 6; ++f) {
        const json& px = got["levels"][l][f];
        REQUIRE(px.size() == size_t(n) * n * 4);
        for (int r = 0; r < n; ++r)
          for (int c = 0; c < n; ++c) {
            const int row = flipRows ? n - 1 - r : r, col = (mirrorFace0 && f == 0) ? n - 1 - c : c;
            const double u = 2 * (col + 0.5) / n - 1, v = 2 * (row + 0.5) / n - 1;
            const auto& b = faces[size_t(f)];
            double d[3];
            for (int k = 0; k < 3; ++k) d[k] = u * b.axisU[size_t(k)] + v * b.axisV[size_t(k)] + b.axisN[size_t(k)];
            d[0] = -d[0];
            // The prtbake texel holding d: by the major axis, then (u, v) on that face.
            int best = 0;
            for (int g = 1; g < 6; ++g) {
              const auto& a = faces[size_t(g)].axisN, & w = faces[size_t(best)].axisN;
              if (a[0] * d[0] + a[1] * d[1] + a[2] * d[2] > w[0] * d[0] + w[1] * d[1] + w[2] * d[2]) best = g;
            }
            const auto& s = faces[size_t(best)];
            const double dn = s.axisN[0] * d[0] + s.axisN[1] * d[1] + s.axisN[2] * d[2];
            const int sc = std::clamp(int(std::floor(((s.axisU[0] * d[0] + s.axisU[1] * d[1] + s.axisU[2] * d[2]) / dn + 1) / 2 * n)), 0, n - 1);
            const int sr = std::clamp(int(std::floor(((s.axisV[0] * d[0] + s.axisV[1] * d[1] + s.axisV[2] * d[2]) / dn + 1) / 2 * n)), 0, n - 1);
            const float* mine = &chain.levels[l].rgb[3 * ((size_t(best) * n + size_t(sr)) * n + size_t(sc))];
            const double m = std::max({double(mine[0]), double(mine[1]), double(mine[2]), 1e-7});
            if (m > 255) continue;  // beyond RGBD's range: clamped
            const double D = std::clamp(std::floor(std::max(255.0 / m, 1.0)), 1.0, 255.0) / 255.0;
            for (int k = 0; k < 3; ++k) {
              const double g = std::pow(double(mine[k]) * D, 1 / 2.2);
              const double bound = (std::pow(std::min(1.0, g + 0.5 / 255), 2.2) - std::pow(g, 2.2)) / D +
                                   std::abs(mine[k]) * std::ldexp(1.0, -11) + 1e-6;
              const double theirs = px[(size_t(r) * n + size_t(c)) * 4 + size_t(k)].get<double>();
              worst = std::max(worst, std::abs(theirs - mine[k]) / bound);
            }
            ++compared;
          }
      }
    }
    CHECK(compared > 6 * 1000);
    return worst;  // in units of the bound
  };
  const double ok = worstAgainst(false, false), mirrored = worstAgainst(true, false), flipped = worstAgainst(false, true);
  INFO("worst texel error / bound: " << ok << "; face +X mirrored: " << mirrored << "; rows flipped: " << flipped);
  CHECK(ok <= 1);
  CHECK(mirrored > 10);
  CHECK(flipped > 10);
}

// The page: Babylon.js renders a unit sphere at the origin, seen from +Z by an orthographic
// camera framing it exactly, into a float render target (linear radiance: image processing is
// left to a post-process that is not there), once per shot [name, metallic, roughness]: a white
// metal (the prefiltered chain and Babylon's BRDF table), and a dielectric whose specular is
// turned off (metallicF0Factor 0: its diffuse alone, from the .env's irradiance).
const char* kBabylonRenderPage = R"(<!doctype html><html><body><canvas id="c" width="64" height="64"></canvas>
<script type="module">
import { Engine } from '__CORE__/Engines/engine.js';
import { Scene } from '__CORE__/scene.js';
import { CubeTexture } from '__CORE__/Materials/Textures/cubeTexture.js';
import '__CORE__/Materials/Textures/Loaders/envTextureLoader.js';
import { PBRMaterial } from '__CORE__/Materials/PBR/pbrMaterial.js';
import { CreateSphere } from '__CORE__/Meshes/Builders/sphereBuilder.js';
import { FreeCamera } from '__CORE__/Cameras/freeCamera.js';
import { Camera } from '__CORE__/Cameras/camera.js';
import { RenderTargetTexture } from '__CORE__/Materials/Textures/renderTargetTexture.js';
import { Vector3 } from '__CORE__/Maths/math.vector.js';
import { Color3, Color4 } from '__CORE__/Maths/math.color.js';
let settle;
window.result = new Promise((resolve) => { settle = resolve; });
const N = __SIZE__;
try {
  const engine = new Engine(document.getElementById('c'), false, { preserveDrawingBuffer: true });
  const scene = new Scene(engine);
  scene.clearColor = new Color4(0, 0, 0, 0);
  scene.imageProcessingConfiguration.applyByPostProcess = true;  // linear output: no tone map, no gamma
  // Far away: Babylon shades with the direction from its eye to the point, also when orthographic.
  const camera = new FreeCamera('camera', new Vector3(0, 0, 1000), scene);
  camera.setTarget(Vector3.Zero());
  camera.mode = Camera.ORTHOGRAPHIC_CAMERA;
  camera.orthoLeft = -1; camera.orthoRight = 1; camera.orthoTop = 1; camera.orthoBottom = -1;
  camera.minZ = 990; camera.maxZ = 1010;
  scene.environmentTexture = new CubeTexture('file://__ENV__', scene);
  const sphere = CreateSphere('sphere', { diameter: 2, segments: 256 }, scene);
  const mat = new PBRMaterial('m', scene);
  mat.albedoColor = new Color3(1, 1, 1);
  mat.brdf.useEnergyConservation = false;
  sphere.material = mat;
  const rtt = new RenderTargetTexture('rt', { width: N, height: N }, scene, false, true, 1 /* float */);
  rtt.renderList = [sphere];
  rtt.activeCamera = camera;
  const shots = {};
  scene.executeWhenReady(async () => {
    try {
      for (const [name, metallic, roughness] of __SHOTS__) {
        mat.metallic = metallic; mat.roughness = roughness;
        mat.metallicF0Factor = metallic > 0 ? 1 : 0;  // a dielectric without specular: its diffuse alone
        await new Promise((r) => scene.executeWhenReady(r));
        // Rendered until two renders agree: the first ones can come before Babylon's own BRDF
        // table (a PNG it loads itself) is in place.
        let previous = '';
        for (let attempt = 0; attempt < 50; ++attempt) {
          rtt.resetRefreshCounter();
          rtt.render();
          shots[name] = Array.from(await rtt.readPixels());
          const now = JSON.stringify(shots[name]);
          if (now === previous) break;
          previous = now;
          await new Promise((r) => setTimeout(r, 50));
        }
      }
      settle('RESULT ' + JSON.stringify({ size: N, shots }));
    } catch (e) { settle('ERROR ' + e + ' ' + e.stack); }
  });
} catch (e) { settle('ERROR ' + e + ' ' + e.stack); }
</script></body></html>
)";

// prtbake's diffuse sphere: albedo 1 · E(n) / π from the SH, on the sphere and camera of
// renderSplitSumSphere (radius 1 from +Z, orthographic, image² pixels, row 0 on top).
LinearImage diffuseSphere(const ShCoeffs& radiance, int image) {
  LinearImage img;
  img.width = img.height = image;
  img.rgb.assign(size_t(image) * size_t(image) * 3, 0.0f);
  for (int y = 0; y < image; ++y)
    for (int x = 0; x < image; ++x) {
      const double nx = (x + 0.5 - image / 2.0) / (image / 2.0), ny = -(y + 0.5 - image / 2.0) / (image / 2.0);
      if (nx * nx + ny * ny >= 1) continue;
      double sh[9];
      shEval(3, nx, ny, std::sqrt(1 - nx * nx - ny * ny), sh);
      for (int c = 0; c < 3; ++c) {
        double e = 0;
        for (int i = 0; i < 9; ++i) e += clampedCosineFactor(i == 0 ? 0 : i < 4 ? 1 : 2) * radiance.rgb[size_t(i)][size_t(c)] * sh[i];
        img.rgb[3 * (size_t(y) * size_t(image) + size_t(x)) + size_t(c)] = float(e / 3.14159265358979323846);
      }
    }
  return img;
}

// sphereLevels' exposure for `want`: 1 / (2 × its mean over the sphere's inner pixels). Pages
// whose engines write 8-bit output apply it before writing, so that the bytes keep precision.
double sphereExposure(const LinearImage& want) {
  const int image = want.width;
  double mean = 0;
  long long count = 0;
  for (int y = 0; y < image; ++y)
    for (int x = 0; x < image; ++x) {
      const double nx = (x + 0.5 - image / 2.0) / (image / 2.0), ny = -(y + 0.5 - image / 2.0) / (image / 2.0);
      if (nx * nx + ny * ny > 0.95 * 0.95) continue;
      for (int c = 0; c < 3; ++c) mean += want.rgb[3 * (size_t(y) * image + size_t(x)) + size_t(c)];
      count += 3;
    }
  return 1 / (2 * mean / double(count));
}

// Mean |Δ| in 8-bit levels between an engine's render `px` (RGBA floats, bottom row first, as
// WebGL reads a target back) and prtbake's `want`, over the sphere's inner pixels (|n_xy| ≤ 0.95:
// the silhouette of a tessellated sphere and grazing lookups left out), both scaled by the same
// exposure, 1 / (2 × prtbake's mean on the sphere), so that a typical pixel sits mid-range (the
// sky is HDR: unscaled, both would clamp to white; scaled by its sun, most would be black), then
// tone-mapped as prtbake's previews. *off: the fraction of pixels more than 32 levels off in a
// channel, which is what a misplaced label shows as where a plain background dominates the mean.
double sphereLevels(const json& px, const LinearImage& want, double* off = nullptr) {
  const int image = want.width;
  REQUIRE(px.size() == size_t(image) * image * 4);
  std::vector<std::pair<size_t, size_t>> pixels;  // (prtbake's index, the engine's)
  for (int y = 0; y < image; ++y)
    for (int x = 0; x < image; ++x) {
      const double nx = (x + 0.5 - image / 2.0) / (image / 2.0), ny = -(y + 0.5 - image / 2.0) / (image / 2.0);
      if (nx * nx + ny * ny <= 0.95 * 0.95) pixels.push_back({size_t(y) * image + size_t(x), size_t(image - 1 - y) * image + size_t(x)});
    }
  const double exposure = sphereExposure(want);
  double sum = 0;
  long long far = 0;
  for (const auto& [mine, theirs] : pixels) {
    double worst = 0;
    for (int c = 0; c < 3; ++c) {
      const double d = std::abs(srgb8(px[4 * theirs + size_t(c)].get<double>() * exposure) -
                                srgb8(want.rgb[3 * mine + size_t(c)] * exposure));
      sum += d;
      worst = std::max(worst, d);
    }
    far += worst > 32 ? 1 : 0;
  }
  if (off) *off = double(far) / double(pixels.size());
  return sum / double(3 * pixels.size());
}

// The chain with one face (+X, −X, +Y, −Y, +Z, −Z = 0..5) mirrored left to right in every level:
// the deliberately wrong export of the render tests.
PrefilterResult mirroredFace(PrefilterResult chain, size_t face) {
  for (auto& l : chain.levels) {
    const size_t n = size_t(l.spec.size);
    for (size_t r = 0; r < n; ++r)
      for (size_t c = 0; c < n / 2; ++c)
        for (size_t k = 0; k < 3; ++k)
          std::swap(l.rgb[3 * ((face * n + r) * n + c) + k], l.rgb[3 * ((face * n + r) * n + n - 1 - c) + k]);
  }
  return chain;
}

// prtbake's white metal sphere with the split sum's second factor 1: Filament and the glTF-Sample-
// Viewer compensate multiple scattering (Filament: Fr = P · E / dfg.y; the viewer: FssEss +
// FmsEms), which for a white metal (f0 = 1) leaves the prefiltered radiance P(R) itself.
LinearImage whiteMetalSphere(const PrefilterResult& chain, double roughness, int image) {
  LutResult unit;
  unit.size = 2;
  unit.a.assign(4, 1.0f);
  unit.b.assign(4, 0.0f);
  return renderSplitSumSphere(chain, unit, roughness, image);
}

// Mean |Δ| in 8-bit levels (sphereLevels) between Babylon's renders and prtbake's, for the package baked from
// `envPath` at base size size, kImage² pixels: a mirror metal sphere and a diffuse one; with
// `controls`, also for the .env with its +Z face mirrored (metal) and with the polynomial's x
// sign flipped (diffuse).
struct SphereRenders {
  double metal = 0, diffuse = 0, mirroredMetal = 0, flippedDiffuse = 0;
  double roughMetal = 0;  // the glTF-Sample-Viewer's: a white metal at level 1's roughness
  double roughness = 0;   // Filament's: the roughness of its metal sphere
  // The fraction of the metal sphere's pixels that differ by more than 32 levels in a channel:
  // what a misplaced label shows as, where the mean is dominated by a plain background.
  double metalOff = 0, mirroredMetalOff = 0;
};
SphereRenders babylonSphereRenders(const std::string& chromium, const std::string& envPath, bool controls, int size,
                                   int image) {
  SphereRenders out;
  const std::string dir = test::tempDir("engines_babylon_render");
  // The package's chain and SH, rebuilt in-process (the same calls and bits as `prtbake ibl`).
  EnvLoadOptions lo;
  const EnvMap env = loadEnvironment(envPath, lo);
  PrefilterOptions po;
  po.schedule = PrefilterSchedule::Babylon;
  po.baseSize = size;
  po.levels = int(std::lround(std::log2(size))) + 1;
  const PrefilterResult chain = prefilterEnvironment(test::runtime(), env, po);
  EnvProjectOptions eo;
  eo.order = 3;
  const ShCoeffs radiance = projectEnvironment(test::runtime(), env, eo).radiance;
  auto writeEnv = [&](const std::string& path, const PrefilterResult& c, EngineSh polynomial) {
    std::vector<std::vector<std::string>> pngs;
    for (const auto& l : c.levels) pngs.push_back(babylonRgbdFaces(l.spec.size, l.rgb));
    std::ofstream(path, std::ios::binary) << babylonEnvBytes(pngs, size, polynomial, 1.0);
  };
  writeEnv(dir + "/good.env", chain, babylonEnvPolynomial(radiance));
  if (controls) {
    const PrefilterResult mirrored = mirroredFace(chain, 4);
    writeEnv(dir + "/mirrored.env", mirrored, babylonEnvPolynomial(radiance));
    EngineSh flipped = babylonEnvPolynomial(radiance);
    for (int k = 0; k < 3; ++k) flipped[size_t(k)] = -flipped[size_t(k)];  // the polynomial's x
    writeEnv(dir + "/flipped.env", chain, flipped);
  }

  // Roughness 0: Babylon reads level 0 (its lod log2(size · 0.0005) is below 0), as prtbake's
  // preview does below level 0's roughness. (Rougher levels: see docs/engines.md, "Not yet".)
  const double r = 0;
  char shots[160];
  std::snprintf(shots, sizeof shots, "[['metal', 1, %.17g], ['diffuse', 0, 1]]", r);
  auto render = [&](const std::string& name) {
    const std::string page = dir + "/" + name + ".html";
    std::ofstream(page) << replaceAll(replaceAll(replaceAll(replaceAll(kBabylonRenderPage, "__CORE__",
                                                                       std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/node_modules/@babylonjs/core"),
                                                            "__ENV__", dir + "/" + name + ".env"),
                                                 "__SIZE__", std::to_string(image)),
                                      "__SHOTS__", shots);
    return chromiumResult(chromium, page);
  };

  // prtbake's own: the preview's split-sum sphere, and albedo · E(n) / π from the SH.
  LutOptions lutOptions;
  lutOptions.size = 64;
  lutOptions.samples = 1024;
  const LutResult lut = computeLut(test::runtime(), lutOptions);
  const LinearImage metal = renderSplitSumSphere(chain, lut, r, image), diffuse = diffuseSphere(radiance, image);
  const json good = render("good");
  out.metal = sphereLevels(good["shots"]["metal"], metal, &out.metalOff);
  out.diffuse = sphereLevels(good["shots"]["diffuse"], diffuse);
  if (controls) {
    out.mirroredMetal = sphereLevels(render("mirrored")["shots"]["metal"], metal, &out.mirroredMetalOff);
    out.flippedDiffuse = sphereLevels(render("flipped")["shots"]["diffuse"], diffuse);
  }
  return out;
}

TEST_CASE("Engines: Babylon.js renders spheres lit by the package as prtbake's preview does", "[engines][chromium]") {
  // Acceptance: mean |Δ| ≤ 2 8-bit levels over the sphere's pixels (after prtbake's tone map),
  // the rim (|n_xy| > 0.95: silhouette pixels of a tessellated sphere, grazing lookups) left out.
  // Both sides read the same chain and SH; they differ by Babylon's BRDF table against prtbake's,
  // its RGBD decode and half-float cube, and filtering on the GPU. Seen failing: the .env with
  // its +Z face mirrored (metal sphere), and with the polynomial's x sign flipped (diffuse).
  constexpr double kMeanLevels = 2.0;
  PRTBAKE_CHROMIUM_OR_SKIP(chromium, "Babylon");
  const SphereRenders r = babylonSphereRenders(chromium, kSky, true, 64, 96);
  INFO("mean |delta| in 8-bit levels: mirror metal " << r.metal << ", diffuse " << r.diffuse << "; +Z face mirrored, metal "
                                                     << r.mirroredMetal << "; polynomial x flipped, diffuse " << r.flippedDiffuse);
  CHECK(r.metal <= kMeanLevels);
  CHECK(r.diffuse <= kMeanLevels);
  CHECK(r.mirroredMetal > kMeanLevels);
  CHECK(r.flippedDiffuse > kMeanLevels);
}

TEST_CASE("Engines: Babylon.js reads level i of the .env at the roughness prtbake gives level i", "[engines][chromium]") {
  // The roughness schedule as Babylon's own shader applies it: an .env whose level i holds
  // (i, 1, 0) everywhere lights white metal spheres at each level's roughness, and the render's
  // red / green is the lod Babylon read, per pixel. The spherical polynomial is zero: Babylon adds
  // a term from it to rough metals (measured: with the sky's polynomial red / green drifts from
  // 1.5 to 5 over a sphere at roughness 0.5; see docs/engines.md). Tolerance 0.05 lod: RGBD byte
  // rounding (~0.5 % of the value) plus Babylon's minimum α_G (0.0005: +0.023 lod at level 1).
  // Seen failing: the same chain under Babylon's default lodGenerationScale, 0.8.
  PRTBAKE_CHROMIUM_OR_SKIP(chromium, "Babylon");
  constexpr double kLodTolerance = 0.05;
  constexpr int kSize = 64, kImage = 48;
  const std::string dir = test::tempDir("engines_babylon_lod");
  PrefilterOptions po;
  po.schedule = PrefilterSchedule::Babylon;
  po.baseSize = kSize;
  po.levels = 7;  // 64² down to 1²: the full chain, lodGenerationScale 1
  PrefilterResult coded = prefilterEnvironment(test::runtime(), loadEnvironment(kSky, EnvLoadOptions()), po);
  std::vector<std::vector<std::string>> pngs;
  for (size_t i = 0; i < coded.levels.size(); ++i) {
    auto& l = coded.levels[i];
    for (size_t t = 0; t < l.rgb.size(); t += 3) l.rgb[t] = float(i), l.rgb[t + 1] = 1, l.rgb[t + 2] = 0;
    pngs.push_back(babylonRgbdFaces(l.spec.size, l.rgb));
  }
  std::string shots = "[";
  for (int i = 1; i <= 5; ++i) {
    char shot[64];
    std::snprintf(shot, sizeof shot, "['l%d', 1, %.17g],", i, coded.levels[size_t(i)].spec.roughness);
    shots += shot;
  }
  shots += "]";
  // The worst |red / green − i| over the inner pixels of each level's sphere.
  auto worstLodError = [&](const std::string& name, double lodGenerationScale) {
    std::ofstream(dir + "/" + name + ".env", std::ios::binary) << babylonEnvBytes(pngs, kSize, EngineSh{}, lodGenerationScale);
    const std::string page = dir + "/" + name + ".html";
    std::ofstream(page) << fillPage(kBabylonRenderPage, {{"__CORE__", std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/node_modules/@babylonjs/core"},
                                                         {"__ENV__", dir + "/" + name + ".env"},
                                                         {"__SIZE__", std::to_string(kImage)},
                                                         {"__SHOTS__", shots}});
    const json result = chromiumResult(chromium, page);
    double worst = 0;
    for (int i = 1; i <= 5; ++i) {
      const json& px = result["shots"]["l" + std::to_string(i)];
      for (int y = 0; y < kImage; ++y)
        for (int x = 0; x < kImage; ++x) {
          const double nx = (x + 0.5 - kImage / 2.0) / (kImage / 2.0), ny = (y + 0.5 - kImage / 2.0) / (kImage / 2.0);
          if (nx * nx + ny * ny > 0.95 * 0.95) continue;
          const size_t j = 4 * (size_t(y) * kImage + size_t(x));
          worst = std::max(worst, std::abs(px[j].get<double>() / px[j + 1].get<double>() - i));
        }
    }
    return worst;
  };
  const double good = worstLodError("good", 1.0), wrong = worstLodError("scale08", 0.8);
  INFO("worst |lod read - level|: " << good << "; under lodGenerationScale 0.8: " << wrong);
  CHECK(good <= kLodTolerance);
  CHECK(wrong > kLodTolerance);
}

TEST_CASE("Engines: Babylon.js shows the labelled environment's axes where prtbake does", "[engines][chromium][data]") {
  // OpenEXR's Orientation map (each direction labelled) through the same renders, at 256² so
  // that its labels survive: a mirror sphere shows the whole environment, so a face or axis
  // misplaced by the export moves labels. Seen failing: its +Z face mirrored.
  PRTBAKE_CHROMIUM_OR_SKIP(chromium, "Babylon");
  const std::string map = test::dataFile("envmaps/openexr/OrientationCube.exr");
  PRTBAKE_SKIP_IF_NO_DATA(map);
  const SphereRenders r = babylonSphereRenders(chromium, map, true, 256, 256);
  INFO("mean |delta| in 8-bit levels: mirror metal " << r.metal << ", diffuse " << r.diffuse << "; +Z face mirrored, metal "
                                                     << r.mirroredMetal << "; pixels off by > 32 levels: " << r.metalOff
                                                     << ", +Z face mirrored " << r.mirroredMetalOff);
  // Where the mean is dominated by the white background, a misplaced label shows as pixels far
  // off: none here, 0.8 % with the +Z face mirrored.
  constexpr double kMisplacedFraction = 0.001;
  CHECK(r.metal <= 2.0);
  CHECK(r.diffuse <= 2.0);
  CHECK(r.metalOff <= kMisplacedFraction);
  CHECK(r.mirroredMetalOff > kMisplacedFraction);
}

// Filament's floor on perceptual roughness in its mobile/WebGL materials (MIN_PERCEPTUAL_ROUGHNESS).
constexpr double kFilamentMinRoughness = 0.089;

// Mean |Δ| in 8-bit levels (sphereLevels) between Filament's renders of a white metal sphere and
// prtbake's, for the Filament chain (the package's: the Filament schedule, default levels) baked
// from `envPath` at base size `size`, at `roughness`, by default level 1's (Filament's lod
// (levels − 1)·r(2 − r) is then exactly 1, and prtbake's preview reads level 1 alone); with
// `controls`, also for the chain with its +Z face mirrored.
SphereRenders filamentSphereRenders(const std::string& chromium, const std::string& envPath, bool controls, int size,
                                    int image, double roughness = -1) {
  SphereRenders out;
  const std::string dir = test::tempDir("engines_filament_render");
  PrefilterOptions po;
  po.schedule = PrefilterSchedule::Filament;
  po.baseSize = size;
  const EnvMap env = loadEnvironment(envPath, EnvLoadOptions());
  const PrefilterResult chain = prefilterEnvironment(test::runtime(), env, po);
  REQUIRE(chain.levels.size() >= 2);
  EnvProjectOptions eo;
  eo.order = 3;
  const EngineSh sh = filamentSh(projectEnvironment(test::runtime(), env, eo).radiance);
  out.roughness = roughness >= 0 ? roughness : chain.levels[1].spec.roughness;
  auto writeKtx = [&](const std::string& path, const PrefilterResult& c) {
    std::vector<CubeLevel> levels;
    for (const auto& l : c.levels) levels.push_back({l.spec.size, &l.rgb});
    std::ofstream(path, std::ios::binary) << filamentKtx1Bytes(levels, &sh);
  };
  writeKtx(dir + "/good.ktx", chain);
  if (controls) {
    const PrefilterResult mirrored = mirroredFace(chain, 4);
    writeKtx(dir + "/mirrored.ktx", mirrored);
  }
  // (Filament's dominant-direction bend, mix(R, N, α²), moves R by α² = 0.7 % at level 1's
  // roughness: within the tolerance.)
  const LinearImage want = whiteMetalSphere(chain, out.roughness, image);
  // Filament writes linear 8-bit: the light's intensity is the comparison's exposure, so that
  // the read-back bytes / 255 are the exposed values and sphereLevels' exposure cancels.
  const double exposure = sphereExposure(want);
  const std::string pageText = readText(std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/filament_render.html");
  auto render = [&](const std::string& name) {
    char intensity[32], shots[96];
    std::snprintf(intensity, sizeof intensity, "%.17g", exposure);
    std::snprintf(shots, sizeof shots, "[['metal', %.17g, 1]]", out.roughness);
    const std::string page = dir + "/" + name + ".html";
    std::ofstream(page) << fillPage(pageText, {{"__JS__", std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js"},
                                               {"__FILAMENT__", std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/node_modules/filament/filament.js"},
                                               {"__IBL__", "file://" + dir + "/" + name + ".ktx"},
                                               {"__SIZE__", std::to_string(image)},
                                               {"__INTENSITY__", intensity},
                                               {"__SHOTS__", shots}});
    json px = chromiumResult(chromium, page)["shots"]["metal"];
    for (auto& v : px) v = v.get<double>() / 255.0 / exposure;
    return px;
  };
  out.metal = sphereLevels(render("good"), want, &out.metalOff);
  if (controls) out.mirroredMetal = sphereLevels(render("mirrored"), want, &out.mirroredMetalOff);
  return out;
}

TEST_CASE("Engines: Filament renders a sphere lit by the package's ibl.ktx as prtbake's preview does", "[engines][chromium]") {
  // The acceptance of the Babylon renders (sphereLevels: mean |Δ| ≤ 2 8-bit levels, rim left
  // out). Filament clamps perceptual roughness to at least 0.089 (its mobile/WebGL floor), so the
  // sphere is at level 1's roughness rather than a mirror. 288² pixels: gltfio's materials
  // widen the lobe by the screen-space change of the normal (specular anti-aliasing), which
  // falls with resolution (mean 2.95 levels at 96², 1.59 at 192², 1.39 at 288², 1.34 at 384²,
  // measured). What remains: R11G11B10F storage, Filament's 8-bit linear output and filtering
  // on the GPU. Seen failing: the +Z face mirrored (16.4).
  constexpr double kMeanLevels = 2.0;
  PRTBAKE_CHROMIUM_OR_SKIP(chromium, "Filament");
  const SphereRenders r = filamentSphereRenders(chromium, kSky, true, 64, 288);
  INFO("roughness " << r.roughness << "; mean |delta| in 8-bit levels: metal " << r.metal << ", +Z face mirrored "
                    << r.mirroredMetal);
  CHECK(r.metal <= kMeanLevels);
  CHECK(r.mirroredMetal > kMeanLevels);
}

TEST_CASE("Engines: Filament shows the labelled environment's axes where prtbake does", "[engines][chromium][data]") {
  // OpenEXR's Orientation map through the same render at base size 256 (level 1: 128², r =
  // 0.134), as for Babylon: a misplaced face or axis moves labels. Seen failing: its +Z face
  // mirrored.
  PRTBAKE_CHROMIUM_OR_SKIP(chromium, "Filament");
  const std::string map = test::dataFile("envmaps/openexr/OrientationCube.exr");
  PRTBAKE_SKIP_IF_NO_DATA(map);
  const SphereRenders r = filamentSphereRenders(chromium, map, true, 256, 288, kFilamentMinRoughness);
  INFO("roughness " << r.roughness << "; mean |delta| in 8-bit levels: metal " << r.metal << ", +Z face mirrored "
                    << r.mirroredMetal << "; pixels off by > 32 levels: " << r.metalOff << ", +Z face mirrored "
                    << r.mirroredMetalOff);
  constexpr double kMisplacedFraction = 0.001;  // as for Babylon
  CHECK(r.metal <= 2.0);
  CHECK(r.metalOff <= kMisplacedFraction);
  CHECK(r.mirroredMetalOff > kMisplacedFraction);
}

// Mean |Δ| in 8-bit levels (sphereLevels) between the glTF-Sample-Viewer's render of a white
// metal mirror sphere (tests/js/gltf_viewer_render.html) and prtbake's, for the glTF target's GGX
// chain (the Linear schedule, default levels) baked from `envPath` at base size `size`; with
// `controls`, also for the chain with its +Z face mirrored. At roughness 0 the viewer's lod,
// roughness · (mips − 1), is 0: level 0, as prtbake's preview reads.
SphereRenders gltfViewerSphereRenders(const std::string& chromium, const std::string& envPath, bool controls, int size,
                                      int image) {
  SphereRenders out;
  const std::string dir = test::tempDir("engines_gltf_viewer_render");
  const EnvMap env = loadEnvironment(envPath, EnvLoadOptions());
  PrefilterOptions po;
  po.schedule = PrefilterSchedule::Linear;
  po.baseSize = size;
  const PrefilterResult chain = prefilterEnvironment(test::runtime(), env, po);
  PrefilterOptions lo;  // the diffuse cube the page also binds (a metal does not read it)
  lo.lobe = PrefilterLobe::Lambertian;
  lo.baseSize = 16;
  lo.levels = 1;
  std::ofstream(dir + "/lambertian.ktx2", std::ios::binary) << prefilterKtx2Bytes(prefilterEnvironment(test::runtime(), env, lo), false);
  std::ofstream(dir + "/good.ktx2", std::ios::binary) << prefilterKtx2Bytes(chain, false);
  if (controls) std::ofstream(dir + "/mirrored.ktx2", std::ios::binary) << prefilterKtx2Bytes(mirroredFace(chain, 4), false);
  const LinearImage want = whiteMetalSphere(chain, 0.0, image);
  // The viewer writes 8-bit pow(color · exposure, 1/2.2): the comparison's exposure is applied
  // there, and undone here with the encoding.
  const double exposure = sphereExposure(want);
  const std::string pageText = readText(std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/gltf_viewer_render.html");
  char rough[32];  // level 1's roughness: the viewer's lod is then exactly 1
  std::snprintf(rough, sizeof rough, "%.17g", chain.levels[1].spec.roughness);
  auto render = [&](const std::string& name) {
    char exposureText[32];
    std::snprintf(exposureText, sizeof exposureText, "%.17g", exposure);
    const std::string page = dir + "/" + name + ".html";
    std::ofstream(page) << fillPage(pageText, {{"__JS__", std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js"},
                                               {"__VIEWER__", std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/node_modules/@khronosgroup/gltf-viewer/dist"},
                                               {"__GGX__", "file://" + dir + "/" + name + ".ktx2"},
                                               {"__LAMBERTIAN__", "file://" + dir + "/lambertian.ktx2"},
                                               {"__MIPS__", std::to_string(chain.levels.size())},
                                               {"__SIZE__", std::to_string(image)},
                                               {"__EXPOSURE__", exposureText},
                                               {"__SHOTS__", std::string("[['metal', 0, 1], ['rough', ") + rough + ", 1]]"}});
    json shots = chromiumResult(chromium, page)["shots"];
    for (auto& [name, px] : shots.items())
      for (auto& v : px) v = std::pow(v.get<double>() / 255.0, 2.2) / exposure;
    return shots;
  };
  const json good = render("good");
  out.metal = sphereLevels(good["metal"], want, &out.metalOff);
  out.roughMetal = sphereLevels(good["rough"], whiteMetalSphere(chain, chain.levels[1].spec.roughness, image));
  if (controls) out.mirroredMetal = sphereLevels(render("mirrored")["metal"], want, &out.mirroredMetalOff);
  return out;
}

TEST_CASE("Engines: the glTF-Sample-Viewer renders a sphere lit by the package's KTX2 cubes as prtbake does", "[engines][chromium]") {
  // The acceptance of the Babylon renders (sphereLevels: mean |Δ| ≤ 2 8-bit levels, rim left
  // out), for a mirror: they differ by half-float storage, the viewer's 8-bit gamma-2.2 output
  // and filtering on the GPU. Seen failing: the +Z face mirrored, which moves the sun's small
  // reflection: 2.4 % of the pixels more than 32 levels off (none for the package; the mean,
  // 2.03, is dominated by the sky around it).
  PRTBAKE_CHROMIUM_OR_SKIP(chromium, "the viewer");
  const SphereRenders r = gltfViewerSphereRenders(chromium, kSky, true, 64, 96);
  INFO("mean |delta| in 8-bit levels: mirror metal " << r.metal << ", level 1's roughness " << r.roughMetal
                                                     << ", +Z face mirrored " << r.mirroredMetal
                                                     << "; pixels off by > 32 levels: " << r.metalOff << ", +Z face mirrored "
                                                     << r.mirroredMetalOff);
  constexpr double kMisplacedFraction = 0.001;  // as for the labelled environment
  CHECK(r.metal <= 2.0);
  CHECK(r.roughMetal <= 2.0);
  CHECK(r.metalOff <= kMisplacedFraction);
  CHECK(r.mirroredMetalOff > kMisplacedFraction);
}

TEST_CASE("Engines: the glTF-Sample-Viewer shows the labelled environment's axes where prtbake does", "[engines][chromium][data]") {
  // OpenEXR's Orientation map through the same mirror render at 256², as for Babylon. Seen
  // failing: its +Z face mirrored.
  PRTBAKE_CHROMIUM_OR_SKIP(chromium, "the viewer");
  const std::string map = test::dataFile("envmaps/openexr/OrientationCube.exr");
  PRTBAKE_SKIP_IF_NO_DATA(map);
  const SphereRenders r = gltfViewerSphereRenders(chromium, map, true, 256, 256);
  INFO("mean |delta| in 8-bit levels: mirror metal " << r.metal << ", +Z face mirrored " << r.mirroredMetal
                                                     << "; pixels off by > 32 levels: " << r.metalOff << ", +Z face mirrored "
                                                     << r.mirroredMetalOff);
  constexpr double kMisplacedFraction = 0.001;  // as for Babylon
  CHECK(r.metal <= 2.0);
  CHECK(r.metalOff <= kMisplacedFraction);
  CHECK(r.mirroredMetalOff > kMisplacedFraction);
}

// The page: three.js (tests/js/node_modules) renders a unit sphere of MeshLambertMaterial, white,
// lit by the LightProbe that ObjectLoader makes of __PROBE__ (the package's light_probe.json),
// seen from +Z by an orthographic camera framing it, into a float target (linear: no tone map).
const char* kThreeRenderPage = R"(<!doctype html><html><body><canvas id="c" width="64" height="64"></canvas>
<script type="module">
import * as THREE from '__THREE__/build/three.module.js';
let settle;
window.result = new Promise((resolve) => { settle = resolve; });
try {
  const N = __SIZE__;
  const renderer = new THREE.WebGLRenderer({ canvas: document.getElementById('c') });
  const target = new THREE.WebGLRenderTarget(N, N, { type: THREE.FloatType });
  const scene = new THREE.Scene();
  scene.add(new THREE.ObjectLoader().parse(__PROBE__));
  scene.add(new THREE.Mesh(new THREE.SphereGeometry(1, 256, 128), new THREE.MeshLambertMaterial({ color: 0xffffff })));
  const camera = new THREE.OrthographicCamera(-1, 1, 1, -1, 990, 1010);
  camera.position.set(0, 0, 1000);
  camera.lookAt(0, 0, 0);
  renderer.setRenderTarget(target);
  renderer.render(scene, camera);
  const px = new Float32Array(N * N * 4);
  renderer.readRenderTargetPixels(target, 0, 0, N, N, px);
  settle('RESULT ' + JSON.stringify({ size: N, shots: { diffuse: Array.from(px) } }));
} catch (e) { settle('ERROR ' + e + ' ' + e.stack); }
</script></body></html>
)";

TEST_CASE("Engines: three.js renders a sphere lit by the package's LightProbe as prtbake does", "[engines][chromium]") {
  // The same acceptance and comparison as Babylon's diffuse sphere (sphereLevels: mean |Δ| ≤ 2
  // 8-bit levels). three.js's target holds SH only (it prefilters cubes itself), so its render is
  // the Lambert sphere. Seen failing: the L1,-1 coefficient's sign flipped.
  PRTBAKE_CHROMIUM_OR_SKIP(chromium, "three.js");
  const std::string dir = test::tempDir("engines_three_render");
  constexpr int kImage = 96;
  EnvProjectOptions eo;
  eo.order = 3;
  const ShCoeffs radiance = projectEnvironment(test::runtime(), loadEnvironment(kSky, EnvLoadOptions()), eo).radiance;
  auto render = [&](const std::string& name, const EngineSh& sh) {
    const std::string page = dir + "/" + name + ".html";
    std::ofstream(page) << replaceAll(replaceAll(replaceAll(kThreeRenderPage, "__THREE__", std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/node_modules/three"),
                                                 "__SIZE__", std::to_string(kImage)),
                                      "__PROBE__", threejsLightProbeJson(sh, ""));
    return chromiumResult(chromium, page)["shots"]["diffuse"];
  };
  const LinearImage want = diffuseSphere(radiance, kImage);
  EngineSh flipped = threejsSh(radiance);
  for (int k = 3; k < 6; ++k) flipped[size_t(k)] = -flipped[size_t(k)];
  const double good = sphereLevels(render("good", threejsSh(radiance)), want);
  const double wrong = sphereLevels(render("flipped", flipped), want);
  INFO("mean |delta| in 8-bit levels: " << good << "; L1,-1 sign flipped: " << wrong);
  CHECK(good <= 2.0);
  CHECK(wrong > 2.0);
}

TEST_CASE("Engines: the glTF layout's KTX2 cubes and 16-bit tables", "[engines]") {
  // Tables: 16-bit rounding of the same table computed in-process, ½ / 65535 (values above 1,
  // the Charlie table at grazing angles, are 1).
  if (!nodeReady()) PRTBAKE_SKIP("node or tests/js/node_modules absent (npm ci in tests/js): KTX2 not read back");
  const std::string dir = test::tempDir("engines_gltf");
  REQUIRE(test::runCli("ibl '" + kSky + "' -o '" + dir + "/pkg' --target gltf" + kPackageArgs).exitCode == 0);
  const json side = json::parse(readText(dir + "/pkg/ibl.json"));
  struct Cube {
    const char* file;
    const char* lobe;
  };
  for (const Cube& c : {Cube{"lambertian/diffuse.ktx2", "lambertian"}, Cube{"ggx/specular.ktx2", "ggx"},
                        Cube{"charlie/sheen.ktx2", "charlie"}}) {
    INFO(c.file);
    const auto r = test::runShell("node '" + std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/ktx2_read.mjs' '" + dir +
                                  "/pkg/gltf/" + c.file + "'");
    REQUIRE(r.exitCode == 0);
    const json k = json::parse(r.output);
    const json& levels = side["targets"]["gltf"]["cubes"][c.lobe]["levels"];
    CHECK(k["vkFormat"] == 97);
    CHECK(k["faceCount"] == 6);
    CHECK(k["levelCount"] == levels.size());
    CHECK(k["pixelWidth"] == levels[0]["size"]);
    for (size_t l = 0; l < levels.size(); ++l) {
      CHECK(k["levels"][l]["finite"] == true);
      // The linear schedule: level i at roughness i/(n − 1).
      if (levels.size() > 1) CHECK(levels[l]["roughness"].get<double>() == Approx(double(l) / double(levels.size() - 1)));
    }
  }
  LutOptions lo;
  lo.size = 32;
  lo.cloth = true;
  lo.tolerance = side["targets"]["gltf"]["lut"]["tolerance"].get<double>();
  const LutResult lut = computeLut(test::runtime(), lo);
  for (const char* name : {"lut_ggx.png", "lut_charlie.png"}) {
    INFO(name);
    const std::string png = readText(dir + "/pkg/gltf/" + name);
    int w = 0, h = 0, ch = 0;
    REQUIRE(stbi_is_16_bit_from_memory(reinterpret_cast<const stbi_uc*>(png.data()), int(png.size())));
    stbi_us* px = stbi_load_16_from_memory(reinterpret_cast<const stbi_uc*>(png.data()), int(png.size()), &w, &h, &ch, 3);
    REQUIRE(px);
    CHECK(w == 32);
    CHECK(h == 32);
    CHECK(ch == 3);
    double worst = 0;
    for (size_t t = 0; t < lut.a.size(); ++t) {
      const double mine[3] = {lut.a[t], lut.b[t], lut.third[t]};
      for (int k = 0; k < 3; ++k)
        worst = std::max(worst, std::abs(px[3 * t + size_t(k)] / 65535.0 - std::min(mine[k], 1.0)));
    }
    stbi_image_free(px);
    CHECK(worst <= 0.5 / 65535 + 1e-7);
  }
}

TEST_CASE("Engines: bad input and bad options fail cleanly, leaving nothing", "[engines][cli]") {
  const std::string dir = test::tempDir("engines_bad");
  auto nothingLeft = [&] { return test::runShell("ls -A '" + dir + "'").output.empty(); };
  auto missing = test::runCli("ibl '" + dir + "/none.exr' -o '" + dir + "/p' --quiet");
  CHECK(missing.exitCode == 1);
  CHECK_THAT(missing.output, Catch::Contains("none.exr"));
  CHECK(nothingLeft());
  for (const std::string bad : {"--target unity", "--size 100", "--size 8", "--lut-size 4", "--tolerance 0"}) {
    INFO(bad);
    auto r = test::runCli("ibl '" + kSky + "' -o '" + dir + "/p' " + bad);
    CHECK(r.exitCode == 2);
    CHECK(nothingLeft());
  }
  // An existing directory that is not a package is not replaced.
  REQUIRE(test::runShell("mkdir '" + dir + "/keep' && touch '" + dir + "/keep/mine.txt'").exitCode == 0);
  auto keep = test::runCli("ibl '" + kSky + "' -o '" + dir + "/keep' --target threejs --quiet");
  CHECK(keep.exitCode == 1);
  CHECK_THAT(keep.output, Catch::Contains("not a prtbake ibl package"));
  CHECK(test::runShell("ls -A '" + dir + "/keep'").output == "mine.txt\n");
  // A previous package is replaced whole.
  REQUIRE(test::runCli("ibl '" + kSky + "' -o '" + dir + "/pkg' --target threejs --quiet").exitCode == 0);
  REQUIRE(test::runCli("ibl '" + kSky + "' -o '" + dir + "/pkg' --target filament" + kPackageArgs).exitCode == 0);
  CHECK(!test::fileExists(dir + "/pkg/threejs/light_probe.json"));
  CHECK(test::fileExists(dir + "/pkg/filament/ibl.ktx"));
  CHECK(test::runShell("ls -A '" + dir + "' | grep -c prtbake-tmp").output == "0\n");
}

TEST_CASE("glTF-Validator: transport's glTF copies with _PRT_T* attributes have no issues", "[engines][gltf]") {
  // Every issue counts: errors, warnings, infos and hints must all be 0. Seen failing: the
  // text copy with one _PRT_T accessor's count 7 too large (ACCESSOR_TOO_LONG,
  // MESH_PRIMITIVE_UNEQUAL_ACCESSOR_COUNT).
  if (!gltfValidatorReady())
    PRTBAKE_SKIP("node or tests/js/node_modules absent (npm ci in tests/js): glTF-Validator cannot run");
  const std::string dir = test::tempDir("gltf_validator");
  const std::string scene = std::string(PRTBAKE_TEST_SOURCE_DIR) + "/../assets/scene.gltf";
  for (const std::string ext : {"glb", "gltf"}) {
    for (const std::string mode : {"unshadowed", "shadowed"}) {
      const std::string out = dir + "/" + mode + "." + ext;
      const json rep = gltfCopyReport(scene, out, "--mode " + mode + " --samples 64");
      INFO(out << ": " << rep.dump());
      CHECK(rep["errors"] == 0);
      CHECK(rep["warnings"] == 0);
      CHECK(rep["infos"] == 0);
      CHECK(rep["hints"] == 0);
    }
  }
  // The control: a broken copy must not pass.
  json broken = json::parse(readText(dir + "/shadowed.gltf"));
  const int prt = broken["meshes"][0]["primitives"][0]["attributes"]["_PRT_T0"].get<int>();
  broken["accessors"][prt]["count"] = broken["accessors"][prt]["count"].get<int>() + 7;
  std::ofstream(dir + "/broken.gltf") << broken.dump();
  CHECK(gltfValidate(dir + "/broken.gltf")["errors"].get<int>() > 0);
}

TEST_CASE("glTF-Validator: a copy written elsewhere carries the source's image files", "[engines][gltf][data]") {
  // BoxTextured.glb unpacked into a .gltf with two external buffers and an external PNG (its URI
  // escaped, "tex%20ture.png"); the copies go to another directory. Seen failing before: the copy
  // kept the URI, which named nothing beside it (the validator's IO_ERROR), so a viewer lost the
  // texture; and the .glb copy kept the second buffer as a data URI (URI_GLB, a warning). Errors
  // and warnings must be 0 (the source's own image view is left unused: an info).
  if (!gltfValidatorReady())
    PRTBAKE_SKIP("node or tests/js/node_modules absent (npm ci in tests/js): glTF-Validator cannot run");
  const std::string glb = test::dataFile("meshes/gltf/BoxTextured.glb");
  PRTBAKE_SKIP_IF_NO_DATA(glb);
  const std::string dir = test::tempDir("gltf_copy_images");
  std::filesystem::create_directories(dir + "/src");
  std::filesystem::create_directories(dir + "/out");
  const std::string bytes = readText(glb);
  uint32_t jsonLength = 0, binLength = 0;
  std::memcpy(&jsonLength, bytes.data() + 12, 4);
  std::memcpy(&binLength, bytes.data() + 20 + jsonLength, 4);
  json doc = json::parse(bytes.substr(20, jsonLength));
  const std::string bin = bytes.substr(20 + jsonLength + 8, binLength);
  const json& view = doc["bufferViews"][doc["images"][0]["bufferView"].get<int>()];
  const std::string png = bin.substr(view.value("byteOffset", size_t(0)), view["byteLength"].get<size_t>());
  REQUIRE(png.compare(0, 4, "\x89PNG") == 0);
  // Two external buffers (the same bytes; every other view reads the second): a GLB holds one.
  doc["buffers"][0]["uri"] = "box.bin";
  doc["buffers"][1] = {{"uri", "box2.bin"}, {"byteLength", doc["buffers"][0]["byteLength"]}};
  for (size_t i = 1; i < doc["bufferViews"].size(); i += 2) doc["bufferViews"][i]["buffer"] = 1;
  doc["images"][0] = {{"uri", "tex%20ture.png"}};
  std::ofstream(dir + "/src/box.gltf") << doc.dump();
  for (const char* name : {"/src/box.bin", "/src/box2.bin"})
    std::ofstream(dir + name, std::ios::binary) << bin.substr(0, doc["buffers"][0]["byteLength"].get<size_t>());
  std::ofstream(dir + "/src/tex ture.png", std::ios::binary) << png;
  for (const std::string ext : {"glb", "gltf"}) {
    const std::string out = dir + "/out/copy." + ext;
    const json rep = gltfCopyReport(dir + "/src/box.gltf", out, "--samples 16");
    INFO(out << ": " << rep.dump());
    CHECK(rep["errors"] == 0);
    CHECK(rep["warnings"] == 0);
  }
  // The PNG's bytes as they were, in the binary copy's BIN chunk.
  const std::string out = readText(dir + "/out/copy.glb");
  std::memcpy(&jsonLength, out.data() + 12, 4);
  const json glbDoc = json::parse(out.substr(20, jsonLength));
  const json& image = glbDoc["images"][0];
  CHECK_FALSE(image.contains("uri"));
  CHECK(image["mimeType"] == "image/png");
  const json& v = glbDoc["bufferViews"][image["bufferView"].get<int>()];
  CHECK(out.substr(20 + jsonLength + 8 + v.value("byteOffset", size_t(0)), v["byteLength"].get<size_t>()) == png);
  // The control: the text copy with the source's URI back fails to load its image.
  json kept = json::parse(readText(dir + "/out/copy.gltf"));
  kept["images"][0] = {{"uri", "tex%20ture.png"}};
  std::ofstream(dir + "/out/kept.gltf") << kept.dump();
  CHECK(gltfValidate(dir + "/out/kept.gltf")["errors"].get<int>() > 0);
}

TEST_CASE("glTF-Validator: the Babylon target's EXT_lights_image_based scene", "[engines][gltf]") {
  // 0 errors and 0 warnings. Accepted infos, the only ones: UNSUPPORTED_EXTENSION (the validator
  // has no schema for EXT_lights_image_based, a vendor extension) and UNUSED_OBJECT for each
  // image (they are referenced only from inside that extension). Seen failing: a copy whose
  // first buffer view runs 4 bytes past the binary chunk (BUFFER_VIEW_TOO_LONG).
  if (!gltfValidatorReady())
    PRTBAKE_SKIP("node or tests/js/node_modules absent (npm ci in tests/js): glTF-Validator cannot run");
  const std::string dir = test::tempDir("gltf_validator_ibl");
  REQUIRE(test::runCli("ibl '" + kSky + "' -o '" + dir + "/pkg' --target babylon --size 16 --quiet").exitCode == 0);
  const std::string glb = dir + "/pkg/babylon/environment.glb";
  const json rep = gltfValidate(glb);
  INFO(rep.dump().substr(0, 2000));
  CHECK(rep["errors"] == 0);
  CHECK(rep["warnings"] == 0);
  CHECK(rep["hints"] == 0);
  int unsupported = 0, unusedImages = 0;
  for (const auto& m : rep["messages"]) {
    const std::string code = m["code"], pointer = m["pointer"];
    if (code == "UNSUPPORTED_EXTENSION" && pointer == "/extensionsUsed/0") ++unsupported;
    else if (code == "UNUSED_OBJECT" && pointer.rfind("/images/", 0) == 0) ++unusedImages;
    else FAIL_CHECK("unexpected message " << m.dump());
  }
  CHECK(unsupported == 1);
  CHECK(unusedImages == 5 * 6);  // 16² down to 1²
  CHECK(rep["infos"] == unsupported + unusedImages);
  // The control: the first buffer view made 4 bytes longer than the data.
  const std::string bytes = readText(glb);
  uint32_t jsonLen = 0;
  std::memcpy(&jsonLen, bytes.data() + 12, 4);
  json gltf = json::parse(bytes.substr(20, jsonLen));
  gltf["bufferViews"][0]["byteOffset"] = gltf["buffers"][0]["byteLength"].get<size_t>() - gltf["bufferViews"][0]["byteLength"].get<size_t>() + 4;
  std::string text = gltf.dump();
  while (text.size() % 4) text.push_back(' ');
  std::string broken = bytes.substr(0, 12);
  const uint32_t newLen = uint32_t(text.size()), total = uint32_t(bytes.size() - jsonLen + text.size());
  std::memcpy(&broken[8], &total, 4);
  broken += std::string(reinterpret_cast<const char*>(&newLen), 4) + "JSON" + text + bytes.substr(20 + jsonLen);
  std::ofstream(dir + "/broken.glb", std::ios::binary) << broken;
  CHECK(gltfValidate(dir + "/broken.glb")["errors"].get<int>() > 0);
}

TEST_CASE("Jobs: an ibl job writes its package directory, skips when up to date, replaces it when forced", "[engines][jobs]") {
  const std::string dir = test::tempDir("engines_job");
  std::ofstream(dir + "/jobs.json") << R"({"jobs": [
    {"id": "pkg", "type": "ibl", "input": ")" << kSky << R"(", "outputs": {"dir": "out/pkg"},
     "target": "threejs", "size": 16}]})";
  REQUIRE(test::runShell("mkdir '" + dir + "/out'").exitCode == 0);
  const auto first = test::runCli("run '" + dir + "/jobs.json'");
  INFO(first.output);
  REQUIRE(first.exitCode == 0);
  CHECK(test::fileExists(dir + "/out/pkg/threejs/light_probe.json"));
  CHECK(test::fileExists(dir + "/out/pkg.manifest.json"));
  CHECK_THAT(test::runCli("run '" + dir + "/jobs.json'").output, Catch::Contains("[skipped] pkg (up to date)"));
  // A changed package is out of date; --force replaces it whole.
  std::ofstream(dir + "/out/pkg/threejs/extra.txt") << "x";
  CHECK_THAT(test::runCli("run '" + dir + "/jobs.json'").output, Catch::Contains("[ok] pkg"));
  CHECK(!test::fileExists(dir + "/out/pkg/threejs/extra.txt"));
  CHECK(test::runCli("run '" + dir + "/jobs.json' --force").exitCode == 0);
  CHECK(test::runShell("ls -A '" + dir + "/out'").output == "pkg\npkg.manifest.json\n");
}
