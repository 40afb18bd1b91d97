// CRC-32 and PNG chunks, shared by the PNG writers and the .npz (zip) writer; PNG images of
// 8- or 16-bit samples (declared for the library's users in prtbake/ibl.h).
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace prtbake::detail {

// CRC-32 (ISO 3309, as PNG uses it) of p[0..n), starting from `crc` (pre-inverted state).
uint32_t crc32(const unsigned char* p, size_t n, uint32_t crc = 0xffffffffu);
void appendBE(std::string& s, uint32_t v);
// Appends length, type, data and CRC.
void appendPngChunk(std::string& png, const std::string& type, const std::string& data);

}  // namespace prtbake::detail

namespace prtbake {
// PNG of width × height samples (channels 1 grey, 2 grey + alpha, 3 RGB, 4 RGBA; rows top
// first), no colour-space chunks; OutputError for a wrong sample count.
std::string png16Bytes(int width, int height, int channels, const std::vector<uint16_t>& samples);
std::string png8Bytes(int width, int height, int channels, const std::vector<uint8_t>& samples);
}  // namespace prtbake
