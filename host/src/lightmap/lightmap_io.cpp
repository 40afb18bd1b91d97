// Lightmap outputs: OpenEXR, KTX 2.0, the AO's PNG and the sidecar (see prtbake/lightmap.h).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <type_traits>
#include <nlohmann/json.hpp>

#include "io/gltf.h"

#include "io/ktx2.h"
#include "io/npy.h"
#include "io/png_chunks.h"
#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/exr.h"
#include "prtbake/lightmap.h"

namespace prtbake {
namespace {

const char* productName(LightmapProduct p) {
  switch (p) {
    case kLightmapAo: return "ao";
    case kLightmapBent: return "bent";
    case kLightmapIrradiance: return "irradiance";
    case kLightmapTransport: return "transport";
    case kLightmapSh: return "sh";
    case kLightmapBentTangent: return "bent_tangent";
  }
  return "?";
}

// The product's planes (texel-major, `width` floats per texel).
const std::vector<float>& planeOf(const LightmapResult& lm, LightmapProduct p, int* width) {
  const std::vector<float>* v = nullptr;
  switch (p) {
    case kLightmapAo: v = &lm.ao, *width = 1; break;
    case kLightmapBent: v = &lm.bent, *width = 3; break;
    case kLightmapIrradiance: v = &lm.irradiance, *width = 3; break;
    case kLightmapTransport: v = &lm.transport, *width = lm.transportChannels * lm.order * lm.order; break;
    case kLightmapSh: v = &lm.sh, *width = 3 * lm.shOrder * lm.shOrder; break;
    case kLightmapBentTangent: v = &lm.bentTangent, *width = 3; break;
  }
  if (!v || v->empty()) throw UsageError("--products", std::string("the lightmap has no ") + productName(p) + " (not asked for)");
  return *v;
}

std::vector<float> validity(const LightmapResult& lm) {
  std::vector<float> a(lm.texels());
  for (size_t i = 0; i < a.size(); ++i) a[i] = lm.valid(i) ? 1.0f : 0.0f;
  return a;
}

}  // namespace

std::string lightmapExrBytes(const LightmapResult& lm, LightmapProduct product, bool half) {
  int width = 0;
  const std::vector<float>& plane = planeOf(lm, product, &width);
  const size_t n = lm.texels();
  std::vector<std::string> names;
  if (product == kLightmapAo) {
    names = {"Y"};
  } else if (product == kLightmapSh) {
    for (int k = 0; k < lm.shOrder * lm.shOrder; ++k)
      for (char c : {'R', 'G', 'B'}) names.push_back("SH" + std::to_string(k) + "." + c);
  } else if (product != kLightmapTransport) {
    names = {"R", "G", "B"};
  } else {
    const int nc = lm.order * lm.order;
    for (int c = 0; c < lm.transportChannels; ++c)
      for (int k = 0; k < nc; ++k)
        names.push_back((lm.transportChannels == 3 ? std::string(1, "RGB"[c]) + "." : std::string()) + "T" + std::to_string(k));
  }
  std::vector<std::vector<float>> planes(names.size(), std::vector<float>(n));
  for (size_t i = 0; i < n; ++i)
    for (size_t c = 0; c < names.size(); ++c) planes[c][i] = plane[i * size_t(width) + c];
  const std::vector<float> alpha = validity(lm);
  std::vector<ExrChannel> channels;
  for (size_t c = 0; c < names.size(); ++c) channels.push_back({names[c], planes[c].data()});
  channels.push_back({"A", alpha.data()});
  ExrWriteOptions o;
  o.half = half;
  o.attributes = {{"prtbake.product", productName(product)},
                  {"prtbake.uvSet", std::to_string(lm.uvSet)},
                  {"prtbake.rows", "row 0 at v = 0 (glTF's UV convention: the image's top)"}};
  return exrBytes(lm.width, lm.height, channels, o);
}

std::string lightmapKtx2Bytes(const LightmapResult& lm, LightmapProduct product) {
  if (product == kLightmapTransport)
    throw UsageError("--format", std::string("the ") + productName(product) + " goes to OpenEXR, not KTX2");
  int width = 0;
  const std::vector<float>& plane = planeOf(lm, product, &width);
  // sh: an array texture, layer k holding coefficient k's RGB (the layers of Godot's SH
  // lightmaps); the others one RGB (ao: grey) texture. Alpha: 1 on valid texels.
  const size_t n = lm.texels(), layers = product == kLightmapSh ? size_t(lm.shOrder * lm.shOrder) : 1;
  std::vector<float> rgba(layers * n * 4);
  for (size_t k = 0; k < layers; ++k)
    for (size_t i = 0; i < n; ++i) {
      float* px = &rgba[4 * (k * n + i)];
      for (size_t c = 0; c < 3; ++c) px[c] = plane[i * size_t(width) + (width == 1 ? 0 : 3 * k + c)];
      px[3] = lm.valid(i) ? 1.0f : 0.0f;
    }
  ktx2::Layout layout;
  layout.width = uint32_t(lm.width), layout.height = uint32_t(lm.height);
  layout.layers = product == kLightmapSh ? uint32_t(layers) : 0;
  return ktx2::rgbaFloatBytes(layout, {{rgba.data(), 4, layers * n}},
                              {{"prtbake.product", productName(product)}, {"prtbake.uvSet", std::to_string(lm.uvSet)}});
}

std::string lightmapAoPngBytes(const LightmapResult& lm, int bits) {
  if (lm.ao.empty()) throw UsageError("--products", "the lightmap has no ao (not asked for)");
  if (bits != 8 && bits != 16) throw UsageError("--png-bits", "must be 8 or 16");
  const double top = bits == 8 ? 255.0 : 65535.0;
  if (bits == 8) {
    std::vector<uint8_t> px(lm.texels());
    for (size_t i = 0; i < px.size(); ++i) px[i] = uint8_t(std::lround(std::clamp(double(lm.ao[i]), 0.0, 1.0) * top));
    return png8Bytes(lm.width, lm.height, 1, px);
  }
  std::vector<uint16_t> px(lm.texels());
  for (size_t i = 0; i < px.size(); ++i) px[i] = uint16_t(std::lround(std::clamp(double(lm.ao[i]), 0.0, 1.0) * top));
  return png16Bytes(lm.width, lm.height, 1, px);
}

std::string lightmapGltfBytes(const std::string& path, const Mesh& mesh, const LightmapResult& lm) {
  if (mesh.format != Mesh::Format::Gltf || mesh.sourcePath.empty())
    throw UsageError("--gltf", "a glTF copy needs a glTF input (this mesh is not one)");
  if (lm.ao.empty()) throw UsageError("--gltf", "the glTF copy carries the AO: add ao to --products");
  tinygltf::Model model;
  detail::loadGltfModel(mesh.sourcePath, model);
  // The AO's PNG in buffer 0 (a .glb's BIN chunk; a .gltf embeds it as a data URI).
  if (model.buffers.empty()) model.buffers.emplace_back();
  auto& buffer = model.buffers[0].data;
  while (buffer.size() % 4) buffer.push_back(0);
  const std::string png = lightmapAoPngBytes(lm, 8);
  tinygltf::BufferView view;
  view.buffer = 0;
  view.byteOffset = buffer.size();
  view.byteLength = png.size();
  buffer.insert(buffer.end(), png.begin(), png.end());
  model.bufferViews.push_back(view);
  tinygltf::Image image;
  image.name = "prtbake_ao";
  image.bufferView = int(model.bufferViews.size() - 1);
  image.mimeType = "image/png";
  model.images.push_back(image);
  tinygltf::Sampler sampler;
  sampler.magFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
  sampler.minFilter = TINYGLTF_TEXTURE_FILTER_LINEAR_MIPMAP_LINEAR;
  sampler.wrapS = sampler.wrapT = TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE;
  model.samplers.push_back(sampler);
  tinygltf::Texture texture;
  texture.source = int(model.images.size() - 1);
  texture.sampler = int(model.samplers.size() - 1);
  model.textures.push_back(texture);
  const int tex = int(model.textures.size() - 1);
  // Every material the baked primitives use reads it on the lightmap's UV set; a primitive
  // without a material gets a default one that does.
  int fallback = -1;
  for (const auto& gp : mesh.gltfPrimitives) {
    auto& prim = model.meshes[size_t(gp.mesh)].primitives[size_t(gp.primitive)];
    if (prim.material < 0) {
      if (fallback < 0) {
        model.materials.emplace_back();
        model.materials.back().name = "prtbake_default";
        fallback = int(model.materials.size() - 1);
      }
      prim.material = fallback;
    }
    auto& occ = model.materials[size_t(prim.material)].occlusionTexture;
    occ.index = tex;
    occ.texCoord = lm.uvSet;
    occ.strength = 1.0;
  }
  return detail::gltfCopyBytes(model, path, mesh.sourcePath);
}

std::string lightmapSidecarBytes(const std::string& inputPath, const LightmapOptions& o, const LightmapResult& lm) {
  using nlohmann::json;
  json j;
  j["tool"] = {{"name", "prtbake"}, {"version", version()}};
  j["product"] = "lightmap";
  j["input"] = {{"path", inputPath}};
  j["parameters"] = {{"products", lightmapProductsName(lm.products)}, {"uv_set", lm.uvSet}, {"size", lm.width},
                     {"samples", o.samples}, {"seed", o.seed}, {"order", lm.order}, {"bounces", o.bounces},
                     {"max_distance", o.maxDistance}, {"dilation", o.dilation}, {"unocclude", o.unocclude},
                     {"stitch_seams", o.stitchSeams}};
  if (o.tolerance > 0) j["parameters"]["tolerance"] = o.tolerance;
  if (lm.shOrder > 0) j["parameters"]["sh_order"] = lm.shOrder;
  j["conventions"] = {
      {"texel", "texel (x, y) covers u in [x, x+1]/W, v in [y, y+1]/H; row 0 at v = 0 (glTF: the image's top)"},
      {"ao", "cosine-weighted unoccluded fraction of the hemisphere, 1 on an open plane"},
      {"bent", "unit cosine-weighted mean unoccluded direction, object space"},
      {"bent_tangent", "bent in tangent space (B.t, B.b, B.n): t the glTF TANGENT made orthogonal to n, "
                       "b = w n x t (meshes with tangents)"},
      {"irradiance", "E/pi, linear RGB: the exit radiance of a white Lambertian surface"},
      {"transport", "per-texel PRT transport, real SH with the Condon-Shortley phase, i = l(l+1)+m; "
                    "shade rho * sum_i l_i T_i"},
      {"sh", "directional irradiance: per RGB channel D_j = (A_l/pi) * projection of the light reaching the "
             "texel from above its tangent plane, real SH with the Condon-Shortley phase, j = l(l+1)+m; "
             "a normal n' shades E(n')/pi = sum_j D_j Y_j(n')"},
      {"alpha", "A = 1 where the texel's sample is valid (baked or moved out of geometry), else 0"}};
  j["texels"] = {{"width", lm.width}, {"height", lm.height}, {"baked", lm.baked}, {"moved", lm.moved},
                 {"buried", lm.buried}, {"dilated", lm.dilated},
                 {"empty", lm.texels() - lm.baked - lm.moved - lm.buried - lm.dilated},
                 {"centre_outside_triangle", lm.centreOutside}, {"touched_by_two_charts", lm.contested}};
  j["mesh"] = {{"charts", lm.charts}, {"degenerate_triangles", lm.degenerateTriangles}};
  j["seams"] = {{"edges", lm.seamEdges}, {"stitched", o.stitchSeams}, {"largest_jump_before", lm.seamJumpBefore},
                {"largest_jump_after", lm.seamJumpAfter},
                {"meaning", "the largest difference of the two sides' bilinear lookups along a seam, in the first "
                            "product's units (ao, bent x, irradiance r, T0 or SH0 r)"}};
  j["samples"] = {{"per_texel", lm.samples}, {"rays", lm.rays}};
  j["error"] = {{"max_std_error", lm.maxStdError}, {"mean_std_error", lm.meanStdError},
                {"meaning", "standard error of the transport's coefficient vector (the AO pass when asked for); "
                            "AO's is 2 sqrt(pi) times that of T_0"}};
  j["timings"] = {{"raster_seconds", lm.rasterSeconds}, {"unocclude_seconds", lm.unoccludeSeconds},
                  {"bake_seconds", lm.bakeSeconds}, {"repair_seconds", lm.repairSeconds},
                  {"total_seconds", lm.totalSeconds}};
  j["device"] = lm.device;
  return j.dump(2) + "\n";
}

namespace {

// The planes a shard's rows carry after the state, in their order, with their widths.
template <class Result>
auto rangePlanes(Result& lm) {
  using Plane = std::conditional_t<std::is_const_v<Result>, const std::vector<float>, std::vector<float>>;
  std::vector<std::pair<Plane*, size_t>> planes;
  for (Plane* v : {&lm.ao, &lm.bent, &lm.bentTangent, &lm.irradiance, &lm.transport, &lm.sh})
    if (!v->empty()) planes.emplace_back(v, v->size() / lm.texels());
  return planes;
}

}  // namespace

std::string lightmapRangeNpyBytes(const LightmapResult& part, const std::vector<uint32_t>& texelOf, size_t first,
                                  size_t count) {
  npy::checkLittleEndian();
  const auto planes = rangePlanes(part);
  size_t columns = 1;
  for (const auto& p : planes) columns += p.second;
  std::vector<float> rows(count * columns);
  for (size_t k = 0; k < count; ++k) {
    const size_t t = texelOf.at(first + k);
    float* r = &rows[k * columns];
    *r++ = float(part.state[t]);
    for (const auto& [plane, width] : planes) r = std::copy_n(&(*plane)[t * width], width, r);
  }
  std::string out = npy::header("<f4", {count, columns});
  out.append(reinterpret_cast<const char*>(rows.data()), rows.size() * sizeof(float));
  return out;
}

void addLightmapRange(LightmapResult& lm, const std::vector<uint32_t>& texelOf, size_t first, const std::vector<float>& values,
                      size_t rows, size_t columns, const std::string& path) {
  const auto planes = rangePlanes(lm);
  size_t expected = 1;
  for (const auto& p : planes) expected += p.second;
  if (columns != expected)
    throw InputError(path, "has " + std::to_string(columns) + " columns; the job's products take " + std::to_string(expected));
  if (first > texelOf.size() || rows > texelOf.size() - first || values.size() != rows * columns)
    throw InputError(path, "holds samples beyond the lightmap's " + std::to_string(texelOf.size()));
  for (size_t k = 0; k < rows; ++k) {
    const size_t t = texelOf[first + k];
    const float* r = &values[k * columns];
    const float state = *r++;
    if (!(state >= 1 && state <= 3)) throw InputError(path, "row " + std::to_string(k) + ": not a baked, moved or buried texel");
    lm.state[t] = uint8_t(state);
    for (const auto& [plane, width] : planes) {
      std::copy_n(r, width, &(*plane)[t * width]);
      r += width;
    }
  }
}

LightmapResult readLightmap(const std::string& dir) {
  const std::string sidecar = dir + "/lightmap.json";
  LightmapResult lm;
  try {
    const auto j = nlohmann::json::parse(readFile(sidecar));
    const auto& uv = j.at("parameters").at("uv_set");
    if (!uv.is_number_integer() || uv.get<long long>() < 0 || uv.get<long long>() > 255)
      throw InputError(sidecar, "parameters.uv_set must be an integer in [0, 255]");
    lm.uvSet = uv.get<int>();
  } catch (const nlohmann::json::exception& e) {
    throw InputError(sidecar, std::string("not a lightmap sidecar: ") + e.what());
  }
  std::vector<float> alpha;
  for (LightmapProduct p : {kLightmapAo, kLightmapBent, kLightmapBentTangent, kLightmapIrradiance, kLightmapSh, kLightmapTransport}) {
    const std::string path = dir + "/" + productName(p) + ".exr";
    if (!std::filesystem::exists(path)) continue;
    const ExrImage img = readExr(path);
    if (lm.products == 0) {
      lm.width = img.width, lm.height = img.height;
    } else if (img.width != lm.width || img.height != lm.height) {
      throw InputError(path, "is " + std::to_string(img.width) + "x" + std::to_string(img.height) + " but the products before it are " +
                                 std::to_string(lm.width) + "x" + std::to_string(lm.height));
    }
    // The channel names the writer gives this product (lightmapExrBytes), in texel-major order.
    std::vector<std::string> names;
    auto has = [&](const std::string& n) { return img.channel(n) != nullptr; };
    if (p == kLightmapAo) {
      names = {"Y"};
    } else if (p == kLightmapSh) {
      for (int k = 0; has("SH" + std::to_string(k) + ".R"); ++k)
        for (char c : {'R', 'G', 'B'}) names.push_back("SH" + std::to_string(k) + "." + c);
      const int m = int(std::lround(std::sqrt(double(names.size() / 3))));
      if (m < 2 || m > 3 || size_t(m * m * 3) != names.size()) throw InputError(path, "holds no L1 or L2 SH layers (SH0.R ...)");
      lm.shOrder = m;
    } else if (p == kLightmapTransport) {
      lm.transportChannels = has("R.T0") ? 3 : 1;
      int count = 0;
      while (has(std::string(lm.transportChannels == 3 ? "R." : "") + "T" + std::to_string(count))) ++count;
      lm.order = int(std::lround(std::sqrt(double(count))));
      if (count == 0 || lm.order * lm.order != count) throw InputError(path, "holds no transport channels T0 ... (a square count)");
      for (int c = 0; c < lm.transportChannels; ++c)
        for (int k = 0; k < count; ++k)
          names.push_back((lm.transportChannels == 3 ? std::string(1, "RGB"[c]) + "." : std::string()) + "T" + std::to_string(k));
    } else {
      names = {"R", "G", "B"};
    }
    names.push_back("A");
    std::vector<const std::vector<float>*> planes;
    for (const auto& n : names) {
      planes.push_back(img.channel(n));
      if (!planes.back()) throw InputError(path, "has no channel '" + n + "' (a " + productName(p) + " lightmap has " +
                                                     std::to_string(names.size()) + " channels)");
    }
    const size_t n = lm.texels(), width = names.size() - 1;
    std::vector<float> plane(n * width);
    for (size_t i = 0; i < n; ++i)
      for (size_t c = 0; c < width; ++c) plane[i * width + c] = (*planes[c])[i];
    if (alpha.empty()) alpha = *planes.back();
    lm.products |= p;
    switch (p) {
      case kLightmapAo: lm.ao = std::move(plane); break;
      case kLightmapBent: lm.bent = std::move(plane); break;
      case kLightmapBentTangent: lm.bentTangent = std::move(plane); break;
      case kLightmapIrradiance: lm.irradiance = std::move(plane); break;
      case kLightmapSh: lm.sh = std::move(plane); break;
      case kLightmapTransport: lm.transport = std::move(plane); break;
    }
  }
  if (lm.products == 0) throw InputError(dir, "holds no lightmap product (ao.exr, bent.exr, ...: written with --format exr or both)");
  lm.state.assign(lm.texels(), uint8_t(TexelState::Empty));
  for (size_t i = 0; i < lm.texels(); ++i) {
    bool any = false;
    for (const auto* v : {&lm.ao, &lm.bent, &lm.bentTangent, &lm.irradiance, &lm.sh, &lm.transport}) {
      const size_t w = v->size() / lm.texels();
      for (size_t c = 0; c < w && !any; ++c) any = (*v)[i * w + c] != 0.0f;
    }
    lm.state[i] = uint8_t(alpha[i] > 0.5f ? TexelState::Baked : any ? TexelState::Dilated : TexelState::Empty);
  }
  return lm;
}

}  // namespace prtbake
