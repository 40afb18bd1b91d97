// Preview images: environment vs its SH reconstruction, LUT channels, PNG output.
#include "prtbake/preview.h"

#include <stb/stb_easy_font.h>
#include <stb/stb_image_write.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "core/constants.h"
#include "io/png_chunks.h"
#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/sh.h"

namespace prtbake {
namespace {

void fillRect(LinearImage& img, int x0, int y0, int x1, int y1, float v) {
  x0 = std::max(x0, 0), y0 = std::max(y0, 0), x1 = std::min(x1, img.width), y1 = std::min(y1, img.height);
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x)
      for (int c = 0; c < 3; ++c) img.rgb[3 * (size_t(y) * size_t(img.width) + size_t(x)) + size_t(c)] = v;
}

void collect(void* ctx, void* data, int size) { static_cast<std::string*>(ctx)->append(static_cast<char*>(data), size_t(size)); }

}  // namespace

Rgb sampleEnvironment(const EnvMap& env, const double d[3]) {
  // Undo the yaw: the map's own direction is Ry(−yaw)·d.
  const double yaw = env.yawDegrees * kPi / 180.0, c = std::cos(yaw), s = std::sin(yaw);
  const double x = c * d[0] - s * d[2], y = d[1], z = s * d[0] + c * d[2];
  size_t index;
  if (env.layout == EnvLayout::Cube) {
    int best = 0;
    double bestDot = -1e300;
    for (int f = 0; f < 6; ++f) {
      const auto& n = env.faces[size_t(f)].axisN;
      const double dot = x * n[0] + y * n[1] + z * n[2];
      if (dot > bestDot) bestDot = dot, best = f;
    }
    const auto& b = env.faces[size_t(best)];
    const double u = (x * b.axisU[0] + y * b.axisU[1] + z * b.axisU[2]) / bestDot;
    const double v = (x * b.axisV[0] + y * b.axisV[1] + z * b.axisV[2]) / bestDot;
    const int n = env.width;
    const int col = std::clamp(int((u + 1) * 0.5 * n), 0, n - 1), row = std::clamp(int((v + 1) * 0.5 * n), 0, n - 1);
    index = (size_t(best) * size_t(n) + size_t(row)) * size_t(n) + size_t(col);
  } else {
    const double lambda = std::atan2(x, z), phi = std::asin(std::clamp(y, -1.0, 1.0));
    const int col = std::clamp(int((0.5 - lambda / (2 * kPi)) * env.width), 0, env.width - 1);
    const int row = std::clamp(int((0.5 - phi / kPi) * env.height), 0, env.height - 1);
    index = size_t(row) * size_t(env.width) + size_t(col);
  }
  const std::array<float, 3> t = env.texel(index);
  return {t[0], t[1], t[2]};
}

LinearImage renderEnvPreview(const EnvMap* env, const ShCoeffs& radiance, int panelWidth) {
  if (panelWidth < 8 || panelWidth > 16384) throw UsageError("--size", "panel width must be in [8, 16384]");
  const int pw = panelWidth, ph = panelWidth / 2, panels = env ? 3 : 2;
  LinearImage img;
  img.width = pw * panels;
  img.height = ph;
  img.rgb.assign(size_t(img.width) * size_t(img.height) * 3, 0.0f);
  const ShCoeffs irr = applyWindowAndQuantity(radiance, std::vector<double>(size_t(radiance.order), 1.0),
                                              ShQuantity::IrradianceOverPi);
  for (int row = 0; row < ph; ++row)
    for (int col = 0; col < pw; ++col) {
      const double lam = -2 * kPi * ((col + 0.5) / pw - 0.5), phi = kPi * (0.5 - (row + 0.5) / ph);
      const double d[3] = {std::sin(lam) * std::cos(phi), std::sin(phi), std::cos(lam) * std::cos(phi)};
      std::vector<Rgb> values;
      if (env) values.push_back(sampleEnvironment(*env, d));
      values.push_back(evalSh(radiance, d[0], d[1], d[2]));
      values.push_back(evalSh(irr, d[0], d[1], d[2]));
      for (int p = 0; p < panels; ++p)
        for (int c = 0; c < 3; ++c)
          img.rgb[3 * (size_t(row) * size_t(img.width) + size_t(p * pw + col)) + size_t(c)] = float(values[size_t(p)][size_t(c)]);
    }
  return img;
}

void drawText(LinearImage& image, int x, int y, const std::string& text, float value, int scale) {
  std::vector<char> buffer(text.size() * 300 + 64);
  // stb_easy_font indexes its glyph table by (char - 32): anything outside printable ASCII (a
  // channel name from a file, say) becomes '?'.
  std::string copy = text;
  for (char& c : copy)
    if (c != '\n' && (static_cast<unsigned char>(c) < 32 || static_cast<unsigned char>(c) > 126)) c = '?';
  unsigned char color[4] = {255, 255, 255, 255};
  const int quads = stb_easy_font_print(0, 0, copy.data(), color, buffer.data(), int(buffer.size()));
  for (int q = 0; q < quads; ++q) {
    float vx[4], vy[4];
    for (int k = 0; k < 4; ++k) {
      std::memcpy(&vx[k], buffer.data() + (q * 4 + k) * 16, 4);
      std::memcpy(&vy[k], buffer.data() + (q * 4 + k) * 16 + 4, 4);
    }
    const int x0 = x + int(std::min({vx[0], vx[1], vx[2], vx[3]})) * scale;
    const int x1 = x + int(std::max({vx[0], vx[1], vx[2], vx[3]})) * scale;
    const int y0 = y + int(std::min({vy[0], vy[1], vy[2], vy[3]})) * scale;
    const int y1 = y + int(std::max({vy[0], vy[1], vy[2], vy[3]})) * scale;
    fillRect(image, x0, y0, x1, y1, value);
  }
}

LinearImage renderLutPreview(int size, const std::vector<LutChannel>& channels, const std::string& xLabel,
                             const std::string& yLabel, float lo, float hi, int panelSize) {
  if (size <= 0 || channels.empty()) throw UsageError("preview", "empty table");
  if (panelSize < 32 || panelSize > 8192) throw UsageError("--size", "panel size must be in [32, 8192]");
  const int margin = 40, top = 24, ps = panelSize;
  LinearImage img;
  img.width = int(channels.size()) * (ps + 2 * margin);
  img.height = ps + top + margin;
  img.rgb.assign(size_t(img.width) * size_t(img.height) * 3, 0.08f);
  for (size_t k = 0; k < channels.size(); ++k) {
    const int ox = int(k) * (ps + 2 * margin) + margin, oy = top;
    for (int py = 0; py < ps; ++py)
      for (int px = 0; px < ps; ++px) {
        const int col = std::min(size - 1, px * size / ps), row = std::min(size - 1, (ps - 1 - py) * size / ps);
        float v = (channels[k].data[size_t(row) * size_t(size) + size_t(col)] - lo) / (hi - lo);
        v = std::clamp(v, 0.0f, 1.0f);
        v = v * v;  // shown through the sRGB curve later: keep mid-greys near the middle
        for (int c = 0; c < 3; ++c)
          img.rgb[3 * (size_t(oy + py) * size_t(img.width) + size_t(ox + px)) + size_t(c)] = v;
      }
    fillRect(img, ox - 1, oy - 1, ox + ps + 1, oy, 1.0f);
    fillRect(img, ox - 1, oy + ps, ox + ps + 1, oy + ps + 1, 1.0f);
    fillRect(img, ox - 1, oy, ox, oy + ps, 1.0f);
    fillRect(img, ox + ps, oy, ox + ps + 1, oy + ps, 1.0f);
    drawText(img, ox, 6, channels[k].name, 1.0f, 1);
    drawText(img, ox, oy + ps + 6, "0", 1.0f);
    drawText(img, ox + ps - 6, oy + ps + 6, "1", 1.0f);
    drawText(img, ox + ps / 2 - 3 * int(xLabel.size()), oy + ps + 18, xLabel + " ->", 1.0f);
    drawText(img, ox - 12, oy + ps - 8, "0", 1.0f);
    drawText(img, ox - 12, oy, "1", 1.0f);
    drawText(img, ox - margin + 2, oy + ps / 2, yLabel, 1.0f);
    drawText(img, ox - margin + 2, oy + ps / 2 + 10, "^", 1.0f);
  }
  return img;
}

void writePreviewPng(const std::string& path, const LinearImage& image, const ToneMap& toneMap,
                     const std::vector<std::pair<std::string, std::string>>& text) {
  if (image.width <= 0 || image.height <= 0) throw OutputError(path, "empty image");
  writeFileAtomic(path, previewPngBytes(image, toneMap, text));
}

std::string previewPngBytes(const LinearImage& image, const ToneMap& toneMap,
                            const std::vector<std::pair<std::string, std::string>>& text) {
  if (image.width <= 0 || image.height <= 0) throw OutputError("preview", "empty image");
  const double scale = std::pow(2.0, toneMap.exposureStops);
  std::vector<unsigned char> px(image.rgb.size());
  for (size_t i = 0; i < px.size(); ++i) {
    double v = std::clamp(double(image.rgb[i]) * scale, 0.0, 1.0);
    v = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
    px[i] = (unsigned char)std::lround(v * 255.0);
  }
  std::string png;
  if (!stbi_write_png_to_func(collect, &png, image.width, image.height, 3, px.data(), image.width * 3))
    throw OutputError("preview", "PNG encoding failed");
  // Insert tEXt chunks right after IHDR (8-byte signature + 25-byte IHDR chunk).
  std::vector<std::pair<std::string, std::string>> all = {
      {"Software", std::string("prtbake ") + version()},
      {"ToneMap", "linear x 2^" + std::to_string(toneMap.exposureStops) + " (exposure in stops), clamped to [0,1], sRGB encoded"}};
  all.insert(all.end(), text.begin(), text.end());
  std::string chunks;
  for (const auto& [k, v] : all) detail::appendPngChunk(chunks, "tEXt", k.substr(0, 79) + std::string(1, '\0') + v);
  png.insert(33, chunks);
  return png;
}

}  // namespace prtbake
