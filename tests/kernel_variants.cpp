// Lists every program variant the host can build, one "file<TAB>options" line each, from
// the option builders the products call (kernel_options.h), for scripts/nvptx_check.sh.
// SH orders are sampled where they only change loop bounds: the smallest, the defaults,
// each unrolling or vector-width threshold and its neighbour, the largest.
#include <cstdio>
#include <string>

#include "core/kernel_options.h"
#include "prtbake/envmap.h"
#include "prtbake/glossy.h"
#include "prtbake/lut.h"
#include "prtbake/prefilter.h"
#include "prtbake/sh.h"
#include "prtbake/transport.h"

using namespace prtbake;

namespace {
void print(const char* file, const std::string& options) { std::printf("%s\t%s\n", file, options.c_str()); }
}  // namespace

int main() {
  for (int order : {1, 2, 3, 4, 5, 8, 9, kMaxShOrder})
    for (int vw : {1, 8, 16})
      for (EnvStorage s : {EnvStorage::Float, EnvStorage::Half, EnvStorage::Code8})
        print("env_project.cl", detail::envProjectOptions(order, vw, s));
  for (LutNdf ndf : {LutNdf::Ggx, LutNdf::Beckmann})
    for (LutVisibility vis : {LutVisibility::SmithCorrelated, LutVisibility::SmithSeparable, LutVisibility::SchlickGgx})
      for (bool cloth : {false, true})
        for (int samples : {1024, 1023})  // a multiple of the kernel's SIMD width, and not
          for (LutDirections dirs : {LutDirections::Table, LutDirections::PreciseTrig, LutDirections::NativeTrig})
            for (bool fast : {false, true}) {
              LutOptions o;
              o.ndf = ndf, o.visibility = vis, o.cloth = cloth, o.samples = samples, o.directions = dirs, o.fastMath = fast;
              print("lut.cl", detail::lutOptions(o));
            }
  for (int order : {1, 3, 4, kMaxTransportOrder})
    for (bool visibility : {false, true})
      for (int channels : {1, 3})
        for (int packet : {0, 8, 16})
          for (int lanes : {1, 8, 32})  // the scalar kernels' work-items per vertex
            if (packet == 0 || lanes == 1) print("transport.cl", detail::transportOptions(order, visibility, channels, packet, lanes));
  for (int order : {1, 3, kMaxTransportOrder})
    for (int channels : {1, 3})
      for (int light : {1, 3, 8, kMaxShOrder})
        for (bool shBackground : {false, true})
          print("preview.cl", detail::previewMeshOptions(order, channels, light, shBackground));
  for (int out = kMinGlossyOrder; out <= kMaxGlossyOrder; ++out)
    for (int in = kMinGlossyOrder; in <= kMaxGlossyOrder; ++in)
      for (bool visibility : {false, true})
        for (int lanes : {1, 8, 32}) print("glossy.cl", detail::glossyOptions(out, in, visibility, lanes));
  for (int out = kMinGlossyOrder; out <= kMaxGlossyOrder; ++out)
    for (int light : {1, 3, kMaxShOrder})
      for (bool shBackground : {false, true})
        print("glossy_preview.cl", detail::glossyPreviewOptions(out, light, shBackground));
  for (PrefilterLobe lobe : {PrefilterLobe::Ggx, PrefilterLobe::Charlie, PrefilterLobe::Lambertian})
    for (int vw : {1, 8, 16}) print("prefilter.cl", detail::prefilterCutOptions(lobe, vw));
  print("prefilter.cl", detail::prefilterSampledOptions());
  for (int order : {2, 3})
    for (int env = order; env <= kMaxTransportOrder; ++env)
      for (int packet : {0, 16})
        for (int lanes : {1, 32})
          if (packet == 0 || lanes == 1) print("probes.cl", detail::probesOptions(order, env, packet, lanes));
  print("lightmap.cl", "");
  print("sh_eval.cl", "");
  return 0;
}
