// Private: pieces of the glossy transfer shared by the device driver (glossy.cpp), the CPU
// reference (glossy_reference.cpp) and the writers.
#pragma once

#include <vector>

#include "prtbake/glossy.h"
#include "prtbake/transport.h"

namespace prtbake::detail {

// The transport options whose ray set-up (origins, frames, per-vertex rotation, seed) the
// glossy bake shares; order = max(n_out, n_in).
TransportOptions glossyTransportOptions(const GlossyOptions& options);
// 3 for interreflection with a coloured albedo, else 1.
int glossyChannels(const Mesh& mesh, const GlossyOptions& options);
// The unshadowed product rule in the local frame: (x, y, z, weight) per direction,
// order-point Gauss–Legendre in z times 2·order azimuths, exact for Y_i Y_j of that order.
std::vector<float> productRuleDirections(int order);
// M (n_out² × n_in²) of one channel from the lower triangle of the Gram sums (rows of
// the order max(n_out, n_in)), plus the bounce sums (n_out² × n_in², or null), × scale.
void assembleMatrix(const double* gram, int nmax2, const double* bounce, int no2, int ni2, double scale, float* out);

}  // namespace prtbake::detail
