// prtbake/preview.h: images of what was baked, for people to check at a glance.
//
// Renderers return linear RGB float images (tests read them before tone mapping);
// writePreviewPng tone-maps (exposure in stops, then the sRGB curve, clamped) and
// writes an 8-bit PNG with the tone map and the image's meaning in tEXt chunks.
#pragma once

#include <array>
#include <string>
#include <utility>
#include <vector>

#include "prtbake/env_sh.h"
#include "prtbake/envmap.h"

namespace prtbake {

struct LinearImage {
  int width = 0, height = 0;
  std::vector<float> rgb;  // interleaved, row 0 on top
  std::array<float, 3> at(int x, int y) const {
    const size_t i = 3 * (size_t(y) * size_t(width) + size_t(x));
    return {rgb[i], rgb[i + 1], rgb[i + 2]};
  }
};

// The environment's radiance in direction `dirWorld` (nearest texel; yaw applied).
Rgb sampleEnvironment(const EnvMap& env, const double dirWorld[3]);

// Lat-long panels (OpenEXR LatLongMap axes, +Y up), each width × width/2, side by
// side: [the environment |] the SH reconstruction of its radiance | the
// reconstructed irradiance/π (the shading of a white diffuse surface). `radiance`
// holds radiance coefficients (windowed as wanted); env may be null.
LinearImage renderEnvPreview(const EnvMap* env, const ShCoeffs& radiance, int panelWidth);

// One panel per named channel of a table over (x = column, y = row), drawn with
// row 0 at the BOTTOM (so the second axis grows upward), grey-scale in [lo, hi],
// with a frame, axis labels and tick values.
struct LutChannel {
  std::string name;
  const float* data;  // size × size values, row-major, row 0 first
};
LinearImage renderLutPreview(int size, const std::vector<LutChannel>& channels, const std::string& xLabel,
                             const std::string& yLabel, float lo, float hi, int panelSize);

struct ToneMap {
  double exposureStops = 0.0;  // linear × 2^exposure before the sRGB curve
};

// Writes the PNG atomically; `text` adds tEXt chunks (key, value).
void writePreviewPng(const std::string& path, const LinearImage& image, const ToneMap& toneMap,
                     const std::vector<std::pair<std::string, std::string>>& text = {});

// Draws `text` with a small vector font into a linear image at (x, y), scaled.
void drawText(LinearImage& image, int x, int y, const std::string& text, float value, int scale = 1);

}  // namespace prtbake
