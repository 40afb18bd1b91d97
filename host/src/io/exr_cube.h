// exr_cube.h (internal): where OpenEXR keeps each texel of a cube map.
//
// An OpenEXR cube map (envmap attribute ENVMAP_CUBE) stacks six N×N faces in an N×6N
// data window, each face oriented as ImfEnvmap.h defines. We do not restate that table;
// we ask the library (Imf::CubeMap). Used by the loader (env_load.cpp) and the prefiltered
// chain's writer (prefilter_write.cpp), so that what one writes the other reads back.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "prtbake/envmap.h"

namespace prtbake::detail {

// For each texel (face·n + row)·n + col of an n×n cube with the given face bases, the index
// y·n + x of its pixel in an OpenEXR cube data window of n × 6n (x, y from the window's
// corner). Every pixel is used exactly once (checked; `subject` names the file in errors).
std::vector<size_t> openExrCubePixels(int n, const std::array<CubeFaceBasis, 6>& faces, const std::string& subject);

}  // namespace prtbake::detail
