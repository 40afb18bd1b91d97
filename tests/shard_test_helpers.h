// Helpers for the scale-out tests (test_shard.cpp, test_slurm.cpp).
#pragma once

#include <cmath>
#include <string>

#include "job_test_helpers.h"

namespace prtbake::test {

// A UV sphere resting on a square ground plane: enough vertices to split 8 ways
// unevenly (V mod 8 ≠ 0), and occlusion between the parts so visibility matters.
inline void writeSceneObj(const std::string& path, int rings = 12, int segments = 17) {
  std::string obj;
  const double kPi = 3.14159265358979323846;
  for (int i = 0; i <= rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const double th = kPi * i / rings, ph = 2 * kPi * j / segments;
      const double x = std::sin(th) * std::cos(ph), y = std::cos(th), z = std::sin(th) * std::sin(ph);
      obj += "v " + std::to_string(x) + " " + std::to_string(y + 1.0) + " " + std::to_string(z) + "\n";
      obj += "vn " + std::to_string(x) + " " + std::to_string(y) + " " + std::to_string(z) + "\n";
    }
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const int a = i * segments + j + 1, b = i * segments + (j + 1) % segments + 1;
      const int c = a + segments, d = b + segments;
      obj += "f " + std::to_string(a) + "//" + std::to_string(a) + " " + std::to_string(b) + "//" + std::to_string(b) +
             " " + std::to_string(d) + "//" + std::to_string(d) + "\n";
      obj += "f " + std::to_string(a) + "//" + std::to_string(a) + " " + std::to_string(d) + "//" + std::to_string(d) +
             " " + std::to_string(c) + "//" + std::to_string(c) + "\n";
    }
  const int base = (rings + 1) * segments, grid = 9;
  for (int i = 0; i < grid; ++i)
    for (int j = 0; j < grid; ++j) {
      obj += "v " + std::to_string(-3.0 + 6.0 * i / (grid - 1)) + " 0 " + std::to_string(-3.0 + 6.0 * j / (grid - 1)) + "\n";
      obj += "vn 0 1 0\n";
    }
  for (int i = 0; i + 1 < grid; ++i)
    for (int j = 0; j + 1 < grid; ++j) {
      const int a = base + i * grid + j + 1, b = a + 1, c = a + grid, d = c + 1;
      auto v = [](int k) { return std::to_string(k) + "//" + std::to_string(k); };
      obj += "f " + v(a) + " " + v(b) + " " + v(d) + "\nf " + v(a) + " " + v(d) + " " + v(c) + "\n";
    }
  writeText(path, obj);
}

}  // namespace prtbake::test
