// Image readers: OpenEXR through the OpenEXR library, everything else through
// stb_image. See image_read.h for what each format becomes.
#include "io/image_read.h"

#include "io/exr_check.h"
#include "io/image_check.h"

#include <ImfChannelList.h>
#include <ImfEnvmap.h>
#include <ImfEnvmapAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfRgbaFile.h>
#include <ImfStandardAttributes.h>
#include <ImfThreading.h>
#include <sys/stat.h>

#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <thread>

#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/limits.h"
#include "io/stb_decode.h"

namespace prtbake::detail {
namespace {

std::vector<unsigned char> readWholeFile(const std::string& path) {
  const size_t size = inputFileSize(path);
  checkInputMemory(path, "reading the file (" + std::to_string(size) + " bytes)", double(size));
  std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  std::vector<unsigned char> bytes;
  unsigned char buf[1 << 16];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, f.get())) > 0) bytes.insert(bytes.end(), buf, buf + n);
  if (std::ferror(f.get())) throw InputError(path, std::string("cannot read: ") + std::strerror(errno));
  return bytes;
}

// Checked before anything of the image's size is allocated. `bytesPerPixel`: what
// decoding holds per pixel at its peak (the float RGB result plus the decoder's copy).
void checkSize(const std::string& path, long long w, long long h, double bytesPerPixel) {
  if (w <= 0 || h <= 0) throw InputError(path, "empty image");
  checkInputMemory(path, "a " + std::to_string(w) + "x" + std::to_string(h) + " image", double(w) * double(h) * bytesPerPixel);
}

// The image's channels, for the error when it has none that prtbake reads.
std::string channelNames(const Imf::ChannelList& ch) {
  std::string names;
  for (auto it = ch.begin(); it != ch.end(); ++it) names += std::string(names.empty() ? "" : ", ") + it.name();
  return names.empty() ? "none" : names;
}

Image readOpenExr(const std::string& path, bool compact) {
  ExrRowReader rows(path, compact, std::numeric_limits<long long>::max());
  checkSize(path, rows.width(), rows.height(), 12);
  if (rows.rowsReadable()) {
    Image img;
    rows.read(0, rows.height(), img);
    return img;
  }
  // Luminance/chroma images: RgbaInputFile converts them to RGB (in half).
  Image img;
  img.format = "OpenEXR";
  img.width = rows.width(), img.height = rows.height();
  img.envmap = rows.envmap();
  Imf::RgbaInputFile rgbaFile(path.c_str());
  const Imath::Box2i dw = rgbaFile.dataWindow();
  img.dataMinX = dw.min.x, img.dataMinY = dw.min.y;
  const size_t n = size_t(img.width) * size_t(img.height);
  std::vector<Imf::Rgba> px(n);
  rgbaFile.setFrameBuffer(px.data() - dw.min.x - ptrdiff_t(dw.min.y) * ptrdiff_t(img.width), 1, size_t(img.width));
  rgbaFile.readPixels(dw.min.y, dw.max.y);
  img.rgb.resize(3 * n);
  for (size_t i = 0; i < n; ++i) img.rgb[3 * i] = px[i].r, img.rgb[3 * i + 1] = px[i].g, img.rgb[3 * i + 2] = px[i].b;
  return img;
}

Image readWithStb(const std::string& path, const std::vector<unsigned char>& bytes, LdrDecode ldrDecode, bool compact) {
  if (bytes.empty()) throw InputError(path, "cannot decode image: the file is empty");
  if (bytes.size() > size_t(std::numeric_limits<int>::max())) throw InputError(path, "file too large");
  // What the file can hold, before stb allocates the image its header claims.
  const auto* buf = bytes.data();
  const int len = int(bytes.size());
  const bool hdr = stb::isHdr(buf, len), sixteen = !hdr && stb::is16Bit(buf, len);
  // What the file can hold, before the input memory limit and before stb allocates the
  // image its header claims: a small file's claim is refused for what it is.
  if (hdr) {
    const std::string problem = radianceProblem(bytes);
    if (!problem.empty()) throw InputError(path, "cannot decode Radiance HDR image: " + problem);
  }
  for (std::string (*check)(const std::vector<unsigned char>&) : {&pngProblem, &jpegProblem}) {
    const std::string problem = check(bytes);
    if (!problem.empty()) throw InputError(path, "cannot decode image: " + problem);
  }
  Image img;
  int w = 0, h = 0;
  // Peak bytes per pixel: the float RGB result (12), stb's decoded copy (3 samples of
  // 4, 2 or 1 bytes) and, for integer images, the 16-bit code copy (6).
  const double peakBytesPerPixel = hdr ? 24 : sixteen ? 24 : 21;
  // The header's size, checked before stb allocates its own buffer of that size. Any one
  // block stb asks for is then bounded: 16 bytes a pixel, padded to JPEG's largest MCU
  // (stb's largest is PNG's inflated data, 2 x 8 bytes a pixel for 16-bit RGBA, with room to
  // double for interlacing), or twice the file (PNG's compressed data, doubled as it grows).
  size_t blockLimit = 2 * bytes.size() + (1 << 20);
  if (stb::info(buf, len, &w, &h)) {
    checkSize(path, w, h, peakBytesPerPixel);
    blockLimit += 16 * (size_t(w) + 32) * (size_t(h) + 32);
  }
  if (hdr) {
    img.format = "Radiance HDR";
    std::unique_ptr<float, decltype(&std::free)> px(stb::loadHdr(buf, len, blockLimit, &w, &h), &std::free);
    if (!px) throw InputError(path, "cannot decode Radiance HDR image: " + stb::reason());
    checkSize(path, w, h, peakBytesPerPixel);
    img.rgb.assign(px.get(), px.get() + 3 * size_t(w) * size_t(h));
  } else {
    double lut16Max = 255.0;
    std::vector<unsigned short> codes;
    if (sixteen) {
      img.format = "16-bit image";
      lut16Max = 65535.0;
      std::unique_ptr<uint16_t, decltype(&std::free)> px(stb::load16(buf, len, blockLimit, &w, &h), &std::free);
      if (!px) throw InputError(path, "cannot decode image: " + stb::reason());
      checkSize(path, w, h, peakBytesPerPixel);
      codes.assign(px.get(), px.get() + 3 * size_t(w) * size_t(h));
    } else {
      img.format = "8-bit image";
      std::unique_ptr<uint8_t, decltype(&std::free)> px(stb::load8(buf, len, blockLimit, &w, &h), &std::free);
      if (!px) throw InputError(path, "cannot decode image: " + stb::reason());
      checkSize(path, w, h, peakBytesPerPixel);
      if (compact) {
        // The codes as they are, with their linear values in the table.
        img.codes = std::move(px);
        for (int c = 0; c < 256; ++c)
          img.codeToLinear[size_t(c)] = float(ldrDecode == LdrDecode::Srgb ? srgbToLinear(c / 255.0) : std::pow(c / 255.0, 2.2));
        img.width = w, img.height = h;
        return img;
      }
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

// Imf::InputFile reads scanline and tiled files alike; for a tiled mip- or rip-mapped file it
// reads level (0, 0), the full resolution.
struct ExrRowReader::File {
  explicit File(const std::string& path) : file(path.c_str()) {}
  Imf::InputFile file;
};

ExrRowReader::ExrRowReader(const std::string& path, bool compact, long long rowsAtOnce) : path_(path) {
  guard([&] {
    // Before the library allocates what the header claims: the header itself, and what the
    // caller will read at once.
    const ExrHeaderFacts facts = checkExrHeader(path);
    // The library decompresses the chunks of a read on this many threads (none by default).
    static std::once_flag threads;
    std::call_once(threads, [] { Imf::setGlobalThreadCount(int(std::max(1u, std::thread::hardware_concurrency()))); });
    if (facts.width > 0 && facts.height > 0) checkSize(path, facts.width, std::min(facts.height, rowsAtOnce), 12);
    file_ = std::make_unique<File>(path);
    const Imf::Header& header = file_->file.header();
    const Imath::Box2i dw = header.dataWindow();
    const long long w = (long long)dw.max.x - dw.min.x + 1, h = (long long)dw.max.y - dw.min.y + 1;
    if (w <= 0 || h <= 0) throw InputError(path, "empty image");
    if (w > std::numeric_limits<int>::max() || h > std::numeric_limits<int>::max())
      throw InputError(path, "image too large (" + std::to_string(w) + "x" + std::to_string(h) + ")");
    width_ = int(w), height_ = int(h), minX_ = dw.min.x, minY_ = dw.min.y;
    if (Imf::hasEnvmap(header)) {
      const Imf::Envmap e = Imf::envmap(header);
      if (e == Imf::ENVMAP_LATLONG) envmap_ = 0;
      else if (e == Imf::ENVMAP_CUBE) envmap_ = 1;
      else throw InputError(path, "unknown OpenEXR envmap attribute value " + std::to_string(int(e)));
    }
    const Imf::ChannelList& ch = header.channels();
    hasRgb_ = ch.findChannel("R") || ch.findChannel("G") || ch.findChannel("B");
    const bool hasY = ch.findChannel("Y") != nullptr, hasChroma = ch.findChannel("RY") || ch.findChannel("BY");
    if (!hasRgb_ && !hasY) throw InputError(path, "no R, G, B or Y channel (channels: " + channelNames(ch) + ")");
    readable_ = hasRgb_ || !hasChroma;
    // Compact: every colour channel the file has is half, so it is read as halves.
    half_ = compact && readable_;
    for (const char* c : {"R", "G", "B", "Y"})
      if (const Imf::Channel* p = ch.findChannel(c); p && p->type != Imf::HALF) half_ = false;
  });
}

ExrRowReader::~ExrRowReader() = default;

void ExrRowReader::read(int y0, int y1, Image& band) {
  PRTBAKE_CHECK(readable_ && 0 <= y0 && y0 < y1 && y1 <= height_, "OpenEXR rows out of range");
  guard([&] {
    checkSize(path_, width_, y1 - y0, 12);
    band = Image{};
    band.format = "OpenEXR";
    band.width = width_, band.height = y1 - y0;
    band.envmap = envmap_;
    band.dataMinX = minX_, band.dataMinY = minY_ + y0;
    const size_t n = size_t(width_) * size_t(y1 - y0);
    // Slices into the interleaved band (every channel is written: OpenEXR fills absent ones
    // with 0), based so that row y0 of the data window lands on the band's first row.
    Imf::FrameBuffer fb;
    const Imf::PixelType type = half_ ? Imf::HALF : Imf::FLOAT;
    const size_t bytes = half_ ? sizeof(uint16_t) : sizeof(float), xs = 3 * bytes, ys = xs * size_t(width_);
    char* first = half_ ? reinterpret_cast<char*>((band.halfRgb.resize(3 * n), band.halfRgb.data()))
                        : reinterpret_cast<char*>((band.rgb.resize(3 * n), band.rgb.data()));
    const Imath::Box2i rows(Imath::V2i(minX_, minY_ + y0), Imath::V2i(minX_ + width_ - 1, minY_ + y1 - 1));
    const char* names[3] = {"R", "G", "B"};
    for (int c = 0; c < (hasRgb_ ? 3 : 1); ++c)
      fb.insert(hasRgb_ ? names[c] : "Y", Imf::Slice::Make(type, first + size_t(c) * bytes, rows, xs, ys));
    file_->file.setFrameBuffer(fb);
    file_->file.readPixels(minY_ + y0, minY_ + y1 - 1);
    if (!hasRgb_)  // grey: Y into all three
      for (size_t i = 0; i < n; ++i) {
        if (half_) band.halfRgb[3 * i + 1] = band.halfRgb[3 * i + 2] = band.halfRgb[3 * i];
        else band.rgb[3 * i + 1] = band.rgb[3 * i + 2] = band.rgb[3 * i];
      }
  });
}

void ExrRowReader::guard(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw InputError(path_, "out of memory while reading the image");
  } catch (const std::exception& e) {
    // OpenEXR (Iex) reports truncated or malformed files with std::exception subclasses.
    throw InputError(path_, std::string("cannot read OpenEXR image: ") + e.what());
  }
}

bool isOpenExr(const std::string& path) {
  inputFileSize(path);
  std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  unsigned char b[4] = {0, 0, 0, 0};
  return std::fread(b, 1, 4, f.get()) == 4 && b[0] == 0x76 && b[1] == 0x2f && b[2] == 0x31 && b[3] == 0x01;
}

double srgbToLinear(double c) { return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4); }

namespace {
// Decoder failures as InputErrors naming `path`.
Image guardedRead(const std::string& path, const std::function<Image()>& read) {
  try {
    return read();
  } catch (const Error&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw InputError(path, "out of memory while reading the image");
  } catch (const std::exception& e) {
    // OpenEXR (Iex) reports truncated or malformed files with std::exception subclasses.
    throw InputError(path, std::string("cannot read OpenEXR image: ") + e.what());
  }
}

}  // namespace

Image readImage(const std::string& path, LdrDecode ldrDecode, bool compact) {
  return guardedRead(path, [&] {
    return isOpenExr(path) ? readOpenExr(path, compact) : readWithStb(path, readWholeFile(path), ldrDecode, compact);
  });
}

Image readImageBytes(const std::string& label, const std::vector<unsigned char>& bytes, LdrDecode ldrDecode,
                     bool compact) {
  return guardedRead(label, [&] { return readWithStb(label, bytes, ldrDecode, compact); });
}

}  // namespace prtbake::detail
