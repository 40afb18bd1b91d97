// glTF 2.0 loader (tinygltf): every triangle primitive of the default scene in world space.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <cstdint>
#include <cstring>
#include <functional>
#include <nlohmann/json.hpp>
#include <sys/stat.h>

#include "io/gltf.h"
#include "geometry/mesh_texture.h"
#include "io/image_read.h"
#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/limits.h"
#include "prtbake/mesh.h"

namespace prtbake {

namespace {
using Mat4 = std::array<double, 16>;  // column-major, as glTF

Mat4 identity() { return {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}; }

Mat4 mul(const Mat4& a, const Mat4& b) {
  Mat4 r{};
  for (int c = 0; c < 4; ++c)
    for (int rr = 0; rr < 4; ++rr) {
      double s = 0;
      for (int k = 0; k < 4; ++k) s += a[k * 4 + rr] * b[c * 4 + k];
      r[c * 4 + rr] = s;
    }
  return r;
}

Mat4 nodeMatrix(const tinygltf::Node& n) {
  if (n.matrix.size() == 16) {
    Mat4 m;
    for (int i = 0; i < 16; ++i) m[i] = n.matrix[i];
    return m;
  }
  Mat4 t = identity(), r = identity(), s = identity();
  if (n.translation.size() == 3) t[12] = n.translation[0], t[13] = n.translation[1], t[14] = n.translation[2];
  if (n.scale.size() == 3) s[0] = n.scale[0], s[5] = n.scale[1], s[10] = n.scale[2];
  if (n.rotation.size() == 4) {
    double x = n.rotation[0], y = n.rotation[1], z = n.rotation[2], w = n.rotation[3];
    const double len = std::sqrt(x * x + y * y + z * z + w * w);
    if (len > 0) x /= len, y /= len, z /= len, w /= len;
    r = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),     0,
         2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),     0,
         2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y), 0,
         0, 0, 0, 1};
  }
  return mul(t, mul(r, s));
}

// The per-vertex attributes of one primitive, each with as many elements as POSITION
// (NORMAL and COLOR_0 are empty when the primitive has none).
struct PrimitiveAttributes {
  std::vector<double> position, normal, color;  // 3 per vertex
  std::vector<std::vector<double>> uv;          // TEXCOORD_k: 2 per vertex (empty: none)
  std::vector<double> tangent;                  // TANGENT: 4 per vertex (empty: none)
  size_t vertexCount = 0;
};

// The most texture coordinate sets read (TEXCOORD_0 … TEXCOORD_7).
constexpr int kMaxUvSets = 8;

PrimitiveAttributes readAttributes(const tinygltf::Model& model, const tinygltf::Primitive& prim,
                                   const std::string& path, const std::string& what) {
  PrimitiveAttributes a;
  auto pos = prim.attributes.find("POSITION");
  if (pos == prim.attributes.end()) throw InputError(path, what + " has no POSITION attribute");
  a.position = detail::readAccessor(model, pos->second, 3, path, what + " POSITION");
  a.vertexCount = a.position.size() / 3;
  if (auto it = prim.attributes.find("NORMAL"); it != prim.attributes.end())
    a.normal = detail::readAccessor(model, it->second, 3, path, what + " NORMAL", a.vertexCount);
  if (auto it = prim.attributes.find("COLOR_0"); it != prim.attributes.end())
    a.color = detail::readAccessor(model, it->second, 3, path, what + " COLOR_0", a.vertexCount);
  if (auto it = prim.attributes.find("TANGENT"); it != prim.attributes.end()) {
    a.tangent = detail::readAccessor(model, it->second, 4, path, what + " TANGENT", a.vertexCount);
    for (size_t v = 0; v < a.vertexCount; ++v)  // glTF 2.0: w is +1 or −1
      if (!(std::abs(std::abs(a.tangent[4 * v + 3]) - 1.0) <= 1e-3))
        throw InputError(path, what + " TANGENT: vertex " + std::to_string(v) + " has w = " +
                                   std::to_string(a.tangent[4 * v + 3]) + " (glTF 2.0 requires +1 or -1)");
  }
  for (int k = 0; k < kMaxUvSets; ++k) {
    const std::string name = "TEXCOORD_" + std::to_string(k);
    if (auto it = prim.attributes.find(name); it != prim.attributes.end()) {
      a.uv.resize(size_t(k) + 1);
      a.uv[size_t(k)] = detail::readAccessor(model, it->second, 2, path, what + " " + name, a.vertexCount);
    }
  }
  return a;
}

// glTF 2.0 requires unit normals; a file that breaks this is refused rather than silently
// repaired (kNormalLengthTol: looser than float rounding, as the glTF validator's own check).
void checkUnitNormals(const std::vector<double>& n, const std::string& path, const std::string& what) {
  constexpr double kNormalLengthTol = 1e-2;
  for (size_t v = 0; v < n.size() / 3; ++v) {
    const double len = std::sqrt(n[3 * v] * n[3 * v] + n[3 * v + 1] * n[3 * v + 1] + n[3 * v + 2] * n[3 * v + 2]);
    if (std::isfinite(len) && std::abs(len - 1.0) > kNormalLengthTol)
      throw InputError(path, what + " NORMAL: vertex " + std::to_string(v) + " has length " + std::to_string(len) +
                                 " (glTF 2.0 requires unit normals)");
  }
}

// The primitive's material's base colour factor (white without one).
std::array<double, 3> baseColor(const tinygltf::Model& model, const tinygltf::Primitive& prim) {
  if (prim.material >= 0 && prim.material < int(model.materials.size())) {
    const auto& f = model.materials[prim.material].pbrMetallicRoughness.baseColorFactor;
    if (f.size() >= 3) return {f[0], f[1], f[2]};
  }
  return {1, 1, 1};
}

// The primitive's corner list (indexed or not), before strip and fan conversion.
std::vector<uint32_t> readCorners(const tinygltf::Model& model, const tinygltf::Primitive& prim, size_t nv,
                                  const std::string& path, const std::string& what) {
  std::vector<uint32_t> corners;
  if (prim.indices < 0) {
    for (size_t i = 0; i < nv; ++i) corners.push_back(uint32_t(i));
    return corners;
  }
  // glTF 2.0: indices are scalar unsigned bytes, shorts or ints, not normalised; so every
  // value read below is a whole number ≥ 0 (a float accessor could hold NaN).
  if (prim.indices < int(model.accessors.size())) {
    const auto& acc = model.accessors[size_t(prim.indices)];
    if ((acc.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
         acc.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
         acc.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) ||
        acc.type != TINYGLTF_TYPE_SCALAR || acc.normalized)
      throw InputError(path, what + " indices: accessor " + std::to_string(prim.indices) +
                                 " must hold unnormalised scalar unsigned integers (glTF 2.0)");
  }
  const std::vector<double> idx = detail::readAccessor(model, prim.indices, 1, path, what + " indices");
  corners.reserve(idx.size());
  for (double v : idx) {
    if (v >= double(nv))
      throw InputError(path, what + ": index " + std::to_string(uint64_t(v)) + " is out of range (" +
                                 std::to_string(nv) + " vertices)");
    corners.push_back(uint32_t(v));
  }
  return corners;
}

// Triangles (three corners each) of a list, strip or fan.
std::vector<uint32_t> triangulate(int mode, const std::vector<uint32_t>& corners) {
  std::vector<uint32_t> tris;
  if (mode == TINYGLTF_MODE_TRIANGLES) {
    for (size_t i = 0; i + 2 < corners.size(); i += 3) tris.insert(tris.end(), {corners[i], corners[i + 1], corners[i + 2]});
  } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
    // glTF: triangle i = (i, i+1, i+2) for even i, (i+1, i, i+2) for odd i.
    for (size_t i = 0; i + 2 < corners.size(); ++i) {
      if (i % 2 == 0)
        tris.insert(tris.end(), {corners[i], corners[i + 1], corners[i + 2]});
      else
        tris.insert(tris.end(), {corners[i + 1], corners[i], corners[i + 2]});
    }
  } else {
    // glTF: triangle i = (i+1, i+2, 0).
    for (size_t i = 0; i + 2 < corners.size(); ++i) tris.insert(tris.end(), {corners[i + 1], corners[i + 2], corners[0]});
  }
  return tris;
}

// Appends the primitive's vertices in world space: positions by `world`, normals by the
// inverse transpose of its upper 3×3, albedo = base colour × COLOR_0. Returns whether the
// transform mirrors (negative determinant: the winding must flip).
bool appendVertices(const PrimitiveAttributes& attrs, const Mat4& world, const std::array<double, 3>& base,
                    Mesh& mesh) {
  const std::vector<double>& p = attrs.position;
  const std::vector<double>& n = attrs.normal;
  const std::vector<double>& col = attrs.color;
  const double* m = world.data();
  const double a = m[0], b = m[4], c = m[8], d = m[1], e = m[5], f = m[9], g = m[2], h = m[6], k = m[10];
  const double det = a * (e * k - f * h) - b * (d * k - f * g) + c * (d * h - e * g);
  // Cofactor matrix = det × inverse transpose (the scale of det does not matter: renormalised).
  const double cof[9] = {e * k - f * h, -(d * k - f * g), d * h - e * g,
                         -(b * k - c * h), a * k - c * g, -(a * h - b * g),
                         b * f - c * e, -(a * f - c * d), a * e - b * d};
  const double sgn = det < 0 ? -1.0 : 1.0;
  for (size_t i = 0; i < attrs.vertexCount; ++i) {
    const double x = p[3 * i], y = p[3 * i + 1], z = p[3 * i + 2];
    mesh.positions.push_back(float(m[0] * x + m[4] * y + m[8] * z + m[12]));
    mesh.positions.push_back(float(m[1] * x + m[5] * y + m[9] * z + m[13]));
    mesh.positions.push_back(float(m[2] * x + m[6] * y + m[10] * z + m[14]));
    double w[3] = {0, 0, 0};
    if (!n.empty()) {
      const double nx = n[3 * i], ny = n[3 * i + 1], nz = n[3 * i + 2];
      // row r of cofactor · n
      w[0] = sgn * (cof[0] * nx + cof[1] * ny + cof[2] * nz);
      w[1] = sgn * (cof[3] * nx + cof[4] * ny + cof[5] * nz);
      w[2] = sgn * (cof[6] * nx + cof[7] * ny + cof[8] * nz);
      const double len = std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
      if (len > 1e-12 && std::isfinite(len))
        for (double& q : w) q /= len;
      else
        w[0] = w[1] = w[2] = 0;  // zero-length or non-finite: recomputed by fillMissingNormals
    }
    for (double q : w) mesh.normals.push_back(float(q));
    for (int ch = 0; ch < 3; ++ch) mesh.albedo.push_back(float(base[ch] * (col.empty() ? 1.0 : col[3 * i + ch])));
  }
  // Tangents: directions, so the upper 3×3 itself, renormalised; a mirror flips the handedness.
  // NaN where this primitive has none (loadGltf then drops them all).
  for (size_t i = 0; i < attrs.vertexCount; ++i) {
    double t[4] = {std::numeric_limits<double>::quiet_NaN(), 0, 0, 0};
    if (!attrs.tangent.empty()) {
      const double* q = &attrs.tangent[4 * i];
      for (int r = 0; r < 3; ++r) t[r] = m[r] * q[0] + m[4 + r] * q[1] + m[8 + r] * q[2];
      const double len = std::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
      for (int r = 0; r < 3; ++r) t[r] = len > 1e-12 ? t[r] / len : 0.0;
      t[3] = q[3] < 0 ? -sgn : sgn;
    }
    for (double q : t) mesh.tangents.push_back(float(q));
  }
  // UV sets: kept per vertex (NaN where this primitive lacks the set; loadGltf drops such sets).
  for (size_t k = 0; k < mesh.uvs.size(); ++k) {
    const bool has = k < attrs.uv.size() && !attrs.uv[k].empty();
    for (size_t i = 0; i < 2 * attrs.vertexCount; ++i)
      mesh.uvs[k].push_back(has ? float(attrs.uv[k][i]) : std::numeric_limits<float>::quiet_NaN());
  }
  return det < 0;
}

// A primitive instance whose material has a base colour texture: its vertices, its corners in
// mesh.indices, and the primitive's name for errors.
struct TexturedRange {
  uint32_t firstVertex = 0, vertexCount = 0;
  size_t firstIndex = 0, indexCount = 0;
  int material = -1;
  std::string what;
};

void addPrimitive(const tinygltf::Model& model, int nodeIndex, int meshIndex, int primIndex, const Mat4& world,
                  const std::string& path, Mesh& mesh, std::vector<TexturedRange>* textured) {
  const auto& prim = model.meshes[meshIndex].primitives[primIndex];
  const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
  if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN)
    return;
  const std::string what = "mesh " + std::to_string(meshIndex) + " primitive " + std::to_string(primIndex);
  const PrimitiveAttributes attrs = readAttributes(model, prim, path, what);
  checkUnitNormals(attrs.normal, path, what);
  const std::vector<uint32_t> tris = triangulate(mode, readCorners(model, prim, attrs.vertexCount, path, what));
  // The scene's vertices, every instance of every primitive (a small file can instance a large
  // primitive many times), against the input memory limit and 32-bit indices.
  const double vertices = double(mesh.vertexCount()) + double(attrs.vertexCount);
  checkInputMemory(path, "the scene's " + std::to_string(int64_t(vertices)) + " vertices (every instance of every primitive)",
                   vertices * (52.0 + 8.0 * double(mesh.uvs.size())) + 4.0 * double(mesh.indices.size() + tris.size()));
  if (vertices > 4294967295.0) throw InputError(path, "the scene has more than 2^32 - 1 vertices");
  const uint32_t first = uint32_t(mesh.vertexCount());
  if (!tris.empty())
    for (size_t k = 0; k < mesh.uvMissing.size(); ++k)
      if (mesh.uvMissing[k].empty() && (k >= attrs.uv.size() || attrs.uv[k].empty()))
        mesh.uvMissing[k] = what + " (node " + std::to_string(nodeIndex) + ") has no TEXCOORD_" + std::to_string(k);
  if (!tris.empty() && attrs.tangent.empty() && mesh.tangentMissing.empty())
    mesh.tangentMissing = what + " (node " + std::to_string(nodeIndex) + ") has no TANGENT";
  const bool mirrored = appendVertices(attrs, world, baseColor(model, prim), mesh);
  if (textured && !tris.empty() && prim.material >= 0 && prim.material < int(model.materials.size()) &&
      model.materials[size_t(prim.material)].pbrMetallicRoughness.baseColorTexture.index >= 0)
    textured->push_back({first, uint32_t(attrs.vertexCount), mesh.indices.size(), tris.size() / 3 * 3, prim.material,
                         what + " (node " + std::to_string(nodeIndex) + ")"});
  for (size_t t = 0; t + 2 < tris.size(); t += 3) {
    if (mirrored)
      mesh.indices.insert(mesh.indices.end(), {first + tris[t], first + tris[t + 2], first + tris[t + 1]});
    else
      mesh.indices.insert(mesh.indices.end(), {first + tris[t], first + tris[t + 1], first + tris[t + 2]});
  }
  mesh.gltfPrimitives.push_back({nodeIndex, meshIndex, primIndex, first, uint32_t(attrs.vertexCount)});
}

// --- base colour textures: each vertex's albedo times the texture's mean around it ---

detail::Wrap wrapMode(int glMode) {
  return glMode == TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE     ? detail::Wrap::Clamp
         : glMode == TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT ? detail::Wrap::Mirror
                                                           : detail::Wrap::Repeat;
}

// KHR_texture_transform of a texture reference: uv' = T(offset) R(rotation) S(scale) uv, and the
// texture coordinate set it may name instead of the reference's own.
struct UvTransform {
  double m[6] = {1, 0, 0, 0, 1, 0};  // u' = m0 u + m1 v + m2, v' = m3 u + m4 v + m5
  int texCoord = -1;
};

UvTransform uvTransform(const tinygltf::TextureInfo& info) {
  UvTransform t;
  const auto it = info.extensions.find("KHR_texture_transform");
  if (it == info.extensions.end() || !it->second.IsObject()) return t;
  const tinygltf::Value& x = it->second;
  auto number = [&](const tinygltf::Value& v, double fallback) {
    return v.IsNumber() && std::isfinite(v.GetNumberAsDouble()) ? v.GetNumberAsDouble() : fallback;
  };
  auto pair = [&](const char* key, double fallback, double out[2]) {
    out[0] = out[1] = fallback;
    if (x.Has(key) && x.Get(key).IsArray() && x.Get(key).ArrayLen() == 2)
      for (int i = 0; i < 2; ++i) out[i] = number(x.Get(key).Get(i), fallback);
  };
  double offset[2], scale[2];
  pair("offset", 0.0, offset);
  pair("scale", 1.0, scale);
  const double r = x.Has("rotation") ? number(x.Get("rotation"), 0.0) : 0.0, c = std::cos(r), s = std::sin(r);
  t.m[0] = c * scale[0], t.m[1] = s * scale[1], t.m[2] = offset[0];
  t.m[3] = -s * scale[0], t.m[4] = c * scale[1], t.m[5] = offset[1];
  if (x.Has("texCoord") && x.Get("texCoord").IsInt()) t.texCoord = x.Get("texCoord").GetNumberAsInt();
  return t;
}

// The image a material's base colour texture reads, decoded (PNG or JPEG), with its index.
detail::Image decodeBaseColor(const tinygltf::Model& model, int image, const std::vector<std::vector<unsigned char>>& bytes,
                              const std::string& path) {
  const std::string label = "image " + std::to_string(image);
  if (size_t(image) >= bytes.size() || bytes[size_t(image)].empty())
    throw InputError(path, label + " could not be read (a missing file, or a data URI of another type than PNG, JPEG, "
                                   "BMP or GIF), and a base colour texture reads it");
  const auto& b = bytes[size_t(image)];
  const std::string type = detail::imageMediaType({reinterpret_cast<const char*>(b.data()), b.size()});
  if (type != "image/png" && type != "image/jpeg")
    throw InputError(path, label + " is not a PNG or JPEG image (" +
                               (type.empty() ? "unknown: mimeType '" + model.images[size_t(image)].mimeType + "'" : type) +
                               "), which a base colour texture must be for its albedo to be read (give --albedo instead)");
  try {
    return detail::readImageBytes(label, b, detail::LdrDecode::Srgb, /*compact=*/true);
  } catch (const InputError& e) {
    throw InputError(path, e.what());  // "image N: what is wrong", of this file
  }
}

// Multiplies each vertex's albedo in `ranges` by its base colour texture's mean around it
// (detail::textureMeans, detail::multiplyAlbedo), decoding each image once.
void applyBaseColorTextures(const tinygltf::Model& model, const std::vector<std::vector<unsigned char>>& images,
                            std::vector<TexturedRange> ranges, const std::string& path, Mesh& mesh) {
  if (ranges.empty()) return;
  auto textureOf = [&](const TexturedRange& r) -> const tinygltf::Texture& {
    const int t = model.materials[size_t(r.material)].pbrMetallicRoughness.baseColorTexture.index;
    if (t >= int(model.textures.size()))
      throw InputError(path, "material " + std::to_string(r.material) + "'s base colour texture " + std::to_string(t) +
                                 " does not exist");
    const auto& tex = model.textures[size_t(t)];
    if (tex.source < 0 || tex.source >= int(model.images.size()))
      throw InputError(path, "texture " + std::to_string(t) + " (material " + std::to_string(r.material) +
                                 "'s base colour) has no PNG or JPEG image" +
                                 (tex.extensions.empty() ? std::string() : ", only " + tex.extensions.begin()->first) +
                                 ": its albedo cannot be read (give --albedo instead)");
    return tex;
  };
  std::stable_sort(ranges.begin(), ranges.end(), [&](const TexturedRange& a, const TexturedRange& b) {
    return textureOf(a).source < textureOf(b).source;
  });
  std::vector<std::array<double, 3>> triangleAlbedo(mesh.triangleCount());
  std::vector<char> has(mesh.triangleCount(), 0);
  for (size_t r0 = 0; r0 < ranges.size();) {
    const int image = textureOf(ranges[r0]).source;
    size_t r1 = r0;
    while (r1 < ranges.size() && textureOf(ranges[r1]).source == image) ++r1;
    std::vector<detail::TextureUse> uses;
    for (size_t r = r0; r < r1; ++r) {
      const TexturedRange& range = ranges[r];
      const tinygltf::TextureInfo& info = model.materials[size_t(range.material)].pbrMetallicRoughness.baseColorTexture;
      const UvTransform tf = uvTransform(info);
      const int set = tf.texCoord >= 0 ? tf.texCoord : info.texCoord;
      const std::string lacks = range.what + ": its base colour texture reads TEXCOORD_" + std::to_string(set) +
                                ", which it does not have";
      if (set < 0 || size_t(set) >= mesh.uvs.size()) throw InputError(path, lacks);
      const tinygltf::Texture& tex = textureOf(range);
      const tinygltf::Sampler* sampler =
          tex.sampler >= 0 && tex.sampler < int(model.samplers.size()) ? &model.samplers[size_t(tex.sampler)] : nullptr;
      detail::TextureUse use;
      use.wrapS = wrapMode(sampler ? sampler->wrapS : TINYGLTF_TEXTURE_WRAP_REPEAT);
      use.wrapT = wrapMode(sampler ? sampler->wrapT : TINYGLTF_TEXTURE_WRAP_REPEAT);
      for (size_t t = range.firstIndex / 3; t < (range.firstIndex + range.indexCount) / 3; ++t) {
        use.triangles.push_back(uint32_t(t));
        for (int corner = 0; corner < 3; ++corner) {
          const size_t v = mesh.indices[3 * t + size_t(corner)];
          const double u0 = mesh.uvs[size_t(set)][2 * v], v0 = mesh.uvs[size_t(set)][2 * v + 1];
          if (std::isnan(u0) || std::isnan(v0)) throw InputError(path, lacks);
          if (!std::isfinite(u0) || !std::isfinite(v0))
            throw InputError(path, range.what + " TEXCOORD_" + std::to_string(set) + ": vertex " +
                                       std::to_string(v - range.firstVertex) +
                                       " is not finite (its base colour texture cannot be sampled there)");
          use.uv.push_back(tf.m[0] * u0 + tf.m[1] * v0 + tf.m[2]);
          use.uv.push_back(tf.m[3] * u0 + tf.m[4] * v0 + tf.m[5]);
          if (!std::isfinite(use.uv.end()[-2]) || !std::isfinite(use.uv.back()))
            throw InputError(path, range.what + ": KHR_texture_transform takes TEXCOORD_" + std::to_string(set) +
                                       " of vertex " + std::to_string(v - range.firstVertex) + " beyond finite numbers");
        }
      }
      uses.push_back(std::move(use));
    }
    const std::vector<std::array<double, 3>> means = detail::textureMeans(decodeBaseColor(model, image, images, path), uses);
    size_t k = 0;
    for (const auto& use : uses)
      for (uint32_t t : use.triangles) triangleAlbedo[t] = means[k++], has[t] = 1;
    r0 = r1;
  }
  detail::multiplyAlbedo(mesh, triangleAlbedo, has);
}

}  // namespace

Mesh loadGltf(const std::string& path, MeshAlbedo albedo) {
  tinygltf::Model model;
  std::vector<std::string> external;
  std::vector<std::vector<unsigned char>> images;
  detail::loadGltfModel(path, model, &external, albedo == MeshAlbedo::Textures ? &images : nullptr);
  std::vector<TexturedRange> textured;
  Mesh mesh;
  mesh.sourcePath = path;
  mesh.inputFiles = {path};
  mesh.inputFiles.insert(mesh.inputFiles.end(), external.begin(), external.end());
  mesh.format = Mesh::Format::Gltf;
  // Each node is walked once: one reached again is a cycle, or has two parents (which glTF 2.0
  // forbids; a chain of such nodes would multiply the instances without bound).
  std::vector<char> onPath(model.nodes.size(), 0), walked(model.nodes.size(), 0);
  std::function<void(int, const Mat4&)> walk = [&](int ni, const Mat4& parent) {
    if (ni < 0 || ni >= int(model.nodes.size())) throw InputError(path, "node " + std::to_string(ni) + " does not exist");
    if (onPath[ni]) throw InputError(path, "the node hierarchy has a cycle at node " + std::to_string(ni));
    if (walked[ni])
      throw InputError(path, "node " + std::to_string(ni) +
                                 " is reached twice: a child of two nodes, or a scene root twice or also a child "
                                 "(glTF 2.0 gives a node one parent)");
    onPath[ni] = walked[ni] = 1;
    const auto& node = model.nodes[ni];
    const Mat4 world = mul(parent, nodeMatrix(node));
    if (node.mesh >= 0) {
      if (node.mesh >= int(model.meshes.size())) throw InputError(path, "mesh " + std::to_string(node.mesh) + " does not exist");
      for (size_t pi = 0; pi < model.meshes[node.mesh].primitives.size(); ++pi)
        addPrimitive(model, ni, node.mesh, int(pi), world, path, mesh,
                     albedo == MeshAlbedo::Textures ? &textured : nullptr);
    }
    for (int c : node.children) walk(c, world);
    onPath[ni] = 0;
  };
  // Every set that some primitive has is read; a set that a triangle primitive lacks is dropped.
  int sets = 0;
  for (const auto& m : model.meshes)
    for (const auto& prim : m.primitives)
      for (int k = 0; k < kMaxUvSets; ++k)
        if (prim.attributes.count("TEXCOORD_" + std::to_string(k))) sets = std::max(sets, k + 1);
  mesh.uvs.resize(size_t(sets));
  mesh.uvMissing.resize(size_t(sets));
  for (int r : detail::gltfRootNodes(model)) walk(r, identity());
  applyBaseColorTextures(model, images, std::move(textured), path, mesh);
  for (size_t k = 0; k < mesh.uvs.size(); ++k)
    if (!mesh.uvMissing[k].empty() || mesh.indices.empty()) mesh.uvs[k].clear();
  if (!mesh.tangentMissing.empty() || mesh.indices.empty()) mesh.tangents.clear();
  return mesh;
}

}  // namespace prtbake
