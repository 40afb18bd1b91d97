// The input memory limit (prtbake/limits.h).
#include "prtbake/limits.h"

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <sstream>

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

}  // namespace prtbake
