// What a device's own compiler makes of kernel variants: builds each "file<TAB>options" line of
// LIST on the device and prints, per kernel, the private and local memory and the largest
// work-group that the driver reports, then the build log when it says anything. With NVIDIA's
// OpenCL, `--extra -cl-nv-verbose` makes that log carry ptxas's registers, stack frame and
// spills: bench/bench_gpu.sh gives it the variants its GPU steps built (PRTBAKE_BUILD_LOG), so
// that bench/gpu_static.sh's figures (clang and ptxas here, without a GPU) meet the driver's.
//
//   bench_kernels LIST [--device D] [--extra OPTIONS]
#include <cstdio>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include "prtbake/runtime.h"

using namespace prtbake;

int main(int argc, char** argv) try {
  if (argc < 2) {
    std::fprintf(stderr, "usage: bench_kernels LIST [--device D] [--extra OPTIONS]\n");
    return 2;
  }
  std::string device, extra;
  for (int i = 2; i < argc; i += 2) {
    const std::string a = argv[i];
    if (i + 1 < argc && a == "--device") device = argv[i + 1];
    else if (i + 1 < argc && a == "--extra") extra = argv[i + 1];
    else {
      std::fprintf(stderr, "bench_kernels: unknown option or no value: %s\n", a.c_str());
      return 2;
    }
  }
  std::ifstream in(argv[1]);
  if (!in) {
    std::fprintf(stderr, "bench_kernels: cannot read %s\n", argv[1]);
    return 1;
  }
  std::set<std::string> lines;  // a variant once, however often it was built
  for (std::string line; std::getline(in, line);)
    if (line.find('\t') != std::string::npos) lines.insert(line);
  Runtime rt(device);
  std::printf("device: %s; %zu variants; extra build options: '%s'\n", rt.deviceLabel().c_str(), lines.size(),
              extra.c_str());
  std::printf("file\toptions\tkernel\tprivate bytes\tlocal bytes\tlargest group\n");
  for (const std::string& line : lines) {
    const std::string file = line.substr(0, line.find('\t')), options = line.substr(line.find('\t') + 1);
    cl::Program p = rt.program(file, extra.empty() ? options : options + " " + extra);
    std::vector<cl::Kernel> kernels;
    p.createKernels(&kernels);
    for (cl::Kernel& k : kernels)
      std::printf("%s\t%s\t%s\t%llu\t%llu\t%zu\n", file.c_str(), options.c_str(),
                  k.getInfo<CL_KERNEL_FUNCTION_NAME>().c_str(),
                  (unsigned long long)k.getWorkGroupInfo<CL_KERNEL_PRIVATE_MEM_SIZE>(rt.device()),
                  (unsigned long long)k.getWorkGroupInfo<CL_KERNEL_LOCAL_MEM_SIZE>(rt.device()),
                  k.getWorkGroupInfo<CL_KERNEL_WORK_GROUP_SIZE>(rt.device()));
    const std::string log = p.getBuildInfo<CL_PROGRAM_BUILD_LOG>(rt.device());
    if (log.find_first_not_of(" \t\r\n") != std::string::npos) std::printf("build log:\n%s\n", log.c_str());
  }
  return 0;
} catch (const std::exception& e) {  // a bad argument or a missing device: one line, no abort
  std::fprintf(stderr, "%s: %s\n", argv[0], e.what());
  return 1;
}
