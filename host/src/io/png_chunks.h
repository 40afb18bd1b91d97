// CRC-32 and PNG chunks, shared by the PNG writers and the .npz (zip) writer.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>

namespace prtbake::detail {

// CRC-32 (ISO 3309, as PNG uses it) of p[0..n), starting from `crc` (pre-inverted state).
uint32_t crc32(const unsigned char* p, size_t n, uint32_t crc = 0xffffffffu);
void appendBE(std::string& s, uint32_t v);
// Appends length, type, data and CRC.
void appendPngChunk(std::string& png, const std::string& type, const std::string& data);

}  // namespace prtbake::detail
