// Progress of a batch on stderr: "[3/20] sky-07 ... ETA 42 s", one job at a time.
// On a terminal the line is rewritten in place and cleared before any other
// output; with --progress on a pipe or file, one line per job is printed instead.
// The ETA is the mean wall time of the jobs run so far (skipped jobs excluded)
// times the jobs left.
#pragma once

#include <string>

namespace prtbake::jobs {

class Progress {
 public:
  // On when forced (--progress), else when stderr is a terminal and not quiet.
  static bool wanted(bool quiet, bool forced);

  Progress(bool enabled, int totalJobs);
  bool enabled() const { return enabled_; }

  // Job `index` (1-based) of the total starts.
  void begin(int index, const std::string& label);
  // The job ended; `ran` when it did work (not skipped or invalid).
  void end(double seconds, bool ran);
  // Removes the in-place line (terminal only) before other output is printed.
  void clearLine();

 private:
  bool enabled_, terminal_;
  int total_;
  int index_ = 0;
  int ranJobs_ = 0;
  double ranSeconds_ = 0;
  bool lineShown_ = false;
};

}  // namespace prtbake::jobs
