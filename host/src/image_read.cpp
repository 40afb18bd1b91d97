// Image readers: OpenEXR through the OpenEXR library, everything else through
// stb_image. See image_read.h for what each format becomes.
#include "image_read.h"

#include "exr_check.h"

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

#include "prtbake/error.h"
#include "prtbake/limits.h"
#include "stb_decode.h"

namespace prtbake::detail {
namespace {

std::vector<unsigned char> readWholeFile(const std::string& path) {
  std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  struct stat st {};
  if (::fstat(::fileno(f.get()), &st) == 0)
    checkInputMemory(path, "reading the file (" + std::to_string(st.st_size) + " bytes)", double(st.st_size));
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

// stb_image's Radiance decoder loops forever on a run-length count of 0, which is
// what it reads past the end of a truncated file (and what a corrupt one may hold).
// This walks the scanline structure the way stb_image's stbi__hdr_load does, without
// decoding, and returns why the data cannot be decoded ("" when stb can be trusted
// with it, including the headers stb rejects by itself).
std::string radianceDataProblem(const std::vector<unsigned char>& b) {
  size_t pos = 0;
  auto line = [&](std::string& out) {
    out.clear();
    while (pos < b.size() && b[pos] != '\n') out += char(b[pos++]);
    if (pos >= b.size()) return false;
    ++pos;
    return true;
  };
  std::string tok;
  if (!line(tok)) return "";  // no identifier line: stb reports it
  do {
    if (!line(tok)) return "";  // header never ends: stb reports it
  } while (!tok.empty() && tok[0] != '\0');  // stb's header also ends at a line that starts with a NUL
  if (!line(tok) || tok.compare(0, 3, "-Y ") != 0) return "";
  char* end = nullptr;
  const long height = std::strtol(tok.c_str() + 3, &end, 10);
  while (*end == ' ') ++end;
  if (std::strncmp(end, "+X ", 3) != 0) return "";
  const long width = std::strtol(end + 3, nullptr, 10);
  if (width <= 0 || height <= 0 || width > (1 << 24) || height > (1 << 24)) return "";
  const size_t flatBytes = 4 * size_t(width) * size_t(height);
  const std::string truncated = "truncated Radiance HDR pixel data";
  if (width < 8 || width >= 32768) return b.size() - pos < flatBytes ? truncated : "";
  for (long j = 0; j < height; ++j) {
    if (b.size() - pos < 4) return truncated;
    if (b[pos] != 2 || b[pos + 1] != 2 || (b[pos + 2] & 0x80)) {
      // stb then reads the whole image flat from here.
      return b.size() - pos < flatBytes ? truncated : "";
    }
    if (((size_t(b[pos + 2]) << 8) | b[pos + 3]) != size_t(width)) return "";  // stb reports it
    pos += 4;
    for (int k = 0; k < 4; ++k) {
      long i = 0;
      while (i < width) {
        if (pos >= b.size()) return truncated;
        unsigned count = b[pos++];
        if (count > 128) {
          if (pos >= b.size()) return truncated;
          ++pos;
          count -= 128;
        } else {
          if (count == 0) return "bad RLE data in HDR (a run of length 0)";
          if (b.size() - pos < count) return truncated;
          pos += count;
        }
        if (long(count) > width - i) return "";  // stb reports "bad RLE data"
        i += long(count);
      }
    }
  }
  return "";
}

// stb_image 2.27 (what Debian ships) writes past its Huffman tables when the 16 code
// counts of a JPEG DHT table add up to more than 256 (fixed upstream in 2.28). This walks
// the marker segments the way stbi__decode_jpeg_image meets them (garbage and fill bytes
// skipped, entropy-coded data passed over to the next marker) and reads each DHT table's
// counts as stb does, past the segment's end while its length says more tables follow.
// Returns why stb cannot be trusted with the data ("" when it can).
std::string jpegHuffmanProblem(const std::vector<unsigned char>& b) {
  size_t start = 0;  // stb takes any number of fill bytes (0xFF) before the SOI marker
  while (start < b.size() && b[start] == 0xFF) ++start;
  if (start == 0 || start == b.size() || b[start] != 0xD8) return "";  // not a JPEG
  auto at = [&](size_t i) { return i < b.size() ? size_t(b[i]) : 0; };  // stb reads 0 past the end
  for (size_t pos = start + 1; pos + 1 < b.size();) {
    const size_t m = b[pos + 1];
    if (b[pos] != 0xFF || m == 0xFF || m == 0x00 || (m >= 0xD0 && m <= 0xD7)) {  // no segment starts here
      ++pos;
      continue;
    }
    if (m == 0xD9) break;  // end of image
    const size_t length = at(pos + 2) << 8 | at(pos + 3);
    if (m == 0xC4)
      for (size_t t = pos + 4, left = length; left > 2;) {  // 2: the length field itself
        size_t codes = 0;
        for (size_t i = 1; i <= 16; ++i) codes += at(t + i);
        if (codes > 256) return "a Huffman table of " + std::to_string(codes) + " codes (at most 256)";
        t += 17 + codes;
        left = left - 2 > 17 + codes ? left - 17 - codes : 2;
      }
    pos += 2 + length;
  }
  return "";
}

Image readWithStb(const std::string& path, const std::vector<unsigned char>& bytes, LdrDecode ldrDecode, bool compact) {
  if (bytes.empty()) throw InputError(path, "cannot decode image: the file is empty");
  if (bytes.size() > size_t(std::numeric_limits<int>::max())) throw InputError(path, "file too large");
  const std::string jpegProblem = jpegHuffmanProblem(bytes);
  if (!jpegProblem.empty()) throw InputError(path, "cannot decode image: " + jpegProblem);
  const auto* buf = bytes.data();
  const int len = int(bytes.size());
  Image img;
  int w = 0, h = 0;
  // Peak bytes per pixel: the float RGB result (12), stb's decoded copy (3 samples of
  // 4, 2 or 1 bytes) and, for integer images, the 16-bit code copy (6).
  const bool hdr = stb::isHdr(buf, len), sixteen = !hdr && stb::is16Bit(buf, len);
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
    const std::string problem = radianceDataProblem(bytes);
    if (!problem.empty()) throw InputError(path, "cannot decode Radiance HDR image: " + problem);
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
  std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  unsigned char b[4] = {0, 0, 0, 0};
  return std::fread(b, 1, 4, f.get()) == 4 && b[0] == 0x76 && b[1] == 0x2f && b[2] == 0x31 && b[3] == 0x01;
}

double srgbToLinear(double c) { return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4); }

Image readImage(const std::string& path, LdrDecode ldrDecode, bool compact) {
  try {
    if (isOpenExr(path)) return readOpenExr(path, compact);
    return readWithStb(path, readWholeFile(path), ldrDecode, compact);
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
