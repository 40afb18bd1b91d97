// prtbake/runtime.h: the OpenCL side of the library.
//
// A Runtime owns one context, one in-order queue on one device, and a cache of
// built programs keyed by (kernel file, build options). Create one per process
// (or per batch run) and pass it to every product call; building a program is
// the expensive step (~1 s cold on PoCL, ~40 ms from PoCL's own disk cache).
#pragma once

#ifndef CL_HPP_ENABLE_EXCEPTIONS
#define CL_HPP_ENABLE_EXCEPTIONS
#endif
#ifndef CL_HPP_TARGET_OPENCL_VERSION
#define CL_HPP_TARGET_OPENCL_VERSION 120
#endif
#ifndef CL_HPP_MINIMUM_OPENCL_VERSION
#define CL_HPP_MINIMUM_OPENCL_VERSION 120
#endif
#include <CL/opencl.hpp>

#include <algorithm>
#include <map>
#include <mutex>
#include <string>
#include <vector>

namespace prtbake {

struct DeviceInfo {
  int index = 0;             // position in the flat list over all platforms
  std::string platform;      // platform name, e.g. "Portable Computing Language"
  std::string name;          // device name
  std::string type;          // "cpu", "gpu" or "other"
  unsigned computeUnits = 0;
  unsigned long long globalMemBytes = 0;
  bool fp64 = false;
};

// Work-items per group for the kernels in which each work-item loops over many rays (a
// vertex, texel or probe each: transport, glossy transfer, lightmaps, probe grids): 16 on a
// CPU device, where PoCL runs a group's work-items one after another and small groups balance
// over the cores; 64 on any other. A GPU runs a group in warps of 32 threads, and NVIDIA's
// keep at most 32 groups resident on a multiprocessor of 2,048 threads (compute capability
// 8.0 and 9.0), so groups of 16 leave half of each warp idle and three quarters of its threads.
size_t defaultLoopGroupSize(const DeviceInfo& device);

// Every OpenCL device of every platform, in platform then device order.
std::vector<DeviceInfo> listDevices();

// Resolves a device specification: "auto" (a GPU if any, else the first CPU),
// "cpu", "gpu", or a decimal index into listDevices(). An empty spec reads the
// PRTBAKE_DEVICE environment variable, then falls back to "auto".
// Throws UsageError for a malformed spec, DeviceError when nothing matches.
int resolveDevice(const std::string& spec);

// Text of a kernel file with its #include "x.clh" lines expanded and #line
// directives inserted, from the sources embedded at build time, or from the
// directory in PRTBAKE_KERNEL_DIR when that is set (development override).
std::string kernelSource(const std::string& file);

class Runtime {
 public:
  explicit Runtime(const std::string& deviceSpec = "");

  const cl::Context& context() const { return context_; }
  const cl::Device& device() const { return device_; }
  cl::CommandQueue& queue() { return queue_; }
  const DeviceInfo& info() const { return info_; }
  // "<device name> (<platform name>)", used in logs, sidecars and errors.
  std::string deviceLabel() const;

  // The program built from `file` with `options`, built once per runtime.
  // A build failure throws DeviceError carrying the device name and build log.
  cl::Program program(const std::string& file, const std::string& options = "");
  // The kernel `name` of that program, created once per runtime and shared: a caller
  // sets every argument before each launch, and two threads do not launch the same
  // kernel at once.
  cl::Kernel kernel(const std::string& file, const std::string& name,
                    const std::string& options = "");

  // Seconds spent building programs so far (cold-build cost is reported apart
  // from kernel time in benchmarks and sidecars).
  double buildSeconds() const { return buildSeconds_; }

  // Largest work-group size the device accepts for a 1-D launch.
  size_t maxWorkGroupSize() const;
  // The group size of the ray-looping kernels: defaultLoopGroupSize, or $PRTBAKE_GROUP_SIZE
  // (1 to maxWorkGroupSize(), for benchmarks; another value is a UsageError).
  size_t loopGroupSize() const { return loopGroupSize_; }
  // The group size of such a kernel that gives each item `lanes` work-items (a power of two
  // up to 32): loopGroupSize() rounded up to a multiple of lanes, within the device's limit.
  size_t loopLocalSize(size_t lanes = 1) const {
    return std::min((loopGroupSize_ + lanes - 1) / lanes * lanes, std::max(maxWorkGroupSize() / lanes, size_t(1)) * lanes);
  }
  // The local memory of kernels/lanes.clh's sums in such a kernel: a float per work-item.
  cl::LocalSpaceArg laneSumMemory(size_t lanes) const { return cl::Local(loopLocalSize(lanes) * sizeof(float)); }
  // The local memory of kernels/lanes.clh's blocked-ray masks in such a kernel: LANES_LAUNCH_UINTS
  // (32) uints, a launch's 1024 rays, per item of the group.
  cl::LocalSpaceArg laneMaskMemory(size_t lanes) const {
    return cl::Local(loopLocalSize(lanes) / lanes * 32 * sizeof(cl_uint));
  }
  // Enqueues such a kernel over items first … first + count − 1, `lanes` work-items each
  // (item i: work-items lanes·i … lanes·i + lanes − 1), in groups of loopLocalSize(lanes) (the
  // last one part-filled: the kernel skips ids past its item count).
  void enqueueLoop(const cl::Kernel& kernel, size_t count, size_t first = 0, size_t lanes = 1) {
    const size_t local = loopLocalSize(lanes), n = (count * lanes + local - 1) / local * local;
    queue_.enqueueNDRangeKernel(kernel, first ? cl::NDRange(first * lanes) : cl::NullRange, cl::NDRange(n),
                                cl::NDRange(local));
  }

  // A read-only device buffer holding `data`, copied when the buffer is created (no
  // command and no wait on the queue: a blocking write costs a round trip to the
  // device's threads, as much as a small launch). Never zero-sized: an empty vector
  // gives a 16-byte buffer, so it can still be bound.
  template <class T>
  cl::Buffer upload(const std::vector<T>& data) {
    const size_t bytes = data.size() * sizeof(T);
    if (!bytes) return cl::Buffer(context_, CL_MEM_READ_ONLY, 16);
    return cl::Buffer(context_, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, bytes, const_cast<T*>(data.data()));
  }

 private:
  DeviceInfo info_;
  cl::Device device_;
  cl::Context context_;
  cl::CommandQueue queue_;
  std::map<std::string, cl::Program> programs_;
  std::map<std::string, cl::Kernel> kernels_;
  std::mutex mutex_;
  double buildSeconds_ = 0.0;
  size_t loopGroupSize_ = 16;
};

// Converts an OpenCL error code into its symbolic name ("CL_OUT_OF_RESOURCES").
const char* clErrorName(int code);

// The label of the device of the most recently created Runtime in this process ("" when
// none), so that a front end can name the device in an OpenCL error it catches.
std::string lastDeviceLabel();

// One line for an OpenCL error on `deviceLabel`: the failing call and the error's name,
// and, for an allocation that failed (CL_MEM_OBJECT_ALLOCATION_FAILURE, CL_OUT_OF_RESOURCES,
// CL_INVALID_BUFFER_SIZE, CL_OUT_OF_HOST_MEMORY), that the device ran out of memory.
std::string describeClError(const cl::Error& e, const std::string& deviceLabel);

}  // namespace prtbake
