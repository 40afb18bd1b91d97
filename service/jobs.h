// Job files: the registry of job types, their schemas, and loading and
// validating a job file (docs/jobs.md is the user-facing description).
//
// A job file is {"jobs": [{"id": ..., "type": ..., "input": ..., "outputs": {...}, ...}]}.
// Each job type declares its keys (name, kind, range or choices, default), the
// output kinds it can write and whether it reads an input; validation checks a
// whole file before anything runs and collects every problem of every job, so
// that one bad job never hides another and never stops the valid ones.
// Nothing here computes anything: executors call the library (job_types.cpp).
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "prtbake/runtime.h"
#include "prtbake/transport.h"

namespace prtbake::jobs {

using nlohmann::json;

// Path: a file that must exist, relative paths resolved like `input`. NumberList: a JSON
// array of 1 to 16 numbers, each in [lo, hi].
enum class ValueKind { Integer, Number, Boolean, Choice, Path, NumberList };

// One key of a job type, named and typed like the command-line option it mirrors.
struct KeySpec {
  std::string name;
  ValueKind kind;
  json defaultValue;                 // null: the key is optional and has no default
  double lo = 0, hi = 0;             // inclusive range of Integer and Number keys
  std::vector<std::string> choices;  // the values of a Choice key
};

struct Job;

// The OpenCL runtime of this process on device `deviceSpec` (as Runtime's constructor takes
// it), started on first use and then kept until the process ends: never released, because
// releasing the context makes PoCL free its compiler's state (0.1 s after a cold build,
// measured), which a process about to exit has no use for. Thread-safe.
Runtime& processRuntime(const std::string& deviceSpec);

// What an executor gets besides the job: the shared OpenCL runtime (created on
// first use) and the paths to write each requested output to. The runner moves
// those files to their final names only when the whole job has succeeded.
struct ExecContext {
  std::function<Runtime&()> runtime;
  std::map<std::string, std::string> outputPaths;  // output kind → path to write
  const std::string& output(const std::string& kind) const { return outputPaths.at(kind); }
  bool wants(const std::string& kind) const { return outputPaths.count(kind) != 0; }
};

struct ExecResult {
  std::vector<std::string> inputFiles;  // every file the product read (for the manifest)
  // SHA-256 of inputs as the product parsed them, where the loader took it (absolute
  // path → hex): the manifest then vouches for the bytes the outputs came from.
  std::map<std::string, std::string> inputHashes;
  json report = json::object();         // sample counts, error estimates, product timings
};

enum class InputKind { None, File, FileOrDirectory };

struct JobType {
  std::string name;
  InputKind input = InputKind::None;
  std::vector<std::string> outputKinds;  // allowed kinds, in manifest-naming order
  std::vector<KeySpec> keys;
  // Cross-key rules (e.g. samples excludes tolerance), given the job as written and
  // its normalised parameters; returns {key, what} problems.
  std::function<std::vector<std::pair<std::string, std::string>>(const json& raw, const json& params)> check;
  std::function<ExecResult(const Job&, ExecContext&)> execute;
  // Accepts the key "split" (true: `prtbake run --shard I/N` splits the job by vertex
  // ranges across the shards; docs/scaleout.md). It selects how the work is spread,
  // not what is computed, so it is not one of the parameters.
  bool splittable = false;
};

// The TransportOptions of a transport job's normalised parameters (job_types.cpp).
TransportOptions transportOptionsFrom(const json& params);

// The glossy transfer job (job_glossy.cpp): its type, the type of one shard's vertex range
// of a split glossy job, and the merge of those ranges (after cmd_merge.cpp has checked every
// partial's manifest; returns the problems, empty when merged and written).
JobType glossyJobType();
const JobType& glossyPartialType();
std::vector<std::string> mergeGlossySplit(const Job& job, int shards, const std::vector<json>& manifests, json* info);

// Every job type of this build (job_types.cpp).
const std::vector<JobType>& jobTypes();
const JobType* findJobType(const std::string& name);

// A problem found while validating. `job` is the job's label ("id" or "#N" when
// it has no usable id); empty for problems of the file as a whole.
struct Problem {
  std::string job;
  std::string key;  // "order", "outputs.json", ... (empty when it is about the job itself)
  std::string what;
};

struct Output {
  std::string kind;
  std::string path;  // absolute, normalised
};

struct Job {
  std::string label;               // id, or "#N" (1-based position) when the id is unusable
  std::string id;                  // empty when missing or invalid
  const JobType* type = nullptr;
  std::string jobFile;             // as named on the command line (for messages)
  std::string input;               // absolute path; empty for types without input
  std::vector<Output> outputs;     // in the type's output-kind order
  json params;                     // normalised: every key with its default, absolute paths
  std::string manifestPath;        // <first output>.manifest.json
  std::vector<Problem> problems;   // empty ⇔ the job is valid
  bool split = false;              // "split": true (types that are splittable only)
  // Where the runner records why the job failed (a JSON file), when set; removed
  // again when the job succeeds or is up to date (sharded runs; docs/scaleout.md).
  std::string failureMarker;

  bool valid() const { return problems.empty(); }
  const Output* findOutput(const std::string& kind) const;
};

struct JobFile {
  std::string path;                 // as given (used in messages)
  std::vector<Job> jobs;
  std::vector<Problem> fileProblems;  // unreadable file, JSON syntax error, bad top level
};

// Loads and validates `path`. Relative paths inside resolve against `baseDir`
// (default: the job file's own directory). Never throws for bad content: every
// problem is recorded in the result.
JobFile loadJobFile(const std::string& path, const std::string& baseDir = "");

// Every file a job read, absolute: the product's list, or else the input itself
// (every regular file in it when it is a directory).
std::vector<std::string> filesRead(const Job& job, const std::vector<std::string>& reported);
// A mesh product's inputs: the mesh's files and `also` (filesRead), and the hash the mesh
// loader took of what it parsed.
void meshInputs(const Job& job, const Mesh& mesh, ExecResult& result, const std::vector<std::string>& also = {});

// Marks jobs (across all files) that write a file another job writes, or whose
// manifest would collide with another job's file. The first writer keeps it.
void checkOutputConflicts(std::vector<JobFile>& files);

// "prtbake: error: <jobfile>: job '<id>': <key>: <what>" (without the "prtbake: error: ").
std::string formatProblem(const std::string& jobFile, const Problem& p);

// The candidate closest to `word` by edit distance, or "" when none is close.
std::string closestMatch(const std::string& word, const std::vector<std::string>& candidates);

}  // namespace prtbake::jobs
