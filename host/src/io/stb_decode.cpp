// stb_image's PNG, JPEG and Radiance decoders with bounded blocks; see stb_decode.h.
#include "io/stb_decode.h"

#include <cstdlib>

namespace {
thread_local size_t blockLimit = 0;  // bytes; set by each load
thread_local size_t refusedBlock = 0;

// Zeroed: stb_image 2.27 reads parts of its blocks that a corrupt file never writes (its
// JPEG decoder's state, a component's plane when a scan ends early at a missing restart
// marker) and would otherwise decode whatever the heap held there; 2.28 zeroes its decoder.
void* boundedMalloc(size_t n) {
  if (n > blockLimit) return refusedBlock = n, nullptr;
  return std::calloc(1, n);
}
void* boundedRealloc(void* p, size_t n) {
  if (n > blockLimit) return refusedBlock = n, nullptr;
  return std::realloc(p, n);
}

// The bound for one load; returns what `load` returns.
template <class Load>
auto bounded(size_t limit, Load load) {
  blockLimit = limit;
  refusedBlock = 0;
  auto* px = load();
  blockLimit = 0;
  return px;
}
}  // namespace

#define STB_IMAGE_STATIC
#define STB_IMAGE_IMPLEMENTATION
#define STBI_ONLY_PNG
#define STBI_ONLY_JPEG
#define STBI_ONLY_HDR
#define STBI_MALLOC(n) boundedMalloc(n)
#define STBI_REALLOC(p, n) boundedRealloc(p, n)
#define STBI_FREE(p) std::free(p)
#include <stb/stb_image.h>

namespace prtbake::detail::stb {

bool isHdr(const unsigned char* data, int len) { return stbi_is_hdr_from_memory(data, len); }
bool is16Bit(const unsigned char* data, int len) { return stbi_is_16_bit_from_memory(data, len); }
bool info(const unsigned char* data, int len, int* width, int* height) {
  int channels = 0;
  return bounded(size_t(1) << 20, [&] { return stbi_info_from_memory(data, len, width, height, &channels) ? data : nullptr; });
}

float* loadHdr(const unsigned char* data, int len, size_t limit, int* width, int* height) {
  int channels = 0;
  return bounded(limit, [&] { return stbi_loadf_from_memory(data, len, width, height, &channels, 3); });
}
uint16_t* load16(const unsigned char* data, int len, size_t limit, int* width, int* height) {
  int channels = 0;
  return bounded(limit, [&] { return stbi_load_16_from_memory(data, len, width, height, &channels, 3); });
}
uint8_t* load8(const unsigned char* data, int len, size_t limit, int* width, int* height) {
  int channels = 0;
  return bounded(limit, [&] { return stbi_load_from_memory(data, len, width, height, &channels, 3); });
}

std::string reason() {
  if (refusedBlock)
    return "its data asks for a block of " + std::to_string(refusedBlock) + " bytes, more than the image needs";
  const char* r = stbi_failure_reason();
  return r ? r : "unknown error";
}

}  // namespace prtbake::detail::stb
