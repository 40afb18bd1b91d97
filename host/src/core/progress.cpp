// Progress hooks (prtbake/progress.h): one per thread, the innermost scope's.
#include "prtbake/progress.h"

namespace prtbake {
namespace {
thread_local const ProgressHook* current = nullptr;
}

ProgressScope::ProgressScope(ProgressHook hook) : hook_(std::move(hook)), previous_(current) {
  current = hook_ ? &hook_ : previous_;
}

ProgressScope::~ProgressScope() { current = previous_; }

bool progressWanted() { return current != nullptr; }

void reportProgress(const char* stage, double fraction) {
  if (current && !(*current)(stage, fraction < 0 ? 0 : fraction > 1 ? 1 : fraction))
    throw Cancelled(stage, "cancelled by the caller");
}

}  // namespace prtbake
