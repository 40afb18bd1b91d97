// prtbake/progress.h: progress and cancellation of long library calls.
//
// A caller installs a hook for the calls its thread makes (ProgressScope). Between units of
// work (a block of vertices of a transport launch, a glossy block, a LUT chunk, a prefilter
// pass, an environment band) the library calls the hook with the stage's name and the
// fraction of it done; the hook returns false to stop the call, which then throws Cancelled
// and leaves its outputs unwritten. Without a hook nothing changes: the work is launched as
// it always is, and reportProgress is a thread-local load. With one, transport launches go in
// blocks of vertices, each waited for (the results are the same bits: every vertex is
// computed by the same work-item code in work-groups of the same vertices).
#pragma once

#include <functional>
#include <string>

#include "prtbake/error.h"

namespace prtbake {

// A call stopped by its caller's progress hook.
class Cancelled : public Error {
 public:
  using Error::Error;
};

using ProgressHook = std::function<bool(const std::string& stage, double fraction)>;

// Installs `hook` for this thread's calls while the scope lives; scopes nest (the innermost wins).
class ProgressScope {
 public:
  explicit ProgressScope(ProgressHook hook);
  ~ProgressScope();
  ProgressScope(const ProgressScope&) = delete;
  ProgressScope& operator=(const ProgressScope&) = delete;

 private:
  ProgressHook hook_;
  const ProgressHook* previous_;
};

// Whether this thread has a hook (the library then works in reportable pieces).
bool progressWanted();

// Tells the hook, if any, that `fraction` (0..1) of `stage` is done; throws Cancelled when it
// says stop.
void reportProgress(const char* stage, double fraction);

}  // namespace prtbake
