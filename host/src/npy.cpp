// NumPy .npy writer (format version 1.0): float32, C order.
#include <cstring>
#include <string>
#include <vector>

#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/transport.h"

namespace prtbake {
namespace {

// Magic, version 1.0, little-endian header length, then the header dict padded with
// spaces and ended by '\n' so that the data starts on a 64-byte boundary.
std::string npyHeader(const std::vector<size_t>& shape) {
  std::string dims;
  for (size_t d : shape) dims += std::to_string(d) + ", ";
  if (shape.size() > 1) dims.resize(dims.size() - 2);  // (V, n) ; a 1-D shape keeps "(V, )"
  else dims.pop_back();
  std::string dict = "{'descr': '<f4', 'fortran_order': False, 'shape': (" + dims + "), }";
  const size_t pre = 10;
  size_t total = pre + dict.size() + 1;
  total = (total + 63) / 64 * 64;
  dict.resize(total - pre - 1, ' ');
  dict += '\n';
  std::string h("\x93NUMPY\x01\x00", 8);
  const uint16_t len = uint16_t(dict.size());
  h += char(len & 0xff);
  h += char(len >> 8);
  return h + dict;
}

}  // namespace

std::string transportNpyBytes(const TransportResult& r) {
  static_assert(sizeof(float) == 4, "float32");
  const uint32_t probe = 1;
  char little;
  std::memcpy(&little, &probe, 1);
  PRTBAKE_CHECK(little == 1, "the .npy writer assumes a little-endian host");
  std::vector<size_t> shape{r.vertexCount};
  if (r.channels > 1) shape.push_back(size_t(r.channels));
  shape.push_back(size_t(r.order) * r.order);
  PRTBAKE_CHECK(r.coeffs.size() == r.vertexCount * r.channels * r.order * r.order, "coefficient count");
  std::string out = npyHeader(shape);
  out.append(reinterpret_cast<const char*>(r.coeffs.data()), r.coeffs.size() * sizeof(float));
  return out;
}

void writeTransportNpy(const std::string& path, const TransportResult& r) {
  writeFileAtomic(path, transportNpyBytes(r));
}

}  // namespace prtbake
