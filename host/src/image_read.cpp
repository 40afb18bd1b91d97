// Image readers: OpenEXR through the OpenEXR library, everything else through
// stb_image. See image_read.h for what each format becomes.
#include "image_read.h"

#include <ImfChannelList.h>
#include <ImfEnvmap.h>
#include <ImfEnvmapAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfRgbaFile.h>
#include <ImfStandardAttributes.h>
#include <stb/stb_image.h>

#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>

#include "prtbake/error.h"

namespace prtbake::detail {
namespace {

// Images larger than this are refused before allocating (3 floats per pixel: 3 GiB).
constexpr long long kMaxPixels = 1LL << 28;

std::vector<unsigned char> readWholeFile(const std::string& path) {
  std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  std::vector<unsigned char> bytes;
  unsigned char buf[1 << 16];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, f.get())) > 0) bytes.insert(bytes.end(), buf, buf + n);
  if (std::ferror(f.get())) throw InputError(path, std::string("cannot read: ") + std::strerror(errno));
  return bytes;
}

// Opens the file (so every format fails the same way when it cannot be opened)
// and tells whether it starts with the OpenEXR magic number 76 2f 31 01.
bool isOpenExr(const std::string& path) {
  std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  unsigned char b[4] = {0, 0, 0, 0};
  return std::fread(b, 1, 4, f.get()) == 4 && b[0] == 0x76 && b[1] == 0x2f && b[2] == 0x31 && b[3] == 0x01;
}

void checkSize(const std::string& path, long long w, long long h) {
  if (w <= 0 || h <= 0) throw InputError(path, "empty image");
  if (w * h > kMaxPixels)
    throw InputError(path, "image too large (" + std::to_string(w) + "x" + std::to_string(h) + ")");
}

Image readOpenExr(const std::string& path) {
  Image img;
  img.format = "OpenEXR";
  // Imf::InputFile reads scanline and tiled files alike; for a tiled mip- or
  // rip-mapped file it reads level (0, 0), the full resolution.
  Imf::InputFile file(path.c_str());
  const Imf::Header& header = file.header();
  const Imath::Box2i dw = header.dataWindow();
  const long long w = (long long)dw.max.x - dw.min.x + 1, h = (long long)dw.max.y - dw.min.y + 1;
  checkSize(path, w, h);
  img.width = int(w), img.height = int(h);
  img.dataMinX = dw.min.x, img.dataMinY = dw.min.y;
  if (Imf::hasEnvmap(header)) {
    const Imf::Envmap e = Imf::envmap(header);
    if (e == Imf::ENVMAP_LATLONG) img.envmap = 0;
    else if (e == Imf::ENVMAP_CUBE) img.envmap = 1;
    else throw InputError(path, "unknown OpenEXR envmap attribute value " + std::to_string(int(e)));
  }
  const Imf::ChannelList& ch = header.channels();
  const bool hasRgb = ch.findChannel("R") || ch.findChannel("G") || ch.findChannel("B");
  const bool hasY = ch.findChannel("Y") != nullptr;
  const bool hasChroma = ch.findChannel("RY") || ch.findChannel("BY");
  const size_t n = size_t(w) * size_t(h);
  img.rgb.assign(3 * n, 0.0f);

  if (hasRgb || (hasY && !hasChroma)) {
    // Float slices into the interleaved buffer; Slice::Make offsets the base
    // pointer by the data window origin. A missing channel keeps its fill value 0.
    Imf::FrameBuffer fb;
    const size_t xs = 3 * sizeof(float), ys = xs * size_t(w);
    if (hasRgb) {
      const char* names[3] = {"R", "G", "B"};
      for (int c = 0; c < 3; ++c)
        fb.insert(names[c], Imf::Slice::Make(Imf::FLOAT, img.rgb.data() + c, dw, xs, ys));
      file.setFrameBuffer(fb);
      file.readPixels(dw.min.y, dw.max.y);
    } else {
      fb.insert("Y", Imf::Slice::Make(Imf::FLOAT, img.rgb.data(), dw, xs, ys));
      file.setFrameBuffer(fb);
      file.readPixels(dw.min.y, dw.max.y);
      for (size_t i = 0; i < n; ++i) img.rgb[3 * i + 1] = img.rgb[3 * i + 2] = img.rgb[3 * i];
    }
    return img;
  }
  if (hasY && hasChroma) {
    // Luminance/chroma images: RgbaInputFile converts them to RGB (in half).
    Imf::RgbaInputFile rgbaFile(path.c_str());
    std::vector<Imf::Rgba> px(n);
    rgbaFile.setFrameBuffer(px.data() - dw.min.x - ptrdiff_t(dw.min.y) * ptrdiff_t(w), 1, size_t(w));
    rgbaFile.readPixels(dw.min.y, dw.max.y);
    for (size_t i = 0; i < n; ++i) {
      img.rgb[3 * i] = px[i].r, img.rgb[3 * i + 1] = px[i].g, img.rgb[3 * i + 2] = px[i].b;
    }
    return img;
  }
  std::string names;
  for (auto it = ch.begin(); it != ch.end(); ++it) names += std::string(names.empty() ? "" : ", ") + it.name();
  throw InputError(path, "no R, G, B or Y channel (channels: " + (names.empty() ? "none" : names) + ")");
}

std::string stbReason() {
  const char* r = stbi_failure_reason();
  return r ? r : "unknown error";
}

struct StbFree {
  void operator()(void* p) const { stbi_image_free(p); }
};

// stb_image's RLE scanline decoder for Radiance .hdr loops forever on a run
// length of 0, which is what it reads at the end of a truncated file (and what
// a corrupt file may hold). Walks the RLE structure the way stb does and returns
// what is wrong, or "" to let stb decode (and report anything else).
std::string hdrRleProblem(const unsigned char* buf, size_t len) {
  size_t pos = 0;
  auto line = [&]() {
    std::string s;
    while (pos < len && buf[pos] != '\n') s += char(buf[pos++]);
    if (pos < len) ++pos;
    return s;
  };
  while (pos < len && !line().empty()) {
  }
  int h = 0, w = 0;
  if (std::sscanf(line().c_str(), "-Y %d +X %d", &h, &w) != 2 || w < 8 || w >= 32768 || h <= 0) return "";
  for (int row = 0; row < h; ++row) {
    if (pos + 4 > len) return "truncated (scanline " + std::to_string(row) + " of " + std::to_string(h) + ")";
    if (buf[pos] != 2 || buf[pos + 1] != 2 || (buf[pos + 2] & 0x80)) return "";  // flat data: stb copes
    pos += 4;
    for (int channel = 0; channel < 4; ++channel)
      for (int x = 0; x < w;) {
        if (pos >= len) return "truncated (scanline " + std::to_string(row) + " of " + std::to_string(h) + ")";
        const int count = buf[pos++];
        if (count == 0) return "corrupt RLE data (a run of length 0 in scanline " + std::to_string(row) + ")";
        if (count > 128) {
          if (count - 128 > w - x) return "";  // stb reports the overrun
          x += count - 128;
          pos += 1;
        } else {
          if (count > w - x) return "";
          x += count;
          pos += size_t(count);
        }
      }
  }
  return "";
}

Image readWithStb(const std::string& path, const std::vector<unsigned char>& bytes, LdrDecode ldrDecode) {
  if (bytes.empty()) throw InputError(path, "cannot decode image: the file is empty");
  if (bytes.size() > size_t(std::numeric_limits<int>::max())) throw InputError(path, "file too large");
  const auto* buf = bytes.data();
  const int len = int(bytes.size());
  Image img;
  int w = 0, h = 0, channelsInFile = 0;
  // Ask stb for 3 channels: it replicates grey and drops alpha.
  if (stbi_is_hdr_from_memory(buf, len)) {
    img.format = "Radiance HDR";
    if (const std::string problem = hdrRleProblem(buf, bytes.size()); !problem.empty())
      throw InputError(path, "cannot decode Radiance HDR image: " + problem);
    std::unique_ptr<float, StbFree> px(stbi_loadf_from_memory(buf, len, &w, &h, &channelsInFile, 3));
    if (!px) throw InputError(path, "cannot decode Radiance HDR image: " + stbReason());
    checkSize(path, w, h);
    img.rgb.assign(px.get(), px.get() + 3 * size_t(w) * size_t(h));
  } else {
    double lut16Max = 255.0;
    std::vector<unsigned short> codes;
    if (stbi_is_16_bit_from_memory(buf, len)) {
      img.format = "16-bit image";
      lut16Max = 65535.0;
      std::unique_ptr<stbi_us, StbFree> px(stbi_load_16_from_memory(buf, len, &w, &h, &channelsInFile, 3));
      if (!px) throw InputError(path, "cannot decode image: " + stbReason());
      checkSize(path, w, h);
      codes.assign(px.get(), px.get() + 3 * size_t(w) * size_t(h));
    } else {
      img.format = "8-bit image";
      std::unique_ptr<stbi_uc, StbFree> px(stbi_load_from_memory(buf, len, &w, &h, &channelsInFile, 3));
      if (!px) throw InputError(path, "cannot decode image: " + stbReason());
      checkSize(path, w, h);
      codes.assign(px.get(), px.get() + 3 * size_t(w) * size_t(h));
    }
    // One table entry per code value, computed in double.
    std::vector<float> lut(size_t(lut16Max) + 1);
    for (size_t c = 0; c < lut.size(); ++c) {
      const double x = double(c) / lut16Max;
      lut[c] = float(ldrDecode == LdrDecode::Srgb ? srgbToLinear(x) : std::pow(x, 2.2));
    }
    img.rgb.resize(codes.size());
    for (size_t i = 0; i < codes.size(); ++i) img.rgb[i] = lut[codes[i]];
  }
  img.width = w, img.height = h;
  return img;
}

}  // namespace

double srgbToLinear(double c) { return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4); }

Image readImage(const std::string& path, LdrDecode ldrDecode) {
  try {
    if (isOpenExr(path)) return readOpenExr(path);
    return readWithStb(path, readWholeFile(path), ldrDecode);
  } catch (const Error&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw InputError(path, "out of memory while reading the image");
  } catch (const std::exception& e) {
    // OpenEXR (Iex) reports truncated or malformed files with std::exception subclasses.
    throw InputError(path, std::string("cannot read OpenEXR image: ") + e.what());
  }
}

}  // namespace prtbake::detail
