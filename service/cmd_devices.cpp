// prtbake devices: list OpenCL platforms/devices and mark the default.
#include <iostream>

#include "cli.h"
#include "prtbake/runtime.h"

namespace prtbake::cli {
namespace {

int runDevices(const CommandLine& cl) {
  const auto devices = listDevices();
  if (devices.empty()) {
    std::cout << "no OpenCL devices found\n";
    return 1;
  }
  const int chosen = resolveDevice(cl.device());
  for (const auto& d : devices) {
    std::cout << (d.index == chosen ? "* " : "  ") << d.index << "  " << d.type << "  " << d.name << "  ["
              << d.platform << "]  " << d.computeUnits << " compute units, "
              << (d.globalMemBytes >> 20) << " MiB" << (d.fp64 ? ", fp64" : "") << "\n";
  }
  std::cout << "(* = the device chosen by --device/$PRTBAKE_DEVICE, default auto)\n";
  return 0;
}

PRTBAKE_COMMAND(Command{"devices", "list OpenCL platforms and devices, mark the default",
                        "prtbake devices [--device SPEC]", {}, 0, 0, runDevices});

}  // namespace
}  // namespace prtbake::cli
