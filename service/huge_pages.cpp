// Every C++ allocation of the prtbake process (its own arrays, the mesh loaders', LLVM's)
// goes through here: blocks of kHugePageBlock bytes or more as RawVector's are made
// (prtbake/raw_vector.h: aligned to 2 MiB and advised as transparent huge pages), the
// rest from malloc. A mesh command touches ~150 MB of fresh memory for a 200,000-triangle
// mesh, a page fault per 4 KiB page, each several microseconds on a virtual machine: on
// bench/bench_embree.sh's knot with 16 samples per vertex, 45,400 faults before and
// 14,400-15,100 with this (bench/results/transport.md).
#include <cstdlib>
#include <new>

#include "prtbake/raw_vector.h"

// Not under AddressSanitizer, whose own operator new records each block's kind: a library
// calling a form not replaced here (nothrow new) would then be freed by this delete.
#if defined(__SANITIZE_ADDRESS__)
#define PRTBAKE_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define PRTBAKE_ASAN 1
#endif
#endif

#ifndef PRTBAKE_ASAN
namespace {

void* allocate(size_t bytes) {
  if (bytes >= prtbake::kHugePageBlock) return prtbake::allocateLarge(bytes);
  void* p = std::malloc(bytes ? bytes : 1);
  if (!p) throw std::bad_alloc();
  return p;
}

}  // namespace

// The other forms (nothrow, sized delete's callers) reach these through libstdc++; the
// aligned forms keep their own aligned_alloc and free, which these blocks share.
void* operator new(size_t bytes) { return allocate(bytes); }
void* operator new[](size_t bytes) { return allocate(bytes); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, size_t) noexcept { std::free(p); }
void operator delete[](void* p, size_t) noexcept { std::free(p); }
#endif
