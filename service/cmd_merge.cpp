// prtbake merge: assemble the outputs of a job file run as N shards (docs/scaleout.md).
//
// Whole jobs (job k ran in shard k mod N) need nothing assembled: merge checks that
// each is complete (its manifest shows it up to date). A transport job with
// "split": true is assembled from its N partial results: every partial must be
// present, made by this prtbake version with the job's parameters and the shard's
// index, from inputs that still hash the same, with the expected vertex range and
// the recorded SHA-256; then the coefficients are concatenated in vertex order and
// written through the same writers as a one-process run (bit-identical outputs),
// followed by the job's manifest, so a later `prtbake run` sees the job up to date.
#include <array>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <iomanip>

#include "cli.h"
#include "manifest.h"
#include "prtbake/atomic_file.h"
#include "prtbake/clock.h"
#include "prtbake/error.h"
#include "prtbake/hash.h"
#include "prtbake/mesh.h"
#include "prtbake/transport.h"
#include "runner.h"
#include "shard.h"

namespace prtbake::cli {
namespace {

using jobs::json;
using Clock = std::chrono::steady_clock;

bool exists(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0;
}

std::string formatSeconds(double s) {
  std::ostringstream ss;
  ss << std::fixed << std::setprecision(2) << s << " s";
  return ss.str();
}

// Why shard i's part of `job` cannot be used ("" when it can), from its failure
// marker, its manifest and its partial file.
std::string partialProblem(const jobs::Job& job, int i, int n, json* manifest) {
  const jobs::ShardSpec s{i, n};
  const jobs::Job part = jobs::partialJob(job, s);
  const std::string why = jobs::whyOutOfDate(part);
  if (why == "no manifest") {
    const std::string marker = jobs::failureMarkerPath(job, i, n);
    if (exists(marker)) {
      std::string error = "see " + marker;
      try {
        error = json::parse(readFile(marker)).value("error", error);
      } catch (const std::exception&) {
      }
      return "shard " + s.name() + " failed: " + error;
    }
    return "shard " + s.name() + " missing: no partial result (" + part.manifestPath + ")";
  }
  if (!why.empty()) return "shard " + s.name() + " is not usable: " + why;
  try {
    *manifest = json::parse(readFile(part.manifestPath));
  } catch (const std::exception& e) {
    return "shard " + s.name() + " is not usable: unreadable manifest";
  }
  const json& report = (*manifest)["report"];
  const std::string path = part.outputs.front().path;
  if (report.value("partial_sha256", "") != sha256File(path))
    return "shard " + s.name() + " is not usable: " + path + " does not match its manifest's SHA-256";
  // Transport and glossy shards hold vertex ranges, probe shards ranges of the grid's probes,
  // lightmap shards ranges of the texels' samples.
  const bool probes = report.contains("grid_probes"), texels = report.contains("lightmap_samples");
  using Keys = std::array<const char*, 4>;  // the total, the range's first and count, what is counted
  const Keys keys = probes   ? Keys{"grid_probes", "first_probe", "probe_count", "probe"}
                    : texels ? Keys{"lightmap_samples", "first_sample", "sample_count", "sample"}
                             : Keys{"mesh_vertices", "first_vertex", "vertex_count", "vertex"};
  const auto [first, count] = jobs::vertexRange(jobs::manifestInt(report, keys[0], size_t(0)), i, n);
  if (jobs::manifestInt(report, keys[1], size_t(1) << 62) != first ||
      jobs::manifestInt(report, keys[2], size_t(1) << 62) != count)
    return "shard " + s.name() + " is not usable: its " + keys[3] + " range does not match shard " + s.name();
  return "";
}

// Assembles a split transport job; returns the problems (empty: merged and written).
std::vector<std::string> mergeSplit(const jobs::Job& job, int n, json* info) {
  std::vector<std::string> problems;
  std::vector<json> manifests(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i)
    if (std::string p = partialProblem(job, i, n, &manifests[size_t(i)]); !p.empty()) problems.push_back(p);
  if (!problems.empty()) return problems;
  const size_t vertices = jobs::manifestInt(manifests[0]["report"], "mesh_vertices", size_t(0));
  for (int i = 1; i < n; ++i)
    if (jobs::manifestInt(manifests[size_t(i)]["report"], "mesh_vertices", size_t(0)) != vertices ||
        manifests[size_t(i)]["inputs"] != manifests[0]["inputs"])
      problems.push_back("shard " + jobs::ShardSpec{i, n}.name() + " read other inputs than shard " +
                         jobs::ShardSpec{0, n}.name());
  if (!problems.empty()) return problems;
  if (job.type->name == "glossy") return jobs::mergeGlossySplit(job, n, manifests, info);
  if (job.type->name == "probes") return jobs::mergeProbesSplit(job, n, manifests, info);
  if (job.type->name == "lightmap") return jobs::mergeLightmapSplit(job, n, manifests, info);

  const TransportOptions options = jobs::transportOptionsFrom(job.params);
  TransportResult r;
  r.order = options.order;
  r.channels = 1;
  r.samples = options.samples;
  r.vertexCount = vertices;
  r.coeffs.reserve(vertices * size_t(r.order) * r.order);
  double errorSum = 0;
  for (int i = 0; i < n; ++i) {
    const json& rep = manifests[size_t(i)]["report"];
    size_t rows = 0, columns = 0;
    const std::string path = jobs::partialPath(job, i, n);
    const std::vector<float> part = jobs::readPartialNpy(path, &rows, &columns);
    if (rows != jobs::manifestInt(rep, "vertex_count", size_t(0)) || columns != size_t(r.order) * r.order)
      throw InputError(path, "shape does not match the job (order " + std::to_string(r.order) + ")");
    r.coeffs.insert(r.coeffs.end(), part.begin(), part.end());
    r.totalSamples += jobs::manifestInt(rep, "total_samples", uint64_t(0));
    r.bvhSeconds += rep["timings"].value("bvh_seconds", 0.0);
    jobs::addShardReport(r, rep, &errorSum);
  }
  r.meanStdError = vertices ? errorSum / double(vertices) : 0;

  // Every output's bytes first, then the writes (as runTransport does).
  const bool needMesh = job.findOutput("gltf") || job.findOutput("games202") || job.findOutput("json");
  Mesh mesh;
  if (needMesh) mesh = jobs::loadMergedMesh(job, vertices);
  std::vector<std::pair<std::string, std::string>> files;
  for (const auto& o : job.outputs) {
    if (o.kind == "npy") files.emplace_back(o.path, transportNpyBytes(r));
    if (o.kind == "games202") files.emplace_back(o.path, games202TransportBytes(mesh, r));
    if (o.kind == "gltf") files.emplace_back(o.path, transportGltfBytes(o.path, mesh, r));
    if (o.kind == "json") files.emplace_back(o.path, transportSidecarBytes(job.input, mesh, options, r));
  }
  jobs::removeOldManifest(job);
  for (const auto& [path, bytes] : files) writeFileAtomic(path, bytes);
  const json report = {{"vertices", r.vertexCount},
                       {"channels", r.channels},
                       {"samples", r.samples},
                       {"rays", r.rays},
                       {"bounces_used", 0},
                       {"standard_error_max", r.maxStdError},
                       {"standard_error_mean", r.meanStdError},
                       {"shards", n},
                       {"timings", {{"bvh_seconds", r.bvhSeconds}, {"kernel_seconds", r.kernelSeconds},
                                    {"total_seconds", r.totalSeconds}}}};
  jobs::writeMergedManifest(job, manifests[0], r.device, r.totalSeconds, report);
  *info = {{"vertices", vertices}};
  return {};
}

int runMerge(const CommandLine& cl) {
  if (!cl.has("shards")) throw UsageError("merge", "missing --shards N (the N of prtbake run --shard I/N)");
  const int n = int(cl.getInt("shards", 0, 1, 100000));
  jobs::Reporter reporter(cl.quiet(), cl.has("log-json"));
  const auto t0 = Clock::now();
  std::vector<jobs::JobFile> files;
  for (const auto& p : cl.positional) files.push_back(jobs::loadJobFile(p));
  jobs::checkOutputConflicts(files);
  int merged = 0, complete = 0, failed = 0;
  for (const auto& f : files) {
    if (!f.fileProblems.empty()) ++failed;
    for (const auto& p : f.fileProblems) reporter.error(jobs::formatProblem(f.path, p));
    for (const auto& job : f.jobs)
      for (const auto& p : job.problems) reporter.error(jobs::formatProblem(f.path, p));
  }
  auto fail = [&](const jobs::Job& job, const std::string& reason) {
    ++failed;
    reporter.status("[failed] " + job.label + ": " + reason);
    if (reporter.quiet()) reporter.error(job.jobFile + ": job '" + job.label + "': " + reason);
    reporter.event({{"event", "job_end"}, {"id", job.label}, {"status", "failed"}, {"error", reason}});
  };
  size_t position = 0;
  for (const auto& f : files)
    for (const auto& job : f.jobs) {
      const size_t k = position++;
      const auto tJob = Clock::now();
      if (!job.valid()) {
        fail(job, "invalid job (see above)");
      } else if (jobs::isSplit(job)) {
        try {
          json info;
          const std::vector<std::string> problems = mergeSplit(job, n, &info);
          if (!problems.empty()) {
            std::string text;
            for (const auto& p : problems) text += (text.empty() ? "" : "; ") + p;
            fail(job, "cannot merge: " + text);
            continue;
          }
          ++merged;
          reporter.status("[merged] " + job.label + " (" + std::to_string(n) + " shards, " +
                          (info.contains("probes")   ? std::to_string(jobs::manifestInt(info, "probes", size_t(0))) + " probes, "
                           : info.contains("texels") ? std::to_string(jobs::manifestInt(info, "texels", size_t(0))) + " texels, "
                                                     : std::to_string(jobs::manifestInt(info, "vertices", size_t(0))) + " vertices, ") +
                          formatSeconds(secondsSince(tJob)) + ")");
          reporter.event({{"event", "job_end"}, {"id", job.label}, {"status", "merged"}});
        } catch (const std::exception& e) {
          fail(job, e.what());
        }
      } else {
        const jobs::ShardSpec s{jobs::shardOfJob(k, n), n};
        const std::string why = jobs::whyOutOfDate(job);
        if (why.empty()) {
          ++complete;
          reporter.status("[ok] " + job.label + " (shard " + s.name() + ")");
          reporter.event({{"event", "job_end"}, {"id", job.label}, {"status", "ok"}});
          continue;
        }
        const std::string marker = jobs::failureMarkerPath(job, s.index, n);
        std::string reason = "shard " + s.name() + " has not completed it (" + why + ")";
        if (exists(marker)) {
          reason = "shard " + s.name() + " failed";
          try {
            reason += ": " + json::parse(readFile(marker)).value("error", std::string("see ") + marker);
          } catch (const std::exception&) {
          }
        }
        fail(job, reason);
      }
    }
  const double seconds = secondsSince(t0);
  reporter.status(std::to_string(merged + complete + failed) + " jobs: " + std::to_string(merged) + " merged, " +
                  std::to_string(complete) + " complete, " + std::to_string(failed) + " failed (" +
                  formatSeconds(seconds) + ")");
  reporter.event({{"event", "summary"}, {"merged", merged}, {"complete", complete}, {"failed", failed},
                  {"seconds", seconds}});
  return failed == 0 ? 0 : 1;
}

PRTBAKE_COMMAND(Command{
    "merge", "assemble the outputs of a job file run as N shards (prtbake run --shard I/N)",
    "prtbake merge JOBFILE... --shards N\n\n"
    "For every transport job with \"split\": true, checks that all N partial results are\n"
    "present and consistent (same parameters, inputs and prtbake version; shard I of N; the\n"
    "recorded SHA-256) and writes the job's outputs and manifest, bit-identical to a\n"
    "one-process run on the same device type. Every other job must have been completed by\n"
    "its shard (job k: shard k mod N). Names every missing or failed shard. Exit code 0 when\n"
    "everything is merged or complete, 1 otherwise, 2 for usage errors. See docs/scaleout.md.",
    {{"shards", true, "the number of shards N the job files were run with"}},
    1, 1000000, runMerge});

}  // namespace
}  // namespace prtbake::cli
