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
//   one-process run on the same device type.
// A shard whose job fails records why in <first output>.shard-I-of-N.failed.json
// (removed when the job later succeeds), so that merge can name failed shards.
#pragma once

#include <string>
#include <utility>

#include "jobs.h"

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

}  // namespace prtbake::jobs
