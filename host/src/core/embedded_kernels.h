// Table of kernel sources embedded at build time (see cmake/embed_kernels.cmake).
#pragma once

namespace prtbake::detail {

struct EmbeddedKernel {
  const char* name;  // file name, e.g. "sh.clh"
  const char* path;  // absolute source path at build time, used in #line
  const char* text;
};

// Terminated by an entry whose name is nullptr.
extern const EmbeddedKernel kEmbeddedKernels[];

}  // namespace prtbake::detail
