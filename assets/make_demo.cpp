// Makes the demo inputs in assets/: a procedural HDR sky with a sun (OpenEXR
// lat-long, float32) and a small glTF scene with occlusion (a ground plane, a
// box, a sphere and an arch, with coloured materials). Run by scripts/demo.sh
// when the files are missing; the committed copies were made by this program.
//
//   prtbake_make_demo OUTDIR
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "prtbake/exr.h"

namespace {

const double kPi = 3.14159265358979323846;

// Sky radiance (linear, arbitrary units ~ W/(m² sr)): a blue gradient, a
// brighter band near the horizon, a warm sun of 0.27° radius at 35° elevation,
// soft cloud streaks, and a dark brownish ground below the horizon.
void skyRadiance(double x, double y, double z, double rgb[3]) {
  const double sunEl = 35 * kPi / 180, sunAz = 40 * kPi / 180;
  const double sx = std::sin(sunAz) * std::cos(sunEl), sy = std::sin(sunEl), sz = std::cos(sunAz) * std::cos(sunEl);
  const double cosSun = x * sx + y * sy + z * sz;
  if (y < 0) {
    const double g = 0.25 + 0.05 * std::exp(5 * y);
    rgb[0] = 0.30 * g, rgb[1] = 0.24 * g, rgb[2] = 0.18 * g;
    return;
  }
  const double t = std::pow(1 - y, 4);
  double r = 0.15 + 0.55 * t, g = 0.30 + 0.50 * t, b = 0.75 + 0.25 * t;
  const double glow = std::exp(40 * (cosSun - 1)) * 4.0;  // aureole
  const double cloud = 0.35 * std::pow(std::max(0.0, std::sin(9 * x + 3 * std::sin(5 * z)) * std::sin(7 * z)), 3) * y;
  r += glow * 1.0 + cloud, g += glow * 0.8 + cloud, b += glow * 0.6 + cloud;
  if (cosSun > std::cos(0.27 * kPi / 180 * 8)) {  // sun disc (widened ×8 so it covers a few texels)
    r += 2.0e4, g += 1.8e4, b += 1.5e4;
  }
  rgb[0] = r, rgb[1] = g, rgb[2] = b;
}

void writeSky(const std::string& path) {
  const int w = 512, h = 256;
  std::vector<float> r(size_t(w) * h), g(r.size()), b(r.size());
  for (int row = 0; row < h; ++row)
    for (int col = 0; col < w; ++col) {
      // 4×4 supersampling per texel on OpenEXR's LatLongMap axes.
      double acc[3] = {0, 0, 0};
      for (int sy = 0; sy < 4; ++sy)
        for (int sx = 0; sx < 4; ++sx) {
          const double lam = -2 * kPi * ((col + (sx + 0.5) / 4) / w - 0.5);
          const double phi = kPi * (0.5 - (row + (sy + 0.5) / 4) / h);
          double c[3];
          skyRadiance(std::sin(lam) * std::cos(phi), std::sin(phi), std::cos(lam) * std::cos(phi), c);
          for (int k = 0; k < 3; ++k) acc[k] += c[k] / 16;
        }
      const size_t i = size_t(row) * w + col;
      r[i] = float(acc[0]), g[i] = float(acc[1]), b[i] = float(acc[2]);
    }
  prtbake::ExrWriteOptions o;
  o.envmap = 0;
  o.attributes = {{"comments", "prtbake demo sky: procedural, linear radiance, sun at 35 deg elevation"}};
  prtbake::writeExr(path, w, h, {{"R", r.data()}, {"G", g.data()}, {"B", b.data()}}, o);
}

struct MeshPart {
  std::vector<float> pos, nrm;
  std::vector<uint32_t> idx;
  void vertex(double x, double y, double z, double nx, double ny, double nz) {
    pos.insert(pos.end(), {float(x), float(y), float(z)});
    nrm.insert(nrm.end(), {float(nx), float(ny), float(nz)});
  }
  uint32_t count() const { return uint32_t(pos.size() / 3); }
};

// A grid on the plane y = 0, [-s, s]², facing +Y.
MeshPart ground(double s, int n) {
  MeshPart m;
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j) m.vertex(-s + 2 * s * j / n, 0, -s + 2 * s * i / n, 0, 1, 0);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const uint32_t a = uint32_t(i * (n + 1) + j), b = a + 1, c = a + uint32_t(n + 1), d = c + 1;
      m.idx.insert(m.idx.end(), {a, c, b, b, c, d});
    }
  return m;
}

// An axis-aligned box with split normals, each face subdivided n×n.
MeshPart box(double cx, double cy, double cz, double hx, double hy, double hz, int n) {
  MeshPart m;
  const double axes[6][9] = {{1, 0, 0, 0, 0, -1, 0, 1, 0}, {-1, 0, 0, 0, 0, 1, 0, 1, 0}, {0, 1, 0, 1, 0, 0, 0, 0, -1},
                             {0, -1, 0, 1, 0, 0, 0, 0, 1}, {0, 0, 1, 1, 0, 0, 0, 1, 0},  {0, 0, -1, -1, 0, 0, 0, 1, 0}};
  for (const auto& a : axes) {
    const uint32_t base = m.count();
    for (int i = 0; i <= n; ++i)
      for (int j = 0; j <= n; ++j) {
        const double u = 2.0 * j / n - 1, v = 2.0 * i / n - 1;
        const double p[3] = {a[0] + u * a[3] + v * a[6], a[1] + u * a[4] + v * a[7], a[2] + u * a[5] + v * a[8]};
        m.vertex(cx + hx * p[0], cy + hy * p[1], cz + hz * p[2], a[0], a[1], a[2]);
      }
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        const uint32_t q = base + uint32_t(i * (n + 1) + j), r = q + 1, s = q + uint32_t(n + 1), t = s + 1;
        m.idx.insert(m.idx.end(), {q, r, s, r, t, s});
      }
  }
  return m;
}

MeshPart sphere(double cx, double cy, double cz, double radius, int rings, int segs) {
  MeshPart m;
  for (int i = 0; i <= rings; ++i)
    for (int j = 0; j <= segs; ++j) {
      const double th = kPi * i / rings, ph = 2 * kPi * j / segs;
      const double nx = std::sin(th) * std::cos(ph), ny = std::cos(th), nz = std::sin(th) * std::sin(ph);
      m.vertex(cx + radius * nx, cy + radius * ny, cz + radius * nz, nx, ny, nz);
    }
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segs; ++j) {
      const uint32_t a = uint32_t(i * (segs + 1) + j), b = a + 1, c = a + uint32_t(segs + 1), d = c + 1;
      if (i != 0) m.idx.insert(m.idx.end(), {a, b, c});
      if (i != rings - 1) m.idx.insert(m.idx.end(), {b, d, c});
    }
  return m;
}

void writeScene(const std::string& dir) {
  struct Item {
    MeshPart mesh;
    const char* name;
    std::array<double, 4> color;
  };
  std::vector<Item> items = {
      {ground(3, 40), "ground", {0.6, 0.6, 0.6, 1}},
      {box(-0.8, 0.5, -0.3, 0.5, 0.5, 0.5, 8), "box", {0.8, 0.25, 0.2, 1}},
      {sphere(0.7, 0.6, 0.4, 0.6, 32, 64), "sphere", {0.7, 0.7, 0.7, 1}},
      {box(0.1, 1.3, -1.2, 1.2, 0.08, 0.35, 6), "lintel", {0.2, 0.4, 0.8, 1}},
      {box(-0.95, 0.6, -1.2, 0.1, 0.6, 0.3, 4), "pillar_left", {0.2, 0.4, 0.8, 1}},
      {box(1.15, 0.6, -1.2, 0.1, 0.6, 0.3, 4), "pillar_right", {0.2, 0.4, 0.8, 1}},
  };
  std::string bin;
  nlohmann::json gltf;
  gltf["asset"] = {{"version", "2.0"}, {"generator", "prtbake make_demo"}};
  gltf["scene"] = 0;
  gltf["scenes"] = {{{"nodes", nlohmann::json::array()}}};
  auto addView = [&](const void* data, size_t bytes, int target) {
    while (bin.size() % 4) bin.push_back('\0');
    gltf["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", bytes}, {"target", target}});
    bin.append(static_cast<const char*>(data), bytes);
    return int(gltf["bufferViews"].size()) - 1;
  };
  for (size_t k = 0; k < items.size(); ++k) {
    const MeshPart& m = items[k].mesh;
    float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
    for (size_t i = 0; i < m.pos.size(); ++i) lo[i % 3] = std::min(lo[i % 3], m.pos[i]), hi[i % 3] = std::max(hi[i % 3], m.pos[i]);
    const int vp = addView(m.pos.data(), m.pos.size() * 4, 34962);
    const int vn = addView(m.nrm.data(), m.nrm.size() * 4, 34962);
    const int vi = addView(m.idx.data(), m.idx.size() * 4, 34963);
    const int a0 = int(gltf["accessors"].size());
    gltf["accessors"].push_back({{"bufferView", vp}, {"componentType", 5126}, {"count", m.count()}, {"type", "VEC3"},
                                 {"min", {lo[0], lo[1], lo[2]}}, {"max", {hi[0], hi[1], hi[2]}}});
    gltf["accessors"].push_back({{"bufferView", vn}, {"componentType", 5126}, {"count", m.count()}, {"type", "VEC3"}});
    gltf["accessors"].push_back({{"bufferView", vi}, {"componentType", 5125}, {"count", m.idx.size()}, {"type", "SCALAR"}});
    gltf["materials"].push_back({{"name", items[k].name}, {"pbrMetallicRoughness", {{"baseColorFactor", items[k].color}, {"metallicFactor", 0.0}}}});
    gltf["meshes"].push_back({{"name", items[k].name},
                              {"primitives", {{{"attributes", {{"POSITION", a0}, {"NORMAL", a0 + 1}}}, {"indices", a0 + 2},
                                               {"material", int(k)}, {"mode", 4}}}}});
    gltf["nodes"].push_back({{"name", items[k].name}, {"mesh", int(k)}});
    gltf["scenes"][0]["nodes"].push_back(int(k));
  }
  gltf["buffers"] = {{{"uri", "scene.bin"}, {"byteLength", bin.size()}}};
  std::ofstream(dir + "/scene.bin", std::ios::binary) << bin;
  std::ofstream(dir + "/scene.gltf") << gltf.dump(1) << "\n";
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: prtbake_make_demo OUTDIR\n");
    return 2;
  }
  const std::string dir = argv[1];
  writeSky(dir + "/sky.exr");
  writeScene(dir);
  std::printf("wrote %s/sky.exr, %s/scene.gltf, %s/scene.bin\n", dir.c_str(), dir.c_str(), dir.c_str());
  return 0;
}
