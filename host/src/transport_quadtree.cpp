// Visibility quadtree for shadowed transport under "--tolerance E" (see transport.h).
//
// With the cosine-weighted map of the uniform path, u ∈ [0, 1]² → ω(u) in the vertex's
// frame (u1 = sin²θ, φ = 2π u2; du = cosθ/π dω), the direct term is
//   T_i = ∫ V(ω(u)) Y_i(ω(u)) du.
// The square starts as a root grid (at least kTransportRootCells² cells, refined for small
// E) on a grid of 2^kDepth steps. A ray is traced at every cell corner (corners are
// shared: each is traced once; the u1 = 0 edge is one direction, the normal, and u2 = 1 is
// u2 = 0). A cell whose four corners agree counts as wholly visible or occluded; a mixed
// cell contributes f·I_c, f its fraction of visible corners and I_c = ∫_cell Y_i du, and
// it may be wrong by all of I_c, so
//   est = max_i c · Σ_mixed ∫_cell |Y_i| du   (c = kTransportMixedFactor).
// While est ≥ E, every mixed cell is split in four; the new corners (edge midpoints and
// centres, deduplicated per vertex by sorting) of all vertices of a batch are traced in
// one launch (kernels/transport.cl, transport_ray_list[_packet]). The cell integrals are
// Gauss–Legendre quadratures in (θ, u2) on the host in double: in θ the integrand is a
// trigonometric polynomial, smooth at the pole and the horizon where it is not in u1. The
// visible part is summed directly, or, where most root cells are visible, as the
// closed-form unshadowed term (clampedCosineProjected) minus the occluded part. Vertices
// are independent: the host work is spread over threads, and the result does not depend
// on their number. Samples are rays. A cell whose corners agree can still hide an occluder
// smaller than itself; the root grid is refined so that one root cell holds at most
// kTransportRootFraction · E of any coefficient.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <thread>

#include "gauss_legendre.h"
#include "prtbake/sh.h"
#include "prtbake/sh_rotate.h"
#include "transport_direct.h"

namespace prtbake::detail {
namespace {

const double kPi = 3.14159265358979323846;
constexpr int kDepth = 14;
constexpr uint32_t kSide = 1u << kDepth;
// Vertices per batch: at most 4096, and few enough that a batch whose every vertex reaches
// the cap (about 40 bytes of keys, directions and cells per ray) stays within 1 GiB.
constexpr size_t kMaxVertexBatch = 4096;
constexpr size_t kBatchBytes = size_t(1) << 30;
constexpr size_t kLocalSize = 16;

// A cell [x, x + s] × [y, y + s] in grid steps (u = grid / kSide) and the visibility of
// its corners: bit 0 (x, y), bit 1 (x + s, y), bit 2 (x, y + s), bit 3 (x + s, y + s).
struct Cell {
  uint32_t x, y, s;
  uint8_t vis;
};

// Spreads the low 16 bits of v to the even bits.
uint32_t spreadBits(uint32_t v) {
  v &= 0xffff;
  v = (v | v << 8) & 0x00ff00ff;
  v = (v | v << 4) & 0x0f0f0f0f;
  v = (v | v << 2) & 0x33333333;
  return (v | v << 1) & 0x55555555;
}
uint32_t compactBits(uint32_t v) {
  v &= 0x55555555;
  v = (v | v >> 1) & 0x33333333;
  v = (v | v >> 2) & 0x0f0f0f0f;
  v = (v | v >> 4) & 0x00ff00ff;
  return (v | v >> 8) & 0xffff;
}
// A corner's key: the Morton code of (x, y) (x ≤ kSide, y < kSide), so that sorted keys,
// traced in that order, put nearby directions into one packet.
uint32_t cornerKey(uint32_t x, uint32_t y) {
  if (x == 0 || y == kSide) y = 0;  // the pole is one direction; φ is periodic
  return spreadBits(x) << 1 | spreadBits(y);
}
constexpr uint32_t kPoleKey = 0;
constexpr uint32_t kPoleSlot = ~0u;
// The visible fraction taken for a mixed cell with 1, 2 or 3 visible corners: the mean
// over straight edges crossing the two sides at uniform positions u, v of the corner
// triangle's area uv/2 (1/8; 7/8 for three corners), 1/2 for two. (The corner count over 4
// overstates a lone corner's share twofold and biases every edge cell.)
constexpr double kMixedFraction[5] = {0, 0.125, 0.5, 0.875, 1};
// The new points of a split cell, in half sides from its corner (x, y): the bottom, left,
// centre, right and top midpoints (the 3 × 3 points minus the four corners).
constexpr uint32_t kSplitPoints[5][2] = {{1, 0}, {0, 1}, {1, 1}, {2, 1}, {1, 2}};

// cos and sin of 2π y / kSide for every grid column y (the azimuths of all corners).
const std::vector<double>& azimuthTable() {
  static const std::vector<double> t = [] {
    std::vector<double> v(2 * size_t(kSide));
    for (uint32_t y = 0; y < kSide; ++y) {
      v[2 * y] = std::cos(2 * kPi * y / kSide);
      v[2 * y + 1] = std::sin(2 * kPi * y / kSide);
    }
    return v;
  }();
  return t;
}

// The local direction of a corner; the horizon (u1 = 1) is lifted by 1e-6 in u1 (1e-3 rad).
void cornerDirection(uint32_t key, float* d) {
  const double u1 = std::min(double(compactBits(key >> 1)) / kSide, 1 - 1e-6);
  const double* cs = &azimuthTable()[2 * size_t(compactBits(key))];  // y < kSide after cornerKey
  const double r = std::sqrt(u1);
  d[0] = float(r * cs[0]), d[1] = float(r * cs[1]), d[2] = float(std::sqrt(1 - u1));
}

struct Tree {
  std::vector<Cell> mixed;                       // the mixed cells of the last level
  std::vector<uint32_t> keys;                    // the new corners of the next level, sorted
  std::vector<uint8_t> keyVis;                   // their visibility once traced
  std::vector<uint32_t> slotKey;                 // mixed cell i's new point q: index in keys (5 i + q)
  std::vector<float> dirs;                       // their rays: local direction, vertex (int bits)
  std::vector<double> full, mixedSum, mixedAbs;  // per coefficient
  bool occludedForm = false;  // `full` sums the occluded cells (T = U − occluded − ...)
  bool splitting = false;
  bool atCap = false;
  uint8_t poleVis = 0;
  int64_t rays = 0;
  float estimate = 0;
};

// Integrals of the local-frame SH over cells. In the vertex's frame Y_j(θ, φ) = A_j(θ) B_j(φ),
// B = cos mφ (m > 0), sin |m|φ (m < 0), 1 (m = 0), and A_{l,−m} = A_{l,m} (both √2 K P_l^|m|
// with the Condon–Shortley phase): A_j(θ) = Y_{l,|m|}(θ, φ = 0). So a cell's integral is
//   I_j = Θ_j(row) · Φ_m(column),  Θ_j = ∫ A_j(θ) 2 sinθ cosθ dθ (du1 = 2 sinθ cosθ dθ),
// Φ_m = ∫ B_m(2π u2) du2 in closed form, and Θ by Gauss–Legendre in θ, where A is a
// trigonometric polynomial (smooth at the pole and the horizon, where it is not in u1):
// kThetaNodes nodes over a row of width w ≤ 0.26 rad give a relative error of about
// ((order + 1) w/2)^(2n)/(2n)!, below 1e-12 to order 8. Rows and columns depend on the
// level alone, so the tables serve every vertex; the world coefficients are the local
// ones rotated once per vertex (shRotationExact).
class CellTables {
 public:
  explicit CellTables(int order) : order_(order), nc_(order * order), g_(gaussLegendre(kThetaNodes)) {
    for (int l = 0; l < order; ++l)
      for (int m = -l; m <= l; ++m) mIndex_.push_back(m + order - 1);
  }
  // Tabulates the rows and columns of cells of side s (not thread-safe: call between levels).
  void prepare(uint32_t s) {
    if (levels_.count(s)) return;
    Level& lv = levels_[s];
    const uint32_t n = kSide / s;
    const int nm = 2 * order_ - 1;
    lv.theta.assign(size_t(n) * nc_, 0.0);
    lv.phi.assign(size_t(n) * nm, 0.0);
    std::vector<double> y(nc_);
    for (uint32_t r = 0; r < n; ++r) {
      const double t0 = std::asin(std::sqrt(double(r) / n)), t1 = std::asin(std::sqrt(double(r + 1) / n));
      double* th = &lv.theta[size_t(r) * nc_];
      for (size_t i = 0; i < g_.x.size(); ++i) {
        const double t = t0 + (t1 - t0) * g_.x[i], st = std::sin(t), ct = std::cos(t);
        shEval(order_, st, 0, ct, y.data());
        const double w = (t1 - t0) * g_.w[i] * 2 * st * ct;
        for (int l = 0, j = 0; l < order_; ++l)
          for (int m = -l; m <= l; ++m, ++j) th[j] += w * y[size_t(l * (l + 1) + std::abs(m))];
      }
      double* ph = &lv.phi[size_t(r) * nm];
      const double c = double(r) / n, d = double(r + 1) / n;
      for (int m = -(order_ - 1); m < order_; ++m) {
        const double k = 2 * kPi * std::abs(m);
        ph[m + order_ - 1] = m == 0 ? d - c
                             : m > 0 ? (std::sin(k * d) - std::sin(k * c)) / k
                                     : (std::cos(k * c) - std::cos(k * d)) / k;
      }
    }
  }
  // sum_j += scale · ∫_cell Y_j du (local frame).
  void add(const Cell& c, double scale, double* sum) const {
    const Level& lv = levels_.at(c.s);
    const double* th = &lv.theta[size_t(c.x / c.s) * nc_];
    const double* ph = &lv.phi[size_t(c.y / c.s) * (2 * order_ - 1)];
    for (int j = 0; j < nc_; ++j) sum[j] += scale * th[j] * ph[mIndex_[j]];
  }

 private:
  static constexpr int kThetaNodes = 8;
  struct Level {
    std::vector<double> theta, phi;  // rows × nc, columns × (2 order − 1)
  };
  int order_, nc_;
  GaussRule g_;
  std::vector<int> mIndex_;
  std::map<uint32_t, Level> levels_;
};

// ∫_cell |Y_i| du in the world frame by the value at the cell's centre (for the estimate
// of a mixed cell, whose own value is uncertain by its whole integral anyway).
void addCentreAbs(int order, const float* frame, const Cell& c, double* abs, std::vector<double>& y) {
  const double u1 = (c.x + 0.5 * c.s) / kSide, phi = 2 * kPi * (c.y + 0.5 * c.s) / kSide;
  const double st = std::sqrt(u1), lx = st * std::cos(phi), ly = st * std::sin(phi), lz = std::sqrt(1 - u1);
  double w[3];
  for (int k = 0; k < 3; ++k) w[k] = frame[k] * lx + frame[4 + k] * ly + frame[8 + k] * lz;
  shEval(order, w[0], w[1], w[2], y.data());
  const double area = double(c.s) * c.s / (double(kSide) * kSide);
  for (size_t k = 0; k < y.size(); ++k) abs[k] += area * std::abs(y[k]);
}

}  // namespace

void quadtreeTransport(Runtime& rt, const RaySetup& setup, cl::Buffer nodes, cl::Buffer tris,
                       const std::vector<uint32_t>& vertices, const TransportOptions& o, TransportResult& r) {
  const int nc = o.order * o.order;
  // Root cells per side: at least kTransportRootCells, and enough that one whole root cell
  // holds at most kTransportRootFraction · E of any coefficient (|Y_i| ≤ √((2l + 1)/4π),
  // largest at l = order − 1), so that an occluder missed between the corners of a cell
  // costs a fraction of E; within the cap.
  const double yMax = std::sqrt((2.0 * o.order - 1) / (4 * kPi));
  uint32_t cells = uint32_t(kTransportRootCells);
  while (cells < kSide / 2 && yMax / (double(cells) * cells) > kTransportRootFraction * o.tolerance &&
         (2 * cells + 1) * 2 * cells + 1 <= uint32_t(o.toleranceMaxSamples))
    cells *= 2;
  const uint32_t root = kSide / cells;
  CellTables tables(o.order);
  tables.prepare(root);
  const std::vector<double> unshadowedLocal = clampedCosineProjected(o.order, 0, 0, 1);
  // The root corners as sorted keys, and where corner (i, j) of the root grid sits among them.
  std::vector<uint32_t> rootKeys;
  for (uint32_t i = 0; i <= cells; ++i)
    for (uint32_t j = 0; j < cells; ++j) rootKeys.push_back(cornerKey(i * root, j * root));
  std::sort(rootKeys.begin(), rootKeys.end());
  rootKeys.erase(std::unique(rootKeys.begin(), rootKeys.end()), rootKeys.end());
  std::vector<uint32_t> rootIndex(size_t(cells + 1) * cells);
  for (uint32_t i = 0; i <= cells; ++i)
    for (uint32_t j = 0; j < cells; ++j)
      rootIndex[size_t(i) * cells + j] = uint32_t(
          std::lower_bound(rootKeys.begin(), rootKeys.end(), cornerKey(i * root, j * root)) - rootKeys.begin());
  // Packets of `width` rays of one vertex (o.packetWidth; 0: one ray per work-item).
  const size_t width = size_t(std::max(1, o.packetWidth));
  cl::Kernel kernel = rt.kernel("transport.cl", width > 1 ? "transport_ray_list_packet" : "transport_ray_list",
                                "-DSH_ORDER=" + std::to_string(o.order) + " -DVISIBILITY=1 -DCHANNELS=1 -DBVH_PACKET=" +
                                    std::to_string(o.packetWidth));
  cl::Buffer origins = rt.upload(setup.origins), frames = rt.upload(setup.frames);
  const unsigned threads = std::max(1u, std::min(4u, std::thread::hardware_concurrency()));

  const size_t batch = std::clamp(kBatchBytes / (40 * size_t(o.toleranceMaxSamples)), size_t(1), kMaxVertexBatch);
  for (size_t first = 0; first < vertices.size(); first += batch) {
    const size_t count = std::min(batch, vertices.size() - first);
    std::vector<Tree> trees(count);
    // Runs f(t, integrator) for every tree, spread over the threads (trees are independent).
    std::vector<std::vector<double>> scratch(threads, std::vector<double>(nc));
    auto forTrees = [&](auto&& f) {
      std::vector<std::thread> pool;
      for (unsigned k = 0; k < threads; ++k)
        pool.emplace_back([&, k] {
          for (size_t t = k; t < count; t += threads) f(t, scratch[k]);
        });
      for (auto& th : pool) th.join();
    };
    // The rays of tree t's pending corners.
    auto directions = [&](size_t t) {
      Tree& tr = trees[t];
      const int32_t v = int32_t(vertices[first + t]);
      tr.dirs.resize(4 * tr.keys.size());
      for (size_t i = 0; i < tr.keys.size(); ++i) {
        cornerDirection(tr.keys[i], &tr.dirs[4 * i]);
        std::memcpy(&tr.dirs[4 * i + 3], &v, 4);
      }
    };
    // Classifies `cells` of tree t: wholly visible or occluded cells are integrated, mixed
    // ones kept; then the estimate, and the next level's corners unless it stops.
    auto classify = [&](size_t t, std::vector<double>& y, const std::vector<Cell>& cells, bool root) {
      Tree& tr = trees[t];
      const float* frame = &setup.frames[12 * size_t(vertices[first + t])];
      if (root) {
        size_t visible = 0, occluded = 0;
        for (const Cell& c : cells) visible += c.vis == 15, occluded += c.vis == 0;
        tr.occludedForm = visible > occluded;
      }
      tr.mixed.clear();
      tr.mixedSum.assign(nc, 0.0), tr.mixedAbs.assign(nc, 0.0);
      const uint8_t whole = tr.occludedForm ? 0 : 15;
      for (const Cell& c : cells) {
        if (c.vis == whole) tables.add(c, 1.0, tr.full.data());
        if (c.vis == 0 || c.vis == 15) continue;
        tr.mixed.push_back(c);
        const double f = kMixedFraction[__builtin_popcount(c.vis)];
        tables.add(c, tr.occludedForm ? 1 - f : f, tr.mixedSum.data());
        addCentreAbs(o.order, frame, c, tr.mixedAbs.data(), y);
      }
      double est = 0;
      for (int k = 0; k < nc; ++k) est = std::max(est, kTransportMixedFactor * tr.mixedAbs[k]);
      tr.estimate = float(est);
      tr.splitting = false;
      if (est < o.tolerance || tr.mixed.empty() || tr.mixed.front().s == 1) return;
      // The new points of the split (kSplitPoints per mixed cell), deduplicated by sorting
      // (key, slot) pairs; each slot keeps the index of its key (the pole is known).
      std::vector<uint64_t> tagged;
      tagged.reserve(5 * tr.mixed.size());
      for (size_t i = 0; i < tr.mixed.size(); ++i) {
        const Cell& c = tr.mixed[i];
        for (uint32_t q = 0; q < 5; ++q) {
          const uint32_t px = c.x + kSplitPoints[q][0] * c.s / 2, py = c.y + kSplitPoints[q][1] * c.s / 2;
          tagged.push_back(uint64_t(cornerKey(px, py)) << 32 | (5 * i + q));
        }
      }
      std::sort(tagged.begin(), tagged.end());
      tr.keys.clear();
      tr.slotKey.assign(tagged.size(), kPoleSlot);
      for (uint64_t g : tagged) {
        const uint32_t k = uint32_t(g >> 32);
        if (k == kPoleKey) continue;
        if (tr.keys.empty() || tr.keys.back() != k) tr.keys.push_back(k);
        tr.slotKey[g & 0xffffffffu] = uint32_t(tr.keys.size() - 1);
      }
      if (tr.rays + int64_t(tr.keys.size()) > o.toleranceMaxSamples) {
        tr.atCap = true;
        return;
      }
      tr.splitting = true;
      directions(t);
    };
    // Traces the pending corners of every splitting tree, padded to whole packets.
    auto trace = [&] {
      std::vector<float> rays;
      std::vector<std::pair<uint32_t, uint32_t>> slot;  // (tree, index in its keys)
      for (size_t t = 0; t < count; ++t) {
        Tree& tr = trees[t];
        if (!tr.splitting || tr.keys.empty()) continue;
        tr.keyVis.assign(tr.keys.size(), 0);
        tr.rays += int64_t(tr.keys.size());
        for (size_t i = 0; i < tr.keys.size() || slot.size() % width; ++i) {
          const size_t k = std::min(i, tr.keys.size() - 1);  // padding repeats the last ray
          rays.insert(rays.end(), &tr.dirs[4 * k], &tr.dirs[4 * k + 4]);
          slot.emplace_back(uint32_t(t), uint32_t(k));
        }
      }
      const size_t nr = slot.size();
      if (nr == 0) return false;
      std::vector<uint8_t> vis(nr);
      cl::Buffer rb = rt.upload(rays);
      cl::Buffer ob(rt.context(), CL_MEM_WRITE_ONLY, nr);
      const size_t items = nr / width;
      kernel.setArg(0, int(items));
      kernel.setArg(1, rb);
      kernel.setArg(2, origins);
      kernel.setArg(3, frames);
      kernel.setArg(4, nodes);
      kernel.setArg(5, tris);
      kernel.setArg(6, setup.tMax);
      kernel.setArg(7, ob);
      rt.queue().enqueueNDRangeKernel(kernel, cl::NullRange,
                                      cl::NDRange((items + kLocalSize - 1) / kLocalSize * kLocalSize),
                                      cl::NDRange(kLocalSize));
      rt.queue().enqueueReadBuffer(ob, CL_TRUE, 0, nr, vis.data());
      for (size_t k = 0; k < nr; ++k) trees[slot[k].first].keyVis[slot[k].second] = vis[k];
      return true;
    };

    // The root grid: its corners (the pole once, u2 = 1 as u2 = 0) are the first level's keys.
    forTrees([&](size_t t, std::vector<double>&) {
      Tree& tr = trees[t];
      tr.full.assign(nc, 0.0);
      tr.keys = rootKeys;
      tr.splitting = true;
      directions(t);
    });
    trace();
    uint32_t levelSide = root;
    forTrees([&](size_t t, std::vector<double>& y) {
      Tree& tr = trees[t];
      auto vis = [&](uint32_t x, uint32_t y) { return tr.keyVis[rootIndex[size_t(x / root) * cells + (y / root) % cells]]; };
      tr.poleVis = vis(0, 0);
      std::vector<Cell> rootCells;
      for (uint32_t i = 0; i < cells; ++i)
        for (uint32_t j = 0; j < cells; ++j) {
          const uint32_t x = i * root, y = j * root;
          const uint8_t m = uint8_t(vis(x, y) | vis(x + root, y) << 1 | vis(x, y + root) << 2 | vis(x + root, y + root) << 3);
          rootCells.push_back({x, y, root, m});
        }
      classify(t, y, rootCells, true);
    });
    // Levels: split every mixed cell of every splitting tree.
    while (trace()) {
      tables.prepare(levelSide /= 2);
      forTrees([&](size_t t, std::vector<double>& shValues) {
        Tree& tr = trees[t];
        if (!tr.splitting) return;
        auto vis = [&](size_t slot) -> uint8_t {
          const uint32_t k = tr.slotKey[slot];
          return k == kPoleSlot ? tr.poleVis : tr.keyVis[k];
        };
        std::vector<Cell> kids;
        kids.reserve(4 * tr.mixed.size());
        for (size_t ci = 0; ci < tr.mixed.size(); ++ci) {
          const Cell& c = tr.mixed[ci];
          const uint32_t h = c.s / 2;
          // The 3 × 3 points of the split, row by row from (x, y).
          const size_t b5 = 5 * ci;
          const uint8_t p[9] = {uint8_t(c.vis & 1), vis(b5), uint8_t(c.vis >> 1 & 1),
                                vis(b5 + 1), vis(b5 + 2), vis(b5 + 3),
                                uint8_t(c.vis >> 2 & 1), vis(b5 + 4), uint8_t(c.vis >> 3 & 1)};
          for (uint32_t q = 0; q < 4; ++q) {
            const uint32_t i = q & 1, j = q >> 1, b = 3 * j + i;
            const uint8_t m = uint8_t(p[b] | p[b + 1] << 1 | p[b + 3] << 2 | p[b + 4] << 3);
            kids.push_back({c.x + i * h, c.y + j * h, h, m});
          }
        }
        classify(t, shValues, kids, false);
      });
    }
    for (size_t t = 0; t < count; ++t) {
      const Tree& tr = trees[t];
      const uint32_t v = vertices[first + t];
      // Local coefficients, then rotated by the frame R = [t b n] (local → world).
      std::vector<double> c(nc, 0.0);
      if (tr.occludedForm) c = unshadowedLocal;
      const double sign = tr.occludedForm ? -1 : 1;
      for (int k = 0; k < nc; ++k) c[k] += sign * (tr.full[k] + tr.mixedSum[k]);
      const float* f = &setup.frames[12 * size_t(v)];
      Rotation rot;
      for (int row = 0; row < 3; ++row)
        for (int col = 0; col < 3; ++col) rot.m[size_t(3 * row + col)] = f[4 * col + row];
      const ShRotationBlocks m = shRotationExact(rot, o.order);
      for (int l = 0; l < o.order; ++l) {
        const int w = 2 * l + 1;
        for (int i = 0; i < w; ++i) {
          double acc = 0;
          for (int j = 0; j < w; ++j) acc += m[size_t(l)][size_t(i * w + j)] * c[size_t(l * l + j)];
          r.coeffs[size_t(v) * nc + l * l + i] = float(acc);
        }
      }
      r.samplesPerVertex[v] = int(tr.rays);
      r.errorEstimate[v] = r.stdError[v] = tr.estimate;
      r.rays += uint64_t(tr.rays);
      r.verticesAtCap += tr.atCap;
    }
  }
}

}  // namespace prtbake::detail
