// lut_cell.h: the POD record of one square of the LUT's adaptive cubature, shared by
// the host (host/src/lut_adaptive.cpp) and kernels/lut_cubature.cl. No float3.
#ifndef PRTBAKE_LUT_CELL_H
#define PRTBAKE_LUT_CELL_H

// Pieces of one texel's half-vector domain (host/src/lut_reference.cpp): bit 0 picks
// the band θ ∈ [θ1, θ2] (else the cap θ ∈ [0, θ1]), bit 1 the cloth integrand (else
// the specular A, B). Each piece is a map of the unit square (s, t).
#define LUT_PIECE_BAND 1
#define LUT_PIECE_CLOTH 2

// One square [s0, s0 + h] × [t0, t0 + h] of one piece at one texel (32 bytes).
typedef struct {
  float mu;      // N·V in [0, 1]
  float alpha;   // NDF width α > 0 (cloth: already clamped to kLutClothAlphaMin)
  float s0, t0, h;
  int piece;     // LUT_PIECE_* bits
  float x1, x2;  // x(θ1), x(θ2) of the texel's θ map (computed on the host in double)
} LutCell;

// Output record per square: its value and its four quadrant predictions (lut_cubature.cl).
#define LUT_CELL_OUT_FLOAT4S 5

#endif
