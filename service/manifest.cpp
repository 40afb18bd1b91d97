// Per-job manifests (see manifest.h).
#include "manifest.h"

#include <sys/stat.h>

#include <ctime>
#include <filesystem>

#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/hash.h"

namespace prtbake::jobs {
namespace {

constexpr int kManifestFormat = 1;

// A file's size; a directory output's (an ibl package) is the total of its files'.
long long fileSize(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return -1;
  if (S_ISREG(st.st_mode)) return static_cast<long long>(st.st_size);
  if (!S_ISDIR(st.st_mode)) return -1;
  long long total = 0;
  std::error_code ec;
  for (const auto& e : std::filesystem::recursive_directory_iterator(path, ec))
    if (e.is_regular_file(ec)) total += static_cast<long long>(e.file_size(ec));
  return ec ? -1 : total;
}


}  // namespace

std::vector<InputHash> hashInputs(const std::vector<std::string>& files, const std::map<std::string, std::string>& known) {
  std::vector<InputHash> out;
  for (const auto& f : files) {
    const auto it = known.find(f);
    out.push_back({f, it != known.end() ? it->second : sha256File(f)});
  }
  return out;
}

json makeManifest(const Job& job, const std::vector<InputHash>& inputs, const std::string& device,
                  const json& timings, const json& report) {
  json in = json::array();
  for (const auto& h : inputs) in.push_back({{"path", h.path}, {"sha256", h.sha256}});
  json out = json::array();
  for (const auto& o : job.outputs) out.push_back({{"kind", o.kind}, {"path", o.path}, {"bytes", fileSize(o.path)}});
  return {{"prtbake_manifest", kManifestFormat},
          {"version", version()},
          {"id", job.id},
          {"type", job.type->name},
          {"job_file", job.jobFile},
          {"parameters", job.params},
          {"inputs", in},
          {"outputs", out},
          {"device", device},
          {"timings", timings},
          {"report", report},
          {"finished_utc", utcNow()}};
}

std::string utcNow() {
  const std::time_t t = std::time(nullptr);
  std::tm tm {};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

namespace {

// whyOutOfDate on a parsed manifest; json::value() and operator[] throw
// json::type_error where the manifest holds a value of another type than it should.
std::string whyOutOfDateParsed(const Job& job, json& m) {
  if (!m.is_object() || manifestInt(m, "prtbake_manifest", 0) != kManifestFormat) return "unknown manifest format";
  const std::string was = m.value("version", "");
  if (was != version()) return "prtbake version changed (" + was + " -> " + version() + ")";
  const json& params = m["parameters"];
  if (params != job.params) {
    std::string changed;
    for (auto it = job.params.begin(); it != job.params.end(); ++it)
      if (!params.is_object() || !params.contains(it.key()) || params[it.key()] != it.value())
        changed += (changed.empty() ? "" : ", ") + it.key();
    return "parameters changed" + (changed.empty() ? std::string() : ": " + changed);
  }
  // Outputs: present with the size recorded (cheap), before hashing any input.
  const json& outs = m["outputs"];
  if (!outs.is_array() || outs.size() != job.outputs.size()) return "outputs changed";
  for (size_t i = 0; i < job.outputs.size(); ++i) {
    const long long bytes = fileSize(job.outputs[i].path);
    if (bytes < 0) return "output missing: " + job.outputs[i].path;
    if (outs[i].value("path", "") != job.outputs[i].path || manifestInt(outs[i], "bytes", -2LL) != bytes)
      return "output changed: " + job.outputs[i].path;
  }
  const json& ins = m["inputs"];
  if (!ins.is_array()) return "unknown manifest format";
  bool primarySeen = job.input.empty();
  for (const auto& in : ins) {
    const std::string path = in.value("path", "");
    // The input itself, or a file inside it when it is a directory (six faces).
    if (path == job.input || path.rfind(job.input + "/", 0) == 0) primarySeen = true;
    if (fileSize(path) < 0) return "input missing: " + path;
    std::string sha;
    try {
      sha = sha256File(path);
    } catch (const Error&) {
      return "input unreadable: " + path;
    }
    if (sha != in.value("sha256", "")) return "input changed: " + path;
  }
  if (!primarySeen) return "input changed: " + job.input;
  return "";
}

}  // namespace

std::string whyOutOfDate(const Job& job) {
  if (fileSize(job.manifestPath) < 0) return "no manifest";
  json m;
  try {
    m = json::parse(readFile(job.manifestPath));
  } catch (const std::exception&) {
    return "unreadable manifest";
  }
  try {
    return whyOutOfDateParsed(job, m);
  } catch (const json::exception&) {
    return "unknown manifest format";  // a value of the wrong type: rerun and rewrite it
  }
}

}  // namespace prtbake::jobs
