// env_irradiance: an asset-pipeline step on the prtbake library.
// Projects an HDR environment (OpenEXR, .hdr, a cross, or a directory of six
// faces) onto SH order 3 and writes the irradiance coefficients as JSON.
//
//   env_irradiance sky.exr sky_irradiance.json
#include <cstdio>
#include <exception>

#include "prtbake/env.h"
#include "prtbake/envmap.h"
#include "prtbake/runtime.h"

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: env_irradiance INPUT OUT.json\n");
    return 2;
  }
  try {
    prtbake::EnvMap env = prtbake::loadEnvironment(argv[1]);
    prtbake::Runtime runtime;  // default device: $PRTBAKE_DEVICE, else a GPU, else the CPU
    prtbake::EnvProjectOptions options;
    options.order = 3;
    options.quantity = prtbake::ShQuantity::Irradiance;
    const prtbake::EnvProjectResult result = prtbake::projectEnvironment(runtime, env, options);
    prtbake::writeShJson(argv[2], result.coeffs, "");  // the JSON states its conventions
    std::printf("E00 = %.6g %.6g %.6g (%s)\n", result.coeffs.rgb[0][0], result.coeffs.rgb[0][1],
                result.coeffs.rgb[0][2], runtime.deviceLabel().c_str());
    return 0;
  } catch (const std::exception& e) {  // prtbake::Error names the file and what is wrong
    std::fprintf(stderr, "env_irradiance: %s\n", e.what());
    return 1;
  }
}
