// prtbake transport end to end: .npy, sidecar, GAMES202 transport.txt, glTF copy,
// error handling (no partial outputs), mary.obj in GAMES202 units.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "prtbake/atomic_file.h"
#include "prtbake/mesh.h"
#include "prtbake/transport.h"
#include "test_common.h"

using namespace prtbake;

namespace {
const double kPi = 3.14159265358979323846;

struct Npy {
  std::string header;
  std::vector<float> data;
};
Npy readNpy(const std::string& path) {
  const std::string bytes = readFile(path);
  REQUIRE(bytes.size() >= 10);
  REQUIRE(bytes.compare(0, 6, "\x93NUMPY") == 0);
  const size_t len = (unsigned char)bytes[8] | (unsigned char)bytes[9] << 8;
  REQUIRE((10 + len) % 64 == 0);
  Npy n;
  n.header = bytes.substr(10, len);
  n.data.resize((bytes.size() - 10 - len) / 4);
  std::memcpy(n.data.data(), bytes.data() + 10 + len, n.data.size() * 4);
  return n;
}
}  // namespace

TEST_CASE("CLI transport: Box.glb to .npy, sidecar and glTF copy", "[transport][cli][data]") {
  const std::string box = test::dataFile("meshes/gltf/Box.glb");
  PRTBAKE_SKIP_IF_NO_DATA(box);
  const std::string dir = test::tempDir("cli-box");
  const auto r = test::runCli("transport '" + box + "' -o '" + dir + "/box.npy' --samples 256 --order 4 --gltf '" +
                              dir + "/box.glb' --quiet");
  INFO(r.output);
  REQUIRE(r.exitCode == 0);
  const Npy npy = readNpy(dir + "/box.npy");
  CHECK(npy.header.find("'descr': '<f4'") != std::string::npos);
  CHECK(npy.header.find("'shape': (24, 16)") != std::string::npos);
  REQUIRE(npy.data.size() == 24 * 16);
  const auto side = nlohmann::json::parse(readFile(dir + "/box.json"));
  CHECK(side["parameters"]["order"] == 4);
  CHECK(side["parameters"]["mode"] == "shadowed");
  CHECK(side["samples"]["per_vertex"] == 256);
  CHECK(side["input"]["sha256"].get<std::string>().size() == 64);
  CHECK(side["conventions"]["index"] == "i = l(l+1)+m");
  CHECK(side.contains("device"));
  CHECK(side["error"]["max"].get<double>() > 0);
  // The glTF copy loads as a mesh again and carries _PRT_T0.._PRT_T3 (16 coefficients).
  const std::string glb = readFile(dir + "/box.glb");
  const uint32_t jsonLen = *reinterpret_cast<const uint32_t*>(glb.data() + 12);
  const auto gj = nlohmann::json::parse(glb.substr(20, jsonLen));
  const auto& attrs = gj["meshes"][0]["primitives"][0]["attributes"];
  for (int g = 0; g < 4; ++g) {
    const std::string name = "_PRT_T" + std::to_string(g);
    REQUIRE(attrs.contains(name));
    const auto& acc = gj["accessors"][attrs[name].get<int>()];
    CHECK(acc["type"] == "VEC4");
    CHECK(acc["componentType"] == 5126);
    CHECK(acc["count"] == 24);
  }
  CHECK_FALSE(attrs.contains("_PRT_T4"));
  const Mesh again = loadMesh(dir + "/box.glb");
  CHECK(again.vertexCount() == 24);
}

TEST_CASE("CLI transport: .gltf with an external .bin to a .gltf copy with embedded buffers", "[transport][cli][data]") {
  const std::string sphere = test::dataFile("meshes/gltf/AnimatedMorphSphere.gltf");
  PRTBAKE_SKIP_IF_NO_DATA(sphere);
  const std::string dir = test::tempDir("cli-gltf");
  const auto r = test::runCli("transport '" + sphere + "' -o '" + dir + "/s.npy' --samples 32 --order 2 --gltf '" +
                              dir + "/copy.gltf' --quiet");
  INFO(r.output);
  REQUIRE(r.exitCode == 0);
  const auto j = nlohmann::json::parse(readFile(dir + "/copy.gltf"));
  for (const auto& b : j["buffers"]) CHECK(b["uri"].get<std::string>().rfind("data:", 0) == 0);
  const auto& prim = j["meshes"][0]["primitives"][0];
  CHECK(prim["attributes"].contains("_PRT_T0"));
  CHECK_FALSE(prim["attributes"].contains("_PRT_T1"));  // order 2: 4 coefficients, one VEC4
  CHECK(prim.contains("targets"));                      // morph targets survive the copy
  const Mesh original = loadMesh(sphere), copy = loadMesh(dir + "/copy.gltf");
  CHECK(copy.vertexCount() == original.vertexCount());
  CHECK(copy.positions == original.positions);
}

TEST_CASE("CLI transport: GAMES202 export on mary.obj in the framework's units", "[transport][cli][data]") {
  const std::string mary = test::dataFile("meshes/obj/mary.obj");
  PRTBAKE_SKIP_IF_NO_DATA(mary);
  const std::string dir = test::tempDir("cli-mary");
  // Unshadowed with cosine sampling: T00 = Y0 exactly, π Y0 = 0.886227 in GAMES202 units.
  const auto r = test::runCli("transport '" + mary + "' -o '" + dir + "/t.npy' --mode unshadowed --samples 16 " +
                              "--games202 '" + dir + "/transport.txt' --quiet");
  INFO(r.output);
  REQUIRE(r.exitCode == 0);
  const std::string text = readFile(dir + "/transport.txt");
  REQUIRE(!text.empty());
  CHECK(text.back() == '\n');
  std::istringstream in(text);
  std::string line;
  std::getline(in, line);
  CHECK(line == "7905");
  size_t rows = 0;
  while (std::getline(in, line)) {
    ++rows;
    // Strict format: 9 numbers, single spaces, no leading or trailing space.
    REQUIRE(!line.empty());
    REQUIRE(line.front() != ' ');
    REQUIRE(line.back() != ' ');
    REQUIRE(line.find("  ") == std::string::npos);
    std::istringstream ls(line);
    std::vector<double> v;
    double x;
    while (ls >> x) v.push_back(x);
    REQUIRE(v.size() == 9);
    REQUIRE(v[0] == Approx(0.886227).epsilon(1e-5));
  }
  CHECK(rows == 3 * 10174);
}

TEST_CASE("Shadowed mary.obj: occluded vertices fall below the unoccluded 0.886", "[transport][data]") {
  const std::string mary = test::dataFile("meshes/obj/mary.obj");
  PRTBAKE_SKIP_IF_NO_DATA(mary);
  const Mesh m = loadMesh(mary);
  TransportOptions o;
  o.samples = 64;
  o.order = 3;
  const auto r = computeTransport(test::runtime(), m, o);
  double mean = 0, maxT00 = 0;
  for (size_t v = 0; v < m.vertexCount(); ++v) {
    mean += kPi * r.vertex(v)[0];
    maxT00 = std::max(maxT00, kPi * r.vertex(v)[0]);
  }
  mean /= m.vertexCount();
  INFO("mean T00 (GAMES202 units) " << mean);
  CHECK(maxT00 <= 0.8862270 * (1 + 1e-6));
  CHECK(mean < 0.85);
  CHECK(mean > 0.4);
}

TEST_CASE("CLI transport: bad input and bad options fail cleanly with no output", "[transport][cli]") {
  const std::string dir = test::tempDir("cli-bad");
  {
    std::ofstream(dir + "/empty.obj") << "# nothing\n";
  }
  auto r = test::runCli("transport '" + dir + "/empty.obj' -o '" + dir + "/e.npy'");
  CHECK(r.exitCode == 1);
  CHECK(r.output.find("prtbake: error: " + dir + "/empty.obj: the mesh has no triangles") != std::string::npos);
  CHECK_FALSE(test::fileExists(dir + "/e.npy"));
  CHECK_FALSE(test::fileExists(dir + "/e.json"));
  const std::string inf = test::dataFile("meshes/gltf/BoxWithInfinites.glb");
  if (!inf.empty()) {
    r = test::runCli("transport '" + inf + "' -o '" + dir + "/i.npy' --gltf '" + dir + "/i.glb'");
    CHECK(r.exitCode == 1);
    CHECK(r.output.find("non-finite position") != std::string::npos);
    CHECK_FALSE(test::fileExists(dir + "/i.npy"));
    CHECK_FALSE(test::fileExists(dir + "/i.glb"));
  }
  {
    std::ofstream(dir + "/t.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  }
  for (const std::string bad : {"--order 0", "--order 9", "--samples 0", "--mode foo", "--bounces 2",
                                "--gltf x.glb"}) {
    r = test::runCli("transport '" + dir + "/t.obj' -o '" + dir + "/t.npy' " + bad);
    INFO(bad << ": " << r.output);
    CHECK(r.exitCode == 2);
    CHECK_FALSE(test::fileExists(dir + "/t.npy"));
  }
  r = test::runCli("transport '" + dir + "/missing.obj' -o '" + dir + "/m.npy'");
  CHECK(r.exitCode == 1);
  // Coloured interreflection refuses the grey-only GAMES202 format, before writing anything.
  const std::string box = test::dataFile("meshes/gltf/Box.glb");
  if (!box.empty()) {
    r = test::runCli("transport '" + box + "' -o '" + dir + "/b.npy' --mode interreflected --samples 16 --games202 '" +
                     dir + "/b.txt'");
    CHECK(r.exitCode == 2);
    CHECK_FALSE(test::fileExists(dir + "/b.npy"));
    CHECK_FALSE(test::fileExists(dir + "/b.txt"));
    // Without it: RGB .npy [24, 3, 9].
    r = test::runCli("transport '" + box + "' -o '" + dir + "/b.npy' --mode interreflected --samples 16 --quiet");
    REQUIRE(r.exitCode == 0);
    CHECK(readNpy(dir + "/b.npy").header.find("'shape': (24, 3, 9)") != std::string::npos);
  }
}

// A mesh whose transport cannot fit is refused before the bake, naming the mesh, and the
// estimate lies above real bakes' peaks (so a refusal never stops a bake that fits) and within
// 3x of them (a wrong factor would refuse meshes that fit). The meshes: the demo scene instanced
// along y (each instance is stored: 1,681+ vertices apiece), shadowed and interreflected (the
// scene's colours: RGB transport).
TEST_CASE("CLI transport: a mesh beyond the memory the process can have is refused, and the estimate bounds real peaks",
          "[transport][cli]") {
  const std::string dir = test::tempDir("cli-transport-memory");
  const std::string assets = std::string(PRTBAKE_TEST_SOURCE_DIR) + "/../assets/";
  nlohmann::json scene = nlohmann::json::parse(readFile(assets + "scene.gltf"));
  std::ofstream(dir + "/scene.bin", std::ios::binary) << readFile(assets + "scene.bin");
  const size_t n0 = scene["nodes"].size();
  auto& roots = scene["scenes"][scene.value("scene", 0)]["nodes"];
  for (int i = 0; i < 150; ++i) {
    scene["nodes"].push_back({{"mesh", 0}, {"translation", {0, 0.01 * i, 0}}});
    roots.push_back(n0 + i);
  }
  std::ofstream(dir + "/many.gltf") << scene.dump();
  const Mesh mesh = loadMesh(dir + "/many.gltf");
  INFO(mesh.vertexCount() << " vertices");
  const auto refused = test::runShell("PRTBAKE_MEMORY_LIMIT_MB=100 '" + std::string(PRTBAKE_CLI_PATH) + "' transport '" +
                                      dir + "/many.gltf' -o '" + dir + "/no.npy' --quiet");
  INFO(refused.output);
  CHECK(refused.exitCode == 2);
  CHECK_THAT(refused.output, Catch::StartsWith("prtbake: error: " + dir + "/many.gltf: transport of " +
                                               std::to_string(mesh.vertexCount()) + " vertices at order 3 needs about"));
  CHECK_FALSE(test::fileExists(dir + "/no.npy"));
  for (const auto& [mode, order] : std::vector<std::pair<std::string, int>>{{"shadowed", 3}, {"shadowed", 8}, {"interreflected", 3}}) {
    TransportOptions o;
    o.mode = parseTransportMode(mode), o.order = order;
    const double estimate = transportPeakBytes(mesh, o);
    std::vector<std::string> args = {"transport", dir + "/many.gltf", "-o", dir + "/t.npy", "--mode", mode, "--order",
                                     std::to_string(order), "--samples", "16", "--quiet"};
    if (mode == "interreflected") args.insert(args.end(), {"--bounces", "1"});
    const auto r = test::runCliMeasured(args, dir + "/run.txt");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    const double peak = r.peakMiB * 1048576;
    INFO(mode << " order " << order << ": peak " << peak / 1048576 << " MiB, estimate " << estimate / 1048576 << " MiB");
    CHECK(peak <= estimate);
    CHECK(peak >= estimate / 3);
  }
}
