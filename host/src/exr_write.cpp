// OpenEXR writer: named float/half channels, written to a temp file then renamed.
#include <ImfChannelList.h>
#include <ImfEnvmapAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>
#include <ImfStandardAttributes.h>
#include <ImfStringAttribute.h>
#include <half.h>

#include <cstdio>

#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/exr.h"

namespace prtbake {

void writeExr(const std::string& path, int width, int height, const std::vector<ExrChannel>& channels,
              const ExrWriteOptions& options) {
  if (width <= 0 || height <= 0 || channels.empty())
    throw OutputError(path, "nothing to write (empty image)");
  // AtomicFile owns the temp name and its removal on failure; OpenEXR writes the
  // temp path itself, then commit() fsyncs and renames it.
  AtomicFile out(path);
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
      Imf::OutputFile file(out.tempPath().c_str(), header);
      file.setFrameBuffer(fb);
      file.writePixels(height);
    }
  } catch (const std::exception& e) {
    throw OutputError(path, std::string("OpenEXR write failed: ") + e.what());
  }
  out.commit();
}

}  // namespace prtbake
