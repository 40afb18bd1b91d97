// parallel.h: host loops split over the machine's threads.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <thread>
#include <vector>

namespace prtbake::detail {

// f(begin, end, t) over `threads` contiguous blocks of [0, n) (t: the block's index), one
// thread each; fewer blocks when n is small (at least 256 items each), and on the
// calling thread alone when one block remains.
template <class F>
void parallelFor(size_t n, int threads, F&& f) {
  const size_t t = std::max<size_t>(1, std::min<size_t>(size_t(std::max(threads, 1)), (n + 255) / 256));
  if (t == 1) {
    f(size_t(0), n, 0);
    return;
  }
  std::vector<std::thread> pool;
  for (size_t i = 1; i < t; ++i) pool.emplace_back([&, i] { f(n * i / t, n * (i + 1) / t, int(i)); });
  f(size_t(0), n / t, 0);
  for (auto& th : pool) th.join();
}

// The host's hardware threads (at least one).
inline int hostThreads() { return int(std::max(1u, std::thread::hardware_concurrency())); }

// body(i) for every i in [0, n), handed out `block` at a time from a shared counter to at
// most `maxThreads` threads, the calling one among them: items of uneven cost balance
// themselves. Each i runs once, on some thread; nothing depends on which.
template <class F>
void parallelEach(size_t n, int maxThreads, F&& body, size_t block = 1) {
  const size_t t = std::max<size_t>(1, std::min<size_t>(size_t(std::max(1, std::min(maxThreads, hostThreads()))),
                                                        (n + block - 1) / block));
  std::atomic<size_t> next{0};
  auto work = [&] {
    for (size_t b; (b = next.fetch_add(block)) < n;)
      for (size_t i = b; i < std::min(n, b + block); ++i) body(i);
  };
  std::vector<std::thread> pool;
  for (size_t i = 1; i < t; ++i) pool.emplace_back(work);
  work();
  for (auto& th : pool) th.join();
}

}  // namespace prtbake::detail
