// Adaptive cubature for the LUT ("--tolerance E"; see lut.h).
//
// Each texel's integrals are those of the double reference (lut_reference.cpp): smooth
// pieces of the half-vector domain, each the image of the unit square; the cloth table
// has its own pieces. Every piece starts as kLutRootCells² leaf cells. A leaf carries Q,
// the 3×3 Gauss–Legendre value over its square, and the values of its four children; it
// contributes the children's sum, and
//   est(leaf) = max over channels |Q − Σ children|
// is the error of the coarser Q, so a pessimistic estimate of the finer sum's (for a
// smooth integrand the rule's error falls like h^6, the children's sum is far closer).
// A root leaf's estimate has a floor against chance agreement (kRootGuard below).
// The texel's estimate is Σ est over its leaves. While it is ≥ E, the leaves with the
// largest estimates are split (a split leaf's children become leaves, each needing its
// own four children: 16 squares), the fewest whose removal brings the sum of the others
// below E, so that the splits of one round go to the device together (kernels/
// lut_cubature.cl, one work-item per square). A texel stops when its estimate is below
// E, or when the next split would pass the cap (counted at the cap). Samples are
// integrand evaluations, 9 per square. Texels are independent and done in batches sized
// so that the host memory stays bounded even when every texel reaches the cap.
// Deterministic.
//
// Measured against uniform Hammersley tables at equal maximum error: docs/accuracy.md,
// bench/study/.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>

#include "lut_cell.h"
#include "lut_detail.h"
#include "prtbake/error.h"
#include "prtbake/runtime.h"

namespace prtbake::detail {
namespace {

const double kPi = 3.14159265358979323846;
constexpr int kNodesPerSquare = 9;         // the 3×3 rule
constexpr int kSquaresPerSplit = 16;       // four new leaves, four children each
constexpr size_t kTexelBatch = 1 << 14;
// Host memory per texel is about kBytesPerEvaluation × its evaluations (leaves and the
// round's requests; measured: 64² at the 65536 cap, 6.1 GB in one batch), so a batch
// holds at most kBatchBytes / (kBytesPerEvaluation × cap) texels.
constexpr size_t kBytesPerEvaluation = 24;
constexpr size_t kBatchBytes = size_t(1) << 30;
// A root cell is coarse enough for Q and its children to agree by chance while both miss
// a feature (measured: 64² Beckmann, E = 1e-4, one texel 1.4e-3 off with an estimate of
// 7e-5). Its estimate is therefore at least kRootGuard × the children's summed distance
// from what Q's own interpolant predicts for each quadrant (which cannot cancel across
// quadrants). Measured on 64² tables: 0.1 leaves Beckmann at E = 1e-2 at a maximum error
// of 4.1e-3, 0.25 brings it to 9e-4 for 5 % more evaluations; 0.5 costs 10–30 % more.
constexpr double kRootGuard = 0.25;

static_assert(sizeof(LutCell) == 32, "LutCell must match kernels/lut_cell.h");

struct Leaf {
  LutCell cell;         // the leaf's square
  double q[3] = {};     // its 3×3 value (A, B, C)
  double kids[4][3] = {};
  double pred[4][3] = {};  // root leaves: Q's interpolant integrated over each quadrant
  int depth = 0;           // 0 for a root leaf
  double est = 0;
};

struct Texel {
  std::vector<Leaf> leaves;
  int64_t evals = 0;
};

// The pieces present at (μ, α) for the specular or the cloth integrand, as root-cell
// templates: piece bits and the x range [x1, x2] of the θ map (lut_cubature.cl).
std::vector<LutCell> piecesAt(double mu, double alpha, bool cloth) {
  std::vector<LutCell> p;
  if (alpha <= 0) return p;
  const double thetaV = std::acos(std::clamp(mu, 0.0, 1.0)), sv = std::sqrt(std::max(0.0, 1 - mu * mu));
  const double th1 = std::max(0.0, kPi / 4 - thetaV / 2), th2 = kPi / 4 + thetaV / 2;
  auto xOf = [&](double th) {
    if (cloth) return th / (kPi / 2);
    return th >= kPi / 2 ? 1.0 : std::atan(std::tan(th) / alpha) / (kPi / 2);
  };
  const int bit = cloth ? LUT_PIECE_CLOTH : 0;
  LutCell c{float(mu), float(alpha), 0, 0, 1, bit, float(xOf(th1)), float(xOf(th2))};
  if (th1 > 0) p.push_back(c);
  c.piece |= LUT_PIECE_BAND;
  if (sv > 0) p.push_back(c);
  return p;
}

LutCell square(const LutCell& parent, int kid) {
  LutCell c = parent;
  c.h = parent.h / 2;
  c.s0 = parent.s0 + (kid & 1) * c.h;
  c.t0 = parent.t0 + (kid >> 1) * c.h;
  return c;
}

class CellEvaluator {
 public:
  CellEvaluator(Runtime& rt, const LutOptions& o) : rt_(rt) {
    for (int piece = 0; piece < 4; ++piece)
      kernels_[piece] = rt.kernel("lut_cubature.cl", "lut_cells",
                                  "-DLUT_NDF=" + std::to_string(o.ndf == LutNdf::Beckmann ? 1 : 0) +
                                      " -DLUT_VIS=" + std::to_string(int(o.visibility)) +
                                      " -DLUT_PIECE=" + std::to_string(piece));
  }
  // The values of `cells` (LUT_CELL_OUT_FLOAT4S float4 each, in the order of `cells`): one
  // launch per kind of piece.
  std::vector<float> operator()(const std::vector<LutCell>& cells, double* seconds) {
    constexpr size_t kOut = 4 * LUT_CELL_OUT_FLOAT4S;
    std::vector<float> out(cells.size() * kOut);
    for (int piece = 0; piece < 4; ++piece) {
      std::vector<LutCell> group;
      std::vector<size_t> where;
      for (size_t i = 0; i < cells.size(); ++i)
        if (cells[i].piece == piece) group.push_back(cells[i]), where.push_back(i);
      if (group.empty()) continue;
      std::vector<float> res(group.size() * kOut);
      cl::Buffer in(rt_.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, group.size() * sizeof(LutCell),
                    group.data());
      cl::Buffer ob(rt_.context(), CL_MEM_WRITE_ONLY, res.size() * sizeof(float));
      cl::Kernel& k = kernels_[piece];
      k.setArg(0, int(group.size()));
      k.setArg(1, in);
      k.setArg(2, ob);
      const size_t local = 16, global = (group.size() + local - 1) / local * local;
      const auto t0 = std::chrono::steady_clock::now();
      rt_.queue().enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(global), cl::NDRange(local));
      rt_.queue().finish();
      *seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      rt_.queue().enqueueReadBuffer(ob, CL_TRUE, 0, res.size() * sizeof(float), res.data());
      for (size_t i = 0; i < where.size(); ++i)
        std::copy_n(&res[i * kOut], kOut, &out[where[i] * kOut]);
    }
    return out;
  }

 private:
  Runtime& rt_;
  cl::Kernel kernels_[4];
};

// A pending request: the value of square `kid` (−1: the leaf's own Q) of leaf `leaf`.
struct Request {
  uint32_t texel, leaf;
  int kid;
};

void requestKids(const Leaf& l, uint32_t texel, uint32_t leaf, std::vector<LutCell>& cells,
                 std::vector<Request>& reqs) {
  for (int k = 0; k < 4; ++k) {
    cells.push_back(square(l.cell, k));
    reqs.push_back({texel, leaf, k});
  }
}

// max over channels |Q − Σ children|; for a root leaf at least kRootGuard ·
// Σ_k |child_k − quadrant k of Q's interpolant|.
double leafEstimate(const Leaf& l) {
  double e = 0, g = 0;
  for (int c = 0; c < 3; ++c) {
    e = std::max(e, std::abs(l.q[c] - (l.kids[0][c] + l.kids[1][c] + l.kids[2][c] + l.kids[3][c])));
    double gc = 0;
    for (int k = 0; k < 4; ++k) gc += std::abs(l.kids[k][c] - l.pred[k][c]);
    g = std::max(g, gc);
  }
  return l.depth == 0 ? std::max(e, kRootGuard * g) : e;
}

}  // namespace

LutResult computeLutAdaptive(Runtime& rt, const LutOptions& options) {
  const auto tStart = std::chrono::steady_clock::now();
  LutResult r;
  r.options = options;
  r.size = options.size;
  r.device = rt.deviceLabel();
  const int n = options.size;
  const size_t texels = size_t(n) * n;
  const double build0 = rt.buildSeconds();
  CellEvaluator evaluate(rt, options);
  r.buildSeconds = rt.buildSeconds() - build0;
  const double tol = options.tolerance;
  const int64_t cap = options.toleranceMaxSamples;
  r.a.assign(texels, 0.0f), r.b.assign(texels, 0.0f);
  std::vector<float> cloth(options.cloth ? texels : 0, 0.0f);
  r.errorEstimate.assign(texels, 0.0f);
  r.samplesPerTexel.assign(texels, 0);

  const size_t batch = std::clamp(kBatchBytes / (kBytesPerEvaluation * size_t(cap)), size_t(16), kTexelBatch);
  for (size_t first = 0; first < texels; first += batch) {
    const size_t count = std::min(batch, texels - first);
    std::vector<Texel> batch(count);
    std::vector<LutCell> cells;
    std::vector<Request> reqs;
    // Round 0: the root leaves, their values and their children.
    for (size_t i = 0; i < count; ++i) {
      const size_t t = first + i;
      const double mu = (double(t % size_t(n)) + 0.5) / n;
      const double alpha = lutAlpha(options, (double(t / size_t(n)) + 0.5) / n);
      Texel& tx = batch[i];
      std::vector<LutCell> pieces = piecesAt(mu, alpha, false);
      if (options.cloth) {
        const std::vector<LutCell> cp = piecesAt(mu, std::max(alpha, kLutClothAlphaMin), true);
        pieces.insert(pieces.end(), cp.begin(), cp.end());
      }
      for (const LutCell& piece : pieces) {
        for (int j = 0; j < kLutRootCells * kLutRootCells; ++j) {
          Leaf l;
          const float h = 1.0f / kLutRootCells;
          l.cell = piece;
          l.cell.s0 = (j % kLutRootCells) * h, l.cell.t0 = (j / kLutRootCells) * h, l.cell.h = h;
          const uint32_t li = uint32_t(tx.leaves.size());
          cells.push_back(l.cell);
          reqs.push_back({uint32_t(i), li, -1});
          requestKids(l, uint32_t(i), li, cells, reqs);
          tx.leaves.push_back(l);
          tx.evals += 5 * kNodesPerSquare;
        }
      }
    }
    while (!cells.empty()) {
      const std::vector<float> v = evaluate(cells, &r.kernelSeconds);
      std::vector<uint32_t> touched;
      for (size_t k = 0; k < reqs.size(); ++k) {
        const Request& q = reqs[k];
        Leaf& l = batch[q.texel].leaves[q.leaf];
        const float* vk = &v[4 * LUT_CELL_OUT_FLOAT4S * k];
        double* dst = q.kid < 0 ? l.q : l.kids[q.kid];
        for (int c = 0; c < 3; ++c) dst[c] = vk[c];
        if (q.kid < 0)
          for (int quad = 0; quad < 4; ++quad)
            for (int c = 0; c < 3; ++c) l.pred[quad][c] = vk[4 * (1 + quad) + c];
        if (touched.empty() || touched.back() != q.texel) touched.push_back(q.texel);
      }
      cells.clear(), reqs.clear();
      for (uint32_t i : touched) {
        Texel& tx = batch[i];
        double total = 0;
        for (Leaf& l : tx.leaves) total += (l.est = leafEstimate(l));
        if (total < tol) continue;
        // The fewest largest leaves whose removal leaves the others below E.
        std::vector<uint32_t> order(tx.leaves.size());
        std::iota(order.begin(), order.end(), 0u);
        std::sort(order.begin(), order.end(), [&](uint32_t x, uint32_t y) {
          return tx.leaves[x].est > tx.leaves[y].est || (tx.leaves[x].est == tx.leaves[y].est && x < y);
        });
        size_t splits = 0;
        for (double rest = total; splits < order.size() && rest >= tol; ++splits) {
          if (tx.evals + int64_t(splits + 1) * kSquaresPerSplit * kNodesPerSquare > cap) break;
          rest -= tx.leaves[order[splits]].est;
        }
        if (splits == 0) {
          ++r.texelsAtCap;
          continue;
        }
        for (size_t s = 0; s < splits; ++s) {
          const Leaf parent = tx.leaves[order[s]];
          for (int k = 0; k < 4; ++k) {
            Leaf child;
            child.cell = square(parent.cell, k);
            child.depth = parent.depth + 1;
            std::copy(parent.kids[k], parent.kids[k] + 3, child.q);
            // The first child replaces the parent; the others are appended.
            const uint32_t li = k == 0 ? order[s] : uint32_t(tx.leaves.size());
            if (k == 0) tx.leaves[li] = child;
            else tx.leaves.push_back(child);
            requestKids(child, i, li, cells, reqs);
          }
        }
        tx.evals += int64_t(splits) * kSquaresPerSplit * kNodesPerSquare;
      }
    }
    for (size_t i = 0; i < count; ++i) {
      const size_t t = first + i;
      const Texel& tx = batch[i];
      double sum[3] = {}, est = 0;
      for (const Leaf& l : tx.leaves) {
        for (int c = 0; c < 3; ++c) sum[c] += l.kids[0][c] + l.kids[1][c] + l.kids[2][c] + l.kids[3][c];
        est += l.est;
      }
      const double alpha = lutAlpha(options, (double(t / size_t(n)) + 0.5) / n);
      if (alpha <= 0) {  // a mirror: closed form
        const double mu = (double(t % size_t(n)) + 0.5) / n, fc = std::pow(1 - mu, 5);
        sum[0] = 1 - fc, sum[1] = fc;
      }
      r.a[t] = float(sum[0]), r.b[t] = float(sum[1]);
      if (options.cloth) cloth[t] = float(sum[2]);
      r.errorEstimate[t] = float(est);
      r.samplesPerTexel[t] = int(tx.evals);
    }
  }
  finishLut(r, cloth, r.errorEstimate);
  double errSum = 0;
  for (size_t t = 0; t < texels; ++t) {
    r.errorEstimateMax = std::max(r.errorEstimateMax, double(r.errorEstimate[t]));
    errSum += r.errorEstimate[t];
    const int s = r.samplesPerTexel[t];
    r.totalSamples += uint64_t(s);
    const size_t k = s > 0 ? size_t(std::floor(std::log2(double(s)))) : 0;
    if (r.samplesHistogram.size() <= k) r.samplesHistogram.resize(k + 1, 0);
    ++r.samplesHistogram[k];
  }
  r.errorEstimateMean = texels ? errSum / double(texels) : 0;
  r.totalSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - tStart).count();
  return r;
}

}  // namespace prtbake::detail
