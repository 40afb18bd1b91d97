// KTX 2.0 writing (ktx2.h).
#include "io/ktx2.h"

#include <half.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "prtbake/atomic_file.h"
#include "prtbake/error.h"

namespace prtbake::ktx2 {
namespace {

constexpr float kHalfMax = 65504.0f;

void put32(std::string& s, uint32_t v) {
  for (int k = 0; k < 4; ++k) s.push_back(char((v >> (8 * k)) & 0xff));
}
void put64(std::string& s, uint64_t v) {
  for (int k = 0; k < 8; ++k) s.push_back(char((v >> (8 * k)) & 0xff));
}
void set32(std::string& s, size_t at, uint32_t v) {
  for (int k = 0; k < 4; ++k) s[at + size_t(k)] = char((v >> (8 * k)) & 0xff);
}
void set64(std::string& s, size_t at, uint64_t v) {
  for (int k = 0; k < 8; ++k) s[at + size_t(k)] = char((v >> (8 * k)) & 0xff);
}
uint32_t floatBits(float f) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  return u;
}

// The Basic Data Format Descriptor of an RGBA float format (KTX 2.0 §3.10, Khronos Data
// Format 1.3 §5): colour model RGBSDA, BT.709 primaries, linear transfer, straight alpha,
// a 1×1×1×1 block of `bytesPerTexel` bytes, four samples R, G, B, A (channel ids 0, 1, 2, 15)
// of `bits` bits each, flagged FLOAT | SIGNED (0xC0), with the sample range −1.0 … 1.0 that
// float formats carry.
std::string basicDfd(int bits) {
  std::string d;
  const uint32_t blockSize = 24 + 16 * 4;
  put32(d, 4 + blockSize);                 // dfdTotalSize
  put32(d, 0);                             // vendorId 0 (Khronos) | descriptorType 0 (basic)
  put32(d, 2u | blockSize << 16);          // versionNumber 2 | descriptorBlockSize
  put32(d, 1u | 1u << 8 | 1u << 16 | 0u << 24);  // RGBSDA, BT709, LINEAR, ALPHA_STRAIGHT
  put32(d, 0);                             // texelBlockDimension 0..3 (value − 1)
  put32(d, uint32_t(4 * bits / 8));        // bytesPlane0
  put32(d, 0);                             // bytesPlane4..7
  const uint32_t channels[4] = {0, 1, 2, 15};
  for (int i = 0; i < 4; ++i) {
    put32(d, uint32_t(i * bits) | uint32_t(bits - 1) << 16 | (0xC0u | channels[i]) << 24);
    put32(d, 0);  // samplePosition 0..3
    put32(d, floatBits(-1.0f));
    put32(d, floatBits(1.0f));
  }
  return d;
}

// One key/value pair of the KTX 2.0 key/value data, padded to 4 bytes.
void keyValue(std::string& kvd, const std::string& key, const std::string& value) {
  const std::string kv = key + std::string(1, '\0') + value + std::string(1, '\0');
  put32(kvd, uint32_t(kv.size()));
  kvd += kv;
  while (kvd.size() % 4) kvd.push_back('\0');
}

size_t levelTexels(const Layout& l, uint32_t i) {
  const auto dim = [i](uint32_t n) { return size_t(std::max(1u, n >> i)); };
  return dim(l.width) * dim(l.height) * (l.depth ? dim(l.depth) : 1) * l.faces * std::max(1u, l.layers);
}

}  // namespace

std::string rgbaFloatBytes(const Layout& layout, const std::vector<Level>& levelData,
                           const std::vector<std::pair<std::string, std::string>>& keyValues,
                           long long* clampedToHalf) {
  if (levelData.empty() || layout.width == 0 || layout.height == 0 || (layout.faces != 1 && layout.faces != 6) ||
      (layout.faces == 6 && layout.depth != 0))
    throw OutputError("ktx2", "nothing to write");
  const uint32_t levels = uint32_t(levelData.size());
  for (uint32_t i = 0; i < levels; ++i)
    if (levelData[i].count != levelTexels(layout, i) || (levelData[i].channels != 3 && levelData[i].channels != 4))
      throw OutputError("ktx2", "level " + std::to_string(i) + " holds " + std::to_string(levelData[i].count) +
                                    " texels where its size needs " + std::to_string(levelTexels(layout, i)));
  const bool float32 = layout.float32;
  const int bytesPerTexel = float32 ? 16 : 8, align = float32 ? 16 : 8;  // lcm(texel block size, 4)
  std::string out;
  const unsigned char id[12] = {0xAB, 'K', 'T', 'X', ' ', '2', '0', 0xBB, '\r', '\n', 0x1A, '\n'};
  out.append(reinterpret_cast<const char*>(id), 12);
  put32(out, float32 ? 109u : 97u);  // VK_FORMAT_R32G32B32A32_SFLOAT | VK_FORMAT_R16G16B16A16_SFLOAT
  put32(out, float32 ? 4u : 2u);     // typeSize
  put32(out, layout.width);          // pixelWidth
  put32(out, layout.height);         // pixelHeight
  put32(out, layout.depth);          // pixelDepth
  put32(out, layout.layers);         // layerCount
  put32(out, layout.faces);          // faceCount
  put32(out, levels);                // levelCount
  put32(out, 0);                     // supercompressionScheme
  const size_t indexAt = out.size();
  for (int i = 0; i < 4; ++i) put32(out, 0);  // dfd, kvd offsets and lengths (set below)
  put64(out, 0);                              // sgdByteOffset
  put64(out, 0);                              // sgdByteLength
  const size_t levelIndexAt = out.size();
  for (uint32_t i = 0; i < levels; ++i) put64(out, 0), put64(out, 0), put64(out, 0);
  const std::string dfd = basicDfd(float32 ? 32 : 16);
  const size_t dfdAt = out.size();
  out += dfd;
  std::string kvd;
  keyValue(kvd, "KTXwriter", std::string("prtbake ") + version());
  for (const auto& [key, value] : keyValues) keyValue(kvd, key, value);
  const size_t kvdAt = out.size();
  out += kvd;
  set32(out, indexAt, uint32_t(dfdAt));
  set32(out, indexAt + 4, uint32_t(dfd.size()));
  set32(out, indexAt + 8, uint32_t(kvdAt));
  set32(out, indexAt + 12, uint32_t(kvd.size()));
  // Level data, smallest level first, each aligned.
  long long clamped = 0;
  for (int li = int(levels) - 1; li >= 0; --li) {
    const Level& l = levelData[size_t(li)];
    while (out.size() % size_t(align)) out.push_back('\0');
    const size_t at = out.size(), channels = size_t(l.channels);
    std::string data(l.count * size_t(bytesPerTexel), '\0');
    for (size_t t = 0; t < l.count; ++t) {
      for (size_t c = 0; c < 4; ++c) {
        float v = c < channels ? l.texels[channels * t + c] : 1.0f;
        if (float32) {
          std::memcpy(&data[16 * t + 4 * c], &v, 4);
        } else {
          if (std::abs(v) > kHalfMax) v = std::copysign(kHalfMax, v), ++clamped;
          const uint16_t bits = half(v).bits();
          std::memcpy(&data[8 * t + 2 * c], &bits, 2);
        }
      }
    }
    out += data;
    set64(out, levelIndexAt + 24 * size_t(li), at);
    set64(out, levelIndexAt + 24 * size_t(li) + 8, data.size());
    set64(out, levelIndexAt + 24 * size_t(li) + 16, data.size());
  }
  if (clampedToHalf) *clampedToHalf = clamped;
  return out;
}

}  // namespace prtbake::ktx2
