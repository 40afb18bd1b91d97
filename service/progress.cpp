// Progress of a batch on stderr (see progress.h).
#include "progress.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <iostream>

namespace prtbake::jobs {
namespace {

std::string formatDuration(double s) {
  const long t = std::lround(s);
  if (t < 1) return "<1 s";
  if (t < 60) return std::to_string(t) + " s";
  if (t < 3600) return std::to_string(t / 60) + " min " + std::to_string(t % 60) + " s";
  return std::to_string(t / 3600) + " h " + std::to_string(t % 3600 / 60) + " min";
}

}  // namespace

bool Progress::wanted(bool quiet, bool forced) { return forced || (!quiet && ::isatty(STDERR_FILENO)); }

Progress::Progress(bool enabled, int totalJobs)
    : enabled_(enabled && totalJobs > 0), terminal_(::isatty(STDERR_FILENO)), total_(totalJobs) {}

void Progress::begin(int index, const std::string& label) {
  if (!enabled_) return;
  index_ = index;
  std::string line = "[" + std::to_string(index) + "/" + std::to_string(total_) + "] " + label + " ...";
  if (ranJobs_ > 0) line += " ETA " + formatDuration(ranSeconds_ / ranJobs_ * (total_ - index + 1));
  if (terminal_) {
    std::cerr << "\r\033[K" << line << std::flush;  // rewritten in place by the next job
    lineShown_ = true;
  } else {
    std::cerr << line << std::endl;
  }
}

void Progress::end(double seconds, bool ran) {
  if (!enabled_) return;
  if (ran) ++ranJobs_, ranSeconds_ += seconds;
  if (index_ == total_) clearLine();
}

void Progress::clearLine() {
  if (!lineShown_) return;
  std::cerr << "\r\033[K" << std::flush;
  lineShown_ = false;
}

}  // namespace prtbake::jobs
