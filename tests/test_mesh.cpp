// Mesh loaders: glTF (binary, text with data URIs, strips, fans, non-indexed, node
// transforms, missing normals, COLOR_0), OBJ (mary.obj), and bad inputs.
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/limits.h"
#include "prtbake/mesh.h"
#include "prtbake/transport.h"
#include "test_common.h"

#include <stb/stb_image_write.h>

using namespace prtbake;
namespace fs = std::filesystem;

namespace {
// Loader arithmetic is float: transformed positions and renormalised normals carry a
// few ulps of float (~1e-7 relative); 1e-5 leaves room without hiding a wrong transform.
constexpr double kGeomTol = 1e-5;

std::string base64(const std::string& in) {
  static const char* t = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const unsigned v = (unsigned char)in[i] << 16 | (unsigned char)in[i + 1] << 8 | (unsigned char)in[i + 2];
    out += t[v >> 18], out += t[(v >> 12) & 63], out += t[(v >> 6) & 63], out += t[v & 63];
  }
  if (i + 1 == in.size()) {
    const unsigned v = (unsigned char)in[i] << 16;
    out += t[v >> 18], out += t[(v >> 12) & 63], out += "==";
  } else if (i + 2 == in.size()) {
    const unsigned v = (unsigned char)in[i] << 16 | (unsigned char)in[i + 1] << 8;
    out += t[v >> 18], out += t[(v >> 12) & 63], out += t[(v >> 6) & 63], out += '=';
  }
  return out;
}

template <class T>
void append(std::string& buf, const std::vector<T>& v) {
  buf.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

void writeText(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

// A .gltf with one data-URI buffer: four vertices of the unit square in z = 0
// (no normals, a COLOR_0), drawn three ways: indexed strip, non-indexed fan,
// indexed triangles; node 1 mirrors x (scale −1) and is translated by +2 in z.
std::string makeTestGltf(const std::string& dir) {
  const std::vector<float> pos = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
  const std::vector<float> col = {0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f};
  const std::vector<uint16_t> strip = {0, 1, 2, 3};
  const std::vector<float> fanPos = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  const std::vector<uint8_t> tris = {0, 1, 3, 0, 3, 2};
  std::string buf;
  append(buf, pos);            // 0..48
  append(buf, col);            // 48..96
  append(buf, strip);          // 96..104
  append(buf, fanPos);         // 104..152
  append(buf, tris);           // 152..158
  const std::string json = R"({
  "asset": {"version": "2.0"},
  "scene": 0,
  "scenes": [{"nodes": [0, 1]}],
  "nodes": [{"mesh": 0}, {"mesh": 1, "scale": [-1, 1, 1], "translation": [0, 0, 2]}],
  "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.5, 1.0, 1.0, 1.0]}}],
  "meshes": [
    {"primitives": [{"attributes": {"POSITION": 0, "COLOR_0": 1}, "indices": 2, "mode": 5, "material": 0},
                    {"attributes": {"POSITION": 3}, "mode": 6}]},
    {"primitives": [{"attributes": {"POSITION": 0}, "indices": 4}]}],
  "buffers": [{"byteLength": 158, "uri": "data:application/octet-stream;base64,)" + base64(buf) + R"("}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                  {"buffer": 0, "byteOffset": 48, "byteLength": 48},
                  {"buffer": 0, "byteOffset": 96, "byteLength": 8},
                  {"buffer": 0, "byteOffset": 104, "byteLength": 48},
                  {"buffer": 0, "byteOffset": 152, "byteLength": 6}],
  "accessors": [
    {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
    {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
    {"bufferView": 2, "componentType": 5123, "count": 4, "type": "SCALAR"},
    {"bufferView": 3, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
    {"bufferView": 4, "componentType": 5121, "count": 6, "type": "SCALAR"}]
})";
  const std::string path = dir + "/square.gltf";
  writeText(path, json);
  return path;
}
// An 8-bit RGB PNG of w × h texels: rows [0, split) in sRGB codes `a`, the rest in `b`.
std::string pngBytes(int w, int h, int split, std::array<uint8_t, 3> a, std::array<uint8_t, 3> b) {
  std::vector<uint8_t> px(size_t(3 * w * h));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) px[size_t(3 * (y * w + x) + c)] = y < split ? a[size_t(c)] : b[size_t(c)];
  std::string out;
  stbi_write_png_to_func([](void* ctx, void* data, int n) { static_cast<std::string*>(ctx)->append((char*)data, size_t(n)); },
                         &out, w, h, 3, px.data(), 3 * w);
  return out;
}

double srgbLinear(int code) {
  const double c = code / 255.0;
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

// A .gltf of unit squares in z = 0 (corners 0 (0,0), 1 (1,0), 2 (0,1), 3 (1,1); triangles 0 1 3 and
// 0 3 2), one primitive per entry of `prims` ("material index, uv accessor": accessor 1 maps the
// square onto the image's top half, v in [0, 0.5]; accessor 2 onto the whole image), with the
// given materials, textures, samplers and images (JSON arrays' contents).
std::string makeTexturedGltf(const std::string& path, const std::vector<std::pair<int, int>>& prims,
                             const std::string& materials, const std::string& textures, const std::string& images,
                             const std::string& samplers = "", const std::string& secondNode = "") {
  const std::vector<float> pos = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
  const std::vector<float> uvTop = {0, 0, 1, 0, 0, 0.5f, 1, 0.5f}, uvAll = {0, 0, 1, 0, 0, 1, 1, 1};
  const std::vector<uint16_t> tris = {0, 1, 3, 0, 3, 2};
  std::string buf;
  append(buf, pos);    // 0..48
  append(buf, uvTop);  // 48..80
  append(buf, uvAll);  // 80..112
  append(buf, tris);   // 112..124
  std::string primitives;
  for (const auto& [material, uv] : prims)
    primitives += std::string(primitives.empty() ? "" : ",") + R"({"attributes": {"POSITION": 0, "TEXCOORD_0": )" +
                  std::to_string(uv) + R"(}, "indices": 3, "material": )" + std::to_string(material) + "}";
  writeText(path, std::string(R"({"asset": {"version": "2.0"}, "scene": 0, )") +
                       (secondNode.empty() ? R"("scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],)"
                                           : R"("scenes": [{"nodes": [0, 1]}], "nodes": [{"mesh": 0}, )" + secondNode + "],") +
                       R"(
  "meshes": [{"primitives": [)" + primitives + R"(]}],
  "materials": [)" + materials + R"(], "textures": [)" + textures + R"(], "images": [)" + images + "]" +
                        (samplers.empty() ? "" : R"(, "samplers": [)" + samplers + "]") + R"(,
  "buffers": [{"byteLength": 124, "uri": "data:application/octet-stream;base64,)" + base64(buf) + R"("}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 32},
                  {"buffer": 0, "byteOffset": 80, "byteLength": 32}, {"buffer": 0, "byteOffset": 112, "byteLength": 12}],
  "accessors": [
    {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
    {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
    {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
    {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"}]})");
  return path;
}
}  // namespace

static void expectInputError(const std::string& path, const std::string& what, MeshAlbedo albedo = MeshAlbedo::Factors);

// The albedo of a textured asset was its base colour factor alone: Duck.glb (factor 1, a yellow
// texture) bounced light as a white surface. With MeshAlbedo::Textures each vertex takes the
// texture's mean over its triangles, weighted by their areas.
TEST_CASE("glTF loader: the base colour texture's mean around each vertex multiplies the albedo", "[mesh]") {
  const std::string dir = test::tempDir("mesh-texture");
  // Top half A, bottom half B (sRGB codes), 64 × 64 texels.
  const std::array<uint8_t, 3> codeA = {200, 100, 50}, codeB = {20, 60, 220};
  const std::string image = R"({"uri": "data:image/png;base64,)" + base64(pngBytes(64, 64, 32, codeA, codeB)) + R"("})";
  const std::string path = makeTexturedGltf(
      dir + "/textured.gltf", {{0, 1}, {1, 1}, {2, 2}},
      R"({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}},
         {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "extensions": {"KHR_texture_transform": {"offset": [0, 0.5]}}}}},
         {"pbrMetallicRoughness": {"baseColorFactor": [0.5, 1, 1, 1], "baseColorTexture": {"index": 0}}})",
      R"({"source": 0, "sampler": 0})", image, R"({"wrapT": 33071})");
  std::array<double, 3> a{}, b{};
  for (int c = 0; c < 3; ++c) a[size_t(c)] = srgbLinear(codeA[size_t(c)]), b[size_t(c)] = srgbLinear(codeB[size_t(c)]);
  // Two effects blur the colour edge at v = 0.5 (y = 32 texels): bilinear sampling blends the rows
  // on either side within half a texel (at most 0.5 × 0.25 / 32 = 0.4 % of the step over a
  // 32-texel-tall footprint), and the ~46 × 46 sub-triangle centroids that straddle the edge
  // (about 1/46 = 2 % of them, half counted on each side). 2.5 % of the step holds both.
  constexpr double kEdgeTol = 0.025;
  auto expectMix = [&](const Mesh& m, uint32_t v, double weightA, std::array<double, 3> factor) {
    for (int c = 0; c < 3; ++c) {
      INFO("vertex " << v << " channel " << c);
      const double want = factor[size_t(c)] * (weightA * a[size_t(c)] + (1 - weightA) * b[size_t(c)]);
      CHECK(std::abs(m.albedo[3 * v + size_t(c)] - want) <= kEdgeTol * std::abs(a[size_t(c)] - b[size_t(c)]) + 1e-6);
    }
  };
  const Mesh m = loadMesh(path, MeshAlbedo::Textures);
  REQUIRE(m.vertexCount() == 12);
  for (uint32_t v = 0; v < 4; ++v) expectMix(m, v, 1.0, {1, 1, 1});      // the top half: A
  for (uint32_t v = 4; v < 8; ++v) expectMix(m, v, 0.0, {1, 1, 1});      // moved down by the transform: B
  // The whole image, factor (0.5, 1, 1): triangle 0 1 3 is wide where v is small (3/4 of it in
  // the top half), triangle 0 3 2 the reverse; corners 0 and 3 share both (equal areas).
  expectMix(m, 8, 0.5, {0.5, 1, 1});
  expectMix(m, 9, 0.75, {0.5, 1, 1});
  expectMix(m, 10, 0.25, {0.5, 1, 1});
  expectMix(m, 11, 0.5, {0.5, 1, 1});
  // Without textures (the default, for the bakes that do not use the albedo): the factors alone.
  const Mesh f = loadMesh(path);
  CHECK(f.albedo[0] == 1.0f);
  CHECK(f.albedo[3 * 8] == 0.5f);
  CHECK(f.albedo[3 * 8 + 1] == 1.0f);

  // A texture prtbake cannot decode, or one that reads a set the primitive lacks, is refused
  // with the file and the reason; without textures the file loads.
  writeText(dir + "/tex.ktx2", "\xabKTX 20\xbb\r\n\x1a\n0000");
  const std::string ktx2 = makeTexturedGltf(dir + "/ktx2.gltf", {{0, 1}}, R"({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}})",
                                            R"({"source": 0})", R"({"uri": "tex.ktx2", "mimeType": "image/ktx2"})");
  CHECK_NOTHROW(loadMesh(ktx2));
  expectInputError(ktx2, "image 0 is not a PNG or JPEG image (image/ktx2)", MeshAlbedo::Textures);
  const std::string dataKtx2 = makeTexturedGltf(dir + "/ktx2-uri.gltf", {{0, 1}},
                                                R"({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}})", R"({"source": 0})",
                                                R"({"uri": "data:image/ktx2;base64,)" + base64("\xabKTX 20\xbb") + R"("})");
  expectInputError(dataKtx2, "image 0 could not be read", MeshAlbedo::Textures);
  const std::string missing = makeTexturedGltf(dir + "/missing.gltf", {{0, 1}},
                                               R"({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}})", R"({"source": 0})",
                                               R"({"uri": "nowhere.png"})");
  expectInputError(missing, "image 0 could not be read", MeshAlbedo::Textures);
  writeText(dir + "/broken.png", pngBytes(8, 8, 4, {1, 2, 3}, {4, 5, 6}).substr(0, 40));
  const std::string broken = makeTexturedGltf(dir + "/broken.gltf", {{0, 1}},
                                              R"({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}})", R"({"source": 0})",
                                              R"({"uri": "broken.png"})");
  expectInputError(broken, "image 0: cannot decode image", MeshAlbedo::Textures);
  const std::string set1 = makeTexturedGltf(dir + "/set1.gltf", {{0, 1}},
                                            R"({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "texCoord": 1}}})",
                                            R"({"source": 0})", image);
  expectInputError(set1, "reads TEXCOORD_1", MeshAlbedo::Textures);
  const std::string noSource = makeTexturedGltf(dir + "/nosource.gltf", {{0, 1}},
                                                R"({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}})",
                                                R"({"extensions": {"KHR_texture_basisu": {"source": 0}}})", image);
  expectInputError(noSource, "has no PNG or JPEG image", MeshAlbedo::Textures);
  const std::string far = makeTexturedGltf(
      dir + "/far.gltf", {{0, 1}},
      R"({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "extensions": {"KHR_texture_transform": {"offset": [1e308, 0], "scale": [1e308, 1]}}}}})",
      R"({"source": 0})", image);
  expectInputError(far, "beyond finite numbers", MeshAlbedo::Textures);
  fs::remove_all(dir);
}

// An OBJ's albedo was 1 whatever its materials said. With MeshAlbedo::Textures each vertex takes the
// area-weighted mean over its faces of their material's Kd (1 where none is given) times the mean of
// its map_Kd, whose -o, -s act on OBJ's v-up coordinates.
TEST_CASE("OBJ loader: the faces' .mtl Kd and map_Kd give the albedo", "[mesh]") {
  const std::string dir = test::tempDir("mesh-obj-mtl");
  const std::array<uint8_t, 3> code = {180, 120, 60}, codeA = {200, 100, 50}, codeB = {20, 60, 220};
  writeText(dir + "/tex.png", pngBytes(8, 8, 8, code, code));
  writeText(dir + "/ab.png", pngBytes(64, 64, 32, codeA, codeB));  // rows 0-31 (the top, OBJ's v > 0.5) A
  writeText(dir + "/m.mtl", "newmtl red\nKd 0.8 0.1 0.1\n"
                            "newmtl tex\nmap_Kd tex.png\n"
                            "newmtl half\nKd 0.5 0.5 0.5\nmap_Kd tex.png\n"
                            "newmtl shifted\nmap_Kd -o 0 0.5 0 ab.png\n");
  // Five unit squares side by side in z = 0, their own vertices: red, tex, half, one split between
  // red and tex along its diagonal (equal areas), and one over OBJ's v in [0, 0.5] moved up by -o.
  std::string obj = "mtllib m.mtl\n";
  for (int q = 0; q < 5; ++q) {
    obj += "v " + std::to_string(2 * q) + " 0 0\nv " + std::to_string(2 * q + 1) + " 0 0\nv " + std::to_string(2 * q + 1) +
           " 1 0\nv " + std::to_string(2 * q) + " 1 0\n";
    obj += q == 4 ? "vt 0 0\nvt 1 0\nvt 1 0.5\nvt 0 0.5\n" : "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n";
  }
  auto face = [](int q, int a, int b, int c) {
    auto corner = [&](int k) { return std::to_string(4 * q + k) + "/" + std::to_string(4 * q + k); };
    return "f " + corner(a) + " " + corner(b) + " " + corner(c) + "\n";
  };
  obj += "usemtl red\n" + face(0, 1, 2, 3) + face(0, 1, 3, 4);
  obj += "usemtl tex\n" + face(1, 1, 2, 3) + face(1, 1, 3, 4);
  obj += "usemtl half\n" + face(2, 1, 2, 3) + face(2, 1, 3, 4);
  obj += "usemtl red\n" + face(3, 1, 2, 3) + "usemtl tex\n" + face(3, 1, 3, 4);
  obj += "usemtl shifted\n" + face(4, 1, 2, 3) + face(4, 1, 3, 4);
  writeText(dir + "/m.obj", obj);
  const Mesh m = loadMesh(dir + "/m.obj", MeshAlbedo::Textures);
  REQUIRE(m.vertexCount() == 20);
  const std::array<double, 3> red = {0.8, 0.1, 0.1};
  std::array<double, 3> tex{}, a{}, b{};
  for (size_t c = 0; c < 3; ++c) tex[c] = srgbLinear(code[c]), a[c] = srgbLinear(codeA[c]), b[c] = srgbLinear(codeB[c]);
  // A uniform texture's mean is its one value (float rounding: 1e-6).
  auto expect = [&](uint32_t v, std::array<double, 3> want, double tol) {
    for (size_t c = 0; c < 3; ++c) {
      INFO("vertex " << v << " channel " << c);
      CHECK(std::abs(m.albedo[3 * v + c] - want[c]) <= tol);
    }
  };
  for (uint32_t v = 0; v < 4; ++v) expect(v, red, 1e-6);
  for (uint32_t v = 4; v < 8; ++v) expect(v, tex, 1e-6);
  for (uint32_t v = 8; v < 12; ++v) expect(v, {0.5 * tex[0], 0.5 * tex[1], 0.5 * tex[2]}, 1e-6);
  // The split square: corners 1 and 3 of both faces take the mean, 2 red's, 4 tex's.
  const std::array<double, 3> mean = {(red[0] + tex[0]) / 2, (red[1] + tex[1]) / 2, (red[2] + tex[2]) / 2};
  expect(12, mean, 1e-6);
  expect(13, red, 1e-6);
  expect(14, mean, 1e-6);
  expect(15, tex, 1e-6);
  // v in [0, 0.5] is the image's bottom half (B); moved up by 0.5 it reads the top (A), within the
  // blur of the colour edge as in the glTF test (2.5 % of the step).
  for (uint32_t v = 16; v < 20; ++v)
    for (size_t c = 0; c < 3; ++c) {
      INFO("vertex " << v << " channel " << c);
      CHECK(std::abs(m.albedo[3 * v + c] - a[c]) <= 0.025 * std::abs(a[c] - b[c]) + 1e-6);
    }
  CHECK(std::find(m.inputFiles.begin(), m.inputFiles.end(), dir + "/m.mtl") != m.inputFiles.end());
  CHECK(std::find(m.inputFiles.begin(), m.inputFiles.end(), dir + "/ab.png") != m.inputFiles.end());
  // Without textures the materials are not read: albedo 1, and a missing library is no error.
  const Mesh f = loadMesh(dir + "/m.obj");
  CHECK(f.albedo[0] == 1.0f);
  fs::remove(dir + "/m.mtl");
  CHECK_NOTHROW(loadMesh(dir + "/m.obj"));
  try {
    loadMesh(dir + "/m.obj", MeshAlbedo::Textures);
    FAIL("no error for the missing library");
  } catch (const InputError& e) {
    INFO(e.what());
    CHECK(e.subject() == dir + "/m.mtl");
    CHECK(std::string(e.what()).find("give --albedo instead") != std::string::npos);
  }
  // A map_Kd on a file whose faces lack vt.
  writeText(dir + "/m.mtl", "newmtl tex\nmap_Kd tex.png\n");
  writeText(dir + "/novt.obj", "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl tex\nf 1 2 3\n");
  expectInputError(dir + "/novt.obj", "has a map_Kd", MeshAlbedo::Textures);
  writeText(dir + "/m.mtl", "newmtl tex\nmap_Kd -s 1e308 1 1 -o 1e308 0 0 tex.png\n");
  try {
    loadMesh(dir + "/m.obj", MeshAlbedo::Textures);
    FAIL("no error for a texture coordinate beyond finite numbers");
  } catch (const InputError& e) {
    INFO(e.what());
    CHECK(e.subject() == dir + "/m.mtl");
    CHECK(std::string(e.what()).find("not finite") != std::string::npos);
  }
  // tinyobjloader reads -o as three numbers and took the file name for the third: refused, not
  // dropped.
  writeText(dir + "/m.mtl", "newmtl tex\nmap_Kd -o 0 0.5 tex.png\n");
  try {
    loadMesh(dir + "/m.obj", MeshAlbedo::Textures);
    FAIL("no error for a map_Kd without its file");
  } catch (const InputError& e) {
    INFO(e.what());
    CHECK(e.subject() == dir + "/m.mtl");
    CHECK(std::string(e.what()).find("names no file") != std::string::npos);
  }
  fs::remove_all(dir);
}

// The bakes that use the albedo read the textures: an interreflected corner (a floor and a wall
// that light each other) textured in one colour, in an image file beside the .gltf, gives the
// transport of the same corner whose base colour factor is that colour, linear.
TEST_CASE("CLI transport: an interreflected bake reads the base colour texture", "[mesh][transport][cli]") {
  const std::string dir = test::tempDir("mesh-texture-cli");
  const std::array<uint8_t, 3> code = {180, 120, 60};
  writeText(dir + "/tex.png", pngBytes(8, 8, 8, code, code));
  const std::string wall = R"({"mesh": 0, "rotation": [0, 0.70710678, 0, 0.70710678], "translation": [0, 0, 1]})";
  const std::string textured = makeTexturedGltf(dir + "/textured.gltf", {{0, 2}},
                                                R"({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}})",
                                                R"({"source": 0})", R"({"uri": "tex.png"})", "", wall);
  char factor[160];
  std::snprintf(factor, sizeof factor, R"({"pbrMetallicRoughness": {"baseColorFactor": [%.17g, %.17g, %.17g, 1]}})",
                srgbLinear(code[0]), srgbLinear(code[1]), srgbLinear(code[2]));
  const std::string plain = makeTexturedGltf(dir + "/plain.gltf", {{0, 2}}, factor, "", "", "", wall);
  for (const std::string& f : {textured, plain}) {
    const auto r = test::runCli("transport '" + f + "' -o '" + f + ".npy' --mode interreflected --bounces 2 --order 2 "
                                "--samples 64 --quiet");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
  }
  // The control: the textured corner as white (the albedo the factor alone gives) bounces more.
  const auto white = test::runCli("transport '" + textured + "' -o '" + dir + "/white.npy' --mode interreflected "
                                  "--bounces 2 --order 2 --samples 64 --albedo 1 --quiet");
  REQUIRE(white.exitCode == 0);
  const TransportCoeffs t = readTransportNpy(textured + ".npy"), p = readTransportNpy(plain + ".npy");
  REQUIRE(t.channels == 3);
  REQUIRE(t.coeffs.size() == p.coeffs.size());
  // The same rays and the same albedo (the texture's one code value, decoded as the factor was
  // computed, both rounded to float): equal up to float rounding in the bounce sums.
  constexpr double kFloatTol = 1e-5;
  const TransportCoeffs w = readTransportNpy(dir + "/white.npy");
  REQUIRE(w.channels == 1);
  double most = 0, whiteMost = 0;
  for (size_t i = 0; i < t.coeffs.size(); ++i) {
    most = std::max(most, double(std::abs(t.coeffs[i] - p.coeffs[i])));
    whiteMost = std::max(whiteMost, double(std::abs(t.coeffs[i] - w.coeffs[i / 12 * 4 + i % 4])));  // grey: V x 4
  }
  CHECK(most <= kFloatTol);
  CHECK(whiteMost > 100 * kFloatTol);
  fs::remove_all(dir);
}

TEST_CASE("glTF loader: strips, fans, non-indexed, data URIs, transforms, normals, albedo", "[mesh]") {
  const std::string dir = test::tempDir("mesh-gltf");
  const Mesh m = loadMesh(makeTestGltf(dir));
  REQUIRE(m.vertexCount() == 12);
  REQUIRE(m.triangleCount() == 6);
  REQUIRE(m.gltfPrimitives.size() == 3);
  // Every triangle of the strip and the fan faces +z (counter-clockwise seen from +z):
  // the computed normals are +z. The mirrored instance keeps its front face +z too
  // (a negative determinant flips the winding), at z = 2.
  for (size_t v = 0; v < m.vertexCount(); ++v) {
    INFO("vertex " << v);
    CHECK(m.normals[3 * v + 2] == Approx(1.0).margin(kGeomTol));
  }
  const auto& mirrored = m.gltfPrimitives[2];
  CHECK(m.positions[3 * (mirrored.firstVertex + 1)] == Approx(-1.0).margin(kGeomTol));
  CHECK(m.positions[3 * (mirrored.firstVertex + 1) + 2] == Approx(2.0).margin(kGeomTol));
  // Albedo = baseColorFactor × COLOR_0 on the strip; 1 where neither is given.
  CHECK(m.albedo[0] == Approx(0.25));
  CHECK(m.albedo[1] == Approx(0.5));
  CHECK(m.albedo[3 * 4] == Approx(1.0));
  CHECK_FALSE(m.greyAlbedo());
  // Triangles cover each square exactly once: total area 3.
  double area = 0;
  for (size_t t = 0; t < m.triangleCount(); ++t) {
    const float* a = &m.positions[3 * m.indices[3 * t]];
    const float* b = &m.positions[3 * m.indices[3 * t + 1]];
    const float* c = &m.positions[3 * m.indices[3 * t + 2]];
    const double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double z = e1[0] * e2[1] - e1[1] * e2[0];
    CHECK(z > 0);  // counter-clockwise seen from +z
    area += 0.5 * std::abs(z);
  }
  CHECK(area == Approx(3.0));
}

// Sparse accessors were not read: their replaced elements kept the base values (zeros without a
// buffer view), so a mesh stored that way lost its shape without a word; and a file that
// requires Draco compression had accessors without data: "vertex 0 has length 0 (glTF 2.0
// requires unit normals)".
TEST_CASE("glTF loader: sparse accessors replace the elements they name, and unknown required extensions are refused",
          "[mesh]") {
  const std::string dir = test::tempDir("mesh-sparse");
  const std::vector<float> square = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
  const std::vector<uint8_t> tris = {0, 1, 3, 0, 3, 2};
  const std::vector<uint16_t> one = {3}, all = {0, 1, 2, 3};
  const std::vector<float> moved = {2, 3, 0.5f};
  std::string buf;
  append(buf, square);  // 0..48
  append(buf, tris);    // 48..54
  buf.resize(56);
  append(buf, one);     // 56..58
  buf.resize(60);
  append(buf, moved);   // 60..72
  append(buf, all);     // 72..80
  append(buf, square);  // 80..128
  auto gltf = [&](const std::string& name, const std::string& position, const std::string& extra) {
    writeText(dir + "/" + name, R"({"asset": {"version": "2.0"}, )" + extra + R"(
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}], "nodes": [{"mesh": 0}],
  "buffers": [{"byteLength": 128, "uri": "data:application/octet-stream;base64,)" + base64(buf) + R"("}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 6},
                  {"buffer": 0, "byteOffset": 56, "byteLength": 2}, {"buffer": 0, "byteOffset": 60, "byteLength": 12},
                  {"buffer": 0, "byteOffset": 72, "byteLength": 8}, {"buffer": 0, "byteOffset": 80, "byteLength": 48}],
  "accessors": [)" + position + R"(, {"bufferView": 1, "componentType": 5121, "count": 6, "type": "SCALAR"}]})");
    return dir + "/" + name;
  };
  // Vertex 3 moved by a sparse accessor over the square.
  const Mesh m = loadMesh(gltf("one.gltf", R"({"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
    "sparse": {"count": 1, "indices": {"bufferView": 2, "componentType": 5123}, "values": {"bufferView": 3}}})", ""));
  REQUIRE(m.vertexCount() == 4);
  const std::vector<float> expect = {0, 0, 0, 1, 0, 0, 0, 1, 0, 2, 3, 0.5f};
  CHECK(m.positions == expect);
  // No buffer view: zeros, every element replaced (the square itself).
  const Mesh z = loadMesh(gltf("all.gltf", R"({"componentType": 5126, "count": 4, "type": "VEC3",
    "sparse": {"count": 4, "indices": {"bufferView": 4, "componentType": 5123}, "values": {"bufferView": 5}}})", ""));
  CHECK(z.positions == square);
  // Bad sparse data: an index past the count, more replacements than elements.
  auto refused = [&](const std::string& path, const std::string& what) {
    INFO(path);
    try {
      loadMesh(path);
      FAIL("accepted");
    } catch (const InputError& e) {
      CHECK(e.subject() == path);
      CHECK_THAT(e.detail(), Catch::Contains(what));
    }
  };
  refused(gltf("past.gltf", R"({"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
    "sparse": {"count": 1, "indices": {"bufferView": 2, "componentType": 5123}, "values": {"bufferView": 3}}})", ""),
          "replaces element 3 of 3");
  refused(gltf("many.gltf", R"({"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
    "sparse": {"count": 9, "indices": {"bufferView": 2, "componentType": 5123}, "values": {"bufferView": 3}}})", ""),
          "replaces 9 of its 4 elements");
  // Required extensions: geometry this loader does not decode is refused; quantised is read.
  const std::string plain = R"({"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"})";
  refused(gltf("draco.gltf", plain, R"("extensionsUsed": ["KHR_draco_mesh_compression"],
    "extensionsRequired": ["KHR_draco_mesh_compression"],)"),
          "requires the glTF extension KHR_draco_mesh_compression, which this loader does not read");
  refused(gltf("instanced.gltf", plain, R"("extensionsUsed": ["EXT_mesh_gpu_instancing"],
    "extensionsRequired": ["EXT_mesh_gpu_instancing"],)"),
          "requires the glTF extension EXT_mesh_gpu_instancing");
  CHECK(loadMesh(gltf("quantised.gltf", plain, R"("extensionsUsed": ["KHR_mesh_quantization"],
    "extensionsRequired": ["KHR_mesh_quantization"],)")).positions == square);
}

// 40 nodes, each with two children that are the same next node: 2^40 instances of the square,
// which ran the loader out of memory ("out of host memory", no file named). glTF 2.0 gives a node
// one parent; a node reached twice is refused, as a cycle is.
TEST_CASE("glTF loader: a node with two parents is refused, and instances count against the input memory limit", "[mesh]") {
  const std::string dir = test::tempDir("mesh-dag");
  const std::vector<float> square = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
  const std::vector<uint8_t> tris = {0, 1, 3, 0, 3, 2};
  std::string buf;
  append(buf, square);
  append(buf, tris);
  std::string nodes;
  for (int i = 0; i < 40; ++i) nodes += R"({"children": [)" + std::to_string(i + 1) + ", " + std::to_string(i + 1) + "]}, ";
  const std::string path = dir + "/dag.gltf";
  writeText(path, R"({"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [)" + nodes + R"({"mesh": 0}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
  "buffers": [{"byteLength": 54, "uri": "data:application/octet-stream;base64,)" + base64(buf) + R"("}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 6}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
                {"bufferView": 1, "componentType": 5121, "count": 6, "type": "SCALAR"}]})");
  try {
    loadMesh(path);
    FAIL("accepted");
  } catch (const InputError& e) {
    CHECK(e.subject() == path);
    CHECK_THAT(e.detail(), Catch::StartsWith("node 40 is reached twice"));
  }
  // Legal instancing counts too: 2,000 nodes of the square are 8,000 vertices (about 416 KB in
  // the mesh's arrays), refused under a 0.25 MiB input limit and loaded under the default.
  nodes.clear();
  for (int i = 0; i < 2000; ++i) nodes += std::string(i ? ", " : "") + R"({"mesh": 0, "translation": [0, 0, )" + std::to_string(i) + "]}";
  std::string roots;
  for (int i = 0; i < 2000; ++i) roots += (i ? ", " : "") + std::to_string(i);
  const std::string many = dir + "/many.gltf";
  writeText(many, R"({"asset": {"version": "2.0"}, "scenes": [{"nodes": [)" + roots + R"(]}], "nodes": [)" + nodes + R"(],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
  "buffers": [{"byteLength": 54, "uri": "data:application/octet-stream;base64,)" + base64(buf) + R"("}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 6}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
                {"bufferView": 1, "componentType": 5121, "count": 6, "type": "SCALAR"}]})");
  CHECK(loadMesh(many).vertexCount() == 8000);
  setInputMemoryLimit(size_t(0.25 * 1048576));
  try {
    loadMesh(many);
    FAIL("accepted");
  } catch (const InputError& e) {
    CHECK_THAT(e.detail(), Catch::Contains("vertices (every instance of every primitive) needs"));
  }
  setInputMemoryLimit(0);
}

TEST_CASE("glTF loader: Box.glb in world space", "[mesh][data]") {
  const std::string path = test::dataFile("meshes/gltf/Box.glb");
  PRTBAKE_SKIP_IF_NO_DATA(path);
  const Mesh m = loadMesh(path);
  CHECK(m.vertexCount() == 24);
  CHECK(m.triangleCount() == 12);
  // Red material: baseColorFactor (0.8, 0, 0).
  CHECK(m.albedo[0] == Approx(0.8));
  CHECK(m.albedo[1] == 0.0f);
  // The root node rotates +Y to +Z... every normal stays a unit axis vector and
  // points away from the cube's centre (the origin).
  for (size_t v = 0; v < m.vertexCount(); ++v) {
    const float* n = &m.normals[3 * v];
    const float* p = &m.positions[3 * v];
    CHECK(std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) == Approx(1.0).margin(kGeomTol));
    CHECK(n[0] * p[0] + n[1] * p[1] + n[2] * p[2] == Approx(0.5).margin(kGeomTol));
  }
}

TEST_CASE("OBJ loader: mary.obj (GAMES202 scene)", "[mesh][data]") {
  const std::string path = test::dataFile("meshes/obj/mary.obj");
  PRTBAKE_SKIP_IF_NO_DATA(path);
  const Mesh m = loadMesh(path);
  // 10174 faces; distinct (v, vt, vn) triples as the framework's loader counts them.
  CHECK(m.triangleCount() == 10174);
  CHECK(m.vertexCount() == 7905);
  CHECK(m.greyAlbedo());
}

TEST_CASE("OBJ loader: zero-length normals are recomputed, duplicates and degenerates kept", "[mesh]") {
  const std::string dir = test::tempDir("mesh-obj");
  writeText(dir + "/q.obj",
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 0\nvn 0 0 0\nvn 0 0 1\n"
            "f 1//1 2//1 3//1\nf 1//2 3//2 4//2\nf 5//2 2//2 2//2\n");
  const Mesh m = loadMesh(dir + "/q.obj");
  CHECK(m.triangleCount() == 3);
  for (size_t v = 0; v < m.vertexCount(); ++v) {
    INFO("vertex " << v);
    CHECK(m.normals[3 * v + 2] == Approx(1.0).margin(kGeomTol));
  }
}

// A one-triangle glTF (data URI) whose NORMAL or COLOR_0 accessor has fewer
// elements than POSITION, or whose NORMAL view has a stride longer than its data
// allows. The loader read past the end of the buffer for the first case before the
// accessor counts were checked against each other (found by fuzzing; under ASan a
// heap-buffer-overflow); now each is one InputError naming the attribute.
static std::string attributeMismatchGltf(const std::string& dir, const std::string& name, int normals, int colors,
                                         int normalStride) {
  const std::vector<float> pos = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const std::vector<float> nrm = {0, 0, 1, 0, 0, 1, 0, 0, 1};
  std::string buf;
  append(buf, pos);  // 0..36
  append(buf, nrm);  // 36..72
  const std::string json = R"({"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "COLOR_0": 2}}]}],
  "buffers": [{"byteLength": 72, "uri": "data:application/octet-stream;base64,)" + base64(buf) + R"("}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                  {"buffer": 0, "byteOffset": 36, "byteLength": 36)" +
                           (normalStride ? ", \"byteStride\": " + std::to_string(normalStride) : "") + R"(}],
  "accessors": [
    {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
    {"bufferView": 1, "componentType": 5126, "count": )" + std::to_string(normals) + R"(, "type": "VEC3"},
    {"bufferView": 1, "componentType": 5126, "count": )" + std::to_string(colors) + R"(, "type": "VEC3"}]})";
  const std::string path = dir + "/" + name + ".gltf";
  writeText(path, json);
  return path;
}

TEST_CASE("glTF loader: every vertex attribute has POSITION's count, and strides fit", "[mesh]") {
  const std::string dir = test::tempDir("mesh-attr");
  CHECK(loadMesh(attributeMismatchGltf(dir, "good", 3, 3, 0)).vertexCount() == 3);
  struct Case {
    const char* name;
    int normals, colors, stride;
    const char* what;
  };
  for (const Case& c : {Case{"short_normals", 2, 3, 0, "NORMAL: accessor 1 has 2 elements, but the primitive has 3 vertices"},
                        Case{"short_colors", 3, 1, 0, "COLOR_0: accessor 2 has 1 elements, but the primitive has 3 vertices"},
                        Case{"long_normals", 4, 3, 0, "NORMAL: accessor 1 has 4 elements, but the primitive has 3 vertices"},
                        Case{"small_stride", 3, 3, 4, "has byte stride 4"},
                        Case{"long_stride", 3, 3, 252, "NORMAL: accessor 1 runs past the end of its buffer"}}) {
    const std::string path = attributeMismatchGltf(dir, c.name, c.normals, c.colors, c.stride);
    INFO(c.name);
    try {
      loadMesh(path);
      FAIL("no error");
    } catch (const InputError& e) {
      INFO(e.what());
      CHECK(e.subject() == path);
      CHECK(std::string(e.what()).find(c.what) != std::string::npos);
    }
  }
}

static void expectInputError(const std::string& path, const std::string& what, MeshAlbedo albedo) {
  try {
    loadMesh(path, albedo);
    FAIL("no error for " << path);
  } catch (const InputError& e) {
    INFO(e.what());
    CHECK(e.subject() == path);
    CHECK(std::string(e.what()).find(what) != std::string::npos);
  }
}

TEST_CASE("Mesh loaders reject bad input with the file name", "[mesh]") {
  const std::string dir = test::tempDir("mesh-bad");
  expectInputError(dir + "/missing.glb", "");
  writeText(dir + "/empty.obj", "# nothing\nv 0 0 0\n");
  expectInputError(dir + "/empty.obj", "no triangles");
  writeText(dir + "/empty.gltf", R"({"asset": {"version": "2.0"}, "scenes": [{"nodes": []}]})");
  expectInputError(dir + "/empty.gltf", "no triangles");
  writeText(dir + "/nan.obj", "v 0 0 0\nv 1e999 0 0\nv 0 1 0\nf 1 2 3\n");
  expectInputError(dir + "/nan.obj", "non-finite");
  writeText(dir + "/garbage.glb", std::string("glTF\x02\0\0\0\x40\0\0\0", 12) + "garbage");
  expectInputError(dir + "/garbage.glb", "");
  writeText(dir + "/x.ply", "ply\n");
  expectInputError(dir + "/x.ply", "unknown mesh format");
}

// A glTF (text, or GLB when `glb`) whose one triangle's positions come from an external
// buffer (36 bytes) named by `uri`, or an image named by it when `image`.
static std::string externalGltf(const std::string& dir, const std::string& name, const std::string& uri, bool glb,
                                bool image = false) {
  const std::string buffer = image ? R"("buffers": [{"uri": "tri.bin", "byteLength": 36}], "images": [{"uri": ")" + uri + R"("}],)"
                                   : R"("buffers": [{"uri": ")" + uri + R"(", "byteLength": 36}],)";
  std::string json = R"({"asset": {"version": "2.0"}, )" + buffer + R"(
    "bufferViews": [{"buffer": 0, "byteLength": 36}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}], "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}]})";
  const std::string path = dir + "/" + name + (glb ? ".glb" : ".gltf");
  if (glb) {
    while (json.size() % 4) json += ' ';
    auto le32 = [](uint32_t v) { return std::string{char(v), char(v >> 8), char(v >> 16), char(v >> 24)}; };
    writeText(path, "glTF" + le32(2) + le32(uint32_t(20 + json.size())) + le32(uint32_t(json.size())) + "JSON" + json);
  } else {
    writeText(path, json);
  }
  return path;
}

// tinygltf reads a directory named by a URI as a file of size 2^63 (std::bad_alloc), so the
// loader refuses one first, in a GLB too, and decodes the URI as tinygltf does ('+' a space,
// %XX): a check on the URI as written missed "a%20dir" and "a+dir" (seen: bad_alloc).
TEST_CASE("glTF loader: an external file that is not a regular file is refused, however its URI is written", "[mesh]") {
  const std::string dir = test::tempDir("mesh-uri");
  for (const char* d : {"/plain", "/a dir"}) fs::create_directories(dir + d);
  const float tri[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  writeText(dir + "/x y.bin", std::string(reinterpret_cast<const char*>(tri), sizeof tri));
  writeText(dir + "/tri.bin", std::string(reinterpret_cast<const char*>(tri), sizeof tri));
  for (bool glb : {false, true}) {
    INFO((glb ? "GLB" : "glTF"));
    // The decoding is tinygltf's: these load the file "x y.bin".
    int good = 0;
    for (const char* uri : {"x%20y.bin", "x+y.bin", "x%20y%2ebin"})
      CHECK(loadMesh(externalGltf(dir, "good" + std::to_string(++good), uri, glb)).vertexCount() == 3);
    expectInputError(externalGltf(dir, "plain", "plain", glb), "buffers uri 'plain' is not a regular file");
    expectInputError(externalGltf(dir, "percent", "a%20dir", glb), "buffers uri 'a dir' is not a regular file");
    expectInputError(externalGltf(dir, "plus", "a+dir", glb), "buffers uri 'a dir' is not a regular file");
    expectInputError(externalGltf(dir, "image", "plain", glb, true), "images uri 'plain' is not a regular file");
  }
  // The files read are recorded decoded (their hashes go into sidecars and manifests).
  const Mesh m = loadMesh(externalGltf(dir, "recorded", "x+y.bin", false));
  CHECK(m.inputFiles == std::vector<std::string>{dir + "/recorded.gltf", dir + "/x y.bin"});
  writeText(dir + "/uris.GLTF", R"({"buffers": [{"uri": "data:,x"}, {"uri": "%2e%2E/a+b%zz%4"}, {"uri": 3}],
                                    "images": [{"uri": "c.png"}]})");
  CHECK(gltfExternalUris(dir + "/uris.GLTF") == std::vector<std::string>{std::string("../a b\0%4", 9), "c.png"});
  writeText(dir + "/uris.obj", R"({"buffers": [{"uri": "b.bin"}]})");
  CHECK(gltfExternalUris(dir + "/uris.obj").empty());
  writeText(dir + "/bad.gltf", "not json");
  CHECK(gltfExternalUris(dir + "/bad.gltf").empty());
}

TEST_CASE("OBJ loader: the number check judges each token as strtod and strtoll read it", "[mesh]") {
  const std::string dir = test::tempDir("mesh-obj-numbers");
  // Each token placed in `before` + token + `after`: it loads when `ok`, else fails with `what`.
  auto judge = [&](const std::vector<std::pair<std::string, bool>>& tokens, const std::string& before,
                   const std::string& after, const std::string& what) {
    for (const auto& [token, ok] : tokens) {
      INFO(token);
      const std::string path = dir + "/t.obj";
      writeText(path, before + token + after);
      if (ok) {
        CHECK_NOTHROW(loadMesh(path));
      } else {
        expectInputError(path, what);
      }
    }
  };
  // Coordinates: finite ones (as doubles) load (plain decimals are judged from their digit
  // counts, the rest by strtod), non-finite ones are refused naming the line. In a texture
  // coordinate: read, but unused, so a float overflow there is harmless.
  const std::string digits200(200, '9');
  judge({{"1e99", true}, {"-1.5E+38", true}, {"+.5", true}, {"7.", true}, {"1e-999", true}, {"1e999", false},
         {"-1e309", false}, {"0x1p99999", false}, {"inf", false}, {"-NaN", false}, {"Infinity", false},
         {digits200 + "e99", true}, {digits200 + "9e99", true}, {"1" + digits200 + "e200", false}},
        "v 0 0 0\nv 1 0 0\nv\t0 1 0\r\nvt 0 ", "\r\nf 1/1 2/1 3/1\n", "line 4: non-finite coordinate");
  // Face indices: out of the int range is refused; in range (through any v/vt/vn form) is not.
  judge({{"3", true}, {"3/1/1", true}, {"-1", true}, {"000000003", true}, {"0000000000003", true},
         {"2147483648", false}, {"3//99999999999", false}, {"-2147483648", false}},
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1 ", "\n", "line 6: face index out of range");
}

TEST_CASE("Mesh loaders reject the external bad meshes with the file name", "[mesh][data]") {
  const std::string inf = test::dataFile("meshes/gltf/BoxWithInfinites.glb");
  const std::string box = test::dataFile("meshes/gltf/Box.glb");
  PRTBAKE_SKIP_IF_NO_DATA(inf);
  PRTBAKE_SKIP_IF_NO_DATA(box);
  expectInputError(inf, "non-finite position");
  // A truncated copy of Box.glb: its accessors run past the end of the BIN chunk.
  const std::string dir = test::tempDir("mesh-bad-data");
  std::string bytes = readFile(box);
  writeText(dir + "/truncated.glb", bytes.substr(0, bytes.size() - 200));
  expectInputError(dir + "/truncated.glb", "");
}
