// NumPy .npy headers: written as format 1.0, read as 1.0–3.0. Shared by the transport,
// glossy-matrix and CPCA readers and writers.
#pragma once

#include <string>
#include <vector>

namespace prtbake::npy {

// Magic, version 1.0, the header dict padded with spaces and ended by '\n' so that the
// data starts on a 64-byte boundary.
std::string header(const std::string& descr, const std::vector<size_t>& shape);

// Throws unless the host stores numbers little-endian, as the writers assume.
void checkLittleEndian();

struct Header {
  std::string descr;
  bool fortranOrder = false;
  std::vector<size_t> shape;  // each a plain decimal integer in the file
  size_t dataOffset = 0;
};

// The header fields of `bytes` (the file, or at least its header); InputError names
// `path` when the magic, version, length or dict is malformed.
Header parseHeader(const std::string& bytes, const std::string& path);

// "[a, b, c]" for messages.
std::string shapeText(const std::vector<size_t>& shape);

}  // namespace prtbake::npy
