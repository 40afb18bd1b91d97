// Seconds on the steady clock: the timings that every product and command reports.
#pragma once

#include <chrono>

namespace prtbake {

using SteadyTime = std::chrono::steady_clock::time_point;

inline double secondsSince(SteadyTime t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace prtbake
