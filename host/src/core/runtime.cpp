// OpenCL runtime: device choice, context/queue, program building and caching.
#include "prtbake/runtime.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/embedded_kernels.h"
#include "prtbake/atomic_file.h"
#include "prtbake/clock.h"
#include "prtbake/error.h"
#include "prtbake/hash.h"

namespace prtbake {
namespace {

struct FlatDevice {
  cl::Platform platform;
  cl::Device device;
};

std::vector<FlatDevice> flatDevices() {
  std::vector<FlatDevice> out;
  std::vector<cl::Platform> platforms;
  try {
    cl::Platform::get(&platforms);
  } catch (const cl::Error&) {
    return out;  // no ICD installed: an empty list, reported by the caller
  }
  for (auto& p : platforms) {
    std::vector<cl::Device> devices;
    try {
      p.getDevices(CL_DEVICE_TYPE_ALL, &devices);
    } catch (const cl::Error&) {
      continue;
    }
    for (auto& d : devices) out.push_back({p, d});
  }
  return out;
}

DeviceInfo describe(const FlatDevice& fd, int index) {
  DeviceInfo info;
  info.index = index;
  info.platform = fd.platform.getInfo<CL_PLATFORM_NAME>();
  info.name = fd.device.getInfo<CL_DEVICE_NAME>();
  cl_device_type t = fd.device.getInfo<CL_DEVICE_TYPE>();
  info.type = (t & CL_DEVICE_TYPE_GPU) ? "gpu" : (t & CL_DEVICE_TYPE_CPU) ? "cpu" : "other";
  info.computeUnits = fd.device.getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>();
  info.globalMemBytes = fd.device.getInfo<CL_DEVICE_GLOBAL_MEM_SIZE>();
  info.fp64 = fd.device.getInfo<CL_DEVICE_EXTENSIONS>().find("cl_khr_fp64") != std::string::npos;
  return info;
}

std::string trim(std::string s) {
  while (!s.empty() && (s.back() == '\0' || s.back() == ' ' || s.back() == '\n')) s.pop_back();
  return s;
}

// Raw text of one kernel file: from PRTBAKE_KERNEL_DIR when set, else embedded.
bool rawKernelText(const std::string& file, std::string& text, std::string& path) {
  if (const char* dir = std::getenv("PRTBAKE_KERNEL_DIR"); dir && *dir) {
    path = std::string(dir) + "/" + file;
    std::ifstream in(path, std::ios::binary);
    if (!in) return false;
    std::ostringstream ss;
    ss << in.rdbuf();
    text = ss.str();
    return true;
  }
  for (const auto* k = detail::kEmbeddedKernels; k->name; ++k) {
    if (file == k->name) {
      text = k->text;
      path = k->path;
      return true;
    }
  }
  return false;
}

void expandInto(const std::string& file, std::ostringstream& out, std::vector<std::string>& stack,
                std::vector<std::string>& done) {
  std::string text, path;
  if (!rawKernelText(file, text, path))
    throw DeviceError(file, "kernel source not found (embedded table or PRTBAKE_KERNEL_DIR)");
  for (const auto& s : stack)
    if (s == file) throw DeviceError(file, "recursive #include in kernel sources");
  stack.push_back(file);
  out << "#line 1 \"" << path << "\"\n";
  std::istringstream in(text);
  std::string line;
  int lineNo = 0;
  while (std::getline(in, line)) {
    ++lineNo;
    const auto first = line.find_first_not_of(" \t");
    if (first != std::string::npos && line.compare(first, 8, "#include") == 0) {
      const auto q0 = line.find('"');
      const auto q1 = q0 == std::string::npos ? q0 : line.find('"', q0 + 1);
      if (q1 != std::string::npos) {
        const std::string inc = line.substr(q0 + 1, q1 - q0 - 1);
        bool seen = false;
        for (const auto& d : done) seen = seen || d == inc;
        if (!seen) {  // every kernel header is included once (an implicit #pragma once)
          done.push_back(inc);
          expandInto(inc, out, stack, done);
        }
        out << "#line " << lineNo + 1 << " \"" << path << "\"\n";
        continue;
      }
    }
    out << line << "\n";
  }
  stack.pop_back();
}

// PRTBAKE_BUILD_LOG=FILE: each program a process builds (kernel file and options) is
// appended to FILE as one line, "file<TAB>options", in one write (processes may share the
// file). scripts/nvptx_check.sh compiles every logged variant for another target.
void logProgram(const std::string& file, const std::string& options) {
  const char* log = std::getenv("PRTBAKE_BUILD_LOG");
  if (!log || !*log) return;
  const std::string line = file + "\t" + options + "\n";
  const int fd = ::open(log, O_WRONLY | O_APPEND | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) return;
  [[maybe_unused]] const ssize_t n = ::write(fd, line.data(), line.size());
  ::close(fd);
}

}  // namespace

std::string kernelSource(const std::string& file) {
  std::ostringstream out;
  std::vector<std::string> stack, done;
  expandInto(file, out, stack, done);
  return out.str();
}

std::vector<DeviceInfo> listDevices() {
  std::vector<DeviceInfo> out;
  auto flat = flatDevices();
  for (size_t i = 0; i < flat.size(); ++i) out.push_back(describe(flat[i], int(i)));
  return out;
}

int resolveDevice(const std::string& specIn) {
  std::string spec = specIn;
  if (spec.empty()) {
    const char* env = std::getenv("PRTBAKE_DEVICE");
    spec = (env && *env) ? env : "auto";
  }
  auto devices = listDevices();
  if (devices.empty())
    throw DeviceError("OpenCL", "no OpenCL device found (is an ICD such as pocl-opencl-icd installed?)");
  if (spec == "auto" || spec == "gpu" || spec == "cpu") {
    const std::string want = spec == "auto" ? "gpu" : spec;
    for (const auto& d : devices)
      if (d.type == want) return d.index;
    if (spec == "auto") return devices.front().index;
    throw DeviceError("--device " + spec, "no OpenCL " + want + " device found");
  }
  char* end = nullptr;
  long n = std::strtol(spec.c_str(), &end, 10);
  if (spec.empty() || *end != '\0')
    throw UsageError("--device " + spec, "expected auto, cpu, gpu or a device index");
  if (n < 0 || n >= long(devices.size()))
    throw UsageError("--device " + spec, "no device with that index (there are " +
                                             std::to_string(devices.size()) + ")");
  return int(n);
}

namespace {
std::mutex gLastLabelMutex;
std::string gLastLabel;
}  // namespace

Runtime::Runtime(const std::string& deviceSpec) {
  const int index = resolveDevice(deviceSpec);
  auto flat = flatDevices();
  device_ = flat.at(size_t(index)).device;
  info_ = describe(flat[size_t(index)], index);
  try {
    context_ = cl::Context(device_);
    queue_ = cl::CommandQueue(context_, device_, CL_QUEUE_PROFILING_ENABLE);
  } catch (const cl::Error& e) {
    throw DeviceError(deviceLabel(), std::string("cannot create a context: ") + e.what() + " (" +
                                         clErrorName(e.err()) + ")");
  }
  loopGroupSize_ = std::min(defaultLoopGroupSize(info_), maxWorkGroupSize());
  if (const char* env = std::getenv("PRTBAKE_GROUP_SIZE"); env && *env) {
    char* end = nullptr;
    const long long n = std::strtoll(env, &end, 10);
    if (*end || n < 1 || size_t(n) > maxWorkGroupSize())
      throw UsageError("PRTBAKE_GROUP_SIZE", "\"" + std::string(env) + "\" is not a work-group size of 1 to " +
                                                 std::to_string(maxWorkGroupSize()) + " on " + deviceLabel());
    loopGroupSize_ = size_t(n);
  }
  std::lock_guard<std::mutex> lock(gLastLabelMutex);
  gLastLabel = deviceLabel();
}

size_t defaultLoopGroupSize(const DeviceInfo& device) { return device.type == "cpu" ? 16 : 64; }

std::string Runtime::deviceLabel() const { return trim(info_.name) + " (" + trim(info_.platform) + ")"; }

std::string lastDeviceLabel() {
  std::lock_guard<std::mutex> lock(gLastLabelMutex);
  return gLastLabel;
}

std::string describeClError(const cl::Error& e, const std::string& deviceLabel) {
  const int code = e.err();
  const bool memory = code == CL_MEM_OBJECT_ALLOCATION_FAILURE || code == CL_OUT_OF_RESOURCES ||
                      code == CL_INVALID_BUFFER_SIZE || code == CL_OUT_OF_HOST_MEMORY;
  const std::string device = deviceLabel.empty() ? std::string("OpenCL") : deviceLabel;
  return device + ": " + (memory ? "out of device memory: " : "OpenCL error: ") + e.what() + " (" +
         clErrorName(code) + ")";
}

size_t Runtime::maxWorkGroupSize() const { return device_.getInfo<CL_DEVICE_MAX_WORK_GROUP_SIZE>(); }

cl::Program Runtime::program(const std::string& file, const std::string& options) {
  std::lock_guard<std::mutex> lock(mutex_);
  const std::string key = file + "\n" + options;
  if (auto it = programs_.find(key); it != programs_.end()) return it->second;
  const auto t0 = std::chrono::steady_clock::now();
  logProgram(file, options);
  const std::string source = kernelSource(file);
  const std::string fullOptions = "-cl-std=CL1.2 " + options;
  // PoCL keeps compiled kernels in POCL_CACHE_DIR; prtbake keeps no binaries of its own:
  // fetching a program's binary makes PoCL compile every kernel of the program (0.2-0.6 s
  // at a cold start, measured) for about 30 ms saved per program on later runs.
  // PoCL 3.1 writes a program's cache entry by removing it first and fails the build when a
  // process sharing the cache removed it in between (5 failed builds in about 1,400 processes
  // started eight at a time on an empty cache). A failure whose log names no compiler error is
  // tried again, twice at most: none failed in 2,000 more, 10 of them saved by a retry. So is
  // one whose compiler could not rename its preprocessed source into the cache ("unable to rename
  // temporary ... No such file or directory": once in CI's queue load test, where workers sharing
  // the cache are killed every second).
  cl::Program program;
  for (int attempt = 0;; ++attempt) {
    program = cl::Program(context_, source);
    std::string log;
    try {
      program.build({device_}, fullOptions.c_str());
      break;
    } catch (const cl::Error&) {
      try {
        log = program.getBuildInfo<CL_PROGRAM_BUILD_LOG>(device_);
      } catch (...) {
      }
    }
    const bool cacheRace = log.find("unable to rename temporary") != std::string::npos;
    if (attempt == 2 || (log.find("error") != std::string::npos && !cacheRace))
      throw DeviceError(file, "kernel build failed on " + deviceLabel() + " with options '" +
                                  fullOptions + "':\n" + trim(log));
  }
  buildSeconds_ += secondsSince(t0);
  programs_.emplace(key, program);
  return program;
}

cl::Kernel Runtime::kernel(const std::string& file, const std::string& name,
                           const std::string& options) {
  cl::Program p = program(file, options);
  const std::string key = file + "\n" + name + "\n" + options;
  std::lock_guard<std::mutex> lock(mutex_);
  if (auto it = kernels_.find(key); it != kernels_.end()) return it->second;
  try {
    // Created once: PoCL loads the kernel's machine code on each clCreateKernel
    // (~0.1 ms, as much as a small launch).
    return kernels_[key] = cl::Kernel(p, name.c_str());
  } catch (const cl::Error& e) {
    throw DeviceError(file, "no kernel named '" + name + "' (" + clErrorName(e.err()) + ")");
  }
}

const char* clErrorName(int code) {
  switch (code) {
#define PRTBAKE_CL_ERR(x) \
  case x:                 \
    return #x;
    PRTBAKE_CL_ERR(CL_SUCCESS)
    PRTBAKE_CL_ERR(CL_DEVICE_NOT_FOUND)
    PRTBAKE_CL_ERR(CL_DEVICE_NOT_AVAILABLE)
    PRTBAKE_CL_ERR(CL_COMPILER_NOT_AVAILABLE)
    PRTBAKE_CL_ERR(CL_MEM_OBJECT_ALLOCATION_FAILURE)
    PRTBAKE_CL_ERR(CL_OUT_OF_RESOURCES)
    PRTBAKE_CL_ERR(CL_OUT_OF_HOST_MEMORY)
    PRTBAKE_CL_ERR(CL_BUILD_PROGRAM_FAILURE)
    PRTBAKE_CL_ERR(CL_INVALID_VALUE)
    PRTBAKE_CL_ERR(CL_INVALID_DEVICE)
    PRTBAKE_CL_ERR(CL_INVALID_CONTEXT)
    PRTBAKE_CL_ERR(CL_INVALID_MEM_OBJECT)
    PRTBAKE_CL_ERR(CL_INVALID_BUILD_OPTIONS)
    PRTBAKE_CL_ERR(CL_INVALID_PROGRAM_EXECUTABLE)
    PRTBAKE_CL_ERR(CL_INVALID_KERNEL_NAME)
    PRTBAKE_CL_ERR(CL_INVALID_KERNEL_ARGS)
    PRTBAKE_CL_ERR(CL_INVALID_ARG_INDEX)
    PRTBAKE_CL_ERR(CL_INVALID_ARG_VALUE)
    PRTBAKE_CL_ERR(CL_INVALID_ARG_SIZE)
    PRTBAKE_CL_ERR(CL_INVALID_WORK_GROUP_SIZE)
    PRTBAKE_CL_ERR(CL_INVALID_WORK_ITEM_SIZE)
    PRTBAKE_CL_ERR(CL_INVALID_GLOBAL_WORK_SIZE)
    PRTBAKE_CL_ERR(CL_INVALID_BUFFER_SIZE)
#undef PRTBAKE_CL_ERR
    default:
      return "CL_UNKNOWN_ERROR";
  }
}

}  // namespace prtbake
