// Transport coefficients as NumPy .npy (float32 little-endian, C order, shape [V, n²] or
// [V, 3, n²]), written and read.
#include <cmath>
#include <cstring>

#include "io/npy.h"
#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/transport.h"

namespace prtbake {

std::string transportNpyBytes(const TransportResult& r) {
  static_assert(sizeof(float) == 4, "float32");
  npy::checkLittleEndian();
  std::vector<size_t> shape{r.vertexCount};
  if (r.channels > 1) shape.push_back(size_t(r.channels));
  shape.push_back(size_t(r.order) * r.order);
  PRTBAKE_CHECK(r.coeffs.size() == r.vertexCount * r.channels * r.order * r.order, "coefficient count");
  std::string out = npy::header("<f4", shape);
  out.append(reinterpret_cast<const char*>(r.coeffs.data()), r.coeffs.size() * sizeof(float));
  return out;
}

void writeTransportNpy(const std::string& path, const TransportResult& r) {
  writeFileAtomic(path, transportNpyBytes(r));
}

TransportCoeffs readTransportNpy(const std::string& path, size_t expectedVertices) {
  const std::string bytes = readFile(path);  // checks the file's size against the input memory limit
  const npy::Header h = npy::parseHeader(bytes, path);
  const std::string shape = npy::shapeText(h.shape);
  if (h.descr != "<f4")
    throw InputError(path, "transport must be float32 little-endian ('<f4'), this file holds '" + h.descr + "'");
  if (h.fortranOrder) throw InputError(path, "transport must be in C order (fortran_order is True)");
  TransportCoeffs t;
  size_t perChannel = 0;
  if (h.shape.size() == 2) {
    t.channels = 1;
    perChannel = h.shape[1];
  } else if (h.shape.size() == 3 && h.shape[1] == 3) {
    t.channels = 3;
    perChannel = h.shape[2];
  } else {
    throw InputError(path, "transport shape must be [V, n^2] or [V, 3, n^2], got " + shape);
  }
  t.vertexCount = h.shape[0];
  if (t.vertexCount == 0) throw InputError(path, "transport holds no vertices (shape " + shape + ")");
  t.order = int(std::lround(std::sqrt(double(perChannel))));
  if (perChannel == 0 || size_t(t.order) * size_t(t.order) != perChannel || t.order > 32)
    throw InputError(path, "the coefficient count " + std::to_string(perChannel) +
                               " per vertex is not n^2 for an SH order n in 1..32 (shape " + shape + ")");
  if (expectedVertices > 0 && t.vertexCount != expectedVertices)
    throw InputError(path, "transport has " + std::to_string(t.vertexCount) + " vertices but the mesh has " +
                               std::to_string(expectedVertices) + " (shape " + shape + ")");
  // In double, so that a shape whose product wraps around in size_t cannot match.
  const double shapeBytes = 4.0 * double(t.vertexCount) * double(t.channels) * double(perChannel);
  const size_t dataBytes = bytes.size() - h.dataOffset;
  if (double(dataBytes) != shapeBytes)
    throw InputError(path, "data size " + std::to_string(dataBytes) + " bytes does not match shape " + shape);
  t.coeffs.resize(dataBytes / 4);
  std::memcpy(t.coeffs.data(), bytes.data() + h.dataOffset, dataBytes);
  for (size_t i = 0; i < t.coeffs.size(); ++i)
    if (!std::isfinite(t.coeffs[i]))
      throw InputError(path, "vertex " + std::to_string(i / (size_t(t.channels) * perChannel)) + ": non-finite coefficient");
  return t;
}

}  // namespace prtbake
