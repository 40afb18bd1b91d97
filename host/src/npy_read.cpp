// NumPy .npy reader for transport coefficients (format versions 1.0, 2.0 and 3.0):
// float32 little-endian, C order, shape [V, n²] or [V, 3, n²].
#include <cmath>
#include <cstring>
#include <sstream>

#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/preview.h"

namespace prtbake {
namespace {

// The value of `key` in the header dict, as written ('descr': '<f4', ...).
std::string dictValue(const std::string& dict, const std::string& key, const std::string& path) {
  const size_t k = dict.find("'" + key + "'");
  if (k == std::string::npos) throw InputError(path, "not a .npy file: the header has no '" + key + "'");
  size_t p = dict.find(':', k);
  if (p == std::string::npos) throw InputError(path, "not a .npy file: malformed header");
  ++p;
  while (p < dict.size() && dict[p] == ' ') ++p;
  size_t e = p;
  if (dict[p] == '(') {
    e = dict.find(')', p);
    if (e == std::string::npos) throw InputError(path, "not a .npy file: malformed shape");
    return dict.substr(p, e - p + 1);
  }
  if (dict[p] == '\'') {
    e = dict.find('\'', p + 1);
    if (e == std::string::npos) throw InputError(path, "not a .npy file: malformed header");
    return dict.substr(p + 1, e - p - 1);
  }
  while (e < dict.size() && dict[e] != ',' && dict[e] != '}') ++e;
  return dict.substr(p, e - p);
}

std::vector<size_t> parseShape(const std::string& s, const std::string& path) {
  if (s.size() < 2 || s.front() != '(' || s.back() != ')') throw InputError(path, "not a .npy file: malformed shape");
  std::vector<size_t> shape;
  std::string inner = s.substr(1, s.size() - 2);
  std::stringstream ss(inner);
  std::string item;
  while (std::getline(ss, item, ',')) {
    size_t a = item.find_first_not_of(' '), b = item.find_last_not_of(' ');
    if (a == std::string::npos) continue;
    item = item.substr(a, b - a + 1);
    char* end = nullptr;
    const unsigned long long v = std::strtoull(item.c_str(), &end, 10);
    if (end == item.c_str() || *end != '\0') throw InputError(path, "malformed shape " + s);
    shape.push_back(size_t(v));
  }
  return shape;
}

std::string shapeText(const std::vector<size_t>& shape) {
  std::string t = "[";
  for (size_t i = 0; i < shape.size(); ++i) t += (i ? ", " : "") + std::to_string(shape[i]);
  return t + "]";
}

}  // namespace

TransportCoeffs readTransportNpy(const std::string& path, size_t expectedVertices) {
  const std::string bytes = readFile(path);  // checks the file's size against the input memory limit
  if (bytes.size() < 10 || bytes.compare(0, 6, "\x93NUMPY") != 0) throw InputError(path, "not a .npy file (bad magic)");
  const int major = static_cast<unsigned char>(bytes[6]);
  size_t headerLen, pre;
  if (major == 1) {
    headerLen = size_t(static_cast<unsigned char>(bytes[8])) | size_t(static_cast<unsigned char>(bytes[9])) << 8;
    pre = 10;
  } else if (major == 2 || major == 3) {
    if (bytes.size() < 12) throw InputError(path, "truncated .npy header");
    headerLen = 0;
    for (int k = 0; k < 4; ++k) headerLen |= size_t(static_cast<unsigned char>(bytes[8 + k])) << (8 * k);
    pre = 12;
  } else {
    throw InputError(path, "unsupported .npy format version " + std::to_string(major));
  }
  if (bytes.size() < pre + headerLen) throw InputError(path, "truncated .npy header");
  const std::string dict = bytes.substr(pre, headerLen);
  const std::string descr = dictValue(dict, "descr", path);
  if (descr != "<f4")
    throw InputError(path, "transport must be float32 little-endian ('<f4'), this file holds '" + descr + "'");
  if (dictValue(dict, "fortran_order", path) != "False")
    throw InputError(path, "transport must be in C order (fortran_order is True)");
  const std::vector<size_t> shape = parseShape(dictValue(dict, "shape", path), path);
  TransportCoeffs t;
  size_t perChannel = 0;
  if (shape.size() == 2) {
    t.channels = 1;
    perChannel = shape[1];
  } else if (shape.size() == 3 && shape[1] == 3) {
    t.channels = 3;
    perChannel = shape[2];
  } else {
    throw InputError(path, "transport shape must be [V, n^2] or [V, 3, n^2], got " + shapeText(shape));
  }
  t.vertexCount = shape[0];
  t.order = int(std::lround(std::sqrt(double(perChannel))));
  if (perChannel == 0 || size_t(t.order) * size_t(t.order) != perChannel || t.order > 32)
    throw InputError(path, "the coefficient count " + std::to_string(perChannel) +
                               " per vertex is not n^2 for an SH order n in 1..32 (shape " + shapeText(shape) + ")");
  if (expectedVertices > 0 && t.vertexCount != expectedVertices)
    throw InputError(path, "transport has " + std::to_string(t.vertexCount) + " vertices but the mesh has " +
                               std::to_string(expectedVertices) + " (shape " + shapeText(shape) + ")");
  // In double, so that a shape whose product wraps around in size_t cannot match.
  const double shapeBytes = 4.0 * double(t.vertexCount) * double(t.channels) * double(perChannel);
  const size_t dataBytes = bytes.size() - pre - headerLen;
  if (double(dataBytes) != shapeBytes)
    throw InputError(path, "data size " + std::to_string(dataBytes) + " bytes does not match shape " + shapeText(shape) +
                               " (" + std::to_string(shapeBytes) + " bytes)");
  const size_t count = dataBytes / 4;
  t.coeffs.resize(count);
  std::memcpy(t.coeffs.data(), bytes.data() + pre + headerLen, count * 4);
  for (size_t i = 0; i < count; ++i)
    if (!std::isfinite(t.coeffs[i]))
      throw InputError(path, "vertex " + std::to_string(i / (size_t(t.channels) * perChannel)) + ": non-finite coefficient");
  return t;
}

}  // namespace prtbake
