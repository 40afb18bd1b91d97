// Preview of a prefiltered chain: its levels as lat-long panels and a row of split-sum spheres.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/constants.h"
#include "prefilter/prefilter_detail.h"
#include "prtbake/error.h"
#include "prtbake/lut.h"
#include "prtbake/preview.h"

namespace prtbake {
namespace {

constexpr int kSpheres = 6;

// Bilinear lookup of a level at unit direction d (texels clamped at face edges).
void sampleLevel(const PrefilterLevel& l, const double d[3], double rgb[3]) {
  const int n = l.spec.size;
  int f;
  double u, v;
  detail::cubeFaceUv(d, &f, &u, &v);
  const double x = std::clamp((u + 1) * 0.5 * n - 0.5, 0.0, double(n - 1)), y = std::clamp((v + 1) * 0.5 * n - 0.5, 0.0, double(n - 1));
  const int x0 = int(x), y0 = int(y), x1 = std::min(n - 1, x0 + 1), y1 = std::min(n - 1, y0 + 1);
  const double fx = x - x0, fy = y - y0;
  auto at = [&](int yy, int xx, int c) { return double(l.rgb[3 * ((size_t(f) * size_t(n) + size_t(yy)) * size_t(n) + size_t(xx)) + size_t(c)]); };
  for (int c = 0; c < 3; ++c)
    rgb[c] = (1 - fy) * ((1 - fx) * at(y0, x0, c) + fx * at(y0, x1, c)) + fy * ((1 - fx) * at(y1, x0, c) + fx * at(y1, x1, c));
}

// P at direction d and roughness r: between the two levels whose roughness brackets r.
void sampleChain(const PrefilterResult& chain, const double d[3], double r, double rgb[3]) {
  const auto& lv = chain.levels;
  size_t i = 0;
  while (i + 1 < lv.size() && lv[i + 1].spec.roughness <= r) ++i;
  sampleLevel(lv[i], d, rgb);
  if (i + 1 < lv.size() && lv[i + 1].spec.roughness > lv[i].spec.roughness && r > lv[i].spec.roughness) {
    const double t = std::min(1.0, (r - lv[i].spec.roughness) / (lv[i + 1].spec.roughness - lv[i].spec.roughness));
    double b[3];
    sampleLevel(lv[i + 1], d, b);
    for (int c = 0; c < 3; ++c) rgb[c] = (1 - t) * rgb[c] + t * b[c];
  }
}

double lutAt(const std::vector<float>& table, int n, double mu, double r) {
  const double x = std::clamp(mu * n - 0.5, 0.0, double(n - 1)), y = std::clamp(r * n - 0.5, 0.0, double(n - 1));
  const int x0 = int(x), y0 = int(y), x1 = std::min(n - 1, x0 + 1), y1 = std::min(n - 1, y0 + 1);
  const double fx = x - x0, fy = y - y0;
  auto at = [&](int yy, int xx) { return double(table[size_t(yy) * size_t(n) + size_t(xx)]); };
  return (1 - fy) * ((1 - fx) * at(y0, x0) + fx * at(y0, x1)) + fy * ((1 - fx) * at(y1, x0) + fx * at(y1, x1));
}

void put(LinearImage& img, int x, int y, const double rgb[3]) {
  if (x < 0 || y < 0 || x >= img.width || y >= img.height) return;
  for (int c = 0; c < 3; ++c) img.rgb[3 * (size_t(y) * size_t(img.width) + size_t(x)) + size_t(c)] = float(rgb[c]);
}

}  // namespace

LinearImage renderSplitSumSphere(const PrefilterResult& chain, const LutResult& lut, double roughness, int size,
                                 std::vector<bool>* mask) {
  if (chain.levels.empty()) throw UsageError("preview", "empty chain");
  if (size < 1 || size > 8192) throw UsageError("preview", "sphere size must be in [1, 8192]");
  LinearImage img;
  img.width = img.height = size;
  img.rgb.assign(size_t(size) * size_t(size) * 3, 0.0f);
  if (mask) mask->assign(size_t(size) * size_t(size), false);
  const double rad = 0.5 * size;
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      const double nx = (x + 0.5 - rad) / rad, ny = -(y + 0.5 - rad) / rad, q = 1 - nx * nx - ny * ny;
      if (q <= 0) continue;
      const double n[3] = {nx, ny, std::sqrt(q)}, mu = n[2];
      const double refl[3] = {2 * mu * n[0], 2 * mu * n[1], 2 * mu * n[2] - 1};
      double rgb[3];
      double scale = 1;
      if (chain.options.lobe == PrefilterLobe::Lambertian) {
        sampleLevel(chain.levels[0], n, rgb);
      } else {
        sampleChain(chain, refl, roughness, rgb);
        scale = lut.options.cloth ? lutAt(lut.third, lut.size, mu, roughness)
                                  : lutAt(lut.a, lut.size, mu, roughness) + lutAt(lut.b, lut.size, mu, roughness);
      }
      for (double& c : rgb) c *= scale;
      put(img, x, y, rgb);
      if (mask) (*mask)[size_t(y) * size_t(size) + size_t(x)] = true;
    }
  return img;
}

LinearImage renderPrefilterPreview(Runtime& rt, const PrefilterResult& chain, int panelWidth) {
  if (chain.levels.empty()) throw UsageError("preview", "empty chain");
  if (panelWidth < 16 || panelWidth > 4096) throw UsageError("--size", "panel width must be in [16, 4096]");
  const int pw = panelWidth, ph = pw / 2, levels = int(chain.levels.size());
  const int sphere = std::clamp(pw * levels / kSpheres - 12, 48, 256);
  const int label = 14;
  LinearImage img;
  img.width = std::max(pw * levels, kSpheres * (sphere + 12));
  img.height = label + ph + label + sphere + 8;
  img.rgb.assign(size_t(img.width) * size_t(img.height) * 3, 0.02f);
  for (int l = 0; l < levels; ++l) {
    for (int row = 0; row < ph; ++row)
      for (int col = 0; col < pw; ++col) {
        const double lam = -2 * kPi * ((col + 0.5) / pw - 0.5), phi = kPi * (0.5 - (row + 0.5) / ph);
        const double d[3] = {std::sin(lam) * std::cos(phi), std::sin(phi), std::cos(lam) * std::cos(phi)};
        double rgb[3];
        sampleLevel(chain.levels[size_t(l)], d, rgb);
        put(img, l * pw + col, label + row, rgb);
      }
    char text[64];
    std::snprintf(text, sizeof text, "r=%.3f %dx%d", chain.levels[size_t(l)].spec.roughness,
                  chain.levels[size_t(l)].spec.size, chain.levels[size_t(l)].spec.size);
    drawText(img, l * pw + 3, 3, text, 1.0f);
  }
  // The split sum's second half from prtbake's own table.
  LutOptions lo;
  lo.size = 32;
  lo.samples = 256;
  lo.cloth = chain.options.lobe == PrefilterLobe::Charlie;
  const LutResult lut = computeLut(rt, lo);
  const int top = label + ph + label;
  for (int s = 0; s < kSpheres; ++s) {
    const double r = double(s) / (kSpheres - 1);
    const int x0 = s * (img.width / kSpheres) + (img.width / kSpheres - sphere) / 2;
    std::vector<bool> on;
    const LinearImage ball = renderSplitSumSphere(chain, lut, r, sphere, &on);
    for (int y = 0; y < sphere; ++y)
      for (int x = 0; x < sphere; ++x) {
        const size_t i = size_t(y) * size_t(sphere) + size_t(x);
        if (!on[i]) continue;
        const double rgb[3] = {ball.rgb[3 * i], ball.rgb[3 * i + 1], ball.rgb[3 * i + 2]};
        put(img, x0 + x, top + y, rgb);
      }
    char text[32];
    std::snprintf(text, sizeof text, "r=%.1f", r);
    drawText(img, x0 + sphere / 2 - 14, label + ph + 3, text, 1.0f);
  }
  return img;
}

void writePrefilterPreviewPng(const std::string& path, Runtime& rt, const PrefilterResult& chain, int panelWidth,
                              const std::string& source) {
  const LinearImage img = renderPrefilterPreview(rt, chain, panelWidth);
  const char* shade = chain.options.lobe == PrefilterLobe::Lambertian ? "P(N), albedo 1"
                      : chain.options.lobe == PrefilterLobe::Charlie  ? "P(R, r) * C(N.V, r) (LUT cloth table)"
                                                                      : "P(R, r) * (A + B)(N.V, r) (f0 = 1, prtbake GGX LUT)";
  writePreviewPng(path, img, ToneMap{},
                  {{"Description", std::string("prtbake prefiltered chain preview (") + toString(chain.options.lobe) + ", " +
                                       toString(chain.options.schedule) +
                                       "): top, every level as a lat-long panel (+Y up, centre column looks along +Z); "
                                       "bottom, spheres r = 0 ... 1 seen from +Z shaded " + shade},
                   {"Source", source}});
}

}  // namespace prtbake
