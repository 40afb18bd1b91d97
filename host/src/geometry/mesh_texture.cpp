// A mesh's albedo from colour textures (mesh_texture.h).
#include "geometry/mesh_texture.h"

#include <algorithm>
#include <cmath>

namespace prtbake::detail {
namespace {

// The most samples the uses of one image take together, and the most a triangle takes: 2^24
// bilinear samples are about 0.6 s here (100k triangles that each cover a 64² image nine times
// took 2.4 s at 2^26).
constexpr double kTextureSampleBudget = 16777216.0;
constexpr int kMaxSamplesPerSide = 64;

// The image sampled bilinearly as a renderer samples level 0, with the wrap modes.
struct Sampler {
  const Image& img;
  Wrap wrapS, wrapT;

  double texel(int x, int y, int c) const {
    const size_t i = 3 * (size_t(y) * size_t(img.width) + size_t(x)) + size_t(c);
    return img.codes ? img.codeToLinear[img.codes.get()[i]] : img.rgb[i];
  }
  // A texel index in [-1, n] onto [0, n).
  static int wrapIndex(int i, int n, Wrap w) {
    if (i >= 0 && i < n) return i;
    if (w == Wrap::Repeat) return (i + n) % n;
    return i < 0 ? 0 : n - 1;  // clamped, or mirrored at the edge
  }
  // A coordinate onto [0, 1] (a repeat onto [0, 1)); any finite value, however large.
  static double wrapCoord(double u, Wrap w) {
    if (w == Wrap::Clamp) return std::clamp(u, 0.0, 1.0);
    if (w == Wrap::Repeat) return u - std::floor(u);
    const double t = u - 2.0 * std::floor(0.5 * u);  // [0, 2)
    return t > 1.0 ? 2.0 - t : t;
  }
  void sample(double u, double v, double rgb[3]) const {
    const double fx = wrapCoord(u, wrapS) * img.width - 0.5, fy = wrapCoord(v, wrapT) * img.height - 0.5;
    const double x0 = std::floor(fx), y0 = std::floor(fy), tx = fx - x0, ty = fy - y0;
    const int xa = wrapIndex(int(x0), img.width, wrapS), xb = wrapIndex(int(x0) + 1, img.width, wrapS);
    const int ya = wrapIndex(int(y0), img.height, wrapT), yb = wrapIndex(int(y0) + 1, img.height, wrapT);
    for (int c = 0; c < 3; ++c)
      rgb[c] = (1 - ty) * ((1 - tx) * texel(xa, ya, c) + tx * texel(xb, ya, c)) +
               ty * ((1 - tx) * texel(xa, yb, c) + tx * texel(xb, yb, c));
  }
};

}  // namespace

std::vector<std::array<double, 3>> textureMeans(const Image& image, const std::vector<TextureUse>& uses) {
  // The samples each triangle asks for: one a texel of its footprint.
  std::vector<double> wanted;
  double total = 0;
  const double most = double(kMaxSamplesPerSide * kMaxSamplesPerSide);
  for (const TextureUse& use : uses)
    for (size_t t = 0; t < use.triangles.size(); ++t) {
      const double* q = &use.uv[6 * t];
      const double area = 0.5 * std::abs((q[2] - q[0]) * (q[5] - q[1]) - (q[3] - q[1]) * (q[4] - q[0])) *
                          double(image.width) * double(image.height);
      wanted.push_back(std::isnan(area) ? most : std::clamp(std::ceil(area), 1.0, most));
      total += wanted.back();
    }
  const double scale = std::min(1.0, kTextureSampleBudget / total);
  std::vector<std::array<double, 3>> means;
  means.reserve(wanted.size());
  for (const TextureUse& use : uses) {
    const Sampler sampler{image, use.wrapS, use.wrapT};
    for (size_t t = 0; t < use.triangles.size(); ++t) {
      const double* q = &use.uv[6 * t];
      const int k = int(std::ceil(std::sqrt(std::max(1.0, std::floor(wanted[means.size()] * scale)))));
      std::array<double, 3> mean{0, 0, 0};
      // The centroids of the k² sub-triangles, as barycentric weights (s, r) of corners 1 and 2.
      auto add = [&](double s, double r) {
        const double w = 1 - s - r;
        double rgb[3];
        sampler.sample(w * q[0] + s * q[2] + r * q[4], w * q[1] + s * q[3] + r * q[5], rgb);
        for (int c = 0; c < 3; ++c) mean[size_t(c)] += rgb[c];
      };
      for (int i = 0; i < k; ++i)
        for (int j = 0; i + j < k; ++j) {
          add((i + 1.0 / 3.0) / k, (j + 1.0 / 3.0) / k);
          if (i + j + 2 <= k) add((i + 2.0 / 3.0) / k, (j + 2.0 / 3.0) / k);
        }
      for (double& m : mean) m /= double(k) * k;
      means.push_back(mean);
    }
  }
  return means;
}

void multiplyAlbedo(Mesh& mesh, const std::vector<std::array<double, 3>>& triangleAlbedo, const std::vector<char>& has) {
  // Per vertex: the area-weighted sums, and plain sums for a vertex of zero-area triangles only.
  std::vector<double> weighted(4 * mesh.vertexCount(), 0.0), plain(4 * mesh.vertexCount(), 0.0);
  for (size_t t = 0; t < mesh.triangleCount(); ++t) {
    if (!has[t]) continue;
    const uint32_t* c = &mesh.indices[3 * t];
    const float* p0 = &mesh.positions[3 * size_t(c[0])];
    const float* p1 = &mesh.positions[3 * size_t(c[1])];
    const float* p2 = &mesh.positions[3 * size_t(c[2])];
    const double e1[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
    const double e2[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
    const double x = e1[1] * e2[2] - e1[2] * e2[1], y = e1[2] * e2[0] - e1[0] * e2[2], z = e1[0] * e2[1] - e1[1] * e2[0];
    const double area = 0.5 * std::sqrt(x * x + y * y + z * z);
    for (int corner = 0; corner < 3; ++corner) {
      const size_t v = c[corner];
      for (size_t ch = 0; ch < 3; ++ch) {
        weighted[4 * v + ch] += area * triangleAlbedo[t][ch];
        plain[4 * v + ch] += triangleAlbedo[t][ch];
      }
      weighted[4 * v + 3] += area;
      plain[4 * v + 3] += 1;
    }
  }
  for (size_t v = 0; v < mesh.vertexCount(); ++v) {
    const double* sum = weighted[4 * v + 3] > 0 ? &weighted[4 * v] : &plain[4 * v];
    if (sum[3] > 0)
      for (size_t ch = 0; ch < 3; ++ch) mesh.albedo[3 * v + ch] *= float(sum[ch] / sum[3]);
  }
}

}  // namespace prtbake::detail
