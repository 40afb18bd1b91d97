// Lightmaps (prtbake/lightmap.h) against closed forms and the per-vertex transport, and the
// repairs each against the failure it prevents: samples under a wall, sliver triangles, texels
// that bilinear and mip lookups read; the UV checks and the command's bad inputs.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>

#include <nlohmann/json.hpp>

#include "prtbake/error.h"
#include "prtbake/exr.h"
#include "prtbake/glossy.h"
#include "prtbake/lightmap.h"
#include "prtbake/preview.h"
#include "prtbake/sh.h"
#include "prtbake/transport.h"
#include "engine_test_helpers.h"
#include "job_test_helpers.h"
#include "test_common.h"

using namespace prtbake;

namespace {

constexpr double kPi = 3.14159265358979323846;

using Vec3 = std::array<double, 3>;
struct UvRect {
  double u0, v0, u1, v1;
};

// A quad p0 p1 p2 p3 (counter-clockwise seen from its front), its corners at the rectangle's
// (u0, v1), (u1, v1), (u1, v0), (u0, v0) in UV set 0.
void addQuad(Mesh& m, const Vec3* p, const UvRect& r) {
  const uint32_t base = uint32_t(m.vertexCount());
  const double e1[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
  const double e2[3] = {p[3][0] - p[0][0], p[3][1] - p[0][1], p[3][2] - p[0][2]};
  double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
  const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  const double uv[4][2] = {{r.u0, r.v1}, {r.u1, r.v1}, {r.u1, r.v0}, {r.u0, r.v0}};
  m.uvs.resize(1);
  m.uvMissing.resize(1);
  for (int v = 0; v < 4; ++v) {
    for (int a = 0; a < 3; ++a) {
      m.positions.push_back(float(p[v][a]));
      m.normals.push_back(float(n[a] / len));
      m.albedo.push_back(1.0f);
    }
    m.uvs[0].insert(m.uvs[0].end(), {float(uv[v][0]), float(uv[v][1])});
  }
  for (uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) m.indices.push_back(base + i);
}

// The floor z = 0 over [−h, h]², facing +z, as one quad (two triangles: a low-poly floor).
void addFloor(Mesh& m, double h, const UvRect& r) {
  const Vec3 p[4] = {{-h, -h, 0}, {h, -h, 0}, {h, h, 0}, {-h, h, 0}};
  addQuad(m, p, r);
}

// The closed box [lo, hi] with outward faces, each face's UVs in its sixth of the rectangle.
void addBox(Mesh& m, const Vec3& lo, const Vec3& hi, const UvRect& r) {
  for (int axis = 0, f = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side, ++f) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      Vec3 p[4];
      const double c[4][2] = {{lo[u], lo[v]}, {hi[u], lo[v]}, {hi[u], hi[v]}, {lo[u], hi[v]}};
      for (int k = 0; k < 4; ++k) {
        p[k][axis] = side ? hi[axis] : lo[axis];
        p[k][u] = c[k][0], p[k][v] = c[k][1];
      }
      if (side == 0) std::swap(p[1], p[3]);  // (u, v) counter-clockwise faces +axis
      const double w = (r.u1 - r.u0) / 6;
      addQuad(m, p, {r.u0 + f * w, r.v0, r.u0 + (f + 0.9) * w, r.v1});
    }
}

// A disk of radius a at height z facing down (−z), a fan of `segments` triangles, its UVs the
// disk's image in the rectangle.
void addDisk(Mesh& m, double a, double z, int segments, const UvRect& r) {
  const uint32_t base = uint32_t(m.vertexCount());
  m.uvs.resize(1);
  m.uvMissing.resize(1);
  auto push = [&](double x, double y) {
    m.positions.insert(m.positions.end(), {float(x), float(y), float(z)});
    m.normals.insert(m.normals.end(), {0.0f, 0.0f, -1.0f});
    m.albedo.insert(m.albedo.end(), {1.0f, 1.0f, 1.0f});
    m.uvs[0].insert(m.uvs[0].end(), {float(r.u0 + (r.u1 - r.u0) * (0.5 + 0.5 * x / a)),
                                     float(r.v0 + (r.v1 - r.v0) * (0.5 + 0.5 * y / a))});
  };
  push(0, 0);
  for (int s = 0; s < segments; ++s) push(a * std::cos(2 * kPi * s / segments), a * std::sin(2 * kPi * s / segments));
  for (int s = 0; s < segments; ++s)  // clockwise seen from +z: faces down
    m.indices.insert(m.indices.end(), {base, uint32_t(base + 1 + (s + 1) % segments), uint32_t(base + 1 + s)});
}

// The view factor from a point on the floor, at distance x from the axis of a parallel disk of
// radius a at height h, to the disk: F = ½ [1 − (h² + x² − a²) / √((h² + x² + a²)² − 4 a² x²)]
// (the differential area to a parallel coaxial-offset disk; Siegel & Howell, configuration B-13).
// The floor's ambient occlusion is 1 − F.
double diskViewFactor(double h, double x, double a) {
  const double s = h * h + x * x + a * a;
  return 0.5 * (1 - (h * h + x * x - a * a) / std::sqrt(s * s - 4 * a * a * x * x));
}

// Bilinear lookup of a W × W plane (c floats per texel, channel ch) at (u, v), texel centres at
// ((x + ½)/W, (y + ½)/W), clamped at the edges: what a GPU's linear filter computes.
double bilinear(const std::vector<float>& plane, int W, int c, int ch, double u, double v) {
  const double s = u * W - 0.5, t = v * W - 0.5;
  const int x0 = int(std::floor(s)), y0 = int(std::floor(t));
  const double fx = s - x0, fy = t - y0;
  auto at = [&](int x, int y) {
    x = std::clamp(x, 0, W - 1), y = std::clamp(y, 0, W - 1);
    return double(plane[(size_t(y) * W + x) * c + ch]);
  };
  return (1 - fy) * ((1 - fx) * at(x0, y0) + fx * at(x0 + 1, y0)) + fy * ((1 - fx) * at(x0, y0 + 1) + fx * at(x0 + 1, y0 + 1));
}

ShCoeffs constantEnv(double L) {
  ShCoeffs c;
  c.order = 1;
  const double l0 = L * std::sqrt(4 * kPi);
  c.rgb = {Rgb{l0, l0, l0}};
  return c;
}

}  // namespace

TEST_CASE("Lightmap: the floor under a disk matches the view factor's closed form at several sizes", "[lightmap]") {
  // Floor [−2, 2]² on UV [0, 1] × [0, 0.5]... the floor takes the left half, the disk the right.
  const double h = 2, a = 0.6, z = 0.5;
  const int segments = 96;
  Mesh m;
  addFloor(m, h, {0, 0, 0.5, 1});
  addDisk(m, a, z, segments, {0.55, 0.05, 0.95, 0.45});
  // The fan's equal-area radius: the formula is for a round disk.
  const double aEff = a * std::sqrt(segments * std::sin(2 * kPi / segments) / (2 * kPi));
  for (int size : {32, 64}) {
    LightmapOptions o;
    o.size = size;
    o.samples = 2048;
    o.products = kLightmapAo | kLightmapIrradiance;
    const double L = 0.7;
    const LightmapResult lm = computeLightmap(test::runtime(), m, constantEnv(L), o);
    REQUIRE(lm.width == size);
    // Every floor texel whose centre lies within 2.5 disk radii of the axis.
    double worst = 0, worstBroken = 1e9, worstIrr = 0;
    int checked = 0;
    for (int y = 0; y < size; ++y)
      for (int x = 0; x < size / 2; ++x) {
        const Vec3 p = {-h + 2 * h * (x + 0.5) / (size / 2), h - 2 * h * (y + 0.5) / size, 0};
        const double r = std::hypot(p[0], p[1]);
        if (r > 2.5 * a) continue;
        const size_t i = size_t(y) * size + x;
        REQUIRE(lm.valid(i));
        const double exact = 1 - diskViewFactor(z, r, aEff);
        const double broken = 1 - diskViewFactor(1.5 * z, r, aEff);  // the disk 50 % higher
        worst = std::max(worst, std::abs(lm.ao[i] - exact));
        worstBroken = std::min(worstBroken, std::abs(lm.ao[i] - broken) + (r > a ? 1.0 : 0.0));
        worstIrr = std::max(worstIrr, std::abs(lm.irradiance[3 * i] - L * exact));
        ++checked;
      }
    // Tolerance: the estimator's standard error bounds the noise (√(A(1 − A)/N) ≤ 0.011 at
    // N = 2048 for independent rays; the low-discrepancy set does better), 4 σ of that is 0.044;
    // the fan's shape beyond its equal-area radius moves F by < 0.002 at these distances.
    INFO("size " << size << ": " << checked << " texels, largest |AO - exact| " << worst
                 << ", irradiance " << worstIrr << ", against the raised disk " << worstBroken);
    CHECK(checked > 20);
    CHECK(worst < 0.03);
    CHECK(worstIrr < 0.03 * L);
    // The oracle can fail: under the disk, the raised disk's closed form is off by more.
    CHECK(worstBroken > 0.06);
  }
}

TEST_CASE("Lightmap: per-texel transport equals the per-vertex transport where a vertex is a texel sample",
          "[lightmap]") {
  // The floor as 2 × 2 quads: its centre vertex (0, 0) at UV (0.5, 0.5), the centre of texel
  // (7, 7) of a 15² map. A disk above it off-centre.
  Mesh m = makeSquare(2, 0, 2, false);
  for (float& v : m.uvs[0]) v *= 0.5f;  // the floor in UV [0, 0.5]²: keep the disk apart
  addDisk(m, 0.8, 0.7, 64, {0.6, 0.6, 0.95, 0.95});
  // makeSquare's centre vertex (index 4: row 1, column 1) sits at UV (0.25, 0.25): texel (3, 3)
  // of a 14² map has its centre there ((3 + 0.5) / 14 = 0.25).
  REQUIRE(m.positions[12] == 0.0f);
  REQUIRE(m.positions[13] == 0.0f);
  REQUIRE(m.uvs[0][8] == 0.25f);
  LightmapOptions o;
  o.size = 14;
  o.samples = 16384;
  o.order = 3;
  o.products = kLightmapTransport;
  const LightmapResult lm = computeLightmap(test::runtime(), m, constantEnv(1), o);
  TransportOptions to;
  to.samples = 16384;
  to.order = 3;
  const TransportResult vt = computeTransport(test::runtime(), m, to);
  const size_t texel = 3 * 14 + 3;
  REQUIRE(lm.valid(texel));
  double worst = 0;
  for (int k = 0; k < 9; ++k) worst = std::max(worst, double(std::abs(lm.transport[texel * 9 + k] - vt.vertex(4)[k])));
  // Two independent estimates of the same integral: their difference has √2 × each one's
  // standard error, at most about √((9/4π)/N) = 0.0066 per vector at N = 16384; 3 σ √2 = 0.028
  // bounds it; the disk changes the coefficients by 0.1 or more, so a wrong point fails.
  INFO("largest coefficient difference " << worst << ", vertex T0 " << vt.vertex(4)[0]);
  CHECK(worst < 0.028);
  CHECK(std::abs(vt.vertex(4)[0] - clampedCosineProjected(3, 0, 0, 1)[0]) > 0.05);  // the disk matters
}

TEST_CASE("Lightmap: a wall on a low-poly floor: no light under it, no shadow bleeding past its foot", "[lightmap]") {
  // One quad of floor [−1, 1]² on UV [0, 1] × [0, 0.5]; a closed box wall 0.1 thick across it
  // (x ∈ [0.04, 0.135]) whose faces take UV [0, 1] × [0.6, 0.9].
  Mesh m;
  addQuad(m, std::array<Vec3, 4>{Vec3{-1, -1, 0}, Vec3{1, -1, 0}, Vec3{1, 1, 0}, Vec3{-1, 1, 0}}.data(), {0, 0, 1, 0.5});
  addBox(m, {0.04, -1.2, -0.05}, {0.135, 1.2, 0.6}, {0, 0.6, 1, 0.9});
  const int size = 64;  // floor texels are 2/64 = 0.03125 wide in x: two lie under the wall, one straddles its face
  auto bake = [&](bool unocclude) {
    LightmapOptions o;
    o.size = size;
    o.samples = 512;
    o.dilation = 0;
    o.unocclude = unocclude;
    return computeLightmap(test::runtime(), m, constantEnv(1), o);
  };
  const LightmapResult lm = bake(true), raw = bake(false);
  double underMax = 0, straddleMinFixed = 1, straddleMaxRaw = 0;
  int under = 0, straddle = 0;
  for (int y = 4; y < 28; ++y)  // the floor's rows (v < 0.5), away from its ends
    for (int x = 0; x < size; ++x) {
      const double x0 = -1 + 2.0 * x / size, x1 = -1 + 2.0 * (x + 1) / size, xc = (x0 + x1) / 2;
      const size_t i = size_t(y) * size + x;
      if (x0 >= 0.04 && x1 <= 0.135) {  // the whole texel under the wall
        underMax = std::max(underMax, double(lm.ao[i]));
        ++under;
      } else if (xc > 0.04 && xc < 0.135) {  // centre under the wall, part of the texel outside
        straddleMinFixed = std::min(straddleMinFixed, double(lm.ao[i]));
        straddleMaxRaw = std::max(straddleMaxRaw, double(raw.ao[i]));
        CHECK(TexelState(lm.state[i]) == TexelState::Moved);
        ++straddle;
      }
    }
  INFO(under << " texels under the wall: largest AO " << underMax << "; " << straddle
             << " straddling its faces: smallest AO moved out " << straddleMinFixed << ", largest left inside "
             << straddleMaxRaw);
  REQUIRE(under > 0);
  REQUIRE(straddle > 0);
  // Under the wall: every ray meets its inside (AO exactly 0 but for rays slipping along the floor).
  CHECK(underMax < 0.02);
  // A sample moved out to the wall's foot sees half its hemisphere's sky at least (a wall is a
  // half-space at most: AO ≥ 0.5 − noise); left inside it sees none (the bleed the repair stops).
  CHECK(straddleMinFixed > 0.4);
  CHECK(straddleMaxRaw < 0.02);
  CHECK(lm.moved >= size_t(straddle));
  CHECK(raw.moved == 0);
}

TEST_CASE("Lightmap: a bake split into sample ranges and repaired once equals the whole bake", "[lightmap][shard]") {
  // The wall on the floor (samples moved out and buried) with the box's six charts (seams to
  // stitch): three ranges, each baking its samples with the rays they take in the whole bake,
  // assembled and repaired, give the whole bake's every texel bit for bit.
  Mesh m;
  addQuad(m, std::array<Vec3, 4>{Vec3{-1, -1, 0}, Vec3{1, -1, 0}, Vec3{1, 1, 0}, Vec3{-1, 1, 0}}.data(), {0, 0, 1, 0.5});
  addBox(m, {0.04, -1.2, -0.05}, {0.135, 1.2, 0.6}, {0, 0.6, 1, 0.9});
  LightmapOptions o;
  o.size = 32;
  o.samples = 64;
  o.products = kLightmapAo | kLightmapBent | kLightmapIrradiance | kLightmapSh;
  o.shOrder = 2;
  const ShCoeffs env = constantEnv(0.8);
  const LightmapResult whole = computeLightmap(test::runtime(), m, env, o);
  {  // a GPU's group size (Runtime::loopGroupSize) on this device: the same bytes
    const LightmapResult grouped = computeLightmap(*test::runtimeWithGroupSize("64"), m, env, o);
    CHECK(grouped.ao == whole.ao);
    CHECK(grouped.sh == whole.sh);
  }
  const LightmapSamples samples = lightmapSamples(m, o);
  const size_t total = samples.texelOf.size();
  LightmapResult joined = samples.lm;
  joined.ao.assign(whole.ao.size(), 0.0f), joined.bent.assign(whole.bent.size(), 0.0f);
  joined.irradiance.assign(whole.irradiance.size(), 0.0f), joined.sh.assign(whole.sh.size(), 0.0f);
  joined.shOrder = 2;
  for (int k = 0; k < 3; ++k) {
    LightmapOptions part = o;
    part.sampleRange = {total * k / 3, total * (k + 1) / 3 - total * k / 3};
    const LightmapResult r = computeLightmap(test::runtime(), m, env, part);
    CHECK(r.dilated == 0);  // not repaired
    for (size_t t = 0; t < r.texels(); ++t) {
      if (TexelState(r.state[t]) == TexelState::Empty) continue;
      joined.state[t] = r.state[t];
      joined.ao[t] = r.ao[t];
      std::copy_n(&r.bent[3 * t], 3, &joined.bent[3 * t]);
      std::copy_n(&r.irradiance[3 * t], 3, &joined.irradiance[3 * t]);
      std::copy_n(&r.sh[12 * t], 12, &joined.sh[12 * t]);
    }
  }
  repairLightmap(m, o, samples.usable, joined);
  CHECK(whole.moved > 0);
  CHECK(whole.seamEdges > 0);
  CHECK(joined.state == whole.state);
  CHECK(joined.ao == whole.ao);
  CHECK(joined.bent == whole.bent);
  CHECK(joined.irradiance == whole.irradiance);
  CHECK(joined.sh == whole.sh);
  CHECK(joined.dilated == whole.dilated);
  // The same split as jobs: three shards' partial rows merged, the outputs byte for byte those of
  // the job run whole (OBJ's v is 1 − v of the mesh's glTF convention).
  const std::string dir = test::tempDir("lightmap-split");
  {
    std::ofstream obj(dir + "/wall.obj");
    for (size_t v = 0; v < m.vertexCount(); ++v)
      obj << "v " << m.positions[3 * v] << ' ' << m.positions[3 * v + 1] << ' ' << m.positions[3 * v + 2] << "\nvt "
          << m.uvs[0][2 * v] << ' ' << 1 - m.uvs[0][2 * v + 1] << "\nvn " << m.normals[3 * v] << ' ' << m.normals[3 * v + 1]
          << ' ' << m.normals[3 * v + 2] << '\n';
    for (size_t t = 0; t < m.triangleCount(); ++t) {
      obj << 'f';
      for (int k = 0; k < 3; ++k) obj << ' ' << m.indices[3 * t + k] + 1 << '/' << m.indices[3 * t + k] + 1 << '/' << m.indices[3 * t + k] + 1;
      obj << '\n';
    }
  }
  auto job = [&](const std::string& id, const std::string& out, bool split) {
    nlohmann::json j = {{"id", id}, {"type", "lightmap"}, {"input", "wall.obj"}, {"size", 32}, {"samples", 64},
                        {"products", "ao,bent,irradiance,sh"}, {"sh_order", 2},
                        {"outputs", {{"ao_exr", out + "/ao.exr"}, {"ao_png", out + "/ao.png"}, {"bent_exr", out + "/bent.exr"},
                                     {"irradiance_ktx2", out + "/irradiance.ktx2"}, {"sh_exr", out + "/sh.exr"},
                                     {"json", out + "/lightmap.json"}}}};
    if (split) j["split"] = true;
    return j;
  };
  std::ofstream(dir + "/jobs.json") << nlohmann::json{{"jobs", {job("split", "s", true), job("whole", "w", false)}}}.dump();
  for (int i = 0; i < 3; ++i) {
    const auto r = test::runCli("run '" + dir + "/jobs.json' --shard " + std::to_string(i) + "/3 --quiet");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
  }
  const auto merged = test::runCli("merge '" + dir + "/jobs.json' --shards 3");
  INFO(merged.output);
  REQUIRE(merged.exitCode == 0);
  CHECK(merged.output.find("texels") != std::string::npos);
  for (const char* f : {"ao.exr", "ao.png", "bent.exr", "irradiance.ktx2", "sh.exr"}) {
    INFO(f);
    const std::string w = test::readText(dir + "/w/" + f);
    CHECK(!w.empty());
    CHECK(test::readText(dir + "/s/" + f) == w);
  }
  const auto splitSide = nlohmann::json::parse(test::readText(dir + "/s/lightmap.json"));
  const auto wholeSide = nlohmann::json::parse(test::readText(dir + "/w/lightmap.json"));
  CHECK(splitSide["texels"] == wholeSide["texels"]);
  CHECK(splitSide["samples"]["rays"] == wholeSide["samples"]["rays"]);
  CHECK(splitSide["error"]["max_std_error"] == wholeSide["error"]["max_std_error"]);
  // The mean: the shards' means weighted by their samples (the sum's order differs: 1e-12).
  CHECK(splitSide["error"]["mean_std_error"].get<double>() ==
        Approx(wholeSide["error"]["mean_std_error"].get<double>()).epsilon(1e-12));
  std::ofstream(dir + "/tol.json") << R"({"jobs": [{"id": "t", "type": "lightmap", "input": "wall.obj", "size": 8,
      "tolerance": 0.05, "split": true, "outputs": {"ao_exr": "t/ao.exr"}}]})";
  const auto tol = test::runCli("run '" + dir + "/tol.json' --dry-run");
  CHECK(tol.exitCode != 0);
  CHECK(tol.output.find("a split bake takes a fixed number of samples") != std::string::npos);

  // A range beyond the samples, and with a tolerance: refused.
  LightmapOptions bad = o;
  bad.sampleRange = {total, 1};
  CHECK_THROWS_AS(computeLightmap(test::runtime(), m, env, bad), UsageError);
  bad.sampleRange = {0, 1};
  bad.tolerance = 0.01;
  CHECK_THROWS_WITH(computeLightmap(test::runtime(), m, env, bad), Catch::Contains("fixed number of samples"));
}

TEST_CASE("Lightmap: a sliver triangle thinner than a texel is baked (conservative rasterisation)", "[lightmap]") {
  // A floor triangle 0.2 texels wide in UV, lying between texel centres: no centre is inside.
  Mesh m;
  m.uvs.resize(1);
  m.uvMissing.resize(1);
  const int size = 32;
  const float u0 = (10 + 0.6f) / size, u1 = (10 + 0.8f) / size;
  const float p[3][3] = {{0, 0, 0}, {0.1f, 3, 0}, {0.0f, 3, 0}};
  const float uv[3][2] = {{u0, 0.05f}, {u1, 0.95f}, {u0, 0.95f}};
  for (int k = 0; k < 3; ++k) {
    m.positions.insert(m.positions.end(), p[k], p[k] + 3);
    m.normals.insert(m.normals.end(), {0, 0, 1});
    m.albedo.insert(m.albedo.end(), {1, 1, 1});
    m.uvs[0].insert(m.uvs[0].end(), uv[k], uv[k] + 2);
  }
  m.indices = {0, 1, 2};
  LightmapOptions o;
  o.size = size;
  o.samples = 64;
  o.dilation = 0;
  const LightmapResult lm = computeLightmap(test::runtime(), m, constantEnv(1), o);
  // Texel column 10 (its centre at 10.5 < 10.6) holds the whole sliver for rows 2 … 29.
  int baked = 0;
  for (int y = 2; y < 30; ++y) {
    const size_t i = size_t(y) * size + 10;
    CHECK(lm.valid(i));
    CHECK(std::abs(lm.ao[i] - 1.0f) < 1e-6f);  // an open plane: the closed form
    baked += lm.valid(i);
  }
  CHECK(baked == 28);
  CHECK(lm.centreOutside == lm.baked);  // none of the sliver's texels has its centre inside
}

TEST_CASE("Lightmap: dilation leaves no unbaked texel in any bilinear or mip footprint of a baked one", "[lightmap]") {
  // A disc-like fan chart in the middle of the map with empty space around it.
  Mesh m;
  addDisk(m, 1.0, 0.0, 24, {0.2, 0.25, 0.7, 0.75});
  auto footprintsClean = [](const LightmapResult& lm, int levels) {
    // Level k's texel (X, Y) averages the 2^k × 2^k block; bilinear at any point of a valid
    // texel's area reads the valid texel and its 8 neighbours at level 0, and the blocks
    // around its block at level k.
    for (int k = 0; k < levels; ++k) {
      const int b = 1 << k, w = lm.width / b;
      for (int y = 0; y < lm.height; ++y)
        for (int x = 0; x < lm.width; ++x) {
          if (!lm.valid(size_t(y) * lm.width + x)) continue;
          const int X = x / b, Y = y / b;
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const int nx = X + dx, ny = Y + dy;
              if (nx < 0 || ny < 0 || nx >= w || ny >= w) continue;
              for (int j = 0; j < b; ++j)
                for (int i = 0; i < b; ++i)
                  if (TexelState(lm.state[size_t(ny * b + j) * lm.width + nx * b + i]) == TexelState::Empty) return false;
            }
        }
    }
    return true;
  };
  LightmapOptions o;
  o.size = 64;
  o.samples = 16;
  o.products = kLightmapAo | kLightmapBent;
  const LightmapResult lm = computeLightmap(test::runtime(), m, constantEnv(1), o);
  CHECK(lm.dilated > 0);
  CHECK(footprintsClean(lm, 3));  // levels 0, 1, 2 (64², 32², 16²): 8 rings cover them
  // Dilated texels hold their neighbours' values (the open plane's AO 1, unit bent normals).
  for (size_t i = 0; i < lm.texels(); ++i)
    if (TexelState(lm.state[i]) == TexelState::Dilated) {
      REQUIRE(std::abs(lm.ao[i] - 1.0f) < 1e-5f);
      REQUIRE(std::abs(std::hypot(lm.bent[3 * i], lm.bent[3 * i + 1], lm.bent[3 * i + 2]) - 1.0) < 1e-5);
    }
  o.dilation = 0;
  CHECK_FALSE(footprintsClean(computeLightmap(test::runtime(), m, constantEnv(1), o), 1));
}

TEST_CASE("Lightmap: the bent normal and AO at the foot of a wall match the half-space closed form", "[lightmap]") {
  // A floor beside a tall wall at x = 0.2 (its face towards −x): the bent normal of the floor
  // near it tilts to −x, and is n far from it.
  Mesh m;
  addFloor(m, 1, {0, 0, 0.5, 1});
  const Vec3 w[4] = {{0.2, -1, 0}, {0.2, -1, 3}, {0.2, 1, 3}, {0.2, 1, 0}};  // faces −x
  addQuad(m, w, {0.6, 0.1, 0.9, 0.9});
  LightmapOptions o;
  o.size = 32;
  o.samples = 1024;
  o.products = kLightmapBent | kLightmapAo;
  const LightmapResult lm = computeLightmap(test::runtime(), m, constantEnv(1), o);
  // The floor spans u ∈ [0, 0.5]: 16 columns of 0.125 m; column 9's centre is at x = 0.1875,
  // 0.0125 m from the wall (3 m tall, 2 m long: nearly a half-space from there), column 2's at
  // x = −0.6875. At the foot of a half-space wall the unoccluded half hemisphere (x < 0) has the
  // cosine-weighted mean direction ∫ cos θ ω dω = (−2/3, 0, π/3): B = (−2, 0, π)/√(4 + π²), and
  // AO = 1/2. Tolerance 0.02: the sampler's noise at 1024 rays (about 0.01) and the wall's
  // finite size (its ends lie 80 wall-distances away).
  const size_t nearWall = size_t(16) * 32 + 9, far = size_t(16) * 32 + 2;
  const double norm = std::sqrt(4 + kPi * kPi);
  const double expect[3] = {-2 / norm, 0, kPi / norm};
  INFO("near: bent (" << lm.bent[3 * nearWall] << ", " << lm.bent[3 * nearWall + 1] << ", " << lm.bent[3 * nearWall + 2]
                      << "), AO " << lm.ao[nearWall]);
  for (int c = 0; c < 3; ++c) CHECK(std::abs(lm.bent[3 * nearWall + c] - expect[c]) < 0.02);
  CHECK(std::abs(lm.ao[nearWall] - 0.5) < 0.02);
  // A wrong axis or sign fails: the far texel's bent normal is n.
  CHECK(lm.bent[3 * far + 2] > 0.95);
}

namespace {

// ∫ Y_j(ω) dω over the directions with z > 0 and sx · x > 0 (a quarter of the sphere), j < 9, by
// the midpoint rule on a 1024 × 2048 grid in (θ, φ) (a reference independent of the bake's
// sampler; its own error is below 1e-5).
std::array<double, 9> quarterSphereIntegrals(double sx) {
  std::array<double, 9> sum{};
  const int nt = 1024, np = 2048;
  for (int i = 0; i < nt; ++i) {
    const double th = (i + 0.5) * (kPi / 2) / nt;
    for (int k = 0; k < np; ++k) {
      const double ph = (k + 0.5) * 2 * kPi / np;
      const double x = std::sin(th) * std::cos(ph), y = std::sin(th) * std::sin(ph), z = std::cos(th);
      if (sx * x <= 0) continue;
      double Y[9];
      shEval(3, x, y, z, Y);
      const double dw = std::sin(th) * (kPi / 2 / nt) * (2 * kPi / np);
      for (int j = 0; j < 9; ++j) sum[size_t(j)] += Y[j] * dw;
    }
  }
  return sum;
}

}  // namespace

TEST_CASE("Lightmap: the bent normal in tangent space follows the mesh's tangent frame", "[lightmap]") {
  // The wall scene of the bent-normal test with tangents on every vertex: the floor's tangent
  // +x with w = +1 (bitangent n × t = +y), or +y with w = −1 (bitangent −(z × y) = +x). The
  // object-space B = (−2, 0, π)/√(4 + π²) near the wall reads (−2, 0, π)/… in the first frame and
  // (0, −2, π)/… in the second; a wrong handedness or a swapped axis fails.
  const double norm = std::sqrt(4 + kPi * kPi);
  struct Frame {
    float t[3], w;
    double expect[3];
  };
  for (const Frame& f : {Frame{{1, 0, 0}, 1, {-2 / norm, 0, kPi / norm}}, Frame{{0, 1, 0}, -1, {0, -2 / norm, kPi / norm}}}) {
    Mesh m;
    addFloor(m, 1, {0, 0, 0.5, 1});
    const Vec3 w[4] = {{0.2, -1, 0}, {0.2, -1, 3}, {0.2, 1, 3}, {0.2, 1, 0}};
    addQuad(m, w, {0.6, 0.1, 0.9, 0.9});
    for (size_t v = 0; v < m.vertexCount(); ++v)  // the wall's own tangent: +y (unused by the test)
      m.tangents.insert(m.tangents.end(), v < 4 ? std::initializer_list<float>{f.t[0], f.t[1], f.t[2], f.w}
                                                : std::initializer_list<float>{0, 1, 0, 1});
    LightmapOptions o;
    o.size = 32;
    o.samples = 1024;
    o.products = kLightmapBent;
    const LightmapResult lm = computeLightmap(test::runtime(), m, constantEnv(1), o);
    REQUIRE(lm.bentTangent.size() == lm.texels() * 3);
    const size_t nearWall = size_t(16) * 32 + 9, far = size_t(16) * 32 + 2;
    INFO("tangent (" << f.t[0] << ", " << f.t[1] << ", " << f.t[2] << "), w " << f.w << ": ("
                     << lm.bentTangent[3 * nearWall] << ", " << lm.bentTangent[3 * nearWall + 1] << ", "
                     << lm.bentTangent[3 * nearWall + 2] << ")");
    // Tolerance 0.02: as the object-space test (the same rays).
    for (int c = 0; c < 3; ++c) CHECK(std::abs(lm.bentTangent[3 * nearWall + c] - f.expect[c]) < 0.02);
    CHECK(lm.bentTangent[3 * far + 2] > 0.95);
  }
  // Without tangents there is no tangent-space image.
  Mesh plain;
  addFloor(plain, 1, {0, 0, 1, 1});
  LightmapOptions o;
  o.size = 8;
  o.samples = 16;
  o.products = kLightmapBent;
  CHECK(computeLightmap(test::runtime(), plain, constantEnv(1), o).bentTangent.empty());
}

TEST_CASE("Lightmap: directional (SH) irradiance at the foot of a wall matches the quarter sphere's closed form",
          "[lightmap]") {
  // The wall of the bent-normal test: under a constant white sky (L = 1, l_0 = √(4π)) the light
  // reaching the floor at the wall's foot comes from the quarter sphere z > 0, x < 0, so
  // D_j = (Â_l/π) ∫_{quarter} Y_j dω, and a normal n′ shades Σ_j D_j Y_j(n′) (E/π, truncated).
  Mesh m;
  addFloor(m, 1, {0, 0, 0.5, 1});
  const Vec3 w[4] = {{0.2, -1, 0}, {0.2, -1, 3}, {0.2, 1, 3}, {0.2, 1, 0}};  // faces −x
  addQuad(m, w, {0.6, 0.1, 0.9, 0.9});
  LightmapOptions o;
  o.size = 32;
  o.samples = 4096;
  o.products = kLightmapSh | kLightmapIrradiance;
  const LightmapResult lm = computeLightmap(test::runtime(), m, constantEnv(1), o);
  REQUIRE(lm.shOrder == 3);
  REQUIRE(lm.sh.size() == lm.texels() * 27);
  const size_t nearWall = size_t(16) * 32 + 9;
  const std::array<double, 9> q = quarterSphereIntegrals(-1), mirrored = quarterSphereIntegrals(+1);
  // Tolerance 0.02 per coefficient: the sampler's noise at 4096 uniform rays (the visible
  // fraction's standard deviation 2π · ½ · Y_0 / √4096 = 0.014 for D_0, less for the others
  // with low-discrepancy points) and the wall's finite size (as the bent-normal test).
  double worst = 0, worstMirrored = 0;
  for (int j = 0; j < 9; ++j) {
    const double a = clampedCosineFactor(int(std::sqrt(j + 0.5))) / kPi;
    for (int c = 0; c < 3; ++c) {
      const double got = lm.sh[nearWall * 27 + 3 * j + c];
      INFO("j " << j << " channel " << c << ": " << got << " against " << a * q[size_t(j)]);
      CHECK(std::abs(got - a * q[size_t(j)]) < 0.02);
      worst = std::max(worst, std::abs(got - a * q[size_t(j)]));
      worstMirrored = std::max(worstMirrored, std::abs(got - a * mirrored[size_t(j)]));
    }
  }
  // The oracle fails on a wall mirrored to the other side (a flipped x).
  INFO("largest difference " << worst << ", against the mirrored wall " << worstMirrored);
  CHECK(worstMirrored > 0.3);
  // Shaded with the texel's own normal, the SH gives the irradiance product back up to the
  // clamped cosine's truncation at L2: |Δ| ≤ l_0 × clampedCosineTruncationBound(3)/√2 (glossy.h)
  // plus the two estimators' noise (0.02), at every valid floor texel.
  double Y[9];
  shEval(3, 0, 0, 1, Y);
  const double bound = std::sqrt(4 * kPi) * clampedCosineTruncationBound(3) / std::sqrt(2.0) + 0.02;
  double largest = 0;
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 16; ++x) {
      const size_t i = size_t(y) * 32 + x;
      if (!lm.valid(i)) continue;
      double e = 0;
      for (int j = 0; j < 9; ++j) e += lm.sh[i * 27 + 3 * j] * Y[j];
      largest = std::max(largest, std::abs(e - lm.irradiance[3 * i]));
    }
  INFO("largest |E_sh(n) - E| " << largest << ", bound " << bound);
  CHECK(largest <= bound);
  // Near the wall the floor's light comes from −x: a normal tilted that way gets more of it.
  double Yt[9];
  shEval(3, -std::sqrt(0.5), 0, std::sqrt(0.5), Yt);
  double tilted = 0, straight = 0;
  for (int j = 0; j < 9; ++j) tilted += lm.sh[nearWall * 27 + 3 * j] * Yt[j], straight += lm.sh[nearWall * 27 + 3 * j] * Y[j];
  CHECK(tilted > straight + 0.1);
}

TEST_CASE("Lightmap: a UV seam around a cylinder is stitched: its two sides agree along it", "[lightmap]") {
  // An open tube (radius 0.5, height 1, 24 sides, outward) unwrapped onto u ∈ [0.1, 0.9] by angle,
  // v ∈ [0.1, 0.9] by height: the edge at angle 0 lies on u = 0.1 and on u = 0.9. Under
  // L = 0.55 + 0.35 ω_y its irradiance E/π = 0.55 + (2/3) 0.35 n_y changes fastest with angle
  // exactly there, so the two sides' lookups along the seam, each reading the texels nearest its
  // own edge (half a texel inside), differ by about the gradient × a texel.
  const int sides = 24;
  Mesh m;
  m.uvs.resize(1);
  m.uvMissing.resize(1);
  for (int s = 0; s <= sides; ++s)
    for (int h = 0; h < 2; ++h) {
      const double a = 2 * kPi * s / sides;
      m.positions.insert(m.positions.end(), {float(0.5 * std::cos(a)), float(0.5 * std::sin(a)), float(h)});
      m.normals.insert(m.normals.end(), {float(std::cos(a)), float(std::sin(a)), 0.0f});
      m.albedo.insert(m.albedo.end(), {1, 1, 1});
      m.uvs[0].insert(m.uvs[0].end(), {float(0.1 + 0.8 * s / sides), float(0.9 - 0.8 * h)});
    }
  // The last column's positions equal the first's exactly (the seam is one edge in space).
  for (int h = 0; h < 2; ++h)
    for (int c = 0; c < 3; ++c) m.positions[3 * (2 * sides + h) + c] = m.positions[3 * h + c];
  for (uint32_t s = 0; s < uint32_t(sides); ++s) {
    const uint32_t a = 2 * s, b = a + 2;  // (a: bottom, a + 1: top) of column s
    m.indices.insert(m.indices.end(), {a, b, b + 1, a, b + 1, a + 1});
  }
  ShCoeffs env;
  env.order = 2;
  env.rgb.assign(4, Rgb{0, 0, 0});
  double y[4];
  shEval(2, 0, 1, 0, y);
  const double c0 = 0.55 * std::sqrt(4 * kPi), c1 = 0.35 * std::sqrt(4 * kPi / 3) * (y[1] > 0 ? 1 : -1);
  env.rgb[0] = Rgb{c0, c0, c0};
  env.rgb[1] = Rgb{c1, c1, c1};
  LightmapOptions o;
  o.size = 64;
  o.samples = 64;
  o.products = kLightmapIrradiance;
  auto jump = [&](const LightmapResult& lm) {
    double worst = 0;
    for (int k = 0; k < 64; ++k) {
      const double v = 0.1 + 0.8 * (k + 0.5) / 64;
      worst = std::max(worst, std::abs(bilinear(lm.irradiance, 64, 3, 0, 0.1, v) - bilinear(lm.irradiance, 64, 3, 0, 0.9, v)));
    }
    return worst;
  };
  const LightmapResult stitched = computeLightmap(test::runtime(), m, env, o);
  o.stitchSeams = false;
  const LightmapResult raw = computeLightmap(test::runtime(), m, env, o);
  // How far stitching moved the baked texels: the data term holds them near their values.
  double moved = 0;
  for (size_t i = 0; i < raw.texels(); ++i)
    if (raw.valid(i)) moved = std::max(moved, double(std::abs(stitched.irradiance[3 * i] - raw.irradiance[3 * i])));
  INFO("seam edges " << stitched.seamEdges << "; largest jump along the seam: raw " << jump(raw) << ", stitched "
                     << jump(stitched) << "; largest change of a baked texel " << moved);
  CHECK(stitched.seamEdges == 1);
  // The raw jump is about the gradient × a texel (0.23 × 0.12 rad ≈ 0.03; measured 0.019); stitched, the sides agree to
  // within 1e-3 (the closed form leaves no noise: what remains is the data term's pull).
  CHECK(jump(raw) > 0.01);
  CHECK(jump(stitched) < 1e-3);
  CHECK(moved < 0.03);
}

TEST_CASE("Lightmap: UV checks: a missing set, non-finite UVs, overlapping charts", "[lightmap]") {
  Mesh m;
  addFloor(m, 1, {0, 0, 0.6, 1});
  LightmapOptions o;
  o.size = 16;
  o.samples = 16;
  o.uvSet = 1;
  CHECK_THROWS_WITH(computeLightmap(test::runtime(), m, constantEnv(1), o),
                    Catch::Contains("no UV set 1") && Catch::Contains("set(s) 0"));
  o.uvSet = 0;
  // Overlap: a second floor whose chart covers part of the first's.
  Mesh twice = m;
  Mesh other;
  addFloor(other, 1, {0.4, 0, 1, 1});
  for (float& p : other.positions) p += 5;
  appendMesh(twice, other);
  CHECK_THROWS_WITH(computeLightmap(test::runtime(), twice, constantEnv(1), o),
                    Catch::Contains("UV charts overlap") && Catch::Contains("texel (") && Catch::Contains("triangle 0"));
  // Stacked: a second floor elsewhere in space on the very same UV square (its edges' UVs equal
  // the first's, so the two join into one chart), as Khronos' MultiUVTest maps all six faces of
  // its cube onto one square of TEXCOORD_1.
  Mesh stacked = m;
  Mesh copy;
  addFloor(copy, 1, {0, 0, 0.6, 1});
  for (float& p : copy.positions) p += 5;
  appendMesh(stacked, copy);
  CHECK_THROWS_WITH(computeLightmap(test::runtime(), stacked, constantEnv(1), o),
                    Catch::Contains("UV charts overlap") && Catch::Contains("of the same chart (UVs stacked or folded)"));
  // Charts side by side closer than a texel are not an overlap.
  Mesh beside = m;
  Mesh near;
  addFloor(near, 1, {0.61, 0, 1, 1});
  for (float& p : near.positions) p += 5;
  appendMesh(beside, near);
  const LightmapResult lm = computeLightmap(test::runtime(), beside, constantEnv(1), o);
  CHECK(lm.contested > 0);
  CHECK(lm.charts == 2);
  Mesh nan = m;
  nan.uvs[0][3] = std::nanf("");
  CHECK_THROWS_WITH(computeLightmap(test::runtime(), nan, constantEnv(1), o),
                    Catch::Contains("vertex 1 has a non-finite v"));
  o.size = 1 << 20;
  CHECK_THROWS_AS(computeLightmap(test::runtime(), m, constantEnv(1), o), UsageError);
}

TEST_CASE("Lightmap: glTF TEXCOORD_n and OBJ vt load as UV sets", "[lightmap]") {
  const std::string dir = test::tempDir("lightmap-uv");
  {
    std::ofstream f(dir + "/quad.obj");
    f << "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nf 1/1 2/2 3/3\n";
  }
  const Mesh obj = loadMesh(dir + "/quad.obj");
  REQUIRE(obj.hasUvSet(0));
  CHECK(obj.uvs[0] == std::vector<float>{0, 1, 1, 1, 1, 0});  // v flipped to glTF's convention
  {
    std::ofstream f(dir + "/novt.obj");
    f << "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n";
  }
  const Mesh novt = loadMesh(dir + "/novt.obj");
  CHECK_FALSE(novt.hasUvSet(0));
  // A glTF of one triangle with TEXCOORD_0 and TEXCOORD_1 (float accessors in one buffer).
  const float data[] = {0, 0, 0, 1, 0, 0, 0, 1, 0,   // POSITION
                        0, 0, 1, 0, 0, 1,            // TEXCOORD_0
                        0.1f, 0.2f, 0.3f, 0.4f, 0.5f, 0.6f};  // TEXCOORD_1
  {
    std::ofstream b(dir + "/tri.bin", std::ios::binary);
    b.write(reinterpret_cast<const char*>(data), sizeof data);
  }
  {
    std::ofstream f(dir + "/tri.gltf");
    f << R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
      "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1, "TEXCOORD_1": 2}}]}],
      "buffers": [{"uri": "tri.bin", "byteLength": 84}],
      "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 24},
                      {"buffer": 0, "byteOffset": 60, "byteLength": 24}],
      "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
                    {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"},
                    {"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC2"}]})";
  }
  const Mesh gltf = loadMesh(dir + "/tri.gltf");
  REQUIRE(gltf.hasUvSet(1));
  CHECK(gltf.uvs[1] == std::vector<float>{0.1f, 0.2f, 0.3f, 0.4f, 0.5f, 0.6f});
  CHECK(gltf.uvs[0] == std::vector<float>{0, 0, 1, 0, 0, 1});
  CHECK(gltf.tangents.empty());
  CHECK(gltf.tangentMissing.find("has no TANGENT") != std::string::npos);
  // TANGENT (VEC4): under a node that mirrors x, the tangent's x flips and so does w (the
  // bitangent w n × t must stay the image of the file's); w other than ±1 is refused.
  auto tangentGltf = [&](const std::string& name, float w, const char* node) {
    const float t[] = {1, 0, 0, w, 0.6f, 0.8f, 0, w, 0, 1, 0, w};
    {
      std::ofstream b(dir + "/" + name + ".bin", std::ios::binary);
      b.write(reinterpret_cast<const char*>(data), 36);
      b.write(reinterpret_cast<const char*>(t), sizeof t);
    }
    std::ofstream f(dir + "/" + name + ".gltf");
    f << R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [)" << node << R"(],
      "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TANGENT": 1}}]}],
      "buffers": [{"uri": ")" << name << R"(.bin", "byteLength": 84}],
      "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 48}],
      "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
                    {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC4"}]})";
    return dir + "/" + name + ".gltf";
  };
  const Mesh tangent = loadMesh(tangentGltf("tangent", 1, R"({"mesh": 0})"));
  CHECK(tangent.tangents == std::vector<float>{1, 0, 0, 1, 0.6f, 0.8f, 0, 1, 0, 1, 0, 1});
  const Mesh mirrored = loadMesh(tangentGltf("mirrored", -1, R"({"mesh": 0, "scale": [-1, 1, 1]})"));
  REQUIRE(mirrored.tangents.size() == 12);
  for (int v = 0; v < 3; ++v) {
    const float want[3][3] = {{-1, 0, 0}, {-0.6f, 0.8f, 0}, {0, 1, 0}};
    for (int c = 0; c < 3; ++c) CHECK(std::abs(mirrored.tangents[4 * v + c] - want[v][c]) < 1e-6f);
    CHECK(mirrored.tangents[4 * v + 3] == 1.0f);
  }
  CHECK_THROWS_WITH(loadMesh(tangentGltf("badw", 0.5f, R"({"mesh": 0})")),
                    Catch::Contains("TANGENT: vertex 0 has w = 0.5") && Catch::Contains("badw.gltf"));
}

TEST_CASE("Lightmap: the command writes every output or none, and refuses bad inputs in one line", "[lightmap]") {
  const std::string dir = test::tempDir("lightmap-cli");
  {
    std::ofstream f(dir + "/floor.obj");
    f << "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 1 0\n"
         "f 1/1/1 4/4/1 3/3/1\nf 1/1/1 3/3/1 2/2/1\n";
    std::ofstream g(dir + "/novt.obj");
    g << "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nf 1 3 2\n";
    std::ofstream n(dir + "/nan.obj");
    n << "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nvt 0 0\nvt nan 0\nvt 1 1\nf 1/1 3/3 2/2\n";
  }
  const auto ok = test::runCli("lightmap '" + dir + "/floor.obj' -o '" + dir + "/out' --size 16 --samples 16 "
                               "--products ao,bent,irradiance,sh --sh-order 2 --format both");
  INFO(ok.output);
  REQUIRE(ok.exitCode == 0);
  for (const char* f : {"ao.exr", "ao.ktx2", "ao.png", "bent.exr", "bent.ktx2", "irradiance.exr", "irradiance.ktx2",
                        "sh.exr", "sh.ktx2", "lightmap.json"})
    CHECK(test::fileExists(dir + "/out/" + f));
  if (test::nodeReady()) {  // sh.ktx2 read by ktx-parse: an array of a layer per coefficient, the EXR's values
    const auto r = test::runShell("node '" + std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/ktx2_read.mjs' '" + dir +
                                  "/out/sh.ktx2' --values");
    INFO(r.output.substr(0, 2000));
    REQUIRE(r.exitCode == 0);
    const nlohmann::json k = nlohmann::json::parse(r.output);
    CHECK(k["vkFormat"] == 97);  // R16G16B16A16_SFLOAT
    CHECK(k["pixelWidth"] == 16);
    CHECK(k["pixelHeight"] == 16);
    CHECK(k["pixelDepth"] == 0);
    CHECK(k["faceCount"] == 1);
    CHECK(k["levelCount"] == 1);
    REQUIRE(k["layerCount"] == 4);  // L1: SH0 … SH3
    CHECK(k["keyValue"]["prtbake.product"] == "sh");
    const ExrImage exr = readExr(dir + "/out/sh.exr");
    const auto& v = k["values"];
    REQUIRE(v.size() == 4 * 16 * 16 * 4);
    // Half precision: relative 2^-11 plus the smallest normal half's step, for values near 0.
    double worst = 0;
    for (int layer = 0; layer < 4; ++layer)
      for (size_t i = 0; i < 256; ++i)
        for (int c = 0; c < 4; ++c) {
          const std::string name = c == 3 ? "A" : "SH" + std::to_string(layer) + "." + "RGB"[c];
          REQUIRE(exr.channel(name) != nullptr);
          const double want = (*exr.channel(name))[i], got = v[(size_t(layer) * 256 + i) * 4 + size_t(c)].get<double>();
          worst = std::max(worst, std::abs(got - want) / (std::abs(want) * std::ldexp(1.0, -11) + std::ldexp(1.0, -24)));
        }
    CHECK(worst <= 1.0);
  }
  CHECK_FALSE(test::fileExists(dir + "/out/bent_tangent.exr"));  // an OBJ has no tangents
  {  // A job that asks for it anyway: the mesh is named, nothing written.
    std::ofstream(dir + "/tangent_job.json")
        << R"({"jobs": [{"id": "t", "type": "lightmap", "input": "floor.obj", "products": "bent", "size": 8,
             "samples": 16, "outputs": {"bent_tangent_exr": "tout/bt.exr", "json": "tout/lm.json"}}]})";
    const auto r = test::runCli("run '" + dir + "/tangent_job.json'");
    INFO(r.output);
    CHECK(r.exitCode != 0);
    CHECK(r.output.find("floor.obj: has no tangents for bent_tangent_exr") != std::string::npos);
    CHECK_FALSE(test::fileExists(dir + "/tout/bt.exr"));  // (the runner makes the job's directories first)
    CHECK_FALSE(test::fileExists(dir + "/tout/lm.json"));
  }
  // The L1 map of an open floor under white, shaded along its normal (+y): E/π = 1, half from
  // D_0 Y_0 and half from the L1 band (the hemisphere's light has no L2 part along n, so the
  // truncation is exact here). Tolerance 0.01: 16 uniform rays estimate ∫ Y_1 over the
  // hemisphere with low-discrepancy points.
  const ExrImage sh = readExr(dir + "/out/sh.exr");
  REQUIRE(sh.channel("SH3.B") != nullptr);
  CHECK(sh.channel("SH4.R") == nullptr);
  double Yn[4];
  shEval(2, 0, 1, 0, Yn);
  for (size_t i = 0; i < 256; ++i) {
    double e = 0;
    for (int j = 0; j < 4; ++j) e += (*sh.channel("SH" + std::to_string(j) + ".G"))[i] * Yn[j];
    CHECK(std::abs(e - 1.0) < 0.01);
  }
  const ExrImage ao = readExr(dir + "/out/ao.exr");
  REQUIRE(ao.width == 16);
  for (float v : *ao.channel("Y")) CHECK(std::abs(v - 1.0f) < 1e-6f);  // an open floor (float: 2√π T_0)
  for (float v : *ao.channel("A")) CHECK(v == 1.0f);
  const nlohmann::json side = nlohmann::json::parse(std::ifstream(dir + "/out/lightmap.json"));
  CHECK(side["texels"]["baked"] == 256);
  struct Bad {
    std::string args, message;
    int status;
  };
  const std::vector<Bad> bad = {
      {"'" + dir + "/novt.obj' --size 16", "has no UV set 0", 1},
      {"'" + dir + "/nan.obj' --size 16", "non-finite", 1},
      {"'" + dir + "/missing.obj' --size 16", "missing.obj", 1},
      {"'" + dir + "/floor.obj' --size 0", "--size", 2},
      {"'" + dir + "/floor.obj' --size 1048576", "--size", 2},
      {"'" + dir + "/floor.obj' --products ao,dust", "dust", 2},
      {"'" + dir + "/floor.obj' --max-distance 1 --products irradiance", "--max-distance", 2},
      {"'" + dir + "/floor.obj' --products sh --sh-order 4", "--sh-order", 2},
      {"'" + dir + "/floor.obj' --products sh --order 7", "--order", 2},
      {"'" + dir + "/floor.obj' --sh-order 2", "--sh-order", 2},
  };
  for (const Bad& b : bad) {
    const std::string out = dir + "/bad";
    const auto r = test::runCli("lightmap " + b.args + " -o '" + out + "'");
    INFO(b.args << ": " << r.output);
    CHECK(r.exitCode == b.status);
    CHECK(r.output.find(b.message) != std::string::npos);
    CHECK_FALSE(test::fileExists(out));
  }
}

namespace {

// A .gltf (external .bin) of `m` with TEXCOORD_0 = `uv0` (texture coordinates that tile and
// overlap, as a real asset's do) and TEXCOORD_1 = m.uvs[0] (the lightmap's), one primitive,
// uint32 indices, no material.
std::string writeTwoUvGltf(const std::string& dir, const Mesh& m, const std::vector<float>& uv0) {
  std::string bin;
  auto put = [&](const void* p, size_t n) {
    bin.append(static_cast<const char*>(p), n);
    while (bin.size() % 4) bin.push_back('\0');
  };
  const size_t nv = m.vertexCount();
  std::vector<size_t> offsets;
  offsets.push_back(bin.size()), put(m.positions.data(), nv * 12);
  offsets.push_back(bin.size()), put(m.normals.data(), nv * 12);
  offsets.push_back(bin.size()), put(uv0.data(), nv * 8);
  offsets.push_back(bin.size()), put(m.uvs[0].data(), nv * 8);
  offsets.push_back(bin.size()), put(m.indices.data(), m.indices.size() * 4);
  std::ofstream(dir + "/scene.bin", std::ios::binary) << bin;
  float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
  for (size_t i = 0; i < nv * 3; ++i) lo[i % 3] = std::min(lo[i % 3], m.positions[i]), hi[i % 3] = std::max(hi[i % 3], m.positions[i]);
  nlohmann::json j;
  j["asset"] = {{"version", "2.0"}};
  j["scene"] = 0;
  j["scenes"] = {{{"nodes", {0}}}};
  j["nodes"] = {{{"mesh", 0}}};
  nlohmann::json prim = {{"attributes", {{"POSITION", 0}, {"NORMAL", 1}, {"TEXCOORD_0", 2}, {"TEXCOORD_1", 3}}},
                         {"indices", 4}};
  j["meshes"] = nlohmann::json::array({{{"primitives", nlohmann::json::array({prim})}}});
  j["buffers"] = {{{"uri", "scene.bin"}, {"byteLength", bin.size()}}};
  const size_t lengths[5] = {nv * 12, nv * 12, nv * 8, nv * 8, m.indices.size() * 4};
  for (int i = 0; i < 5; ++i)
    j["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", offsets[size_t(i)]}, {"byteLength", lengths[i]},
                                {"target", i < 4 ? 34962 : 34963}});
  j["accessors"] = {{{"bufferView", 0}, {"componentType", 5126}, {"count", nv}, {"type", "VEC3"},
                     {"min", {lo[0], lo[1], lo[2]}}, {"max", {hi[0], hi[1], hi[2]}}},
                    {{"bufferView", 1}, {"componentType", 5126}, {"count", nv}, {"type", "VEC3"}},
                    {{"bufferView", 2}, {"componentType", 5126}, {"count", nv}, {"type", "VEC2"}},
                    {{"bufferView", 3}, {"componentType", 5126}, {"count", nv}, {"type", "VEC2"}},
                    {{"bufferView", 4}, {"componentType", 5125}, {"count", m.indices.size()}, {"type", "SCALAR"}}};
  std::ofstream(dir + "/scene.gltf") << j.dump(1);
  return dir + "/scene.gltf";
}

// The page: three.js r187 (tests/js/node_modules) loads each glTF copy (__COPIES__: names of
// NAME.glb beside the page) with its GLTFLoader and renders the floor from above (+z, orthographic
// over [−1, 1]², W × W pixels) into a float target, linear (no tone map, no output encoding). Shot
// "<copy>": every mesh's material replaced by a white MeshBasicMaterial carrying the copy's aoMap
// as the loader made it (the occlusionTexture, on the UV set its texCoord names); pixel = AO. Shot
// "light:<name>": a white MeshBasicMaterial whose lightMap is NAME.ktx2 (KTX2Loader) on uv1
// (__LIGHT_CHANNEL__), lightMapIntensity π; pixel = the texel's E/π (three divides by π).
// Result: per shot, the red channel of every pixel, bottom row first.
const char* kLightmapPage = R"(<!doctype html><html><head>
<script type="importmap">{"imports": {"three": "__THREE__/build/three.module.js", "three/addons/": "__THREE__/examples/jsm/"}}</script>
</head><body><canvas id="c" width="__W__" height="__W__"></canvas>
<script src="__JS__/file_fetch.js"></script>
<script type="module">
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { KTX2Loader } from 'three/addons/loaders/KTX2Loader.js';
let settle;
window.result = new Promise((resolve) => { settle = resolve; });
try {
  const W = __W__;
  const renderer = new THREE.WebGLRenderer({ canvas: document.getElementById('c') });
  const target = new THREE.WebGLRenderTarget(W, W, { type: THREE.FloatType });
  const camera = new THREE.OrthographicCamera(-1, 1, 1, -1, 1, 100);
  camera.position.set(0, 0, 50);
  const shots = {};
  const shoot = (name, scene) => {
    renderer.setRenderTarget(target);
    renderer.setClearColor(0x000000, 0);
    renderer.clear();
    renderer.render(scene, camera);
    const px = new Float32Array(W * W * 4);
    renderer.readRenderTargetPixels(target, 0, 0, W, W, px);
    const red = [];
    for (let i = 0; i < W * W; ++i) red.push(px[4 * i]);
    shots[name] = red;
  };
  for (const name of __COPIES__) {
    const gltf = await new GLTFLoader().loadAsync('./' + name + '.glb');
    let aoMaps = 0;
    gltf.scene.traverse((o) => {
      if (!o.isMesh) return;
      if (o.material.aoMap) ++aoMaps;
      o.material = new THREE.MeshBasicMaterial({ color: 0xffffff, aoMap: o.material.aoMap });
    });
    if (aoMaps === 0) throw new Error(name + ': the loader made no aoMap');
    shoot(name, gltf.scene);
  }
  const ktx2 = new KTX2Loader().setTranscoderPath('__THREE__/examples/jsm/libs/basis/').detectSupport(renderer);
  const plain = await new GLTFLoader().loadAsync('./__PLAIN__.glb');
  for (const name of __LIGHTS__) {
    const map = await ktx2.loadAsync('./' + name + '.ktx2');
    map.channel = __LIGHT_CHANNEL__;
    map.minFilter = THREE.LinearFilter;
    map.magFilter = THREE.LinearFilter;
    map.generateMipmaps = false;
    map.flipY = false;
    const scene = plain.scene.clone();
    scene.traverse((o) => {
      if (o.isMesh) o.material = new THREE.MeshBasicMaterial({ color: 0xffffff, lightMap: map, lightMapIntensity: Math.PI });
    });
    shoot('light:' + name, scene);
  }
  settle('RESULT ' + JSON.stringify({ shots }));
} catch (e) { settle('ERROR ' + e + ' ' + e.stack); }
</script></body></html>
)";

}  // namespace

// A 16384² lightmap of AO took 12 GB and 28 s before "out of host memory" under a 16 GB limit
// (and the OOM killer without one); its transport at order 8 would need ~350 GiB. The estimate
// is checked both ways on real bakes: above each one's peak (so a refusal never stops a bake
// that fits), and within 4x of it (a wrong factor would refuse sizes that fit).
TEST_CASE("Lightmap: a size beyond the memory the process can have is refused at once, and the estimate bounds real peaks",
          "[lightmap]") {
  const std::string dir = test::tempDir("lightmap-memory");
  std::ofstream(dir + "/floor.obj") << "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                                       "vn 0 1 0\nf 1/1/1 4/4/1 3/3/1\nf 1/1/1 3/3/1 2/2/1\n";
  const auto refused = test::runCli("lightmap '" + dir + "/floor.obj' -o '" + dir + "/big' --size 16384 --products "
                                    "ao,transport --order 8 --quiet");
  INFO(refused.output);
  CHECK(refused.exitCode == 2);
  CHECK_THAT(refused.output, Catch::StartsWith("prtbake: error: --size: a lightmap of 16384x16384 texels with ao,transport "
                                               "at order 8 needs about ") && Catch::Contains("GiB at its peak, more than the"));
  CHECK_FALSE(test::fileExists(dir + "/big"));
  struct Bake {
    unsigned products;
    int size, order;
  };
  for (const Bake& b : {Bake{kLightmapAo, 512, 3}, Bake{kLightmapAo | kLightmapBent, 1024, 3},
                        Bake{kLightmapTransport, 1024, 6}}) {
    LightmapOptions o;
    o.products = b.products, o.order = b.order;
    const double estimate = lightmapPeakBytes(o, b.size, b.size);
    const auto r = test::runCliMeasured({"lightmap", dir + "/floor.obj", "-o", dir + "/m", "--size", std::to_string(b.size),
                                         "--products", lightmapProductsName(b.products), "--order", std::to_string(b.order),
                                         "--samples", "4", "--quiet"},
                                        dir + "/run.txt");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    const double peak = r.peakMiB * 1048576;
    INFO(lightmapProductsName(b.products) << " at " << b.size << "²: peak " << peak / 1048576 << " MiB, estimate "
                                          << estimate / 1048576 << " MiB");
    CHECK(peak <= estimate);
    CHECK(peak >= estimate / 4);
  }
}

TEST_CASE("Lightmap: the preview shows each product on the mesh where its UV reads it, beside the atlas", "[lightmap][preview]") {
  // The floor z = 0 over [−1, 1]², facing the front view's camera (+z; screen up +y, right +x),
  // its UVs u = (x + 1)/2, v = (1 − y)/2. Synthetic 32² maps whose values are linear in the UV,
  // which bilinear filtering reproduces exactly: ao = v at texel centres, so the view reads v
  // (larger down the image); bent's x = 2u − 1, shown R = sRGB⁻¹(u) (larger to the right);
  // sh (L1) with D_2 = 1 alone, shaded along n = +z: Y_2(+z) = √(3/4π) everywhere.
  Mesh m;
  addFloor(m, 1, {0, 0, 1, 1});
  const int W = 32;
  LightmapResult lm;
  lm.width = lm.height = W;
  lm.uvSet = 0;
  lm.products = kLightmapAo | kLightmapBent | kLightmapSh;
  lm.shOrder = 2;
  lm.state.assign(size_t(W) * W, uint8_t(TexelState::Baked));
  lm.state[0] = uint8_t(TexelState::Empty);  // the atlas's top-left texel: dark blue
  lm.ao.resize(size_t(W) * W);
  lm.bent.assign(size_t(W) * W * 3, 0.0f);
  lm.sh.assign(size_t(W) * W * 12, 0.0f);
  for (int y = 0; y < W; ++y)
    for (int x = 0; x < W; ++x) {
      const size_t i = size_t(y) * W + x;
      lm.ao[i] = float((y + 0.5) / W);
      lm.bent[3 * i] = float(2 * (x + 0.5) / W - 1), lm.bent[3 * i + 2] = 1.0f;
      lm.sh[12 * i + 3 * 2 + 1] = 1.0f;  // D_2, green
    }
  MeshPreviewOptions view;
  view.width = 160, view.height = 120;
  const LinearImage img = renderLightmapPreview(test::runtime(), m, lm, view);
  REQUIRE(img.width == 160 + 120);
  REQUIRE(img.height == 3 * 120);
  auto at = [&](int x, int y, int c) { return double(img.rgb[3 * (size_t(y) * img.width + x) + c]); };
  auto srgbToLinear = [](double s) { return s <= 0.04045 ? s / 12.92 : std::pow((s + 0.055) / 1.055, 2.4); };
  const double background = double(0.18f);  // the mesh panel's background
  // The centre pixel looks at the floor's centre (the camera aims at the bounds' centre): v = 0.5
  // within half a pixel's footprint (2 units over < 0.9 × 120 pixels: 0.01 in v).
  CHECK(std::abs(at(80, 60, 0) - 0.5) < 0.01);
  CHECK(at(2, 60, 0) == Approx(background));  // beside the floor
  // Down the centre column, over the floor: non-decreasing, from the top edge's v to the bottom's.
  std::vector<double> column;
  for (int y = 0; y < 120; ++y)
    if (at(80, y, 0) != background) column.push_back(at(80, y, 0));
  REQUIRE(column.size() > 60);
  CHECK(std::is_sorted(column.begin(), column.end()));
  CHECK(column.front() < 0.1);
  CHECK(column.back() > 0.9);
  // bent: along the centre row, R = sRGB⁻¹(u) rising to the right, and B = sRGB⁻¹(1).
  std::vector<double> row;
  for (int x = 0; x < 160; ++x)
    if (at(x, 120 + 60, 2) != background) row.push_back(at(x, 120 + 60, 0));
  REQUIRE(row.size() > 60);
  CHECK(std::is_sorted(row.begin(), row.end()));
  CHECK(row.front() < srgbToLinear(0.1));
  CHECK(row.back() > srgbToLinear(0.9));
  CHECK(at(80, 120 + 60, 2) == Approx(1.0).margin(1e-6));
  // sh: the L1 band's z term along the floor's normal, at every floor pixel below the label (float sums: 1e-5).
  const double y2 = std::sqrt(3 / (4 * kPi));
  int floorPixels = 0;
  for (int y = 240; y < 360; ++y)
    for (int x = 0; x < 160; ++x)
      if (at(x, y, 0) != background || at(x, y, 1) != background) {
        ++floorPixels;
        if (std::abs(at(x, y, 1) - y2) > 1e-5 && y > 240 + 30) FAIL("sh pixel (" << x << ", " << y << ") = " << at(x, y, 1));
      }
  CHECK(floorPixels > 5000);
  // The atlas: nearest texel, rows top-down as the file's; the empty texel dark blue.
  CHECK(at(160 + 60, 60 + 2, 0) == Approx((W / 2 + 0.5) / W));
  CHECK(at(160 + 60, 118, 0) == Approx((W - 1 + 0.5) / W));
  CHECK(at(160 + 1, 24, 0) == Approx((24 * W / 120 + 0.5) / W));
  CHECK(at(160 + 1, 1, 2) == Approx(0.08));
  // A mesh without the lightmap's UV set: the mesh is named.
  lm.uvSet = 1;
  CHECK_THROWS_WITH(renderLightmapPreview(test::runtime(), m, lm, view), Catch::Contains("has no UV set 1"));

  // The command: a lightmap directory read back, and its errors.
  const std::string dir = test::tempDir("lightmap-preview");
  std::ofstream(dir + "/floor.obj") << "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 1 0\n"
                                       "f 1/1/1 4/4/1 3/3/1\nf 1/1/1 3/3/1 2/2/1\n";
  std::ofstream(dir + "/novt.obj") << "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nf 1 3 2\n";
  const auto bake = test::runCli("lightmap '" + dir + "/floor.obj' -o '" + dir + "/lm' --size 16 --samples 16 --products ao,bent --quiet");
  REQUIRE(bake.exitCode == 0);
  const LightmapResult back = readLightmap(dir + "/lm");
  CHECK(back.products == (kLightmapAo | kLightmapBent));
  CHECK(back.width == 16);
  CHECK(std::count(back.state.begin(), back.state.end(), uint8_t(TexelState::Baked)) == 256);
  const auto r = test::runCli("preview lightmap '" + dir + "/floor.obj' --lightmap '" + dir + "/lm' -o '" + dir +
                              "/p.png' --size 64x48 --view top");
  INFO(r.output);
  CHECK(r.exitCode == 0);
  CHECK(test::fileExists(dir + "/p.png"));
  const auto noDir = test::runCli("preview lightmap '" + dir + "/floor.obj' -o '" + dir + "/q.png'");
  CHECK(noDir.exitCode == 2);
  CHECK(noDir.output.find("--lightmap DIR") != std::string::npos);
  const auto empty = test::runCli("preview lightmap '" + dir + "/floor.obj' --lightmap '" + dir + "' -o '" + dir + "/q.png'");
  CHECK(empty.exitCode == 1);
  CHECK(empty.output.find("lightmap.json") != std::string::npos);
  const auto noUv = test::runCli("preview lightmap '" + dir + "/novt.obj' --lightmap '" + dir + "/lm' -o '" + dir + "/q.png'");
  CHECK(noUv.exitCode == 1);
  CHECK(noUv.output.find("novt.obj: has no UV set 0") != std::string::npos);
  CHECK_FALSE(test::fileExists(dir + "/q.png"));
}

TEST_CASE("Lightmap: three.js and Babylon.js render the AO and the irradiance lightmap on uv1 as prtbake samples them",
          "[lightmap][engines][chromium]") {
  // The wall scene of the leak test as a real glTF: TEXCOORD_0 tiles the floor 4 times and gives
  // every face of the wall the whole square (overlapping: a texture's UVs), TEXCOORD_1 is the
  // lightmap's. Baked through the library, written by the command's writers.
  Mesh m;
  addQuad(m, std::array<Vec3, 4>{Vec3{-1, -1, 0}, Vec3{1, -1, 0}, Vec3{1, 1, 0}, Vec3{-1, 1, 0}}.data(), {0, 0, 1, 0.5});
  addBox(m, {0.04, -0.5, -0.05}, {0.135, 0.7, 0.6}, {0, 0.6, 1, 0.9});
  std::vector<float> uv0;
  for (size_t v = 0; v < m.vertexCount(); ++v) {
    const bool floor = v < 4;
    uv0.push_back(floor ? 2 * (m.positions[3 * v] + 1) : float((v % 4 == 1 || v % 4 == 2) ? 1 : 0));
    uv0.push_back(floor ? 2 * (1 - m.positions[3 * v + 1]) : float(v % 4 >= 2 ? 0 : 1));
  }
  const std::string dir = test::tempDir("lightmap_threejs");
  const std::string input = writeTwoUvGltf(dir, m, uv0);
  const Mesh mesh = loadMesh(input);
  REQUIRE(mesh.hasUvSet(1));
  // glTF-Validator: the copy has no issue of any severity (seen failing: occlusionTexture's
  // texCoord 2, which no primitive has: MATERIAL_... error).
  const std::string js = std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/";
  PRTBAKE_CHROMIUM_OR_SKIP(chromium, "three.js");
  // An environment brighter above than below (l_0 and l_{1,0} along +z), so that irradiance is
  // not a multiple of the AO: L(ω) = 0.55 + 0.35 ω_z, E/π between 0 and 0.9.
  ShCoeffs env;
  env.order = 2;
  env.rgb.assign(4, Rgb{0, 0, 0});
  const double c0 = 0.55 * std::sqrt(4 * kPi), c1 = 0.35 * std::sqrt(4 * kPi / 3);
  env.rgb[0] = Rgb{c0, c0, c0};
  double y[4];
  shEval(2, 0, 0, 1, y);
  env.rgb[2] = Rgb{c1 * y[2] / std::abs(y[2]), c1 * y[2] / std::abs(y[2]), c1 * y[2] / std::abs(y[2])};
  LightmapOptions o;
  o.size = 64;
  o.samples = 256;
  o.products = kLightmapAo | kLightmapIrradiance;
  LightmapResult lm = computeLightmap(test::runtime(), mesh, env, o);
  REQUIRE(lm.uvSet == 1);
  // The copies: prtbake's, the AO flipped vertically (an exporter's bottom-up rows), and one whose
  // occlusionTexture names TEXCOORD_0.
  std::ofstream(dir + "/good.glb", std::ios::binary) << lightmapGltfBytes(dir + "/good.glb", mesh, lm);
  LightmapResult flipped = lm;
  for (int yy = 0; yy < lm.height; ++yy)
    for (int x = 0; x < lm.width; ++x) {
      flipped.ao[size_t(yy) * lm.width + x] = lm.ao[size_t(lm.height - 1 - yy) * lm.width + x];
      for (int c = 0; c < 3; ++c)
        flipped.irradiance[3 * (size_t(yy) * lm.width + x) + c] = lm.irradiance[3 * (size_t(lm.height - 1 - yy) * lm.width + x) + c];
    }
  std::ofstream(dir + "/v_flipped.glb", std::ios::binary) << lightmapGltfBytes(dir + "/v_flipped.glb", mesh, flipped);
  LightmapResult wrongSet = lm;
  wrongSet.uvSet = 0;
  std::ofstream(dir + "/uv0.glb", std::ios::binary) << lightmapGltfBytes(dir + "/uv0.glb", mesh, wrongSet);
  std::ofstream(dir + "/irradiance.ktx2", std::ios::binary) << lightmapKtx2Bytes(lm, kLightmapIrradiance);
  std::ofstream(dir + "/irradiance_flipped.ktx2", std::ios::binary) << lightmapKtx2Bytes(flipped, kLightmapIrradiance);
  {
    const test::CliResult r = test::runShell("node '" + js + "gltf_validate.mjs' '" + dir + "/good.glb'");
    INFO(r.output.substr(0, 3000));
    REQUIRE(r.exitCode == 0);
    const nlohmann::json rep = nlohmann::json::parse(r.output);
    CHECK(rep["errors"] == 0);
    CHECK(rep["warnings"] == 0);
  }
  const int W = 192;
  const std::string page = dir + "/lightmap.html";
  auto render = [&](int lightChannel) {
    std::ofstream(page) << test::fillPage(kLightmapPage, {{"__THREE__", std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/node_modules/three"},
                                                          {"__JS__", std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js"},
                                                          {"__W__", std::to_string(W)},
                                                          {"__COPIES__", lightChannel == 1 ? R"(["good", "v_flipped", "uv0"])" : "[]"},
                                                          {"__PLAIN__", "good"},
                                                          {"__LIGHTS__", lightChannel == 1 ? R"(["irradiance", "irradiance_flipped"])" : R"(["irradiance"])"},
                                                          {"__LIGHT_CHANNEL__", std::to_string(lightChannel)}});
    return test::chromiumResult(chromium, page)["shots"];
  };
  const nlohmann::json shots = render(1), wrongChannel = render(0);
  // prtbake's side: the floor point under each pixel's centre, its lightmap UV (the floor quad maps
  // x ∈ [−1, 1] to u ∈ [0, 1] and y ∈ [1, −1] to v ∈ [0, 0.5]), the maps sampled bilinearly.
  // Pixels over the wall's top (and one pixel around it) are left out.
  auto mean = [&](const nlohmann::json& red, const std::vector<float>& plane, int c, double scale) {
    double sum = 0;
    int n = 0;
    for (int py = 0; py < W; ++py)
      for (int px = 0; px < W; ++px) {
        const double x = -1 + 2 * (px + 0.5) / W, yw = -1 + 2 * (py + 0.5) / W;
        if (x > 0.04 - 2.0 / W && x < 0.135 + 2.0 / W && yw > -0.5 - 2.0 / W && yw < 0.7 + 2.0 / W) continue;
        const double u = (x + 1) / 2, v = 0.5 * (1 - yw) / 2;
        const double want = scale * bilinear(plane, lm.width, c, 0, u, v);
        sum += 255 * std::abs(red[size_t(py) * W + px].get<double>() - want);
        ++n;
      }
    return sum / n;
  };
  const double ao = mean(shots["good"], lm.ao, 1, 1), aoFlipped = mean(shots["v_flipped"], lm.ao, 1, 1),
               aoUv0 = mean(shots["uv0"], lm.ao, 1, 1);
  const double light = mean(shots["light:irradiance"], lm.irradiance, 3, 1),
               lightFlipped = mean(shots["light:irradiance_flipped"], lm.irradiance, 3, 1),
               lightUv0 = mean(wrongChannel["light:irradiance"], lm.irradiance, 3, 1);
  // Acceptance: mean |Δ| ≤ 2 linear 8-bit levels (the AO's PNG is 8-bit: ≤ 0.5 of that is its
  // rounding; the irradiance's KTX2 is half float; the GPU's filter weights are 8-bit fixed point).
  INFO("mean |delta| (linear 8-bit levels): AO " << ao << " (V flipped " << aoFlipped << ", TEXCOORD_0 " << aoUv0
                                                << "); irradiance " << light << " (V flipped " << lightFlipped
                                                << ", uv0 " << lightUv0 << ")");
  CHECK(ao <= 2.0);
  CHECK(light <= 2.0);
  CHECK(aoFlipped > 2.0);
  CHECK(aoUv0 > 2.0);
  CHECK(lightFlipped > 2.0);
  CHECK(lightUv0 > 2.0);

  // Babylon.js: the same glTF through Babylon's glTF loader, the AO's PNG (8-bit, as the command
  // writes it) as a StandardMaterial's lightmapTexture used as a shadow map, the irradiance's
  // OpenEXR (float) added, both on coordinatesIndex 1 (TEXCOORD_1) and read by Babylon's own
  // texture loaders with invertY false; the flipped files and coordinatesIndex 0 must fail.
  std::ofstream(dir + "/ao.png", std::ios::binary) << lightmapAoPngBytes(lm, 8);
  std::ofstream(dir + "/ao_flipped.png", std::ios::binary) << lightmapAoPngBytes(flipped, 8);
  std::ofstream(dir + "/irradiance.exr", std::ios::binary) << lightmapExrBytes(lm, kLightmapIrradiance, false);
  std::ofstream(dir + "/irradiance_flipped.exr", std::ios::binary) << lightmapExrBytes(flipped, kLightmapIrradiance, false);
  std::ofstream(page) << test::fillPage(
      test::readText(js + "babylon_lightmap.html"),
      {{"__JS__", std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js"},
       {"__W__", std::to_string(W)},
       {"__GLTF__", "./good.glb"},
       {"__SHOTS__", R"([{"name": "ao", "file": "./ao.png", "shadowmap": true, "channel": 1},
                      {"name": "ao_flipped", "file": "./ao_flipped.png", "shadowmap": true, "channel": 1},
                      {"name": "ao_uv0", "file": "./ao.png", "shadowmap": true, "channel": 0},
                      {"name": "light", "file": "./irradiance.exr", "shadowmap": false, "channel": 1, "flipV": true},
                      {"name": "light_flipped", "file": "./irradiance_flipped.exr", "shadowmap": false, "channel": 1, "flipV": true},
                      {"name": "light_uv0", "file": "./irradiance.exr", "shadowmap": false, "channel": 0, "flipV": true},
                      {"name": "light_no_vscale", "file": "./irradiance.exr", "shadowmap": false, "channel": 1}])"}});
  const nlohmann::json bab = test::chromiumResult(chromium, page)["shots"];
  const double bAo = mean(bab["ao"], lm.ao, 1, 1), bAoFlipped = mean(bab["ao_flipped"], lm.ao, 1, 1),
               bAoUv0 = mean(bab["ao_uv0"], lm.ao, 1, 1), bLight = mean(bab["light"], lm.irradiance, 3, 1),
               bLightFlipped = mean(bab["light_flipped"], lm.irradiance, 3, 1),
               bLightUv0 = mean(bab["light_uv0"], lm.irradiance, 3, 1),
               bLightNoVScale = mean(bab["light_no_vscale"], lm.irradiance, 3, 1);
  // The same 2-level bound (Babylon's canvas is read back in 8 bits: ≤ 0.5 level more).
  INFO("Babylon.js, mean |delta| (linear 8-bit levels): AO " << bAo << " (V flipped " << bAoFlipped << ", uv0 " << bAoUv0
                                                            << "); irradiance " << bLight << " (V flipped " << bLightFlipped
                                                            << ", uv0 " << bLightUv0 << ", without the V flip "
                                                            << bLightNoVScale << ")");
  CHECK(bAo <= 2.0);
  CHECK(bLight <= 2.0);
  CHECK(bAoFlipped > 2.0);
  CHECK(bAoUv0 > 2.0);
  CHECK(bLightFlipped > 2.0);
  CHECK(bLightUv0 > 2.0);
  CHECK(bLightNoVScale > 2.0);  // Babylon's EXR rows are bottom-up: the V flip docs/lightmap.md gives is needed
}

TEST_CASE("Lightmap: real files: texture UVs whose charts overlap are refused, a real box's bake", "[lightmap][data]") {
  // Files nobody here made. The Duck's and Mary's only UV sets are texture UVs (charts share
  // texels: a texture atlas, not a lightmap): refused in one line naming the file and the texel,
  // exit 1, nothing written. BoxTextured's UV set 0 holds its six faces apart: it bakes, and the
  // box is convex, so every texel takes the closed form of an unoccludable point: AO 1.
  const std::string duck = test::dataFile("meshes/gltf/Duck.glb"), mary = test::dataFile("meshes/obj/mary.obj"),
                    box = test::dataFile("meshes/gltf/BoxTextured.glb");
  PRTBAKE_SKIP_IF_NO_DATA(duck);
  PRTBAKE_SKIP_IF_NO_DATA(mary);
  PRTBAKE_SKIP_IF_NO_DATA(box);
  const std::string dir = test::tempDir("lightmap-real");
  for (const std::string& f : {duck, mary}) {
    const auto r = test::runCli("lightmap '" + f + "' -o '" + dir + "/out' --size 256 --samples 16 --uv 0");
    INFO(r.output);
    CHECK(r.exitCode == 1);
    CHECK(r.output.find(f + ": UV charts overlap: texel (") != std::string::npos);
    CHECK_FALSE(test::fileExists(dir + "/out"));
  }
  const auto ok = test::runCli("lightmap '" + box + "' -o '" + dir + "/box' --size 64 --samples 16 --gltf '" + dir +
                               "/box.glb'");
  INFO(ok.output);
  REQUIRE(ok.exitCode == 0);
  const ExrImage ao = readExr(dir + "/box/ao.exr");
  size_t valid = 0;
  float lowest = 1;
  for (size_t i = 0; i < ao.channel("A")->size(); ++i)
    if ((*ao.channel("A"))[i] == 1.0f) ++valid, lowest = std::min(lowest, (*ao.channel("Y"))[i]);
  CHECK(valid > 1000);
  CHECK(lowest > 1.0f - 1e-6f);  // float: 2√π T_0 of the closed form
  if (test::nodeReady()) {
    const test::CliResult r = test::runShell("node '" + std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/gltf_validate.mjs' '" +
                                             dir + "/box.glb'");
    INFO(r.output.substr(0, 3000));
    REQUIRE(r.exitCode == 0);
    const nlohmann::json rep = nlohmann::json::parse(r.output);
    CHECK(rep["errors"] == 0);
  } else {
    test::skipPart("tests/js/node_modules absent: glTF-Validator not run on the real box's copy");
  }
}
