// Private: the checks every reader of a ProbeGridResult makes before indexing it.
#pragma once

#include "prtbake/probes.h"

namespace prtbake {

// Throws UsageError ("probe grid") unless the order is 1..kMaxShOrder, each resolution
// 1..kMaxProbesPerAxis, the bounds non-empty and finite, and coeffs holds count × order² × 3
// floats.
void checkProbeGridShape(const ProbeGridResult& grid);

}  // namespace prtbake
