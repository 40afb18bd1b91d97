// Private: pieces of the LUT driver shared by lut.cpp, lut_reference.cpp and
// lut_adaptive.cpp.
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
// The adaptive driver (LutOptions::tolerance > 0).
LutResult computeLutAdaptive(Runtime& rt, const LutOptions& o);

}  // namespace prtbake::detail
