// Job files: loading, schema validation and path resolution (see jobs.h).
#include "jobs.h"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <mutex>
#include <sstream>

#include "confine.h"
#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/mesh.h"

namespace prtbake::jobs {
namespace fs = std::filesystem;

std::vector<std::string> gltfExternalFiles(const std::string& path) {
  std::vector<std::string> files;
  for (const auto& uri : gltfExternalUris(path)) files.push_back((fs::path(path).parent_path() / uri).lexically_normal().string());
  return files;
}

bool sameFile(const std::string& a, const std::string& b) {
  struct stat sa {}, sb {};
  if (::stat(a.c_str(), &sa) == 0 && ::stat(b.c_str(), &sb) == 0) return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
  return fs::absolute(a).lexically_normal() == fs::absolute(b).lexically_normal();
}

std::string harmToInput(const std::string& in, const std::string& out, const std::string& named) {
  const std::string input = named.empty() ? "the input " + in : named;
  if (sameFile(in, out)) return "would overwrite " + input;
  struct stat b {};
  if (::stat(out.c_str(), &b) != 0 || !S_ISDIR(b.st_mode)) return "";
  std::error_code ec, ec2;
  const fs::path dir = fs::canonical(out, ec), file = fs::canonical(in, ec2);
  if (ec || ec2) return "";
  const auto [d, f] = std::mismatch(dir.begin(), dir.end(), file.begin(), file.end());
  return d == dir.end() ? "would delete " + input + ", which lies inside it (the directory is replaced whole)" : "";
}

std::vector<std::string> harmsToInputs(const std::vector<std::string>& inputs, const std::vector<std::string>& outputs) {
  std::vector<std::pair<std::string, std::string>> files;  // each input, then the files it reads, with their names
  for (const auto& in : inputs) {
    if (in.empty()) continue;
    files.emplace_back(in, "");
    for (const auto& f : gltfExternalFiles(in)) files.emplace_back(f, "the input " + f + " (a file " + in + " reads)");
  }
  std::vector<std::string> harms(outputs.size());
  for (size_t i = 0; i < outputs.size(); ++i)
    for (const auto& [file, named] : files)
      if (harms[i].empty() && !outputs[i].empty()) harms[i] = harmToInput(file, outputs[i], named);
  return harms;
}

void checkOutputsSpareInputs(const std::vector<std::string>& inputs, const std::vector<std::string>& outputs) {
  const std::vector<std::string> harms = harmsToInputs(inputs, outputs);
  for (size_t i = 0; i < outputs.size(); ++i)
    if (!harms[i].empty()) throw UsageError(outputs[i], harms[i]);
}

namespace {

const std::vector<std::string> kCommonKeys = {"id", "type", "input", "outputs"};

std::string didYouMean(const std::string& word, const std::vector<std::string>& candidates) {
  const std::string m = closestMatch(word, candidates);
  return m.empty() ? "" : " (did you mean '" + m + "'?)";
}

// A JSON value as it appeared, shortened for messages.
std::string shown(const json& v) {
  std::string s = v.dump();
  if (s.size() > 40) s = s.substr(0, 37) + "...";
  return s;
}

bool validId(const std::string& id) {
  if (id.empty() || id.size() > 128) return false;
  return std::all_of(id.begin(), id.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-';
  });
}

class JobValidator {
 public:
  JobValidator(Job& job, const fs::path& baseDir, const Confinement* confinement)
      : job_(job), baseDir_(baseDir), confinement_(confinement) {}

  void validate(const json& j, size_t position) {
    job_.label = "#" + std::to_string(position);
    if (!j.is_object()) {
      problem("", "expected an object, got " + shown(j));
      return;
    }
    checkId(j);
    if (!checkType(j)) return;
    const JobType& t = *job_.type;
    json params = json::object();
    params["id"] = job_.id;
    params["type"] = t.name;

    std::vector<std::string> known = kCommonKeys;
    for (const auto& k : t.keys) known.push_back(k.name);
    if (t.splittable) {
      known.push_back("split");
      if (auto it = j.find("split"); it != j.end()) {
        if (it->is_boolean()) job_.split = it->get<bool>();
        else problem("split", "expected true or false, got " + shown(*it));
      }
    }
    for (auto it = j.begin(); it != j.end(); ++it) {
      if (std::find(known.begin(), known.end(), it.key()) != known.end()) continue;
      problem(it.key(), "unknown key for " + t.name + " jobs" + didYouMean(it.key(), known));
    }
    KeyProblems keyProblems;
    params.update(normalise(t.keys, j, &keyProblems));
    for (const auto& [key, what] : keyProblems) problem(key, what);
    for (const auto& k : t.keys) {
      if (k.kind != ValueKind::Path || !params[k.name].is_string()) continue;
      params[k.name] = resolve(params[k.name].get<std::string>());
      if (!confinedInput(k.name, params[k.name].get<std::string>())) continue;
      struct stat st {};
      if (::stat(params[k.name].get<std::string>().c_str(), &st) != 0)
        problem(k.name, "file does not exist: " + params[k.name].get<std::string>());
    }
    checkInput(j, &params);
    checkOutputs(j, &params);
    if (job_.valid() && t.check)
      for (const auto& [key, what] : t.check(j, params)) problem(key, what);
    job_.params = params;
    if (!job_.outputs.empty()) job_.manifestPath = job_.outputs.front().path + ".manifest.json";
    if (confinement_ && !job_.manifestPath.empty())
      if (const std::string why = confinement_->checkOutput(job_.manifestPath); !why.empty()) problem("manifest", why);
  }

 private:
  void problem(const std::string& key, const std::string& what) { job_.problems.push_back({job_.label, key, what}); }

  std::string resolve(const std::string& p) const { return (baseDir_ / p).lexically_normal().string(); }

  // Under confinement, a path outside the input roots is refused before anything looks at it
  // (not even whether it exists); a glTF's external files are checked as well.
  bool confinedInput(const std::string& key, const std::string& path) {
    if (!confinement_) return true;
    std::string why = confinement_->checkInput(path);
    // An absolute URI is checked as itself (the loader would join it to the directory).
    if (why.empty())
      for (const auto& file : gltfExternalFiles(path))
        if (why = confinement_->checkInput(file); !why.empty()) break;
    if (!why.empty()) problem(key, why);
    return why.empty();
  }

  void checkId(const json& j) {
    auto it = j.find("id");
    if (it == j.end()) {
      problem("id", "missing");
    } else if (!it->is_string()) {
      problem("id", "expected a string, got " + shown(*it));
    } else if (!validId(it->get<std::string>())) {
      problem("id", "'" + it->get<std::string>() +
                        "' is not a valid id (1 to 128 letters, digits, '.', '_' or '-')");
    } else {
      job_.id = job_.label = it->get<std::string>();
    }
  }

  bool checkType(const json& j) {
    std::vector<std::string> names;
    for (const auto& t : jobTypes()) names.push_back(t.name);
    auto it = j.find("type");
    if (it == j.end()) {
      problem("type", "missing (expected " + joinChoices(names) + ")");
      return false;
    }
    if (!it->is_string()) {
      problem("type", "expected one of " + joinChoices(names) + ", got " + shown(*it));
      return false;
    }
    job_.type = findJobType(it->get<std::string>());
    if (!job_.type) {
      const std::string s = it->get<std::string>();
      problem("type", "unknown job type '" + s + "' (expected " + joinChoices(names) + ")" +
                          (closestMatch(s, names).empty() ? "" : "; did you mean '" + closestMatch(s, names) + "'?"));
      return false;
    }
    return true;
  }

  void checkInput(const json& j, json* params) {
    const JobType& t = *job_.type;
    auto it = j.find("input");
    if (t.input == InputKind::None) {
      if (it != j.end()) problem("input", t.name + " jobs take no input");
      return;
    }
    if (it == j.end()) {
      problem("input", "missing");
      return;
    }
    if (!it->is_string() || it->get<std::string>().empty()) {
      problem("input", "expected a path, got " + shown(*it));
      return;
    }
    const std::string path = resolve(it->get<std::string>());
    if (!confinedInput("input", path)) return;
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) {
      problem("input", "file does not exist: " + path);
      return;
    }
    if (S_ISDIR(st.st_mode) && t.input != InputKind::FileOrDirectory) {
      problem("input", "is a directory, expected a file: " + path);
      return;
    }
    if (::access(path.c_str(), R_OK) != 0) {
      problem("input", "cannot be read: " + path);
      return;
    }
    job_.input = path;
    (*params)["input"] = path;
  }

  void checkOutputs(const json& j, json* params) {
    const JobType& t = *job_.type;
    const std::string expected = joinChoices(t.outputKinds, ", ");
    auto it = j.find("outputs");
    if (it == j.end()) {
      problem("outputs", "missing (expected an object naming one or more of " + expected + ")");
      return;
    }
    if (!it->is_object() || it->empty()) {
      problem("outputs", "expected an object naming one or more of " + expected + ", got " + shown(*it));
      return;
    }
    for (auto o = it->begin(); o != it->end(); ++o)
      if (std::find(t.outputKinds.begin(), t.outputKinds.end(), o.key()) == t.outputKinds.end())
        problem("outputs." + o.key(), "not an output of " + t.name + " jobs (expected " + expected + ")" +
                                          didYouMean(o.key(), t.outputKinds));
    std::vector<std::string> inputs = {job_.input};  // and the files that keys name (an environment)
    for (const auto& k : t.keys)
      if (k.kind == ValueKind::Path && params->contains(k.name) && (*params)[k.name].is_string())
        inputs.push_back((*params)[k.name].get<std::string>());
    json outs = json::object();
    for (const auto& kind : t.outputKinds) {  // the type's order: the first one names the manifest
      auto o = it->find(kind);
      if (o == it->end()) continue;
      const std::string key = "outputs." + kind;
      if (!o->is_string() || o->get<std::string>().empty()) {
        problem(key, "expected a path, got " + shown(*o));
        continue;
      }
      const std::string path = resolve(o->get<std::string>());
      if (confinement_)
        if (const std::string why = confinement_->checkOutput(path); !why.empty()) {
          problem(key, why);
          continue;
        }
      // The finished output is renamed into place: it would replace a device or a pipe.
      struct stat st {};
      if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode) && (kind != "dir" || !S_ISDIR(st.st_mode))) {
        problem(key, S_ISDIR(st.st_mode) ? "is a directory: " + path  // "dir": an ibl package
                                         : "not a regular file (a device, pipe or socket): " + path);
        continue;
      }
      job_.outputs.push_back({kind, path});
      outs[kind] = path;
    }
    std::vector<std::string> paths;
    for (const auto& o : job_.outputs) paths.push_back(o.path);
    const std::vector<std::string> harms = harmsToInputs(inputs, paths);
    for (size_t i = 0; i < paths.size(); ++i)
      if (!harms[i].empty()) problem("outputs." + job_.outputs[i].kind, harms[i]);
    (*params)["outputs"] = outs;
  }

  Job& job_;
  fs::path baseDir_;
  const Confinement* confinement_;
};

}  // namespace

const Output* Job::findOutput(const std::string& kind) const {
  for (const auto& o : outputs)
    if (o.kind == kind) return &o;
  return nullptr;
}

std::vector<std::string> filesRead(const Job& job, const std::vector<std::string>& reported) {
  std::vector<std::string> files;
  if (!reported.empty()) {
    for (const auto& f : reported) files.push_back(fs::absolute(f).lexically_normal().string());
    return files;
  }
  if (job.input.empty()) return files;
  if (!fs::is_directory(job.input)) return {job.input};
  for (const auto& e : fs::directory_iterator(job.input))
    if (e.is_regular_file()) files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  return files;
}

Runtime& processRuntime(const std::string& deviceSpec) {
  // Never destroyed, so that the runtimes stay reachable (not leaks) to the very end.
  static std::mutex mutex;
  static auto* const runtimes = new std::map<std::string, Runtime*>();
  std::lock_guard<std::mutex> lock(mutex);
  Runtime*& rt = (*runtimes)[deviceSpec];
  if (!rt) rt = new Runtime(deviceSpec);
  return *rt;
}

void meshInputs(const Job& job, const Mesh& mesh, ExecResult& result, const std::vector<std::string>& also) {
  std::vector<std::string> read = mesh.inputFiles;
  read.insert(read.end(), also.begin(), also.end());
  result.inputFiles = filesRead(job, read);
  if (!mesh.sourceSha256.empty())
    result.inputHashes[fs::absolute(mesh.sourcePath).lexically_normal().string()] = mesh.sourceSha256;
}

const JobType* findJobType(const std::string& name) {
  for (const auto& t : jobTypes())
    if (t.name == name) return &t;
  return nullptr;
}

namespace {

// nlohmann's serializer (used to show a wrong value in a message) and copies recurse
// once per nesting level, so a job file nested thousands deep would overflow the
// stack. Job files nest four levels; deeper text is refused before it is parsed.
constexpr int kMaxJsonDepth = 64;

int jsonNestingDepth(const std::string& text) {
  int depth = 0, deepest = 0;
  bool inString = false, escaped = false;
  for (const char c : text) {
    if (inString) {
      if (escaped) escaped = false;
      else if (c == '\\') escaped = true;
      else if (c == '"') inString = false;
    } else if (c == '"') {
      inString = true;
    } else if (c == '[' || c == '{') {
      deepest = std::max(deepest, ++depth);
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return deepest;
}

}  // namespace

JobFile loadJobFile(const std::string& path, const std::string& baseDir, const JobFileLimits& limits) {
  JobFile file;
  file.path = path;
  std::string text;
  try {
    struct stat st {};
    if (::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode) && size_t(st.st_size) > limits.maxBytes) {
      file.fileProblems.push_back({"", "", std::to_string(st.st_size) + " bytes, more than the limit of " +
                                               std::to_string(limits.maxBytes) + " for a job file"});
      return file;
    }
    text = readFile(path);
  } catch (const Error& e) {
    file.fileProblems.push_back({"", "", e.detail()});
    return file;
  }
  if (jsonNestingDepth(text) > kMaxJsonDepth) {
    file.fileProblems.push_back({"", "", "JSON nested deeper than " + std::to_string(kMaxJsonDepth) + " levels"});
    return file;
  }
  json root;
  try {
    root = json::parse(text);
  } catch (const json::exception& e) {  // parse_error, and out_of_range for numbers like 1e400
    std::string what = e.what();
    if (auto pos = what.find("] "); what.rfind("[json.exception", 0) == 0 && pos != std::string::npos)
      what = what.substr(pos + 2);
    file.fileProblems.push_back({"", "", what});
    return file;
  }
  if (!root.is_object()) {
    file.fileProblems.push_back({"", "", "expected an object {\"jobs\": [...]}, got " + shown(root)});
    return file;
  }
  for (auto it = root.begin(); it != root.end(); ++it)
    if (it.key() != "jobs")
      file.fileProblems.push_back({"", it.key(), "unknown key" + didYouMean(it.key(), {"jobs"})});
  auto jobs = root.find("jobs");
  if (jobs == root.end() || !jobs->is_array()) {
    file.fileProblems.push_back({"", "jobs", jobs == root.end() ? "missing" : "expected an array, got " + shown(*jobs)});
    return file;
  }
  if (jobs->size() > limits.maxJobs) {
    file.fileProblems.push_back({"", "jobs", std::to_string(jobs->size()) + " jobs, more than the limit of " +
                                                 std::to_string(limits.maxJobs) + " for a job file"});
    return file;
  }
  const fs::path base = baseDir.empty() ? fs::absolute(path).parent_path() : fs::absolute(baseDir);
  std::map<std::string, std::string> firstPosition;  // id → label of its first job
  size_t position = 0;
  for (const auto& j : *jobs) {
    Job job;
    job.jobFile = path;
    JobValidator(job, base, limits.confinement).validate(j, ++position);
    if (!job.id.empty()) {
      auto [it, inserted] = firstPosition.emplace(job.id, "#" + std::to_string(position));
      if (!inserted)
        job.problems.push_back({job.label, "id",
                                "duplicate id: job #" + std::to_string(position) + " repeats the id of job " + it->second});
    }
    file.jobs.push_back(std::move(job));
  }
  return file;
}

void checkOutputConflicts(std::vector<JobFile>& files) {
  struct Owner {
    const Job* job;
    std::string key;
  };
  std::map<std::string, Owner> owners;  // canonical path → first writer
  for (auto& file : files) {
    for (auto& job : file.jobs) {
      if (!job.valid()) continue;
      std::vector<std::pair<std::string, std::string>> written;  // key, path
      for (const auto& o : job.outputs) written.push_back({"outputs." + o.kind, o.path});
      written.push_back({"manifest", job.manifestPath});
      std::vector<Problem> found;
      for (const auto& [key, path] : written) {
        std::error_code ec;
        const std::string canon = fs::weakly_canonical(path, ec).string();
        const std::string id = ec ? path : canon;
        auto [it, inserted] = owners.emplace(id, Owner{&job, key});
        if (inserted) continue;
        const Owner& first = it->second;
        std::string who = first.job == &job ? first.key
                                            : "job '" + first.job->label + "'" +
                                                  (first.job->jobFile == job.jobFile ? "" : " of " + first.job->jobFile) +
                                                  " (" + first.key + ")";
        found.push_back({job.label, key, path + " is also written by " + who});
      }
      job.problems.insert(job.problems.end(), found.begin(), found.end());
    }
  }
}

std::string formatProblem(const std::string& jobFile, const Problem& p) {
  std::string s = jobFile + ": ";
  if (!p.job.empty()) s += "job '" + p.job + "': ";
  if (!p.key.empty()) s += p.key + ": ";
  return Error::oneLine(s + p.what);  // a key or id from the file may hold a newline
}

std::string closestMatch(const std::string& word, const std::vector<std::string>& candidates) {
  // Optimal-string-alignment distance (a transposition counts as one edit), case-insensitive.
  auto lower = [](std::string s) {
    for (auto& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
    return s;
  };
  const std::string a = lower(word);
  std::string best;
  size_t bestDistance = std::string::npos;
  for (const auto& candidate : candidates) {
    const std::string b = lower(candidate);
    std::vector<std::vector<size_t>> d(a.size() + 1, std::vector<size_t>(b.size() + 1));
    for (size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
    for (size_t k = 0; k <= b.size(); ++k) d[0][k] = k;
    for (size_t i = 1; i <= a.size(); ++i)
      for (size_t k = 1; k <= b.size(); ++k) {
        d[i][k] = std::min({d[i - 1][k] + 1, d[i][k - 1] + 1, d[i - 1][k - 1] + (a[i - 1] != b[k - 1])});
        if (i > 1 && k > 1 && a[i - 1] == b[k - 2] && a[i - 2] == b[k - 1])
          d[i][k] = std::min(d[i][k], d[i - 2][k - 2] + 1);
      }
    if (d[a.size()][b.size()] < bestDistance) {
      bestDistance = d[a.size()][b.size()];
      best = candidate;
    }
  }
  // Close enough to be a slip: at most 2 edits, and fewer than half the word.
  if (bestDistance == std::string::npos || bestDistance > 2 || 2 * bestDistance >= std::max<size_t>(a.size(), 2))
    return "";
  return best;
}

}  // namespace prtbake::jobs
