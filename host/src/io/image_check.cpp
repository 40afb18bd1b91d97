// The walks over Radiance, PNG and JPEG files before stb_image decodes them (image_check.h).
#include "io/image_check.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <utility>

namespace prtbake::detail {
namespace {

std::string sizeText(double width, double height) { return wholeNumber(width) + "x" + wholeNumber(height); }
std::string bytesText(double bytes) { return wholeNumber(bytes) + " bytes"; }

// The resolution line of a Radiance file, "-Y H +X W" (the only orientation stb_image
// reads); false when `line` is not one.
bool parseResolution(const std::string& line, long long& height, long long& width) {
  size_t i = 0;
  auto spaces = [&] {
    const size_t start = i;
    while (i < line.size() && line[i] == ' ') ++i;
    return i > start;
  };
  auto word = [&](const char* w) {
    if (line.compare(i, std::strlen(w), w) != 0) return false;
    i += std::strlen(w);
    return true;
  };
  auto number = [&](long long& v) {
    const size_t start = i;
    for (v = 0; i < line.size() && std::isdigit(uint8_t(line[i])) && i - start < 12; ++i) v = 10 * v + (line[i] - '0');
    return i > start;
  };
  if (!(word("-Y") && spaces() && number(height) && spaces() && word("+X") && spaces() && number(width))) return false;
  spaces();
  return i == line.size();
}

}  // namespace

std::string wholeNumber(double v) {
  char text[64];
  std::snprintf(text, sizeof text, "%.0f", v);
  return text;
}

// stb_image's stbi__hdr_load: the identifier line, header lines up to an empty one (or one
// that starts with a NUL), the resolution line, then the pixels: flat RGBE when the width
// is below 8 or at least 32768, else run-length scanlines, the whole image read flat from
// the first scanline that does not start 2, 2. A header line ends at a newline or at the
// end of the file; stb_image decodes a run count of 0 forever.
std::string radianceProblem(const std::vector<unsigned char>& b) {
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
  } while (!tok.empty() && tok[0] != '\0');
  const bool ended = line(tok);
  if (tok.compare(0, 3, "-Y ") != 0) return "";  // stb reports other layouts
  long long height = 0, width = 0;
  // Up to its newline: stb_image took the line on to the next newline in the pixel data, or
  // to the end of the file, and decoded the image from there.
  const std::string printable = tok.substr(0, std::min<size_t>(32, std::find_if(tok.begin(), tok.end(), [](char c) {
                                                                     return !std::isprint(uint8_t(c));
                                                                   }) - tok.begin()));
  if (!ended) return "the resolution line (" + printable + ") is not ended by a newline";
  if (!parseResolution(tok, height, width)) return "the resolution line (" + printable + ") is not '-Y HEIGHT +X WIDTH'";
  if (width <= 0 || height <= 0 || width > (1 << 24) || height > (1 << 24)) return "";  // stb reports it
  const double flatBytes = 4.0 * double(width) * double(height);
  const bool runLength = width >= 8 && width < 32768;
  const double leastBytes = runLength ? double(height) * (4.0 + 8.0 * std::ceil(double(width) / 127.0)) : flatBytes;
  const double have = double(b.size() - pos);
  if (have < leastBytes)
    return "truncated: a " + sizeText(double(width), double(height)) + " image needs at least " + bytesText(leastBytes) +
           " of pixel data, the file has " + bytesText(have);
  const std::string truncated = "truncated Radiance HDR pixel data";
  if (!runLength) return "";
  for (long long j = 0; j < height; ++j) {
    if (b.size() - pos < 4) return truncated;
    if (b[pos] != 2 || b[pos + 1] != 2 || (b[pos + 2] & 0x80))  // stb then reads the whole image flat from here
      return double(b.size() - pos) < flatBytes ? truncated : "";
    if (((size_t(b[pos + 2]) << 8) | b[pos + 3]) != size_t(width)) return "";  // stb reports it
    pos += 4;
    for (int k = 0; k < 4; ++k) {
      long long i = 0;
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
        if ((long long)count > width - i) return "";  // stb reports "bad RLE data"
        i += count;
      }
    }
  }
  return "";
}

// The chunks as stb_image's stbi__parse_png_file meets them: IHDR gives the size, bit depth
// and colour type; the IDAT chunks up to IEND hold the deflated rows.
std::string pngProblem(const std::vector<unsigned char>& b) {
  static const unsigned char kSignature[8] = {137, 80, 78, 71, 13, 10, 26, 10};
  if (b.size() < 8 || std::memcmp(b.data(), kSignature, 8) != 0) return "";
  auto be32 = [&](size_t at) { return uint32_t(b[at]) << 24 | uint32_t(b[at + 1]) << 16 | uint32_t(b[at + 2]) << 8 | b[at + 3]; };
  double width = 0, height = 0, bitsPerPixel = 0, idat = 0;
  for (size_t pos = 8; b.size() - pos >= 8;) {
    const uint32_t length = be32(pos);
    const std::string type(reinterpret_cast<const char*>(&b[pos + 4]), 4);
    const size_t present = std::min<size_t>(length, b.size() - pos - 8);
    if (type == "IHDR" && bitsPerPixel == 0 && present >= 13) {
      width = be32(pos + 8), height = be32(pos + 12);
      const int depth = b[pos + 16], colour = b[pos + 17];
      const int channels = colour == 0 || colour == 3 ? 1 : colour == 2 ? 3 : colour == 4 ? 2 : colour == 6 ? 4 : 0;
      bitsPerPixel = double(depth * channels);
    } else if (type == "IDAT") {
      idat += double(present);
    } else if (type == "IEND") {
      break;
    }
    if (present < length || b.size() - pos - 8 - present < 4) break;  // the chunk or its CRC runs past the end
    pos += 12 + length;
  }
  if (width <= 0 || height <= 0 || bitsPerPixel <= 0) return "";  // stb reports it
  // Deflate codes a match of at most 258 bytes in 2 bits or more: 1032 bytes a byte. The
  // filter bytes and Adam7's passes only add to the rows' size.
  const double rowBytes = width * height * bitsPerPixel / 8;
  if (rowBytes > 1032.0 * idat + 1032.0)
    return "truncated: its " + bytesText(idat) + " of image data cannot hold a " + sizeText(width, height) + " image of " +
           std::to_string(int(bitsPerPixel)) + " bits a pixel (" + bytesText(rowBytes) +
           "; deflate expands at most 1032-fold)";
  return "";
}

// The marker segments as stbi__decode_jpeg_image meets them (fill bytes before SOI, and
// garbage and fill bytes between segments, skipped; entropy-coded data after a start of
// scan passed over to the next marker), with each DHT table's counts read as stb_image
// reads them, past the segment's end while its length says more tables follow. stb_image
// 2.27 neither zeroes its decoder nor checks that a scan's tables were defined: a scan that
// uses a Huffman or quantization table no segment before it defined decodes with whatever
// the heap held there (an AC table's slow path then indexes its arrays with a stale
// offset). Which tables a scan uses follows stb's decoder: a baseline scan its components'
// DC and AC Huffman tables; a progressive scan the DC table in a first DC scan (Ss = 0,
// Ah = 0), none in a DC refinement, the AC table in an AC scan; every scan its components'
// quantization tables.
std::string jpegProblem(const std::vector<unsigned char>& b) {
  size_t start = 0;  // stb takes any number of fill bytes (0xFF) before the SOI marker
  while (start < b.size() && b[start] == 0xFF) ++start;
  if (start == 0 || start == b.size() || b[start] != 0xD8) return "";  // not a JPEG
  auto at = [&](size_t i) { return i < b.size() ? size_t(b[i]) : 0; };  // stb reads 0 past the end
  double width = 0, height = 0, entropyBytes = 0;
  bool inScan = false, progressive = false;
  bool huffman[2][4] = {}, quant[4] = {};  // defined so far: [DC, AC][id], [id]
  std::vector<std::pair<size_t, size_t>> components;  // the frame's (id, quantization table)
  for (size_t pos = start + 1; pos + 1 < b.size();) {
    const size_t m = b[pos + 1];
    if (b[pos] != 0xFF || m == 0xFF || m == 0x00 || (m >= 0xD0 && m <= 0xD7)) {  // no segment starts here
      entropyBytes += inScan;
      ++pos;
      continue;
    }
    if (m == 0xD9) break;  // end of image
    const size_t length = at(pos + 2) << 8 | at(pos + 3);
    if ((m == 0xC0 || m == 0xC1 || m == 0xC2) && width == 0) {  // the frame: baseline, extended or progressive
      height = double(at(pos + 5) << 8 | at(pos + 6)), width = double(at(pos + 7) << 8 | at(pos + 8));
      progressive = m == 0xC2;
      for (size_t k = 0, n = at(pos + 9); k < n; ++k) components.emplace_back(at(pos + 10 + 3 * k), at(pos + 12 + 3 * k));
    }
    if (m == 0xDB)
      for (size_t t = pos + 4, left = length; left > 2;) {  // as the DHT tables below
        const size_t bytes = at(t) >> 4 ? 129 : 65;
        if (at(t) >> 4 < 2 && (at(t) & 15) < 4) quant[at(t) & 15] = true;
        t += bytes;
        left = left - 2 > bytes ? left - bytes : 2;
      }
    if (m == 0xC4)
      for (size_t t = pos + 4, left = length; left > 2;) {  // 2: the length field itself
        size_t codes = 0;
        for (size_t i = 1; i <= 16; ++i) codes += at(t + i);
        if (codes > 256) return "a Huffman table of " + std::to_string(codes) + " codes (at most 256)";
        if (at(t) >> 4 < 2 && (at(t) & 15) < 4) huffman[at(t) >> 4][at(t) & 15] = true;
        t += 17 + codes;
        left = left - 2 > 17 + codes ? left - 17 - codes : 2;
      }
    if (m == 0xDA) {
      const size_t n = at(pos + 4), ss = at(pos + 5 + 2 * n), ah = at(pos + 7 + 2 * n) >> 4;
      for (size_t k = 0; k < n; ++k) {
        const size_t id = at(pos + 5 + 2 * k), dc = at(pos + 6 + 2 * k) >> 4, ac = at(pos + 6 + 2 * k) & 15;
        const auto c = std::find_if(components.begin(), components.end(), [&](const auto& f) { return f.first == id; });
        if (c == components.end() || dc > 3 || ac > 3 || c->second > 3) continue;  // stb reports it
        auto undefined = [&](const char* table, size_t i) {
          return "a scan (at byte " + std::to_string(pos) + ") uses " + table + " " + std::to_string(i) +
                 ", which no segment before it defines";
        };
        if (!quant[c->second]) return undefined("quantization table", c->second);
        if ((!progressive || (ss == 0 && ah == 0)) && !huffman[0][dc]) return undefined("DC Huffman table", dc);
        if ((!progressive || ss > 0) && !huffman[1][ac]) return undefined("AC Huffman table", ac);
      }
    }
    inScan = m == 0xDA;
    pos += 2 + length;
  }
  // Every 8x8 block of the full-resolution component codes its DC difference in 1 bit or
  // more (Huffman codes are at least 1 bit long; stb_image reads no arithmetic coding), in
  // the baseline scan or a progressive image's first DC scan.
  const double blocks = std::ceil(width / 8) * std::ceil(height / 8);
  if (blocks > 0 && 8 * entropyBytes < blocks)
    return "truncated: its " + bytesText(entropyBytes) + " of entropy-coded data cannot hold a " + sizeText(width, height) +
           " image (at least 1 bit for each of its " + wholeNumber(blocks) + " 8x8 blocks)";
  return "";
}

}  // namespace prtbake::detail
