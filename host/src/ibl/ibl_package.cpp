// `prtbake ibl`: one directory with what each engine needs, in its conventions (prtbake/engine.h).
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "prtbake/atomic_file.h"
#include "prtbake/clock.h"
#include "prtbake/error.h"
#include "prtbake/hash.h"
#include "prtbake/ibl.h"
#include "prtbake/lut.h"

namespace prtbake {
namespace fs = std::filesystem;

namespace {

// The glTF target's LUT: every texel within this of the converged table (95 % of texels, the
// tolerance pilot's guarantee), well below an 8-bit step (1/255) and above a 16-bit one.
constexpr double kGltfLutTolerance = 1e-4;
// The Khronos layout's diffuse cube: the irradiance varies slowly, 64² per face is ample.
constexpr int kLambertianMaxSize = 64;
// The sheen cube: the GGX cube's size up to 512². Its sharpest level (r = 0, α = 0.007921) is a
// ring whose weight rises from R's horizon to its peak over 0.016 rad, 4 texels at 512²: larger
// faces add no detail and cost the ring's sum per texel (venice_sunset_1k, 2 cores, filament:
// 256² 8.3 s, 512² 21.7 s, 1024² 134 s; docs/prefilter.md, "Charlie's ring").
constexpr int kCharlieMaxSize = 512;

nlohmann::json shJson(const EngineSh& sh) {
  nlohmann::json j = nlohmann::json::array();
  for (int i = 0; i < 9; ++i) j.push_back({sh[size_t(3 * i)], sh[size_t(3 * i + 1)], sh[size_t(3 * i + 2)]});
  return j;
}

// Files go into `root` (the staging directory); each is listed with what it is.
struct Package {
  std::string root;
  IblPackageResult* result;
  void write(const std::string& rel, const std::string& bytes, const std::string& what) {
    const fs::path p = fs::path(root) / rel;
    fs::create_directories(p.parent_path());
    writeFileAtomic(p.string(), bytes);
    result->files.push_back({rel, what, bytes.size()});
  }
};

PrefilterResult prefilter(Runtime& rt, const EnvMap& env, PrefilterLobe lobe, PrefilterSchedule schedule, int size,
                          int levels, double tolerance) {
  PrefilterOptions o;
  o.lobe = lobe;
  o.schedule = schedule;
  o.baseSize = size;
  o.levels = levels;
  o.tolerance = tolerance;
  return prefilterEnvironment(rt, env, o);
}

nlohmann::json chainJson(const PrefilterResult& r) {
  nlohmann::json levels = nlohmann::json::array();
  for (const auto& l : r.levels)
    levels.push_back({{"size", l.spec.size},
                      {"roughness", l.spec.roughness},
                      {"alpha", l.alphaUsed},
                      {"estimated_error_p99", l.error.p99}});
  return {{"lobe", toString(r.options.lobe)}, {"schedule", toString(r.options.schedule)}, {"levels", levels},
          {"seconds", r.totalSeconds}};
}

void threejsTarget(Package& pkg, const ShCoeffs& radiance, nlohmann::json& side) {
  const EngineSh sh = threejsSh(radiance);
  pkg.write("threejs/light_probe.json",
            threejsLightProbeJson(sh, nlohmann::json{{"generator", std::string("prtbake ") + version()}}.dump()),
            "three.js Object JSON of a LightProbe (ObjectLoader.parse); object.sh is SphericalHarmonics3.fromArray's input");
  pkg.write("threejs/README.txt",
            "three.js lighting baked by prtbake " + std::string(version()) +
                "\n\n"
                "light_probe.json is a three.js Object JSON holding one LightProbe:\n\n"
                "  const probe = new THREE.ObjectLoader().parse(json);   // a LightProbe\n"
                "  scene.add(probe);\n\n"
                "or, keeping your own probe, probe.sh.fromArray(json.object.sh).\n\n"
                "The coefficients are radiance SH (three.js's basis: no Condon-Shortley phase), in the\n"
                "environment's world frame (right-handed, +Y up), so probe.sh.getIrradianceAt(n) is the\n"
                "irradiance at world normal n and MeshStandardMaterial shades with it unchanged.\n"
                "three.js prefilters environment maps itself (PMREMGenerator), so this target has no cubes.\n",
            "how to load it");
  side["threejs"] = {{"sh", shJson(sh)},
                     {"convention", "SphericalHarmonics3 radiance coefficients, basis without the Condon-Shortley phase "
                                    "(prtbake's c_i with i = 1, 3, 5, 7 negated)"}};
}

void filamentTarget(Package& pkg, Runtime& rt, const EnvMap& env, const ShCoeffs& radiance, const IblPackageOptions& o,
                    nlohmann::json& side) {
  const EngineSh sh = filamentSh(radiance);
  const PrefilterResult chain = prefilter(rt, env, PrefilterLobe::Ggx, PrefilterSchedule::Filament, o.size, 0, o.tolerance);
  std::vector<CubeLevel> levels;
  for (const auto& l : chain.levels) levels.push_back({l.spec.size, &l.rgb});
  long long clampedIbl = 0, clampedSky = 0;
  pkg.write("filament/ibl.ktx", filamentKtx1Bytes(levels, &sh, &clampedIbl),
            "KTX 1.1 cube, R11F_G11F_B10F, the GGX chain in Filament's roughness schedule, key \"sh\" = sh.txt's numbers");
  const int skySize = o.skyboxSize > 0 ? o.skyboxSize : o.size;
  const std::vector<float> sky = resampleEnvironment(env, skySize);
  pkg.write("filament/skybox.ktx", filamentKtx1Bytes({{skySize, &sky}}, nullptr, &clampedSky),
            "KTX 1.1 cube, R11F_G11F_B10F, one level: the environment");
  pkg.write("filament/sh.txt", filamentShText(sh), "Filament irradiance SH (cmgen --sh-shader's sh.txt)");
  pkg.write("filament/README.txt",
            "Filament lighting baked by prtbake " + std::string(version()) +
                "\n\n"
                "ibl.ktx and skybox.ktx are what cmgen --format=ktx --deploy writes:\n\n"
                "  const ibl = engine.createIblFromKtx1('ibl.ktx');\n"
                "  // createIblFromKtx1 does not apply the SH it reads: rebuild with them.\n"
                "  const light = Filament.IndirectLight.Builder()\n"
                "      .reflections(ibl.getReflectionsTexture())\n"
                "      .irradianceSh(3, ibl.shfloats)\n"
                "      .intensity(1)   // the files hold the environment's own units\n"
                "      .build(engine);\n"
                "  scene.setIndirectLight(light);\n"
                "  scene.setSkybox(engine.createSkyFromKtx1('skybox.ktx'));\n\n"
                "In C++: IndirectLight::Builder().reflections(tex).irradiance(3, sh) with sh from sh.txt.\n"
                "Level i of ibl.ktx is filtered for the perceptual roughness r with r(2 - r) = i/(levels - 1),\n"
                "the lod Filament's shader looks up. Faces are Filament's (+X, -X, +Y, -Y, +Z, -Z, OpenGL\n"
                "orientation) with world direction d showing the environment's d: unlike cmgen, prtbake does\n"
                "not mirror the environment. The SH are unwindowed (cmgen windows by default).\n",
            "how to load it");
  side["filament"] = {
      {"sh", shJson(sh)},
      {"convention", "irradiance / pi pre-multiplied by each basis function's signed constant (Filament's shader "
                     "evaluates the bare polynomial 1, y, z, x, xy, yz, 3z^2-1, xz, x^2-y^2)"},
      {"ibl", chainJson(chain)},
      {"skybox_size", skySize},
      {"texels_clamped_to_format_max", clampedIbl + clampedSky}};
}

void babylonTarget(Package& pkg, Runtime& rt, const EnvMap& env, const ShCoeffs& radiance, const IblPackageOptions& o,
                   nlohmann::json& side) {
  // One chain for both files: every level down to 1², as a .env must hold, in the schedule of
  // Babylon's glTF loader, lod = log2(size · α_G) · (levels − 1) / log2(size); the .env states
  // the same lodGenerationScale (1 for a full chain), so both read level i at α_G = 2^i / size.
  int levels = 1;
  while ((1 << (levels - 1)) < o.size) ++levels;
  const PrefilterResult chain = prefilter(rt, env, PrefilterLobe::Ggx, PrefilterSchedule::Babylon, o.size, levels, o.tolerance);
  std::vector<std::vector<std::string>> pngs;
  long long clamped = 0;
  for (const auto& l : chain.levels) pngs.push_back(babylonRgbdFaces(l.spec.size, l.rgb, &clamped));
  const double lodScale = double(levels - 1) / std::log2(double(o.size));
  const EngineSh polynomial = babylonEnvPolynomial(radiance), irradiance = babylonIrradianceSh(radiance);
  pkg.write("babylon/environment.env", babylonEnvBytes(pngs, o.size, polynomial, lodScale),
            ".env (version 2): spherical-polynomial irradiance and the GGX chain as RGBD PNG cube faces");
  pkg.write("babylon/environment.glb", babylonIblGlbBytes(pngs, o.size, irradiance),
            "glTF binary whose scene carries an EXT_lights_image_based light (the same chain, irradiance SH)");
  pkg.write("babylon/README.txt",
            "Babylon.js lighting baked by prtbake " + std::string(version()) +
                "\n\n"
                "environment.env, Babylon's prefiltered environment file:\n\n"
                "  scene.environmentTexture = new BABYLON.CubeTexture('environment.env', scene);\n"
                "  // or BABYLON.CubeTexture.CreateFromPrefilteredData('environment.env', scene)\n\n"
                "environment.glb, a glTF scene with only an EXT_lights_image_based light; import or append it\n"
                "with @babylonjs/loaders (SceneLoader.AppendAsync) and the light becomes the scene's\n"
                "environment. Both hold the same GGX chain (every level down to 1x1; level i filtered for\n"
                "alpha_G = 2^i / size, the level Babylon's shader reads for alpha_G = roughness^2 + 0.0005)\n"
                "as RGBD PNGs, and the irradiance: .env as the spherical polynomial, .glb as irradiance SH.\n"
                "Frame: Babylon's default left-handed scene, into which its glTF loader brings glTF (and\n"
                "prtbake's) direction (x, y, z) as (-x, y, z); so a model loaded from glTF sees the\n"
                "environment as prtbake does. RGBD keeps values up to 255; brighter texels are clamped\n"
                "(counted in ibl.json).\n",
            "how to load it");
  side["babylon"] = {{"irradiance_polynomial", shJson(polynomial)},
                     {"irradiance_sh", shJson(irradiance)},
                     {"convention", "Babylon's left-handed frame (environment x negated); .env irradiance: the "
                                    "spherical polynomial whose FromPolynomial harmonics are E_i/pi; glTF "
                                    "irradianceCoefficients: E_i (Condon-Shortley basis)"},
                     {"specular", chainJson(chain)},
                     {"lod_generation_scale", lodScale},
                     {"channels_clamped_to_rgbd_max", clamped}};
}

void gltfTarget(Package& pkg, Runtime& rt, const EnvMap& env, const IblPackageOptions& o, nlohmann::json& side) {
  nlohmann::json chains;
  struct Cube {
    PrefilterLobe lobe;
    const char* file;
    int size;
  };
  for (const Cube& c : {Cube{PrefilterLobe::Lambertian, "gltf/lambertian/diffuse.ktx2", std::min(o.size, kLambertianMaxSize)},
                        Cube{PrefilterLobe::Ggx, "gltf/ggx/specular.ktx2", o.size},
                        Cube{PrefilterLobe::Charlie, "gltf/charlie/sheen.ktx2", std::min(o.size, kCharlieMaxSize)}}) {
    const PrefilterResult r = prefilter(rt, env, c.lobe, PrefilterSchedule::Linear, c.size,
                                        c.lobe == PrefilterLobe::Lambertian ? 1 : 0, o.tolerance);
    Ktx2Stats stats;
    pkg.write(c.file, prefilterKtx2Bytes(r, false, &stats),
              std::string("KTX 2.0 cube, R16G16B16A16_SFLOAT, ") + toString(c.lobe) +
                  (c.lobe == PrefilterLobe::Lambertian ? " (irradiance / pi)" : ", level i at roughness i/(levels - 1)"));
    chains[toString(c.lobe)] = chainJson(r);
    chains[toString(c.lobe)]["texels_clamped_to_half_max"] = stats.clampedToHalf;
  }
  // One table with R = A (scale), G = B (bias), B = the Charlie (sheen) table, as the Khronos
  // IBL sampler writes it; the Sample Viewer reads .rg of lut_ggx and .b of lut_charlie.
  LutOptions lo;
  lo.size = o.lutSize;
  lo.cloth = true;
  lo.tolerance = kGltfLutTolerance;
  const LutResult lut = computeLut(rt, lo);
  // PNG samples are unsigned normalised: the Charlie table exceeds 1 at grazing angles for low
  // roughness (up to π at r → 0), where it is clamped as the Khronos sampler's table is; counted.
  std::vector<uint16_t> px;
  double quant16 = 0, quant8 = 0;
  long long clampedTexels = 0;
  for (size_t t = 0; t < lut.a.size(); ++t)
    for (float v : {lut.a[t], lut.b[t], lut.third[t]}) {
      const double c = std::clamp(double(v), 0.0, 1.0);
      clampedTexels += c != double(v) ? 1 : 0;
      const uint16_t q = uint16_t(std::lround(c * 65535.0));
      px.push_back(q);
      quant16 = std::max(quant16, std::abs(q / 65535.0 - c));
      quant8 = std::max(quant8, std::abs(std::lround(c * 255.0) / 255.0 - c));
    }
  const std::string png = png16Bytes(lut.size, lut.size, 3, px);
  const std::string lutWhat = "16-bit RGB PNG, x = N.V, y (rows from the top) = perceptual roughness; R = A, G = B, B = Charlie";
  pkg.write("gltf/lut_ggx.png", png, lutWhat);
  pkg.write("gltf/lut_charlie.png", png, lutWhat);
  pkg.write("gltf/README.txt",
            "glTF / Khronos layout baked by prtbake " + std::string(version()) +
                "\n\n"
                "The files the glTF-Sample-Viewer and the Khronos glTF-IBL-Sampler use:\n"
                "  lambertian/diffuse.ktx2  irradiance / pi (the diffuse term for albedo 1), one level\n"
                "  ggx/specular.ktx2        GGX prefiltered, level i at perceptual roughness i/(levels - 1)\n"
                "  charlie/sheen.ktx2       Charlie (sheen) prefiltered, the same schedule\n"
                "  lut_ggx.png, lut_charlie.png  R = A, G = B (f0 * A + B), B = the Charlie table;\n"
                "                           sample at (N.V, roughness), row 0 = roughness 0\n"
                "KTX2 cubes: faces +X, -X, +Y, -Y, +Z, -Z in the KTX/OpenGL orientation, linear BT.709.\n"
                "The tables are 16-bit: an 8-bit table's steps (up to 1/510) band on smooth surfaces.\n"
                "The Charlie table exceeds 1 at grazing angles for roughness below about 0.2 (up to pi);\n"
                "a PNG holds [0, 1], so those values are 1, as in the Khronos sampler's table.\n",
            "how to load it");
  side["gltf"] = {{"cubes", chains},
                  {"lut", {{"size", lut.size},
                           {"samples_per_texel", lut.options.samples},
                           {"tolerance", kGltfLutTolerance},
                           {"predicted_error_p95", lut.tolerance.predictedError},
                           {"quantisation_max_16bit", quant16},
                           {"values_clamped_to_1", clampedTexels},
                           {"quantisation_max_8bit_for_comparison", quant8}}}};
}

// Moves the finished staging directory to `dir`, replacing a previous package there.
void publish(const std::string& staging, const std::string& dir) {
  std::error_code ec;
  if (fs::exists(dir, ec)) {
    if (!fs::is_directory(dir, ec) || !(fs::is_empty(dir, ec) || fs::exists(fs::path(dir) / "ibl.json", ec)))
      throw OutputError(dir, "exists and is not a prtbake ibl package (no ibl.json): not replaced");
    const std::string old = staging + ".old";
    fs::rename(dir, old, ec);
    if (ec) throw OutputError(dir, "cannot move the previous package aside: " + ec.message());
    fs::rename(staging, dir, ec);
    if (ec) {
      fs::rename(old, dir);
      throw OutputError(dir, "cannot move the new package into place: " + ec.message());
    }
    fs::remove_all(old, ec);
    return;
  }
  fs::rename(staging, dir, ec);
  if (ec) throw OutputError(dir, "cannot create: " + ec.message());
}

}  // namespace

const char* toString(EngineTarget t) {
  switch (t) {
    case EngineTarget::Threejs: return "threejs";
    case EngineTarget::Filament: return "filament";
    case EngineTarget::Babylon: return "babylon";
    case EngineTarget::Gltf: return "gltf";
  }
  return "?";
}

std::vector<EngineTarget> parseEngineTargets(const std::string& text, const std::string& subject) {
  std::vector<EngineTarget> out;
  size_t start = 0;
  for (;;) {
    const size_t comma = text.find(',', start);
    const std::string t = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    std::vector<EngineTarget> add;
    if (t == "all") add = IblPackageOptions().targets;
    else if (t == "threejs") add = {EngineTarget::Threejs};
    else if (t == "filament") add = {EngineTarget::Filament};
    else if (t == "babylon") add = {EngineTarget::Babylon};
    else if (t == "gltf") add = {EngineTarget::Gltf};
    else throw UsageError(subject, "unknown target '" + t + "' (expected threejs|filament|babylon|gltf|all, or a comma-separated list)");
    for (EngineTarget e : add)
      if (std::find(out.begin(), out.end(), e) == out.end()) out.push_back(e);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return out;
}

void validateIblPackageOptions(const IblPackageOptions& o) {
  auto pow2 = [](int n) { return n > 0 && (n & (n - 1)) == 0; };
  if (o.targets.empty()) throw UsageError("--target", "no target");
  if (!pow2(o.size) || o.size < 16 || o.size > 4096)
    throw UsageError("--size", std::to_string(o.size) + " must be a power of two in [16, 4096]");
  if (o.skyboxSize != 0 && (o.skyboxSize < 1 || o.skyboxSize > 4096))
    throw UsageError("--skybox-size", std::to_string(o.skyboxSize) + " is out of range [1, 4096]");
  if (o.lutSize < 16 || o.lutSize > 1024) throw UsageError("--lut-size", std::to_string(o.lutSize) + " is out of range [16, 1024]");
  if (!(o.tolerance >= 1e-4 && o.tolerance <= 0.1)) throw UsageError("--tolerance", "must be in [1e-4, 0.1]");
}

IblPackageResult writeIblPackage(Runtime& rt, const EnvMap& env, const std::string& dir, const IblPackageOptions& o,
                                 const std::string& metaJson) {
  const auto t0 = std::chrono::steady_clock::now();
  validateIblPackageOptions(o);
  if (dir.empty()) throw UsageError("-o", "missing the package directory");
  std::error_code ec;
  if (fs::exists(dir, ec) && (!fs::is_directory(dir, ec) || !(fs::is_empty(dir, ec) || fs::exists(fs::path(dir) / "ibl.json", ec))))
    throw OutputError(dir, "exists and is not a prtbake ibl package (no ibl.json): not replaced");
  const fs::path target = fs::absolute(dir);
  const fs::path parent = target.parent_path();
  if (!fs::is_directory(parent, ec)) throw OutputError(dir, "its parent directory does not exist");
  removeStaleTempFiles(parent.string());
  const std::string staging =
      (parent / ("." + target.filename().string() + ".prtbake-tmp." + std::to_string(getpid()) + ".0")).string();
  fs::remove_all(staging, ec);
  if (!fs::create_directory(staging, ec)) throw OutputError(dir, "cannot create a directory beside it: " + ec.message());

  IblPackageResult result;
  try {
    EnvProjectOptions po;
    po.order = 3;
    result.radiance = projectEnvironment(rt, env, po).radiance;
    Package pkg{staging, &result};
    nlohmann::json side = metaJson.empty() ? nlohmann::json::object() : nlohmann::json::parse(metaJson);
    side["tool"] = {{"name", "prtbake"}, {"version", version()}};
    side["environment"] = {{"source", env.source}, {"layout", env.layoutName}, {"yaw_degrees", env.yawDegrees}};
    nlohmann::json hashes = nlohmann::json::object();
    for (const auto& f : env.inputFiles) hashes[f] = sha256File(f);
    side["inputs"] = hashes;
    side["frame"] = "the environment's world frame (lat-long inputs: OpenEXR LatLongMap axes), right-handed, +Y up; "
                    "every target's files are in it (see each README.txt)";
    nlohmann::json rad = nlohmann::json::array();
    for (int i = 0; i < 9; ++i) rad.push_back(result.radiance.rgb[size_t(i)]);
    side["radiance_sh"] = {{"coefficients", rad},
                           {"convention", "c_i = integral of L Y_i, real orthonormal SH with the Condon-Shortley phase, "
                                          "i = l(l+1)+m (prtbake docs/conventions.md, SH basis); every target's SH are made from these"}};
    nlohmann::json targets = nlohmann::json::object();
    for (EngineTarget t : o.targets) {
      switch (t) {
        case EngineTarget::Threejs: threejsTarget(pkg, result.radiance, targets); break;
        case EngineTarget::Filament: filamentTarget(pkg, rt, env, result.radiance, o, targets); break;
        case EngineTarget::Babylon: babylonTarget(pkg, rt, env, result.radiance, o, targets); break;
        case EngineTarget::Gltf: gltfTarget(pkg, rt, env, o, targets); break;
      }
    }
    side["targets"] = targets;
    nlohmann::json files = nlohmann::json::array();
    for (const auto& f : result.files) files.push_back({{"path", f.path}, {"bytes", f.bytes}, {"what", f.what}});
    side["files"] = files;
    result.seconds = secondsSince(t0);
    side["timings_seconds"]["package"] = result.seconds;
    const std::string text = side.dump(2) + "\n";
    pkg.write("ibl.json", text, "this sidecar");
    publish(staging, target.string());
  } catch (...) {
    fs::remove_all(staging, ec);
    throw;
  }
  return result;
}

}  // namespace prtbake
