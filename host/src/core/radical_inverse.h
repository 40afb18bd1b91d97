// Private: the base-2 radical inverse (van der Corput) behind every Hammersley set the host
// builds (LUT directions, transport rays, the prefilter's sampled estimator), and the hash that
// turns seeds and indices into reproducible random numbers (rotations, shifts, jitter).
#pragma once

#include <cstdint>

namespace prtbake::detail {

// Radical inverse in base 2 of k, exact in double for k < 2^32.
inline double radicalInverse2(uint32_t k) {
  k = (k << 16) | (k >> 16);
  k = ((k & 0x00ff00ffu) << 8) | ((k & 0xff00ff00u) >> 8);
  k = ((k & 0x0f0f0f0fu) << 4) | ((k & 0xf0f0f0f0u) >> 4);
  k = ((k & 0x33333333u) << 2) | ((k & 0xccccccccu) >> 2);
  k = ((k & 0x55555555u) << 1) | ((k & 0xaaaaaaaau) >> 1);
  return double(k) * 0x1.0p-32;
}

// SplitMix64 (Steele, Lea & Flood): a well-mixed 64-bit hash of x.
inline uint64_t splitmix64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// A hash's top 53 bits as a double in [0, 1).
inline double unitFromBits(uint64_t h) { return double(h >> 11) * 0x1.0p-53; }

}  // namespace prtbake::detail
