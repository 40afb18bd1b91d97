// Writes the fuzz targets' seed corpora (tests/fuzz/corpus/<target>/): small valid
// files of every format each target reads, made with prtbake's own writers and
// stb_image_write, plus the bad-input corpus of tests/corpus/ framed for each target.
// Build and run (the output is committed; rerun only to change the seeds):
//   cmake --build build --target prtbake_make_seeds && build/tests/prtbake_make_seeds tests
// Framing (fuzz_target.h): an options byte where the target takes one, and parts
// preceded by their 4-byte little-endian length, the last part unprefixed.
#include <stb/stb_image_write.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <tuple>

#include "jobs.h"
#include "manifest.h"
#include "prtbake/atomic_file.h"
#include "prtbake/env.h"
#include "prtbake/exr.h"
#include "prtbake/glossy.h"
#include "prtbake/transport.h"

namespace fs = std::filesystem;
using namespace prtbake;

namespace {

using Bytes = std::string;
std::string gTests;  // the tests/ directory

Bytes slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return Bytes(std::istreambuf_iterator<char>(in), {});
}

void put(const std::string& target, const std::string& name, const Bytes& bytes) {
  const fs::path dir = fs::path(gTests) / "fuzz" / "corpus" / target;
  fs::create_directories(dir);
  std::ofstream out(dir / name, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), std::streamsize(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + (dir / name).string());
}

Bytes lenPrefixed(const Bytes& b) {
  Bytes out(4, '\0');
  for (int i = 0; i < 4; ++i) out[size_t(i)] = char((b.size() >> (8 * i)) & 0xff);
  return out + b;
}

Bytes parts(const std::vector<Bytes>& p) {
  Bytes out;
  for (size_t i = 0; i + 1 < p.size(); ++i) out += lenPrefixed(p[i]);
  return out + p.back();
}

// Files written through a temp path by the library's writers, read back as bytes.
const std::string& tmp() {
  static const std::string d = [] {
    const std::string t = fs::temp_directory_path() / "prtbake-make-seeds";
    fs::remove_all(t);
    fs::create_directories(t);
    return t;
  }();
  return d;
}

std::vector<float> gradient(int w, int h, float scale) {
  std::vector<float> px(size_t(w) * size_t(h) * 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) px[(size_t(y) * size_t(w) + size_t(x)) * 3 + size_t(c)] = scale * float(1 + x + 2 * y + c);
  return px;
}

Bytes exr(int w, int h, int envmap, bool half) {
  const auto px = gradient(w, h, 0.1f);
  std::vector<float> r(size_t(w) * size_t(h)), g(r.size()), b(r.size());
  for (size_t i = 0; i < r.size(); ++i) r[i] = px[3 * i], g[i] = px[3 * i + 1], b[i] = px[3 * i + 2];
  ExrWriteOptions o;
  o.envmap = envmap;
  o.half = half;
  const std::string path = tmp() + "/x.exr";
  writeExr(path, w, h, {{"R", r.data()}, {"G", g.data()}, {"B", b.data()}}, o);
  return slurp(path);
}

void appendBytes(void* ctx, void* data, int size) { static_cast<Bytes*>(ctx)->append(static_cast<char*>(data), size_t(size)); }

Bytes png(int w, int h) {
  const auto px = gradient(w, h, 8.0f);
  std::vector<unsigned char> c(px.size());
  for (size_t i = 0; i < px.size(); ++i) c[i] = (unsigned char)std::min(255.0f, px[i]);
  Bytes out;
  stbi_write_png_to_func(appendBytes, &out, w, h, 3, c.data(), w * 3);
  return out;
}

Bytes jpg(int w, int h) {
  const auto px = gradient(w, h, 8.0f);
  std::vector<unsigned char> c(px.size());
  for (size_t i = 0; i < px.size(); ++i) c[i] = (unsigned char)std::min(255.0f, px[i]);
  Bytes out;
  stbi_write_jpg_to_func(appendBytes, &out, w, h, 3, c.data(), 90);
  return out;
}

Bytes hdr(int w, int h) {
  const auto px = gradient(w, h, 0.5f);
  Bytes out;
  stbi_write_hdr_to_func(appendBytes, &out, w, h, 3, px.data());
  return out;
}

void envImages() {
  put("env_image", "latlong.exr", "\x00" + exr(8, 4, 0, true));
  put("env_image", "latlong_float_clamp.exr", "\x04" + exr(8, 4, -1, false));
  put("env_image", "cube.exr", Bytes(1, '\0') + exr(4, 24, 1, true));
  put("env_image", "cross.png", "\x02" + png(16, 12));
  put("env_image", "vertical_cross.png", Bytes(1, '\0') + png(12, 16));
  put("env_image", "strip.jpg", Bytes(1, '\0') + jpg(24, 4));
  put("env_image", "progressive.jpg", Bytes(1, '\0') + slurp(gTests + "/images/progressive.jpg"));  // tests/images/README.md
  put("env_image", "latlong.hdr", "\x01" + hdr(16, 8));
  for (const auto& e : fs::directory_iterator(fs::path(gTests) / "corpus")) {
    const std::string ext = e.path().extension().string();
    if (ext == ".exr" || ext == ".hdr" || ext == ".png" || ext == ".jpg")
      put("env_image", "corpus_" + e.path().filename().string(), Bytes(1, '\0') + slurp(e.path().string()));
  }
  std::vector<Bytes> faces;
  for (int f = 0; f < 6; ++f) faces.push_back(png(4, 4));
  put("env_faces", "png_faces", "\x00" + parts(faces));
  put("env_faces", "png_faces_games202", "\x01" + parts(faces));
  for (auto& f : faces) f = exr(4, 4, -1, true);
  put("env_faces", "exr_faces", "\x0c" + parts(faces));
  for (auto& f : faces) f = hdr(4, 4);
  put("env_faces", "hdr_faces", "\x08" + parts(faces));
  faces[3] = hdr(8, 8);
  put("env_faces", "hdr_faces_mismatch", "\x08" + parts(faces));
}

// One triangle (3 positions, normals, colours, uint16 indices) in one buffer.
Bytes triangleBin() {
  const float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0}, nrm[9] = {0, 0, 1, 0, 0, 1, 0, 0, 1};
  const float col[9] = {1, 0.5f, 0.25f, 1, 0.5f, 0.25f, 1, 0.5f, 0.25f};
  const uint16_t idx[4] = {0, 1, 2, 0};
  Bytes b;
  b.append(reinterpret_cast<const char*>(pos), sizeof pos);
  b.append(reinterpret_cast<const char*>(nrm), sizeof nrm);
  b.append(reinterpret_cast<const char*>(col), sizeof col);
  b.append(reinterpret_cast<const char*>(idx), sizeof idx);
  return b;  // 116 bytes
}

std::string triangleGltf(const std::string& uri) {
  return R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
"nodes": [{"mesh": 0, "rotation": [0, 0.7071068, 0, 0.7071068], "translation": [1, 2, 3]}],
"materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1]}}],
"meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "COLOR_0": 2}, "indices": 3, "material": 0}]}],
"buffers": [{"uri": ")" + uri + R"(", "byteLength": 116}],
"bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 108, "byteStride": 12},
                {"buffer": 0, "byteOffset": 108, "byteLength": 8}],
"accessors": [{"bufferView": 0, "byteOffset": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
              {"bufferView": 0, "byteOffset": 36, "componentType": 5126, "count": 3, "type": "VEC3"},
              {"bufferView": 0, "byteOffset": 72, "componentType": 5126, "count": 3, "type": "VEC3"},
              {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}]})";
}

Bytes base64(const Bytes& in) {
  static const char* t = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  Bytes out;
  size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const unsigned v = unsigned(uint8_t(in[i])) << 16 | unsigned(uint8_t(in[i + 1])) << 8 | uint8_t(in[i + 2]);
    out += t[v >> 18], out += t[(v >> 12) & 63], out += t[(v >> 6) & 63], out += t[v & 63];
  }
  if (i + 1 == in.size()) {
    const unsigned v = unsigned(uint8_t(in[i])) << 16;
    out += t[v >> 18], out += t[(v >> 12) & 63], out += "==";
  } else if (i + 2 == in.size()) {
    const unsigned v = unsigned(uint8_t(in[i])) << 16 | unsigned(uint8_t(in[i + 1])) << 8;
    out += t[v >> 18], out += t[(v >> 12) & 63], out += t[(v >> 6) & 63], out += '=';
  }
  return out;
}

// The triangle with a base colour texture (a 4 x 4 PNG in a data URI, mirrored, moved by
// KHR_texture_transform) on TEXCOORD_0 (the positions' x, y), for the albedo's texture pass.
std::string texturedGltf(const std::string& uri) {
  std::vector<uint8_t> px(4 * 4 * 3);
  for (size_t i = 0; i < px.size(); ++i) px[i] = uint8_t(37 * i);
  Bytes png;
  stbi_write_png_to_func([](void* ctx, void* data, int n) { static_cast<Bytes*>(ctx)->append(static_cast<char*>(data), size_t(n)); },
                         &png, 4, 4, 3, px.data(), 12);
  std::string g = triangleGltf(uri);
  const auto at = [&](const std::string& from) { return g.find(from); };
  g.replace(at(R"("COLOR_0": 2})"), 13, R"("COLOR_0": 2, "TEXCOORD_0": 4})");
  g.replace(at(R"("baseColorFactor": [0.8, 0.8, 0.8, 1]})"), 38,
            R"("baseColorFactor": [0.8, 0.8, 0.8, 1], "baseColorTexture": {"index": 0, "extensions": )"
            R"({"KHR_texture_transform": {"offset": [0.5, 0], "rotation": 0.3, "scale": [2, 3]}}}})");
  g.replace(at(R"("type": "SCALAR"}])"), 18,
            R"("type": "SCALAR"}, {"bufferView": 0, "byteOffset": 0, "componentType": 5126, "count": 3, "type": "VEC2"}],
"textures": [{"source": 0, "sampler": 0}], "samplers": [{"wrapS": 33648, "wrapT": 33071}],
"images": [{"uri": "data:image/png;base64,)" + base64(png) + R"("}])");
  return g;
}

void meshes() {
  const Bytes bin = triangleBin();
  put("gltf", "external_buffer", Bytes(1, '\0') + parts({triangleGltf("b.bin"), bin}));
  put("gltf", "base_color_texture", Bytes(1, '\2') + parts({texturedGltf("b.bin"), bin}));
  put("gltf", "data_uri", Bytes(1, '\0') + parts({triangleGltf("data:application/octet-stream;base64," + base64(bin)), ""}));
  // A transport copy with _PRT_T* attributes, as `prtbake transport --gltf copy.glb` writes it.
  const std::string src = tmp() + "/tri.gltf";
  writeFileAtomic(tmp() + "/b.bin", bin);
  writeFileAtomic(src, triangleGltf("b.bin"));
  const Mesh mesh = loadMesh(src);
  TransportResult t;
  t.order = 3;
  t.channels = 1;
  t.vertexCount = mesh.vertexCount();
  t.coeffs.resize(mesh.vertexCount() * 9);
  for (size_t i = 0; i < t.coeffs.size(); ++i) t.coeffs[i] = 0.1f * float(i % 9);
  put("gltf", "prt_copy_glb", "\x01" + parts({transportGltfBytes(tmp() + "/copy.glb", mesh, t), ""}));
  put("gltf", "prt_copy_gltf", Bytes(1, '\0') + parts({transportGltfBytes(tmp() + "/copy.gltf", mesh, t), ""}));
  put("npy", "grey", "\x03" + transportNpyBytes(t));
  t.channels = 3;
  t.coeffs.resize(mesh.vertexCount() * 27, 0.5f);
  put("npy", "rgb", Bytes(1, '\0') + transportNpyBytes(t));
  put("npy", "rgb_wrong_count", "\x04" + transportNpyBytes(t));
  for (const auto& e : fs::directory_iterator(fs::path(gTests) / "corpus")) {
    const std::string name = e.path().filename().string(), ext = e.path().extension().string();
    if (ext == ".gltf" || ext == ".glb") {
      const Bytes external = name.find("bad_index") != std::string::npos ? slurp(gTests + "/corpus/bad_index.bin")
                             : name.find("nan_position") != std::string::npos ? slurp(gTests + "/corpus/nan_position.bin")
                                                                              : bin;
      put("gltf", "corpus_" + name, Bytes(1, ext == ".glb" ? '\1' : '\0') + parts({slurp(e.path().string()), external}));
    }
    if (ext == ".obj") put("obj", "corpus_" + name, slurp(e.path().string()));
  }
  put("obj", "quad", "# a quad and a triangle\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\n"
                     "f 1//1 2//1 3//1 4//1\nf 1/1 2/1 3/1\no second\ng group\nusemtl none\nf -1 -2 -3\n");
}

void shAndLut() {
  ShCoeffs c;
  c.order = 3;
  c.quantity = ShQuantity::Irradiance;
  for (int i = 0; i < 9; ++i) c.rgb.push_back({0.1 * i, -0.05 * i, 1.0 / (1 + i)});
  writeShJson(tmp() + "/sh.json", c, R"({"parameters": {"order": 3}})");
  put("sh_json", "order3", slurp(tmp() + "/sh.json"));
  c.order = 1;
  c.rgb.resize(1);
  c.quantity = ShQuantity::Radiance;
  writeShJson(tmp() + "/sh.json", c, "");
  put("sh_json", "order1", slurp(tmp() + "/sh.json"));
  put("sh_json", "minimal", R"({"order": 2, "quantity": "radiance", "coefficients": [[1,1,1],[0,0,0],[0,0,0],[0,0,0]]})");
  put("lut_exr", "lut_float", exr(8, 8, -1, false));
  put("lut_exr", "lut_half", exr(4, 4, -1, true));
  put("lut_exr", "not_square", exr(8, 4, 0, true));
  for (const auto& e : fs::directory_iterator(fs::path(gTests) / "corpus"))
    if (e.path().extension() == ".exr") put("lut_exr", "corpus_" + e.path().filename().string(), slurp(e.path().string()));
}

void jobFiles() {
  const std::string good = R"({"jobs": [
  {"id": "sky", "type": "env", "input": "in.exr", "outputs": {"json": "out.json", "games202": "light.txt"}, "order": 3},
  {"id": "mesh", "type": "transport", "input": "in.exr", "outputs": {"npy": "t.npy"}, "mode": "shadowed", "samples": 64, "split": true},
  {"id": "lut", "type": "lut", "outputs": {"exr": "lut.exr"}, "size": 32, "tolerance": 0.001},
  {"id": "gloss", "type": "glossy", "input": "in.obj", "outputs": {"npy": "m.npy", "cpca": "m.npz"}, "order": 3, "samples": 64, "cpca_clusters": 2, "cpca_vectors": 1, "split": true}]})";
  // The manifest a finished "sky" job leaves (paths as a run in the fuzz scratch directory would give).
  std::ofstream(tmp() + "/in.exr") << "x";
  writeFileAtomic(tmp() + "/job.json", good);
  const jobs::JobFile f = jobs::loadJobFile(tmp() + "/job.json");
  const std::string manifest = f.jobs.empty() || !f.jobs[0].valid()
                                   ? std::string("{}")
                                   : jobs::makeManifest(f.jobs[0], {{tmp() + "/in.exr", std::string(64, '0')}}, "cpu",
                                                        {{"total", 1.0}}, {{"samples", 0}}).dump(1);
  put("jobfile", "valid_with_manifest", parts({good, manifest}));
  put("jobfile", "valid_no_manifest", parts({good, ""}));
  put("jobfile", "manifest_wrong_types", parts({good, R"({"prtbake_manifest": 1, "version": 5, "parameters": [], "outputs": {"a": 1}, "inputs": 7})"}));
  for (const auto& e : fs::directory_iterator(fs::path(gTests) / "corpus")) {
    const std::string name = e.path().filename().string();
    if (name.rfind("job_", 0) == 0 && name.size() < 200) put("jobfile", "corpus_" + name, parts({slurp(e.path().string()), ""}));
  }
  put("jobfile", "demo", parts({slurp(gTests + "/../assets/demo.json"), ""}));
  put("jobfile", "prefilter", parts({R"({"jobs": [
  {"id": "spec", "type": "prefilter", "input": "in.exr", "outputs": {"ktx2": "s.ktx2", "exr": "s.exr", "json": "s.json"}, "schedule": "filament", "size": 64},
  {"id": "sheen", "type": "prefilter", "input": "in.exr", "outputs": {"ktx2": "c.ktx2"}, "lobe": "charlie", "roughness": [0.25, 1], "float32": true}]})",
                                     ""}));
}

// Glossy matrices as the bake writes them (float32 and float16, grey and RGB) and the CPCA
// .npz of a few of them.
void glossy() {
  const size_t vertices = 4;
  for (int ch : {1, 3})
    for (MatrixDtype dtype : {MatrixDtype::Float32, MatrixDtype::Float16}) {
      const std::vector<size_t> shape = glossyNpyShape(vertices, ch, 3, 2);
      Bytes bytes = glossyNpyHeader(shape, dtype);
      const size_t n = vertices * size_t(ch) * 9 * 4;
      for (size_t i = 0; i < n; ++i) {
        const float v = 0.01f * float(i % 17);
        if (dtype == MatrixDtype::Float32)
          bytes.append(reinterpret_cast<const char*>(&v), 4);
        else {
          const uint16_t h = floatToHalf(v);
          bytes.append(reinterpret_cast<const char*>(&h), 2);
        }
      }
      const std::string name = std::string(ch == 1 ? "grey" : "rgb") + (dtype == MatrixDtype::Float32 ? "_f32" : "_f16");
      put("glossy", name, Bytes(1, '\0') + bytes);
      if (dtype == MatrixDtype::Float32) put("glossy", name + "_mapped", Bytes(1, '\1') + bytes);
    }
  const size_t dim = 9 * 4;
  std::vector<float> data(8 * dim);
  for (size_t i = 0; i < data.size(); ++i) data[i] = std::sin(0.37f * float(i)) + float(i / dim % 2);
  CpcaOptions o;
  o.clusters = 2, o.vectors = 1, o.threads = 1;
  const CpcaResult c = cpcaCompress(data.data(), 8, dim, o);
  put("glossy", "cpca", Bytes(1, '\2') + cpcaNpzBytes(c, 3, 2, 1));
  o.weightBits = 8;
  put("glossy", "cpca_int8", Bytes(1, '\2') + cpcaNpzBytes(cpcaCompress(data.data(), 8, dim, o), 3, 2, 1));
}

// The lightmap target (fuzz_lightmap.cpp): OBJ vt and glTF TEXCOORD_0/1 and TANGENT.
void lightmaps() {
  const Bytes floor = "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nv -0.5 1 -0.5\nv 0.5 1 -0.5\nv 0.5 1 0.5\n"
                      "vt 0 0\nvt 0.45 0\nvt 0.45 0.45\nvt 0 0.45\nvt 0.55 0.55\nvt 1 0.55\nvt 1 1\nvn 0 1 0\nvn 0 -1 0\n"
                      "f 1/1/1 4/4/1 3/3/1\nf 1/1/1 3/3/1 2/2/1\nf 5/5/2 6/6/2 7/7/2\n";
  put("lightmap", "obj_two_charts", "\x05" + floor);
  put("lightmap", "obj_overlap", "\x01v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nvt 0 0\nvt 1 0\nvt 1 1\n"
                                 "f 1/1 2/2 3/3\nf 4/1 5/2 6/3\n");
  put("lightmap", "obj_nan_uv", "\x01v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt nan 0\nvt 1 1\nf 1/1 2/2 3/3\n");
  put("lightmap", "obj_no_uv", "\x01v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n");
  // One triangle: POSITION, TEXCOORD_0, TEXCOORD_1, TANGENT (w as given), one buffer.
  auto gltf = [](float w) {
    const float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0}, uv0[] = {0, 0, 1, 0, 0, 1}, uv1[] = {0.1f, 0.1f, 0.9f, 0.1f, 0.1f, 0.9f};
    const float tan[] = {1, 0, 0, w, 1, 0, 0, w, 1, 0, 0, w};
    Bytes bin;
    for (const auto& [p, n] : {std::pair{pos, sizeof pos}, {uv0, sizeof uv0}, {uv1, sizeof uv1}, {tan, sizeof tan}})
      bin.append(reinterpret_cast<const char*>(p), n);
    return R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1, "TEXCOORD_1": 2, "TANGENT": 3}}]}],
  "buffers": [{"uri": "b.bin", "byteLength": 132}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 24},
                  {"buffer": 0, "byteOffset": 60, "byteLength": 24}, {"buffer": 0, "byteOffset": 84, "byteLength": 48}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
                {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"},
                {"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC2"},
                {"bufferView": 3, "componentType": 5126, "count": 3, "type": "VEC4"}]})" + std::string() + "\n" + bin;
  };
  for (const auto& [name, w, flags] : {std::tuple{"gltf_uv1_tangent", 1.0f, '\x18'}, {"gltf_bad_tangent_w", 0.5f, '\x10'}}) {
    const Bytes both = gltf(w);
    const size_t split = both.find("\n");
    put("lightmap", name, Bytes(1, flags) + parts({both.substr(0, split), both.substr(split + 1)}));
  }
  for (const auto& e : fs::directory_iterator(fs::path(gTests) / "corpus")) {
    const std::string file = e.path().filename().string(), ext = e.path().extension().string();
    if (ext == ".obj") put("lightmap", "corpus_" + file, "\x01" + slurp(e.path().string()));
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: prtbake_make_seeds TESTS_DIR\n";
    return 2;
  }
  gTests = argv[1];
  try {
    envImages();
    meshes();
    shAndLut();
    jobFiles();
    glossy();
    lightmaps();
  } catch (const std::exception& e) {
    std::cerr << "prtbake_make_seeds: " << e.what() << "\n";
    return 1;
  }
  fs::remove_all(tmp());
  return 0;
}
