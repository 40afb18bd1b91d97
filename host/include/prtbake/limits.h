// prtbake/limits.h: the memory an input may take once decoded, and a process altogether.
//
// Every loader checks the size a file claims (an image's width and height, a glTF
// accessor's count, a .npy shape) against this limit before it allocates, so a
// header that lies costs one clear error instead of an allocation failure, a swap
// storm or the OOM killer. The limit is per decoded input (one image, one mesh,
// one array), not for the whole process.
//
// Default: 4 GiB, enough for a 16384×8192 float lat-long (1.6 GB) or a mesh of
// tens of millions of vertices. The environment variable PRTBAKE_INPUT_LIMIT_MB
// (read once, on first use) or setInputMemoryLimit() changes it.
#pragma once

#include <cstddef>
#include <string>

namespace prtbake {

// The limit in bytes.
size_t inputMemoryLimit();
// Sets the limit for this process (0 restores the default / the environment's).
void setInputMemoryLimit(size_t bytes);

// Throws InputError(subject, "<what> needs N MiB, more than the input memory limit
// of M MiB (set PRTBAKE_INPUT_LIMIT_MB to change it)") when `bytes` exceed the
// limit. `bytes` is a double so that a product of header fields cannot wrap.
void checkInputMemory(const std::string& subject, const std::string& what, double bytes);

// The memory of the process before its work: the OpenCL runtime and its compiler at their peak
// (measured: 160 MiB with the transport kernels of order 3, 280 MiB with those of order 8).
constexpr double kRuntimeMemoryBytes = 320.0 * 1048576;

// The memory this process can have: the machine's physical memory, or less under its cgroup's
// limit (a container, a Slurm job's --mem); PRTBAKE_MEMORY_LIMIT_MB (MiB), when set, in place of
// both (less, or more where swap will do); read once.
double processMemoryBytes();
// Throws UsageError(subject, "<what> needs about N GiB at its peak, more than the M GiB this
// process can have ...") when `bytes`, a work's estimated peak, exceed processMemoryBytes():
// a request that could only end in the OOM killer or swapping fails before it starts.
void checkProcessMemory(const std::string& subject, const std::string& what, double bytes);

}  // namespace prtbake
