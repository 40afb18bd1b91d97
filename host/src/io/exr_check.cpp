// The OpenEXR header walk (exr_check.h).
#include "io/exr_check.h"
#include "io/image_check.h"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>

#include "prtbake/atomic_file.h"
#include "prtbake/error.h"

namespace prtbake::detail {
namespace {

constexpr uint32_t kTiledFlag = 0x200, kLongNamesFlag = 0x400, kMultipartFlag = 0x1000;

int32_t le32(const std::string& b, size_t at) {
  uint32_t v = 0;
  for (int k = 0; k < 4; ++k) v |= uint32_t(uint8_t(b[at + size_t(k)])) << (8 * k);
  return int32_t(v);
}

// Scanlines per chunk of each compression (ImfCompression.h order).
int linesPerChunk(int compression) {
  switch (compression) {
    case 0: case 1: case 2: return 1;  // NONE, RLE, ZIPS
    case 3: case 5: return 16;         // ZIP, PXR24
    case 4: case 6: case 7: case 8: return 32;  // PIZ, B44, B44A, DWAA
    case 9: return 256;                // DWAB
    default: return 0;                 // unknown: the library reports it
  }
}

// The bytes the library reads for a value of a fixed-size type (ImfStandardAttributes:
// it reads these whatever the size field says, so a different size would shift every
// later attribute); 0 for a type of variable size or one it does not know.
size_t fixedValueSize(const std::string& type) {
  static const struct {
    const char* type;
    size_t bytes;
  } kSizes[] = {{"box2i", 16}, {"box2f", 16}, {"compression", 1}, {"lineOrder", 1}, {"envmap", 1},
                {"deepImageState", 1}, {"float", 4}, {"int", 4}, {"double", 8}, {"rational", 8},
                {"v2i", 8}, {"v2f", 8}, {"v2d", 16}, {"v3i", 12}, {"v3f", 12}, {"v3d", 24},
                {"m33f", 36}, {"m33d", 72}, {"m44f", 64}, {"m44d", 128}, {"chromaticities", 32},
                {"keycode", 28}, {"timecode", 8}, {"tiledesc", 9}};
  for (const auto& k : kSizes)
    if (type == k.type) return k.bytes;
  return 0;
}

// The most bytes of pixel data that one byte of a chunk can decode to, by compression
// (ImfCompression.h order), so that a file too short for its data window is refused from
// its header and size. NONE stores the pixels; RLE runs are at most 127 bytes from 2 (64);
// ZIP and ZIPS are deflate, at most 1032:1 (a 258-byte match in 2 bits); PIZ is Huffman
// with runs of at most 256 16-bit values in 10 bits (410, taken as 512); PXR24 is deflate
// of 24 bits a float (1032 x 4/3); B44A stores a flat 4x4 block of halves (32 bytes) in 3
// (11); DWAA/DWAB keep one DC value (2 bytes) per 8x8 block of halves (128 bytes) and
// deflate it (66,048, taken as 131,072). 0: unknown (the library reports it).
double maxExpansion(int compression) {
  switch (compression) {
    case 0: return 1;
    case 1: return 64;
    case 2: case 3: return 1032;
    case 4: return 512;
    case 5: return 1376;
    case 6: case 7: return 11;
    case 8: case 9: return 131072;
    default: return 0;
  }
}

// The header, attributes and offset table are at the start of the file: only this much of
// it is read for the walk (a file's pixels may be gigabytes).
constexpr size_t kHeaderBytes = size_t(64) << 20;

InputError corruptHeader(const std::string& path, const std::string& what) {
  return InputError(path, "corrupt OpenEXR header: " + what);
}

// The values the library reads by their content rather than by the size field must fill
// their size exactly, or the library's reading and the header walk part ways (a chlist one
// byte longer than its size had the library take later bytes for a 1.6 GB string's length).
// The value of attribute `name` lies in b[pos, end); a channel list's channels and bytes per
// pixel go to *channels and *bytesPerPixel.
void checkValueFill(const std::string& path, const std::string& b, size_t pos, size_t end, const std::string& name,
                    const std::string& type, int* channels, double* bytesPerPixel) {
  const size_t size = end - pos;
  const size_t fixed = fixedValueSize(type);
  if (fixed && size != fixed)
    throw corruptHeader(path, "attribute '" + name + "' of type " + type + " has " + std::to_string(size) +
                                  " bytes, not " + std::to_string(fixed));
  if (type == "chlist") {  // entries name\0 + 16 bytes, then \0
    size_t p = pos;
    while (p < end && b[p] != '\0') {
      const size_t nul = b.find('\0', p);
      if (nul == std::string::npos || nul >= end || end - nul - 1 < 16) throw corruptHeader(path, "malformed channel list");
      // pixel type (0 uint, 1 half, 2 float), pLinear and 3 reserved bytes, x and y sampling
      const int32_t pixelType = le32(b, nul + 1), xs = le32(b, nul + 9), ys = le32(b, nul + 13);
      if (xs > 0 && ys > 0) *bytesPerPixel += (pixelType == 1 ? 2.0 : 4.0) / (double(xs) * double(ys));
      p = nul + 1 + 16;
      ++*channels;
    }
    if (p + 1 != end)
      throw corruptHeader(path, "the channel list does not fill its " + std::to_string(size) + " bytes");
  } else if (type == "preview") {  // width, height, then width × height RGBA bytes
    if (size < 8 || double(uint32_t(le32(b, pos))) * double(uint32_t(le32(b, pos + 4))) * 4 + 8 != double(size))
      throw corruptHeader(path, "the preview image does not fill its " + std::to_string(size) + " bytes");
  } else if (type == "stringvector") {  // int32 length, then that many bytes, repeated
    size_t p = pos;
    while (end - p >= 4) {
      const int32_t n = le32(b, p);
      if (n < 0 || size_t(n) > end - p - 4) throw corruptHeader(path, "malformed string vector '" + name + "'");
      p += 4 + size_t(n);
    }
    if (p != end) throw corruptHeader(path, "malformed string vector '" + name + "'");
  }
}

// What the first part's header says of its pixels' storage.
struct PixelStorage {
  int compression = 3;  // a header without the attribute keeps the library's default, ZIP
  long long tileWidth = 0, tileHeight = 0;
  double pixelBytes = 0;  // of the channels, per pixel of the data window
  bool tiled = false, multipart = false;
};

// The bytes after the headers (from `pos` on) must be able to hold the data window's pixels:
// the chunks hold them at most maxExpansion times their size (a tiled file's other levels and
// other parts only add to what they need), and a single-part scanline file's offset table
// follows the header.
void checkPixelBytes(const std::string& path, const ExrHeaderFacts& facts, const PixelStorage& ps, size_t fileSize,
                     size_t pos) {
  // The library's decompressor holds a whole chunk, whatever the data window: a scanline
  // chunk's lines (16 for ZIP: a 14-million-pixel row of a 177-byte file had it allocate
  // 914 MB) or a tile, so the data window counts as at least one chunk.
  const double ratio = maxExpansion(ps.compression), dataBytes = double(fileSize - pos);
  const double width = double(std::max(facts.width, 0LL)), height = double(std::max(facts.height, 0LL));
  const double chunkWidth = ps.tiled ? double(ps.tileWidth) : width;
  const double chunkLines = ps.tiled ? double(ps.tileHeight) : linesPerChunk(ps.compression);
  const double pixelDataBytes = std::max(width * height, chunkWidth * chunkLines) * ps.pixelBytes;
  if (ratio > 0 && pixelDataBytes > ratio * dataBytes + 65536.0)
    throw InputError(path, "truncated OpenEXR file: its " + std::to_string(facts.width) + "x" + std::to_string(facts.height) +
                               " data window" + (width * height >= chunkWidth * chunkLines ? "" : " (in chunks of " +
                               wholeNumber(chunkWidth) + "x" + wholeNumber(chunkLines) + ")") + " holds " +
                               wholeNumber(pixelDataBytes) + " bytes of pixels, more than the " + wholeNumber(dataBytes) +
                               " bytes after its header can decode to");
  // One 8-byte offset per chunk of lines.
  if (!ps.multipart && !ps.tiled && facts.height > 0) {
    const int lines = linesPerChunk(ps.compression);
    if (lines > 0) {
      const double tableBytes = 8.0 * double((facts.height + lines - 1) / lines);
      if (tableBytes > double(fileSize - pos))
        throw InputError(path, "truncated OpenEXR file: the offset table of its " + std::to_string(facts.height) +
                                   " lines needs " + std::to_string((long long)tableBytes) + " bytes, the file has " +
                                   std::to_string(fileSize - pos) + " after the header");
    }
  }
}

}  // namespace

ExrHeaderFacts checkExrHeader(const std::string& path) {
  size_t fileSize = 0;
  const std::string b = readFilePrefix(path, kHeaderBytes, &fileSize);
  auto corrupt = [&](const std::string& what) { return corruptHeader(path, what); };
  if (b.size() < 8) throw InputError(path, "truncated OpenEXR file (" + std::to_string(b.size()) + " bytes)");
  const bool whole = b.size() == fileSize;
  // Where the walk needs a byte beyond b: past the end of the file, or of the prefix read.
  auto pastEnd = [&](const std::string& what) {
    return whole ? corrupt(what + " runs past the end of the file")
                 : InputError(path, "OpenEXR header longer than " + std::to_string(kHeaderBytes >> 20) +
                                        " MiB: not supported (" + what + " runs past it)");
  };
  const uint32_t flags = uint32_t(le32(b, 4)) & ~0xffu;
  const size_t maxName = (flags & kLongNamesFlag) ? 255 : 31;
  ExrHeaderFacts facts;
  PixelStorage ps;
  ps.multipart = (flags & kMultipartFlag) != 0;
  ps.tiled = (flags & kTiledFlag) != 0;
  size_t pos = 8;
  // A null-terminated string of at most maxName characters at pos.
  auto readName = [&](const char* what) {
    const size_t end = b.find('\0', pos);
    if (end == std::string::npos) throw pastEnd(std::string("a ") + what);
    if (end - pos > maxName) throw corrupt(std::string("a ") + what + " is longer than " + std::to_string(maxName) + " bytes");
    std::string s = b.substr(pos, end - pos);
    pos = end + 1;
    return s;
  };
  for (int part = 0;; ++part) {
    if (pos >= b.size()) throw pastEnd("the header");
    if (b[pos] == '\0') {  // an empty header: the end of a multi-part file's header list
      if (part == 0) throw corrupt("no attributes");
      ++pos;
      break;
    }
    for (;;) {  // attributes of one header
      if (pos >= b.size()) throw pastEnd("the header");
      if (b[pos] == '\0') {
        ++pos;
        break;
      }
      const std::string name = readName("attribute name"), type = readName("attribute type");
      if (b.size() - pos < 4) throw pastEnd("attribute '" + name + "'");
      const int32_t size = le32(b, pos);
      pos += 4;
      if (size < 0 || size_t(size) > fileSize - pos)
        throw corrupt("attribute '" + name + "' claims " + std::to_string(size) + " bytes, the file has " +
                      std::to_string(fileSize - pos) + " left");
      if (size_t(size) > b.size() - pos) throw pastEnd("attribute '" + name + "'");
      const size_t end = pos + size_t(size);
      int channels = 0;
      double bytesPerPixel = 0;
      checkValueFill(path, b, pos, end, name, type, &channels, &bytesPerPixel);
      if (part == 0 && name == "channels" && type == "chlist") facts.channels = channels, ps.pixelBytes = bytesPerPixel;
      if (part == 0 && name == "dataWindow" && type == "box2i") {
        facts.width = (long long)le32(b, pos + 8) - le32(b, pos) + 1;
        facts.height = (long long)le32(b, pos + 12) - le32(b, pos + 4) + 1;
      } else if (part == 0 && name == "compression" && type == "compression") {
        ps.compression = uint8_t(b[pos]);
      } else if (part == 0 && name == "tiles" && type == "tiledesc") {
        ps.tileWidth = (long long)uint32_t(le32(b, pos)), ps.tileHeight = (long long)uint32_t(le32(b, pos + 4));
      }
      pos = end;
    }
    if (!ps.multipart) break;
  }
  checkPixelBytes(path, facts, ps, fileSize, pos);
  return facts;
}

}  // namespace prtbake::detail
