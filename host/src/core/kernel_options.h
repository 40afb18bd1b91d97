// Private: the build options of every program the host builds, one function per kernel
// file, so that tests/kernel_variants.cpp can list every variant for the portability
// check (scripts/nvptx_check.sh) from the same code the products use.
#pragma once

#include <string>


namespace prtbake {
// The products' option types (prtbake/envmap.h, lut.h, prefilter.h), declared here only, so
// that this core header includes no product.
enum class EnvStorage;
struct LutOptions;
enum class PrefilterLobe;
}  // namespace prtbake

namespace prtbake::detail {

// " -DRAY_LANES=L" for the one-ray kernels' work-items per item (kernels/lanes.clh), nothing for 1.
inline std::string rayLanesOption(int lanes) { return lanes > 1 ? " -DRAY_LANES=" + std::to_string(lanes) : ""; }

// env_project.cl: SH order, vector width (1, 8, 16) and texel storage.
std::string envProjectOptions(int order, int vectorWidth, EnvStorage storage);
// lut.cl
std::string lutOptions(const LutOptions& o);
// transport.cl: SH order, visibility tested, channels (1 or 3), packet width (0, 8, 16), the
// scalar kernels' work-items per vertex (TransportOptions::rayLanes).
std::string transportOptions(int order, bool visibility, int channels, int packetWidth, int rayLanes = 1);
// preview.cl: transport order and channels, lighting order, SH or image background.
std::string previewMeshOptions(int order, int channels, int lightOrder, bool shBackground);
// glossy.cl: output and input SH orders (the kernel's basis goes to the larger), visibility.
std::string glossyOptions(int orderOut, int orderIn, bool visibility, int rayLanes = 1);
// glossy_preview.cl: the matrices' output order, lighting order, SH or image background.
std::string glossyPreviewOptions(int orderOut, int lightOrder, bool shBackground);
// prefilter.cl, prefilter_cut: the lobe and texels per work-item (1, 8, 16);
// prefilter_sampled: one texel per work-item.
std::string prefilterCutOptions(PrefilterLobe lobe, int vectorWidth);
std::string prefilterSampledOptions();
// probes.cl: the probes' SH order, the environment's, and the packet width (0 or 16).
std::string probesOptions(int order, int envOrder, int packetWidth, int rayLanes = 1);

}  // namespace prtbake::detail
