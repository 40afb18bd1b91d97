// Writes the bad-input corpus (tests/corpus/) that tests/test_corpus.cpp feeds to
// the CLI: empty, truncated, garbage and lying files of every supported format.
// Build and run (the output is committed; rerun only to change the corpus):
//   cmake --build build --target prtbake_make_corpus && build/tests/prtbake_make_corpus tests/corpus
// Every file is small; the "huge" cases only claim huge sizes in their headers.
#include <stb/stb_image_write.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <limits>
#include <string>
#include <vector>

#include "prtbake/exr.h"

namespace {

using Bytes = std::string;
std::string gDir;

void put(const std::string& name, const Bytes& bytes) {
  std::ofstream out(gDir + "/" + name, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), std::streamsize(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + name);
}

Bytes get(const std::string& name) {
  std::ifstream in(gDir + "/" + name, std::ios::binary);
  return Bytes(std::istreambuf_iterator<char>(in), {});
}

// Deterministic noise (xorshift), so the corpus is reproducible.
Bytes noise(size_t n, uint32_t seed) {
  Bytes b(n, '\0');
  uint32_t s = seed;
  for (auto& c : b) {
    s ^= s << 13, s ^= s >> 17, s ^= s << 5;
    c = char(s & 0xff);
  }
  return b;
}

Bytes cut(const Bytes& b, double fraction) { return b.substr(0, size_t(double(b.size()) * fraction)); }

void be32(Bytes& b, size_t at, uint32_t v) {
  for (int i = 0; i < 4; ++i) b[at + i] = char((v >> (24 - 8 * i)) & 0xff);
}
void le32(Bytes& b, size_t at, uint32_t v) {
  for (int i = 0; i < 4; ++i) b[at + i] = char((v >> (8 * i)) & 0xff);
}

uint32_t crc32(const Bytes& b, size_t from, size_t n) {
  uint32_t c = 0xffffffffu;
  for (size_t i = from; i < from + n; ++i) {
    c ^= uint8_t(b[i]);
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
  }
  return ~c;
}

// A small smooth RGB gradient, w×h.
std::vector<float> gradient(int w, int h) {
  std::vector<float> px(size_t(w) * h * 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) px[(size_t(y) * w + x) * 3 + c] = 0.2f + 0.6f * float(x + y + c) / float(w + h);
  return px;
}

void writeExrLatLong(const std::string& name, int w, int h, float value = -1.0f) {
  std::vector<float> r(size_t(w) * h), g(r.size()), b(r.size());
  const auto px = gradient(w, h);
  for (size_t i = 0; i < r.size(); ++i) {
    r[i] = value >= 0 ? value : px[3 * i];
    g[i] = value >= 0 ? value : px[3 * i + 1];
    b[i] = value >= 0 ? value : px[3 * i + 2];
  }
  if (std::isnan(value)) r[r.size() / 2] = std::numeric_limits<float>::quiet_NaN();
  prtbake::ExrWriteOptions o;
  o.envmap = 0;
  prtbake::writeExr(gDir + "/" + name, w, h, {{"R", r.data()}, {"G", g.data()}, {"B", b.data()}}, o);
}

std::vector<unsigned char> ldr(int w, int h) {
  const auto px = gradient(w, h);
  std::vector<unsigned char> out(px.size());
  for (size_t i = 0; i < px.size(); ++i) out[i] = (unsigned char)(px[i] * 255.0f);
  return out;
}

// The offset of the 16-byte box2i value of an EXR header attribute.
size_t exrBox(const Bytes& exr, const std::string& attr) {
  const std::string key = attr + std::string(1, '\0') + "box2i" + std::string(1, '\0');
  const size_t at = exr.find(key);
  if (at == Bytes::npos) throw std::runtime_error("no " + attr + " in the EXR header");
  return at + key.size() + 4;  // skip the attribute's size field
}

void images() {
  for (const char* ext : {"exr", "hdr", "png", "jpg"}) put(std::string("empty.") + ext, "");

  // OpenEXR: a valid 64×32 lat-long, cut, and with lying or broken headers.
  writeExrLatLong("valid_latlong.exr", 64, 32);
  const Bytes exr = get("valid_latlong.exr");
  std::remove((gDir + "/valid_latlong.exr").c_str());
  put("truncated_header.exr", cut(exr, 0.05));
  put("truncated_pixels.exr", cut(exr, 0.6));
  put("garbage.exr", exr.substr(0, 4) + noise(2048, 1));  // the magic number, then noise
  put("not_exr.exr", "This is a text file with an .exr extension.\n");
  Bytes hugeWindow = exr;  // data window 100000×50000 (a 2:1 lat-long) with 32 rows of data
  for (const char* attr : {"dataWindow", "displayWindow"}) {
    const size_t at = exrBox(hugeWindow, attr);
    le32(hugeWindow, at + 8, 99999);
    le32(hugeWindow, at + 12, 49999);
  }
  put("huge_window.exr", hugeWindow);
  Bytes extremeWindow = exr;  // x from −2^31 to 2^31−1: width overflows 32 bits
  {
    const size_t at = exrBox(extremeWindow, "dataWindow");
    le32(extremeWindow, at, 0x80000000u);
    le32(extremeWindow, at + 8, 0x7fffffffu);
  }
  put("extreme_window.exr", extremeWindow);
  Bytes inverted = exr;  // xMax < xMin
  le32(inverted, exrBox(inverted, "dataWindow") + 8, uint32_t(-5));
  put("inverted_window.exr", inverted);
  writeExrLatLong("latlong_1x1.exr", 1, 1, 1.0f);
  writeExrLatLong("nan_texel.exr", 16, 8, std::numeric_limits<float>::quiet_NaN());
  {
    std::vector<float> v(16 * 8, -1.0f);  // negative radiance
    prtbake::ExrWriteOptions o;
    o.envmap = 0;
    prtbake::writeExr(gDir + "/negative.exr", 16, 8, {{"R", v.data()}, {"G", v.data()}, {"B", v.data()}}, o);
  }
  {
    std::vector<float> v(16 * 8, 1.0f);  // a lat-long with only an alpha channel
    prtbake::ExrWriteOptions o;
    o.envmap = 0;
    prtbake::writeExr(gDir + "/alpha_only.exr", 16, 8, {{"A", v.data()}}, o);
  }

  // Radiance HDR.
  const auto hdrPx = gradient(64, 32);
  stbi_write_hdr((gDir + "/valid.hdr").c_str(), 64, 32, 3, hdrPx.data());
  const Bytes hdr = get("valid.hdr");
  std::remove((gDir + "/valid.hdr").c_str());
  put("truncated.hdr", cut(hdr, 0.5));
  Bytes zeroRun = hdr;  // the first RLE count of the first scanline set to 0
  const size_t scan = zeroRun.find("+X 64\n");
  if (scan == Bytes::npos) throw std::runtime_error("no resolution line in the HDR");
  zeroRun[scan + 6 + 4] = '\0';
  put("zero_run.hdr", zeroRun);
  put("garbage.hdr", "#?RADIANCE\n" + noise(2048, 2));
  put("huge_header.hdr", "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 200000\n" + noise(512, 3));
  put("bad_resolution.hdr", "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y -4 +X abc\n" + noise(64, 4));

  // PNG: truncated, garbage, and an IHDR that claims 100000×100000 (with a valid CRC).
  const auto png8 = ldr(64, 32);
  stbi_write_png((gDir + "/valid.png").c_str(), 64, 32, 3, png8.data(), 64 * 3);
  const Bytes png = get("valid.png");
  std::remove((gDir + "/valid.png").c_str());
  put("truncated.png", cut(png, 0.5));
  put("garbage.png", png.substr(0, 8) + noise(2048, 5));  // the signature, then noise
  Bytes hugePng = png;  // IHDR: length(4) "IHDR"(4) width(4) height(4) ... at offset 8
  be32(hugePng, 16, 100000);
  be32(hugePng, 20, 100000);
  be32(hugePng, 29, crc32(hugePng, 12, 17));
  put("huge_header.png", hugePng);
  const auto tiny = ldr(1, 1);
  stbi_write_png((gDir + "/latlong_1x1.png").c_str(), 1, 1, 3, tiny.data(), 3);

  // JPEG.
  stbi_write_jpg((gDir + "/valid.jpg").c_str(), 64, 32, 3, png8.data(), 90);
  const Bytes jpg = get("valid.jpg");
  std::remove((gDir + "/valid.jpg").c_str());
  put("truncated.jpg", cut(jpg, 0.5));
  put("garbage.jpg", jpg.substr(0, 4) + noise(2048, 6));
  Bytes hugeJpg = jpg;  // the SOF0 frame header: FF C0 len(2) precision(1) height(2) width(2)
  const size_t sof = hugeJpg.find("\xff\xc0");
  if (sof == Bytes::npos) throw std::runtime_error("no SOF0 in the JPEG");
  hugeJpg[sof + 5] = hugeJpg[sof + 6] = hugeJpg[sof + 7] = hugeJpg[sof + 8] = char(0xff);
  put("huge_header.jpg", hugeJpg);
  Bytes undefinedTable = jpg;  // the scan's first component names AC Huffman table 3, which no DHT defines
  const size_t sos = undefinedTable.find("\xff\xda");
  if (sos == Bytes::npos) throw std::runtime_error("no SOS in the JPEG");
  undefinedTable[sos + 6] = char(0x03);  // SOS: FF DA len(2) count(1), then component id(1), tables(1)
  put("undefined_table.jpg", undefinedTable);
}

// A one-triangle glTF: JSON + a 42-byte buffer (3 float3 positions + 3 uint16 indices).
Bytes triangleBin() {
  Bytes b;
  const float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const uint16_t idx[3] = {0, 1, 2};
  b.append(reinterpret_cast<const char*>(pos), sizeof pos);
  b.append(reinterpret_cast<const char*>(idx), sizeof idx);
  return b;
}

std::string triangleJson(const std::string& uri, int bufferBytes, int positionCount) {
  return R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
"meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
"buffers": [{)" + (uri.empty() ? std::string() : "\"uri\": \"" + uri + "\", ") +
         "\"byteLength\": " + std::to_string(bufferBytes) + R"(}],
"bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
"accessors": [{"bufferView": 0, "componentType": 5126, "count": )" +
         std::to_string(positionCount) + R"(, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
              {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}]})" "\n";
}

Bytes glb(const std::string& json, const Bytes& bin) {
  std::string j = json;
  while (j.size() % 4) j += ' ';
  Bytes b = bin;
  while (b.size() % 4) b += '\0';
  Bytes out(12, '\0');
  out.replace(0, 4, "glTF");
  le32(out, 4, 2);
  le32(out, 8, uint32_t(12 + 8 + j.size() + 8 + b.size()));
  Bytes chunk(8, '\0');
  le32(chunk, 0, uint32_t(j.size()));
  chunk.replace(4, 4, "JSON");
  out += chunk + j;
  le32(chunk, 0, uint32_t(b.size()));
  chunk.replace(4, 4, std::string("BIN\0", 4));
  out += chunk + b;
  return out;
}

void meshes() {
  for (const char* ext : {"glb", "gltf", "obj"}) put(std::string("empty.") + ext, "");
  const Bytes bin = triangleBin();

  // glTF with external buffers.
  put("gltf_syntax_error.gltf", triangleJson("triangle.bin", 42, 3).substr(0, 120));
  put("gltf_missing_bin.gltf", triangleJson("does_not_exist.bin", 42, 3));
  put("short.bin", bin.substr(0, 12));
  put("gltf_short_bin.gltf", triangleJson("short.bin", 42, 3));
  put("triangle.bin", bin);
  put("gltf_huge_count.gltf", triangleJson("triangle.bin", 42, 1000000000));
  put("gltf_empty_bin.gltf", triangleJson("empty.bin", 42, 3));
  put("empty.bin", "");
  put("gltf_not_gltf.gltf", R"({"jobs": [], "asset": 5})" "\n");
  put("gltf_wrong_types.gltf", R"({"asset": {"version": 2}, "meshes": "none", "accessors": {"count": -1}})" "\n");
  put("gltf_uri_is_dir.gltf", triangleJson(".", 42, 3));
  // Index 7 of a 3-vertex mesh: indices out of range.
  {
    Bytes badIdx = bin;
    const uint16_t seven = 7;
    badIdx.replace(40, 2, reinterpret_cast<const char*>(&seven), 2);
    put("bad_index.bin", badIdx);
    put("gltf_bad_index.gltf", triangleJson("bad_index.bin", 42, 3));
  }
  // A NORMAL accessor with fewer elements than POSITION (the loader once read past the
  // end of the normals for the third vertex): the positions' view read as normals.
  {
    std::string j = triangleJson("triangle.bin", 42, 3);
    const std::string attr = R"("attributes": {"POSITION": 0})";
    j.replace(j.find(attr), attr.size(), R"("attributes": {"POSITION": 0, "NORMAL": 2})");
    const std::string last = R"("type": "SCALAR"}]})";
    j.replace(j.find(last), last.size(),
              R"("type": "SCALAR"}, {"bufferView": 0, "componentType": 5126, "count": 2, "type": "VEC3"}]})");
    put("gltf_normal_count.gltf", j);
  }
  // NaN position.
  {
    Bytes nanBin = bin;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    nanBin.replace(4, 4, reinterpret_cast<const char*>(&nan), 4);
    put("nan_position.bin", nanBin);
    put("gltf_nan_position.gltf", triangleJson("nan_position.bin", 42, 3));
  }

  // GLB.
  const Bytes good = glb(triangleJson("", 42, 3), bin);
  put("glb_truncated.glb", cut(good, 0.7));
  put("glb_garbage.glb", good.substr(0, 4) + noise(1024, 7));
  Bytes hugeLen = good;
  le32(hugeLen, 8, 0xfffffff0u);  // total length far beyond the file
  put("glb_huge_length.glb", hugeLen);
  Bytes hugeChunk = good;
  le32(hugeChunk, 12, 0x7ffffff0u);  // JSON chunk length far beyond the file
  put("glb_huge_chunk.glb", hugeChunk);
  put("glb_huge_count.glb", glb(triangleJson("", 42, 1000000000), bin));
  put("glb_version1.glb", [&] { Bytes v = good; le32(v, 4, 1); return v; }());

  // OBJ.
  put("obj_garbage.obj", noise(2048, 8));
  put("obj_bad_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99\n");
  put("obj_nan.obj", "v nan nan nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  put("obj_inf.obj", "v 1e39 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  put("obj_truncated.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2");
  put("obj_no_faces.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
  put("obj_huge_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999\n");
}

// Job files: the test writes white.exr beside each one, so the listed problem is
// the only one (unless the file cannot be parsed at all).
void jobFiles() {
  const std::string env = R"({"id": "sky", "type": "env", "input": "white.exr", "outputs": {"json": "out/sky.json"})";
  put("job_empty.json", "");
  put("job_syntax_error.json", R"({"jobs": [{"id": "sky", "type": "env",)" "\n");
  put("job_trailing_comma.json", R"({"jobs": [{"id": "sky", "type": "env", "input": "white.exr", "outputs": {"json": "out/sky.json"},}]})" "\n");
  put("job_not_object.json", "[1, 2, 3]\n");
  put("job_jobs_not_array.json", R"({"jobs": {"id": "sky"}})" "\n");
  put("job_binary.json", noise(512, 9));
  put("job_wrong_types.json",
      R"({"jobs": [{"id": 5, "type": "env", "input": ["white.exr"], "outputs": {"json": 3}, "order": "three", "clamp_invalid": "yes"}]})" "\n");
  put("job_outputs_not_object.json",
      R"({"jobs": [{"id": "sky", "type": "env", "input": "white.exr", "outputs": ["out/sky.json"]}]})" "\n");
  put("job_order_negative.json", R"({"jobs": [)" + env + R"(, "order": -3}]})" "\n");
  put("job_order_fraction.json", R"({"jobs": [)" + env + R"(, "order": 2.5}]})" "\n");
  put("job_order_huge.json", R"({"jobs": [)" + env + R"(, "order": 1e12}]})" "\n");
  put("job_order_overflow.json", R"({"jobs": [)" + env + R"(, "order": 1e400}]})" "\n");
  put("job_size_huge.json",
      R"({"jobs": [{"id": "lut", "type": "lut", "outputs": {"exr": "out/lut.exr"}, "size": 1e12, "samples": 1e30}]})" "\n");
  put("job_unknown_type.json", R"({"jobs": [{"id": "x", "type": "bake", "outputs": {"json": "out/x.json"}}]})" "\n");
  put("job_missing_input.json",
      R"({"jobs": [{"id": "sky", "type": "env", "input": "missing.exr", "outputs": {"json": "out/sky.json"}}]})" "\n");
  put("job_bad_id.json",
      R"({"jobs": [{"id": "../../etc/passwd", "type": "env", "input": "white.exr", "outputs": {"json": "out/sky.json"}}]})" "\n");
  put("job_output_is_input.json",
      R"({"jobs": [{"id": "sky", "type": "env", "input": "white.exr", "outputs": {"json": "white.exr"}}]})" "\n");
  put("job_deep_nesting.json", std::string(20000, '[') + std::string(20000, ']') + "\n");
  put("job_nul_in_string.json",
      std::string(R"({"jobs": [{"id": "sk)") + std::string(1, '\0') +
          R"(y", "type": "env", "input": "white.exr", "outputs": {"json": "out/sky.json"}}]})" "\n");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: prtbake_make_corpus DIR\n";
    return 2;
  }
  gDir = argv[1];
  try {
    images();
    meshes();
    jobFiles();
  } catch (const std::exception& e) {
    std::cerr << "prtbake_make_corpus: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
