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

#include "options.h"
#include "prtbake/runtime.h"
#include "prtbake/env.h"
#include "prtbake/glossy.h"
#include "prtbake/ibl.h"
#include "prtbake/lut.h"
#include "prtbake/prefilter.h"
#include "prtbake/lightmap.h"
#include "prtbake/probes.h"
#include "prtbake/transport.h"

namespace prtbake::jobs {

using nlohmann::json;

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

// A product's library options from its normalised parameters (a job's, or the command
// line's: productParams in cli.h), in job_types.cpp; the glossy ones in job_glossy.cpp.
EnvLoadOptions envLoadOptionsFrom(const json& params, bool compact);
EnvProjectOptions envProjectOptionsFrom(const json& params);  // order auto: kAutoReferenceOrder
TransportOptions transportOptionsFrom(const json& params);
LutOptions lutOptionsFrom(const json& params);  // validated
PrefilterOptions prefilterOptionsFrom(const json& params);
IblPackageOptions iblOptionsFrom(const json& params);  // validated
GlossyOptions glossyOptionsFrom(const json& params);
CpcaOptions cpcaOptionsFrom(const json& params);
// The exit-radiance BRDF matrix of keys brdf, roughness and f0 (empty for brdf none).
std::vector<double> brdfFrom(const json& params, int orderOut);

// Order "auto" of env: the projection at kAutoReferenceOrder is cut to the smallest order up
// to kAutoMaxOrder whose truncation error (relative L2 over the sphere, in the quantity asked,
// against that reference) is within the key `tolerance` (null: 0.01); r and po are updated
// (window and quantity applied again) and the sidecar's "order_selection" returned.
constexpr int kAutoReferenceOrder = 24, kAutoMaxOrder = 20;
json selectEnvOrder(EnvProjectResult& r, EnvProjectOptions& po, const json& tolerance);

// The glossy transfer job (job_glossy.cpp): its type, the type of one shard's vertex range
// of a split glossy job, and the merge of those ranges (after cmd_merge.cpp has checked every
// partial's manifest; returns the problems, empty when merged and written).
JobType glossyJobType();

// The probe grid job (job_probes.cpp): its type, the library's options from its parameters,
// and its lighting (the key env: a radiance SH JSON, an environment map projected to env_order,
// or none: constant white), the files read appended to *files.
JobType probesJobType();
const JobType& probesPartialType();
// The probes job's png output (and prtbake probes --preview): renderProbeGridPreview's PNG.
std::string probeGridPreviewPngBytes(const Mesh& mesh, const ProbeGridResult& grid, Runtime& rt);
std::vector<std::string> mergeProbesSplit(const Job& job, int shards, const std::vector<json>& manifests, json* info);
ProbeOptions probeOptionsFrom(const json& params);
ShCoeffs probeEnvironment(const json& params, const std::function<Runtime&()>& runtime, std::vector<std::string>* files);
const JobType& glossyPartialType();

// The lightmap job (job_lightmap.cpp): its type, the library's options from its parameters, and
// the bytes of the outputs named in `outputs` (kind → path; kinds <product>_exr, <product>_ktx2,
// ao_png, gltf: the input's copy with the AO as occlusionTexture, json). Its lighting is the probes' key env (probeEnvironment).
JobType lightmapJobType();
LightmapOptions lightmapOptionsFrom(const json& params);
std::vector<std::pair<std::string, std::string>> lightmapOutputBytes(const std::map<std::string, std::string>& outputs,
                                                                     const std::string& input, const Mesh& mesh,
                                                                     const json& params, const LightmapOptions& options,
                                                                     const LightmapResult& lightmap);
json lightmapReport(const LightmapResult& lightmap);
// A split lightmap job (docs/scaleout.md): each shard bakes a range of the samples (the partial
// .npy of lightmapRangeNpyBytes), the merge assembles them and runs the repairs once.
const JobType& lightmapPartialType();
std::vector<std::string> mergeLightmapSplit(const Job& job, int shards, const std::vector<json>& manifests, json* info);
std::vector<std::string> mergeGlossySplit(const Job& job, int shards, const std::vector<json>& manifests, json* info);

// The parameters of `type` from command-line texts (key → text, flags ""): each value read
// by cliValue and checked by checkValue as a job's is, defaults filled, then the type's rules
// run as on a job whose outputs are `outputs` (options.cpp). Problems go to *problems.
json paramsFromText(const JobType& type, const std::map<std::string, std::string>& texts, const json& outputs,
                    KeyProblems* problems);

// A key's default and range or values, as --help and docs/jobs.md show them: "1..32, default 3".
std::string describeRange(const KeySpec& k);

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

class Confinement;

// What a job file may be and do, for files that someone else wrote (docs/jobs.md, "A shared
// queue"): its size and job count, checked before it is parsed, and the roots its jobs may
// read and write (confine.h; none: anywhere).
struct JobFileLimits {
  size_t maxBytes = size_t(16) << 20;
  size_t maxJobs = 10000;
  const Confinement* confinement = nullptr;
};

// Loads and validates `path`. Relative paths inside resolve against `baseDir`
// (default: the job file's own directory). Never throws for bad content: every
// problem is recorded in the result.
JobFile loadJobFile(const std::string& path, const std::string& baseDir = "", const JobFileLimits& limits = {});

// Every file a job read, absolute: the product's list, or else the input itself
// (every regular file in it when it is a directory).
std::vector<std::string> filesRead(const Job& job, const std::vector<std::string>& reported);
// A mesh product's inputs: the mesh's files and `also` (filesRead), and the hash the mesh
// loader took of what it parsed.
void meshInputs(const Job& job, const Mesh& mesh, ExecResult& result, const std::vector<std::string>& also = {});

// The files a .gltf or .glb at `path` names by URI (gltfExternalUris), resolved against its
// directory; none for another file.
std::vector<std::string> gltfExternalFiles(const std::string& path);

// Whether two paths name the same file: by device and inode when both exist (a link or another
// spelling of the path included), else the same absolute path.
bool sameFile(const std::string& a, const std::string& b);

// What writing `out` would do to the input `in` (named "the input IN" unless `named` is given):
// "" nothing; "would overwrite the input IN" when they are the same file (sameFile); "would
// delete the input IN, which lies inside it (...)" when `out` is a directory that holds it (a
// directory output, an ibl package, is replaced whole).
std::string harmToInput(const std::string& in, const std::string& out, const std::string& named = "");
// For each of `outputs`, the first harm of writing it to one of `inputs` (empty ones skipped) or
// to a file that one of them, a glTF, reads (its buffers and images: each glTF is read once).
std::vector<std::string> harmsToInputs(const std::vector<std::string>& inputs, const std::vector<std::string>& outputs);

// A UsageError naming the first of `outputs` that would overwrite or delete one of `inputs` or
// a file a glTF among them reads (harmsToInputs), before anything is read or written.
void checkOutputsSpareInputs(const std::vector<std::string>& inputs, const std::vector<std::string>& outputs);

// Marks jobs (across all files) that write a file another job writes, or whose
// manifest would collide with another job's file. The first writer keeps it.
void checkOutputConflicts(std::vector<JobFile>& files);

// "prtbake: error: <jobfile>: job '<id>': <key>: <what>" (without the "prtbake: error: ").
std::string formatProblem(const std::string& jobFile, const Problem& p);

// The candidate closest to `word` by edit distance, or "" when none is close.
std::string closestMatch(const std::string& word, const std::vector<std::string>& candidates);

}  // namespace prtbake::jobs
