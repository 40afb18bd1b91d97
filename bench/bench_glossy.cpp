// bench_glossy: whole-command times and peak memory of glossy transfer on a 50k-vertex mesh.
//
// usage: bench_glossy [--vertices-target N] [--repeats R] [--dir DIR]
// Writes a bumpy sphere of about 50,000 vertices (makeBumpySphere(100000): 50,562 vertices,
// 100,488 triangles) as OBJ, then times, with /usr/bin/time -v (wall, peak RSS):
//   prtbake transport bumpy.obj -o m.npy --transfer matrix --order 5 --samples 1024
//   prtbake transport bumpy.obj -o mi.npy --transfer matrix --order 5 --samples 1024 --mode interreflected
//   prtbake cpca m.npy -o c.npz --clusters 32 --vectors 8
//   prtbake cpca m.npy -o c8.npz --clusters 1 --vectors 72 --weights int8
// after one warm-up run of each (program caches warm). Prints one line per run and the
// medians. Results: bench/results/glossy.md.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "prtbake/mesh.h"

using namespace prtbake;

namespace {
struct Run {
  double wall = 0, rssMiB = 0;
  std::string last;
};

Run timed(const std::string& cmd, const std::string& dir) {
  const std::string log = dir + "/time.log";
  const std::string full = "/usr/bin/time -v " + cmd + " 2> " + log;
  Run r;
  if (std::system(full.c_str()) != 0) {
    std::fprintf(stderr, "failed: %s (see %s)\n", cmd.c_str(), log.c_str());
    std::exit(1);
  }
  std::ifstream in(log);
  std::string line;
  while (std::getline(in, line)) {
    if (line.find("Elapsed (wall clock)") != std::string::npos) {
      const std::string t = line.substr(line.rfind(' ') + 1);
      const size_t c = t.find(':');
      r.wall = std::stod(t.substr(0, c)) * 60 + std::stod(t.substr(c + 1));
    } else if (line.find("Maximum resident set size") != std::string::npos) {
      r.rssMiB = std::stod(line.substr(line.rfind(' ') + 1)) / 1024.0;
    } else if (line.find("prtbake:") != std::string::npos) {
      r.last = line;
    }
  }
  return r;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}
}  // namespace

int main(int argc, char** argv) try {
  int target = 100000, repeats = 3;
  std::string dir = "/tmp/prtbake_bench_glossy";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--triangles") target = std::atoi(argv[i + 1]);
    else if (a == "--repeats") repeats = std::atoi(argv[i + 1]);
    else if (a == "--dir") dir = argv[i + 1];
  }
  std::system(("mkdir -p '" + dir + "'").c_str());
  const Mesh m = makeBumpySphere(target);
  {
    std::ofstream obj(dir + "/bumpy.obj");
    for (size_t v = 0; v < m.vertexCount(); ++v)
      obj << "v " << m.positions[3 * v] << ' ' << m.positions[3 * v + 1] << ' ' << m.positions[3 * v + 2] << "\nvn "
          << m.normals[3 * v] << ' ' << m.normals[3 * v + 1] << ' ' << m.normals[3 * v + 2] << '\n';
    for (size_t t = 0; t < m.triangleCount(); ++t) {
      obj << 'f';
      for (int k = 0; k < 3; ++k) obj << ' ' << m.indices[3 * t + k] + 1 << "//" << m.indices[3 * t + k] + 1;
      obj << '\n';
    }
  }
  std::printf("mesh: %zu vertices, %zu triangles\n", m.vertexCount(), m.triangleCount());
  const std::string cli = PRTBAKE_CLI_PATH;
  const std::string bake = cli + " transport " + dir + "/bumpy.obj -o " + dir + "/m.npy --transfer matrix --order 5 --samples 1024";
  const std::string bakeInter = cli + " transport " + dir + "/bumpy.obj -o " + dir +
                                "/mi.npy --transfer matrix --order 5 --samples 1024 --mode interreflected";
  const std::string cpca = cli + " cpca " + dir + "/m.npy -o " + dir + "/c.npz --clusters 32 --vectors 8";
  const std::string cpca8 = cli + " cpca " + dir + "/m.npy -o " + dir + "/c8.npz --clusters 1 --vectors 72 --weights int8";
  for (const auto& [name, cmd] : {std::pair{"bake", bake}, std::pair{"bake-interreflected", bakeInter},
                                  std::pair{"cpca", cpca}, std::pair{"cpca-int8", cpca8}}) {
    timed(cmd, dir);  // warm-up: program caches
    std::vector<double> wall, rss;
    for (int i = 0; i < repeats; ++i) {
      const Run r = timed(cmd, dir);
      wall.push_back(r.wall);
      rss.push_back(r.rssMiB);
      std::printf("%s: wall %.2f s, peak RSS %.0f MiB | %s\n", name, r.wall, r.rssMiB, r.last.c_str());
      std::fflush(stdout);
    }
    std::printf("%s: median wall %.2f s, median peak RSS %.0f MiB (%d runs)\n", name, median(wall), median(rss), repeats);
  }
  return 0;
} catch (const std::exception& e) {  // a bad argument or a missing device: one line, no abort
  std::fprintf(stderr, "%s: %s\n", argv[0], e.what());
  return 1;
}
