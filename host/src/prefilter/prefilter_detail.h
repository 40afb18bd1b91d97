// Private: the pieces of the prefilter driver (prefilter.cpp) that tests and the
// reference share: the bin tree, the lobe's tables and the tile cuts (prefilter_cut.cpp).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <utility>
#include <vector>

#include "prtbake/envmap.h"
#include "prtbake/prefilter.h"
#include "prtbake/raw_vector.h"

namespace prtbake::detail {


// The quadtree of cube-face bins over the source. Level 0 holds the finest bins
// (faceSize0 per face side), level m bins of faceSize0 >> m, the last level one bin per
// face. Node (m, face, row, col) sits at offset[m] + (face·M + row)·M + col, M = faceSize0 >> m.
// Per node (float4 each, for the kernel):
//   flux  (F_r, F_g, F_b, Ω): Σ L_t Ω_t and Σ Ω_t over the source texels whose centre falls
//         in the bin (exact texel solid angles, yaw applied)
//   dirL  the radiance-weighted centroid direction normalize(Σ w_t Ω_t ω_t), w = (r+g+b)/3
//         (the solid-angle one for a black bin)
//   dirG  the solid-angle-weighted centroid direction normalize(Σ Ω_t ω_t)
// and, for the host's cut only (geom), the spreads about those centroids
//   spreadL = Σ w_t Ω_t |ω_t − c^L|² / Σ w_t Ω_t = 2 (1 − |Σ w_t Ω_t ω_t| / Σ w_t Ω_t)
//   spreadG, the same with w = 1 (0 for a bin of one texel, whatever its size).
// Sums are taken in double and rounded once. The arrays are filled once, never zeroed first
// (fresh memory is slow to touch on these machines, PERF.md).
struct BinTree {
  int faceSize0 = 0;
  int levels = 0;
  std::vector<size_t> offset;  // levels + 1 entries
  RawVector<float> flux, dirL, dirG;
  // For the traversal, per node: centre direction (x, y, z), angular radius, mean-of-channels
  // flux F̃, Ω, spreadL, spreadG.
  RawVector<std::array<float, 8>> geom;
  size_t nodes() const { return offset.back(); }
};

// faceSize0: a power of two up to 1024.
BinTree buildBinTree(const EnvMap& env, int faceSize0);

// Sums of one bin in double: F (3), Ω, m_L = Σ w_t Ω_t ω_t (3), m_G = Σ Ω_t ω_t (3).
using BinSums = std::array<double, 10>;

// The same tree from a map read a band of texels at a time (forEachLatLongBand), to the
// bit: every texel is added to its finest bin's sums as it comes, in index order, as
// buildBinTree sums each bin's texels. Holds 80 bytes per finest bin (6·faceSize0²) until
// finish() has read them.
class BinTreeBands {
 public:
  // description: the map's layout, size, face bases and yaw (its texels are not read).
  BinTreeBands(const EnvMap& description, int faceSize0);
  ~BinTreeBands();
  // Adds `count` texels of float RGB, those of index firstTexel.. of the map (texelDirection's
  // index). Bands must come in index order.
  void add(const float* rgb, size_t firstTexel, size_t count);
  // The tree; frees the sums.
  BinTree finish();

 private:
  struct Stream;
  std::unique_ptr<Stream> stream_;
  int faceSize0_ = 0;
  std::array<std::vector<BinSums>, 6> sums_;  // per face, by Morton code
};

// The finest bin size used for a source: the largest power of two not above the source's
// face size (cube) or width/4 (lat-long), at most kMaxBinFaceSize.
constexpr int kMaxBinFaceSize = 512;
int binFaceSizeFor(const EnvMap& env);
// The angular size (radians) of the source's largest texel: 2/n (cube), 2π/W (lat-long).
double sourceTexelAngle(const EnvMap& env);

// The lobe as a function of the angle θ between R and l, g(θ) = prefilterLobeWeight(μ = cos θ),
// tabulated on a θ grid over [0, π/2] (dense near the peak) with range queries for the
// smallest g and the largest curvature H = max(|g''|, |g' cot θ|) over an interval of θ,
// the lobe's mean weight ḡ = ∫ g dω/(4π) and its slope at the horizon |g'(π/2)|, where
// max(0, μ) kinks. The cut criterion built on these is in prefilter_cut.cpp.
class LobeScale {
 public:
  LobeScale(PrefilterLobe lobe, double alpha, double tolerance);
  double tolerance() const { return tolerance_; }
  // Over [lo, hi] ∩ [0, π/2] (radians): the smallest g, the largest H and the largest
  // H/g (infinite when the range crosses the horizon).
  void range(double lo, double hi, double* gMin, double* hMax, double* rMax) const;
  double meanWeight() const { return gMean_; }
  // Charlie: a ring near the horizon, thinner than most tiles (prefilter_cut.cpp's lower bounds).
  bool ring() const { return ring_; }
  double horizonSlope() const { return horizonSlope_; }

 private:
  int index(double theta, bool up) const;
  double gridPosition(double theta) const;
  std::vector<std::vector<std::array<float, 4>>> table_;  // sparse table over the θ grid
  double tolerance_ = 0, gMean_ = 0, horizonSlope_ = 0;
  bool ring_ = false;
  double split_ = 0, fineStep_ = 1, coarseStep_ = 1, invFine_ = 1, invCoarse_ = 0;
  int grid_ = 0, fine_ = 0;
};

// Output tiles. Each face of an n×n level is covered by a quadtree of tiles over the
// padded size P = the power of two ≥ n: leaves of L×L texels (L = min(kLeafSize, P), twice
// that from n = kLargeLeafFrom), parents doubling up to the whole face; tiles that start
// beyond n do not exist, tiles across it are clipped. Larger leaves share more of the cut and
// sum more bins: measured at the filament schedule, 16² leaves halve the host's share of the
// 512² level of a 1024 chain (3.4 → 1.8 s) for a slower kernel (1.6 → 1.9 s), and cost more
// than they save at 128² (0.8 → 0.9 s). Tile (k, face, ty, tx), k = 0 for the leaves,
// has id offset[k] + (face·S_k + ty)·S_k + tx with S_k = P/(L·2^k) tiles per side.
constexpr int kLeafSize = 8;
constexpr int kLargeLeafFrom = 256;
struct TileTree {
  int n = 0, padded = 0, leaf = 0, levels = 0;
  std::vector<uint32_t> offset;  // levels + 1 entries
  int side(int k) const { return padded / (leaf << k); }
  uint32_t id(int k, int face, int ty, int tx) const {
    return offset[size_t(k)] + uint32_t((face * side(k) + ty) * side(k) + tx);
  }
};
TileTree makeTileTree(int n);

// The cut: for every tile, the bins whose whole contribution it takes for all its texels,
// start[id]..start[id+1] in `bins` (entries as forEachBinEntry reads them); a texel sums the
// lists of its leaf and of every tile above it. Found by a dual traversal of tiles and bins: a (tile, bin) pair is taken when
// the bin meets the criterion of prefilter_cut.cpp for every texel of the tile; otherwise
// the larger of the two is opened (a finest bin in a leaf is taken anyway and counted in
// `unresolved`). Bins beyond the horizon of every texel of a tile, and empty bins, are
// left out. Only the tiles of `face` above the leaves in `leaves` (leaf index ty·S_0 + tx;
// all leaves of the face when empty) are cut.
struct TileCuts {
  std::vector<uint32_t> start, bins;
  size_t unresolved = 0;
};
TileCuts buildTileCuts(const BinTree& tree, const LobeScale& scale, const TileTree& tiles, int face,
                       const std::vector<int>& leaves);

// List entries: bin (level, face, row, col) taken as its 4^depth descendants `depth` levels
// down (depth 0: the bin itself), packed as level:4 | depth:4 | face:3 | row:10 | col:10.
// f(node) for every bin of an entry.
void forEachBinEntry(const BinTree& tree, uint32_t entry, const std::function<void(size_t)>& f);

// The same sum as the kernel, in double, for every texel of the given leaves of `face` (RGB
// per texel, leaves in order, row-major within a leaf, texels inside the level only). For tests.
std::vector<double> evaluateCutsReference(const BinTree& tree, const TileCuts& cuts, const TileTree& tiles,
                                          PrefilterLobe lobe, double alpha, int face, const std::vector<int>& leaves);

// resampleEnvironment of a lat-long map read a band of rows at a time (forEachLatLongBand).
// Each bilinear lookup is taken in the band that holds its rows (the previous band's last row
// is kept), into double sums per output texel that live from the first band reaching the
// texel's tile of 8 × 8 to the band covering its last rows. A texel whose lookups all fall in
// one band gets resampleEnvironment's bits; one whose lookups straddle bands adds them in
// another order (a difference of at most one float ulp, 2⁻²³ relative).
class ResampleBands {
 public:
  // description: the map's size and yaw (its texels are not read); n: the cube's face size.
  ResampleBands(const EnvMap& description, int n);
  ~ResampleBands();
  // Rows firstRow.. of the map as float RGB (band.rgb); bands must come in order.
  void add(const EnvMap& band, int firstRow);
  // The n×n cube (as resampleEnvironment's), once every row has come.
  std::vector<float> finish();

 private:
  struct Tile;
  bool finishTile(size_t id);  // false when the tile missed lookups
  void tilePosition(size_t id, int* face, int* ty, int* tx) const;  // id = (face·side + ty)·side + tx
  EnvMap map_;                 // the description
  int n_ = 0, side_ = 0, nextRow_ = 0;
  std::vector<int> rowLo_, rowHi_;  // per tile: the rows its lookups may start at
  std::vector<std::unique_ptr<Tile>> tiles_;
  std::vector<float> out_, lastRow_;
  std::atomic<size_t> finished_{0};
};

// Face (0..5) and u, v ∈ [−1, 1] of a direction in the standard cube (docs/conventions.md "Cube faces").
void cubeFaceUv(const double d[3], int* face, double* u, double* v);

}  // namespace prtbake::detail
