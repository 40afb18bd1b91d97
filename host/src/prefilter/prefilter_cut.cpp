// Prefiltering by exact sums over a cut of the bin tree: the bins, the lobe's length
// scale, the per-tile cuts and their double-precision evaluation (docs/prefilter.md).
//
// Why a cut is accurate. For a bin b holding texels t (radiance L_t, solid angle Ω_t,
// direction ω_t, luminance weight w_t = mean of the channels), its exact contribution to
// the numerator of P(R), Σ_t L_t Ω_t g(R·ω_t), expands about the radiance-weighted centroid
// c^L as
//   F_b g(R·c^L) + ½ Σ_t L_t Ω_t (ω_t − c^L)ᵀ ∇²g (ω_t − c^L) + …
// (the first-order term vanishes at the centroid), so taking the bin whole errs by at most
// ½ H σ_L² F̃_b, with H the largest curvature of g over the angles the bin spans from the
// tile and σ_L² the bin's radiance-weighted spread about its centroid (F̃ = mean-of-channels
// flux). A sun in one texel has no spread: it is summed without error at any distance. The
// denominator's bin errs by ½ H σ_G² Ω_b. A bin is taken whole when both stay within
//   (N)  ½ H σ_L² F̃_b ≤ ε (g_min F̃_b + ζ N̂)
//   (D)  ½ H σ_G² Ω_b ≤ ε (g_min Ω_b + ζ D̂)
// i.e. within ε of its own smallest contribution to the tile, or within εζ of the tile's
// whole sum: N̂ and D̂ are lower bounds of the numerator and denominator of every texel of
// the tile, Σ g_min F̃_b and Σ g_min Ω_b over a coarse first cut. With at most ~1/ζ bins
// leaning on the second allowance, the relative error of N and D, and so of P, stays of
// order ε; in the lobe's tails (D) sets bin radii growing as H^(-1/4), the allocation that
// minimises the bins for a given error, and (N) refines only where the light is bright.
// Across the horizon, where max(0, μ) kinks, H is at least |g'(π/2)|/ρ_b. The denominator
// uses the solid-angle centroid with the same g, so a constant environment gives exactly
// the constant.
//
// Finding the cut. Output texels are grouped in a quadtree of tiles (8×8 or 16×16 leaves) and the
// cut is found for (tile, bin) pairs at once: a pair that meets the criterion for every
// texel of the tile is listed with the tile (shared by all its texels), otherwise the
// larger of the two is opened. Where the host would open a bin all the way down to its
// finest bins, or where a bin is far from the tile for its size, the bin is listed once as
// a block of its descendants at one depth (the finest, or the depth the tile's nearest
// texel needs), which the kernel walks as rows of the bin array.

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <new>

#include "core/constants.h"
#include "core/parallel.h"
#include "prefilter/prefilter_detail.h"
#include "prtbake/error.h"
#include "prtbake/lut.h"

namespace prtbake {
namespace {

// Host threads of the cut's walks (tiles and pieces of uneven cost, handed out one at a time).
constexpr int kCutThreads = 8;

const double kHalfPi = kPi / 2;

// A bin at least this many times (its radius + the tile's) away from a tile may be taken as
// one block of its descendants at a uniform depth (the depth its nearest texel needs):
// fewer list entries for the host to find, a few more bins for the kernel (measured in
// docs/prefilter.md).
constexpr double kBlockDistance = 2.0;
// Near blocks (all finest bins of a bin, when every one of them would be opened anyway) are
// at most 2^k × 2^k finest bins.
constexpr int kNearBlockLevel = 3;
// ζ: the share of the tile's whole sum that one bin may err by (criterion (N), (D) above).
// Measured on the four HDR maps: ζ from 1e-3 to 3e-2 changes no level's 99th percentile by more
// than 1.3× and takes 30 % fewer bins.
constexpr double kTileShare = 3e-2;
// ζ for Charlie's ring, whose finest bins are all wider than its band at small α (a texel's error
// is then that of the finest bins, not of the criterion). Measured (venice_sunset_1k.hdr,
// 6 × 256², r = 0): ζ = 0.06 sums 9,364 bins per texel instead of 11,926 (whole command 8.8 s
// instead of 11.0 s) for an estimated mean error of 1.3e-3 instead of 9e-4 (bench/results/charlie.md).
constexpr double kRingTileShare = 6e-2;
// The first cut (for the lower bounds N̂, D̂): relative tolerance and weight floor η of
//   ½ H ρ_b² ≤ ε₁ g or ≤ ε₁ η ḡ at every angle.
constexpr double kFirstTolerance = 0.5;
constexpr double kFirstFloor = 1.0;
// The θ grid of the lobe tables: kFineGrid steps over the peak [0, 16α], kScaleGrid steps
// from there to π/2.
constexpr int kFineGrid = 1024;
// Added to every tile's radius: covers the fast arc cosine's error (6.8e-5 rad) and the
// rounding of the bins' float centres.
constexpr double kAngleSlack = 1e-4;
constexpr int kScaleGrid = 2048;

const std::array<CubeFaceBasis, 6>& bases() {
  static const std::array<CubeFaceBasis, 6> b = standardCubeBases();
  return b;
}

void normalize3(double v[3]) {
  const double l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  if (l > 0) v[0] /= l, v[1] /= l, v[2] /= l;
}

// Charlie's peak: μ* = 1/(1 + a), a = 1/(2α), maximises μ ((1 − μ)/2)^a.
double charlieLogPeak(double alpha) {
  const double a = 1.0 / (2.0 * alpha), m = 1.0 / (1.0 + a);
  return std::log(m) + a * std::log(0.5 * (1.0 - m));
}

// The lobe continued past the horizon (no max(0, μ)), in terms of e = 1 − μ ∈ [0, 2].
double lobeSmooth(PrefilterLobe lobe, double alpha, double e) {
  const double mu = 1.0 - e;
  switch (lobe) {
    case PrefilterLobe::Ggx: {
      const double a2 = alpha * alpha, q = 0.5 * e + (1.0 - 0.5 * e) * a2, w = a2 / q;
      return mu * w * w;
    }
    case PrefilterLobe::Charlie: {
      // Continued past the horizon like the others (μ < 0 there): cut off at μ = 0, the
      // finite differences of the curvature table saw a kink of slope ~1/step (H ~ 4e7) and
      // every bin reaching the horizon was opened to the finest level (174k bins per texel).
      if (e <= 0) return 0.0;
      return mu * std::exp(std::log(0.5 * e) / (2.0 * alpha) - charlieLogPeak(alpha));
    }
    case PrefilterLobe::Lambertian: return mu;
  }
  return 0.0;
}

}  // namespace

double prefilterLobeWeight(PrefilterLobe lobe, double alpha, double mu) {
  if (!(mu > 0)) return 0.0;
  return lobeSmooth(lobe, alpha, 1.0 - std::min(mu, 1.0));
}

namespace detail {

void cubeFaceUv(const double d[3], int* face, double* u, double* v) {
  const double ax = std::abs(d[0]), ay = std::abs(d[1]), az = std::abs(d[2]);
  int f;
  if (ax >= ay && ax >= az) f = d[0] >= 0 ? 0 : 1;
  else if (ay >= az) f = d[1] >= 0 ? 2 : 3;
  else f = d[2] >= 0 ? 4 : 5;
  const CubeFaceBasis& b = bases()[size_t(f)];
  const double n = d[0] * b.axisN[0] + d[1] * b.axisN[1] + d[2] * b.axisN[2];
  *face = f;
  *u = (d[0] * b.axisU[0] + d[1] * b.axisU[1] + d[2] * b.axisU[2]) / n;
  *v = (d[0] * b.axisV[0] + d[1] * b.axisV[1] + d[2] * b.axisV[2]) / n;
}

int binFaceSizeFor(const EnvMap& env) {
  const int res = env.layout == EnvLayout::Cube ? env.width : std::max(1, env.width / 4);
  int m = 1;
  while (m * 2 <= res && m * 2 <= kMaxBinFaceSize) m *= 2;
  return m;
}

double sourceTexelAngle(const EnvMap& env) {
  return env.layout == EnvLayout::Cube ? 2.0 / env.width : 2.0 * kPi / env.width;
}

// --- the bin tree ---

namespace {

// Centre direction (in face coordinates: dir = a·U + b·V + c·N) and angular radius of
// the cell [u0,u1]×[v0,v1] of a face.
struct Cell {
  double a, b, c, radius;
};
Cell cellOf(double u0, double u1, double v0, double v1) {
  const double uc = 0.5 * (u0 + u1), vc = 0.5 * (v0 + v1), l = std::sqrt(uc * uc + vc * vc + 1.0);
  Cell cell{uc / l, vc / l, 1.0 / l, 0.0};
  for (const double u : {u0, u1})
    for (const double v : {v0, v1}) {
      const double lc = std::sqrt(u * u + v * v + 1.0);
      const double dot = (u * cell.a + v * cell.b + cell.c) / lc;
      cell.radius = std::max(cell.radius, std::acos(std::clamp(dot, -1.0, 1.0)));
    }
  return cell;
}

void toWorld(int face, const Cell& cell, double d[3]) {
  const CubeFaceBasis& b = bases()[size_t(face)];
  for (int k = 0; k < 3; ++k) d[k] = cell.a * b.axisU[size_t(k)] + cell.b * b.axisV[size_t(k)] + cell.c * b.axisN[size_t(k)];
}

}  // namespace



namespace {

// Morton code of (row, col) < 1024: bits interleaved, col in the even bits.
uint32_t spread10(uint32_t x) {
  x &= 0x3ff;
  x = (x | (x << 8)) & 0x00ff00ffu;
  x = (x | (x << 4)) & 0x0f0f0f0fu;
  x = (x | (x << 2)) & 0x33333333u;
  x = (x | (x << 1)) & 0x55555555u;
  return x;
}
uint32_t compact10(uint32_t x) {
  x &= 0x55555555u;
  x = (x | (x >> 1)) & 0x33333333u;
  x = (x | (x >> 2)) & 0x0f0f0f0fu;
  x = (x | (x >> 4)) & 0x00ff00ffu;
  x = (x | (x >> 8)) & 0x0000ffffu;
  return x;
}

// Calls f(t, direction, solid angle) for source texel t (yaw applied).
class TexelStream {
 public:
  explicit TexelStream(const EnvMap& env) : env_(env) {
    const double yaw = env.yawDegrees * kPi / 180.0;
    cy_ = std::cos(yaw), sy_ = std::sin(yaw);
    if (env.layout == EnvLayout::LatLong) {
      const int w = env.width, h = env.height;
      for (int c = 0; c < w; ++c) {
        const double lambda = -2.0 * kPi * ((c + 0.5) / w - 0.5);
        colSin_.push_back(std::sin(lambda)), colCos_.push_back(std::cos(lambda));
      }
      for (int r = 0; r < h; ++r) {
        const double phi = kPi * (0.5 - (r + 0.5) / h);
        const double top = kPi * (0.5 - double(r) / h), bottom = kPi * (0.5 - double(r + 1) / h);
        rowSin_.push_back(std::sin(phi)), rowCos_.push_back(std::cos(phi));
        rowOmega_.push_back((2.0 * kPi / w) * (std::sin(top) - std::sin(bottom)));
      }
    } else {
      // Exact texel solid angles of one face from the corner function (envmap.h).
      const int n = env.width;
      std::vector<double> corner(size_t(n + 1) * size_t(n + 1));
      for (int r = 0; r <= n; ++r)
        for (int c = 0; c <= n; ++c) {
          const double u = 2.0 * c / n - 1.0, v = 2.0 * r / n - 1.0;
          corner[size_t(r) * size_t(n + 1) + size_t(c)] = std::atan2(u * v, std::sqrt(u * u + v * v + 1.0));
        }
      auto f = [&](int r, int c) { return corner[size_t(r) * size_t(n + 1) + size_t(c)]; };
      omega_.resize(size_t(n) * size_t(n));
      for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c)
          omega_[size_t(r) * size_t(n) + size_t(c)] = std::abs(f(r, c) - f(r + 1, c) - f(r, c + 1) + f(r + 1, c + 1));
    }
  }
  void texel(size_t t, double d[3], double* omega) const {
    double m[3];
    if (env_.layout == EnvLayout::LatLong) {
      const size_t w = size_t(env_.width), r = t / w, c = t % w;
      m[0] = colSin_[c] * rowCos_[r], m[1] = rowSin_[r], m[2] = colCos_[c] * rowCos_[r];
      *omega = rowOmega_[r];
    } else {
      const size_t n = size_t(env_.width), face = t / (n * n), r = (t / n) % n, c = t % n;
      const CubeFaceBasis& b = env_.faces[face];
      const double u = 2.0 * (double(c) + 0.5) / double(n) - 1.0, v = 2.0 * (double(r) + 0.5) / double(n) - 1.0;
      for (int k = 0; k < 3; ++k) m[k] = u * b.axisU[size_t(k)] + v * b.axisV[size_t(k)] + b.axisN[size_t(k)];
      normalize3(m);
      *omega = omega_[r * n + c];
    }
    d[0] = cy_ * m[0] + sy_ * m[2], d[1] = m[1], d[2] = -sy_ * m[0] + cy_ * m[2];
  }

 private:
  const EnvMap& env_;
  double cy_ = 1, sy_ = 0;
  std::vector<double> colSin_, colCos_, rowSin_, rowCos_, rowOmega_, omega_;
};

}  // namespace

// The finest bins' sums are taken bin by bin, each over its texels in index order, and the
// bins are visited in key order (face·M0² + Morton(row, col)): the four children of every
// node then come one after the other, so each level's sums are reduced into the next with a
// stack of one partial sum per level instead of a double array per level. A whole map finds
// each bin's texels by a counting sort on the key; a map read in bands (BinTreeBands) adds
// every texel to its bin's sums as it comes, in index order too, so both give the same bits.
namespace {

uint32_t binKey(const double d[3], int m0) {
  double u, v;
  int f;
  cubeFaceUv(d, &f, &u, &v);
  const uint32_t c = uint32_t(std::clamp(int((u + 1.0) * 0.5 * m0), 0, m0 - 1));
  const uint32_t r = uint32_t(std::clamp(int((v + 1.0) * 0.5 * m0), 0, m0 - 1));
  return uint32_t(f) * uint32_t(m0) * uint32_t(m0) + (spread10(r) << 1 | spread10(c));
}

// Adds one texel (world direction d, solid angle omega, float RGB) to a bin's sums.
void addTexel(BinSums& a, const double d[3], double omega, const float* rgb) {
  const double w = (double(rgb[0]) + rgb[1] + rgb[2]) / 3.0 * omega;
  for (int j = 0; j < 3; ++j) {
    a[size_t(j)] += double(rgb[j]) * omega;
    a[size_t(4 + j)] += w * d[j];
    a[size_t(7 + j)] += omega * d[j];
  }
  a[3] += omega;
}

// The texels in Morton order of their finest bins: bin k's texels are order[start[k] ..
// start[k + 1]), in index order (the sort is stable).
void mortonOrder(const TexelStream& stream, size_t count, int m0, std::vector<uint32_t>* start,
                 RawVector<uint32_t>* order) {
  const size_t keys = 6 * size_t(m0) * size_t(m0);
  RawVector<uint32_t> key(count);
  start->assign(keys + 1, 0);
  for (size_t i = 0; i < count; ++i) {
    double d[3], omega;
    stream.texel(i, d, &omega);
    key[i] = binKey(d, m0);
    ++(*start)[key[i] + 1];
  }
  for (size_t k = 0; k < keys; ++k) (*start)[k + 1] += (*start)[k];
  std::vector<uint32_t> fill(start->begin(), start->end() - 1);
  for (size_t i = 0; i < count; ++i) (*order)[fill[key[i]]++] = uint32_t(i);
}

// Bin `faceKey` (face and Morton code) of `level` from its sums: flux, the two mean
// directions and the geometry the traversal reads. cells: each level's cells.
void storeBin(BinTree& t, const std::vector<std::vector<Cell>>& cells, int level, uint32_t faceKey,
              const BinSums& a) {
  const int m = t.faceSize0 >> level;
  const uint32_t perFace = uint32_t(m) * uint32_t(m), face = faceKey / perFace, morton = faceKey % perFace;
  const uint32_t r = compact10(morton >> 1), c = compact10(morton);
  const size_t i = t.offset[size_t(level)] + (size_t(face) * size_t(m) + r) * size_t(m) + c;
  double dl[3] = {a[4], a[5], a[6]}, dg[3] = {a[7], a[8], a[9]};
  const double wl = (a[0] + a[1] + a[2]) / 3.0;
  const double lenL = std::sqrt(dl[0] * dl[0] + dl[1] * dl[1] + dl[2] * dl[2]);
  const double lenG = std::sqrt(dg[0] * dg[0] + dg[1] * dg[1] + dg[2] * dg[2]);
  const float spreadG = a[3] > 0 ? float(std::max(0.0, 2.0 * (1.0 - lenG / a[3]))) : 0.0f;
  const float spreadL = wl > 0 ? float(std::max(0.0, 2.0 * (1.0 - lenL / wl))) : spreadG;
  const Cell& cell = cells[size_t(level)][size_t(r) * size_t(m) + c];
  double centre[3];
  toWorld(int(face), cell, centre);
  if (!(lenL > 0)) std::copy(dg, dg + 3, dl);
  if (!(lenG > 0)) std::copy(centre, centre + 3, dg), std::copy(centre, centre + 3, dl);
  normalize3(dl);
  normalize3(dg);
  for (int k = 0; k < 4; ++k) t.flux[4 * i + size_t(k)] = float(a[size_t(k)]);
  for (int k = 0; k < 3; ++k) t.dirL[4 * i + size_t(k)] = float(dl[k]), t.dirG[4 * i + size_t(k)] = float(dg[k]);
  t.dirL[4 * i + 3] = t.dirG[4 * i + 3] = 0.0f;
  t.geom[i] = {float(centre[0]), float(centre[1]), float(centre[2]), float(cell.radius),
               float(wl), float(a[3]), spreadL, spreadG};
}

// The tree from its finest bins' sums: finest(k, a) sets a to the sums of the bin of key k
// (called once per key, in key order); each node's sums are its children's, added in key order.
BinTree treeFromFinestSums(int m0, const std::function<void(uint32_t key, BinSums& a)>& finest) {
  PRTBAKE_CHECK(m0 >= 1 && m0 <= 1024 && (m0 & (m0 - 1)) == 0, "bin face size must be a power of two up to 1024");
  BinTree t;
  t.faceSize0 = m0;
  for (int m = m0; m >= 1; m /= 2) ++t.levels;
  t.offset.assign(size_t(t.levels) + 1, 0);
  for (int l = 0; l < t.levels; ++l) {
    const size_t m = size_t(m0 >> l);
    t.offset[size_t(l) + 1] = t.offset[size_t(l)] + 6 * m * m;
  }
  t.flux.resize(4 * t.nodes());
  t.dirL.resize(4 * t.nodes());
  t.dirG.resize(4 * t.nodes());
  t.geom.resize(t.nodes());

  // Per-level cells (centre and radius in face coordinates), the same on every face.
  std::vector<std::vector<Cell>> cells(static_cast<size_t>(t.levels));
  for (int l = 0; l < t.levels; ++l) {
    const int m = m0 >> l;
    cells[size_t(l)].resize(size_t(m) * size_t(m));
    for (int r = 0; r < m; ++r)
      for (int c = 0; c < m; ++c)
        cells[size_t(l)][size_t(r) * size_t(m) + size_t(c)] =
            cellOf(2.0 * c / m - 1.0, 2.0 * (c + 1) / m - 1.0, 2.0 * r / m - 1.0, 2.0 * (r + 1) / m - 1.0);
  }
  const uint32_t keys = 6 * uint32_t(m0) * uint32_t(m0);
  std::vector<BinSums> partial(static_cast<size_t>(t.levels), BinSums{});
  std::vector<int> children(static_cast<size_t>(t.levels), 0);
  for (uint32_t k = 0; k < keys; ++k) {
    BinSums a{};
    finest(k, a);
    // Store the bin, then every ancestor whose four children are now done.
    uint32_t code = k;
    for (int l = 0; l < t.levels; ++l) {
      storeBin(t, cells, l, code, a);
      if (l + 1 == t.levels) break;
      BinSums& p = partial[size_t(l) + 1];
      for (size_t j = 0; j < a.size(); ++j) p[j] += a[j];
      if (++children[size_t(l) + 1] < 4) break;
      a = p;
      p = BinSums{};
      children[size_t(l) + 1] = 0;
      code >>= 2;
    }
  }
  return t;
}

}  // namespace

BinTree buildBinTree(const EnvMap& env, int m0) {
  PRTBAKE_CHECK(m0 >= 1 && m0 <= 1024 && (m0 & (m0 - 1)) == 0, "bin face size must be a power of two up to 1024");
  const TexelStream stream(env);
  RawVector<uint32_t> order(env.texelCount());
  std::vector<uint32_t> start;
  mortonOrder(stream, env.texelCount(), m0, &start, &order);
  return treeFromFinestSums(m0, [&](uint32_t k, BinSums& a) {
    for (uint32_t o = start[k]; o < start[k + 1]; ++o) {
      double d[3], omega;
      stream.texel(order[o], d, &omega);
      addTexel(a, d, omega, &env.rgb[3 * size_t(order[o])]);
    }
  });
}

// The map's description (no texels) and its texels' directions and solid angles.
struct BinTreeBands::Stream {
  explicit Stream(const EnvMap& description) : map(withoutTexels(description)), texels(map) {}
  static EnvMap withoutTexels(const EnvMap& description) {
    EnvMap m;
    m.layout = description.layout;
    m.width = description.width, m.height = description.height;
    m.faces = description.faces;
    m.yawDegrees = description.yawDegrees;
    return m;
  }
  const EnvMap map;
  const TexelStream texels;  // reads map
};

BinTreeBands::BinTreeBands(const EnvMap& description, int faceSize0)
    : stream_(std::make_unique<Stream>(description)), faceSize0_(faceSize0) {
  PRTBAKE_CHECK(faceSize0 >= 1 && faceSize0 <= 1024 && (faceSize0 & (faceSize0 - 1)) == 0,
                "bin face size must be a power of two up to 1024");
  for (auto& face : sums_) face.assign(size_t(faceSize0) * size_t(faceSize0), BinSums{});
}

BinTreeBands::~BinTreeBands() = default;

void BinTreeBands::add(const float* rgb, size_t firstTexel, size_t count) {
  for (size_t i = 0; i < count; ++i) {
    double d[3], omega;
    stream_->texels.texel(firstTexel + i, d, &omega);
    const uint32_t key = binKey(d, faceSize0_), perFace = uint32_t(faceSize0_) * uint32_t(faceSize0_);
    addTexel(sums_[key / perFace][key % perFace], d, omega, rgb + 3 * i);
  }
}

BinTree BinTreeBands::finish() {
  // Keys are face-major: each face's sums are freed once read, as the tree's pages fill.
  const uint32_t perFace = uint32_t(faceSize0_) * uint32_t(faceSize0_);
  return treeFromFinestSums(faceSize0_, [&](uint32_t k, BinSums& a) {
    std::vector<BinSums>& face = sums_[k / perFace];
    a = face[k % perFace];
    if (k % perFace == perFace - 1) std::vector<BinSums>().swap(face);
  });
}

// --- the lobe's tables ---

LobeScale::LobeScale(PrefilterLobe lobe, double alpha, double tolerance)
    : tolerance_(tolerance), ring_(lobe == PrefilterLobe::Charlie) {
  // The θ grid: step α/64 up to 16α (the peak), then (π/2 − 16α)/kScaleGrid to π/2.
  const double split = std::min(kHalfPi, 16.0 * alpha);
  fineStep_ = split / kFineGrid;
  const int fine = split > 0 ? kFineGrid : 0;
  coarseStep_ = (kHalfPi - split) / kScaleGrid;
  const int coarse = coarseStep_ > 0 ? kScaleGrid : 0;
  split_ = split;
  fine_ = fine;
  const int J = fine + coarse;
  grid_ = J;
  auto theta = [&](int j) { return j <= fine ? j * fineStep_ : split + (j - fine) * coarseStep_; };
  auto g = [&](double th) { return lobeSmooth(lobe, alpha, 1.0 - std::cos(th)); };
  // ḡ = ∫ g dω/(4π) = ½ ∫_0^{π/2} g(θ) sin θ dθ (trapezoid on the θ grid).
  double integral = 0;
  for (int j = 0; j < J; ++j) {
    const double a = theta(j), b = theta(j + 1);
    integral += 0.5 * (b - a) * (g(a) * std::sin(a) + g(b) * std::sin(b));
  }
  gMean_ = 0.5 * integral;
  std::vector<float> gv(size_t(J) + 1), hv(size_t(J) + 1);
  for (int j = 0; j <= J; ++j) {
    const double th = theta(j);
    const double h = std::max(1e-7, std::min(1e-5, 0.25 * (theta(std::min(j + 1, J)) - th) + 1e-9));
    double g1, g2;
    if (j == 0) {
      g1 = 0;
      g2 = 2.0 * (g(h) - g(0)) / (h * h);
    } else {
      g1 = (g(th + h) - g(th - h)) / (2 * h);
      g2 = (g(th + h) - 2 * g(th) + g(th - h)) / (h * h);
    }
    gv[size_t(j)] = float(std::max(0.0, g(th)));
    hv[size_t(j)] = float(std::max(std::abs(g2), j == 0 ? 0.0 : std::abs(g1) * std::cos(th) / std::sin(th)));
  }
  const double hk = 1e-6;
  horizonSlope_ = std::abs((g(kHalfPi + hk) - g(kHalfPi - hk)) / (2 * hk));
  // Sparse tables: [k][j] = min g (max H) over [j, j + 2^k).
  std::vector<float> rv(gv.size());
  for (size_t j = 0; j < gv.size(); ++j) rv[j] = gv[j] > 0 ? float(double(hv[j]) / gv[j]) : 3e38f;
  // Sparse table: table_[k][j] = (min g, max H, max H/g) over [j, j + 2^k), one cache line apart.
  std::vector<std::array<float, 4>> level0(gv.size());
  for (size_t j = 0; j < gv.size(); ++j) level0[j] = {gv[j], hv[j], rv[j], 0.0f};
  table_.push_back(std::move(level0));
  for (int k = 1; (1 << k) <= J + 1; ++k) {
    const std::vector<std::array<float, 4>>& prev = table_.back();
    const size_t half = size_t(1) << (k - 1), len = prev.size() - half;
    std::vector<std::array<float, 4>> cur(len);
    for (size_t j = 0; j < len; ++j)
      cur[j] = {std::min(prev[j][0], prev[j + half][0]), std::max(prev[j][1], prev[j + half][1]),
                std::max(prev[j][2], prev[j + half][2]), 0.0f};
    table_.push_back(std::move(cur));
  }
  invFine_ = fineStep_ > 0 ? 1.0 / fineStep_ : 0.0;
  invCoarse_ = coarseStep_ > 0 ? 1.0 / coarseStep_ : 0.0;
}

int LobeScale::index(double th, bool up) const {
  const double x = gridPosition(th);
  const int i = int(std::max(0.0, x));  // floor for x ≥ 0
  return std::min(grid_, up ? i + 1 : i);
}

void LobeScale::range(double lo, double hi, double* gMin, double* hMax, double* rMax) const {
  const int a = index(lo, false), b = index(std::min(hi, kHalfPi), true);
  const int k = 31 - __builtin_clz(unsigned(b - a + 1));
  const size_t i0 = size_t(a), i1 = size_t(b - (1 << k) + 1), kk = size_t(k);
  const std::array<float, 4>&a0 = table_[kk][i0], &a1 = table_[kk][i1];
  *gMin = hi > kHalfPi ? 0.0 : double(std::min(a0[0], a1[0]));
  *hMax = double(std::max(a0[1], a1[1]));
  *rMax = hi > kHalfPi ? 3e38 : double(std::max(a0[2], a1[2]));
}

double LobeScale::gridPosition(double th) const {
  if (th < split_) return th * invFine_;
  return fine_ + (std::min(th, kHalfPi) - split_) * invCoarse_;
}

// --- tile cuts ---

namespace {

// A tile's texel-centre extent: centre direction and angular radius.
struct TileGeom {
  double d[3];
  double radius;
  bool exists;
};

std::vector<TileGeom> tileGeometry(const TileTree& tt, int face) {
  std::vector<TileGeom> g(tt.offset.back());
  const int n = tt.n;
  auto centre = [n](int i) { return 2.0 * (i + 0.5) / n - 1.0; };
  for (int k = 0; k < tt.levels; ++k) {
    const int s = tt.side(k), size = tt.leaf << k;
    for (int ty = 0; ty < s; ++ty)
      for (int tx = 0; tx < s; ++tx) {
        TileGeom& t = g[tt.id(k, face, ty, tx)];
        const int r0 = ty * size, c0 = tx * size;
        t.exists = r0 < n && c0 < n;
        if (!t.exists) continue;
        const int r1 = std::min(n, r0 + size) - 1, c1 = std::min(n, c0 + size) - 1;
        const Cell c = cellOf(centre(c0), centre(c1), centre(r0), centre(r1));
        toWorld(face, c, t.d);
        t.radius = c.radius + kAngleSlack;
      }
  }
  return g;
}

struct BinRef {
  int level, face, row, col;
  size_t node(const BinTree& t) const {
    const int m = t.faceSize0 >> level;
    return t.offset[size_t(level)] + (size_t(face) * size_t(m) + size_t(row)) * size_t(m) + size_t(col);
  }
};

struct Pair {
  int k, ty, tx;
  BinRef b;
};

// A list entry: bin (level, face, row, col) taken as its 4^depth descendants `depth` levels
// down (depth 0: the bin itself), packed as level:4 | depth:4 | face:3 | row:10 | col:10.
uint32_t blockEntry(const BinRef& b, int depth) {
  return uint32_t(b.level) << 27 | uint32_t(depth) << 23 | uint32_t(b.face) << 20 | uint32_t(b.row) << 10 |
         uint32_t(b.col);
}

// What the lobe tables say about the angles [lo, hi] a bin spans from a tile.
struct Range {
  double lo, hi, gMin, h, rMax;
};

// The cut criterion of the header comment for one (tile, bin) pair.
class Criterion {
 public:
  explicit Criterion(const LobeScale& s) : s_(s), slope_(s.horizonSlope()), floor1_(kFirstFloor * s.meanWeight()) {}
  bool ring() const { return s_.ring(); }

  // Over the angles [lo, hi]: smallest g, largest H and largest H/g (one table query).
  Range range(double lo, double hi) const {
    Range r{lo, hi, 0, 0, 0};
    s_.range(lo, hi, &r.gMin, &r.h, &r.rMax);
    return r;
  }
  // H with the kink across the horizon counted as a curvature |g'(π/2)|/ρ.
  double curvature(const Range& r, double radius) const {
    return r.hi > kHalfPi ? std::max(r.h, slope_ / std::max(radius, 1e-12)) : r.h;
  }
  // First cut: ½ H ρ² ≤ ε₁ g or ≤ ε₁ η ḡ at every angle.
  bool coarseFits(const Range& r, double radius) const {
    const double r2 = 0.5 * radius * radius;
    return r2 * r.rMax <= kFirstTolerance || r2 * curvature(r, radius) <= kFirstTolerance * floor1_;
  }
  // (N) and (D) with the tile's allowances εζN̂, εζD̂, for the bin's descendants `depth` levels
  // down taken as 4^depth equal parts: radius / 2^d, spreads, flux and solid angle / 4^d.
  bool fits(const Range& r, const std::array<float, 8>& g, double nAllow, double dAllow, int depth = 0) const {
    const double shrink = std::ldexp(1.0, -2 * depth), eps = s_.tolerance();
    const double h = curvature(r, std::ldexp(double(g[3]), -depth));
    const double sl = 0.5 * g[6] * shrink, sg = 0.5 * g[7] * shrink;
    const double f = g[4] * shrink, om = g[5] * shrink;
    return (sl * r.rMax <= eps || sl * h * f <= eps * nAllow) && (sg * r.rMax <= eps || sg * h * om <= eps * dAllow);
  }

 private:
  const LobeScale& s_;
  double slope_, floor1_;
};

// The angle between unit vectors, from Abramowitz & Stegun 4.4.45 (|error| ≤ 6.8e-5 rad; the
// tiles' radii carry kAngleSlack for it and for the float centres).
double angleBetween(const double a[3], const std::array<float, 8>& g) {
  const double x = std::clamp(a[0] * g[0] + a[1] * g[1] + a[2] * g[2], -1.0, 1.0), ax = std::abs(x);
  const double r = std::sqrt(1.0 - ax) * (1.5707288 + ax * (-0.2121144 + ax * (0.0742610 - 0.0187293 * ax)));
  return x >= 0 ? r : kPi - r;
}

// Lower bounds N̂, D̂ of every texel's numerator and denominator in a tile: Σ g_min F̃ and
// Σ g_min Ω over the coarse first cut.
void lowerBounds(const BinTree& tree, const Criterion& crit, const TileGeom& t, std::vector<BinRef>& stack,
                 double* nLow, double* dLow) {
  *nLow = *dLow = 0;
  stack.clear();
  for (int f = 0; f < 6; ++f) stack.push_back({tree.levels - 1, f, 0, 0});
  while (!stack.empty()) {
    const BinRef b = stack.back();
    stack.pop_back();
    const auto& g = tree.geom[b.node(tree)];
    if (g[5] <= 0.0f) continue;
    const double delta = angleBetween(t.d, g);
    const double lo = std::max(0.0, delta - t.radius - g[3]), hi = delta + t.radius + g[3];
    if (lo >= kHalfPi) continue;
    const Range r = crit.range(lo, hi);
    if (b.level == 0 || crit.coarseFits(r, g[3])) {
      *nLow += r.gMin * g[4];
      *dLow += r.gMin * g[5];
      continue;
    }
    for (int k = 0; k < 4; ++k) stack.push_back({b.level - 1, b.face, 2 * b.row + (k >> 1), 2 * b.col + (k & 1)});
  }
}

// A ring (Charlie) thinner than the tile: the tile's own bounds are ~0, every bin leaving some
// texel's ring, and every bin would then have to meet the relative test (all of them down to
// the finest level). Its bounds are instead the smallest of the true bounds at the texels of a
// lattice (every S-th row and column of the face, and the last; S = kRingLattice tiles of the
// level the bounds start at) around the tile. An estimate, not a bound: a texel between lattice
// points may see less light; the level's error estimate measures the outcome (docs/prefilter.md).
// Measured (venice_sunset_1k.hdr, 6 × 256², r = 0): a lattice every 16 texels instead of 8 takes
// the bounds' walks from 1.4 to 0.45 s for 1 % more bins and the same estimated error; half the
// lattice's bound (as before the 16² leaves) summed 16,710 bins per texel instead of 11,836 for
// an estimated mean error of 6.5e-4 instead of 9.1e-4.
constexpr int kRingLattice = 2;

// The tile level the traversal starts from: the coarsest with at least 16 tiles per face
// (4 × 4), or the leaves.
int kPieceLevel(const TileTree& tt) {
  int k = 0;
  while (k + 1 < tt.levels && tt.side(k + 1) >= 4) ++k;
  return k;
}

}  // namespace

void forEachBinEntry(const BinTree& tree, uint32_t entry, const std::function<void(size_t)>& f) {
  const int level = int(entry >> 27), depth = int((entry >> 23) & 15u), face = int((entry >> 20) & 7u);
  const int row = int((entry >> 10) & 1023u), col = int(entry & 1023u);
  const int lc = level - depth, m = tree.faceSize0 >> lc, span = 1 << depth;
  for (int r = row * span; r < (row + 1) * span; ++r)
    for (int c = col * span; c < (col + 1) * span; ++c)
      f(tree.offset[size_t(lc)] + (size_t(face) * size_t(m) + size_t(r)) * size_t(m) + size_t(c));
}

TileTree makeTileTree(int n) {
  TileTree t;
  t.n = n;
  t.padded = 1;
  while (t.padded < n) t.padded *= 2;
  t.leaf = std::min(n >= kLargeLeafFrom ? 2 * kLeafSize : kLeafSize, t.padded);
  t.levels = 1;
  while ((t.leaf << (t.levels - 1)) < t.padded) ++t.levels;
  t.offset.assign(size_t(t.levels) + 1, 0);
  for (int k = 0; k < t.levels; ++k) t.offset[size_t(k) + 1] = t.offset[size_t(k)] + uint32_t(6 * t.side(k) * t.side(k));
  return t;
}

namespace {

// One piece's pairs of the dual traversal: (tile id, packed bin entry), and the pairs that
// fit no test.
struct CutPairs {
  std::vector<std::pair<uint32_t, uint32_t>> pairs;
  size_t unresolved = 0;
};

// Each wanted tile's lower bounds of the lobe's numerator and denominator: its own first cut
// for tiles of 8 texels or more (kBound up), inherited by the smaller tiles below.
void tileLowerBounds(const BinTree& tree, const Criterion& crit, const TileTree& tt, int face,
                     const std::vector<TileGeom>& geom, const std::vector<uint8_t>& wanted, std::vector<double>* nLow,
                     std::vector<double>* dLow) {
  const int top = tt.levels - 1;
  int kBound = 0;
  while ((tt.leaf << kBound) < 8 && kBound + 1 < tt.levels) ++kBound;
  nLow->assign(tt.offset.back(), 0.0);
  dLow->assign(tt.offset.back(), 0.0);
  std::vector<uint32_t> ids;
  for (int k = kBound; k <= std::max(kBound, std::min(top, kPieceLevel(tt))); ++k)
    for (int ty = 0; ty < tt.side(k); ++ty)
      for (int tx = 0; tx < tt.side(k); ++tx) {
        const uint32_t id = tt.id(k, face, ty, tx);
        if (geom[id].exists && wanted[id]) ids.push_back(id);
      }
  if (!crit.ring()) {
    detail::parallelEach(ids.size(), kCutThreads, [&](size_t i) {
      thread_local std::vector<BinRef> stack;  // the walk's, kept from tile to tile
      lowerBounds(tree, crit, geom[ids[i]], stack, &(*nLow)[ids[i]], &(*dLow)[ids[i]]);
    });
  } else {
    // The lattice: rows and columns min(i·S, n − 1), S the tiles' size at kBound; each point that
    // a wanted tile touches is walked once.
    const int S = kRingLattice * (tt.leaf << kBound), count = (tt.n - 1 + S - 1) / S + 1;
    auto at = [&](int i) { return std::min(i * S, tt.n - 1); };
    auto span = [&](uint32_t id, int* i0, int* i1, int* j0, int* j1) {
      int k = kBound;
      while (id >= tt.offset[size_t(k) + 1]) ++k;
      const int s = tt.side(k), size = tt.leaf << k, local = int(id - tt.offset[size_t(k)]) % (s * s);
      const int y0 = (local / s) * size, x0 = (local % s) * size;
      *i0 = y0 / S, *j0 = x0 / S;
      *i1 = std::min(count - 1, (y0 + size + S - 1) / S), *j1 = std::min(count - 1, (x0 + size + S - 1) / S);
    };
    std::vector<uint8_t> needed(size_t(count) * size_t(count), 0);
    for (const uint32_t id : ids) {
      int i0, i1, j0, j1;
      span(id, &i0, &i1, &j0, &j1);
      for (int i = i0; i <= i1; ++i)
        for (int j = j0; j <= j1; ++j) needed[size_t(i * count + j)] = 1;
    }
    std::vector<size_t> points;
    for (size_t i = 0; i < needed.size(); ++i)
      if (needed[i]) points.push_back(i);
    std::vector<double> pn(needed.size()), pd(needed.size());
    detail::parallelEach(points.size(), kCutThreads, [&](size_t q) {
      thread_local std::vector<BinRef> stack;
      const size_t i = points[q];
      TileGeom t{};
      cubeTexelCenter(tt.n, face, at(int(i) / count), at(int(i) % count), t.d);
      t.radius = kAngleSlack;
      t.exists = true;
      lowerBounds(tree, crit, t, stack, &pn[i], &pd[i]);
    });
    for (const uint32_t id : ids) {
      int i0, i1, j0, j1;
      span(id, &i0, &i1, &j0, &j1);
      double nMin = 1e300, dMin = 1e300;
      for (int i = i0; i <= i1; ++i)
        for (int j = j0; j <= j1; ++j)
          nMin = std::min(nMin, pn[size_t(i * count + j)]), dMin = std::min(dMin, pd[size_t(i * count + j)]);
      (*nLow)[id] = nMin;
      (*dLow)[id] = dMin;
    }
  }
  for (int k = kBound - 1; k >= 0; --k)
    for (int ty = 0; ty < tt.side(k); ++ty)
      for (int tx = 0; tx < tt.side(k); ++tx) {
        const uint32_t id = tt.id(k, face, ty, tx), up = tt.id(kBound, face, ty >> (kBound - k), tx >> (kBound - k));
        (*nLow)[id] = (*nLow)[up], (*dLow)[id] = (*dLow)[up];
      }
}

// The dual traversal of one face's tiles and the bin tree: each (tile, bin) pair is taken
// whole when the lobe is flat enough over it (within kTileShare of the tile's lower bounds),
// else the larger of the two is opened.
class DualTraversal {
 public:
  DualTraversal(const BinTree& tree, const Criterion& crit, const TileTree& tt, int face,
                const std::vector<TileGeom>& geom, const std::vector<uint8_t>& wanted, const std::vector<double>& nLow,
                const std::vector<double>& dLow)
      : tree_(tree), crit_(crit), tt_(tt), face_(face), geom_(geom), wanted_(wanted), nLow_(nLow), dLow_(dLow),
        share_(crit.ring() ? kRingTileShare : kTileShare) {}

  // The pairs reached from the starting pairs of one piece.
  void run(std::vector<Pair> stack, CutPairs& out) const {
    std::vector<BinRef> todo;
    while (!stack.empty()) {
      const Pair p = stack.back();
      stack.pop_back();
      const uint32_t tid = tt_.id(p.k, face_, p.ty, p.tx);
      const TileGeom& t = geom_[tid];
      const auto& g = tree_.geom[p.b.node(tree_)];
      const Judgement j = judge(g, t, tid);
      if (j.verdict == Verdict::Empty || j.verdict == Verdict::Beyond) continue;
      const bool splitB = p.b.level > 0, splitT = p.k > 0;
      const bool fits = j.verdict == Verdict::Fits;
      if (fits || (!splitB && !splitT)) {
        if (!fits) ++out.unresolved;
        out.pairs.push_back({tid, blockEntry(p.b, 0)});
        continue;
      }
      if (!splitT && p.b.level <= kNearBlockLevel) {
        // A leaf opening a small bin: its whole subtree for this leaf in one walk.
        if (resolve(p.b, t, tid, out) == Subtree::AllFinest) {
          out.pairs.push_back({tid, blockEntry(p.b, p.b.level)});
          out.unresolved += size_t(1) << (2 * p.b.level);
        }
        continue;
      }
      if (splitB && (!splitT || g[3] >= t.radius) && p.b.level <= kNearBlockLevel && allFinest(p.b, t, tid, todo)) {
        // Every descendant would be opened down to the finest level: the same bins as one block.
        out.pairs.push_back({tid, blockEntry(p.b, p.b.level)});
        out.unresolved += size_t(1) << (2 * p.b.level);
        continue;
      }
      if (splitB && !crit_.ring() && j.rg.lo >= kBlockDistance * (g[3] + t.radius)) {
        // Far from the tile for its size: take its descendants at the first depth that fits
        // over the whole range (the finest when none does) as one block. Not for a ring: far
        // from the tile is where the ring lies, and a block at the depth its thin band needs
        // would sum that depth over the whole bin (211k bins per texel at r = 0, 64², against
        // 28k when they are opened).
        const double nAllow = share_ * nLow_[tid], dAllow = share_ * dLow_[tid];
        int depth = 1;
        while (depth < p.b.level && !crit_.fits(j.rg, g, nAllow, dAllow, depth)) ++depth;
        if (depth == p.b.level && !crit_.fits(j.rg, g, nAllow, dAllow, depth)) ++out.unresolved;
        out.pairs.push_back({tid, blockEntry(p.b, depth)});
        continue;
      }
      if (splitB && (!splitT || g[3] >= t.radius)) {
        for (int k = 0; k < 4; ++k)
          stack.push_back({p.k, p.ty, p.tx, {p.b.level - 1, p.b.face, 2 * p.b.row + (k >> 1), 2 * p.b.col + (k & 1)}});
      } else {
        for (int k = 0; k < 4; ++k) {
          const int ty = 2 * p.ty + (k >> 1), tx = 2 * p.tx + (k & 1);
          const uint32_t cid = tt_.id(p.k - 1, face_, ty, tx);
          if (geom_[cid].exists && wanted_[cid]) stack.push_back({p.k - 1, ty, tx, p.b});
        }
      }
    }
  }

 private:
  // A (tile, bin) pair: the bin empty (no texel centre falls in it), beyond every texel's
  // horizon (weight 0), flat enough over the tile to be taken whole (within ζ of the tile's
  // lower bounds), or to be opened; rg: the range of angles between them.
  enum class Verdict { Empty, Beyond, Fits, Opens };
  struct Judgement {
    Verdict verdict;
    Range rg;
  };
  Judgement judge(const std::array<float, 8>& g, const TileGeom& t, uint32_t tid) const {
    if (g[5] <= 0.0f) return {Verdict::Empty, {}};
    const double delta = angleBetween(t.d, g);
    const double lo = std::max(0.0, delta - t.radius - g[3]), hi = delta + t.radius + g[3];
    if (lo >= kHalfPi) return {Verdict::Beyond, {}};
    const Range rg = crit_.range(lo, hi);
    return {crit_.fits(rg, g, share_ * nLow_[tid], share_ * dLow_[tid]) ? Verdict::Fits : Verdict::Opens, rg};
  }

  // What the traversal makes of a bin's subtree at a leaf: nothing (an empty bin: no texel
  // centre in it), nothing (beyond the horizon), its pairs (listed), or every descendant opened
  // down to the finest bins (listed by the caller, whole or merged into its parent's block).
  enum class Subtree { Empty, Beyond, Listed, AllFinest };
  // The pairs of leaf t with the subtree of a bin that fails the criterion, found as the
  // traversal finds them but in one walk (allFinest walks a subtree once per level): the same
  // bins in another order, less the finest ones that add nothing (empty or beyond the horizon)
  // that a block would have held.
  Subtree resolve(const BinRef& b, const TileGeom& t, uint32_t tid, CutPairs& out) const {
    if (b.level == 0) return Subtree::AllFinest;
    Subtree child[4];
    bool all = true;
    for (int k = 0; k < 4; ++k) {
      const BinRef c{b.level - 1, b.face, 2 * b.row + (k >> 1), 2 * b.col + (k & 1)};
      child[k] = classify(c, t, tid, out);
      all = all && (child[k] == Subtree::AllFinest || child[k] == Subtree::Empty);
    }
    if (all) return Subtree::AllFinest;
    for (int k = 0; k < 4; ++k)
      if (child[k] == Subtree::AllFinest) {
        const BinRef c{b.level - 1, b.face, 2 * b.row + (k >> 1), 2 * b.col + (k & 1)};
        out.pairs.push_back({tid, blockEntry(c, c.level)});
        out.unresolved += size_t(1) << (2 * c.level);
      }
    return Subtree::Listed;
  }
  // One bin of such a subtree: skipped, taken whole (listed), or resolved further.
  Subtree classify(const BinRef& b, const TileGeom& t, uint32_t tid, CutPairs& out) const {
    switch (judge(tree_.geom[b.node(tree_)], t, tid).verdict) {
      case Verdict::Empty: return Subtree::Empty;
      case Verdict::Beyond: return Subtree::Beyond;
      case Verdict::Fits: out.pairs.push_back({tid, blockEntry(b, 0)}); return Subtree::Listed;
      case Verdict::Opens: break;
    }
    return resolve(b, t, tid, out);
  }

  // Whether opening bin `root` for tile t would end in finest bins only: it fails and so does
  // every descendant above the finest level (each tested with its own range).
  bool allFinest(const BinRef& root, const TileGeom& t, uint32_t tid, std::vector<BinRef>& todo) const {
    todo.clear();
    todo.push_back(root);
    while (!todo.empty()) {
      const BinRef b = todo.back();
      todo.pop_back();
      if (b.level == 0) continue;
      const Verdict v = judge(tree_.geom[b.node(tree_)], t, tid).verdict;
      if (v == Verdict::Empty) continue;
      if (v != Verdict::Opens) return false;
      for (int k = 0; k < 4; ++k) todo.push_back({b.level - 1, b.face, 2 * b.row + (k >> 1), 2 * b.col + (k & 1)});
    }
    return true;
  }

  const BinTree& tree_;
  const Criterion& crit_;
  const TileTree& tt_;
  int face_;
  const std::vector<TileGeom>& geom_;
  const std::vector<uint8_t>& wanted_;
  const std::vector<double>&nLow_, &dLow_;
  double share_;  // ζ
};

// The pieces' pairs as lists per tile (a counting sort by tile id), pieces in order.
TileCuts sortByTile(const std::vector<CutPairs>& outs, const TileTree& tt) {
  TileCuts cuts;
  cuts.start.assign(tt.offset.back() + 1, 0);
  size_t total = 0;
  for (const CutPairs& o : outs) {
    total += o.pairs.size();
    cuts.unresolved += o.unresolved;
    for (const auto& pr : o.pairs) ++cuts.start[pr.first + 1];
  }
  PRTBAKE_CHECK(total < (size_t(1) << 32), "tile cut lists too long for 32-bit offsets");
  for (size_t i = 1; i < cuts.start.size(); ++i) cuts.start[i] += cuts.start[i - 1];
  cuts.bins.resize(total);
  std::vector<uint32_t> fill(cuts.start.begin(), cuts.start.end() - 1);
  for (const CutPairs& o : outs)
    for (const auto& pr : o.pairs) cuts.bins[fill[pr.first]++] = pr.second;
  return cuts;
}

}  // namespace

TileCuts buildTileCuts(const BinTree& tree, const LobeScale& scale, const TileTree& tt, int face,
                       const std::vector<int>& leaves) {
  PRTBAKE_CHECK(tree.faceSize0 <= 1024 && tree.levels < 16, "bin tree too large for packed list entries");
  PRTBAKE_CHECK(tree.geom.size() == tree.nodes(), "bin tree without traversal geometry");
  const std::vector<TileGeom> geom = tileGeometry(tt, face);
  // Wanted tiles: those above a requested leaf.
  std::vector<uint8_t> wanted(tt.offset.back(), leaves.empty() ? 1 : 0);
  for (int leaf : leaves)
    for (int k = 0; k < tt.levels; ++k) wanted[tt.id(k, face, (leaf / tt.side(0)) >> k, (leaf % tt.side(0)) >> k)] = 1;
  const Criterion crit(scale);
  std::vector<double> nLow, dLow;
  tileLowerBounds(tree, crit, tt, face, geom, wanted, &nLow, &dLow);
  // The traversal starts from the tiles of level kTop (at least 16 per face when the level
  // has them), each piece on its own thread; pieces are joined in order.
  const int kTop = std::min(tt.levels - 1, kPieceLevel(tt));
  std::vector<std::vector<Pair>> pieces;
  for (int ty = 0; ty < tt.side(kTop); ++ty)
    for (int tx = 0; tx < tt.side(kTop); ++tx) {
      const uint32_t id = tt.id(kTop, face, ty, tx);
      if (!geom[id].exists || !wanted[id]) continue;
      std::vector<Pair> piece;
      for (int f = 0; f < 6; ++f) piece.push_back({kTop, ty, tx, {tree.levels - 1, f, 0, 0}});
      pieces.push_back(std::move(piece));
    }
  const DualTraversal traversal(tree, crit, tt, face, geom, wanted, nLow, dLow);
  std::vector<CutPairs> outs(pieces.size());
  detail::parallelEach(pieces.size(), kCutThreads, [&](size_t i) { traversal.run(pieces[i], outs[i]); });
  return sortByTile(outs, tt);
}

std::vector<double> evaluateCutsReference(const BinTree& tree, const TileCuts& cuts, const TileTree& tt,
                                          PrefilterLobe lobe, double alpha, int face, const std::vector<int>& leaves) {
  std::vector<double> out;
  const int n = tt.n, s0 = tt.side(0);
  for (int leaf : leaves) {
    const int ty = leaf / s0, tx = leaf % s0;
    for (int r = ty * tt.leaf; r < std::min(n, (ty + 1) * tt.leaf); ++r)
      for (int c = tx * tt.leaf; c < std::min(n, (tx + 1) * tt.leaf); ++c) {
        double d[3];
        cubeTexelCenter(n, face, r, c, d);
        double acc[4] = {0, 0, 0, 0};
        for (int k = tt.levels - 1; k >= 0; --k) {
          const uint32_t id = tt.id(k, face, ty >> k, tx >> k);
          std::vector<size_t> nodes;
          for (uint32_t i = cuts.start[id]; i < cuts.start[id + 1]; ++i) forEachBinEntry(tree, cuts.bins[i], [&](size_t b) { nodes.push_back(b); });
          for (const size_t b : nodes) {
            auto weight = [&](const RawVector<float>& dir) {
              double e = 0;
              for (int j = 0; j < 3; ++j) {
                const double x = d[j] - double(dir[4 * b + size_t(j)]);
                e += x * x;
              }
              e *= 0.5;
              return 1.0 - e > 0 ? lobeSmooth(lobe, alpha, e) : 0.0;
            };
            const double wl = weight(tree.dirL), wg = weight(tree.dirG);
            for (int j = 0; j < 3; ++j) acc[j] += wl * double(tree.flux[4 * b + size_t(j)]);
            acc[3] += wg * double(tree.flux[4 * b + 3]);
          }
        }
        for (int j = 0; j < 3; ++j) out.push_back(acc[3] > 0 ? acc[j] / acc[3] : 0.0);
      }
  }
  return out;
}

}  // namespace detail

size_t cubeTexelIndex(int n, const double d[3]) {
  int f;
  double u, v;
  detail::cubeFaceUv(d, &f, &u, &v);
  const int c = std::clamp(int((u + 1.0) * 0.5 * n), 0, n - 1), r = std::clamp(int((v + 1.0) * 0.5 * n), 0, n - 1);
  return (size_t(f) * size_t(n) + size_t(r)) * size_t(n) + size_t(c);
}

void cubeTexelCenter(int n, int face, int row, int col, double d[3]) {
  const CubeFaceBasis& b = bases()[size_t(face)];
  const double u = 2.0 * (col + 0.5) / n - 1.0, v = 2.0 * (row + 0.5) / n - 1.0;
  for (int k = 0; k < 3; ++k) d[k] = u * b.axisU[size_t(k)] + v * b.axisV[size_t(k)] + b.axisN[size_t(k)];
  normalize3(d);
}

}  // namespace prtbake
