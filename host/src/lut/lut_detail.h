// Private: pieces of the LUT driver shared by lut.cpp and lut_reference.cpp.
#pragma once

#include <cstdint>
#include <vector>

#include "prtbake/lut.h"
#include "prtbake/runtime.h"

namespace prtbake::detail {

// Fills the derived tables (third, Kulla–Conty, error summary) from a, b, cloth.
void finishLut(LutResult& r, const std::vector<float>& cloth, const std::vector<float>& stdErr);
// The texel centres of an n×n table, row major.
std::vector<LutPoint> texelPoints(int n);

}  // namespace prtbake::detail
