// Per-job manifests: the record that makes reruns incremental.
//
// After every output of a job is in place, the runner writes
// <first output>.manifest.json (atomically, last) holding the prtbake version,
// the normalised job parameters, every input file with its SHA-256, every
// output with its size, the device and the timings. A later run skips the job
// when version and parameters are equal, every input hashes the same and every
// output still exists with its recorded size.
#pragma once

#include <string>
#include <vector>

#include "jobs.h"

namespace prtbake::jobs {

struct InputHash {
  std::string path;
  std::string sha256;
};

// SHA-256 of each file (throws InputError naming a file that cannot be read).
std::vector<InputHash> hashInputs(const std::vector<std::string>& files);

// The manifest of a job whose outputs are now committed.
json makeManifest(const Job& job, const std::vector<InputHash>& inputs, const std::string& device,
                  const json& timings, const json& report);

// The current time as ISO 8601 UTC ("2026-11-22T16:55:33Z"), for manifests and logs.
std::string utcNow();

// Why `job` must run: "" when its manifest shows it is up to date, otherwise a
// short reason ("no manifest", "parameters changed: order", "input changed: <path>", ...).
std::string whyOutOfDate(const Job& job);

}  // namespace prtbake::jobs
