// Glossy transfer end to end: the command line and its files, bad input, jobs split into
// shards, the preview's white furnace, and CPCA (synthetic oracles and mary.obj).
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>

#include <nlohmann/json.hpp>

#include "prtbake/error.h"
#include "prtbake/glossy.h"
#include "prtbake/preview.h"
#include "prtbake/mesh.h"
#include "prtbake/sh.h"
#include "shard_test_helpers.h"
#include "test_common.h"

using namespace prtbake;
using nlohmann::json;

namespace {
const double kPi = 3.14159265358979323846;

std::string q(const std::string& s) { return "'" + s + "'"; }

ShCoeffs whiteSky(int order) {
  ShCoeffs s;
  s.order = order;
  s.rgb.assign(size_t(order) * order, Rgb{0, 0, 0});
  s.rgb[0] = Rgb{std::sqrt(4 * kPi), std::sqrt(4 * kPi), std::sqrt(4 * kPi)};  // L = 1 everywhere
  return s;
}
}  // namespace

TEST_CASE("CLI: --transfer matrix writes the matrices, float16 and the sidecar", "[glossy][cli]") {
  const std::string dir = test::tempDir("glossy_cli");
  test::writeSceneObj(dir + "/scene.obj");
  const Mesh mesh = loadMesh(dir + "/scene.obj");
  auto r = test::runCli("transport " + q(dir + "/scene.obj") + " -o " + q(dir + "/m.npy") +
                        " --transfer matrix --order-out 3 --order-in 4 --samples 256 --quiet");
  INFO(r.output);
  REQUIRE(r.exitCode == 0);
  const GlossyMatrices g = readGlossyNpy(dir + "/m.npy", mesh.vertexCount());
  CHECK(g.orderOut == 3);
  CHECK(g.orderIn == 4);
  CHECK(g.channels == 1);
  // The same values as the library call (the CLI streams blocks; nothing may differ).
  GlossyOptions o;
  o.orderOut = 3, o.orderIn = 4, o.samples = 256;
  const GlossyResult lib = computeGlossyTransfer(test::runtime(), mesh, o);
  CHECK(g.values == lib.matrices);
  const json side = json::parse(test::readText(dir + "/m.json"));
  CHECK(side["product"] == "glossy_transfer");
  CHECK(side["output"]["shape"] == json({mesh.vertexCount(), 9, 16}));
  CHECK(side["conventions"]["index"] == "i = l(l+1)+m");
  CHECK(side["error"]["max"].get<double>() > 0);
  // float16: the same matrices rounded to half precision (relative 2^-11, plus the
  // subnormal step 2^-24 near zero).
  r = test::runCli("transport " + q(dir + "/scene.obj") + " -o " + q(dir + "/h.npy") +
                   " --transfer matrix --order-out 3 --order-in 4 --samples 256 --dtype float16 --quiet");
  REQUIRE(r.exitCode == 0);
  const GlossyMatrices h = readGlossyNpy(dir + "/h.npy");
  CHECK(h.dtype == MatrixDtype::Float16);
  REQUIRE(h.values.size() == g.values.size());
  double worst = 0;
  for (size_t i = 0; i < g.values.size(); ++i)
    worst = std::max(worst, std::abs(h.values[i] - g.values[i]) - std::abs(g.values[i]) * 0x1.0p-11 - 0x1.0p-24);
  CHECK(worst <= 0);
}

TEST_CASE("Glossy .npy readers refuse shapes without vertices or outside the orders", "[glossy][errors]") {
  // Each file's data matches its header, so only the shape itself is wrong. The first two
  // were fuzzing findings: a header with V = 0 (written "-0") and n_out = 1 was read as
  // valid matrices.
  const std::string dir = test::tempDir("glossy_npy_shapes");
  const struct {
    std::vector<size_t> shape;
    const char* why;
  } cases[] = {{{0, 9, 16}, "no vertices"},    {{2, 1, 4}, "order 1"},      {{2, 9, 49}, "order 7"},
               {{2, 3, 9, 15}, "not a square"}, {{2, 2, 9, 9}, "2 channels"}};
  for (const auto& c : cases) {
    size_t n = 1;
    for (size_t d : c.shape) n *= d;
    std::string bytes = glossyNpyHeader(c.shape, MatrixDtype::Float32);
    bytes.append(n * 4, '\0');
    std::ofstream(dir + "/m.npy", std::ios::binary | std::ios::trunc) << bytes;
    INFO(c.why);
    CHECK_THROWS_AS(readGlossyNpy(dir + "/m.npy"), InputError);
    CHECK_THROWS_AS(GlossyNpyMap(dir + "/m.npy"), InputError);
  }
  // The control: the same writer with a valid shape reads back.
  std::string ok = glossyNpyHeader({2, 9, 16}, MatrixDtype::Float32);
  ok.append(2 * 9 * 16 * 4, '\0');
  std::ofstream(dir + "/m.npy", std::ios::binary | std::ios::trunc) << ok;
  CHECK(readGlossyNpy(dir + "/m.npy").values.size() == 2 * 9 * 16);
  CHECK(GlossyNpyMap(dir + "/m.npy").info().orderIn == 4);
  // A fuzzing finding: a header one byte longer puts the floats at an odd offset; the
  // mapping read them misaligned (UBSan). It now refuses, and the copying reader (which
  // `prtbake cpca` falls back to) reads the same values.
  std::string odd = glossyNpyHeader({2, 9, 16}, MatrixDtype::Float32);
  const size_t newline = odd.size() - 1;
  odd.insert(newline, " ");
  odd[8] = char(uint8_t(odd[8]) + 1);  // HEADER_LEN (little-endian, < 255 here)
  for (int i = 0; i < 2 * 9 * 16; ++i) {
    const float x = 0.25f * float(i % 7);
    odd.append(reinterpret_cast<const char*>(&x), 4);
  }
  std::ofstream(dir + "/odd.npy", std::ios::binary | std::ios::trunc) << odd;
  CHECK_THROWS_WITH(GlossyNpyMap(dir + "/odd.npy"), Catch::Contains("odd.npy") && Catch::Contains("multiple of 4"));
  const GlossyMatrices g = readGlossyNpy(dir + "/odd.npy");
  REQUIRE(g.values.size() == 2 * 9 * 16);
  CHECK(g.values[5] == 0.25f * 5);
  const auto r = test::runCli("cpca " + q(dir + "/odd.npy") + " -o " + q(dir + "/odd.npz") + " --clusters 1 --vectors 1");
  INFO(r.output);
  CHECK(r.exitCode == 0);
}

TEST_CASE("CLI: the matrices stream to disk in vertex blocks (bounded memory)", "[glossy][cli][memory]") {
  // Two bakes at order 6 with the exact product rule (no rays: quick): 13,000 and 52,000
  // vertices, 64 and 256 MiB of float32 matrices. The command holds one block of vertices
  // (4096) and the mesh, never the tensor, so its peak resident size grows only with the
  // mesh's own arrays and with how the allocator's per-thread arenas happen to fill: measured
  // growths of 31 to 88 MiB over runs; holding the tensor would add the files' 192 MiB
  // difference. kGrowthMiB = 120 sits between the two.
  // Peaks come from wait4 of each child.
  constexpr double kGrowthMiB = 120;
  const std::string dir = test::tempDir("glossy_stream");
  auto writeObj = [&](const std::string& path, const Mesh& m) {
    std::ofstream obj(path);
    for (size_t v = 0; v < m.vertexCount(); ++v)
      obj << "v " << m.positions[3 * v] << ' ' << m.positions[3 * v + 1] << ' ' << m.positions[3 * v + 2] << "\nvn "
          << m.normals[3 * v] << ' ' << m.normals[3 * v + 1] << ' ' << m.normals[3 * v + 2] << '\n';
    for (size_t t = 0; t < m.triangleCount(); ++t)
      obj << "f " << m.indices[3 * t] + 1 << "//" << m.indices[3 * t] + 1 << ' ' << m.indices[3 * t + 1] + 1 << "//"
          << m.indices[3 * t + 1] + 1 << ' ' << m.indices[3 * t + 2] + 1 << "//" << m.indices[3 * t + 2] + 1 << '\n';
  };
  writeObj(dir + "/small.obj", makeUvSphere(1.0, 80, 163));
  writeObj(dir + "/large.obj", makeUvSphere(1.0, 160, 326));
  double peak[2];
  off_t size[2];
  for (int k = 0; k < 2; ++k) {
    const std::string name = k == 0 ? "small" : "large", obj = dir + "/" + name + ".obj", npy = dir + "/" + name + ".npy";
    const test::MeasuredRun run = test::runCliMeasured({"transport", obj, "-o", npy, "--transfer", "matrix", "--order", "6",
                                                        "--mode", "unshadowed", "--quiet"},
                                                       dir + "/" + name + ".log");
    INFO(run.output);
    REQUIRE(run.exitCode == 0);
    peak[k] = run.peakMiB;
    struct stat st {};
    ::stat(npy.c_str(), &st);
    size[k] = st.st_size;
  }
  INFO("files " << double(size[0]) / 1048576 << " and " << double(size[1]) / 1048576 << " MiB, peak resident "
                << peak[0] << " and " << peak[1] << " MiB");
  CHECK(double(size[1] - size[0]) > 150.0 * 1048576);
  CHECK(peak[1] - peak[0] < kGrowthMiB);
}

TEST_CASE("CLI: bad options and inputs give one error line and no output", "[glossy][cli][errors]") {
  const std::string dir = test::tempDir("glossy_cli_errors");
  test::writeSceneObj(dir + "/scene.obj");
  const std::string base = "transport " + q(dir + "/scene.obj") + " -o " + q(dir + "/m.npy") + " --transfer matrix ";
  struct Case {
    std::string args;
    int exitCode;
    std::string says;
  };
  const std::vector<Case> cases = {
      {"--order 7", 2, "out of range [2, 6]"},
      {"--order-in 1", 2, "--order-in"},
      {"--gltf x.glb", 2, "only applies to --transfer vector"},
      {"--tolerance 0.01", 2, "only applies to --transfer vector"},
      {"--dtype float64", 2, "float32|float16"},
      {"--brdf phong:3", 2, "ggx:R[:F0]"},
      {"--cpca 4", 2, "--cpca"},
      {"--cpca 4,4 --cpca-error 0.1", 2, "not both"},
      {"--cpca 4,129", 2, "--cpca-vectors: 129 is out of range [0, 128]"},
      {"--order 2 --cpca 2,17", 2, "more PCA vectors (17) than values per vertex (16)"},
      {"--cpca-weights int8", 2, "--cpca-weights: goes with cpca_clusters/cpca_vectors or cpca_error"},
      {"--cpca 4,4 --cpca-weights int4", 2, "float32|int8"},
      {"--bounces 2", 2, "interreflected"},
  };
  for (const Case& c : cases) {
    const auto r = test::runCli(base + c.args);
    INFO(c.args << ": " << r.output);
    CHECK(r.exitCode == c.exitCode);
    CHECK(r.output.find(c.says) != std::string::npos);
    CHECK(r.output.find("prtbake: error: ") == 0);
    CHECK(!test::fileExists(dir + "/m.npy"));
  }
  // Matrices that would not fit the memory limit, for CPCA (which holds them): the size.
  auto r = test::runShell("PRTBAKE_INPUT_LIMIT_MB=1 '" + std::string(PRTBAKE_CLI_PATH) + "' " + base +
                          "--order 6 --cpca 4,4");
  INFO(r.output);
  CHECK(r.exitCode == 2);
  CHECK(r.output.find("MiB, more than the memory limit of 1 MiB") != std::string::npos);
  CHECK(!test::fileExists(dir + "/m.npy"));
  // Diffuse-only runs refuse the matrix options.
  r = test::runCli("transport " + q(dir + "/scene.obj") + " -o " + q(dir + "/t.npy") + " --order-out 3");
  CHECK(r.exitCode == 2);
  // Bad mesh files: exit 1, as for diffuse transport.
  test::writeText(dir + "/nan.obj", "v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n");
  test::writeText(dir + "/empty.obj", "v 0 0 0\n");
  for (const char* bad : {"/nan.obj", "/empty.obj", "/missing.obj"}) {
    r = test::runCli("transport " + q(dir + bad) + " -o " + q(dir + "/m.npy") + " --transfer matrix");
    INFO(bad << ": " << r.output);
    CHECK(r.exitCode == 1);
    CHECK(!test::fileExists(dir + "/m.npy"));
  }
}

TEST_CASE("Jobs: a split glossy job merges to the one-process bytes and reruns skip it", "[glossy][jobs][shard]") {
  const std::string dir = test::tempDir("glossy_jobs");
  test::writeSceneObj(dir + "/scene.obj");
  auto job = [&](const std::string& id, const std::string& out, bool split) {
    json j = {{"id", id},
              {"type", "glossy"},
              {"input", "scene.obj"},
              {"order", 3},
              {"samples", 128},
              {"cpca_clusters", 3},
              {"cpca_vectors", 2},
              {"cpca_weights", "int8"},
              {"outputs", {{"npy", out + ".npy"}, {"json", out + ".json"}, {"cpca", out + ".cpca.npz"}}}};
    if (split) j["split"] = true;
    return j;
  };
  test::writeJobFile(dir + "/jobs.json", {job("split", "s/g", true), job("whole", "w/g", false)});
  for (int i = 0; i < 3; ++i) {
    const auto r = test::runCli("run " + q(dir + "/jobs.json") + " --shard " + std::to_string(i) + "/3 --quiet");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
  }
  auto r = test::runCli("merge " + q(dir + "/jobs.json") + " --shards 3");
  INFO(r.output);
  REQUIRE(r.exitCode == 0);
  CHECK(test::readText(dir + "/s/g.npy") == test::readText(dir + "/w/g.npy"));
  CHECK(test::readText(dir + "/s/g.cpca.npz") == test::readText(dir + "/w/g.cpca.npz"));
  int oo = 0, oi = 0, ch = 0;
  CHECK(readCpcaNpz(dir + "/s/g.cpca.npz", &oo, &oi, &ch).weightBits == 8);
  r = test::runCli("run " + q(dir + "/jobs.json"));
  CHECK(r.exitCode == 0);
  CHECK(r.output.find("[skipped] split (up to date)") != std::string::npos);
  CHECK(r.output.find("[skipped] whole (up to date)") != std::string::npos);
  // Validation mirrors the command line.
  test::writeJobFile(dir + "/bad.json", {json{{"id", "b"}, {"type", "glossy"}, {"input", "scene.obj"}, {"order", 7},
                                              {"outputs", {{"npy", "b.npy"}}}},
                                         json{{"id", "c"}, {"type", "glossy"}, {"input", "scene.obj"},
                                              {"outputs", {{"npy", "c.npy"}, {"cpca", "c.npz"}}}}});
  r = test::runCli("run " + q(dir + "/bad.json") + " --dry-run");
  INFO(r.output);
  CHECK(r.exitCode != 0);
  CHECK(r.output.find("order") != std::string::npos);
  CHECK(r.output.find("cpca") != std::string::npos);
}

TEST_CASE("Preview furnace: white sky, unoccluded mesh, normalised lobe: every pixel shows the albedo",
          "[glossy][preview]") {
  // Under L = 1 the transferred radiance of an unoccluded vertex is t = M e_0 √4π = the
  // hemisphere's projection h(n); the preview divides the lobe's response to t by its
  // response to the interpolated h, so the ratio is 1 at every pixel for any lobe and view.
  // Unshadowed (exact product rule): float rounding, kFurnaceExact = 1e-4. Shadowed (1024
  // uniform samples of a convex mesh): the sampling error of M's first column over D
  // (measured 7.3e-3 with phong:16, 1.3e-3 with the cosine lobe): kFurnaceSampled = 1e-2;
  // unshadowed measured 3.6e-7. Seen failing: normalising with one vertex's h instead of the
  // interpolated one gave 0.39 (cosine) to 1.6 (phong:16).
  constexpr double kFurnaceExact = 1e-4, kFurnaceSampled = 1e-2;
  Mesh sphere = makeUvSphere(1.0, 12, 24);
  for (size_t v = 0; v < sphere.vertexCount(); ++v) sphere.albedo[3 * v] = 0.5f, sphere.albedo[3 * v + 2] = 0.25f;
  for (auto [mode, tol] : {std::pair{TransportMode::Unshadowed, kFurnaceExact}, std::pair{TransportMode::Shadowed, kFurnaceSampled}}) {
    GlossyOptions o;
    o.mode = mode;
    o.orderOut = o.orderIn = 5;
    const GlossyResult r = computeGlossyTransfer(test::runtime(), sphere, o);
    GlossyMatrices g;
    g.orderOut = g.orderIn = 5, g.channels = 1, g.vertexCount = sphere.vertexCount(), g.values = r.matrices;
    for (const char* lobeText : {"phong:16", "ggx:0.4", "cosine"}) {
      GlossyPreviewOptions po;
      po.view.width = 64, po.view.height = 48, po.view.yawDeg = 30, po.view.pitchDeg = 20;
      const MeshPreviewResult img =
          renderGlossyPreview(test::runtime(), sphere, g, nullptr, whiteSky(5), parseGlossyLobe(lobeText, 5), po);
      double worst = 0;
      size_t hits = 0;
      for (size_t p = 0; p < img.hitTriangle.size(); ++p) {
        if (img.hitTriangle[p] < 0) continue;
        ++hits;
        const float want[3] = {0.5f, 1.0f, 0.25f};
        for (int c = 0; c < 3; ++c) worst = std::max(worst, double(std::abs(img.image.rgb[3 * p + c] - want[c]) / want[c]));
      }
      INFO(transportModeName(mode) << ", " << lobeText << ": " << hits << " pixels, max relative error " << worst);
      CHECK(hits > 500);
      CHECK(worst < tol);
    }
  }
}

TEST_CASE("Preview: view-dependent, light rotation, CPCA, and the command line", "[glossy][preview][cli]") {
  const std::string dir = test::tempDir("glossy_preview");
  test::writeSceneObj(dir + "/scene.obj");
  auto r = test::runCli("transport " + q(dir + "/scene.obj") + " -o " + q(dir + "/m.npy") +
                        " --transfer matrix --order 4 --samples 128 --cpca 2,4 --quiet");
  INFO(r.output);
  REQUIRE(r.exitCode == 0);
  REQUIRE(test::fileExists(dir + "/m.cpca.npz"));
  // A sky with a bright lobe: radiance SH of order 4.
  ShCoeffs sky = whiteSky(4);
  std::vector<double> y(16);
  shEval(4, 0.3, 0.9, 0.3, y.data());
  for (int i = 0; i < 16; ++i)
    for (int c = 0; c < 3; ++c) sky.rgb[size_t(i)][size_t(c)] += 3.0 * y[size_t(i)] * (c == 0 ? 1.0 : 0.7);
  writeShJson(dir + "/sky.json", sky, "");
  const Mesh mesh = loadMesh(dir + "/scene.obj");
  const GlossyMatrices g = readGlossyNpy(dir + "/m.npy");
  const GlossyLobe lobe = phongLobe(32, 4);
  auto render = [&](double yaw, double light, const CpcaResult* c) {
    GlossyPreviewOptions po;
    po.view.width = 48, po.view.height = 36, po.view.yawDeg = yaw, po.view.lightRotationDeg = light;
    return renderGlossyPreview(test::runtime(), mesh, g, c, sky, lobe, po).image.rgb;
  };
  auto diff = [](const std::vector<float>& a, const std::vector<float>& b) {
    double d = 0;
    for (size_t i = 0; i < a.size(); ++i) d = std::max(d, double(std::abs(a[i] - b[i])));
    return d;
  };
  const auto base = render(0, 0, nullptr);
  CHECK(diff(base, render(0, 90, nullptr)) > 0.05);  // the light turned
  CHECK(diff(base, render(0, 360, nullptr)) < 1e-4);  // a whole turn: the same image
  int oo = 0, oi = 0, ch = 0;
  const CpcaResult c = readCpcaNpz(dir + "/m.cpca.npz", &oo, &oi, &ch);
  CHECK(oo == 4);
  CHECK(diff(base, render(0, 0, &c)) < 0.5);  // close to the uncompressed image
  r = test::runCli("preview mesh " + q(dir + "/scene.obj") + " --matrices " + q(dir + "/m.npy") + " --env " +
                   q(dir + "/sky.json") + " -o " + q(dir + "/p.png") + " --lobe ggx:0.3 --rotate-light 45 --size 64x48 --quiet");
  INFO(r.output);
  CHECK(r.exitCode == 0);
  CHECK(test::fileExists(dir + "/p.png"));
  r = test::runCli("preview mesh " + q(dir + "/scene.obj") + " --cpca " + q(dir + "/m.cpca.npz") + " --env " +
                   q(dir + "/sky.json") + " -o " + q(dir + "/c.png") + " --size 64x48 --quiet");
  CHECK(r.exitCode == 0);
  r = test::runCli("preview mesh " + q(dir + "/scene.obj") + " --matrices " + q(dir + "/m.npy") + " --env " +
                   q(dir + "/sky.json") + " -o " + q(dir + "/x.png") + " --lobe blinn:3");
  CHECK(r.exitCode == 2);
  CHECK(!test::fileExists(dir + "/x.png"));
}

TEST_CASE("CPCA recovers clusters of affine subspaces exactly, and the ladder meets a target", "[glossy][cpca]") {
  // Synthetic data on K = 3 affine subspaces of dimension P = 2 in R^D (D = 49: 7 × 7, not
  // symmetric): CPCA with K, P must reconstruct every point to float rounding
  // (kExactCpca = 1e-5 relative); with P = 1 it cannot (the second direction is lost).
  constexpr double kExactCpca = 1e-5;
  const size_t V = 600, D = 49;
  std::vector<float> x(V * D);
  uint64_t s = 1;
  auto rnd = [&] {
    s = s * 6364136223846793005ull + 1442695040888963407ull;
    return double(s >> 11) * 0x1.0p-53 - 0.5;
  };
  std::vector<double> mu(3 * D), b(3 * 2 * D);
  for (double& v : mu) v = 4 * rnd();
  for (double& v : b) v = rnd();
  for (size_t v = 0; v < V; ++v) {
    const size_t k = v % 3;
    const double w0 = 3 * rnd(), w1 = 3 * rnd();
    for (size_t d = 0; d < D; ++d) x[v * D + d] = float(mu[k * D + d] + w0 * b[(k * 2) * D + d] + w1 * b[(k * 2 + 1) * D + d]);
  }
  CpcaOptions o;
  o.clusters = 3, o.vectors = 2;
  const CpcaResult c = cpcaCompress(x.data(), V, D, o);
  INFO("total " << c.totalError << ", max vertex " << c.maxVertexError);
  CHECK(c.totalError < kExactCpca);
  CHECK(c.maxVertexError < 10 * kExactCpca);
  std::vector<float> rec(D);
  cpcaReconstruct(c, 5, rec.data());
  for (size_t d = 0; d < D; ++d) CHECK(rec[d] == Approx(x[5 * D + d]).margin(1e-4));
  o.vectors = 1;
  CHECK(cpcaCompress(x.data(), V, D, o).totalError > 0.05);
  // Deterministic.
  o.vectors = 2;
  const CpcaResult again = cpcaCompress(x.data(), V, D, o);
  CHECK(again.weights == c.weights);
  CHECK(again.clusterOf == c.clusterOf);
  // The ladder: the cheapest (K, P) whose total error meets the target.
  CpcaOptions t;
  t.targetError = 1e-3;
  const CpcaResult l = cpcaCompress(x.data(), V, D, t);
  INFO("ladder chose K " << l.clusters << ", P " << l.vectors);
  CHECK(l.totalError <= 1e-3);
  // The first rung that holds the true model (K = 3, P = 2): the ladder's K are powers of two.
  CHECK(l.clusters == 4);
  CHECK(l.vectors == 2);
  CHECK(!l.tried.empty());
  // Per-vertex errors add up to the total.
  double se = 0, sn = 0;
  for (size_t v = 0; v < V; ++v) {
    double n = 0;
    for (size_t d = 0; d < D; ++d) n += double(x[v * D + d]) * x[v * D + d];
    se += double(l.vertexError[v]) * l.vertexError[v] * n, sn += n;
  }
  CHECK(std::sqrt(se / sn) == Approx(l.totalError).epsilon(1e-3));
  CHECK_THROWS_AS(cpcaCompress(x.data(), V, D, CpcaOptions{}), UsageError);
}

TEST_CASE("CPCA with int8 weights: each weight within half a step, and the .npz reads back bit for bit",
          "[glossy][cpca]") {
  // Synthetic matrices (D = 36, not symmetric) whose norms span 1e-3 to 1. q_vp =
  // round(w_vp / (c_kp t_v)): every weight lies within half its step of the float weight,
  // and, the basis being orthonormal and the float residual orthogonal to it, the squared
  // error is the float error plus Σ (w8 − w32)² exactly (Pythagoras).
  const size_t V = 500, D = 36, P = 6;
  std::vector<float> x(V * D);
  for (size_t v = 0; v < V; ++v) {
    const double size = std::pow(10.0, -3.0 * double(v % 7) / 6.0);
    for (size_t d = 0; d < D; ++d) x[v * D + d] = float(size * (1.0 + std::sin(0.37 * double(v) * (1 + d % 5) + 0.5 * d)));
  }
  CpcaOptions o;
  o.clusters = 2, o.vectors = int(P);
  const CpcaResult f = cpcaCompress(x.data(), V, D, o);
  o.weightBits = 8;
  const CpcaResult c = cpcaCompress(x.data(), V, D, o);
  REQUIRE(c.weightBits == 8);
  REQUIRE(c.weightScales.size() == 2 * P);
  REQUIRE(c.vertexScales.size() == V);
  REQUIRE(c.clusterOf == f.clusterOf);  // quantisation comes after the clustering
  double worstStep = 0, e8 = 0, e32 = 0, dw = 0;
  for (size_t v = 0; v < V; ++v) {
    double n2 = 0;
    for (size_t d = 0; d < D; ++d) n2 += double(x[v * D + d]) * x[v * D + d];
    e8 += n2 * c.vertexError[v] * c.vertexError[v], e32 += n2 * f.vertexError[v] * f.vertexError[v];
    for (size_t p = 0; p < P; ++p) {
      const double step = cpcaInt8Step(c, v, p);
      const double d = double(c.weights[v * P + p]) - f.weights[v * P + p];
      worstStep = std::max(worstStep, std::abs(d) / step);
      dw += d * d;
    }
  }
  INFO("largest |w8 - w32| / step " << worstStep << "; squared errors int8 " << e8 << ", float32 " << e32
                                    << " + weights " << dw);
  CHECK(worstStep <= 0.5 + 1e-3);  // rounding to the nearest code, float slack
  CHECK(dw > 0);
  CHECK(e8 == Approx(e32 + dw).epsilon(1e-3));  // kPythagoras: float32 per-vertex errors
  // More vectors than values per vertex: refused (the basis could not be orthonormal).
  o.vectors = int(D) + 1;
  CHECK_THROWS_WITH(cpcaCompress(x.data(), V, D, o), Catch::Contains("more PCA vectors (37)"));
  // 1 byte per weight plus 4 per vertex scale, against 4 per float weight.
  CHECK(c.storedBytes() == Approx(f.storedBytes() - double(V) * P * 3 + 4.0 * (V + 2 * P)));
  // The archive: numpy's int8 array and both scales; read back bit for bit.
  const std::string dir = test::tempDir("cpca_int8");
  test::writeText(dir + "/c.npz", cpcaNpzBytes(c, 3, 2, 1));
  int oo = 0, oi = 0, ch = 0;
  const CpcaResult back = readCpcaNpz(dir + "/c.npz", &oo, &oi, &ch);
  CHECK(back.weightBits == 8);
  CHECK(back.weights == c.weights);
  CHECK(back.weightScales == c.weightScales);
  CHECK(back.vertexScales == c.vertexScales);
  test::writeText(dir + "/f.npz", cpcaNpzBytes(f, 3, 2, 1));
  CHECK(readCpcaNpz(dir + "/f.npz", &oo, &oi, &ch).weightBits == 32);
  // Vertex scales that disagree with their shape are refused with the file named.
  CpcaResult badScales = c;
  badScales.vertexScales.push_back(1.0f);
  test::writeText(dir + "/bad.npz", cpcaNpzBytes(badScales, 3, 2, 1));
  CHECK_THROWS_WITH(readCpcaNpz(dir + "/bad.npz", &oo, &oi, &ch),
                    Catch::Contains("bad.npz") && Catch::Contains("vertex_scales"));
}

TEST_CASE("CPCA of mary.obj at order 5: compression and error", "[glossy][cpca][data]") {
  // The acceptance figure asked for ≥ 20× at ≤ 2 % relative RMS. Measured on the shadowed
  // bake (1024 samples): K = 32, P = 8 is 19.7× at 11.9 %; the error is the visibility's
  // detail, not sampling noise (16384 samples gave 12.1 %), and global PCA needs ~64
  // vectors (8.9×) for 2.3 %. So the shadowed target is not met and this test bounds what
  // is measured (kShadowedError = 0.13); the unshadowed matrices (normal-dependent only)
  // meet it: K = 16, P = 8 is 30.7× at 1.6 % (kUnshadowedError = 0.02).
  constexpr double kShadowedError = 0.13, kUnshadowedError = 0.02;
  const std::string path = test::dataFile("meshes/obj/mary.obj");
  PRTBAKE_SKIP_IF_NO_DATA(path);
  const Mesh mary = loadMesh(path);
  for (TransportMode mode : {TransportMode::Shadowed, TransportMode::Unshadowed}) {
    GlossyOptions o;
    o.mode = mode;
    o.orderOut = o.orderIn = 5;
    const GlossyResult r = computeGlossyTransfer(test::runtime(), mary, o);
    CpcaOptions co;
    co.clusters = mode == TransportMode::Shadowed ? 32 : 16;
    co.vectors = 8;
    const CpcaResult c = cpcaCompress(r.matrices.data(), mary.vertexCount(), 625, co);
    INFO(transportModeName(mode) << ": K " << c.clusters << " P " << c.vectors << ": " << c.compressionRatio()
                                 << "x, total " << c.totalError << ", per-vertex RMS " << c.rmsVertexError << ", "
                                 << c.seconds << " s");
    CHECK(c.compressionRatio() > (mode == TransportMode::Shadowed ? 19.5 : 20.0));
    CHECK(c.totalError < (mode == TransportMode::Shadowed ? kShadowedError : kUnshadowedError));
    if (mode != TransportMode::Shadowed) continue;
    // int8 weights: the shadowed matrices span exactly 81 dimensions (M is linear in the
    // visibility's SH to order 9), and one byte per weight buys enough of them: K = 1, P = 72
    // measured 24.2x at 1.57 % total (per-vertex RMS 4.5 %); the acceptance is ≥ 20x at ≤ 2 %.
    co.clusters = 1, co.vectors = 72, co.weightBits = 8;
    const CpcaResult q8 = cpcaCompress(r.matrices.data(), mary.vertexCount(), 625, co);
    INFO("int8: K 1 P 72: " << q8.compressionRatio() << "x, total " << q8.totalError << ", per-vertex RMS "
                            << q8.rmsVertexError << ", " << q8.seconds << " s");
    CHECK(q8.compressionRatio() >= 20.0);
    CHECK(q8.totalError <= 0.02);
    // The ladder finds it (or cheaper) from the target alone.
    CpcaOptions t;
    t.targetError = 0.02, t.weightBits = 8;
    const CpcaResult l = cpcaCompress(r.matrices.data(), mary.vertexCount(), 625, t);
    INFO("ladder: K " << l.clusters << " P " << l.vectors << ": " << l.compressionRatio() << "x, total " << l.totalError);
    CHECK(l.compressionRatio() >= q8.compressionRatio());
    CHECK(l.totalError <= 0.02);
  }
}
