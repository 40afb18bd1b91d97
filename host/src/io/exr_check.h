// exr_check.h (internal): a walk over an OpenEXR file's header(s) before the OpenEXR
// library reads it.
//
// The library allocates what a header claims before it checks the claim against the
// file: an attribute's value of the size its header field gives (OpaqueAttribute),
// and a line offset table of one entry per chunk of the data window. A file of a few
// bytes can so make it allocate gigabytes. checkExrHeader reads the file once
// (readFile: within the input memory limit) and verifies, for every header of a
// single- or multi-part file, that each attribute's value lies inside the file, and
// for a single-part scanline file that its line offset table does; it returns the
// first part's data window and channel count, so that the caller checks the decoded
// size against the input memory limit before the library allocates it.
// Layout: openexr.com "OpenEXR File Layout" (magic, version and flags, headers of
// name\0 type\0 int32 size value, each header ending in \0; offset tables).
#pragma once

#include <string>

namespace prtbake::detail {

struct ExrHeaderFacts {
  long long width = 0, height = 0;  // of the first part's data window; 0 when absent
  int channels = 0;                 // entries of the first part's channel list
};

// Throws InputError(path, ...) for a file whose header cannot be what it claims.
ExrHeaderFacts checkExrHeader(const std::string& path);

}  // namespace prtbake::detail
