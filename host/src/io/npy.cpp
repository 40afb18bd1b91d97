// NumPy .npy headers (io/npy.h).
#include <cmath>
#include <cstring>

#include "io/npy.h"
#include "prtbake/error.h"

namespace prtbake {
namespace npy {
namespace {

// The text of `key`'s value in the header dict: a quoted string without its quotes, a
// tuple without its parentheses, or a bare word.
std::string dictValue(const std::string& dict, const std::string& key, const std::string& path) {
  const size_t k = dict.find("'" + key + "'");
  if (k == std::string::npos) throw InputError(path, "not a .npy file: the header has no '" + key + "'");
  size_t p = dict.find(':', k);
  if (p == std::string::npos) throw InputError(path, "not a .npy file: malformed header");
  p = dict.find_first_not_of(' ', p + 1);
  if (p == std::string::npos) throw InputError(path, "not a .npy file: malformed header");
  const char close = dict[p] == '(' ? ')' : dict[p] == '\'' ? '\'' : '\0';
  if (close) {
    const size_t e = dict.find(close, p + 1);
    if (e == std::string::npos) throw InputError(path, "not a .npy file: malformed '" + key + "'");
    return dict.substr(p + 1, e - p - 1);
  }
  const size_t e = dict.find_first_of(",}", p);
  return dict.substr(p, e == std::string::npos ? std::string::npos : e - p);
}

// "V, 3, 25" or "V," : each dimension plain decimal digits (no sign, no exponent).
std::vector<size_t> parseShape(const std::string& s, const std::string& path) {
  std::vector<size_t> shape;
  size_t at = 0;
  while (at < s.size()) {
    const size_t comma = std::min(s.find(',', at), s.size());
    const size_t a = s.find_first_not_of(' ', at);
    if (a >= comma) {  // an empty item: only the trailing one of "(V,)" is allowed
      if (comma != s.size() && s.find_first_not_of(' ', comma + 1) != std::string::npos)
        throw InputError(path, "malformed .npy shape (" + s + ")");
      break;
    }
    const size_t b = s.find_last_not_of(' ', comma - 1);
    const std::string item = s.substr(a, b - a + 1);
    if (item.size() > 19 || item.find_first_not_of("0123456789") != std::string::npos)
      throw InputError(path, "malformed .npy shape (" + s + "): '" + item + "' is not a dimension");
    shape.push_back(size_t(std::stoull(item)));
    at = comma + 1;
  }
  if (shape.empty()) throw InputError(path, "the .npy holds a scalar, not an array");
  return shape;
}

}  // namespace

std::string header(const std::string& descr, const std::vector<size_t>& shape) {
  std::string dims;
  for (size_t i = 0; i < shape.size(); ++i) dims += (i ? ", " : "") + std::to_string(shape[i]);
  if (shape.size() == 1) dims += ",";
  std::string dict = "{'descr': '" + descr + "', 'fortran_order': False, 'shape': (" + dims + "), }";
  const size_t pre = 10;
  const size_t total = (pre + dict.size() + 1 + 63) / 64 * 64;
  dict.resize(total - pre - 1, ' ');
  dict += '\n';
  std::string h("\x93NUMPY\x01\x00", 8);
  h += char(dict.size() & 0xff);
  h += char(dict.size() >> 8);
  return h + dict;
}

void checkLittleEndian() {
  const uint32_t probe = 1;
  char little;
  std::memcpy(&little, &probe, 1);
  PRTBAKE_CHECK(little == 1, "the .npy writer assumes a little-endian host");
}

Header parseHeader(const std::string& bytes, const std::string& path) {
  if (bytes.size() < 10 || bytes.compare(0, 6, "\x93NUMPY") != 0) throw InputError(path, "not a .npy file (bad magic)");
  const int major = uint8_t(bytes[6]);
  size_t len = 0, pre = 10;
  if (major == 1) {
    len = size_t(uint8_t(bytes[8])) | size_t(uint8_t(bytes[9])) << 8;
  } else if (major == 2 || major == 3) {
    if (bytes.size() < 12) throw InputError(path, "truncated .npy header");
    for (int k = 0; k < 4; ++k) len |= size_t(uint8_t(bytes[8 + k])) << (8 * k);
    pre = 12;
  } else {
    throw InputError(path, "unsupported .npy format version " + std::to_string(major));
  }
  if (bytes.size() < pre + len) throw InputError(path, "truncated .npy header");
  const std::string dict = bytes.substr(pre, len);
  Header h;
  h.dataOffset = pre + len;
  h.descr = dictValue(dict, "descr", path);
  const std::string fortran = dictValue(dict, "fortran_order", path);
  if (fortran != "False" && fortran != "True")
    throw InputError(path, "not a .npy file: fortran_order is '" + fortran + "', not True or False");
  h.fortranOrder = fortran == "True";
  h.shape = parseShape(dictValue(dict, "shape", path), path);
  return h;
}

std::string shapeText(const std::vector<size_t>& shape) {
  std::string t = "[";
  for (size_t i = 0; i < shape.size(); ++i) t += (i ? ", " : "") + std::to_string(shape[i]);
  return t + "]";
}

}  // namespace npy

}  // namespace prtbake
