// Light probe grids (prtbake/probes.h) against closed forms: an empty scene, a closed room,
// probes above a disk (Funk–Hecke), relocation and fill of probes inside geometry, and the
// bounces' convergence.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>

#include <nlohmann/json.hpp>

#include "prtbake/error.h"
#include "prtbake/preview.h"
#include "prtbake/probes.h"
#include "prtbake/sh.h"
#include "job_test_helpers.h"
#include "test_common.h"

using namespace prtbake;

namespace {

constexpr double kPi = 3.14159265358979323846;

// A quad p0 p1 p2 p3 (counter-clockwise seen from its front) as two triangles, albedo a.
void addQuad(Mesh& m, const std::array<double, 3>* p, double albedo = 1.0) {
  const uint32_t base = uint32_t(m.vertexCount());
  const double e1[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
  const double e2[3] = {p[3][0] - p[0][0], p[3][1] - p[0][1], p[3][2] - p[0][2]};
  double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
  const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  for (int v = 0; v < 4; ++v)
    for (int a = 0; a < 3; ++a) {
      m.positions.push_back(float(p[v][a]));
      m.normals.push_back(float(n[a] / len));
      m.albedo.push_back(float(albedo));
    }
  for (uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) m.indices.push_back(base + i);
}

// The box [lo, hi]³ with its faces' fronts inside (a room) or outside (a solid block).
Mesh makeBox(double lo, double hi, bool inward, double albedo = 1.0) {
  Mesh m;
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      std::array<double, 3> p[4];
      const double c[4][2] = {{lo, lo}, {hi, lo}, {hi, hi}, {lo, hi}};
      for (int k = 0; k < 4; ++k) {
        p[k][axis] = side ? hi : lo;
        p[k][u] = c[k][0], p[k][v] = c[k][1];
      }
      // (u, v) counter-clockwise faces +axis; flip for the low side; flip again for inward.
      if ((side == 0) != inward) std::swap(p[1], p[3]);
      addQuad(m, p, albedo);
    }
  return m;
}

// A disk of radius r in the plane y = 0, facing +y, as a fan of `segments` triangles.
Mesh makeDisk(double r, int segments) {
  Mesh m;
  m.positions = {0, 0, 0};
  m.normals = {0, 1, 0};
  m.albedo = {1, 1, 1};
  for (int s = 0; s < segments; ++s) {
    const double phi = 2 * kPi * s / segments;
    m.positions.insert(m.positions.end(), {float(r * std::cos(phi)), 0.0f, float(r * std::sin(phi))});
    m.normals.insert(m.normals.end(), {0, 1, 0});
    m.albedo.insert(m.albedo.end(), {1, 1, 1});
    // Counter-clockwise seen from +y: centre, next, this.
    m.indices.insert(m.indices.end(), {0u, uint32_t(1 + (s + 1) % segments), uint32_t(1 + s)});
  }
  return m;
}

// A constant white environment, L = 1: l_0 = √(4π).
ShCoeffs white(int order = 3) {
  ShCoeffs c;
  c.order = order;
  c.rgb.assign(size_t(order) * order, Rgb{0, 0, 0});
  c.rgb[0] = Rgb{std::sqrt(4 * kPi), std::sqrt(4 * kPi), std::sqrt(4 * kPi)};
  return c;
}

// A coloured, directional environment of order 3 (every coefficient non-zero).
ShCoeffs sky() {
  ShCoeffs c = white(3);
  for (int i = 1; i < 9; ++i) c.rgb[i] = Rgb{0.3 * std::sin(1.0 + i), 0.2 * std::cos(2.0 * i), 0.25 * std::sin(0.5 * i)};
  return c;
}

}  // namespace

TEST_CASE("Probes: an empty scene gives the environment's coefficients at every probe", "[probes]") {
  Mesh empty;
  ProbeOptions o;
  o.resolution = std::array<int, 3>{3, 2, 4};
  o.boundsMin = std::array<double, 3>{-1, 0, 2};
  o.boundsMax = std::array<double, 3>{2, 1, 5};
  o.requireGeometry = false;
  for (int order : {2, 3}) {
    o.order = order;
    const ShCoeffs env = sky();
    const ProbeGridResult g = computeProbeGrid(test::runtime(), empty, env, o);
    REQUIRE(g.coeffs.size() == 24u * order * order * 3);
    // Float precision: the quadrature is exact for these products; the float sums of a few
    // hundred terms of size ≤ 4π |L| keep about 1e-6 of the largest coefficient.
    double worst = 0;
    for (size_t p = 0; p < 24; ++p)
      for (int i = 0; i < order * order; ++i)
        for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(g.probe(p)[3 * i + c] - env.rgb[i][c]));
    INFO("order " << order << ": largest |P - l| " << worst);
    CHECK(worst < 1e-5);
    CHECK(g.moved == 0);
    CHECK(g.invalid == 0);
  }
}

TEST_CASE("Probes: a probe inside a closed room sees none of the environment", "[probes]") {
  const Mesh room = makeBox(-1, 1, true);
  ProbeOptions o;
  o.resolution = std::array<int, 3>{3, 3, 3};
  o.boundsMin = std::array<double, 3>{-0.9, -0.9, -0.9};
  o.boundsMax = std::array<double, 3>{0.9, 0.9, 0.9};
  o.bounces = 0;
  const ProbeGridResult g = computeProbeGrid(test::runtime(), room, sky(), o);
  double worst = 0;
  for (float v : g.coeffs) worst = std::max(worst, double(std::abs(v)));
  CHECK(worst == 0.0);  // every ray hits a front face: exactly nothing is added
  CHECK(g.invalid == 0);
  // The same room seen from outside its walls (a solid block): every ray of the centre probe hits
  // a back face, and no free point lies within reach: invalid.
  const Mesh block = makeBox(-1, 1, false);
  o.resolution = std::array<int, 3>{1, 1, 1};
  const ProbeGridResult b = computeProbeGrid(test::runtime(), block, sky(), o);
  CHECK(b.invalid == 1);
  CHECK(b.backfaceFraction[0] > o.backfaceLimit);  // its trace stops there: all it needs to know
}

TEST_CASE("Probes: above a disk, the unoccluded sphere's projection (Funk-Hecke)", "[probes]") {
  // Probes at heights h above a disk of radius R facing them (bounces 0: the disk is black)
  // under the environment l. The disk covers the cap of half-angle α around −y, cos α = h/√(h²+R²);
  // the probe sees l minus the cap's projection of the environment's radiance. For the constant
  // white environment (L = 1): P_i = √(4π) δ_i0 − λ_l Y_i(−y), λ_0 = 2π(1 − c), λ_1 = π(1 − c²),
  // λ_2 = π c (1 − c²) (Funk–Hecke with the cap's indicator), c = cos α.
  const double R = 1.0;
  const int segments = 720;  // the polygon's area is within 1.3e-5 of the disk's
  const Mesh disk = makeDisk(R, segments);
  ProbeOptions o;
  o.resolution = std::array<int, 3>{1, 4, 1};
  o.boundsMin = std::array<double, 3>{-0.05, 0.0, -0.05};
  o.boundsMax = std::array<double, 3>{0.05, 2.0, 0.05};
  o.bounces = 0;
  o.samples = 4096;
  o.relocateFraction = 0;
  for (int broken = 0; broken < 2; ++broken) {
    Mesh m = disk;
    if (broken) {  // the disk above the probes, facing down: the oracle must fail
      for (size_t t = 0; t < m.triangleCount(); ++t) std::swap(m.indices[3 * t + 1], m.indices[3 * t + 2]);
      for (size_t v = 0; v < m.vertexCount(); ++v) m.positions[3 * v + 1] = 2.0f, m.normals[3 * v + 1] = -1.0f;
    }
    const ProbeGridResult g = computeProbeGrid(test::runtime(), m, white(), o);
    double worstRatio = 0;
    for (int j = 0; j < 4; ++j) {
      const double h = g.positions[3 * j + 1];
      const double x = g.positions[3 * j], z = g.positions[3 * j + 2];
      (void)x, (void)z;  // the probes stand on the axis within 0.05 R: the cap's tilt is below 3°
      const double c = h / std::sqrt(h * h + R * R);
      const double lambda[3] = {2 * kPi * (1 - c), kPi * (1 - c * c), kPi * c * (1 - c * c)};
      double y[9];
      shEval(3, 0, -1, 0, y);
      // The error bound: the quadrature misjudges only the cells that the cap's rim crosses,
      // about 2π sin α / √(4π/N) of them, each worth at most its weight 4π/N times |Y| ≤ 0.63;
      // with independent signs (the per-probe rotation), 4 standard deviations of that sum. The
      // probe's offset from the axis (≤ 0.07) tilts the cap by under 3°: 0.05 of λ_1 · |Y_1| at most.
      const int N = g.samples;
      const double cells = 2 * kPi * std::sqrt(1 - c * c) / std::sqrt(4 * kPi / N);
      const double bound = 4 * std::sqrt(cells) * (4 * kPi / N) * 0.63 + 0.05 * lambda[1] * 0.49;
      for (int i = 0; i < 9; ++i) {
        const int l = i == 0 ? 0 : (i < 4 ? 1 : 2);
        const double expected = (i == 0 ? std::sqrt(4 * kPi) : 0.0) - lambda[l] * y[i];
        const double got = g.probe(j)[3 * i];
        worstRatio = std::max(worstRatio, std::abs(got - expected) / bound);
        if (!broken) INFO("h " << h << " coefficient " << i << ": " << got << " expected " << expected);
        if (!broken) CHECK(std::abs(got - expected) <= bound);
      }
    }
    if (broken) CHECK(worstRatio > 10);  // a back face is not a black front face: far outside the bound
  }
}

TEST_CASE("Probes: probes inside a solid block are moved out or filled from their neighbours", "[probes]") {
  // A solid block [−0.5, 0.5]³ (outward faces) in a 5×5×5 grid over [−1, 1]³ (cells 0.4, probes
  // at 0, ±0.4, ±0.8): 27 probes inside. Those at ±0.4 along some axis (0.1 from a face) move out
  // within 0.45 of a cell (0.18); the centre (0.5 from every face) cannot, and is filled.
  ProbeOptions o;
  o.resolution = std::array<int, 3>{5, 5, 5};
  o.boundsMin = std::array<double, 3>{-1, -1, -1};
  o.boundsMax = std::array<double, 3>{1, 1, 1};
  o.bounces = 0;
  o.samples = 128;
  const Mesh block = makeBox(-0.5, 0.5, false);
  const ProbeGridResult g = computeProbeGrid(test::runtime(), block, white(), o);
  CHECK(g.invalid == 1);
  CHECK(g.moved == 26);
  const auto idx = [](int x, int y, int z) { return size_t((z * 5 + y) * 5 + x); };
  CHECK(g.state[idx(2, 2, 2)] == 2);
  for (int z = 1; z <= 3; ++z)
    for (int y = 1; y <= 3; ++y)
      for (int x = 1; x <= 3; ++x) {
        const size_t i = idx(x, y, z);
        if (i == idx(2, 2, 2)) continue;
        INFO("probe " << x << "," << y << "," << z);
        CHECK(g.state[i] == 1);
        CHECK(g.backfaceFraction[i] <= o.backfaceLimit);
        // Moved out of the block by at most 0.45 of a cell.
        bool outside = false;
        double moved2 = 0;
        const auto p0 = g.layout.probePosition(x, y, z);
        for (int a = 0; a < 3; ++a) {
          outside = outside || std::abs(g.positions[3 * i + a]) > 0.5;
          moved2 += std::pow(g.positions[3 * i + a] - p0[a], 2);
        }
        CHECK(outside);
        CHECK(std::sqrt(moved2) <= 0.45 * 0.4 + 1e-6);
      }
  // The invalid centre holds the mean of its six moved neighbours.
  const size_t centre = idx(2, 2, 2), nc = 27;
  for (size_t k = 0; k < nc; ++k) {
    double mean = 0;
    for (size_t j : {idx(1, 2, 2), idx(3, 2, 2), idx(2, 1, 2), idx(2, 3, 2), idx(2, 2, 1), idx(2, 2, 3)})
      mean += g.coeffs[j * nc + k] / 6;
    CHECK(std::abs(g.coeffs[centre * nc + k] - mean) < 1e-5);
  }
  // Without relocation all 27 are invalid and filled, from the rim inwards (2 passes).
  o.relocateFraction = 0;
  const ProbeGridResult f = computeProbeGrid(test::runtime(), block, white(), o);
  CHECK(f.invalid == 27);
  CHECK(f.moved == 0);
  CHECK(f.fillPasses == 2);
}

TEST_CASE("Probes: interreflection converges with bounces", "[probes]") {
  // A room open at the top (five inward faces, albedo 0.5) under the white sky: each bounce adds
  // light seen off the walls, at most ρ times the last one's.
  Mesh room = makeBox(-1, 1, true, 0.5);
  // Drop the ceiling (+y face: the fourth quad, axis 1 side 1): its two triangles.
  room.indices.erase(room.indices.begin() + 3 * 6, room.indices.begin() + 4 * 6);
  ProbeOptions o;
  o.resolution = std::array<int, 3>{2, 2, 2};
  o.boundsMin = std::array<double, 3>{-0.8, -0.8, -0.8};
  o.boundsMax = std::array<double, 3>{0.8, 0.8, 0.8};
  o.samples = 512;
  o.transportSamples = 512;
  std::vector<double> p0;
  for (int b = 0; b <= 4; ++b) {
    o.bounces = b;
    const ProbeGridResult g = computeProbeGrid(test::runtime(), room, white(), o);
    p0.push_back(g.probe(0)[0]);
  }
  for (int b = 1; b <= 4; ++b) {
    INFO("bounces " << b << ": P_00 " << p0[b] << " after " << p0[b - 1]);
    CHECK(p0[b] > p0[b - 1]);
    // The k-th bounce's light is at most ρ^k of the sky's (walls lit by at most the sky, ×ρ per
    // bounce); 10 % for the transport's and the probes' sampling noise.
    if (b >= 2) CHECK(p0[b] - p0[b - 1] <= 0.5 * (p0[b - 1] - p0[b - 2]) * 1.1);
  }
}

TEST_CASE("Probes: bad grids are refused with one line", "[probes]") {
  const Mesh room = makeBox(-1, 1, true);
  ProbeOptions o;
  o.boundsMin = std::array<double, 3>{0, 0, 0};
  o.boundsMax = std::array<double, 3>{1, -1, 1};
  CHECK_THROWS_AS(computeProbeGrid(test::runtime(), room, white(), o), UsageError);
  o.boundsMax = std::array<double, 3>{1, 1, 1};
  o.resolution = std::array<int, 3>{0, 4, 4};
  CHECK_THROWS_AS(computeProbeGrid(test::runtime(), room, white(), o), UsageError);
  o.resolution = std::array<int, 3>{1024, 1024, 1024};
  CHECK_THROWS_AS(computeProbeGrid(test::runtime(), room, white(), o), UsageError);
  o.resolution = std::array<int, 3>{2, 2, 2};
  o.boundsMin = std::array<double, 3>{5, 5, 5};
  o.boundsMax = std::array<double, 3>{6, 6, 6};
  CHECK_THROWS_AS(computeProbeGrid(test::runtime(), room, white(), o), InputError);
}

TEST_CASE("prtbake probes: bad grids get one line and no output, and a job writes the command bytes", "[probes][cli]") {
  const std::string dir = test::tempDir("probes-cli");
  const std::string scene = std::string(PRTBAKE_TEST_SOURCE_DIR) + "/../assets/scene.gltf";
  struct Bad {
    std::string args, message;
    int exitCode;
  };
  const Bad bad[] = {
      {"--bounds 0,0,0,1,-1,1", "--bounds: empty or inverted along y", 2},
      {"--bounds 0,0,0,1,1", "--bounds: expected 6 numbers", 2},
      {"--resolution 0,4,4", "--resolution: 0 is out of range", 2},
      {"--resolution 2000,4,4", "--resolution: 2000 is out of range", 2},
      {"--resolution 1024,1024,8", "probes is over the limit", 2},
      {"--resolution 4,4", "--resolution: expected 3 integers", 2},
      {"--bounds 50,50,50,60,60,60", "no geometry inside the probes' bounds", 1},
      {"--order 4", "--order: 4 is out of range", 2},
      {"--samples 0", "--samples: 0 is out of range", 2},
      {"--env " + dir + "/missing.json", "missing.json", 1},
  };
  for (const Bad& b : bad) {
    const test::CliResult r = test::runCli("probes '" + scene + "' -o '" + dir + "/out' " + b.args);
    INFO(b.args << ": exit " << r.exitCode << ": " << r.output);
    CHECK(r.exitCode == b.exitCode);
    CHECK(r.output.find(b.message) != std::string::npos);
    CHECK(std::count(r.output.begin(), r.output.end(), '\n') == 1);
    CHECK_FALSE(test::fileExists(dir + "/out"));
  }
  // The command and a job of the same parameters write the same coefficients.
  const std::string args = " --resolution 4,2,4 --samples 64 --bounces 1 --transport-samples 64";
  const test::CliResult cli = test::runCli("probes '" + scene + "' -o '" + dir + "/cli'" + args + " --quiet");
  REQUIRE(cli.exitCode == 0);
  std::ofstream(dir + "/job.json") << nlohmann::json{
      {"jobs", {{{"id", "grid"}, {"type", "probes"}, {"input", scene}, {"resolution", {4, 2, 4}}, {"samples", 64},
                 {"transport_samples", 64}, {"outputs", {{"npy", "job/probes.npy"}, {"json", "job/probes.json"}}}}}}}
                                          .dump();
  const test::CliResult run = test::runCli("run '" + dir + "/job.json' --quiet");
  INFO(run.output);
  REQUIRE(run.exitCode == 0);
  const auto bytes = [](const std::string& p) { return test::readText(p); };
  const std::string a = bytes(dir + "/cli/probes.npy"), b = bytes(dir + "/job/probes.npy");
  CHECK(a.size() == 128 + 32 * 9 * 3 * 4);
  CHECK(a == b);
}

TEST_CASE("Probes: the packet kernel and the one-ray kernel agree", "[probes]") {
  // A room open to the sky (no ceiling: a closed one would leave every coefficient 0, and the
  // comparisons below empty) with a solid block in it (moved and filled probes too), lit with
  // one bounce.
  Mesh scene = makeBox(-1, 1, true, 0.6);
  std::vector<uint32_t> walls;
  for (size_t t = 0; t < scene.triangleCount(); ++t) {
    bool ceiling = true;
    for (int c = 0; c < 3; ++c) ceiling = ceiling && scene.positions[3 * scene.indices[3 * t + c] + 1] > 0.99f;
    if (!ceiling) walls.insert(walls.end(), &scene.indices[3 * t], &scene.indices[3 * t] + 3);
  }
  scene.indices = walls;
  appendMesh(scene, makeBox(-0.35, 0.25, false, 0.8));
  ProbeOptions o;
  o.resolution = std::array<int, 3>{4, 3, 5};
  o.samples = 200;
  o.transportSamples = 64;
  o.packetWidth = 0;
  const ProbeGridResult a = computeProbeGrid(test::runtime(), scene, sky(), o);
  o.packetWidth = 16;
  const ProbeGridResult b = computeProbeGrid(test::runtime(), scene, sky(), o);
  // A GPU's group size (Runtime::loopGroupSize) gives the same bytes, in both forms (60 probes:
  // the last group part-filled).
  const auto grouped = test::runtimeWithGroupSize("64");
  CHECK(computeProbeGrid(*grouped, scene, sky(), o).coeffs == b.coeffs);
  o.packetWidth = 0;
  CHECK(computeProbeGrid(*grouped, scene, sky(), o).coeffs == a.coeffs);
  REQUIRE(a.coeffs.size() == b.coeffs.size());
  CHECK(a.state == b.state);
  CHECK(a.moved > 0);
  // The same rays and hits; float sums in another order: 1e-5 of the largest coefficient. A hit
  // decided differently at a shared edge would differ by a whole ray's weight (≈ 0.06 · |L|).
  double worst = 0, largest = 0;
  for (size_t i = 0; i < a.coeffs.size(); ++i)
    worst = std::max(worst, double(std::abs(a.coeffs[i] - b.coeffs[i]))), largest = std::max(largest, double(std::abs(a.coeffs[i])));
  INFO("largest |difference| " << worst << " of " << largest);
  CHECK(largest > 0.1);  // the sky reaches the probes
  CHECK(worst <= 1e-5 * largest);
  // 32 work-items per probe (a GPU's default, kernels/lanes.clh): the same rays, their sums in a
  // fixed tree, so against one work-item the same tolerance, and any group size the same bytes.
  o.packetWidth = 0, o.rayLanes = 32;
  const ProbeGridResult c = computeProbeGrid(test::runtime(), scene, sky(), o);
  CHECK(computeProbeGrid(*grouped, scene, sky(), o).coeffs == c.coeffs);
  REQUIRE(c.coeffs.size() == a.coeffs.size());
  CHECK(c.state == a.state);
  double worstLanes = 0;
  for (size_t i = 0; i < a.coeffs.size(); ++i) worstLanes = std::max(worstLanes, double(std::abs(a.coeffs[i] - c.coeffs[i])));
  INFO("32 lanes: largest |difference| " << worstLanes << " of " << largest);
  CHECK(worstLanes <= 1e-5 * largest);
  o.rayLanes = 3;
  CHECK_THROWS_AS(computeProbeGrid(test::runtime(), scene, sky(), o), UsageError);
}

TEST_CASE("A split probes job: shards then merge give the whole run's bytes", "[probes][cli]") {
  // The demo scene with a solid block reaching into the grid, so that shards relocate probes
  // (each probe's rays depend on its grid index only) and leave invalid ones to the merge's fill.
  const std::string dir = test::tempDir("probes-split");
  Mesh scene = loadMesh(std::string(PRTBAKE_TEST_SOURCE_DIR) + "/../assets/scene.gltf");
  appendMesh(scene, makeBox(-1.2, 0.6, false, 0.7));
  {
    std::ofstream obj(dir + "/scene.obj");
    for (size_t v = 0; v < scene.vertexCount(); ++v)
      obj << "v " << scene.positions[3 * v] << ' ' << scene.positions[3 * v + 1] << ' ' << scene.positions[3 * v + 2] << '\n';
    for (size_t t = 0; t < scene.triangleCount(); ++t)
      obj << "f " << scene.indices[3 * t] + 1 << ' ' << scene.indices[3 * t + 1] + 1 << ' ' << scene.indices[3 * t + 2] + 1 << '\n';
  }
  auto job = [&](const std::string& id, const std::string& out, bool split) {
    nlohmann::json j = {{"id", id}, {"type", "probes"}, {"input", "scene.obj"}, {"resolution", {6, 3, 5}},
                        {"samples", 64}, {"transport_samples", 32},
                        {"outputs", {{"npy", out + "/probes.npy"}, {"json", out + "/probes.json"},
                                     {"ktx2", out + "/probes.ktx2"}, {"js", out + "/probes.mjs"}}}};
    if (split) j["split"] = true;
    return j;
  };
  std::ofstream(dir + "/jobs.json") << nlohmann::json{{"jobs", {job("split", "s", true), job("whole", "w", false)}}}.dump();
  for (int i = 0; i < 3; ++i) {
    const auto r = test::runCli("run '" + dir + "/jobs.json' --shard " + std::to_string(i) + "/3 --quiet");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
  }
  const auto m = test::runCli("merge '" + dir + "/jobs.json' --shards 3");
  INFO(m.output);
  REQUIRE(m.exitCode == 0);
  const auto bytes = [](const std::string& p) { return test::readText(p); };
  const std::string whole = bytes(dir + "/w/probes.npy");
  REQUIRE(whole.size() == 128 + 90 * 27 * 4);
  CHECK(bytes(dir + "/s/probes.npy") == whole);
  CHECK(bytes(dir + "/s/probes.ktx2") == bytes(dir + "/w/probes.ktx2"));
  const auto sidecar = nlohmann::json::parse(bytes(dir + "/s/probes.json"));
  const auto wholeSidecar = nlohmann::json::parse(bytes(dir + "/w/probes.json"));
  CHECK(sidecar["validity"]["moved_probes"] == wholeSidecar["validity"]["moved_probes"]);
  CHECK(sidecar["validity"]["invalid_probes"] == wholeSidecar["validity"]["invalid_probes"]);
  CHECK(wholeSidecar["validity"]["moved"].get<int>() > 0);
  CHECK(wholeSidecar["validity"]["invalid"].get<int>() > 0);
}

TEST_CASE("Probes: the preview's slice runs x to the right and z downwards", "[probes][preview]") {
  // A roof (a square facing down, at y = 0.9) over the quarter x > 0, z > 0 of a floorless box of
  // probes (y 0 to 1, the slice at 0.5) under
  // the white sky: the slice's bottom-right quarter is the darkest, its top-left the brightest.
  Mesh roof;
  std::array<double, 3> q[4] = {{0, 0.9, 0}, {0, 0.9, 1.2}, {1.2, 0.9, 1.2}, {1.2, 0.9, 0}};  // front face down
  addQuad(roof, q);
  ProbeOptions o;
  o.resolution = std::array<int, 3>{8, 2, 8};
  o.boundsMin = std::array<double, 3>{-1, 0, -1};
  o.boundsMax = std::array<double, 3>{1, 1, 1};
  o.bounces = 0;
  o.samples = 128;
  const ProbeGridResult g = computeProbeGrid(test::runtime(), roof, white(), o);
  MeshPreviewOptions view;
  view.width = 160, view.height = 120;
  const LinearImage img = renderProbeGridPreview(test::runtime(), roof, g, view);
  REQUIRE(img.height == 120);
  REQUIRE(img.width == 160 + 120);  // the slice is as tall as the scene panel, square like the box
  auto mean = [&](int x0, int y0) {  // a 20 × 20 block of the slice, its x0, y0 in slice pixels
    double s = 0;
    for (int y = y0; y < y0 + 20; ++y)
      for (int x = x0; x < x0 + 20; ++x) s += img.at(160 + x, y)[0];
    return s / 400;
  };
  const double topLeft = mean(10, 10), bottomRight = mean(90, 90), topRight = mean(90, 10), bottomLeft = mean(10, 90);
  INFO("slice quarters: " << topLeft << " " << topRight << " / " << bottomLeft << " " << bottomRight);
  CHECK(bottomRight < 0.8 * topLeft);
  CHECK(bottomRight < topRight);
  CHECK(bottomRight < bottomLeft);
}

TEST_CASE("Probes: --tolerance brings 95 % of the probes within it", "[probes]") {
  // A room with a block and an open ceiling under the coloured sky, bounces 0 (the visibility the
  // quadrature resolves); the reference at 16384 rays. The pilot's prediction overestimates (it
  // bounds the 95th percentile; tolerance.h), so the check is the promise itself: p95 ≤ E.
  Mesh scene = makeBox(-1, 1, true, 0.6);
  scene.indices.erase(scene.indices.begin() + 3 * 6, scene.indices.begin() + 4 * 6);
  appendMesh(scene, makeBox(-0.35, 0.25, false, 0.8));
  ProbeOptions o;
  o.resolution = std::array<int, 3>{6, 4, 6};
  o.bounces = 0;
  o.relocateFraction = 0;
  o.samples = 16384;
  const ProbeGridResult ref = computeProbeGrid(test::runtime(), scene, sky(), o);
  const double l0 = sky().rgb[0][0];
  for (double tolerance : {0.05, 0.01}) {
    o.tolerance = tolerance;
    const ProbeGridResult g = computeProbeGrid(test::runtime(), scene, sky(), o);
    REQUIRE(g.tolerance.size() == 1);
    std::vector<double> errors;
    for (size_t p = 0; p < g.probeCount; ++p) {
      if (ref.state[p] != 0) continue;
      double e = 0;
      for (int k = 0; k < 27; ++k) e = std::max(e, double(std::abs(g.probe(p)[k] - ref.probe(p)[k])));
      errors.push_back(e / l0);
    }
    std::sort(errors.begin(), errors.end());
    const double p95 = errors[errors.size() * 95 / 100];
    INFO("tolerance " << tolerance << ": " << g.samples << " rays per probe, p95 error " << p95);
    CHECK(p95 <= tolerance);
    CHECK(g.samples < 16384);
  }
}
