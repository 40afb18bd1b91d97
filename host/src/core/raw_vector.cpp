#include "prtbake/raw_vector.h"

#include <sys/mman.h>

#include <cstdint>
#include <cstdlib>

namespace prtbake {

void* allocateLarge(size_t bytes) {
  constexpr size_t kHuge = size_t(2) << 20, kSmallAlign = 128;
  if (bytes > SIZE_MAX / 2) throw std::bad_alloc();  // rounding up below would wrap
  const size_t align = bytes >= kHugePageBlock ? kHuge : kSmallAlign;
  const size_t rounded = (bytes + align - 1) / align * align;  // aligned_alloc wants a multiple
  void* p = std::aligned_alloc(align, rounded ? rounded : align);
  if (!p) throw std::bad_alloc();
  if (bytes >= kHugePageBlock) ::madvise(p, rounded, MADV_HUGEPAGE);  // a hint: ignored where huge pages are off
  return p;
}

void freeLarge(void* p) noexcept { std::free(p); }

}  // namespace prtbake
