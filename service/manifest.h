// Per-job manifests: the record that makes reruns incremental.
//
// After every output of a job is in place, the runner writes
// <first output>.manifest.json (atomically, last) holding the prtbake version,
// the normalised job parameters, every input file with its SHA-256, every
// output with its size, the device and the timings. A later run skips the job
// when version and parameters are equal, every input hashes the same and every
// output still exists with its recorded size.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "jobs.h"

namespace prtbake::jobs {

struct InputHash {
  std::string path;
  std::string sha256;
};

// SHA-256 of each file (throws InputError naming a file that cannot be read), taken
// from `known` where it holds the file.
std::vector<InputHash> hashInputs(const std::vector<std::string>& files,
                                  const std::map<std::string, std::string>& known = {});

// The manifest of a job whose outputs are now committed.
json makeManifest(const Job& job, const std::vector<InputHash>& inputs, const std::string& device,
                  const json& timings, const json& report);

// The current time as ISO 8601 UTC ("2026-11-22T16:55:33Z"), for manifests and logs.
std::string utcNow();

// obj[key] as the integer type T when it holds an integer that T can represent, else
// `fallback` (also when obj is not an object or has no such key). json::value converts a
// float or an out-of-range integer by a cast that is undefined for values T cannot hold, and
// a manifest may be damaged or edited by hand.
template <class T>
T manifestInt(const json& obj, const char* key, T fallback) {
  if (!obj.is_object()) return fallback;
  const auto it = obj.find(key);
  if (it == obj.end() || !it->is_number_integer()) return fallback;
  if (it->is_number_unsigned()) {
    const uint64_t v = it->template get<uint64_t>();
    return v <= uint64_t(std::numeric_limits<T>::max()) ? T(v) : fallback;
  }
  const int64_t v = it->template get<int64_t>();
  if (v >= 0) return uint64_t(v) <= uint64_t(std::numeric_limits<T>::max()) ? T(v) : fallback;
  return std::numeric_limits<T>::is_signed && v >= int64_t(std::numeric_limits<T>::min()) ? T(v) : fallback;
}

// Why `job` must run: "" when its manifest shows it is up to date, otherwise a
// short reason ("no manifest", "parameters changed: order", "input changed: <path>", ...).
std::string whyOutOfDate(const Job& job);

}  // namespace prtbake::jobs
