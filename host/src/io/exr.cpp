// OpenEXR writer: named float/half channels, written to a temp file then renamed.
#include <ImfChannelList.h>
#include <ImfEnvmapAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfIO.h>
#include <ImfOutputFile.h>
#include <ImfStandardAttributes.h>
#include <ImfStringAttribute.h>
#include <half.h>

#include <cstdio>
#include <cstring>
#include <memory>

#include "io/exr_check.h"
#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/limits.h"
#include "prtbake/exr.h"

namespace prtbake {

namespace {

// An OpenEXR stream into a string (exrBytes).
class StringOStream : public Imf::OStream {
 public:
  explicit StringOStream(std::string& s) : Imf::OStream("memory"), s_(s) {}
  void write(const char c[], int n) override {
    if (pos_ + uint64_t(n) > s_.size()) s_.resize(pos_ + uint64_t(n));
    std::memcpy(&s_[pos_], c, size_t(n));
    pos_ += uint64_t(n);
  }
  uint64_t tellp() override { return pos_; }
  void seekp(uint64_t pos) override { pos_ = pos; }

 private:
  std::string& s_;
  uint64_t pos_ = 0;
};

// The header and frame buffer of an image, then `open(header)` gives the Imf::OutputFile.
template <class Open>
void encodeExr(const std::string& what, int width, int height, const std::vector<ExrChannel>& channels,
               const ExrWriteOptions& options, Open&& open) {
  if (width <= 0 || height <= 0 || channels.empty())
    throw OutputError(what, "nothing to write (empty image)");
  try {
    Imf::Header header(width, height);
    header.compression() = Imf::ZIP_COMPRESSION;
    for (const auto& [k, v] : options.attributes) header.insert(k, Imf::StringAttribute(v));
    if (options.envmap == 0) Imf::addEnvmap(header, Imf::ENVMAP_LATLONG);
    if (options.envmap == 1) Imf::addEnvmap(header, Imf::ENVMAP_CUBE);
    const Imf::PixelType type = options.half ? Imf::HALF : Imf::FLOAT;
    for (const auto& c : channels) header.channels().insert(c.name, Imf::Channel(type));
    const size_t n = size_t(width) * size_t(height);
    std::vector<std::vector<half>> halves;
    Imf::FrameBuffer fb;
    for (const auto& c : channels) {
      if (options.half) {
        halves.emplace_back(n);
        for (size_t i = 0; i < n; ++i) halves.back()[i] = half(c.data[i]);
        fb.insert(c.name, Imf::Slice(Imf::HALF, reinterpret_cast<char*>(halves.back().data()), sizeof(half),
                                     sizeof(half) * size_t(width)));
      } else {
        fb.insert(c.name, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(const_cast<float*>(c.data)),
                                     sizeof(float), sizeof(float) * size_t(width)));
      }
    }
    {
      std::unique_ptr<Imf::OutputFile> file = open(header);
      file->setFrameBuffer(fb);
      file->writePixels(height);
    }
  } catch (const std::exception& e) {
    throw OutputError(what, std::string("OpenEXR write failed: ") + e.what());
  }
}

}  // namespace

void writeExr(const std::string& path, int width, int height, const std::vector<ExrChannel>& channels,
              const ExrWriteOptions& options) {
  // AtomicFile owns the temp file and its removal on failure; OpenEXR writes it through
  // writerPath(), then commit() fsyncs and renames it.
  AtomicFile out(path);
  encodeExr(path, width, height, channels, options, [&](const Imf::Header& h) {
    return std::make_unique<Imf::OutputFile>(out.writerPath().c_str(), h);
  });
  out.commit();
}

std::string exrBytes(int width, int height, const std::vector<ExrChannel>& channels, const ExrWriteOptions& options) {
  std::string bytes;
  StringOStream stream(bytes);
  encodeExr("exr", width, height, channels, options,
            [&](const Imf::Header& h) { return std::make_unique<Imf::OutputFile>(stream, h); });
  return bytes;
}

const std::vector<float>* ExrImage::channel(const std::string& name) const {
  for (size_t i = 0; i < channelNames.size(); ++i)
    if (channelNames[i] == name) return &channels[i];
  return nullptr;
}

ExrImage readExr(const std::string& path) {
  // A clear error for missing files and directories, and for headers that lie about
  // their size, before the OpenEXR library allocates what they claim.
  const detail::ExrHeaderFacts facts = detail::checkExrHeader(path);
  checkInputMemory(path, "a " + std::to_string(facts.width) + "x" + std::to_string(facts.height) + " image of " +
                             std::to_string(facts.channels) + " channels",
                   4.0 * double(facts.width) * double(facts.height) * double(facts.channels));
  ExrImage out;
  try {
    Imf::InputFile file(path.c_str());
    const Imath::Box2i dw = file.header().dataWindow();
    // In long long: a corrupt data window can span more than INT_MAX pixels.
    const long long w = (long long)dw.max.x - dw.min.x + 1, h = (long long)dw.max.y - dw.min.y + 1;
    if (w <= 0 || h <= 0) throw InputError(path, "empty data window");
    size_t channelCount = 0;
    for (auto it = file.header().channels().begin(); it != file.header().channels().end(); ++it) ++channelCount;
    checkInputMemory(path, "a " + std::to_string(w) + "x" + std::to_string(h) + " image of " +
                               std::to_string(channelCount) + " channels",
                     4.0 * double(w) * double(h) * double(channelCount));
    out.width = int(w), out.height = int(h);
    Imf::FrameBuffer fb;
    for (auto it = file.header().channels().begin(); it != file.header().channels().end(); ++it) {
      out.channelNames.push_back(it.name());
      out.channels.emplace_back(size_t(out.width) * size_t(out.height));
    }
    // Slice::Make places the data window's origin at the buffer's start (the library does the
    // offset arithmetic; a base pointer computed here would lie outside the allocation).
    for (size_t i = 0; i < out.channels.size(); ++i)
      fb.insert(out.channelNames[i], Imf::Slice::Make(Imf::FLOAT, out.channels[i].data(), dw, sizeof(float),
                                                      sizeof(float) * size_t(out.width)));
    file.setFrameBuffer(fb);
    file.readPixels(dw.min.y, dw.max.y);
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw InputError(path, std::string("cannot read OpenEXR: ") + e.what());
  }
  return out;
}

}  // namespace prtbake
