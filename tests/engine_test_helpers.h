// Shared by the tests that run the engines' own code (three.js, Filament, Babylon.js, the
// glTF-Sample-Viewer from tests/js/node_modules) in node or headless Chromium: readiness and
// skips, page templates, Chromium results and prtbake's 8-bit view of a render.
#pragma once

#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "test_common.h"

namespace prtbake::test {

// node and the npm engines of tests/js/package.json are installed.
inline bool nodeReady() {
  const std::string js = std::string(PRTBAKE_TEST_SOURCE_DIR) + "/js/node_modules/";
  return runShell("command -v node").exitCode == 0 && fileExists(js + "three/package.json") &&
         fileExists(js + "filament/package.json") && fileExists(js + "ktx-parse/package.json") &&
         fileExists(js + "@babylonjs/core/package.json") && fileExists(js + "@khronosgroup/gltf-viewer/package.json");
}

inline std::string replaceAll(std::string s, const std::string& from, const std::string& to) {
  for (size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size())) s.replace(at, from.size(), to);
  return s;
}

// A page template with each placeholder replaced.
inline std::string fillPage(std::string text, const std::vector<std::pair<std::string, std::string>>& values) {
  for (const auto& [from, to] : values) text = replaceAll(text, from, to);
  return text;
}

// prtbake's 8-bit view of linear radiance: exposure 0, clamped, sRGB-encoded (the previews').
inline double srgb8(double v) {
  v = std::clamp(v, 0.0, 1.0);
  return 255.0 * (v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055);
}

// Loads a page in Chromium and parses its "RESULT {json}".
inline nlohmann::json chromiumResult(const std::string& chromium, const std::string& page) {
  const CliResult res = chromiumPage(chromium, page);
  const size_t at = res.output.find("RESULT {");
  INFO(page << ": chromium_page.mjs exit " << res.exitCode << ": " << res.output.substr(0, 2000));
  REQUIRE(at != std::string::npos);
  return nlohmann::json::parse(res.output.substr(at + 7, res.output.find('\n', at) - at - 7));
}

}  // namespace prtbake::test

// Declares `var`, Chromium's path, or skips the test case without Chromium or the npm engines.
#define PRTBAKE_CHROMIUM_OR_SKIP(var, engine)                                                             \
  const std::string var = ::prtbake::test::chromiumPath();                                                \
  if (var.empty()) PRTBAKE_SKIP("chromium not found (Debian package 'chromium'): " engine " cannot run"); \
  if (!::prtbake::test::nodeReady()) PRTBAKE_SKIP("tests/js/node_modules absent (npm ci in tests/js): " engine " not installed")
