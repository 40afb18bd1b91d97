// Writing prefiltered chains: the JSON sidecar, KTX 2.0 and a mip-mapped OpenEXR cube.
#include <ImfChannelList.h>
#include <ImfEnvmapAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIntAttribute.h>
#include <ImfStandardAttributes.h>
#include <ImfStringAttribute.h>
#include <ImfTileDescription.h>
#include <ImfTiledOutputFile.h>
#include <half.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "io/exr_cube.h"
#include "io/ktx2.h"
#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/hash.h"
#include "prtbake/prefilter.h"

namespace prtbake {
namespace {

constexpr float kHalfMax = 65504.0f;

std::string fileName(const std::string& path) { return path.substr(path.find_last_of('/') + 1); }

std::string definitionText(PrefilterLobe lobe) {
  const std::string common =
      "P(R) = integral of L(l) k(R.l) dl / integral of k(R.l) dl over the sphere, for each texel direction R; ";
  switch (lobe) {
    case PrefilterLobe::Ggx:
      return common + "k = D_GGX(h) max(0, R.l), h = normalize(R + l), D_GGX = alpha^2 / (pi ((N.H)^2 (alpha^2 - 1) + 1)^2) "
                      "with N = V = R (the split sum's first half)";
    case PrefilterLobe::Charlie:
      return common + "k = D_Charlie(h) max(0, R.l), D_Charlie = (2 + 1/alpha) sin(theta_h)^(1/alpha) / (2 pi), "
                      "alpha clamped to >= 0.007921 (as the BRDF LUT's cloth table), N = V = R";
    case PrefilterLobe::Lambertian:
      return common + "k = max(0, R.l): P = irradiance / pi (every level; roughness is not used)";
  }
  return common;
}

nlohmann::json levelList(const PrefilterResult& r) {
  nlohmann::json levels = nlohmann::json::array();
  for (size_t i = 0; i < r.levels.size(); ++i) {
    const PrefilterLevel& l = r.levels[i];
    nlohmann::json j = {{"level", i},
                        {"size", l.spec.size},
                        {"roughness", l.spec.roughness},
                        {"alpha", l.spec.alpha},
                        {"alpha_used", l.alphaUsed}};
    if (l.alphaUsed == 0 && r.options.lobe == PrefilterLobe::Ggx) {
      j["method"] = "resampled source (r = 0)";
      j["error_estimate"] = nullptr;
    } else if (r.options.method == PrefilterMethod::Sampled) {
      j["method"] = "sampled";
      j["samples"] = r.options.samples;
      j["error_estimate"] = nullptr;
    } else {
      j["method"] = "cut";
      j["per_bin_tolerance"] = l.binTolerance;
      j["passes"] = l.passes;
      j["bin_evaluations_per_texel"] = double(l.binsSummed) / (6.0 * l.spec.size * l.spec.size);
      if (r.options.errorEstimate)
        j["error_estimate"] = {{"mean", l.error.mean}, {"p99", l.error.p99}, {"max", l.error.max}, {"texels", l.error.texels}};
      else
        j["error_estimate"] = nullptr;
    }
    j["timings_seconds"] = {{"cut", l.cutSeconds}, {"kernel", l.kernelSeconds}, {"estimate", l.estimateSeconds}};
    levels.push_back(j);
  }
  return levels;
}

}  // namespace

std::string prefilterSidecarText(const PrefilterResult& r, const EnvMap& env, const std::string& metaJson) {
  nlohmann::json j = metaJson.empty() ? nlohmann::json::object() : nlohmann::json::parse(metaJson);
  const PrefilterOptions& o = r.options;
  j["tool"] = {{"name", "prtbake"}, {"version", version()}};
  j["product"] = "prefiltered_specular";
  j["definition"] = definitionText(o.lobe);
  j["lobe"] = toString(o.lobe);
  j["schedule"] = o.schedule == PrefilterSchedule::Explicit ? "explicit" : toString(o.schedule);
  j["schedule_definition"] =
      o.schedule == PrefilterSchedule::Linear     ? "r_i = i/(n - 1), alpha = r^2 (Khronos IBL sampler, glTF-Sample-Viewer)"
      : o.schedule == PrefilterSchedule::Filament ? "lod i of n: r(2 - r) = i/(n - 1), r_i = 1 - sqrt(1 - i/(n - 1)), alpha = r^2"
      : o.schedule == PrefilterSchedule::Babylon
          ? "Babylon glTF loader: lod = log2(size alpha_G) (n - 1)/log2(size), so alpha_G,i = size^(i/(n-1) - 1) "
            "(the level is filtered with alpha = alpha_G) and r_i = sqrt(max(0, alpha_G - 0.0005))"
          : "explicit roughness list, alpha = r^2";
  j["level_sizes"] = "size_i = max(1, base >> i)";
  j["levels"] = levelList(r);
  if (o.method == PrefilterMethod::Sampled) {
    j["method"] = "sampled (the anchors' estimator): " + std::to_string(o.samples) +
                  " Hammersley GGX half vectors per texel, weights N.L, each read trilinearly (seamless) from the box-filtered "
                  "mip chain of the level-0 cube at lod = log4(omega_s/omega_p) + 1 (Filament, K = 4)";
  } else {
    j["method"] =
        "cut: exact sums over a cut of a quadtree of cube-face bins (flux, solid angle, radiance- and solid-angle-"
        "weighted centroids), each bin taken whole where its second-order error is within the per-bin tolerance "
        "(docs/prefilter.md); r = 0 levels are the source resampled (area-weighted when minifying, bilinear when "
        "magnifying)";
    j["bins"] = {{"finest_face_size", r.binFaceSize}, {"alpha_floor", r.alphaFloor}};
  }
  j["tolerance"] = {{"target_p99", o.tolerance},
                    {"meaning", "each level's estimated 99th-percentile relative error (max over channels) is kept within "
                                "the target by halving the per-bin tolerance, at most 3 times"}};
  j["error_estimate_definition"] =
      "per level: |P - P'|/P' x 4/3 (max over channels) over about 1024 texels per face (whole leaves of 8x8 or "
      "16x16), P' recomputed with a quarter of the per-bin tolerance (the cut's error is second order in the bin size); null for resampled and "
      "sampled levels";
  j["conventions"] = {
      {"faces", "+X, -X, +Y, -Y, +Z, -Z"},
      {"orientation",
       "row 0 at the top; u = 2(col + 0.5)/N - 1, v = 2(row + 0.5)/N - 1; +X (1,-v,-u), -X (-1,-v,u), +Y (u,1,v), "
       "-Y (u,-1,-v), +Z (u,-v,1), -Z (-u,-v,-1): the OpenGL/Vulkan cube map and KTX 'rd' layout"},
      {"frame", "the input's world frame (lat-long inputs: OpenEXR LatLongMap axes, +Y up), rotated by yaw about +Y"},
      {"quantity", o.lobe == PrefilterLobe::Lambertian ? "irradiance / pi (linear)" : "prefiltered radiance (linear)"}};
  nlohmann::json hashes = nlohmann::json::object();
  for (const auto& f : env.inputFiles) hashes[f] = sha256File(f);
  j["inputs"] = hashes;
  j["environment"] = {{"layout", env.layoutName},
                      {"width", env.width},
                      {"height", env.height},
                      {"yaw_degrees", env.yawDegrees},
                      {"clamped_texels", env.clampedTexels}};
  j["device"] = r.device;
  nlohmann::json t = {{"bins", r.binSeconds},
                      {"resample", r.resampleSeconds},
                      {"kernel", r.kernelSeconds},
                      {"program_build", r.buildSeconds},
                      {"prefilter", r.totalSeconds}};
  if (j.contains("timings_seconds")) t.update(j["timings_seconds"]);
  j["timings_seconds"] = t;
  return j.dump(2) + "\n";
}

std::string prefilterKtx2Bytes(const PrefilterResult& r, bool float32, Ktx2Stats* stats) {
  if (r.levels.empty()) throw OutputError("ktx2", "nothing to write");
  ktx2::Layout layout;
  layout.width = layout.height = uint32_t(r.levels[0].spec.size);
  layout.faces = 6;
  layout.float32 = float32;
  // Faces +X … −Z, rows top first; alpha 1.
  std::vector<ktx2::Level> levels;
  for (const PrefilterLevel& l : r.levels)
    levels.push_back({l.rgb.data(), 3, 6 * size_t(l.spec.size) * size_t(l.spec.size)});
  nlohmann::json meta = {{"lobe", toString(r.options.lobe)}, {"schedule", toString(r.options.schedule)}};
  for (const auto& l : r.levels) meta["roughness"].push_back(l.spec.roughness);
  long long clamped = 0;
  std::string out = ktx2::rgbaFloatBytes(layout, levels, {{"prtbake.prefilter", meta.dump()}}, &clamped);
  if (stats) stats->clampedToHalf = clamped;
  return out;
}

void writePrefilterExr(const std::string& path, const PrefilterResult& r, bool half16) {
  if (r.levels.empty()) throw OutputError(path, "nothing to write");
  const int n = r.levels[0].spec.size;
  if (n & (n - 1))
    throw UsageError(path, "a mip-mapped OpenEXR cube needs a power-of-two base size (OpenEXR's levels must stay N x 6N); "
                           "got " + std::to_string(n) + ", use --ktx2 or a power-of-two --size");
  AtomicFile out(path);
  try {
    Imf::Header header(n, 6 * n);
    header.compression() = Imf::ZIP_COMPRESSION;
    header.setTileDescription(Imf::TileDescription(64, 64, Imf::MIPMAP_LEVELS, Imf::ROUND_DOWN));
    Imf::addEnvmap(header, Imf::ENVMAP_CUBE);
    header.insert("prtbake:product", Imf::StringAttribute("prefiltered_specular"));
    header.insert("prtbake:version", Imf::StringAttribute(version()));
    header.insert("prtbake:lobe", Imf::StringAttribute(toString(r.options.lobe)));
    header.insert("prtbake:schedule", Imf::StringAttribute(toString(r.options.schedule)));
    header.insert("prtbake:prefilteredLevels", Imf::IntAttribute(int(r.levels.size())));
    std::string rough;
    for (const auto& l : r.levels) rough += (rough.empty() ? "" : ",") + std::to_string(l.spec.roughness);
    header.insert("prtbake:roughness", Imf::StringAttribute(rough));
    const Imf::PixelType type = half16 ? Imf::HALF : Imf::FLOAT;
    for (const char* c : {"R", "G", "B"}) header.channels().insert(c, Imf::Channel(type));
    Imf::TiledOutputFile file(out.writerPath().c_str(), header);
    // Level images in OpenEXR's layout, RGB float; levels past the schedule are 2×2 box
    // filters of the level above (plain image mip-mapping; faces stay apart while N_l ≥ 2).
    std::vector<float> image;
    std::vector<::half> halfImage;
    int w = 0, h = 0;
    for (int level = 0; level < file.numLevels(); ++level) {
      const Imath::Box2i dw = file.dataWindowForLevel(level);
      const int lw = dw.max.x - dw.min.x + 1, lh = dw.max.y - dw.min.y + 1;
      std::vector<float> next(size_t(lw) * size_t(lh) * 3);
      if (size_t(level) < r.levels.size()) {
        const PrefilterLevel& l = r.levels[size_t(level)];
        PRTBAKE_CHECK(lw == l.spec.size && lh == 6 * l.spec.size, "OpenEXR level size differs from the chain's");
        const std::vector<size_t> pixel = detail::openExrCubePixels(l.spec.size, standardCubeBases(), path);
        for (size_t t = 0; t < pixel.size(); ++t)
          for (int c = 0; c < 3; ++c) next[3 * pixel[t] + size_t(c)] = l.rgb[3 * t + size_t(c)];
      } else {
        for (int y = 0; y < lh; ++y)
          for (int x = 0; x < lw; ++x)
            for (int c = 0; c < 3; ++c) {
              double s = 0;
              int k = 0;
              for (int j = 0; j < 2; ++j)
                for (int i = 0; i < 2; ++i)
                  if (2 * x + i < w && 2 * y + j < h) s += image[3 * (size_t(2 * y + j) * size_t(w) + size_t(2 * x + i)) + size_t(c)], ++k;
              next[3 * (size_t(y) * size_t(lw) + size_t(x)) + size_t(c)] = float(s / std::max(k, 1));
            }
      }
      image.swap(next);
      w = lw, h = lh;
      Imf::FrameBuffer fb;
      const char* names[3] = {"R", "G", "B"};
      if (half16) {
        halfImage.resize(image.size());
        for (size_t i = 0; i < image.size(); ++i) halfImage[i] = ::half(std::min(image[i], kHalfMax));
        char* base = reinterpret_cast<char*>(halfImage.data());
        for (int c = 0; c < 3; ++c)
          fb.insert(names[c], Imf::Slice(Imf::HALF, base + 2 * size_t(c), 6, 6 * size_t(lw)));
      } else {
        char* base = reinterpret_cast<char*>(image.data());
        for (int c = 0; c < 3; ++c)
          fb.insert(names[c], Imf::Slice(Imf::FLOAT, base + 4 * size_t(c), 12, 12 * size_t(lw)));
      }
      file.setFrameBuffer(fb);
      file.writeTiles(0, file.numXTiles(level) - 1, 0, file.numYTiles(level) - 1, level);
    }
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw OutputError(path, std::string("OpenEXR write failed: ") + e.what());
  }
  out.commit();
}

void writePrefilterFiles(const PrefilterResult& result, const EnvMap& env, const std::string& jsonPath,
                         const std::string& ktx2Path, bool ktx2Float32, const std::string& exrPath, bool exrHalf,
                         const std::string& metaJson) {
  // Everything that can fail before a byte is written is checked first.
  const int n = result.levels.empty() ? 0 : result.levels[0].spec.size;
  if (!exrPath.empty() && (n & (n - 1)))
    writePrefilterExr(exrPath, result, exrHalf);  // throws the usage error without writing
  std::vector<std::string> written;
  auto undo = [&] {
    for (const auto& p : written) std::remove(p.c_str());
  };
  try {
    Ktx2Stats stats;
    const std::string ktx = ktx2Path.empty() ? std::string() : prefilterKtx2Bytes(result, ktx2Float32, &stats);
    if (!jsonPath.empty()) {
      nlohmann::json meta = metaJson.empty() ? nlohmann::json::object() : nlohmann::json::parse(metaJson);
      nlohmann::json outs = nlohmann::json::object();
      if (!ktx2Path.empty())
        outs["ktx2"] = {{"file", fileName(ktx2Path)},
                        {"format", ktx2Float32 ? "VK_FORMAT_R32G32B32A32_SFLOAT" : "VK_FORMAT_R16G16B16A16_SFLOAT"},
                        {"layout", "one cube (faceCount 6) with every level, alpha = 1"},
                        {"texels_clamped_to_half_max", stats.clampedToHalf}};
      if (!exrPath.empty())
        outs["exr"] = {{"file", fileName(exrPath)},
                       {"pixel_type", exrHalf ? "half" : "float32"},
                       {"layout", "one tiled, mip-mapped (ROUND_DOWN) OpenEXR cube map (envmap = cube, faces as ImfEnvmap.h "
                                  "defines); levels 0.." + std::to_string(result.levels.size() - 1) +
                                      " prefiltered, later levels 2x2 box filters of the level above"}};
      meta["outputs"] = outs;
      writeFileAtomic(jsonPath, prefilterSidecarText(result, env, meta.dump()));
      written.push_back(jsonPath);
    }
    if (!ktx2Path.empty()) {
      writeFileAtomic(ktx2Path, ktx);
      written.push_back(ktx2Path);
    }
    if (!exrPath.empty()) {
      writePrefilterExr(exrPath, result, exrHalf);
      written.push_back(exrPath);
    }
  } catch (...) {
    undo();
    throw;
  }
}

}  // namespace prtbake
