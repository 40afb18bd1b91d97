// Fuzz target: OpenEXR files through readExr, the reader of `prtbake preview lut
// LUT.exr`, and, when the image is a square table, the preview's own use of it.
// Input: the file.
#include "fuzz_target.h"
#include "prtbake/exr.h"
#include "prtbake/preview.h"

using namespace prtbake;

PRTBAKE_FUZZ_TARGET(lut_exr) {
  fuzz::clearScratch();
  const std::string path = fuzz::writeScratch("lut.exr", std::string(reinterpret_cast<const char*>(data), size));
  ExrImage img;
  if (!fuzz::expectCleanFailure(path, [&] { img = readExr(path); })) return 0;
  if (img.width <= 0 || img.height <= 0 || img.channels.size() != img.channelNames.size())
    fuzz::fail("inconsistent ExrImage");
  std::vector<LutChannel> channels;
  for (size_t i = 0; i < img.channels.size(); ++i) {
    if (img.channels[i].size() != size_t(img.width) * size_t(img.height)) fuzz::fail("channel plane of the wrong size");
    channels.push_back({img.channelNames[i], img.channels[i].data()});
  }
  if (img.width == img.height && img.width <= 64 && !channels.empty())
    renderLutPreview(img.width, channels, "N.V", "rough", 0.0f, 1.0f, 32);
  return 0;
}
