// Prefiltering pieces that read the source texel by texel: the r = 0 resampling, the
// double-precision brute force (the definition itself) and the anchors' sampled estimator.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>

#include "core/constants.h"
#include "core/kernel_options.h"
#include "core/parallel.h"
#include "core/radical_inverse.h"
#include "prefilter/prefilter_detail.h"
#include "prtbake/clock.h"
#include "prtbake/error.h"
#include "prtbake/prefilter.h"
#include "prtbake/runtime.h"

namespace prtbake {
namespace {

// Subsamples per side of an output texel when resampling: at most this many.
constexpr int kMaxSupersample = 16;
// Host threads of the resampling loops, rows of 64 at a time.
constexpr int kResampleThreads = 8;
constexpr size_t kResampleBlock = 64;

// The map's own direction of world direction w: yaw undone (a map direction d is seen at
// Ry(yaw)·d); cs = (cos yaw, sin yaw).
void mapDirection(const double cs[2], const double w[3], double d[3]) {
  d[0] = cs[0] * w[0] - cs[1] * w[2];
  d[1] = w[1];
  d[2] = cs[1] * w[0] + cs[0] * w[2];
}

// The solid angle of the source texel seen in map direction d.
double sourceTexelSr(const EnvMap& env, const double d[3]) {
  if (env.layout == EnvLayout::LatLong)
    return (2 * kPi / env.width) * (kPi / env.height) * std::max(std::sqrt(std::max(0.0, 1.0 - d[1] * d[1])), 0.5 / env.height);
  const double m = std::max({std::abs(d[0]), std::abs(d[1]), std::abs(d[2])});  // 1/|(u, v, 1)| for unit d
  return (4.0 / (double(env.width) * env.width)) * m * m * m;
}

// Cube source: the face whose axis is nearest `d` (any face bases), and its u, v.
int sourceFace(const EnvMap& env, const double d[3], double* u, double* v) {
  int best = 0;
  double bestDot = -1e300;
  for (int f = 0; f < 6; ++f) {
    const auto& n = env.faces[size_t(f)].axisN;
    const double dot = d[0] * n[0] + d[1] * n[1] + d[2] * n[2];
    if (dot > bestDot) bestDot = dot, best = f;
  }
  const auto& b = env.faces[size_t(best)];
  *u = (d[0] * b.axisU[0] + d[1] * b.axisU[1] + d[2] * b.axisU[2]) / bestDot;
  *v = (d[0] * b.axisV[0] + d[1] * b.axisV[1] + d[2] * b.axisV[2]) / bestDot;
  return best;
}

// Texel (ix, iy) of face `face` of a cube source; outside the face, the texel of whichever
// face holds that point of the face's plane (so taps cross edges seamlessly).
const float* cubeTap(const EnvMap& env, int face, int ix, int iy) {
  const int n = env.width;
  if (ix < 0 || iy < 0 || ix >= n || iy >= n) {
    const auto& b = env.faces[size_t(face)];
    const double u = 2.0 * (ix + 0.5) / n - 1.0, v = 2.0 * (iy + 0.5) / n - 1.0;
    double d[3], uu, vv;
    for (int k = 0; k < 3; ++k) d[k] = u * b.axisU[size_t(k)] + v * b.axisV[size_t(k)] + b.axisN[size_t(k)];
    face = sourceFace(env, d, &uu, &vv);
    ix = std::clamp(int((uu + 1.0) * 0.5 * n), 0, n - 1);
    iy = std::clamp(int((vv + 1.0) * 0.5 * n), 0, n - 1);
  }
  return &env.rgb[3 * ((size_t(face) * size_t(n) + size_t(iy)) * size_t(n) + size_t(ix))];
}

// The bilinear taps of a lat-long source of w × h at map direction d (unit): columns ix0,
// ix1 (wrapping), rows iy0 and iy1 = min(h − 1, iy0 + 1), and the weights fx, fy of ix1, iy1.
// The rows alone (latLongRows) tell a band whether the lookup is its.
struct LatLongTaps {
  int ix0, ix1, iy0, iy1;
  double fx, fy;
};
void latLongRows(int h, const double d[3], LatLongTaps* p) {
  const double phi = std::asin(std::clamp(d[1], -1.0, 1.0));
  const double fy = std::clamp((0.5 - phi / kPi) * h - 0.5, 0.0, double(h - 1)), y0 = std::floor(fy);
  p->fy = fy - y0;
  p->iy0 = int(y0), p->iy1 = std::min(h - 1, p->iy0 + 1);
}
void latLongColumns(int w, const double d[3], LatLongTaps* p) {
  const double lambda = std::atan2(d[0], d[2]);
  const double fx = (0.5 - lambda / (2 * kPi)) * w - 0.5, x0 = std::floor(fx);
  p->fx = fx - x0;
  p->ix0 = ((int(x0) % w) + w) % w, p->ix1 = (p->ix0 + 1) % w;
}
LatLongTaps latLongTaps(int w, int h, const double d[3]) {
  LatLongTaps p;
  latLongRows(h, d, &p);
  latLongColumns(w, d, &p);
  return p;
}

// The bilinear blend of taps t (x0y0, x1y0, x0y1, x1y1).
void blend(const float* const t[4], double fx, double fy, double rgb[3]) {
  for (int c = 0; c < 3; ++c)
    rgb[c] = (1 - fy) * ((1 - fx) * t[0][c] + fx * t[1][c]) + fy * ((1 - fx) * t[2][c] + fx * t[3][c]);
}

// Bilinear radiance of the source at map direction d (unit).
void bilinear(const EnvMap& env, const double d[3], double rgb[3]) {
  double fx, fy;
  const float* t[4];
  if (env.layout == EnvLayout::LatLong) {
    const size_t w = size_t(env.width);
    const LatLongTaps p = latLongTaps(env.width, env.height, d);
    fx = p.fx, fy = p.fy;
    t[0] = &env.rgb[3 * (size_t(p.iy0) * w + size_t(p.ix0))];
    t[1] = &env.rgb[3 * (size_t(p.iy0) * w + size_t(p.ix1))];
    t[2] = &env.rgb[3 * (size_t(p.iy1) * w + size_t(p.ix0))];
    t[3] = &env.rgb[3 * (size_t(p.iy1) * w + size_t(p.ix1))];
  } else {
    const int n = env.width;
    double u, v;
    const int face = sourceFace(env, d, &u, &v);
    fx = (u + 1.0) * 0.5 * n - 0.5;
    fy = (v + 1.0) * 0.5 * n - 0.5;
    const double x0 = std::floor(fx), y0 = std::floor(fy);
    fx -= x0, fy -= y0;
    t[0] = cubeTap(env, face, int(x0), int(y0));
    t[1] = cubeTap(env, face, int(x0) + 1, int(y0));
    t[2] = cubeTap(env, face, int(x0), int(y0) + 1);
    t[3] = cubeTap(env, face, int(x0) + 1, int(y0) + 1);
  }
  blend(t, fx, fy, rgb);
}

// Output texel (row, col) of face b of an n×n cube as the resampling reads the source: the
// map direction of its centre and s, the subsamples per side: the ratio of the texel's
// angular size to the source's there, rounded up, in [1, kMaxSupersample].
struct OutputTexel {
  OutputTexel(const EnvMap& env, const CubeFaceBasis& b, const double cs[2], int n, int row, int col)
      : b(b), cs(cs), n(n), row(row), col(col) {
    // The texel's solid angle against the source's at its centre sets the subsamples.
    const double uc = 2.0 * (col + 0.5) / n - 1.0, vc = 2.0 * (row + 0.5) / n - 1.0;
    const double r2 = uc * uc + vc * vc + 1.0, outSr = (4.0 / (double(n) * n)) / (r2 * std::sqrt(r2));
    double w[3];
    for (int k = 0; k < 3; ++k) w[k] = uc * b.axisU[size_t(k)] + vc * b.axisV[size_t(k)] + b.axisN[size_t(k)];
    const double l = std::sqrt(r2);
    for (double& x : w) x /= l;
    mapDirection(cs, w, centre);
    s = std::clamp(int(std::ceil(std::sqrt(outSr / sourceTexelSr(env, centre)) - 1e-9)), 1, kMaxSupersample);
  }
  // Subsample (i, j) (column i, row j of the s × s grid): its solid-angle density on the face
  // plane, 1/|(u, v, 1)|³, and (direction) its map direction.
  double density(int i, int j, double* direction = nullptr) const {
    const double u = 2.0 * (col + (i + 0.5) / s) / n - 1.0, v = 2.0 * (row + (j + 0.5) / s) / n - 1.0;
    const double q2 = u * u + v * v + 1.0, dw = 1.0 / (q2 * std::sqrt(q2));
    if (direction) {
      const double ql = std::sqrt(q2);
      double w[3];
      for (int k = 0; k < 3; ++k) w[k] = (u * b.axisU[size_t(k)] + v * b.axisV[size_t(k)] + b.axisN[size_t(k)]) / ql;
      mapDirection(cs, w, direction);
    }
    return dw;
  }

  const CubeFaceBasis& b;
  const double* cs;
  int n, row, col, s = 1;
  double centre[3];
};

}  // namespace

// Each output texel: magnifying (s = 1), the bilinear value at its centre; otherwise the
// solid-angle-weighted mean of the bilinear values at its s × s subtexel centres,
//   P = Σ_ij dω_ij L(d_ij) / Σ_ij dω_ij,  dω = 1/|(u, v, 1)|³ (the face plane's density),
// summed in double in the order j, i.
std::vector<float> resampleEnvironment(const EnvMap& env, int n) {
  if (n < 1) throw UsageError("--size", "must be at least 1");
  std::vector<float> out(size_t(6) * size_t(n) * size_t(n) * 3);
  const auto bases = standardCubeBases();
  const double yaw = env.yawDegrees * kPi / 180.0, cs[2] = {std::cos(yaw), std::sin(yaw)};
  detail::parallelEach(size_t(6) * size_t(n), kResampleThreads, [&](size_t fr) {
    const int face = int(fr / size_t(n)), row = int(fr % size_t(n));
    const auto& b = bases[size_t(face)];
    for (int col = 0; col < n; ++col) {
      const OutputTexel t(env, b, cs, n, row, col);
      double d[3], rgb[3];
      float* o = &out[3 * ((size_t(face) * size_t(n) + size_t(row)) * size_t(n) + size_t(col))];
      if (t.s == 1) {  // magnifying: the bilinear value at the centre
        bilinear(env, t.centre, rgb);
        for (int k = 0; k < 3; ++k) o[k] = float(rgb[k]);
        continue;
      }
      double acc[3] = {0, 0, 0}, weight = 0;
      for (int j = 0; j < t.s; ++j)
        for (int i = 0; i < t.s; ++i) {
          const double dw = t.density(i, j, d);
          bilinear(env, d, rgb);
          for (int k = 0; k < 3; ++k) acc[k] += dw * rgb[k];
          weight += dw;
        }
      for (int k = 0; k < 3; ++k) o[k] = float(acc[k] / weight);
    }
  }, kResampleBlock);
  return out;
}

namespace detail {
namespace {

// The rows iy0 (latLongTaps) that subsamples of the face rectangle [u0, u1] × [v0, v1] of
// the standard cube can read first from an h-row lat-long source, one row wider either side
// for rounding. Yaw keeps the world y of a direction, which is −v/ℓ on the side faces and
// ±1/ℓ on ±Y, ℓ = |(u, v, 1)|: for a fixed v the extremes lie at the u nearest 0 or farthest
// from it, for a fixed u at v0 or v1 (side faces; −v/ℓ falls with v), and on ±Y at the
// point nearest the face's centre and the corner farthest from it.
void rectangleRows(int face, double u0, double u1, double v0, double v1, int h, int* lo, int* hi) {
  auto nearest = [](double a, double b) { return std::clamp(0.0, a, b); };
  auto farthest = [](double a, double b) { return std::abs(a) > std::abs(b) ? a : b; };
  auto worldY = [face](double u, double v) {
    const double l = std::sqrt(u * u + v * v + 1.0);
    return face == 2 ? 1.0 / l : face == 3 ? -1.0 / l : -v / l;
  };
  const double un = nearest(u0, u1), uf = farthest(u0, u1);
  double ys[4];
  if (face == 2 || face == 3) {
    ys[0] = ys[2] = worldY(un, nearest(v0, v1));
    ys[1] = ys[3] = worldY(uf, farthest(v0, v1));
  } else {
    ys[0] = worldY(un, v0), ys[1] = worldY(uf, v0), ys[2] = worldY(un, v1), ys[3] = worldY(uf, v1);
  }
  const double yMin = *std::min_element(ys, ys + 4), yMax = *std::max_element(ys, ys + 4);
  auto row = [h](double y) {
    const double fy = std::clamp((0.5 - std::asin(std::clamp(y, -1.0, 1.0)) / kPi) * h - 0.5, 0.0, double(h - 1));
    return int(std::floor(fy));
  };
  *lo = std::max(0, row(yMax) - 1);
  *hi = std::min(h - 1, row(yMin) + 1);
}

}  // namespace

// Tiles of kTile × kTile output texels; a tile's sums live from the first band that reaches
// its rows to the one that covers its last.
constexpr int kTile = 8;

struct ResampleBands::Tile {
  std::array<double, 3 * kTile * kTile> acc{};
  size_t taken = 0;  // subsamples added
};

ResampleBands::ResampleBands(const EnvMap& description, int n) : n_(n) {
  PRTBAKE_CHECK(description.layout == EnvLayout::LatLong, "bands are rows of a lat-long map");
  if (n < 1) throw UsageError("--size", "must be at least 1");
  map_.layout = EnvLayout::LatLong;
  map_.width = description.width, map_.height = description.height;
  map_.yawDegrees = description.yawDegrees;
  out_.resize(size_t(6) * size_t(n) * size_t(n) * 3);
  side_ = (n + kTile - 1) / kTile;
  const size_t tiles = size_t(6) * size_t(side_) * size_t(side_);
  rowLo_.resize(tiles), rowHi_.resize(tiles);
  tiles_.resize(tiles);
  for (size_t id = 0; id < tiles; ++id) {
    int face, ty, tx;
    tilePosition(id, &face, &ty, &tx);
    const int r1 = std::min(n, (ty + 1) * kTile), c1 = std::min(n, (tx + 1) * kTile);
    rectangleRows(face, 2.0 * tx * kTile / n - 1.0, 2.0 * c1 / n - 1.0, 2.0 * ty * kTile / n - 1.0, 2.0 * r1 / n - 1.0,
                  map_.height, &rowLo_[id], &rowHi_[id]);
  }
}

ResampleBands::~ResampleBands() = default;

void ResampleBands::tilePosition(size_t id, int* face, int* ty, int* tx) const {
  const size_t side = size_t(side_);
  *face = int(id / (side * side)), *ty = int(id / side % side), *tx = int(id % side);
}

void ResampleBands::add(const EnvMap& band, int firstRow) {
  PRTBAKE_CHECK(firstRow == nextRow_ && band.width == map_.width && band.height >= 1 &&
                    band.rgb.size() == 3 * band.texelCount(),
                "bands must come in order, as float rows of the map");
  const int w = map_.width, h = map_.height, last = firstRow + band.height;
  // Subsamples whose first row iy0 lies in [lo, hi) are taken now: their rows iy0 and iy1 are
  // this band's or (iy0 = firstRow − 1) the previous band's last row.
  const int lo = firstRow == 0 ? 0 : firstRow - 1, hi = last == h ? h : last - 1;
  auto rowOf = [&](int y) -> const float* {
    return y < firstRow ? lastRow_.data() : &band.rgb[3 * size_t(y - firstRow) * size_t(w)];
  };
  const auto bases = standardCubeBases();
  const double yaw = map_.yawDegrees * kPi / 180.0, cs[2] = {std::cos(yaw), std::sin(yaw)};
  const int n = n_;
  std::atomic<bool> broken{false};  // checked after the threads (an exception would end the process)
  parallelEach(tiles_.size(), kResampleThreads, [&](size_t id) {
    if (rowHi_[id] < lo || rowLo_[id] >= hi) return;
    int face, ty, tx;
    tilePosition(id, &face, &ty, &tx);
    std::unique_ptr<Tile>& tile = tiles_[id];
    if (!tile) tile = std::make_unique<Tile>();
    const CubeFaceBasis& b = bases[size_t(face)];
    for (int row = ty * kTile; row < std::min(n, (ty + 1) * kTile); ++row)
      for (int col = tx * kTile; col < std::min(n, (tx + 1) * kTile); ++col) {
        int texelLo, texelHi;  // the rows this texel's lookups may start at
        rectangleRows(face, 2.0 * col / n - 1.0, 2.0 * (col + 1) / n - 1.0, 2.0 * row / n - 1.0, 2.0 * (row + 1) / n - 1.0,
                      h, &texelLo, &texelHi);
        if (texelHi < lo || texelLo >= hi) continue;
        const OutputTexel t(map_, b, cs, n, row, col);
        double* acc = &tile->acc[3 * size_t((row - ty * kTile) * kTile + (col - tx * kTile))];
        auto take = [&](const double d[3], double dw) {
          LatLongTaps p;
          latLongRows(h, d, &p);
          if (p.iy0 < lo || p.iy0 >= hi) return;
          if (p.iy0 < texelLo || p.iy0 > texelHi) broken = true;  // outside its texel's rows
          latLongColumns(w, d, &p);
          const float* r0 = rowOf(p.iy0);
          const float* r1 = rowOf(p.iy1);
          const float* taps[4] = {r0 + 3 * size_t(p.ix0), r0 + 3 * size_t(p.ix1), r1 + 3 * size_t(p.ix0),
                                  r1 + 3 * size_t(p.ix1)};
          double rgb[3];
          blend(taps, p.fx, p.fy, rgb);
          for (int k = 0; k < 3; ++k) acc[k] += dw * rgb[k];
          ++tile->taken;
        };
        if (t.s == 1) {
          take(t.centre, 1.0);  // magnifying: the bilinear value at the centre, weight 1
          continue;
        }
        double d[3];
        for (int j = 0; j < t.s; ++j)
          for (int i = 0; i < t.s; ++i) take(d, t.density(i, j, d));
      }
    if (rowHi_[id] < hi && !finishTile(id)) broken = true;
  }, 4);
  PRTBAKE_CHECK(!broken, "the resampling's bands missed or misplaced subsamples");
  lastRow_.assign(rowOf(last - 1), rowOf(last - 1) + 3 * size_t(w));
  nextRow_ = last;
}

// The tile's texels: acc / Σ dω, the weights summed in the order resampleEnvironment sums them.
bool ResampleBands::finishTile(size_t id) {
  const int n = n_;
  int face, ty, tx;
  tilePosition(id, &face, &ty, &tx);
  const CubeFaceBasis b = standardCubeBases()[size_t(face)];
  const double yaw = map_.yawDegrees * kPi / 180.0, cs[2] = {std::cos(yaw), std::sin(yaw)};
  const Tile& tile = *tiles_[id];
  size_t expected = 0;
  for (int row = ty * kTile; row < std::min(n, (ty + 1) * kTile); ++row)
    for (int col = tx * kTile; col < std::min(n, (tx + 1) * kTile); ++col) {
      const OutputTexel t(map_, b, cs, n, row, col);
      double weight = t.s == 1 ? 1.0 : 0.0;
      for (int j = 0; j < t.s && t.s > 1; ++j)
        for (int i = 0; i < t.s; ++i) weight += t.density(i, j);
      expected += size_t(t.s) * size_t(t.s);
      const double* acc = &tile.acc[3 * size_t((row - ty * kTile) * kTile + (col - tx * kTile))];
      float* o = &out_[3 * ((size_t(face) * size_t(n) + size_t(row)) * size_t(n) + size_t(col))];
      for (int k = 0; k < 3; ++k) o[k] = float(acc[k] / weight);
    }
  const bool complete = tile.taken == expected;
  tiles_[id].reset();
  ++finished_;
  return complete;
}

std::vector<float> ResampleBands::finish() {
  PRTBAKE_CHECK(nextRow_ == map_.height && finished_ == tiles_.size(), "the resampling needs every row of the map");
  return std::move(out_);
}

}  // namespace detail

std::vector<double> prefilterBruteForce(const EnvMap& env, PrefilterLobe lobe, double alpha,
                                        const std::vector<double>& dirs) {
  const size_t count = env.texelCount();
  std::vector<double> dx(count), dy(count), dz(count), om(count), cr(count), cg(count), cb(count);
  for (size_t t = 0; t < count; ++t) {
    double d[3];
    texelDirection(env, t, d, &om[t]);
    dx[t] = d[0], dy[t] = d[1], dz[t] = d[2];
    cr[t] = env.rgb[3 * t], cg[t] = env.rgb[3 * t + 1], cb[t] = env.rgb[3 * t + 2];
  }
  const size_t n = dirs.size() / 3;
  std::vector<double> out(3 * n);
  const double a2 = alpha * alpha;
  detail::parallelEach(n, kResampleThreads, [&](size_t i) {
    const double* r = &dirs[3 * i];
    // Four interleaved partial sums per quantity (independent chains), added in a fixed order.
    double acc[4][4] = {};
    for (size_t t = 0; t < count; ++t) {
      const double mu = r[0] * dx[t] + r[1] * dy[t] + r[2] * dz[t];
      double w;
      if (lobe == PrefilterLobe::Ggx) {
        // k = μ (α²/q)², q = e/2 + (1 − e/2) α², e = 1 − μ (prefilterLobeWeight, inlined).
        const double e = 1.0 - mu, q = 0.5 * e + (1.0 - 0.5 * e) * a2, x = a2 / q;
        w = (mu > 0 ? mu : 0.0) * x * x * om[t];
      } else {
        w = mu > 0 ? prefilterLobeWeight(lobe, alpha, mu) * om[t] : 0.0;
      }
      double* a = acc[t & 3];
      a[0] += w * cr[t], a[1] += w * cg[t], a[2] += w * cb[t], a[3] += w;
    }
    double s[4];
    for (int k = 0; k < 4; ++k) s[k] = (acc[0][k] + acc[1][k]) + (acc[2][k] + acc[3][k]);
    for (int c = 0; c < 3; ++c) out[3 * i + size_t(c)] = s[3] > 0 ? s[c] / s[3] : 0.0;
  }, kResampleBlock);
  return out;
}

namespace detail {

// The box-filtered mip chain of an n×n cube (each level the 2×2 mean of the one above,
// odd sizes rounding down), down to 1×1.
std::vector<std::vector<float>> boxChain(const std::vector<float>& base, int n) {
  std::vector<std::vector<float>> chain = {base};
  for (int m = n; m > 1;) {
    const int h = m / 2;
    const std::vector<float>& src = chain.back();
    std::vector<float> dst(size_t(6) * size_t(h) * size_t(h) * 3);
    for (int f = 0; f < 6; ++f)
      for (int r = 0; r < h; ++r)
        for (int c = 0; c < h; ++c)
          for (int k = 0; k < 3; ++k) {
            double s = 0;
            for (int j = 0; j < 2; ++j)
              for (int i = 0; i < 2; ++i)
                s += src[3 * ((size_t(f) * size_t(m) + size_t(2 * r + j)) * size_t(m) + size_t(2 * c + i)) + size_t(k)];
            dst[3 * ((size_t(f) * size_t(h) + size_t(r)) * size_t(h) + size_t(c)) + size_t(k)] = float(s / 4);
          }
    chain.push_back(std::move(dst));
    m = h;
  }
  return chain;
}

// Filament's CubemapIBL::roughnessFilter (and the Khronos sampler's filterColor): GGX half
// vectors from the Hammersley set, L = reflect(−N, H) with N = V = R, weight N·L, read at
// lod = log4(Ω_s/Ω_p) + log4(K), K = 4, Ω_s = 1/(S pdf), pdf = D/4, Ω_p = 4π/(6 n0²).
std::vector<float> prefilterSampledLevel(Runtime& rt, const std::vector<std::vector<float>>& chain, int n,
                                         double alpha, int samples, double* kernelSeconds) {
  const int n0 = int(std::lround(std::sqrt(double(chain[0].size() / 18))));
  const int maxLevel = int(chain.size()) - 1;
  std::vector<cl_float4> table(static_cast<size_t>(samples));
  std::vector<float> lods(static_cast<size_t>(samples));
  const double a2 = alpha * alpha, omegaP = 4 * kPi / (6.0 * n0 * n0);
  for (int i = 0; i < samples; ++i) {
    const double u1 = double(i) / samples, u2 = detail::radicalInverse2(uint32_t(i));
    const double ct = std::sqrt((1 - u2) / (1 + (a2 - 1) * u2)), st = std::sqrt(std::max(0.0, 1 - ct * ct));
    const double phi = 2 * kPi * u1;
    const double l[3] = {2 * ct * st * std::cos(phi), 2 * ct * st * std::sin(phi), 2 * ct * ct - 1};
    const double q = ct * ct * (a2 - 1) + 1, d = a2 / (kPi * q * q);
    table[size_t(i)] = {{float(l[0]), float(l[1]), float(l[2]), float(std::max(0.0, l[2]))}};
    lods[size_t(i)] = float(d > 0 ? 0.5 * std::log2((1.0 / (samples * d / 4)) / omegaP) + 1.0 : maxLevel);
  }
  // Bordered levels: (m + 2)² texels per face, the border from the neighbouring faces.
  std::vector<cl_float4> bordered;
  std::vector<cl_int2> levels;
  for (int l = 0; l <= maxLevel; ++l) {
    const int m = std::max(1, n0 >> l), s = m + 2;
    levels.push_back({{int(bordered.size()), m}});
    const std::vector<float>& src = chain[size_t(l)];
    const auto bases = standardCubeBases();
    for (int f = 0; f < 6; ++f)
      for (int y = -1; y <= m; ++y)
        for (int x = -1; x <= m; ++x) {
          size_t idx;
          if (x >= 0 && y >= 0 && x < m && y < m) {
            idx = (size_t(f) * size_t(m) + size_t(y)) * size_t(m) + size_t(x);
          } else {
            const auto& b = bases[size_t(f)];
            const double u = 2.0 * (x + 0.5) / m - 1.0, v = 2.0 * (y + 0.5) / m - 1.0;
            double d[3];
            for (int k = 0; k < 3; ++k) d[k] = u * b.axisU[size_t(k)] + v * b.axisV[size_t(k)] + b.axisN[size_t(k)];
            idx = cubeTexelIndex(m, d);
          }
          bordered.push_back({{src[3 * idx], src[3 * idx + 1], src[3 * idx + 2], 1.0f}});
        }
    (void)s;
  }
  std::vector<float> faceBases;
  for (const CubeFaceBasis& b : standardCubeBases())
    for (const auto* a : {&b.axisU, &b.axisV, &b.axisN})
      for (double x : *a) faceBases.push_back(float(x));
  cl::Kernel k = rt.kernel("prefilter.cl", "prefilter_sampled", detail::prefilterSampledOptions());
  cl::Buffer chainBuf = rt.upload(bordered), levelBuf = rt.upload(levels), tab = rt.upload(table), lodBuf = rt.upload(lods);
  cl::Buffer basesBuf = rt.upload(faceBases);
  const size_t texels = size_t(6) * size_t(n) * size_t(n);
  cl::Buffer out(rt.context(), CL_MEM_WRITE_ONLY, texels * 3 * sizeof(float));
  int a = 0;
  k.setArg(a++, chainBuf);
  k.setArg(a++, levelBuf);
  k.setArg(a++, maxLevel);
  k.setArg(a++, tab);
  k.setArg(a++, lodBuf);
  k.setArg(a++, samples);
  k.setArg(a++, n);
  k.setArg(a++, basesBuf);
  k.setArg(a++, out);
  const size_t local = 16, global = (texels + local - 1) / local * local;
  const auto t0 = std::chrono::steady_clock::now();
  rt.queue().enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(global), cl::NDRange(local));
  rt.queue().finish();
  *kernelSeconds = secondsSince(t0);
  std::vector<float> rgb(texels * 3);
  rt.queue().enqueueReadBuffer(out, CL_TRUE, 0, rgb.size() * sizeof(float), rgb.data());
  return rgb;
}

}  // namespace detail
}  // namespace prtbake
