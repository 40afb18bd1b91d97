// prtbake/raw_vector.h: vectors for large arrays that are written before they are read.
//
// RawVector<T> is a std::vector whose resize() leaves new elements uninitialised, and
// whose blocks of 4 MiB or more are aligned to 2 MiB and advised as transparent huge
// pages. On virtual machines a first touch of fresh memory is a slow page fault per
// 4 KiB page (PERF.md); zero-filling what is about to be overwritten pays it twice.
// The alignment also lets CPU OpenCL devices use the array in place
// (CL_MEM_USE_HOST_PTR) instead of copying it.
#pragma once

#include <cstddef>
#include <new>
#include <utility>
#include <vector>

namespace prtbake {

// Blocks of this many bytes or more are aligned to 2 MiB and advised as huge pages.
constexpr size_t kHugePageBlock = size_t(4) << 20;

void* allocateLarge(size_t bytes);
void freeLarge(void* p) noexcept;

template <class T>
struct UninitAllocator {
  using value_type = T;
  UninitAllocator() = default;
  template <class U>
  UninitAllocator(const UninitAllocator<U>&) {}
  T* allocate(size_t n) { return static_cast<T*>(allocateLarge(n * sizeof(T))); }
  void deallocate(T* p, size_t) noexcept { freeLarge(p); }
  template <class U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... A>
  void construct(U* p, A&&... a) {
    ::new (static_cast<void*>(p)) U(std::forward<A>(a)...);
  }
  template <class U>
  bool operator==(const UninitAllocator<U>&) const {
    return true;
  }
  template <class U>
  bool operator!=(const UninitAllocator<U>&) const {
    return false;
  }
};

template <class T>
using RawVector = std::vector<T, UninitAllocator<T>>;

}  // namespace prtbake
