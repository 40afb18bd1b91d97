// Helpers for the job-runner and queue tests: small inputs, job files, and
// hand-made manifests (the format docs/jobs.md documents), so that skip logic
// and the queue can be tested without running a product.
#pragma once

#include <sys/stat.h>

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "prtbake/atomic_file.h"
#include "prtbake/exr.h"
#include "prtbake/hash.h"
#include "test_common.h"

namespace prtbake::test {

using nlohmann::json;

inline void writeText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

inline std::string readText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A small lat-long OpenEXR environment (16×8, envmap attribute = lat-long) of
// constant radiance `value`: the white furnace when value = 1.
inline void writeLatLongExr(const std::string& path, float value = 1.0f) {
  const int w = 16, h = 8;
  std::vector<float> c(size_t(w) * h, value);
  ExrWriteOptions options;
  options.envmap = 0;
  writeExr(path, w, h, {{"R", c.data()}, {"G", c.data()}, {"B", c.data()}}, options);
}

// One env job as JSON text.
inline json envJob(const std::string& id, const std::string& input, const std::string& jsonOut) {
  return {{"id", id}, {"type", "env"}, {"input", input}, {"outputs", {{"json", jsonOut}}}};
}

inline void writeJobFile(const std::string& path, const std::vector<json>& jobs) {
  writeText(path, json{{"jobs", jobs}}.dump(2));
}

// The JSON events (--log-json lines) in a CLI's output.
inline std::vector<json> events(const std::string& output) {
  std::vector<json> out;
  std::istringstream ss(output);
  std::string line;
  while (std::getline(ss, line))
    if (!line.empty() && line[0] == '{') out.push_back(json::parse(line, nullptr, false));
  return out;
}

inline long long fileBytes(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 ? static_cast<long long>(st.st_size) : -1;
}

// Makes every job of `jobFile` look done: asks `run --dry-run --log-json` for
// each job's normalised parameters, writes a placeholder for every output and a
// manifest in the documented format. A following `run` must skip every job.
inline void fakeCompletedRun(const std::string& jobFile) {
  const CliResult r = runCli("run '" + jobFile + "' --dry-run --log-json");
  for (const auto& e : events(r.output)) {
    if (e.value("event", "") != "job_end" || e.value("status", "") != "would_run") continue;
    const json& params = e["parameters"];
    json outputs = json::array();
    std::string first;
    for (const char* kind : {"json", "games202", "npy", "gltf", "exr"}) {  // the types' naming order
      if (!params["outputs"].contains(kind)) continue;
      const std::string path = params["outputs"][kind];
      writeText(path, std::string("placeholder ") + kind + "\n");
      outputs.push_back({{"kind", kind}, {"path", path}, {"bytes", fileBytes(path)}});
      if (first.empty()) first = path;
    }
    json inputs = json::array();
    if (params.contains("input"))
      inputs.push_back({{"path", params["input"]}, {"sha256", sha256File(params["input"])}});
    const json manifest = {{"prtbake_manifest", 1}, {"version", version()},  {"id", params["id"]},
                           {"type", params["type"]}, {"parameters", params}, {"inputs", inputs},
                           {"outputs", outputs},     {"device", ""}};
    writeText(first + ".manifest.json", manifest.dump(2));
  }
}

inline int countOf(const std::string& text, const std::string& what) {
  int n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + what.size())) ++n;
  return n;
}

}  // namespace prtbake::test
