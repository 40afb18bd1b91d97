// The input memory limit (prtbake/limits.h).
#include "prtbake/limits.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "prtbake/error.h"

namespace prtbake {
namespace {

constexpr size_t kDefaultLimitBytes = size_t(4) << 30;

std::atomic<size_t> gLimitOverride{0};

size_t limitFromEnvironment() {
  const char* v = std::getenv("PRTBAKE_INPUT_LIMIT_MB");
  if (!v || !*v) return kDefaultLimitBytes;
  char* end = nullptr;
  const double mb = std::strtod(v, &end);
  if (*end != '\0' || !std::isfinite(mb) || mb < 1e-3 || mb > 1e9)
    throw UsageError("PRTBAKE_INPUT_LIMIT_MB", std::string("expected a number of MiB in [0.001, 1e9], got '") + v + "'");
  return size_t(mb * 1048576.0);
}

std::string mib(double bytes) {
  std::ostringstream s;
  s.precision(bytes < 10 * 1048576.0 ? 2 : 0);
  s << std::fixed << bytes / 1048576.0;
  return s.str();
}

}  // namespace

size_t inputMemoryLimit() {
  if (const size_t o = gLimitOverride.load()) return o;
  static const size_t fromEnv = limitFromEnvironment();
  return fromEnv;
}

void setInputMemoryLimit(size_t bytes) { gLimitOverride = bytes; }

void checkInputMemory(const std::string& subject, const std::string& what, double bytes) {
  const double limit = double(inputMemoryLimit());
  if (!(bytes <= limit))
    throw InputError(subject, what + " needs " + mib(bytes) + " MiB, more than the input memory limit of " + mib(limit) +
                                  " MiB (set PRTBAKE_INPUT_LIMIT_MB to change it)");
}

double processMemoryBytes() {
  static const double bytes = [] {
    double b = double(::sysconf(_SC_PHYS_PAGES)) * double(::sysconf(_SC_PAGESIZE));
    // A cgroup's limit: v2 (memory.max of the process's group, or of the root a container
    // sees) and v1 (memory.limit_in_bytes). "max" or an unreadable file: none.
    std::vector<std::string> files = {"/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"};
    std::ifstream groups("/proc/self/cgroup");
    for (std::string line; std::getline(groups, line);)
      if (line.rfind("0::", 0) == 0) files.push_back("/sys/fs/cgroup" + line.substr(3) + "/memory.max");
    for (const auto& f : files) {
      std::ifstream in(f);
      double v = 0;
      if (in >> v && v > 0) b = std::min(b, v);
    }
    // Or as the user says: PRTBAKE_MEMORY_LIMIT_MB (a shared machine's share, or more than the
    // machine has where swap or a tighter estimate would do).
    if (const char* v = std::getenv("PRTBAKE_MEMORY_LIMIT_MB"); v && *v) {
      char* end = nullptr;
      const double mb = std::strtod(v, &end);
      if (*end != '\0' || !std::isfinite(mb) || mb < 1 || mb > 1e9)
        throw UsageError("PRTBAKE_MEMORY_LIMIT_MB", std::string("expected a number of MiB in [1, 1e9], got '") + v + "'");
      b = mb * 1048576.0;
    }
    return b;
  }();
  return bytes;
}

void checkProcessMemory(const std::string& subject, const std::string& what, double bytes) {
  const double have = processMemoryBytes();
  if (!(bytes <= have)) {
    std::ostringstream s;
    s.precision(1);
    s << std::fixed << what << " needs about " << bytes / 1073741824.0 << " GiB at its peak, more than the "
      << have / 1073741824.0 << " GiB this process can have (the machine's memory or its cgroup's limit; "
      << "PRTBAKE_MEMORY_LIMIT_MB sets another)";
    throw UsageError(subject, s.str());
  }
}

}  // namespace prtbake
