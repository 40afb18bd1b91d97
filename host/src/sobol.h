// Private: the 2-D Sobol' sequence used by the adaptive ("--tolerance") drivers.
//
// Point i is (radinv₂(i), sobol₂(i)): the first coordinate is the van der Corput sequence
// (bit reversal), the second the Sobol' second dimension (generator matrix = Pascal's
// triangle mod 2; Kollig & Keller 2002, "Efficient multidimensional sampling"). Every
// prefix of 2^m points, and every aligned block [k·2^m, (k+1)·2^m), is a (0,m,2)-net in
// base 2: each of the 2^m elementary intervals of area 2^−m holds exactly one point. So
// the first 2^m points stratify like the 2^m-point Hammersley set, and an item that
// takes points [n, 2n) next keeps that quality at 2n. A digital shift (XOR of both
// coordinates with fixed bits) preserves the net property of every such block.
#pragma once

#include <cstdint>

namespace prtbake::detail {

inline uint32_t sobolDim0(uint32_t i) {
  i = (i << 16) | (i >> 16);
  i = ((i & 0x00ff00ffu) << 8) | ((i & 0xff00ff00u) >> 8);
  i = ((i & 0x0f0f0f0fu) << 4) | ((i & 0xf0f0f0f0u) >> 4);
  i = ((i & 0x33333333u) << 2) | ((i & 0xccccccccu) >> 2);
  i = ((i & 0x55555555u) << 1) | ((i & 0xaaaaaaaau) >> 1);
  return i;
}

inline uint32_t sobolDim1(uint32_t i) {
  uint32_t r = 0;
  for (uint32_t v = 1u << 31; i; i >>= 1, v ^= v >> 1)
    if (i & 1) r ^= v;
  return r;
}

// Point i with digital shift (x0, x1), as doubles in [0, 1).
inline void sobolPoint(uint32_t i, uint32_t x0, uint32_t x1, double& u1, double& u2) {
  u1 = double(sobolDim0(i) ^ x0) * 0x1.0p-32;
  u2 = double(sobolDim1(i) ^ x1) * 0x1.0p-32;
}

}  // namespace prtbake::detail
