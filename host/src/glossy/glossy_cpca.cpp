// Clustered PCA of per-vertex transfer matrices (Sloan, Hall, Hart and Snyder 2003).
//
// Each vertex's matrix is a point x_v in R^D (D = channels × n_out² × n_in²). K clusters,
// each an affine subspace: a mean μ_k and P orthonormal directions b_k1..b_kP. A vertex v
// in cluster k is stored as its id and its weights w_vp = b_kp·(x_v − μ_k), and
// reconstructed as x̃_v = μ_k + Σ_p w_vp b_kp. Lloyd iteration:
//   1. assign each vertex to the cluster whose subspace reconstructs it best:
//      e_k(x) = |x − μ_k|² − Σ_p (b_kp·(x − μ_k))²  (the squared distance to the subspace);
//   2. refit each cluster: μ_k the mean of its members, b_k the top-P principal directions
//      of the centred members by subspace iteration (B ← orth(Σ_v (x_v − μ) (B(x_v − μ))ᵀ)),
//      warm-started from the previous iteration's basis;
// until fewer than 0.1 % of the vertices move. Initial clusters: k-means++ seeding on a
// fixed subset with a fixed generator (deterministic), then nearest-mean assignment.
// The dot products x·μ_k and x·b_kp dominate (V × K(P+1) × D multiply-adds per
// iteration); they run in 4 × 4 tiles of (vertex, row) with 8-wide float vectors (AVX2
// where the CPU has it), over the vertices in threads. Weights and errors are computed in
// double at the end.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <thread>

#include "core/radical_inverse.h"
#include "core/parallel.h"
#include "prtbake/clock.h"
#include "prtbake/error.h"
#include "prtbake/glossy.h"

namespace prtbake {
using detail::parallelFor;
namespace {

typedef float v8 __attribute__((vector_size(32)));

#pragma GCC diagnostic ignored "-Wpsabi"  // v8 never crosses a call boundary between the two builds
#define LOAD8(dst, p) std::memcpy(&(dst), (p), 32)
#define hsum8(v) ((((v)[0] + (v)[1]) + ((v)[2] + (v)[3])) + (((v)[4] + (v)[5]) + ((v)[6] + (v)[7])))

typedef float v16 __attribute__((vector_size(64)));

// out[i * ldo + r] = x_i · c_r for i < ni (≤ 4 vertex rows xs[i]) and r < nr rows of c:
// tiles of 4 vertices × TR rows, W-wide vectors VT (16 accumulators and 5 operands fit
// AVX-512's 32 registers; AVX2's 16 take 4 × 2).
#define PRTBAKE_DOT_TILE_BODY(VT, W, TR)                                                        \
  const size_t dw = dim / W * W;                                                                \
  for (size_t r0 = 0; r0 < nr; r0 += TR) {                                                      \
    const size_t rn = std::min<size_t>(TR, nr - r0);                                            \
    VT acc[4][TR];                                                                              \
    for (auto& a : acc)                                                                         \
      for (auto& b : a) b = VT{} * 0.0f;                                                        \
    const float* cr[TR];                                                                        \
    for (size_t r = 0; r < TR; ++r) cr[r] = c + (r0 + std::min(r, rn - 1)) * dim;               \
    const float* xr[4];                                                                         \
    for (size_t i = 0; i < 4; ++i) xr[i] = xs[std::min(i, ni - 1)];                             \
    for (size_t d = 0; d < dw; d += W) {                                                        \
      VT cv[TR];                                                                                \
      for (size_t r = 0; r < TR; ++r) std::memcpy(&cv[r], cr[r] + d, sizeof(VT));               \
      for (size_t i = 0; i < 4; ++i) {                                                          \
        VT x;                                                                                   \
        std::memcpy(&x, xr[i] + d, sizeof(VT));                                                 \
        for (size_t r = 0; r < TR; ++r) acc[i][r] += x * cv[r];                                 \
      }                                                                                         \
    }                                                                                           \
    for (size_t i = 0; i < ni; ++i)                                                             \
      for (size_t r = 0; r < rn; ++r) {                                                         \
        float s = 0.0f;                                                                         \
        for (size_t k = 0; k < W; ++k) s += acc[i][r][k];                                       \
        for (size_t d = dw; d < dim; ++d) s += xr[i][d] * cr[r][d];                             \
        out[i * ldo + r0 + r] = s;                                                              \
      }                                                                                         \
  }

__attribute__((target("avx512f,avx512vl,fma"))) void dotTileAvx512(const float* const* xs, size_t ni, const float* c,
                                                                   size_t nr, size_t dim, float* out, size_t ldo) {
  PRTBAKE_DOT_TILE_BODY(v16, 16, 4)
}
__attribute__((target("avx2,fma"))) void dotTileAvx2(const float* const* xs, size_t ni, const float* c, size_t nr,
                                                     size_t dim, float* out, size_t ldo) {
  PRTBAKE_DOT_TILE_BODY(v8, 8, 2)
}
void dotTileGeneric(const float* const* xs, size_t ni, const float* c, size_t nr, size_t dim, float* out, size_t ldo) {
  PRTBAKE_DOT_TILE_BODY(v8, 8, 2)
}

// z[r] += a[r] * x for the rows r < nr of z (D each): the rank-1 updates of subspace iteration.
#define PRTBAKE_AXPY_BODY                                      \
  const size_t d8 = dim / 8 * 8;                               \
  for (size_t r = 0; r < nr; ++r) {                            \
    float* zr = z + r * dim;                                   \
    const v8 av = v8{a[r], a[r], a[r], a[r], a[r], a[r], a[r], a[r]}; \
    for (size_t d = 0; d < d8; d += 8) {                       \
      v8 zv, xv;                                               \
      LOAD8(zv, zr + d);                                       \
      LOAD8(xv, x + d);                                        \
      zv += av * xv;                                           \
      std::memcpy(zr + d, &zv, 32);                            \
    }                                                          \
    for (size_t d = d8; d < dim; ++d) zr[d] += a[r] * x[d];   \
  }
__attribute__((target("avx2,fma"))) void axpyAvx2(const float* a, size_t nr, const float* x, size_t dim, float* z) {
  PRTBAKE_AXPY_BODY
}
void axpyGeneric(const float* a, size_t nr, const float* x, size_t dim, float* z) { PRTBAKE_AXPY_BODY }

bool haveAvx2() {
  static const bool yes = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return yes;
}
bool haveAvx512() {
  static const bool yes = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") && haveAvx2();
  return yes;
}
void dotTile(const float* const* xs, size_t ni, const float* c, size_t nr, size_t dim, float* out, size_t ldo) {
  if (haveAvx512()) dotTileAvx512(xs, ni, c, nr, dim, out, ldo);
  else if (haveAvx2()) dotTileAvx2(xs, ni, c, nr, dim, out, ldo);
  else dotTileGeneric(xs, ni, c, nr, dim, out, ldo);
}
void axpy(const float* a, size_t nr, const float* x, size_t dim, float* z) {
  if (haveAvx2()) axpyAvx2(a, nr, x, dim, z);
  else axpyGeneric(a, nr, x, dim, z);
}

using detail::splitmix64;

struct Model {
  size_t K = 0, P = 0, D = 0;
  std::vector<float> rows;  // K × (P + 1) × D: μ_k then b_k1..b_kP
  std::vector<float> beta;  // K × P: b_kp · μ_k
  std::vector<float> mu2;   // K: |μ_k|²
  const float* mean(size_t k) const { return rows.data() + k * (P + 1) * D; }
  float* mean(size_t k) { return rows.data() + k * (P + 1) * D; }
  float* basis(size_t k, size_t p) { return rows.data() + (k * (P + 1) + 1 + p) * D; }
  void refresh() {
    beta.assign(K * P, 0.0f);
    mu2.assign(K, 0.0f);
    for (size_t k = 0; k < K; ++k) {
      const float* m = mean(k);
      double s = 0;
      for (size_t d = 0; d < D; ++d) s += double(m[d]) * m[d];
      mu2[k] = float(s);
      for (size_t p = 0; p < P; ++p) {
        const float* b = basis(k, p);
        double t = 0;
        for (size_t d = 0; d < D; ++d) t += double(b[d]) * m[d];
        beta[k * P + p] = float(t);
      }
    }
  }
};

// Orthonormalises the rows of z (n × D) by modified Gram–Schmidt in double; a row that
// vanishes is replaced by the first coordinate axis independent of the others.
void orthonormalise(float* z, size_t n, size_t D) {
  std::vector<double> q(n * D);
  for (size_t i = 0; i < n * D; ++i) q[i] = z[i];
  for (size_t r = 0; r < n; ++r) {
    double* a = &q[r * D];
    for (int pass = 0; pass < 2; ++pass)
      for (size_t s = 0; s < r; ++s) {
        const double* b = &q[s * D];
        double dot = 0;
        for (size_t d = 0; d < D; ++d) dot += a[d] * b[d];
        for (size_t d = 0; d < D; ++d) a[d] -= dot * b[d];
      }
    double norm = 0;
    for (size_t d = 0; d < D; ++d) norm += a[d] * a[d];
    norm = std::sqrt(norm);
    if (norm < 1e-20) {
      for (size_t axis = 0; axis < D; ++axis) {
        std::fill(a, a + D, 0.0);
        a[axis] = 1;
        for (size_t s = 0; s < r; ++s) {
          const double* b = &q[s * D];
          const double dot = b[axis];
          for (size_t d = 0; d < D; ++d) a[d] -= dot * b[d];
        }
        norm = 0;
        for (size_t d = 0; d < D; ++d) norm += a[d] * a[d];
        norm = std::sqrt(norm);
        if (norm > 0.5) break;
      }
    }
    for (size_t d = 0; d < D; ++d) a[d] /= norm;
  }
  for (size_t i = 0; i < n * D; ++i) z[i] = float(q[i]);
}

class Cpca {
 public:
  Cpca(const float* x, size_t V, size_t D, int threads) : x_(x), V_(V), D_(D), threads_(threads) {
    norm2_.resize(V);
    for (size_t v = 0; v < V; ++v) {
      double s = 0;
      for (size_t d = 0; d < D; ++d) s += double(row(v)[d]) * row(v)[d];
      norm2_[v] = s;
    }
  }
  const float* row(size_t v) const { return x_ + v * D_; }

  // Squared reconstruction error of every vertex in every cluster's subspace; the best
  // cluster per vertex. Returns how many vertices changed cluster.
  size_t assign(const Model& m, std::vector<int32_t>& cluster, std::vector<float>* bestErr = nullptr) {
    const size_t R = m.K * (m.P + 1);
    std::vector<size_t> moved(size_t(std::max(threads_, 1)), 0);
    if (bestErr) bestErr->assign(V_, 0.0f);
    parallelFor(V_, threads_, [&](size_t a, size_t b, int t) {
      std::vector<float> dots(4 * R);
      for (size_t v0 = a; v0 < b; v0 += 4) {
        const size_t ni = std::min<size_t>(4, b - v0);
        const float* xs[4];
        for (size_t i = 0; i < 4; ++i) xs[i] = row(v0 + std::min(i, ni - 1));
        dotTile4(xs, ni, m.rows.data(), R, dots.data());
        for (size_t i = 0; i < ni; ++i) {
          const float* dv = &dots[i * R];
          double best = INFINITY;
          int32_t bk = 0;
          for (size_t k = 0; k < m.K; ++k) {
            const float* dk = dv + k * (m.P + 1);
            double e = norm2_[v0 + i] - 2.0 * dk[0] + m.mu2[k];
            for (size_t p = 0; p < m.P; ++p) {
              const double w = double(dk[1 + p]) - m.beta[k * m.P + p];
              e -= w * w;
            }
            if (e < best) best = e, bk = int32_t(k);
          }
          if (cluster[v0 + i] != bk) ++moved[size_t(t)];
          cluster[v0 + i] = bk;
          if (bestErr) (*bestErr)[v0 + i] = float(std::max(0.0, best));
        }
      }
    });
    size_t total = 0;
    for (size_t c : moved) total += c;
    return total;
  }

  // Means and (warm-started) bases of every cluster; `steps` subspace iterations.
  void fit(Model& m, const std::vector<int32_t>& cluster, int steps) {
    std::vector<std::vector<uint32_t>> members(m.K);
    for (size_t v = 0; v < V_; ++v) members[size_t(cluster[v])].push_back(uint32_t(v));
    parallelFor(m.K, threads_, [&](size_t a, size_t b, int) {
      std::vector<float> z, dots, y;
      for (size_t k = a; k < b; ++k) fitCluster(m, k, members[k], steps, z, dots, y);
    });
    m.refresh();
  }

 private:
  void dotTile4(const float* const* xs, size_t ni, const float* c, size_t nr, float* out) const {
    dotTile(xs, ni, c, nr, D_, out, nr);
  }

  void fitCluster(Model& m, size_t k, const std::vector<uint32_t>& mem, int steps, std::vector<float>& z,
                  std::vector<float>& dots, std::vector<float>& y) const {
    const size_t D = D_, P = m.P;
    float* mu = m.mean(k);
    if (mem.empty()) return;  // kept as it was (the caller reseeds empty clusters)
    std::vector<double> sum(D, 0.0);
    for (uint32_t v : mem)
      for (size_t d = 0; d < D; ++d) sum[d] += row(v)[d];
    for (size_t d = 0; d < D; ++d) mu[d] = float(sum[d] / double(mem.size()));
    if (P == 0) return;
    float* B = m.basis(k, 0);
    if (mem.size() <= P + 1) {
      // The affine span of the members: exact.
      for (size_t p = 0; p < P; ++p)
        for (size_t d = 0; d < D; ++d) B[p * D + d] = p + 1 < mem.size() ? row(mem[p + 1])[d] - row(mem[0])[d] : 0.0f;
      orthonormalise(B, P, D);
      return;
    }
    z.resize(P * D);
    y.resize(P);
    dots.resize(4 * P);
    for (int s = 0; s < steps; ++s) {
      std::vector<double> muB(P);
      for (size_t p = 0; p < P; ++p) {
        double t = 0;
        for (size_t d = 0; d < D; ++d) t += double(B[p * D + d]) * mu[d];
        muB[p] = t;
      }
      std::fill(z.begin(), z.end(), 0.0f);
      std::vector<double> ysum(P, 0.0);
      for (size_t i0 = 0; i0 < mem.size(); i0 += 4) {
        const size_t ni = std::min<size_t>(4, mem.size() - i0);
        const float* xs[4];
        for (size_t i = 0; i < 4; ++i) xs[i] = row(mem[i0 + std::min(i, ni - 1)]);
        dotTile(xs, ni, B, P, D, dots.data(), P);
        for (size_t i = 0; i < ni; ++i) {
          for (size_t p = 0; p < P; ++p) {
            y[p] = float(double(dots[i * P + p]) - muB[p]);
            ysum[p] += y[p];
          }
          axpy(y.data(), P, xs[i], D, z.data());
        }
      }
      // z_p = Σ_v y_vp (x_v − μ) = Σ_v y_vp x_v − μ Σ_v y_vp.
      for (size_t p = 0; p < P; ++p)
        for (size_t d = 0; d < D; ++d) z[p * D + d] -= float(ysum[p]) * mu[d];
      orthonormalise(z.data(), P, D);
      std::copy(z.begin(), z.end(), B);
    }
  }

  const float* x_;
  size_t V_, D_;
  int threads_;
  std::vector<double> norm2_;
};

// Bytes of a CPCA: float32 means and basis, int32 cluster ids, weights of `bits` bits (and
// with int8 weights float32 scales per cluster and vector and per vertex).
double cpcaBytes(double K, double P, double V, double D, int bits) {
  return 4 * (K * (P + 1) * D + V) + V * P * (bits / 8) + (bits == 8 ? 4 * (K * P + V) : 0);
}

// k-means++ seeding of the K means on at most 4096 vertices spread over the mesh, with a
// fixed generator.
void seedMeans(const Cpca& c, Model& m, size_t V) {
  const size_t K = m.K, D = m.D;
  std::vector<size_t> subset;
  const size_t ns = std::min<size_t>(V, 4096);
  for (size_t i = 0; i < ns; ++i) subset.push_back(i * V / ns);
  std::vector<double> dist(ns, INFINITY);
  uint64_t state = 0x5EED;
  size_t pick = subset[0];
  for (size_t k = 0; k < K; ++k) {
    std::copy(c.row(pick), c.row(pick) + D, m.mean(k));
    double total = 0;
    for (size_t i = 0; i < ns; ++i) {
      double e = 0;
      const float* a = c.row(subset[i]);
      const float* b = m.mean(k);
      for (size_t d = 0; d < D; ++d) e += double(a[d] - b[d]) * (a[d] - b[d]);
      dist[i] = std::min(dist[i], e);
      total += dist[i];
    }
    state = splitmix64(state);
    double target = double(state >> 11) * 0x1.0p-53 * total;
    pick = subset[ns - 1];
    for (size_t i = 0; i < ns; ++i) {
      target -= dist[i];
      if (target <= 0 && dist[i] > 0) {
        pick = subset[i];
        break;
      }
    }
  }
  // Bases start as coordinate-free directions: orthonormalised deterministic noise.
  for (size_t k = 0; k < K; ++k)
    for (size_t p = 0; p < m.P; ++p) {
      float* b = m.basis(k, p);
      for (size_t d = 0; d < D; ++d) b[d] = float(double(splitmix64(k * 1000003 + p * 7919 + d) >> 11) * 0x1.0p-53 - 0.5);
    }
  for (size_t k = 0; k < K; ++k)
    if (m.P) orthonormalise(m.basis(k, 0), m.P, D);
}

// The first assignment by nearest mean (P = 0), then Lloyd iterations with P until fewer than
// 0.1 % of the vertices move, then a last fit; returns the iterations run.
int lloyd(Cpca& c, Model& m, std::vector<int32_t>& cluster, size_t V, int iterations) {
  const size_t K = m.K, D = m.D;
  {
    Model m0;
    m0.K = K, m0.P = 0, m0.D = D;
    m0.rows.assign(K * D, 0.0f);
    for (size_t k = 0; k < K; ++k) std::copy(m.mean(k), m.mean(k) + D, m0.mean(k));
    m0.refresh();
    c.assign(m0, cluster);
  }
  int it = 0;
  std::vector<float> err;
  for (; it < iterations; ++it) {
    c.fit(m, cluster, it == 0 ? 4 : 2);
    const size_t moved = c.assign(m, cluster, &err);
    // Empty clusters take the worst-reconstructed vertices.
    std::vector<size_t> count(K, 0);
    for (int32_t k : cluster) ++count[size_t(k)];
    for (size_t k = 0; k < K; ++k)
      if (count[k] == 0) {
        const size_t worst = size_t(std::max_element(err.begin(), err.end()) - err.begin());
        --count[size_t(cluster[worst])];
        cluster[worst] = int32_t(k);
        count[k] = 1;
        err[worst] = 0;
      }
    if (it > 0 && double(moved) < 1e-3 * double(V)) {
      ++it;
      break;
    }
  }
  c.fit(m, cluster, 4);
  return it;
}

// x_v − μ_k of vertex v in its cluster k, in double.
void centred(const Cpca& c, const CpcaResult& r, size_t v, std::vector<double>& diff) {
  const size_t D = r.dim, k = size_t(r.clusterOf[v]);
  const float* x = c.row(v);
  for (size_t d = 0; d < D; ++d) diff[d] = double(x[d]) - r.means[k * D + d];
}

// int8 weights: w_vp ≈ q_vp · c_kp · t_v, c_kp the RMS of weight p over cluster k's members,
// t_v the vertex's largest |w_vp| / c_kp over 127. The per-vertex factor keeps the relative
// error of weakly lit (small) matrices as small as that of the others; w becomes exactly what
// a reader of the int8 array reconstructs.
void quantiseWeights(CpcaResult& r) {
  const size_t K = size_t(r.clusters), P = size_t(r.vectors), V = r.vertexCount;
  const std::vector<int32_t>& cluster = r.clusterOf;
  std::vector<double> sum2(K * P, 0.0);
  std::vector<size_t> members(K, 0);
  for (size_t v = 0; v < V; ++v) {
    ++members[size_t(cluster[v])];
    for (size_t p = 0; p < P; ++p) sum2[size_t(cluster[v]) * P + p] += double(r.weights[v * P + p]) * r.weights[v * P + p];
  }
  r.weightScales.assign(K * P, 0.0f);
  for (size_t k = 0; k < K; ++k)
    for (size_t p = 0; p < P; ++p)
      if (members[k]) r.weightScales[k * P + p] = float(std::sqrt(sum2[k * P + p] / double(members[k])));
  r.vertexScales.assign(V, 0.0f);
  for (size_t v = 0; v < V; ++v) {
    const float* c = &r.weightScales[size_t(cluster[v]) * P];
    float t = 0;
    for (size_t p = 0; p < P; ++p)
      if (c[p] > 0) t = std::max(t, std::fabs(r.weights[v * P + p]) / c[p]);
    r.vertexScales[v] = t / 127.0f;
  }
  for (size_t v = 0; v < V; ++v)
    for (size_t p = 0; p < P; ++p) {
      const float step = cpcaInt8Step(r, v, p);
      r.weights[v * P + p] = cpcaInt8Value(cpcaInt8Code(r.weights[v * P + p], step), step);
    }
}

// Each vertex's relative error with the stored weights, as a shader reconstructs it, and the
// totals (CpcaResult's error fields).
void measureErrors(const Cpca& c, CpcaResult& r, int threads) {
  const size_t V = r.vertexCount, D = r.dim, P = size_t(r.vectors);
  r.vertexError.assign(V, 0.0f);
  std::vector<double> errAbs(V, 0.0), norms(V, 0.0);
  parallelFor(V, threads, [&](size_t a, size_t b, int) {
    std::vector<double> diff(D);
    for (size_t v = a; v < b; ++v) {
      const size_t k = size_t(r.clusterOf[v]);
      centred(c, r, v, diff);
      for (size_t p = 0; p < P; ++p) {
        const float* bp = &r.basis[(k * P + p) * D];
        const double w = r.weights[v * P + p];
        for (size_t d = 0; d < D; ++d) diff[d] -= w * bp[d];
      }
      const float* x = c.row(v);
      double e = 0, n = 0;
      for (size_t d = 0; d < D; ++d) e += diff[d] * diff[d], n += double(x[d]) * x[d];
      errAbs[v] = e, norms[v] = n;
      r.vertexError[v] = n > 0 ? float(std::sqrt(e / n)) : 0.0f;
    }
  });
  double se = 0, sn = 0, sr = 0;
  for (size_t v = 0; v < V; ++v) {
    se += errAbs[v], sn += norms[v];
    sr += double(r.vertexError[v]) * r.vertexError[v];
    r.maxVertexError = std::max(r.maxVertexError, double(r.vertexError[v]));
  }
  r.totalError = sn > 0 ? std::sqrt(se / sn) : 0;
  r.rmsVertexError = V ? std::sqrt(sr / double(V)) : 0;
}

CpcaResult runCpca(const float* data, size_t V, size_t D, size_t K, size_t P, int iterations, int threads,
                   int weightBits) {
  const auto t0 = std::chrono::steady_clock::now();
  K = std::max<size_t>(1, std::min(K, V));
  Cpca c(data, V, D, threads);
  Model m;
  m.K = K, m.P = P, m.D = D;
  m.rows.assign(K * (P + 1) * D, 0.0f);
  seedMeans(c, m, V);
  std::vector<int32_t> cluster(V, -1);
  const int it = lloyd(c, m, cluster, V, iterations);
  // Weights and errors in double.
  CpcaResult r;
  r.clusters = int(K), r.vectors = int(P), r.vertexCount = V, r.dim = D, r.iterations = it;
  r.means.resize(K * D);
  r.basis.resize(K * P * D);
  for (size_t k = 0; k < K; ++k) {
    std::copy(m.mean(k), m.mean(k) + D, &r.means[k * D]);
    for (size_t p = 0; p < P; ++p) std::copy(m.basis(k, p), m.basis(k, p) + D, &r.basis[(k * P + p) * D]);
  }
  r.clusterOf = cluster;
  r.weights.assign(V * P, 0.0f);
  parallelFor(V, threads, [&](size_t a, size_t b, int) {
    std::vector<double> diff(D);
    for (size_t v = a; v < b; ++v) {
      const size_t k = size_t(cluster[v]);
      centred(c, r, v, diff);
      for (size_t p = 0; p < P; ++p) {
        const float* bp = &r.basis[(k * P + p) * D];
        double w = 0;
        for (size_t d = 0; d < D; ++d) w += bp[d] * diff[d];
        r.weights[v * P + p] = float(w);
      }
    }
  });
  r.weightBits = weightBits;
  if (weightBits == 8) quantiseWeights(r);
  measureErrors(c, r, threads);
  r.seconds = secondsSince(t0);
  return r;
}

}  // namespace

double CpcaResult::storedBytes() const {
  return cpcaBytes(clusters, vectors, double(vertexCount), double(dim), weightBits);
}

double CpcaResult::compressionRatio() const {
  const double s = storedBytes();
  return s > 0 ? 4 * double(vertexCount) * double(dim) / s : 0;
}

namespace {

// Symmetric m × m matrices (shadowed and unshadowed transfer with n_in = n_out) are packed
// isometrically before clustering: the diagonal, then √2 × the lower triangle, so that
// Euclidean norms, PCA and every error are unchanged and the work halves. Returns m, or 0
// when the data are not such matrices.
size_t symmetricSide(const float* data, size_t V, size_t D) {
  const size_t m = size_t(std::lround(std::sqrt(double(D))));
  if (m * m != D || m < 2) return 0;
  for (size_t v = 0; v < V; ++v) {
    const float* x = data + v * D;
    for (size_t i = 0; i < m; ++i)
      for (size_t j = 0; j < i; ++j)
        if (x[i * m + j] != x[j * m + i]) return 0;
  }
  return m;
}

void packSymmetric(const float* x, size_t m, float* out) {
  size_t k = 0;
  for (size_t i = 0; i < m; ++i) out[k++] = x[i * m + i];
  for (size_t i = 0; i < m; ++i)
    for (size_t j = 0; j < i; ++j) out[k++] = float(std::sqrt(2.0) * x[i * m + j]);
}

void unpackSymmetric(const float* p, size_t m, float* x) {
  size_t k = 0;
  for (size_t i = 0; i < m; ++i) x[i * m + i] = p[k++];
  for (size_t i = 0; i < m; ++i)
    for (size_t j = 0; j < i; ++j) x[i * m + j] = x[j * m + i] = float(p[k++] / std::sqrt(2.0));
}

// storedD: the values per vertex as stored (symmetric data are clustered packed, stored whole).
CpcaResult cpcaSearch(const float* data, size_t V, size_t D, size_t storedD, const CpcaOptions& o);

}  // namespace

CpcaResult cpcaCompress(const float* data, size_t V, size_t D, const CpcaOptions& o) {
  if (V == 0 || D == 0) throw UsageError("cpca", "nothing to compress (no vertices)");
  const size_t m = symmetricSide(data, V, D);
  if (m == 0) return cpcaSearch(data, V, D, D, o);
  const size_t dp = m * (m + 1) / 2;
  std::vector<float> packed(V * dp);
  for (size_t v = 0; v < V; ++v) packSymmetric(data + v * D, m, &packed[v * dp]);
  CpcaResult r = cpcaSearch(packed.data(), V, dp, D, o);
  // Means and basis rows back to full matrices (the basis stays orthonormal).
  std::vector<float> means(size_t(r.clusters) * D), basis(size_t(r.clusters) * size_t(r.vectors) * D);
  for (size_t k = 0; k < size_t(r.clusters); ++k) unpackSymmetric(&r.means[k * dp], m, &means[k * D]);
  for (size_t k = 0; k < size_t(r.clusters) * size_t(r.vectors); ++k) unpackSymmetric(&r.basis[k * dp], m, &basis[k * D]);
  r.means.swap(means);
  r.basis.swap(basis);
  r.dim = D;
  return r;
}

namespace {
CpcaResult cpcaSearch(const float* data, size_t V, size_t D, size_t storedD, const CpcaOptions& o) {
  const int threads = o.threads > 0 ? o.threads : std::max(1, int(std::thread::hardware_concurrency()));
  if (o.iterations < 1 || o.iterations > 1000) throw UsageError("--cpca-iterations", "must lie in [1, 1000]");
  if (o.weightBits != 32 && o.weightBits != 8) throw UsageError("--cpca-weights", "must be float32 or int8");
  if (o.clusters > 0 && o.vectors >= 0 && !(o.targetError > 0)) {
    if (o.vectors > kMaxCpcaVectors)
      throw UsageError("--cpca", "at most " + std::to_string(kMaxCpcaVectors) + " PCA vectors per cluster");
    if (size_t(o.clusters) > V) throw UsageError("--cpca", "more clusters than vertices");
    if (size_t(o.vectors) > D)
      throw UsageError("--cpca", "more PCA vectors (" + std::to_string(o.vectors) + ") than independent values per vertex (" +
                                     std::to_string(D) + (D < storedD ? ": the matrices are symmetric)" : ")"));
    return runCpca(data, V, D, size_t(o.clusters), size_t(o.vectors), o.iterations, threads, o.weightBits);
  }
  if (!(o.targetError > 0 && o.targetError < 1))
    throw UsageError("--cpca-error", "give K and P, or a target relative RMS error in (0, 1)");
  // The ladder: K a power of two ≤ 256, P from the list below; the cheapest (K, P) in bytes
  // whose total error meets the target. The error falls with P, so for each K the smallest
  // P that meets it is found by bisection among the P cheaper than the best so far (each
  // tried with at most 8 iterations, the winner refitted in full).
  const std::vector<size_t> ladderP{1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 40, 48, 56, 64, 72, 80, 96, 112, 128};
  const double plainBytes = 4 * double(V) * double(storedD);
  std::vector<std::array<double, 3>> tried;
  CpcaResult best;
  double bestBytes = plainBytes;
  auto attempt = [&](size_t K, size_t P) {
    CpcaResult r = runCpca(data, V, D, K, P, std::min(o.iterations, 8), threads, o.weightBits);
    tried.push_back({double(K), double(P), r.totalError});
    return r;
  };
  for (size_t K = 1; K <= 256 && K <= V; K *= 2) {
    std::vector<size_t> ps;
    for (size_t P : ladderP)
      if (P < D && cpcaBytes(K, P, V, storedD, o.weightBits) < bestBytes) ps.push_back(P);
    if (ps.empty()) break;  // larger K only cost more
    CpcaResult hi = attempt(K, ps.back());
    if (hi.totalError > o.targetError) continue;
    size_t lo = 0, up = ps.size() - 1;  // ps[up] meets the target
    while (lo < up) {
      const size_t mid = (lo + up) / 2;
      CpcaResult r = attempt(K, ps[mid]);
      if (r.totalError <= o.targetError) up = mid, hi = std::move(r);
      else lo = mid + 1;
    }
    best = std::move(hi);
    bestBytes = cpcaBytes(K, best.vectors, V, storedD, o.weightBits);
  }
  if (best.clusters == 0)
    throw UsageError("--cpca-error", "no clustering of the ladder reaches relative RMS error " +
                                         std::to_string(o.targetError) + " while staying smaller than the matrices");
  if (o.iterations > 8)
    best = runCpca(data, V, D, size_t(best.clusters), size_t(best.vectors), o.iterations, threads, o.weightBits);
  best.tried = tried;
  return best;
}
}  // namespace

void cpcaReconstruct(const CpcaResult& c, size_t v, float* out) {
  const size_t k = size_t(c.clusterOf[v]), D = c.dim, P = size_t(c.vectors);
  for (size_t d = 0; d < D; ++d) out[d] = c.means[k * D + d];
  for (size_t p = 0; p < P; ++p) {
    const float w = c.weights[v * P + p];
    const float* b = &c.basis[(k * P + p) * D];
    for (size_t d = 0; d < D; ++d) out[d] += w * b[d];
  }
}

}  // namespace prtbake
