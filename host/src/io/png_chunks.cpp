#include "io/png_chunks.h"

#include <array>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "prtbake/atomic_file.h"
#include "prtbake/error.h"

// The deflate of the system's stb library (stb_image_write.c), which its header declares only
// in the implementation part.
extern "C" unsigned char* stbi_zlib_compress(unsigned char* data, int data_len, int* out_len, int quality);

namespace prtbake::detail {

uint32_t crc32(const unsigned char* p, size_t n, uint32_t crc) {
  static const auto table = [] {
    std::array<uint32_t, 256> t{};
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xedb88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  for (size_t i = 0; i < n; ++i) crc = table[(crc ^ p[i]) & 0xff] ^ (crc >> 8);
  return crc;
}

void appendBE(std::string& s, uint32_t v) {
  for (int k = 3; k >= 0; --k) s.push_back(char((v >> (8 * k)) & 0xff));
}

void appendPngChunk(std::string& png, const std::string& type, const std::string& data) {
  const std::string body = type + data;
  appendBE(png, uint32_t(data.size()));
  png += body;
  appendBE(png, crc32(reinterpret_cast<const unsigned char*>(body.data()), body.size()) ^ 0xffffffffu);
}

}  // namespace prtbake::detail

namespace prtbake {
namespace {

// A PNG of `bitDepth`-bit samples (8 or 16) from its filtered scanlines (`raw`: per row a
// filter byte 0, then the samples, big-endian), no colour-space chunks.
std::string pngFromScanlines(int width, int height, int channels, int bitDepth, std::string& raw) {
  int zlen = 0;
  unsigned char* z = stbi_zlib_compress(reinterpret_cast<unsigned char*>(raw.data()), int(raw.size()), &zlen, 8);
  if (!z) throw OutputError("png", "deflate failed");
  const std::string idat(reinterpret_cast<const char*>(z), size_t(zlen));
  std::free(z);
  static const int kColourType[5] = {0, 0, 4, 2, 6};  // grey, grey + alpha, RGB, RGBA
  std::string ihdr;
  detail::appendBE(ihdr, uint32_t(width));
  detail::appendBE(ihdr, uint32_t(height));
  ihdr += std::string{char(bitDepth), char(kColourType[channels]), 0, 0, 0};
  std::string png("\x89PNG\r\n\x1a\n", 8);
  detail::appendPngChunk(png, "IHDR", ihdr);
  detail::appendPngChunk(png, "tEXt", std::string("Software") + std::string(1, '\0') + "prtbake " + version());
  detail::appendPngChunk(png, "IDAT", idat);
  detail::appendPngChunk(png, "IEND", "");
  return png;
}

void checkPngShape(int width, int height, int channels, size_t samples) {
  if (width < 1 || height < 1 || channels < 1 || channels > 4 || samples != size_t(width) * size_t(height) * size_t(channels))
    throw OutputError("png", "bad image dimensions");
}

}  // namespace

std::string png16Bytes(int width, int height, int channels, const std::vector<uint16_t>& samples) {
  checkPngShape(width, height, channels, samples.size());
  const size_t rowBytes = 1 + 2 * size_t(width) * size_t(channels);
  std::string raw(rowBytes * size_t(height), '\0');
  for (int y = 0; y < height; ++y)
    for (size_t x = 0; x < size_t(width) * size_t(channels); ++x) {
      const uint16_t v = samples[size_t(y) * size_t(width) * size_t(channels) + x];
      raw[size_t(y) * rowBytes + 1 + 2 * x] = char(v >> 8);
      raw[size_t(y) * rowBytes + 2 + 2 * x] = char(v & 0xff);
    }
  return pngFromScanlines(width, height, channels, 16, raw);
}

std::string png8Bytes(int width, int height, int channels, const std::vector<uint8_t>& samples) {
  checkPngShape(width, height, channels, samples.size());
  const size_t rowBytes = 1 + size_t(width) * size_t(channels);
  std::string raw(rowBytes * size_t(height), '\0');
  for (int y = 0; y < height; ++y)
    std::memcpy(&raw[size_t(y) * rowBytes + 1], samples.data() + size_t(y) * (rowBytes - 1), rowBytes - 1);
  return pngFromScanlines(width, height, channels, 8, raw);
}

}  // namespace prtbake
