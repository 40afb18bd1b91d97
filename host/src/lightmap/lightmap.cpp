// Lightmaps: conservative rasterisation of the UV charts, the samples' unocclusion, the bake
// through the transport at surface points, and dilation (see prtbake/lightmap.h).
#include "prtbake/lightmap.h"
#include "prtbake/limits.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <map>
#include <numeric>
#include <unordered_map>

#include "core/constants.h"
#include "prtbake/bvh.h"
#include "prtbake/clock.h"
#include "prtbake/error.h"
#include "prtbake/glossy.h"
#include "transport/transport_setup.h"

namespace prtbake {
namespace {
using Clock = std::chrono::steady_clock;

std::string subjectOf(const Mesh& mesh) { return mesh.sourcePath.empty() ? "mesh" : mesh.sourcePath; }

int resolveUvSet(const Mesh& mesh, int requested) {
  const int set = requested >= 0 ? requested : mesh.hasUvSet(1) ? 1 : 0;
  if (!mesh.hasUvSet(set)) {
    std::string why = size_t(set) < mesh.uvMissing.size() && !mesh.uvMissing[size_t(set)].empty()
                          ? mesh.uvMissing[size_t(set)]
                          : "no primitive has it";
    std::string has;
    for (size_t k = 0; k < mesh.uvs.size(); ++k)
      if (!mesh.uvs[k].empty()) has += (has.empty() ? "" : ", ") + std::to_string(k);
    throw InputError(subjectOf(mesh), "has no UV set " + std::to_string(set) + " (TEXCOORD_" + std::to_string(set) +
                                          "): " + why + (has.empty() ? "; it has no UV set at all" : "; it has set(s) " + has + " (--uv)"));
  }
  const std::vector<float>& uv = mesh.uvs[size_t(set)];
  if (uv.size() != 2 * mesh.vertexCount())
    throw InputError(subjectOf(mesh), "UV set " + std::to_string(set) + " does not have one UV per vertex");
  for (size_t i = 0; i < uv.size(); ++i)
    if (!std::isfinite(uv[i]))
      throw InputError(subjectOf(mesh), "UV set " + std::to_string(set) + ": vertex " + std::to_string(i / 2) +
                                            " has a non-finite " + (i % 2 ? "v" : "u"));
  return set;
}

double cross2(double ax, double ay, double bx, double by) { return ax * by - ay * bx; }

// The point of segment [a, b] nearest to p (as the parameter s ∈ [0, 1]) and its squared distance.
double segmentNearest(const double* a, const double* b, const double* p, double* s) {
  const double dx = b[0] - a[0], dy = b[1] - a[1];
  const double len2 = dx * dx + dy * dy;
  double t = len2 > 0 ? ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  *s = t;
  const double ex = a[0] + t * dx - p[0], ey = a[1] + t * dy - p[1];
  return ex * ex + ey * ey;
}

// Separating axes: does the triangle (texel units) meet the square [x, x + 1] × [y, y + 1]?
bool triangleTouchesTexel(const double q[3][2], int x, int y) {
  // (The square's own axes: the caller visits only texels within the triangle's bounding box.)
  const double corners[4][2] = {{double(x), double(y)}, {x + 1.0, double(y)}, {double(x), y + 1.0}, {x + 1.0, y + 1.0}};
  const double orient = cross2(q[1][0] - q[0][0], q[1][1] - q[0][1], q[2][0] - q[0][0], q[2][1] - q[0][1]);
  for (int e = 0; e < 3; ++e) {  // the triangle's edge normals: all corners outside one edge → apart
    const double* a = q[e];
    const double* b = q[(e + 1) % 3];
    bool allOutside = true;
    for (const auto& c : corners)
      if (orient * cross2(b[0] - a[0], b[1] - a[1], c[0] - a[0], c[1] - a[1]) >= 0) {
        allOutside = false;
        break;
      }
    if (allOutside) return false;
  }
  return true;
}

// Union–find over triangles.
struct Charts {
  std::vector<uint32_t> parent;
  explicit Charts(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0u); }
  uint32_t find(uint32_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  }
  void join(uint32_t a, uint32_t b) {
    a = find(a), b = find(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  }
};

// Charts: triangles joined by an edge whose two UV endpoints are the same (exact floats).
Charts findCharts(const Mesh& mesh, const std::vector<float>& uv, const std::vector<char>& usable) {
  const size_t nt = mesh.triangleCount();
  Charts charts(nt);
  struct Key {
    float a[4];
    bool operator==(const Key& o) const { return std::memcmp(a, o.a, sizeof a) == 0; }
  };
  struct Hash {
    size_t operator()(const Key& k) const {
      uint64_t h = 1469598103934665603ull;
      const auto* p = reinterpret_cast<const unsigned char*>(k.a);
      for (size_t i = 0; i < sizeof k.a; ++i) h = (h ^ p[i]) * 1099511628211ull;
      return size_t(h);
    }
  };
  std::unordered_map<Key, uint32_t, Hash> edges;
  edges.reserve(nt * 3);
  for (size_t t = 0; t < nt; ++t) {
    if (!usable[t]) continue;
    for (int e = 0; e < 3; ++e) {
      const uint32_t i = mesh.indices[3 * t + e], j = mesh.indices[3 * t + (e + 1) % 3];
      std::array<float, 2> p{uv[2 * i], uv[2 * i + 1]}, q{uv[2 * j], uv[2 * j + 1]};
      if (q < p) std::swap(p, q);
      const Key key{{p[0], p[1], q[0], q[1]}};
      auto [it, fresh] = edges.emplace(key, uint32_t(t));
      if (!fresh) charts.join(uint32_t(t), it->second);
    }
  }
  return charts;
}

// What the rasterisation keeps per texel: the triangle of its sample, its barycentrics and the
// squared distance (texel units) from the texel's centre to the sample (0: inside).
struct TexelHit {
  int32_t tri = -1;
  uint32_t chart = 0;
  float w[3] = {0, 0, 0};
  float dist2 = 0;
  bool inside = false, contested = false;
  bool strict = false;  // the centre lies inside by more than kStrictInside (not on an edge)
};

// Barycentric margin that puts a texel centre strictly inside a triangle: two triangles of one
// chart share at most an edge, whose centres compute to within rounding (~1e-16) of 0 on it.
constexpr double kStrictInside = 1e-7;

void rasterise(const Mesh& mesh, const std::vector<float>& uv, int W, int H, const std::vector<char>& usable,
               Charts& charts, std::vector<TexelHit>& texels) {
  texels.assign(size_t(W) * size_t(H), TexelHit{});
  for (size_t t = 0; t < mesh.triangleCount(); ++t) {
    if (!usable[t]) continue;
    double q[3][2];
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = mesh.indices[3 * t + k];
      q[k][0] = double(uv[2 * v]) * W, q[k][1] = double(uv[2 * v + 1]) * H;
    }
    const double area = cross2(q[1][0] - q[0][0], q[1][1] - q[0][1], q[2][0] - q[0][0], q[2][1] - q[0][1]);
    // The texel range it covers, clamped to the map in double first (UVs may lie far outside it).
    auto cell = [](double c, int n) { return int(std::floor(std::clamp(c, -1.0, double(n)))); };
    const int x0 = std::max(0, cell(std::min({q[0][0], q[1][0], q[2][0]}), W)),
              x1 = std::min(W - 1, cell(std::max({q[0][0], q[1][0], q[2][0]}), W)),
              y0 = std::max(0, cell(std::min({q[0][1], q[1][1], q[2][1]}), H)),
              y1 = std::min(H - 1, cell(std::max({q[0][1], q[1][1], q[2][1]}), H));
    const uint32_t chart = charts.find(uint32_t(t));
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        if (!triangleTouchesTexel(q, x, y)) continue;
        const double c[2] = {x + 0.5, y + 0.5};
        // Barycentrics of the centre; inside when all are ≥ 0.
        double b[3];
        for (int k = 0; k < 3; ++k) {
          const double* a = q[(k + 1) % 3];
          const double* e = q[(k + 2) % 3];
          b[k] = cross2(e[0] - a[0], e[1] - a[1], c[0] - a[0], c[1] - a[1]) / area;
        }
        double d2 = 0;
        const bool inside = b[0] >= 0 && b[1] >= 0 && b[2] >= 0;
        if (!inside) {  // the nearest point of the boundary, pulled 0.1 % towards the centroid
          d2 = 1e300;
          for (int e = 0; e < 3; ++e) {
            double s = 0;
            const double dd = segmentNearest(q[e], q[(e + 1) % 3], c, &s);
            if (dd < d2) {
              d2 = dd;
              b[e] = 1 - s, b[(e + 1) % 3] = s, b[(e + 2) % 3] = 0;
            }
          }
          for (double& w : b) w = 0.999 * w + 0.001 / 3;
        }
        TexelHit& h = texels[size_t(y) * W + x];
        const bool strict = inside && std::min({b[0], b[1], b[2]}) > kStrictInside;
        // Two charts' triangles both holding the centre, or two of one chart both holding it
        // strictly (UVs stacked or folded onto themselves: charts join by edges with equal UVs,
        // so copies of one UV square join into one chart).
        if (h.tri >= 0 && inside && h.inside && (h.chart != chart || (strict && h.strict)))
          throw InputError(subjectOf(mesh),
                           "UV charts overlap: texel (" + std::to_string(x) + ", " + std::to_string(y) + ") of the " +
                               std::to_string(W) + "x" + std::to_string(H) + " lightmap is covered by triangle " +
                               std::to_string(h.tri) + " and triangle " + std::to_string(t) +
                               (h.chart != chart ? " of another chart" : " of the same chart (UVs stacked or folded)") +
                               " (a lightmap needs a UV set whose charts do not overlap)");
        if (h.tri >= 0 && h.chart != chart) h.contested = true;
        if (h.tri >= 0 && (h.inside || (!inside && h.dist2 <= d2))) continue;
        h.tri = int32_t(t);
        h.chart = chart;
        h.inside = inside;
        h.strict = strict;
        h.dist2 = float(d2);
        for (int k = 0; k < 3; ++k) h.w[k] = float(b[k]);
      }
  }
}

std::array<double, 3> faceNormalOf(const Mesh& mesh, size_t t, double* area) {
  const float* p0 = &mesh.positions[3 * size_t(mesh.indices[3 * t])];
  const float* p1 = &mesh.positions[3 * size_t(mesh.indices[3 * t + 1])];
  const float* p2 = &mesh.positions[3 * size_t(mesh.indices[3 * t + 2])];
  const double e1[3] = {double(p1[0]) - p0[0], double(p1[1]) - p0[1], double(p1[2]) - p0[2]};
  const double e2[3] = {double(p2[0]) - p0[0], double(p2[1]) - p0[1], double(p2[2]) - p0[2]};
  std::array<double, 3> n{e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
  const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  *area = len / 2;
  if (len > 0)
    for (double& c : n) c /= len;
  return n;
}

// Moves samples out of closed geometry (kernels/lightmap.cl); returns per sample 0 unchanged,
// 1 moved, 2 buried, and updates the positions of the moved ones.
std::vector<uint8_t> unocclude(Runtime& rt, const Mesh& mesh, SurfacePoints& pts, const std::vector<float>& reach) {
  const size_t n = pts.count();
  std::vector<uint8_t> state(n, 0);
  if (n == 0) return state;
  TransportOptions to;
  const detail::RaySetup setup = detail::makePointRaySetup(mesh, pts, to);
  const Bvh bvh = buildBvh(mesh);
  const size_t nt = mesh.triangleCount();
  std::vector<float> normals(nt * 4, 0.0f), corners(nt * 12, 0.0f);
  for (size_t t = 0; t < nt; ++t) {
    double area = 0;
    const auto fn = faceNormalOf(mesh, t, &area);
    for (int c = 0; c < 3; ++c) normals[4 * t + c] = float(fn[c]);
    for (int k = 0; k < 3; ++k)
      for (int c = 0; c < 3; ++c) corners[12 * t + 4 * k + c] = mesh.positions[3 * size_t(mesh.indices[3 * t + k]) + c];
  }
  std::vector<float> origins(n * 4), frames(n * 12);
  for (size_t i = 0; i < n; ++i) {
    const float* g = &pts.faceNormals[3 * i];
    for (int c = 0; c < 3; ++c) origins[4 * i + c] = float(pts.positions[3 * i + c] + setup.epsilon * g[c]);
    origins[4 * i + 3] = reach[i];
    // A tangent frame about the face normal (Duff et al. 2017).
    const double nx = g[0], ny = g[1], nz = g[2];
    const double sign = std::copysign(1.0, nz), a = -1.0 / (sign + nz), b = nx * ny * a;
    const double t0[3] = {1 + sign * nx * nx * a, sign * b, -sign * nx}, b0[3] = {b, sign + ny * ny * a, -ny};
    for (int c = 0; c < 3; ++c) frames[12 * i + c] = float(t0[c]), frames[12 * i + 4 + c] = float(b0[c]), frames[12 * i + 8 + c] = g[c];
  }
  const cl::Buffer o = rt.upload(origins), f = rt.upload(frames), nodes = detail::uploadBvhNodes(rt, bvh, false),
                   tris = detail::uploadBvhTriangles(rt, bvh, false), fn = rt.upload(normals), cn = rt.upload(corners);
  cl::Buffer out(rt.context(), CL_MEM_WRITE_ONLY, n * 16);
  cl::Kernel k = rt.kernel("lightmap.cl", "lightmap_unocclude", "");
  int a = 0;
  k.setArg(a++, int(n));
  k.setArg(a++, o);
  k.setArg(a++, f);
  k.setArg(a++, nodes);
  k.setArg(a++, tris);
  k.setArg(a++, setup.tMax);
  k.setArg(a++, float(setup.epsilon));
  k.setArg(a++, fn);
  k.setArg(a++, cn);
  k.setArg(a++, out);
  rt.enqueueLoop(k, n);
  std::vector<float> result(n * 4);
  rt.queue().enqueueReadBuffer(out, CL_TRUE, 0, result.size() * 4, result.data());
  for (size_t i = 0; i < n; ++i) {
    state[i] = uint8_t(result[4 * i + 3]);
    if (state[i] == 1)
      for (int c = 0; c < 3; ++c) pts.positions[3 * i + c] = result[4 * i + c];
  }
  return state;
}

// Fills empty texels within `rings` of the valid ones with the mean of their already filled
// 8-neighbours, ring by ring (a breadth-first front: each texel is visited once).
void dilate(LightmapResult& lm, int rings, const std::vector<std::vector<float>*>& planes,
            const std::vector<int>& widths) {
  const int W = lm.width, H = lm.height;
  std::vector<int> dist(lm.texels(), -1);
  std::vector<uint32_t> front, next;
  for (size_t i = 0; i < lm.texels(); ++i)
    if (TexelState(lm.state[i]) != TexelState::Empty) dist[i] = 0, front.push_back(uint32_t(i));
  for (int ring = 1; ring <= rings && !front.empty(); ++ring) {
    next.clear();
    for (uint32_t i : front) {
      const int x = int(i % uint32_t(W)), y = int(i / uint32_t(W));
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int nx = x + dx, ny = y + dy;
          if (nx < 0 || ny < 0 || nx >= W || ny >= H) continue;
          const size_t j = size_t(ny) * W + nx;
          if (dist[j] >= 0) continue;
          dist[j] = ring;
          next.push_back(uint32_t(j));
        }
    }
    for (uint32_t j : next) {
      const int x = int(j % uint32_t(W)), y = int(j / uint32_t(W));
      int count = 0;
      for (size_t p = 0; p < planes.size(); ++p) {
        std::vector<float>& plane = *planes[p];
        const int c = widths[p];
        std::vector<double> sum(size_t(c), 0.0);
        count = 0;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int nx = x + dx, ny = y + dy;
            if (nx < 0 || ny < 0 || nx >= W || ny >= H) continue;
            const size_t k = size_t(ny) * W + nx;
            if (dist[k] < 0 || dist[k] >= ring) continue;
            for (int q = 0; q < c; ++q) sum[size_t(q)] += plane[k * c + q];
            ++count;
          }
        for (int q = 0; q < c; ++q) plane[size_t(j) * c + q] = float(sum[size_t(q)] / std::max(count, 1));
      }
      lm.state[j] = uint8_t(TexelState::Dilated);
    }
    lm.dilated += next.size();
    front.swap(next);
  }
}

// Seam stitching (least squares, as in the seam-erasure write-ups: Liu, Ferguson and Jacobson's
// "Seamless", Sloan's "stitching lightmaps"). A seam is an edge of the surface (two triangles
// sharing both endpoints in space) whose two sides lie on different UV edges. Along it, at
// points t_k every half texel, the bilinear lookups of the two sides should agree:
//   minimise Σ_k (B_A(t_k) x − B_B(t_k) x)² + Σ_i λ_i (x_i − x0_i)²,
// x the texels that any lookup reads (B: the 4 bilinear weights at the UV of t_k on that side),
// x0 their baked values, λ_i = kSeamDataWeight for a texel with a valid sample (the data holds
// it near its value) and kSeamFreeWeight for the others (dilated: free to follow). The normal
// equations (SᵀS + Λ) x = Λ x0 are solved per channel by conjugate gradients. Returns the seam
// edges found and the worst jump across them before and after (in the first plane's units).
struct SeamStats {
  size_t edges = 0;
  double jumpBefore = 0, jumpAfter = 0;
};
constexpr double kSeamDataWeight = 0.1, kSeamFreeWeight = 1e-3;

SeamStats stitchSeams(const Mesh& mesh, const std::vector<float>& uv, const std::vector<char>& usable, LightmapResult& lm,
                      const std::vector<std::vector<float>*>& planes, const std::vector<int>& widths) {
  SeamStats st;
  const int W = lm.width, H = lm.height;
  struct Side {
    uint32_t tri;
    float uv0[2], uv1[2];  // the UVs at the edge's first and second endpoint (in position order)
  };
  std::map<std::array<float, 6>, std::vector<Side>> edges;
  for (size_t t = 0; t < mesh.triangleCount(); ++t) {
    if (!usable[t]) continue;
    for (int e = 0; e < 3; ++e) {
      uint32_t i = mesh.indices[3 * t + e], j = mesh.indices[3 * t + (e + 1) % 3];
      std::array<float, 3> pi{mesh.positions[3 * i], mesh.positions[3 * i + 1], mesh.positions[3 * i + 2]};
      std::array<float, 3> pj{mesh.positions[3 * j], mesh.positions[3 * j + 1], mesh.positions[3 * j + 2]};
      if (pj < pi) std::swap(pi, pj), std::swap(i, j);
      edges[{pi[0], pi[1], pi[2], pj[0], pj[1], pj[2]}].push_back(
          {uint32_t(t), {uv[2 * i], uv[2 * i + 1]}, {uv[2 * j], uv[2 * j + 1]}});
    }
  }
  // The constraints: per sample point, 4 (texel, weight) of side A and 4 of side B (weight negated).
  struct Tap {
    uint32_t texel;
    double w;
  };
  std::vector<std::array<Tap, 8>> rows;
  auto taps = [&](double u, double v, double sign, Tap* out) {
    // Clamped before the integer conversion: a lookup outside the map reads its edge.
    const double s = std::clamp(u * W - 0.5, -1.0, double(W)), t = std::clamp(v * H - 0.5, -1.0, double(H));
    const int x0 = int(std::floor(s)), y0 = int(std::floor(t));
    const double fx = s - x0, fy = t - y0;
    int k = 0;
    for (int dy = 0; dy < 2; ++dy)
      for (int dx = 0; dx < 2; ++dx) {
        const int x = std::clamp(x0 + dx, 0, W - 1), y = std::clamp(y0 + dy, 0, H - 1);
        out[k++] = {uint32_t(size_t(y) * W + x), sign * (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy)};
      }
  };
  for (const auto& [key, sides] : edges) {
    if (sides.size() != 2) continue;
    const Side& a = sides[0];
    const Side& b = sides[1];
    if (std::memcmp(a.uv0, b.uv0, 8) == 0 && std::memcmp(a.uv1, b.uv1, 8) == 0) continue;  // one chart's inside edge
    ++st.edges;
    const double lenA = std::hypot((a.uv1[0] - a.uv0[0]) * W, (a.uv1[1] - a.uv0[1]) * H);
    const double lenB = std::hypot((b.uv1[0] - b.uv0[0]) * W, (b.uv1[1] - b.uv0[1]) * H);
    // Two points per texel of the longer side, at most as many as the map's perimeter holds
    // (an edge that long lies mostly outside the map).
    const int k = std::max(2, int(std::ceil(2 * std::min(std::max(lenA, lenB), 2.0 * (W + H)))));
    for (int q = 0; q < k; ++q) {
      const double t = (q + 0.5) / k;
      std::array<Tap, 8> row;
      taps(a.uv0[0] + t * (a.uv1[0] - a.uv0[0]), a.uv0[1] + t * (a.uv1[1] - a.uv0[1]), 1, &row[0]);
      taps(b.uv0[0] + t * (b.uv1[0] - b.uv0[0]), b.uv0[1] + t * (b.uv1[1] - b.uv0[1]), -1, &row[4]);
      rows.push_back(row);
    }
  }
  if (rows.empty() || planes.empty()) return st;
  // The unknowns: every texel a constraint reads, numbered.
  std::unordered_map<uint32_t, uint32_t> index;
  std::vector<uint32_t> texel;
  for (const auto& row : rows)
    for (const Tap& tp : row)
      if (index.emplace(tp.texel, uint32_t(texel.size())).second) texel.push_back(tp.texel);
  const size_t n = texel.size();
  std::vector<double> lambda(n);
  for (size_t i = 0; i < n; ++i) lambda[i] = lm.valid(texel[i]) ? kSeamDataWeight : kSeamFreeWeight;
  auto apply = [&](const std::vector<double>& x, std::vector<double>& y) {  // y = (SᵀS + Λ) x
    for (size_t i = 0; i < n; ++i) y[i] = lambda[i] * x[i];
    for (const auto& row : rows) {
      double r = 0;
      for (const Tap& tp : row) r += tp.w * x[index[tp.texel]];
      for (const Tap& tp : row) y[index[tp.texel]] += tp.w * r;
    }
  };
  auto worstJump = [&](const std::vector<float>& plane, int width) {
    double worst = 0;
    for (const auto& row : rows) {
      double r = 0;
      for (const Tap& tp : row) r += tp.w * plane[size_t(tp.texel) * width];
      worst = std::max(worst, std::abs(r));
    }
    return worst;
  };
  st.jumpBefore = worstJump(*planes[0], widths[0]);
  std::vector<double> x(n), b(n), r(n), p(n), ap(n);
  for (size_t pl = 0; pl < planes.size(); ++pl)
    for (int c = 0; c < widths[pl]; ++c) {
      std::vector<float>& plane = *planes[pl];
      const size_t w = size_t(widths[pl]);
      for (size_t i = 0; i < n; ++i) x[i] = plane[texel[i] * w + c], b[i] = lambda[i] * x[i];
      apply(x, ap);
      double rr = 0, bb = 0;
      for (size_t i = 0; i < n; ++i) r[i] = b[i] - ap[i], p[i] = r[i], rr += r[i] * r[i], bb += b[i] * b[i];
      for (int it = 0; it < 1000 && rr > 1e-20 * std::max(bb, 1e-30); ++it) {
        apply(p, ap);
        double pap = 0;
        for (size_t i = 0; i < n; ++i) pap += p[i] * ap[i];
        const double alpha = rr / pap;
        double next = 0;
        for (size_t i = 0; i < n; ++i) x[i] += alpha * p[i], r[i] -= alpha * ap[i], next += r[i] * r[i];
        for (size_t i = 0; i < n; ++i) p[i] = r[i] + next / rr * p[i];
        rr = next;
      }
      for (size_t i = 0; i < n; ++i) plane[texel[i] * w + c] = float(x[i]);
    }
  st.jumpAfter = worstJump(*planes[0], widths[0]);
  return st;
}

// The tangent frame of a sample (glTF's: the interpolated tangent made orthogonal to the unit
// normal n, bitangent w n × t with w the sign of the interpolated handedness), appended to
// `frames` as t, b; zeros where the tangents give no direction off n.
void tangentFrame(const Mesh& mesh, const TexelHit& h, const float* n, std::vector<float>& frames) {
  double t[3] = {0, 0, 0}, w = 0;
  for (int k = 0; k < 3; ++k) {
    const float* q = &mesh.tangents[4 * size_t(mesh.indices[3 * size_t(h.tri) + k])];
    for (int c = 0; c < 3; ++c) t[c] += h.w[k] * q[c];
    w += h.w[k] * q[3];
  }
  const double d = t[0] * n[0] + t[1] * n[1] + t[2] * n[2];
  for (int c = 0; c < 3; ++c) t[c] -= d * n[c];
  const double len = std::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
  const double s = len > 1e-9 ? 1 / len : 0.0, sign = w < 0 ? -1.0 : 1.0;
  for (double& c : t) c *= s;
  const double b[3] = {sign * (n[1] * t[2] - n[2] * t[1]), sign * (n[2] * t[0] - n[0] * t[2]),
                       sign * (n[0] * t[1] - n[1] * t[0])};
  for (double c : t) frames.push_back(float(c));
  for (double c : b) frames.push_back(float(c));
}

// The sh product (lightmap.h): the glossy transfer matrices M at the samples, block by block,
// reduced at once to D_j = (Â_l/π) Σ_i M_ji l_i per channel (memory: one block of matrices).
void bakeSh(Runtime& rt, const Mesh& mesh, const SurfacePoints& pts, const std::vector<uint32_t>& texelOf,
            const ShCoeffs& env, const LightmapOptions& o, LightmapResult& lm) {
  GlossyOptions g;
  g.mode = o.bounces > 0 ? TransportMode::Interreflected : TransportMode::Shadowed;
  g.bounces = std::max(o.bounces, 1);
  g.orderOut = o.shOrder;
  g.orderIn = std::max(kMinGlossyOrder, o.order);
  g.samples = o.samples;
  g.seed = o.seed;
  g.albedoOverride = o.albedoOverride;
  const int no2 = g.orderOut * g.orderOut, ni2 = g.orderIn * g.orderIn;
  const int ne = std::min(ni2, env.order * env.order), ch = glossyChannels(mesh, g);
  std::vector<double> factor(size_t(no2), 0.0);
  for (int j = 0; j < no2; ++j) factor[size_t(j)] = clampedCosineFactor(int(std::sqrt(double(j)) + 1e-9)) / kPi;
  lm.shOrder = o.shOrder;
  lm.sh.assign(lm.texels() * size_t(no2) * 3, 0.0f);
  const GlossyStats st = bakeGlossyTransferAtPoints(rt, mesh, pts, g, [&](size_t first, size_t count, const float* M) {
    for (size_t i = 0; i < count; ++i) {
      float* d = &lm.sh[size_t(texelOf[first + i]) * no2 * 3];
      for (int c = 0; c < 3; ++c) {
        const float* Mc = M + (i * ch + (ch == 3 ? c : 0)) * size_t(no2) * ni2;
        for (int j = 0; j < no2; ++j) {
          double sum = 0;
          for (int k = 0; k < ne; ++k) sum += double(Mc[size_t(j) * ni2 + k]) * env.rgb[size_t(k)][c];
          d[3 * j + c] = float(factor[size_t(j)] * sum);
        }
      }
    }
  });
  lm.rays += st.rays;
  if (lm.samples == 0 || o.products == kLightmapSh) lm.samples = o.samples;
  if (o.products == kLightmapSh) lm.maxStdError = st.maxStdError, lm.meanStdError = st.meanStdError;
}

}  // namespace

unsigned parseLightmapProducts(const std::string& list) {
  unsigned bits = 0;
  size_t start = 0;
  while (start <= list.size()) {
    const size_t end = std::min(list.find(',', start), list.size());
    const std::string name = list.substr(start, end - start);
    if (name == "ao") bits |= kLightmapAo;
    else if (name == "bent") bits |= kLightmapBent;
    else if (name == "irradiance") bits |= kLightmapIrradiance;
    else if (name == "transport") bits |= kLightmapTransport;
    else if (name == "sh") bits |= kLightmapSh;
    else throw UsageError("--products", "unknown product '" + name + "' (expected ao, bent, irradiance, transport, sh)");
    start = end + 1;
  }
  return bits;
}

std::string lightmapProductsName(unsigned products) {
  std::string s;
  for (auto [bit, name] : {std::pair{kLightmapAo, "ao"}, {kLightmapBent, "bent"}, {kLightmapIrradiance, "irradiance"},
                           {kLightmapTransport, "transport"}, {kLightmapSh, "sh"}})
    if (products & bit) s += (s.empty() ? "" : ",") + std::string(name);
  return s;
}

int lightmapSize(const Mesh& mesh, const LightmapOptions& o) {
  if (o.size != 0 && (o.size < 1 || o.size > kMaxLightmapSize))
    throw UsageError("--size", std::to_string(o.size) + " is out of range [1, " + std::to_string(kMaxLightmapSize) + "]");
  if (!(o.texelsPerUnit >= 0) || !std::isfinite(o.texelsPerUnit))
    throw UsageError("--texels-per-unit", "must be a finite number > 0");
  if (o.size != 0 && o.texelsPerUnit > 0) throw UsageError("--texels-per-unit", "cannot be combined with --size");
  if (o.size != 0) return o.size;
  if (o.texelsPerUnit == 0) return 512;
  const int set = resolveUvSet(mesh, o.uvSet);
  const std::vector<float>& uv = mesh.uvs[size_t(set)];
  double area3 = 0, areaUv = 0;
  for (size_t t = 0; t < mesh.triangleCount(); ++t) {
    double a = 0;
    faceNormalOf(mesh, t, &a);
    area3 += a;
    const uint32_t i = mesh.indices[3 * t], j = mesh.indices[3 * t + 1], k = mesh.indices[3 * t + 2];
    areaUv += std::abs(cross2(uv[2 * j] - uv[2 * i], uv[2 * j + 1] - uv[2 * i + 1], uv[2 * k] - uv[2 * i],
                              uv[2 * k + 1] - uv[2 * i + 1])) / 2;
  }
  if (!(areaUv > 0)) throw InputError(subjectOf(mesh), "UV set " + std::to_string(set) + " covers no area");
  const double side = o.texelsPerUnit * std::sqrt(area3 / areaUv);
  if (!(side <= kMaxLightmapSize))
    throw UsageError("--texels-per-unit", "gives a " + std::to_string(int64_t(std::min(side, 1e15))) + "-texel side (at most " +
                                              std::to_string(kMaxLightmapSize) + ")");
  return std::max(4, int(std::ceil(side / 4)) * 4);
}

// The bake's peak memory, fitted to peaks measured at 512² to 4096² (docs/lightmap.md, "Memory"):
// the runtime's memory (kRuntimeMemoryBytes), 320 bytes a texel for the samples, their rays' set-up and the
// device's copies, and 12 bytes for each float a texel holds (its products and the transport
// they come from, four sets of it with bounces: the device's, the host's and the map's copies).
// It errs high, by up to 2x for sh.
double lightmapPeakBytes(const LightmapOptions& o, int W, int H) {
  const double nc = double(o.order) * o.order;
  double floats = 0;
  if (o.products & (kLightmapAo | kLightmapBent)) floats += 5 + (o.products & kLightmapBent ? 6 : 0);
  if (o.products & (kLightmapIrradiance | kLightmapTransport | kLightmapSh)) floats += nc * (o.bounces > 0 ? 4 : 1);
  if (o.products & kLightmapIrradiance) floats += 3;
  if (o.products & kLightmapTransport) floats += nc;
  if (o.products & kLightmapSh) floats += 3.0 * o.shOrder * o.shOrder;
  return kRuntimeMemoryBytes + double(W) * H * (320 + 12 * floats);
}

LightmapSamples lightmapSamples(const Mesh& mesh, const LightmapOptions& o) {
  const auto tStart = Clock::now();
  validateMesh(mesh, subjectOf(mesh));
  LightmapSamples out;
  LightmapResult& lm = out.lm;
  lm.products = o.products;
  lm.uvSet = resolveUvSet(mesh, o.uvSet);
  lm.width = lm.height = lightmapSize(mesh, o);
  checkProcessMemory(o.size ? "--size" : "--texels-per-unit",
                     "a lightmap of " + std::to_string(lm.width) + "x" + std::to_string(lm.height) + " texels with " +
                         lightmapProductsName(o.products) +
                         (o.products & ~(kLightmapAo | kLightmapBent) ? " at order " + std::to_string(o.order) : ""),
                     lightmapPeakBytes(o, lm.width, lm.height));
  lm.samples = o.samples;
  const int W = lm.width, H = lm.height;
  const std::vector<float>& uv = mesh.uvs[size_t(lm.uvSet)];

  // Triangles that can hold a sample: positive area in UV and in space.
  const size_t nt = mesh.triangleCount();
  std::vector<char>& usable = out.usable;
  usable.assign(nt, 0);
  std::vector<double> worldPerTexel(nt, 0.0);
  for (size_t t = 0; t < nt; ++t) {
    const uint32_t i = mesh.indices[3 * t], j = mesh.indices[3 * t + 1], k = mesh.indices[3 * t + 2];
    const double uvArea = std::abs(cross2(double(uv[2 * j] - uv[2 * i]) * W, double(uv[2 * j + 1] - uv[2 * i + 1]) * H,
                                          double(uv[2 * k] - uv[2 * i]) * W, double(uv[2 * k + 1] - uv[2 * i + 1]) * H)) / 2;
    double area = 0;
    faceNormalOf(mesh, t, &area);
    usable[t] = uvArea > 1e-12 && area > 0;
    lm.degenerateTriangles += usable[t] ? 0 : 1;
    if (usable[t]) worldPerTexel[t] = std::sqrt(area / uvArea);
  }
  if (lm.degenerateTriangles == nt)
    throw InputError(subjectOf(mesh), "no triangle has a positive area in UV set " + std::to_string(lm.uvSet) +
                                          " and in space: nothing to bake");
  Charts charts = findCharts(mesh, uv, usable);
  std::vector<TexelHit> hits;
  rasterise(mesh, uv, W, H, usable, charts, hits);
  for (size_t t = 0; t < nt; ++t) lm.charts += usable[t] && charts.find(uint32_t(t)) == t;

  // The samples (and with tangents, each one's tangent frame t, b: 6 floats).
  SurfacePoints& pts = out.points;
  std::vector<float>& frames = out.tangentFrames;
  std::vector<uint32_t>& texelOf = out.texelOf;
  std::vector<float>& reach = out.reach;
  for (size_t i = 0; i < hits.size(); ++i) {
    const TexelHit& h = hits[i];
    if (h.tri < 0) continue;
    texelOf.push_back(uint32_t(i));
    lm.centreOutside += h.inside ? 0 : 1;
    lm.contested += h.contested ? 1 : 0;
    double area = 0;
    const auto fn = faceNormalOf(mesh, size_t(h.tri), &area);
    double n[3] = {0, 0, 0}, p[3] = {0, 0, 0};
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = mesh.indices[3 * size_t(h.tri) + k];
      for (int c = 0; c < 3; ++c) n[c] += h.w[k] * mesh.normals[3 * v + c], p[c] += h.w[k] * mesh.positions[3 * v + c];
    }
    for (double c : p) pts.positions.push_back(float(c));
    double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(len > 1e-12)) n[0] = fn[0], n[1] = fn[1], n[2] = fn[2], len = 1;
    for (int c = 0; c < 3; ++c) pts.normals.push_back(float(n[c] / len)), pts.faceNormals.push_back(float(fn[c]));
    if (!mesh.tangents.empty()) tangentFrame(mesh, h, &pts.normals[pts.normals.size() - 3], frames);
    // The texel's half-width: a sample moves out only where the texel's own area reaches outside.
    reach.push_back(float(0.5 * worldPerTexel[size_t(h.tri)]));
  }
  lm.state.assign(lm.texels(), uint8_t(TexelState::Empty));
  for (uint32_t i : texelOf) lm.state[i] = uint8_t(TexelState::Baked);
  lm.rasterSeconds = secondsSince(tStart);
  return out;
}

namespace {

// A split bake's shard: the samples [first, first + count) alone, each keeping its index in the
// whole set (its rays), the other texels Empty.
void keepSampleRange(LightmapSamples& s, const LightmapOptions& o) {
  const size_t first = o.sampleRange->first, count = o.sampleRange->second;  // (lambdas cannot capture bindings in C++17)
  const size_t total = s.texelOf.size();
  if (first > total || count > total - first)
    throw UsageError("sample range", "[" + std::to_string(first) + ", " + std::to_string(first + count) + ") is not within the " +
                                         std::to_string(total) + " samples");
  if (o.tolerance > 0)
    throw UsageError("tolerance", "a split bake takes a fixed number of samples (each shard's pilot would see other texels)");
  auto slice = [&](auto& v, size_t per) {
    if (v.empty()) return;
    v.erase(v.begin() + ptrdiff_t((first + count) * per), v.end());
    v.erase(v.begin(), v.begin() + ptrdiff_t(first * per));
  };
  slice(s.points.positions, 3), slice(s.points.normals, 3), slice(s.points.faceNormals, 3);
  s.points.firstIndex = first;
  slice(s.texelOf, 1), slice(s.reach, 1), slice(s.tangentFrames, 6);
  s.lm.state.assign(s.lm.texels(), uint8_t(TexelState::Empty));
  for (uint32_t t : s.texelOf) s.lm.state[t] = uint8_t(TexelState::Baked);
}

}  // namespace

void repairLightmap(const Mesh& mesh, const LightmapOptions& o, const std::vector<char>& usable, LightmapResult& lm) {
  if (usable.size() != mesh.triangleCount() || !mesh.hasUvSet(lm.uvSet) || lm.state.size() != lm.texels())
    throw UsageError("lightmap", "the repairs need the mesh, its usable triangles and the lightmap they were baked with");
  const std::vector<float>& uv = mesh.uvs[size_t(lm.uvSet)];
  const auto tRepair = Clock::now();
  std::vector<std::vector<float>*> planes;
  std::vector<int> widths;
  auto add = [&](std::vector<float>& p, int c) {
    if (!p.empty()) planes.push_back(&p), widths.push_back(c);
  };
  add(lm.ao, 1);
  add(lm.bent, 3);
  add(lm.irradiance, 3);
  add(lm.transport, lm.transportChannels * lm.order * lm.order);
  add(lm.sh, 3 * lm.shOrder * lm.shOrder);
  // Tangent frames may differ across a UV seam: the tangent-space bent normal is dilated, not stitched.
  std::vector<std::vector<float>*> dilated = planes;
  std::vector<int> dilatedWidths = widths;
  if (!lm.bentTangent.empty()) dilated.push_back(&lm.bentTangent), dilatedWidths.push_back(3);
  for (size_t k = 0; k < dilated.size(); ++k)
    if (dilatedWidths[k] < 1 || dilated[k]->size() != lm.texels() * size_t(dilatedWidths[k]))
      throw UsageError("lightmap", "a product's plane does not hold its values for every texel");
  dilate(lm, o.dilation, dilated, dilatedWidths);
  if (o.stitchSeams) {
    const SeamStats seams = stitchSeams(mesh, uv, usable, lm, planes, widths);
    lm.seamEdges = seams.edges, lm.seamJumpBefore = seams.jumpBefore, lm.seamJumpAfter = seams.jumpAfter;
  }
  // Dilated and stitched bent normals are means of unit vectors: renormalised.
  for (std::vector<float>* plane : {&lm.bent, &lm.bentTangent})
    for (size_t i = 0; i < plane->size() / 3; ++i) {
      float* b = &(*plane)[3 * i];
      const double len = std::sqrt(double(b[0]) * b[0] + double(b[1]) * b[1] + double(b[2]) * b[2]);
      if (len > 0)
        for (int c = 0; c < 3; ++c) b[c] = float(b[c] / len);
    }
  lm.repairSeconds = secondsSince(tRepair);
}

LightmapResult computeLightmap(Runtime& rt, const Mesh& mesh, const ShCoeffs& env, const LightmapOptions& o) {
  const auto tStart = Clock::now();
  if (o.products == 0 || (o.products & ~kLightmapAllProducts)) throw UsageError("--products", "no product asked for");
  if (o.products & kLightmapSh) {
    if (o.shOrder != 2 && o.shOrder != 3) throw UsageError("--sh-order", "must be 2 (L1) or 3 (L2)");
    if (o.order > kMaxGlossyOrder)
      throw UsageError("--order", "the sh product takes environment orders up to " + std::to_string(kMaxGlossyOrder));
  }
  if (o.dilation < 0 || o.dilation > 4096) throw UsageError("--dilation", "must lie in [0, 4096]");
  if (o.bounces < 0 || o.bounces > 16) throw UsageError("--bounces", "must lie in [0, 16]");
  if (o.maxDistance != 0 && !(o.maxDistance > 0 && std::isfinite(o.maxDistance)))
    throw UsageError("--max-distance", "must be a finite number > 0");
  LightmapSamples samples = lightmapSamples(mesh, o);
  if (o.sampleRange) keepSampleRange(samples, o);
  LightmapResult& lm = samples.lm;
  lm.device = rt.deviceLabel();
  SurfacePoints& pts = samples.points;
  const std::vector<uint32_t>& texelOf = samples.texelOf;
  const std::vector<float>& frames = samples.tangentFrames;
  const std::vector<char>& usable = samples.usable;

  if (o.unocclude) {
    const auto t0 = Clock::now();
    const std::vector<uint8_t> s = unocclude(rt, mesh, pts, samples.reach);
    for (size_t i = 0; i < s.size(); ++i)
      if (s[i]) lm.state[texelOf[i]] = uint8_t(s[i] == 1 ? TexelState::Moved : TexelState::Buried);
    lm.unoccludeSeconds = secondsSince(t0);
  }
  for (uint32_t i : texelOf) {
    const auto st = TexelState(lm.state[i]);
    lm.baked += st == TexelState::Baked, lm.moved += st == TexelState::Moved, lm.buried += st == TexelState::Buried;
  }

  // The bake: ao and bent from shadowed transport of order 2 (or 1) within the range D;
  // irradiance and transport from the transport of order n (interreflected with bounces). One
  // pass serves both when D is the whole scene and nothing bounces.
  const auto tBake = Clock::now();
  const bool wantAo = o.products & (kLightmapAo | kLightmapBent);
  const bool wantLight = o.products & (kLightmapIrradiance | kLightmapTransport);
  if (o.order < 1 || o.order > kMaxTransportOrder)
    throw UsageError("--order", std::to_string(o.order) + " is out of range [1, " + std::to_string(kMaxTransportOrder) + "]");
  TransportOptions base;
  base.samples = o.samples;
  base.seed = o.seed;
  base.tolerance = o.tolerance;
  base.toleranceMaxSamples = o.toleranceMaxSamples;
  base.albedoOverride = o.albedoOverride;
  base.packetWidth = o.packetWidth;
  const bool shared = wantAo && wantLight && o.maxDistance == 0 && o.bounces == 0;
  const size_t ns = pts.count();
  auto run = [&](TransportOptions to) {
    const TransportResult r = computeTransportAtPoints(rt, mesh, pts, to);
    lm.rays += r.rays;
    return r;
  };
  if (wantAo) {
    TransportOptions to = base;
    to.mode = TransportMode::Shadowed;
    to.order = std::max(o.products & kLightmapBent ? 2 : 1, shared ? o.order : 1);
    to.maxDistance = o.maxDistance;
    const TransportResult r = run(to);
    lm.maxStdError = r.maxStdError, lm.meanStdError = r.meanStdError;
    lm.samples = r.samples;
    const int nc = to.order * to.order;
    const double y0 = 1 / (2 * std::sqrt(kPi));
    double ax[4], ay[4], az[4];  // the order-2 basis at the axes: Y_1m = a · (x, y or z)
    shEval(2, 1, 0, 0, ax), shEval(2, 0, 1, 0, ay), shEval(2, 0, 0, 1, az);
    if (o.products & kLightmapAo) lm.ao.assign(lm.texels(), 0.0f);
    if (o.products & kLightmapBent) lm.bent.assign(lm.texels() * 3, 0.0f);
    if ((o.products & kLightmapBent) && !frames.empty()) lm.bentTangent.assign(lm.texels() * 3, 0.0f);
    for (size_t i = 0; i < ns; ++i) {
      const float* T = r.vertex(i);
      if (o.products & kLightmapAo) lm.ao[texelOf[i]] = float(std::clamp(T[0] / y0, 0.0, 1.0));
      if (o.products & kLightmapBent) {
        double b[3] = {T[3] / ax[3], T[1] / ay[1], T[2] / az[2]};
        const double len = std::sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
        float* B = &lm.bent[3 * size_t(texelOf[i])];
        for (int c = 0; c < 3; ++c) B[c] = len > 1e-9 ? float(b[c] / len) : pts.normals[3 * i + c];
        if (!frames.empty()) {
          const float *t = &frames[6 * i], *bt = t + 3, *n = &pts.normals[3 * i];
          float* out = &lm.bentTangent[3 * size_t(texelOf[i])];
          out[0] = B[0] * t[0] + B[1] * t[1] + B[2] * t[2];
          out[1] = B[0] * bt[0] + B[1] * bt[1] + B[2] * bt[2];
          out[2] = B[0] * n[0] + B[1] * n[1] + B[2] * n[2];
        }
      }
    }
    if (shared) {
      lm.order = o.order;
      if (o.products & kLightmapTransport) lm.transport.assign(lm.texels() * size_t(nc), 0.0f);
      if (o.products & kLightmapIrradiance) lm.irradiance.assign(lm.texels() * 3, 0.0f);
      for (size_t i = 0; i < ns; ++i) {
        const float* T = r.vertex(i);
        if (o.products & kLightmapTransport) std::copy_n(T, nc, &lm.transport[size_t(texelOf[i]) * nc]);
        if (o.products & kLightmapIrradiance)
          for (int c = 0; c < 3; ++c) {
            double e = 0;
            for (int k = 0; k < std::min(nc, env.order * env.order); ++k) e += env.rgb[size_t(k)][c] * T[k];
            lm.irradiance[3 * size_t(texelOf[i]) + c] = float(e);
          }
      }
    }
  }
  if (wantLight && !shared) {
    TransportOptions to = base;
    to.mode = o.bounces > 0 ? TransportMode::Interreflected : TransportMode::Shadowed;
    to.bounces = std::max(o.bounces, 1);
    to.order = o.order;
    const TransportResult r = run(to);
    if (!wantAo) lm.maxStdError = r.maxStdError, lm.meanStdError = r.meanStdError, lm.samples = r.samples;
    const int nc = o.order * o.order, ch = r.channels;
    lm.order = o.order;
    lm.transportChannels = ch;
    if (o.products & kLightmapTransport) lm.transport.assign(lm.texels() * size_t(ch * nc), 0.0f);
    if (o.products & kLightmapIrradiance) lm.irradiance.assign(lm.texels() * 3, 0.0f);
    for (size_t i = 0; i < ns; ++i) {
      const float* T = r.vertex(i);
      if (o.products & kLightmapTransport) std::copy_n(T, ch * nc, &lm.transport[size_t(texelOf[i]) * ch * nc]);
      if (o.products & kLightmapIrradiance)
        for (int c = 0; c < 3; ++c) {
          const float* Tc = T + (ch == 3 ? c * nc : 0);
          double e = 0;
          for (int k = 0; k < std::min(nc, env.order * env.order); ++k) e += env.rgb[size_t(k)][c] * Tc[k];
          lm.irradiance[3 * size_t(texelOf[i]) + c] = float(e);
        }
    }
  }
  if (o.products & kLightmapSh) bakeSh(rt, mesh, pts, texelOf, env, o, lm);
  if (lm.order == 0) lm.order = o.order;
  lm.bakeSeconds = secondsSince(tBake);

  if (!o.sampleRange) repairLightmap(mesh, o, usable, lm);
  lm.totalSeconds = secondsSince(tStart);
  return lm;
}


}  // namespace prtbake
