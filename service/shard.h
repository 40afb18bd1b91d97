// Scale-out: one job file run as N shards (Slurm array tasks, Kubernetes Indexed
// Jobs, or any N processes), then merged (docs/scaleout.md).
//
// Partition rule, fixed so that every shard and the merge agree without talking:
// - jobs are numbered k = 0, 1, 2, ... in job-file order (across the job files of
//   the command line, in their order); job k belongs to shard k mod N;
// - except a transport job with "split": true (unshadowed or shadowed), which every
//   shard runs for its own vertex range [⌊iV/N⌋, ⌊(i+1)V/N⌋) against the whole
//   mesh, writing a partial result <first output>.shard-I-of-N.npy with its own
//   manifest (<partial>.manifest.json) next to the job's first output. `prtbake
//   merge` concatenates the partials into the job's outputs, bit-identical to a
//   one-process run on the same device type. Glossy, probes and lightmap jobs split alike
//   (ranges of vertices, of the grid's probes, of the texels' samples; docs/scaleout.md).
// A shard whose job fails records why in <first output>.shard-I-of-N.failed.json
// (removed when the job later succeeds), so that merge can name failed shards.
#pragma once

#include <algorithm>
#include <string>
#include <utility>

#include "jobs.h"
#include "manifest.h"

namespace prtbake::jobs {

struct ShardSpec {
  int index = 0;  // I, 0-based
  int count = 0;  // N; 0: not sharded
  bool active() const { return count > 0; }
  std::string name() const { return std::to_string(index) + "/" + std::to_string(count); }
};

// "I/N" with 0 ≤ I < N ≤ 100000, or "auto/N" (I from $SLURM_ARRAY_TASK_ID, else
// $JOB_COMPLETION_INDEX). Throws UsageError naming `option`.
ShardSpec parseShardSpec(const std::string& text, const std::string& option = "--shard");

// The shard that runs whole job number `position` (0-based).
inline int shardOfJob(size_t position, int count) { return int(position % size_t(count)); }

// Whether `job` is split by vertices across the shards.
inline bool isSplit(const Job& job) { return job.valid() && job.split; }

// Shard i's vertex range of `vertices` vertices: {first, count}.
std::pair<size_t, size_t> vertexRange(size_t vertices, int index, int count);

// <first output>.shard-I-of-N.npy
std::string partialPath(const Job& job, int index, int count);
// <first output>.shard-I-of-N.failed.json
std::string failureMarkerPath(const Job& job, int index, int count);

// The job that shard `s` runs for a split job: it computes the shard's vertex range
// and writes only the partial result (its manifest records the job's parameters
// plus "shard": {"index", "count"}).
Job partialJob(const Job& job, ShardSpec s);

// Reads a partial result written by the partial job: float32 [vertices, n²].
std::vector<float> readPartialNpy(const std::string& path, size_t* vertices, size_t* columns);

// Merging: what the split products (transport, glossy) do alike.

// Adds one shard's report to the merged statistics (TransportResult or GlossyStats: the
// fields they share): rays, vertex counts and kernel and total seconds summed, the largest
// standard error, BVH and degenerate counts the most of any shard (each shard builds the
// whole mesh's BVH), the first device; the mean standard error is accumulated, weighted by
// the shard's vertices, into *errorSum (divide by all the vertices at the end).
template <class Stats>
void addShardReport(Stats& s, const json& report, double* errorSum) {
  s.rays += manifestInt(report, "rays", uint64_t(0));
  s.verticesUnoccludable += manifestInt(report, "vertices_unoccludable", size_t(0));
  s.verticesWithoutNormal += manifestInt(report, "vertices_without_normal", size_t(0));
  s.maxStdError = std::max(s.maxStdError, report.value("standard_error_max", 0.0));
  *errorSum += report.value("standard_error_mean", 0.0) * double(manifestInt(report, "vertex_count", size_t(0)));
  s.bvhNodes = std::max(s.bvhNodes, manifestInt(report, "bvh_nodes", size_t(0)));
  s.degenerateTriangles = std::max(s.degenerateTriangles, manifestInt(report, "degenerate_triangles", size_t(0)));
  if (s.device.empty()) s.device = report.value("device", "");
  const json& t = report["timings"];
  s.kernelSeconds += t.value("kernel_seconds", 0.0);
  s.totalSeconds += t.value("total_seconds", 0.0);
}

// The job's mesh, which must have the `vertices` vertices the shards saw (InputError).
Mesh loadMergedMesh(const Job& job, size_t vertices);

// Removes the job's old manifest before the merged outputs are written, so that it never
// vouches for a mixed set (OutputError when it cannot).
void removeOldManifest(const Job& job);

// Writes the merged job's manifest last: the inputs the shards hashed (`shardManifest`'s),
// the device, the shards' summed seconds and the report.
void writeMergedManifest(const Job& job, const json& shardManifest, const std::string& device, double shardSeconds,
                         const json& report);

}  // namespace prtbake::jobs
