// sh_eval.cl: evaluates the SH basis at a list of directions (tests, previews).
#include "sh.clh"

#define SH_EVAL_MAX 1024

// order: SH order n (n² ≤ 1024)
// count: number of directions
// dirs:  count × (x, y, z), unit vectors
// out:   count × n² basis values, direction-major
__kernel void sh_eval_dirs(int order, int count, __global const float* dirs, __global float* out) {
  int i = get_global_id(0);
  if (i >= count) return;
  float y[SH_EVAL_MAX];
  sh_eval(order, dirs[3 * i], dirs[3 * i + 1], dirs[3 * i + 2], y);
  int nc = order * order;
  for (int k = 0; k < nc; ++k) out[(size_t)i * nc + k] = y[k];
}
