// stb_decode.h (internal): stb_image's PNG, JPEG and Radiance decoders, compiled into
// prtbake (stb_decode.cpp) rather than taken from the system's libstb (which the image
// writers use), for bounds that library cannot give:
// - only these three formats: libstb also decodes BMP, GIF, PSD, TGA, PIC and PNM, and
//   the version Debian ships (2.27) has known memory-safety bugs in its GIF and TGA
//   decoders;
// - no block larger than `blockLimit` bytes: libstb grows its buffers by what the data
//   claims (a PNG chunk that claims 1 GiB, or deflate data that expands 1000-fold had it
//   realloc 2 GiB for a 621-byte file);
// - signed arithmetic that wraps (-fwrapv): 2.27's JPEG decoder overflows int on corrupt
//   entropy-coded data.
// The callers (image_read.cpp) check what stb would trust from the data before calling:
// the image's size, Radiance run lengths, JPEG Huffman tables.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace prtbake::detail::stb {

bool isHdr(const unsigned char* data, int len);
bool is16Bit(const unsigned char* data, int len);
// The header's size; false where stb cannot read one.
bool info(const unsigned char* data, int len, int* width, int* height);
// Decode to 3 channels (grey replicated, alpha dropped) into a malloc'd block (free it
// with std::free), or nullptr with reason() saying why.
float* loadHdr(const unsigned char* data, int len, size_t blockLimit, int* width, int* height);
uint16_t* load16(const unsigned char* data, int len, size_t blockLimit, int* width, int* height);
uint8_t* load8(const unsigned char* data, int len, size_t blockLimit, int* width, int* height);
// Why the last load on this thread failed.
std::string reason();

}  // namespace prtbake::detail::stb
