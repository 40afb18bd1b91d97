// image_read.h (internal): one image file → linear float RGB in memory.
//
// Formats are recognised by their content, not their extension:
//   OpenEXR (magic 76 2f 31 01): via the OpenEXR library, scanline or tiled, half,
//     float or uint channels; tiled mip-/rip-mapped files are read at level 0; the
//     data window is respected (the image is the data window, its origin kept in
//     dataMinX/Y). R, G, B channels (missing ones read as 0), or a Y-only grey
//     image, or luminance/chroma (Y, RY, BY) through RgbaInputFile.
//   Radiance .hdr: stb_image's stbi_loadf (linear as stored).
//   PNG (8 or 16 bits) and JPEG: stb_image, decoded to integers and linearised with
//     `ldrDecode`; grey is expanded to RGB and alpha is dropped. stb_image's other
//     formats (BMP, GIF, PSD, TGA, PIC, PNM) are not read.
// Every failure is an InputError naming the file and the library's reason.
#pragma once

#include <array>
#include <cstdint>
#include <cstdlib>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "prtbake/raw_vector.h"

namespace prtbake::detail {

// How 8/16-bit code values c ∈ [0, 1] become linear radiance.
enum class LdrDecode {
  Srgb,     // the exact sRGB EOTF (IEC 61966-2-1): c/12.92, or ((c + 0.055)/1.055)^2.4
  Gamma22,  // c^2.2, what stb_image's stbi_loadf (and so the GAMES202 framework) does
};

struct Image {
  int width = 0, height = 0;
  // width·height interleaved RGB, row 0 (top) first, in one of three storages (as
  // EnvMap, envmap.h): floats, or with `compact` reading, OpenEXR halves as halves and
  // 8-bit images as codes with their linear values in codeToLinear (3·width·height
  // bytes in stb_image's own buffer, handed over without a copy).
  RawVector<float> rgb;
  RawVector<uint16_t> halfRgb;
  std::unique_ptr<uint8_t, void (*)(void*)> codes{nullptr, std::free};
  std::array<float, 256> codeToLinear{};
  int envmap = -1;             // OpenEXR envmap attribute: -1 none, 0 lat-long, 1 cube
  int dataMinX = 0, dataMinY = 0;  // OpenEXR data window origin (0, 0 for other formats)
  std::string format;          // "OpenEXR", "Radiance HDR", "PNG/JPEG (8-bit)", ...
};

Image readImage(const std::string& path, LdrDecode ldrDecode = LdrDecode::Srgb, bool compact = false);

// An OpenEXR image read a band of rows at a time, so that the whole image need not be in
// memory. The constructor checks the header as readImage does, and the size of
// `rowsAtOnce` rows against the input memory limit; read(y0, y1, band) decodes the rows
// [y0, y1) of the data window into `band` (height y1 − y0, in readImage's storage).
// Images of R, G, B or Y channels only (rowsReadable); luminance/chroma images are
// converted by readImage as a whole. Failures are InputErrors naming the file.
class ExrRowReader {
 public:
  ExrRowReader(const std::string& path, bool compact, long long rowsAtOnce);
  ~ExrRowReader();
  int width() const { return width_; }
  int height() const { return height_; }
  int envmap() const { return envmap_; }  // as Image::envmap
  bool rowsReadable() const { return readable_; }
  void read(int y0, int y1, Image& band);

 private:
  struct File;
  void guard(const std::function<void()>& f);
  std::string path_;
  std::unique_ptr<File> file_;
  int width_ = 0, height_ = 0, minX_ = 0, minY_ = 0, envmap_ = -1;
  bool hasRgb_ = false, readable_ = false, half_ = false;
};

// An 8- or 16-bit PNG or JPEG image held in memory (an image inside a glTF file), decoded as
// readImage decodes one; `label` names it in errors ("scene.glb: image 2").
Image readImageBytes(const std::string& label, const std::vector<unsigned char>& bytes, LdrDecode ldrDecode,
                     bool compact);

// Opens the file (so every format fails the same way when it cannot be opened) and tells
// whether it starts with the OpenEXR magic number 76 2f 31 01.
bool isOpenExr(const std::string& path);

// The exact sRGB EOTF of one code value in [0, 1].
double srgbToLinear(double c);

}  // namespace prtbake::detail
