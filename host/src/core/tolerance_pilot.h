// Private: the "--tolerance" pilot (prtbake/tolerance.h) shared by the products.
#pragma once

#include <functional>
#include <vector>

#include <nlohmann/json.hpp>

#include "prtbake/tolerance.h"

namespace prtbake::detail {

// Runs the pilot. evaluate(counts) returns the pilot items' values at each of the
// counts (one or two; `stride` values per item, the same layout on every call, the
// counts one after the other), so that a product may run two counts in one launch.
// Returns the report with `samples` = M, a quarter-octave count (2^m × {1, 5/4, 3/2, 7/4})
// at least `granularity` and at most maxSamples.
using PilotEvaluate = std::function<std::vector<std::vector<double>>(const std::vector<int>& counts)>;
ToleranceReport runTolerancePilot(const PilotEvaluate& evaluate, size_t stride, double tolerance, int maxSamples,
                                  int granularity);

// Indices of every step-th of `count` items, from the middle of the first step.
std::vector<size_t> pilotSubset(size_t count, size_t step);

// The report as a sidecar block.
nlohmann::json toleranceJson(const ToleranceReport& report);

}  // namespace prtbake::detail
