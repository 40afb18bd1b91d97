// prtbake/exr.h: writing OpenEXR images with named channels, atomically.
#pragma once

#include <string>
#include <vector>

namespace prtbake {

struct ExrChannel {
  std::string name;         // "R", "G", "B", "A", or any name
  const float* data;        // width*height values, row 0 (top) first
};

struct ExrWriteOptions {
  bool half = false;                       // store 16-bit half instead of float32
  std::vector<std::pair<std::string, std::string>> attributes;  // string header attributes
  int envmap = -1;                         // -1: none; 0: lat-long; 1: cube (Imf::Envmap)
};

// Writes a scanline OpenEXR file (ZIP compressed) at `path` via a temp file and
// rename: the file appears whole or not at all. Throws OutputError.
void writeExr(const std::string& path, int width, int height, const std::vector<ExrChannel>& channels,
              const ExrWriteOptions& options = {});

// The same file's bytes, for a caller that commits several outputs together.
std::string exrBytes(int width, int height, const std::vector<ExrChannel>& channels,
                     const ExrWriteOptions& options = {});

struct ExrImage {
  int width = 0, height = 0;
  std::vector<std::string> channelNames;     // in the file's (alphabetical) order
  std::vector<std::vector<float>> channels;  // one plane per name, row 0 first
  const std::vector<float>* channel(const std::string& name) const;
};

// Reads every channel of an OpenEXR file (level 0, data window) as float planes.
// Throws InputError naming the file.
ExrImage readExr(const std::string& path);

}  // namespace prtbake
