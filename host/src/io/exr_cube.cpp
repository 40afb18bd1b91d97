// Where OpenEXR keeps each cube texel (exr_cube.h).
//
// For our texel (f, row, col) we hand Imf::CubeMap::faceAndPixelPosition the unnormalised
// direction u·axisU + v·axisV + axisN (its components are 0, ±1, ±u, ±v, exact in float for
// power-of-two N), and Imf::CubeMap::pixelPosition turns the face position into a pixel of
// the data window.
//
// OpenEXR samples a face at pixel positions 0 … N−1 mapped to [−1, 1] (pixel centres on the
// face edges), we at centres u = 2(c + 0.5)/N − 1. Our texel c so lands at
// c + 0.5 − (c + 0.5)/N (or its mirror N − 1 − that), strictly within 0.5 of an integer:
// rounding recovers the pixel exactly. The two conventions differ by less than half a texel
// in angle; the data is the same grid. Self-test: the map must use every pixel exactly once.
#include "io/exr_cube.h"

#include <ImfEnvmap.h>

#include <cmath>

#include "prtbake/error.h"

namespace prtbake::detail {

std::vector<size_t> openExrCubePixels(int n, const std::array<CubeFaceBasis, 6>& faces, const std::string& subject) {
  const Imath::Box2i dw(Imath::V2i(0, 0), Imath::V2i(n - 1, 6 * n - 1));
  std::vector<size_t> pixel(6 * size_t(n) * size_t(n));
  std::vector<unsigned char> used(pixel.size(), 0);
  for (int f = 0; f < 6; ++f) {
    const CubeFaceBasis& b = faces[size_t(f)];
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) {
        const float u = float(2.0 * (c + 0.5) / n - 1.0), v = float(2.0 * (r + 0.5) / n - 1.0);
        const Imath::V3f d(float(u * b.axisU[0] + v * b.axisV[0] + b.axisN[0]),
                           float(u * b.axisU[1] + v * b.axisV[1] + b.axisN[1]),
                           float(u * b.axisU[2] + v * b.axisV[2] + b.axisN[2]));
        Imf::CubeMapFace exrFace;
        Imath::V2f pif;
        Imf::CubeMap::faceAndPixelPosition(d, dw, exrFace, pif);
        const Imath::V2f pos = Imf::CubeMap::pixelPosition(exrFace, dw, pif);
        const int x = int(std::floor(pos.x + 0.5f)), y = int(std::floor(pos.y + 0.5f));
        if (!(x >= 0 && x < n && y >= 0 && y < 6 * n)) throw InputError(subject, "OpenEXR cube pixel outside the image");
        const size_t p = size_t(y) * size_t(n) + size_t(x);
        if (used[p]) throw InputError(subject, "two cube texels map to one OpenEXR pixel");
        used[p] = 1;
        pixel[(size_t(f) * size_t(n) + size_t(r)) * size_t(n) + size_t(c)] = p;
      }
  }
  // 6N² distinct pixels of a 6N² image were hit: each exactly once.
  return pixel;
}

}  // namespace prtbake::detail
