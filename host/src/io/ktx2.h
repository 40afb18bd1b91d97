// KTX 2.0 files of linear RGBA float texels, uncompressed: 2D, cube or 3D, any number of
// levels. Shared by the prefiltered cubes (prefilter_write.cpp) and the probe grids' three.js
// atlas (probes_threejs.cpp).
//
// Format: VK_FORMAT_R16G16B16A16_SFLOAT (values beyond the half range clamped to ±65504 and
// counted) or R32G32B32A32_SFLOAT; the Basic data format descriptor (RGBSDA, BT.709
// primaries, linear transfer, straight alpha); no supercompression; key/value data
// "KTXwriter" then the caller's pairs. Texels are stored as given: x fastest, then rows (y),
// then faces, then slices (z); levels' data smallest level first, each 8- (half) or
// 16-byte (float) aligned, as KTX 2.0 §4 asks.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace prtbake::ktx2 {

struct Layout {
  uint32_t width = 0, height = 0;
  uint32_t depth = 0;  // pixelDepth: 0 for a 2D or cube texture, the slice count of a 3D one
  uint32_t faces = 1;  // 1, or 6 for a cube (faces +X, −X, +Y, −Y, +Z, −Z)
  uint32_t layers = 0;  // layerCount: 0 for one texture, the layers of an array
  bool float32 = false;
};

// One level's texels: `channels` (3: alpha written as 1, or 4) floats per texel, exactly
// max(1, width >> i) · max(1, height >> i) · max(1, depth >> i) · faces · max(1, layers) texels
// for level i, layer by layer (KTX 2.0 §3.9.5: layers, then faces, then slices, then rows).
struct Level {
  const float* texels = nullptr;
  int channels = 4;
  size_t count = 0;  // texels, checked against the layout
};

// The whole file. keyValues: after "KTXwriter", in the order given (KTX 2.0 asks for keys
// sorted by code point; "KTXwriter" sorts before lower-case keys such as "prtbake.*").
// *clampedToHalf (when given) receives the number of channel values clamped to the half range.
// Throws OutputError ("ktx2") for an empty layout, no level, or a level of the wrong size.
std::string rgbaFloatBytes(const Layout& layout, const std::vector<Level>& levels,
                           const std::vector<std::pair<std::string, std::string>>& keyValues,
                           long long* clampedToHalf = nullptr);

}  // namespace prtbake::ktx2
