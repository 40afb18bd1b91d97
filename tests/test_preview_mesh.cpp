// Mesh preview: the furnace by image, orientation of the lighting and its rotation,
// the background, deterministic PNG bytes, the .npy reader and the CLI's errors.
// Every figure is read from the linear image, before tone mapping.
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>

#include "prtbake/env.h"
#include "prtbake/error.h"
#include "prtbake/preview.h"
#include "prtbake/transport.h"
#include "test_common.h"

using namespace prtbake;

namespace {
const double kPi = 3.14159265358979323846;

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

TransportCoeffs toCoeffs(const TransportResult& r) {
  TransportCoeffs t;
  t.order = r.order, t.channels = r.channels, t.vertexCount = r.vertexCount, t.coeffs = r.coeffs;
  return t;
}

ShCoeffs whiteEnvironment(int order) {
  ShCoeffs sh;
  sh.order = order;
  sh.rgb.assign(size_t(order) * order, Rgb{0, 0, 0});
  sh.rgb[0] = {std::sqrt(4 * kPi), std::sqrt(4 * kPi), std::sqrt(4 * kPi)};  // L = 1 everywhere
  return sh;
}

// A lat-long environment bright toward +Y only, L = exp(6 (y − 1)), as radiance SH.
ShCoeffs upLobe(int order) {
  EnvMap env;
  env.layout = EnvLayout::LatLong;
  env.width = 256, env.height = 128;
  env.rgb.resize(env.texelCount() * 3);
  for (size_t t = 0; t < env.texelCount(); ++t) {
    double d[3];
    texelDirection(env, t, d, nullptr);
    env.rgb[3 * t] = env.rgb[3 * t + 1] = env.rgb[3 * t + 2] = float(std::exp(6 * (d[1] - 1)));
  }
  return projectEnvironmentReference(env, order);
}

const Mesh& sphere() {
  static const Mesh m = makeUvSphere(1.0, 24, 48);
  return m;
}

// Transport of the UV sphere (1024 samples, shadowed; grey, so independent of the
// albedo), computed once.
const TransportResult& sphereTransport() {
  static const TransportResult r = [] {
    TransportOptions o;
    o.mode = TransportMode::Shadowed;
    o.order = 3;
    o.samples = 1024;
    return computeTransport(test::runtime(), sphere(), o);
  }();
  return r;
}

// Mean luminance of the mesh pixels above and below the image's middle row.
void halves(const MeshPreviewResult& r, double* top, double* bottom) {
  double s[2] = {0, 0};
  int n[2] = {0, 0};
  for (int y = 0; y < r.image.height; ++y)
    for (int x = 0; x < r.image.width; ++x) {
      if (r.hitTriangle[size_t(y) * r.image.width + x] < 0 || 2 * y + 1 == r.image.height) continue;
      const int h = 2 * y < r.image.height ? 0 : 1;
      s[h] += r.image.at(x, y)[1];
      ++n[h];
    }
  *top = s[0] / std::max(n[0], 1);
  *bottom = s[1] / std::max(n[1], 1);
}
}  // namespace

TEST_CASE("Mesh preview furnace: a convex mesh under a white environment shows its albedo", "[preview][mesh]") {
  // Under L = 1 every unoccluded vertex has Σ l_i T_i = √(4π) T_0 = 1. With cosine-
  // distributed samples Y_0 is constant, so T_0 of a fully visible vertex is exact up to
  // float summation (no self-shadowing on a convex mesh: its tangent planes bound it).
  // Interpolating equal values across a triangle is exact, so every mesh pixel is ρ up
  // to float rounding of the 1024-sample sum and the interpolation.
  const double kFurnaceTol = 1e-4;
  Mesh m = sphere();
  const std::array<float, 3> rho = {0.2f, 0.5f, 0.8f};
  for (size_t v = 0; v < m.vertexCount(); ++v)
    for (int c = 0; c < 3; ++c) m.albedo[3 * v + c] = rho[size_t(c)];
  const TransportResult tr = sphereTransport();
  REQUIRE(tr.channels == 1);
  MeshPreviewOptions o;
  o.width = 160, o.height = 120;
  o.yawDeg = 30, o.pitchDeg = 20;
  const MeshPreviewResult r = renderMeshPreview(test::runtime(), m, toCoeffs(tr), whiteEnvironment(3), o);
  double maxErr = 0;
  size_t hits = 0;
  for (int y = 0; y < o.height; ++y)
    for (int x = 0; x < o.width; ++x) {
      if (r.hitTriangle[size_t(y) * o.width + x] < 0) continue;
      ++hits;
      const auto p = r.image.at(x, y);
      for (int c = 0; c < 3; ++c) maxErr = std::max(maxErr, std::abs(double(p[size_t(c)]) - rho[size_t(c)]) / rho[size_t(c)]);
    }
  WARN("furnace: " << hits << " mesh pixels, max relative error " << maxErr);
  REQUIRE(hits > size_t(o.width * o.height / 10));
  REQUIRE(maxErr < kFurnaceTol);
}

TEST_CASE("Mesh preview orientation: light from +Y lights the top, 180 deg about X swaps", "[preview][mesh]") {
  // Front view: +Y is up on screen. The lobe exp(6(y−1)) at order 4 leaves the
  // downward-facing half with a small (ringing) remainder only.
  const double kContrast = 5.0;
  const TransportResult& tr = sphereTransport();
  const ShCoeffs light = upLobe(4);
  MeshPreviewOptions o;
  o.width = 120, o.height = 90;
  const MeshPreviewResult up = renderMeshPreview(test::runtime(), sphere(), toCoeffs(tr), light, o);
  double top, bottom;
  halves(up, &top, &bottom);
  WARN("light toward +Y: mesh mean top " << top << ", bottom " << bottom);
  REQUIRE(top > kContrast * std::max(bottom, 1e-6));
  o.lightAxis = {1, 0, 0};
  o.lightRotationDeg = 180;
  const MeshPreviewResult down = renderMeshPreview(test::runtime(), sphere(), toCoeffs(tr), light, o);
  double top2, bottom2;
  halves(down, &top2, &bottom2);
  WARN("rotated 180 deg about X: mesh mean top " << top2 << ", bottom " << bottom2);
  REQUIRE(bottom2 > kContrast * std::max(top2, 1e-6));
  // The rotation is exact: the halves swap (within the asymmetry of one pixel row).
  CHECK(top2 == Approx(bottom).margin(0.05 * top));
  CHECK(bottom2 == Approx(top).epsilon(0.05));
  // About +Y (the default axis) the +Y lobe is invariant: the image does not change.
  o.lightAxis = {0, 1, 0};
  o.lightRotationDeg = 73;
  const MeshPreviewResult turned = renderMeshPreview(test::runtime(), sphere(), toCoeffs(tr), light, o);
  double maxDiff = 0;
  for (size_t i = 0; i < up.image.rgb.size(); ++i)
    maxDiff = std::max(maxDiff, double(std::abs(up.image.rgb[i] - turned.image.rgb[i])));
  CHECK(maxDiff < 1e-3 * top);
}

TEST_CASE("Mesh preview background: missed pixels show the SH reconstruction", "[preview][mesh]") {
  // The camera model of preview.h: front view, vertical fov 35 deg, screen-right +X, up +Y.
  const double kBackgroundTol = 1e-4;  // float SH evaluation vs double
  const ShCoeffs light = upLobe(4);
  const TransportResult& tr = sphereTransport();
  MeshPreviewOptions o;
  o.width = 64, o.height = 48;
  const MeshPreviewResult r = renderMeshPreview(test::runtime(), sphere(), toCoeffs(tr), light, o);
  const double tanV = std::tan(0.5 * 35 * kPi / 180), tanH = tanV * 64 / 48;
  int checked = 0;
  for (int y = 0; y < o.height; ++y)
    for (int x = 0; x < o.width; ++x) {
      if (r.hitTriangle[size_t(y) * o.width + x] >= 0) continue;
      const double px = (2 * (x + 0.5) / o.width - 1) * tanH, py = (1 - 2 * (y + 0.5) / o.height) * tanV;
      const double n = std::sqrt(px * px + py * py + 1);
      const Rgb want = evalSh(light, px / n, py / n, -1 / n);
      REQUIRE(r.image.at(x, y)[0] == Approx(want[0]).margin(kBackgroundTol));
      ++checked;
    }
  REQUIRE(checked > 100);
}

TEST_CASE("Mesh preview PNG: identical bytes on rerun", "[preview][mesh]") {
  const std::string dir = test::tempDir("previewmesh");
  const TransportResult& tr = sphereTransport();
  MeshPreviewOptions o;
  o.width = 96, o.height = 72;
  o.lightRotationDeg = 40;
  for (const char* name : {"a.png", "b.png"}) {
    const MeshPreviewResult r = renderMeshPreview(test::runtime(), sphere(), toCoeffs(tr), upLobe(3), o);
    writePreviewPng(dir + "/" + name, r.image, ToneMap{1.0}, {{"Description", r.camera}});
  }
  REQUIRE(slurp(dir + "/a.png") == slurp(dir + "/b.png"));
}

TEST_CASE("Transport .npy reader: round trip and validation", "[preview][mesh]") {
  const std::string dir = test::tempDir("npyread");
  TransportResult r;
  r.order = 2, r.channels = 3, r.vertexCount = 5;
  for (int i = 0; i < 5 * 3 * 4; ++i) r.coeffs.push_back(float(i) * 0.25f);
  writeTransportNpy(dir + "/t.npy", r);
  const TransportCoeffs t = readTransportNpy(dir + "/t.npy", 5);
  REQUIRE((t.order == 2 && t.channels == 3 && t.vertexCount == 5));
  REQUIRE(t.coeffs == r.coeffs);
  REQUIRE_THROWS_AS(readTransportNpy(dir + "/t.npy", 6), InputError);
  REQUIRE_THROWS_AS(readTransportNpy(dir + "/missing.npy"), InputError);
  // float64 data: refused with the dtype named.
  std::string bad = slurp(dir + "/t.npy");
  bad.replace(bad.find("<f4"), 3, "<f8");
  std::ofstream(dir + "/f8.npy", std::ios::binary) << bad;
  try {
    readTransportNpy(dir + "/f8.npy");
    FAIL("no error");
  } catch (const InputError& e) {
    REQUIRE(std::string(e.what()).find("<f8") != std::string::npos);
  }
  // A truncated file.
  std::ofstream(dir + "/short.npy", std::ios::binary) << slurp(dir + "/t.npy").substr(0, 100);
  REQUIRE_THROWS_AS(readTransportNpy(dir + "/short.npy"), InputError);
  // Shapes a header can lie with: no vertices (the data is then empty), a sign that
  // strtoull would accept and wrap, an exponent, an empty dimension. Each is refused with
  // the shape quoted; the first was a fuzzing finding (a zero-length copy from null).
  for (const std::string shape : {"(0, 3, 4)", "(-0, 3, 4)", "(-5, 3, 4)", "(5e0, 3, 4)", "(5, , 3, 4)", "()"}) {
    std::string lie = slurp(dir + "/t.npy");
    const size_t at = lie.find("(5, 3, 4)");
    REQUIRE(at != std::string::npos);
    lie.replace(at, 9, shape);
    if (shape.rfind("(0", 0) == 0 || shape.rfind("(-0", 0) == 0) lie.resize(lie.find('\n') + 1);  // no data
    std::ofstream(dir + "/lie.npy", std::ios::binary | std::ios::trunc) << lie;
    try {
      readTransportNpy(dir + "/lie.npy");
      FAIL("no error for shape " << shape);
    } catch (const InputError& e) {
      INFO(shape << ": " << e.what());
      REQUIRE(std::string(e.what()).find("lie.npy") != std::string::npos);
    }
  }
}

TEST_CASE("CLI preview mesh: output and errors", "[preview][mesh][cli]") {
  const std::string dir = test::tempDir("previewmeshcli");
  // An octahedron as OBJ (6 vertices).
  std::ofstream(dir + "/octa.obj") << "v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n"
                                      "f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n";
  auto r = test::runCli("transport '" + dir + "/octa.obj' -o '" + dir + "/t.npy' --samples 64 --quiet");
  REQUIRE(r.exitCode == 0);
  writeShJson(dir + "/rad.json", whiteEnvironment(3), "{}");
  ShCoeffs irr = whiteEnvironment(3);
  irr.quantity = ShQuantity::Irradiance;
  writeShJson(dir + "/irr.json", irr, "{}");
  TransportResult wrong;
  wrong.order = 3, wrong.vertexCount = 7;
  wrong.coeffs.assign(7 * 9, 0.1f);
  writeTransportNpy(dir + "/wrong.npy", wrong);

  const std::string mesh = "'" + dir + "/octa.obj'";
  r = test::runCli("preview mesh " + mesh + " --transport '" + dir + "/t.npy' --env '" + dir +
                   "/rad.json' -o '" + dir + "/ok.png' --size 64x48 --view 30,20 --rotate-light 45 --quiet");
  INFO(r.output);
  REQUIRE(r.exitCode == 0);
  REQUIRE(test::fileExists(dir + "/ok.png"));
  REQUIRE(slurp(dir + "/ok.png").find("tEXtToneMap") != std::string::npos);

  struct Case {
    std::string args, names;
  } cases[] = {
      {mesh + " --transport '" + dir + "/wrong.npy' --env '" + dir + "/rad.json'", "wrong.npy"},
      {mesh + " --transport '" + dir + "/t.npy' --env '" + dir + "/irr.json'", "irr.json"},
      {mesh + " --transport '" + dir + "/nothere.npy' --env '" + dir + "/rad.json'", "nothere.npy"},
      {mesh + " --transport '" + dir + "/t.npy' --env '" + dir + "/nothere.json'", "nothere.json"},
      {"'" + dir + "/nothere.obj' --transport '" + dir + "/t.npy' --env '" + dir + "/rad.json'", "nothere.obj"},
  };
  for (const auto& c : cases) {
    r = test::runCli("preview mesh " + c.args + " -o '" + dir + "/bad.png'");
    INFO(c.args << "\n" << r.output);
    REQUIRE(r.exitCode == 1);
    REQUIRE(r.output.find(c.names) != std::string::npos);
    REQUIRE_FALSE(test::fileExists(dir + "/bad.png"));
  }
  r = test::runCli("preview mesh " + mesh + " --transport '" + dir + "/t.npy' --env '" + dir +
                   "/rad.json' -o '" + dir + "/bad.png' --view sideways");
  REQUIRE(r.exitCode == 2);
  REQUIRE_FALSE(test::fileExists(dir + "/bad.png"));
}

TEST_CASE("Mesh preview: camera rays do not slip between the triangles of a closed mesh", "[preview][mesh]") {
  // Every pixel of a closed convex mesh must see a front face; a ray through a shared
  // vertex that slipped through would see the inside of the far side (a back face).
  Mesh fine = makeUvSphere(1.0, 96, 192);
  TransportCoeffs t;
  t.order = 1, t.channels = 1, t.vertexCount = fine.vertexCount();
  t.coeffs.assign(t.vertexCount, 0.1f);
  for (double yaw : {0.0, 37.0, 90.0}) {
    for (double pitch : {0.0, 24.0}) {
      MeshPreviewOptions o;
      o.width = 320, o.height = 240;
      o.yawDeg = yaw, o.pitchDeg = pitch;
      const MeshPreviewResult r = renderMeshPreview(test::runtime(), fine, t, whiteEnvironment(1), o);
      const double cy = std::cos(yaw * kPi / 180), sy = std::sin(yaw * kPi / 180);
      const double cp = std::cos(pitch * kPi / 180), sp = std::sin(pitch * kPi / 180);
      const double f[3] = {-sy * cp, -sp, -cy * cp}, right[3] = {cy, 0, -sy};
      const double up[3] = {right[1] * f[2] - right[2] * f[1], right[2] * f[0] - right[0] * f[2],
                            right[0] * f[1] - right[1] * f[0]};
      const double tanV = std::tan(0.5 * 35 * kPi / 180), tanH = tanV * 4 / 3;
      int backFaces = 0, hits = 0;
      for (int y = 0; y < o.height; ++y)
        for (int x = 0; x < o.width; ++x) {
          const int tri = r.hitTriangle[size_t(y) * o.width + x];
          if (tri < 0) continue;
          ++hits;
          const double px = (2 * (x + 0.5) / o.width - 1) * tanH, py = (1 - 2 * (y + 0.5) / o.height) * tanV;
          double d[3], e1[3], e2[3];
          const float* p0 = &fine.positions[3 * size_t(fine.indices[3 * size_t(tri)])];
          const float* p1 = &fine.positions[3 * size_t(fine.indices[3 * size_t(tri) + 1])];
          const float* p2 = &fine.positions[3 * size_t(fine.indices[3 * size_t(tri) + 2])];
          for (int k = 0; k < 3; ++k) d[k] = f[k] + px * right[k] + py * up[k], e1[k] = p1[k] - p0[k], e2[k] = p2[k] - p0[k];
          const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
          if (n[0] * d[0] + n[1] * d[1] + n[2] * d[2] > 0) ++backFaces;
        }
      INFO("yaw " << yaw << " pitch " << pitch << ": " << hits << " mesh pixels");
      REQUIRE(hits > 1000);
      REQUIRE(backFaces == 0);
    }
  }
}

TEST_CASE("Job runner: png outputs of env, transport and lut jobs", "[preview][mesh][jobs]") {
  const std::string dir = test::tempDir("previewjobs");
  std::ofstream(dir + "/octa.obj") << "v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n"
                                      "f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n";
  writeShJson(dir + "/rad.json", upLobe(3), "{}");
  // A small lat-long environment map (a .hdr) for the env job and as a preview_env.
  {
    std::ofstream hdr(dir + "/sky.hdr", std::ios::binary);
    hdr << "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 16 +X 32\n";
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 32; ++x) hdr << char(y < 8 ? 200 : 60) << char(180) << char(160) << char(129);
  }
  std::ofstream(dir + "/jobs.json") << R"({"jobs": [
    {"id": "env", "type": "env", "input": "sky.hdr", "outputs": {"json": "out/env.json", "png": "out/env.png"}},
    {"id": "lut", "type": "lut", "outputs": {"exr": "out/lut.exr", "png": "out/lut.png"}, "size": 16, "samples": 64},
    {"id": "mesh", "type": "transport", "input": "octa.obj", "samples": 64, "preview_env": "rad.json",
     "outputs": {"npy": "out/t.npy", "png": "out/mesh.png"}},
    {"id": "mesh-map", "type": "transport", "input": "octa.obj", "samples": 64, "preview_env": "sky.hdr",
     "outputs": {"npy": "out/t2.npy", "png": "out/mesh2.png"}}
  ]})";
  auto r = test::runCli("run '" + dir + "/jobs.json' --quiet");
  INFO(r.output);
  REQUIRE(r.exitCode == 0);
  for (const char* f : {"env.png", "lut.png", "mesh.png", "mesh2.png"}) REQUIRE(test::fileExists(dir + "/out/" + f));
  // The preview environment is an input of the job (hashed in the manifest).
  REQUIRE(slurp(dir + "/out/t.npy.manifest.json").find("rad.json") != std::string::npos);

  // A png without preview_env, preview_env without png, a missing preview_env, irradiance SH.
  ShCoeffs irr = upLobe(3);
  irr.quantity = ShQuantity::Irradiance;
  writeShJson(dir + "/irr.json", irr, "{}");
  std::ofstream(dir + "/bad.json") << R"({"jobs": [
    {"id": "a", "type": "transport", "input": "octa.obj", "outputs": {"png": "bad/a.png"}},
    {"id": "b", "type": "transport", "input": "octa.obj", "preview_env": "rad.json", "outputs": {"npy": "bad/b.npy"}},
    {"id": "c", "type": "transport", "input": "octa.obj", "preview_env": "nothere.json", "outputs": {"png": "bad/c.png"}},
    {"id": "d", "type": "transport", "input": "octa.obj", "samples": 16, "preview_env": "irr.json",
     "outputs": {"npy": "bad/d.npy", "png": "bad/d.png"}}
  ]})";
  r = test::runCli("run '" + dir + "/bad.json'");
  INFO(r.output);
  REQUIRE(r.exitCode == 1);
  REQUIRE(r.output.find("job 'a': preview_env") != std::string::npos);
  REQUIRE(r.output.find("job 'b': preview_env") != std::string::npos);
  REQUIRE(r.output.find("nothere.json") != std::string::npos);
  REQUIRE(r.output.find("irr.json") != std::string::npos);
  REQUIRE_FALSE(test::fileExists(dir + "/bad/d.npy"));
  REQUIRE_FALSE(test::fileExists(dir + "/bad/d.png"));
}

TEST_CASE("Transport from a glTF copy: the _PRT_ attributes read back exactly", "[preview][mesh]") {
  const std::string dir = test::tempDir("previewgltf");
  const Mesh scene = loadMesh(std::string(PRTBAKE_TEST_SOURCE_DIR) + "/../assets/scene.gltf");
  for (TransportMode mode : {TransportMode::Shadowed, TransportMode::Interreflected}) {
    TransportOptions o;
    o.mode = mode;
    o.order = 3;
    o.samples = 16;
    o.bounces = 1;
    const TransportResult r = computeTransport(test::runtime(), scene, o);
    writeTransportGltf(dir + "/copy.glb", scene, r);
    const Mesh copy = loadMesh(dir + "/copy.glb");
    REQUIRE(copy.vertexCount() == scene.vertexCount());
    const TransportCoeffs t = readTransportGltf(copy);
    REQUIRE((t.order == 3 && t.channels == r.channels && t.vertexCount == r.vertexCount));
    REQUIRE(t.coeffs == r.coeffs);
  }
  // The input itself has no transport attributes.
  REQUIRE_THROWS_AS(readTransportGltf(scene), InputError);
}
