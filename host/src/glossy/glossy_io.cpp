// Glossy transfer files: the streamed .npy writer (float32/float16), the reader, the
// sidecar, and the CPCA arrays.
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>

#include <nlohmann/json.hpp>

#include "io/npy.h"
#include "io/png_chunks.h"
#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/glossy.h"
#include "prtbake/limits.h"

namespace prtbake {
namespace {

template <class T>
std::string npyBytes(const std::string& descr, const std::vector<size_t>& shape, const std::vector<T>& data) {
  npy::checkLittleEndian();
  std::string out = npy::header(descr, shape);
  out.append(reinterpret_cast<const char*>(data.data()), data.size() * sizeof(T));
  return out;
}

int orderOfCount(size_t count) {
  const int n = int(std::lround(std::sqrt(double(count))));
  return size_t(n) * size_t(n) == count ? n : 0;
}

// A transfer-matrix .npy's header, parsed and its shape checked before any data is read
// (a lying shape costs an error, not an allocation). Sets `g`'s shape fields and dtype.
npy::Header readMatrixHeader(const std::string& path, GlossyMatrices& g) {
  inputFileSize(path);
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  std::string head(65536 + 12, '\0');
  head.resize(std::fread(&head[0], 1, head.size(), f));
  std::fclose(f);
  const npy::Header h = npy::parseHeader(head, path);
  const auto& s = h.shape;
  const std::string shape = npy::shapeText(s);
  if (h.descr == "<f4") g.dtype = MatrixDtype::Float32;
  else if (h.descr == "<f2") g.dtype = MatrixDtype::Float16;
  else throw InputError(path, "expected float32 or float16 transfer matrices, not '" + h.descr + "'");
  if (h.fortranOrder || (s.size() != 3 && !(s.size() == 4 && s[1] == 3)))
    throw InputError(path, "expected C-order shape [V, n_out^2, n_in^2] or [V, 3, n_out^2, n_in^2], got " + shape);
  g.channels = s.size() == 4 ? 3 : 1;
  g.vertexCount = s[0];
  g.orderOut = orderOfCount(s[s.size() - 2]);
  g.orderIn = orderOfCount(s[s.size() - 1]);
  if (g.vertexCount == 0) throw InputError(path, "holds no vertices (shape " + shape + ")");
  for (const int n : {g.orderOut, g.orderIn})
    if (n < kMinGlossyOrder || n > kMaxGlossyOrder)
      throw InputError(path, "matrix dimensions are not n^2 for an order n in [" + std::to_string(kMinGlossyOrder) +
                                 ", " + std::to_string(kMaxGlossyOrder) + "] (shape " + shape + ")");
  checkInputMemory(path, "the transfer matrices", 4.0 * double(g.vertexCount) * g.channels *
                                                      double(s[s.size() - 2]) * double(s[s.size() - 1]));
  return h;
}

// The file's size matches the header's shape at `elementBytes` per value.
void checkMatrixDataSize(const std::string& path, const npy::Header& h, size_t fileSize, double values,
                         size_t elementBytes) {
  if (fileSize < h.dataOffset || double(fileSize - h.dataOffset) != values * double(elementBytes))
    throw InputError(path, "data size does not match the shape " + npy::shapeText(h.shape));
}

}  // namespace

uint16_t floatToHalf(float f) {
  uint32_t x;
  std::memcpy(&x, &f, 4);
  const uint32_t sign = (x >> 16) & 0x8000u;
  const uint32_t absx = x & 0x7fffffffu;
  if (absx >= 0x7f800000u) return uint16_t(sign | 0x7c00u | (absx > 0x7f800000u ? 0x200u : 0u));  // inf, NaN
  if (absx >= 0x477ff000u) return uint16_t(sign | 0x7c00u);                                        // overflow
  if (absx < 0x38800000u) {                                                                        // subnormal
    const float a = std::fabs(f) * 16777216.0f;  // × 2^24: the half subnormal unit is 2^-24
    return uint16_t(sign | uint32_t(std::nearbyint(a)));
  }
  // Normal: rebias the exponent, round the mantissa to 10 bits, ties to even.
  uint32_t h = ((absx >> 13) - (112u << 10));
  const uint32_t rest = absx & 0x1fffu;
  if (rest > 0x1000u || (rest == 0x1000u && (h & 1u))) ++h;
  return uint16_t(sign | h);
}

float halfToFloat(uint16_t h) {
  const uint32_t sign = uint32_t(h & 0x8000u) << 16, e = (h >> 10) & 0x1f, m = h & 0x3ff;
  float v;
  if (e == 0) v = std::ldexp(float(m), -24);
  else if (e == 31) v = m ? NAN : INFINITY;
  else v = std::ldexp(float(m | 0x400), int(e) - 25);
  uint32_t x;
  std::memcpy(&x, &v, 4);
  x |= sign;
  std::memcpy(&v, &x, 4);
  return v;
}

struct NpyStreamWriter::Impl {
  AtomicFile file;
  MatrixDtype dtype;
  size_t expected = 0, written = 0;
  std::vector<uint16_t> half;
  explicit Impl(const std::string& p) : file(p) {}
};

NpyStreamWriter::NpyStreamWriter(const std::string& path, const std::vector<size_t>& shape, MatrixDtype dtype)
    : impl_(new Impl(path)) {
  npy::checkLittleEndian();
  impl_->dtype = dtype;
  impl_->expected = 1;
  for (size_t d : shape) impl_->expected *= d;
  impl_->file.write(npy::header(dtype == MatrixDtype::Float16 ? "<f2" : "<f4", shape));
}

NpyStreamWriter::~NpyStreamWriter() { delete impl_; }

void NpyStreamWriter::append(const float* values, size_t count) {
  PRTBAKE_CHECK(impl_->written + count <= impl_->expected, "more values than the .npy shape holds");
  if (impl_->dtype == MatrixDtype::Float32) {
    impl_->file.write(values, count * 4);
  } else {
    impl_->half.resize(count);
    for (size_t i = 0; i < count; ++i) impl_->half[i] = floatToHalf(values[i]);
    impl_->file.write(impl_->half.data(), count * 2);
  }
  impl_->written += count;
}

void NpyStreamWriter::commit() {
  PRTBAKE_CHECK(impl_->written == impl_->expected, "the .npy holds fewer values than its shape");
  impl_->file.commit();
}

const std::string& NpyStreamWriter::path() const { return impl_->file.path(); }

std::string glossyNpyHeader(const std::vector<size_t>& shape, MatrixDtype dtype) {
  return npy::header(dtype == MatrixDtype::Float16 ? "<f2" : "<f4", shape);
}

std::vector<size_t> glossyNpyShape(size_t vertices, int channels, int orderOut, int orderIn) {
  std::vector<size_t> s{vertices};
  if (channels > 1) s.push_back(size_t(channels));
  s.push_back(size_t(orderOut) * orderOut);
  s.push_back(size_t(orderIn) * orderIn);
  return s;
}

GlossyMatrices readGlossyNpy(const std::string& path, size_t expectedVertices) {
  GlossyMatrices g;
  const npy::Header info = readMatrixHeader(path, g);
  if (expectedVertices && g.vertexCount != expectedVertices)
    throw InputError(path, "has " + std::to_string(g.vertexCount) + " vertices but the mesh has " +
                               std::to_string(expectedVertices));
  const double n = double(g.vertexCount) * g.channels * g.orderOut * g.orderOut * g.orderIn * g.orderIn;
  const size_t elem = g.dtype == MatrixDtype::Float16 ? 2 : 4;
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  struct Closer {
    std::FILE* f;
    ~Closer() { std::fclose(f); }
  } closer{f};
  if (std::fseek(f, 0, SEEK_END) != 0) throw InputError(path, "cannot seek");
  const long size = std::ftell(f);
  if (size < 0) throw InputError(path, "cannot seek");
  checkMatrixDataSize(path, info, size_t(size), n, elem);
  std::fseek(f, long(info.dataOffset), SEEK_SET);
  g.values.resize(size_t(n));
  if (elem == 4) {
    if (std::fread(g.values.data(), 4, g.values.size(), f) != g.values.size()) throw InputError(path, "truncated");
  } else {
    std::vector<uint16_t> h(1 << 16);
    for (size_t at = 0; at < g.values.size(); at += h.size()) {
      const size_t k = std::min(h.size(), g.values.size() - at);
      if (std::fread(h.data(), 2, k, f) != k) throw InputError(path, "truncated");
      for (size_t i = 0; i < k; ++i) g.values[at + i] = halfToFloat(h[i]);
    }
  }
  for (float v : g.values)
    if (!std::isfinite(v)) throw InputError(path, "holds a non-finite value");
  return g;
}

GlossyNpyMap::GlossyNpyMap(const std::string& path) {
  // The header through the reader's checks, then a read-only mapping of the whole file.
  const npy::Header info = readMatrixHeader(path, info_);
  if (info_.dtype != MatrixDtype::Float32) throw InputError(path, "only float32 matrices can be mapped");
  // Floats are read in place: numpy pads its headers to a multiple of 64 bytes.
  if (info.dataOffset % alignof(float) != 0)
    throw InputError(path, "the data starts at byte " + std::to_string(info.dataOffset) +
                               ", not a multiple of 4: it cannot be mapped (read it instead)");
  const double n = double(info_.vertexCount) * info_.channels * info_.orderOut * info_.orderOut * info_.orderIn *
                   info_.orderIn;
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd < 0) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  struct stat st {};
  try {
    if (::fstat(fd, &st) != 0) throw InputError(path, std::string("cannot stat: ") + std::strerror(errno));
    checkMatrixDataSize(path, info, size_t(st.st_size), n, 4);
  } catch (...) {
    ::close(fd);
    throw;
  }
  length_ = size_t(st.st_size);
  base_ = ::mmap(nullptr, length_, PROT_READ, MAP_PRIVATE, fd, 0);
  ::close(fd);
  if (base_ == MAP_FAILED) {
    base_ = nullptr;
    throw InputError(path, std::string("cannot map: ") + std::strerror(errno));
  }
  data_ = reinterpret_cast<const float*>(static_cast<const char*>(base_) + info.dataOffset);
  for (size_t i = 0; i < size_t(n); ++i)
    if (!std::isfinite(data_[i])) {
      ::munmap(base_, length_);
      throw InputError(path, "holds a non-finite value");
    }
}

GlossyNpyMap::~GlossyNpyMap() {
  if (base_) ::munmap(base_, length_);
}

std::string glossySidecarBytes(const std::string& inputPath, const Mesh& mesh, const GlossyOptions& o,
                               const GlossyStats& st, MatrixDtype dtype, const std::string& npyPath) {
  using nlohmann::json;
  json j;
  j["tool"] = {{"name", "prtbake"}, {"version", version()}};
  j["product"] = "glossy_transfer";
  json params = {{"mode", transportModeName(o.mode)}, {"order_out", o.orderOut}, {"order_in", o.orderIn},
                 {"samples", o.samples},           {"seed", o.seed},           {"dtype", matrixDtypeName(dtype)}};
  if (o.mode == TransportMode::Interreflected) {
    params["bounces"] = o.bounces;
    params["bounce_tolerance"] = o.bounceTolerance;
  }
  if (o.albedoOverride) params["albedo"] = {(*o.albedoOverride)[0], (*o.albedoOverride)[1], (*o.albedoOverride)[2]};
  j["parameters"] = params;
  j["input"] = {{"path", inputPath}, {"sha256", mesh.inputSha256(inputPath)},
                {"vertices", mesh.vertexCount()}, {"triangles", mesh.triangleCount()}};
  const std::vector<size_t> shape = glossyNpyShape(st.vertexCount, st.channels, st.orderOut, st.orderIn);
  j["output"] = {{"npy", npyPath}, {"shape", shape}, {"dtype", matrixDtypeName(dtype)}};
  j["conventions"] = {
      {"basis", "real orthonormal SH with the Condon-Shortley phase"},
      {"index", "i = l(l+1)+m"},
      {"frame", mesh.format == Mesh::Format::Gltf ? "glTF world (node transforms applied), right-handed, +Y up"
                                                  : "input frame as is"},
      {"quantity", "transfer matrix M(p): environment radiance SH (order n_in) -> SH of the radiance reaching p "
                   "from above its tangent plane (order n_out)"},
      {"definition", o.mode == TransportMode::Unshadowed
                         ? "M_ij = integral of H(n.w) Y_i(w) Y_j(w) dw (exact product rule)"
                     : o.mode == TransportMode::Shadowed
                         ? "M_ij = integral of V(p,w) H(n.w) Y_i(w) Y_j(w) dw"
                         : "M_ij = integral of H(n.w) Y_i(w) [V(p,w) Y_j(w) + hit(p,w) albedo(q) T_j(q)] dw, T the "
                           "diffuse transport summed over bounces 0..B-1"},
      {"layout", st.channels == 1 ? "[vertices, n_out^2 (row: output coefficient), n_in^2 (column: environment "
                                    "coefficient)], row-major"
                                  : "[vertices, 3 (RGB), n_out^2, n_in^2], row-major"},
      {"shading", "L_o = albedo * sum_lm g_l (M l)_lm Y_lm(R), R the reflected view direction, g_l the lobe's "
                  "Funk-Hecke factors (docs/glossy.md)"},
      {"sampling", o.mode == TransportMode::Unshadowed
                       ? "none: Gauss-Legendre in n.w x uniform azimuths, exact"
                       : "uniform over the hemisphere (pdf 1/2pi): shifted Hammersley warped from the cosine set, "
                         "per-vertex rotation about the normal; M = (2pi/N) sum_s ..."}};
  j["samples"] = {{"per_vertex", st.samples}, {"rays", st.rays}, {"vertices_unoccludable", st.verticesUnoccludable}};
  j["error"] = {{"estimate", "independent-sample standard error of M (Frobenius norm), sqrt((v n_out^2 n_in^2/4 - "
                             "|M|^2)/N), v = 2 M_00 the visible fraction"},
                {"max", st.maxStdError},
                {"mean", st.meanStdError}};
  if (o.mode == TransportMode::Interreflected) j["bounces"] = {{"used", st.bouncesUsed}};
  j["vertex_range"] = {{"first", st.firstVertex}, {"count", st.vertexCount}};
  j["mesh"] = {{"degenerate_triangles", st.degenerateTriangles},
               {"vertices_without_normal", st.verticesWithoutNormal},
               {"bvh_nodes", st.bvhNodes}};
  j["timings_s"] = {{"diffuse", st.diffuseSeconds}, {"kernels", st.kernelSeconds}, {"total", st.totalSeconds}};
  j["device"] = st.device;
  return j.dump(2) + "\n";
}

namespace {

void put16(std::string& s, uint32_t v) {
  s += char(v & 0xff);
  s += char((v >> 8) & 0xff);
}
void put32(std::string& s, uint32_t v) {
  put16(s, v & 0xffff);
  put16(s, v >> 16);
}
uint32_t get16(const std::string& s, size_t at) { return uint32_t(uint8_t(s[at])) | uint32_t(uint8_t(s[at + 1])) << 8; }
uint32_t get32(const std::string& s, size_t at) { return get16(s, at) | get16(s, at + 2) << 16; }

// A zip archive of stored (uncompressed) members, as numpy.savez writes without
// compression. Members must stay below 4 GiB (no zip64).
std::string zipStored(const std::vector<std::pair<std::string, std::string>>& members) {
  std::string out, central;
  for (const auto& [name, data] : members) {
    if (data.size() >= 0xFFFFFFFFull) throw OutputError(name, "a .npz member of 4 GiB or more (zip64) is not supported");
    const uint32_t crc = detail::crc32(reinterpret_cast<const unsigned char*>(data.data()), data.size()) ^ 0xFFFFFFFFu, offset = uint32_t(out.size());
    put32(out, 0x04034b50u);
    put16(out, 20), put16(out, 0), put16(out, 0), put16(out, 0), put16(out, 0x21);  // version, flags, stored, time, date
    put32(out, crc), put32(out, uint32_t(data.size())), put32(out, uint32_t(data.size()));
    put16(out, uint32_t(name.size())), put16(out, 0);
    out += name;
    out += data;
    put32(central, 0x02014b50u);
    put16(central, 20), put16(central, 20), put16(central, 0), put16(central, 0), put16(central, 0), put16(central, 0x21);
    put32(central, crc), put32(central, uint32_t(data.size())), put32(central, uint32_t(data.size()));
    put16(central, uint32_t(name.size())), put16(central, 0), put16(central, 0), put16(central, 0), put16(central, 0);
    put32(central, 0), put32(central, offset);
    central += name;
  }
  const uint32_t cdOffset = uint32_t(out.size());
  out += central;
  put32(out, 0x06054b50u);
  put16(out, 0), put16(out, 0), put16(out, uint32_t(members.size())), put16(out, uint32_t(members.size()));
  put32(out, uint32_t(central.size())), put32(out, cdOffset), put16(out, 0);
  return out;
}

// The members of a stored zip, by walking its local headers.
std::map<std::string, std::string> unzipStored(const std::string& z, const std::string& path) {
  std::map<std::string, std::string> out;
  size_t at = 0;
  while (at + 30 <= z.size() && get32(z, at) == 0x04034b50u) {
    if (get16(z, at + 8) != 0) throw InputError(path, "compressed .npz members are not supported");
    const size_t size = get32(z, at + 18), nameLen = get16(z, at + 26), extra = get16(z, at + 28);
    if (at + 30 + nameLen + extra + size > z.size()) throw InputError(path, "truncated .npz");
    out[z.substr(at + 30, nameLen)] = z.substr(at + 30 + nameLen + extra, size);
    at += 30 + nameLen + extra + size;
  }
  if (out.empty()) throw InputError(path, "not a .npz archive");
  return out;
}

// Parses one member .npy of the expected descr and rank.
std::string memberArray(const std::map<std::string, std::string>& m, const std::string& name, const std::string& descr,
                        size_t rank, std::vector<size_t>& shape, const std::string& path) {
  const auto it = m.find(name + ".npy");
  if (it == m.end()) throw InputError(path, "the CPCA archive has no '" + name + "'");
  const npy::Header info = npy::parseHeader(it->second, path + ":" + name);
  if (info.descr != descr || info.fortranOrder || info.shape.size() != rank)
    throw InputError(path, "'" + name + "' is not a C-order " + descr + " array of rank " + std::to_string(rank));
  double n = 1;
  for (size_t d : info.shape) n *= double(d);
  const double itemBytes = descr == "|i1" ? 1 : 4;
  if (double(it->second.size() - info.dataOffset) != n * itemBytes)
    throw InputError(path, "'" + name + "' is truncated");
  shape = info.shape;
  return it->second.substr(info.dataOffset);
}

}  // namespace

std::string cpcaNpzBytes(const CpcaResult& c, int orderOut, int orderIn, int channels) {
  const size_t K = size_t(c.clusters), P = size_t(c.vectors), V = c.vertexCount;
  std::vector<size_t> dimShape = glossyNpyShape(0, channels, orderOut, orderIn);
  dimShape.erase(dimShape.begin());
  std::vector<size_t> means{K}, basis{K, P};
  means.insert(means.end(), dimShape.begin(), dimShape.end());
  basis.insert(basis.end(), dimShape.begin(), dimShape.end());
  std::vector<std::pair<std::string, std::string>> members{
      {"means.npy", npyBytes("<f4", means, c.means)},
      {"basis.npy", npyBytes("<f4", basis, c.basis)},
      {"clusters.npy", npyBytes("<i4", {V}, c.clusterOf)}};
  if (c.weightBits == 8) {
    // The weights are q · (c_kp · t_v) (runCpca quantised them): q back exactly.
    std::vector<int8_t> q(c.weights.size());
    for (size_t v = 0; v < V; ++v)
      for (size_t p = 0; p < P; ++p)
        q[v * P + p] = cpcaInt8Code(c.weights[v * P + p], cpcaInt8Step(c, v, p));
    members.push_back({"weights.npy", npyBytes("|i1", {V, P}, q)});
    members.push_back({"weight_scales.npy", npyBytes("<f4", {K, P}, c.weightScales)});
    members.push_back({"vertex_scales.npy", npyBytes("<f4", {V}, c.vertexScales)});
  } else {
    members.push_back({"weights.npy", npyBytes("<f4", {V, P}, c.weights)});
  }
  members.push_back({"error.npy", npyBytes("<f4", {V}, c.vertexError)});
  members.push_back({"orders.npy", npyBytes("<i4", {3}, std::vector<int32_t>{orderOut, orderIn, channels})});
  return zipStored(members);
}

std::string cpcaSidecarJson(const CpcaResult& c, const std::string& npzPath) {
  using nlohmann::json;
  json tried = json::array();
  for (const auto& t : c.tried) tried.push_back({{"clusters", int(t[0])}, {"vectors", int(t[1])}, {"error", t[2]}});
  const json j = {
      {"npz", npzPath},
      {"clusters", c.clusters},
      {"vectors", c.vectors},
      {"vertices", c.vertexCount},
      {"layout", "M(v) ~ means[k] + sum_p weights[v, p] * basis[k, p], k = clusters[v]; arrays row-major; the basis "
                 "rows of a cluster are orthonormal; a shader needs means[k] l and basis[k, p] l per cluster and "
                 "light, then P multiply-adds per vertex (docs/glossy.md)"},
      {"error",
       {{"definition", "relative RMS: per vertex |M - M~|_F / |M|_F (array 'error'); total sqrt(sum |M - M~|^2 / "
                       "sum |M|^2)"},
        {"total", c.totalError},
        {"rms_vertex", c.rmsVertexError},
        {"max_vertex", c.maxVertexError}}},
      {"weights", c.weightBits == 8 ? "int8: w[v, p] = weights[v, p] * (weight_scales[k, p] * vertex_scales[v])" : "float32"},
      {"compression",
       {{"stored_bytes", c.storedBytes()},
        {"matrix_bytes_float32", 4 * double(c.vertexCount) * double(c.dim)},
        {"ratio_to_float32", c.compressionRatio()}}},
      {"iterations", c.iterations},
      {"ladder_tried", tried},
      {"seconds", c.seconds}};
  return j.dump();
}

CpcaResult readCpcaNpz(const std::string& path, int* orderOut, int* orderIn, int* channels) {
  const auto m = unzipStored(readFile(path), path);
  std::vector<size_t> so, sm, sb, sc, sw;
  const std::string ord = memberArray(m, "orders", "<i4", 1, so, path);
  if (so[0] != 3) throw InputError(path, "'orders' must hold 3 values");
  int32_t o[3];
  std::memcpy(o, ord.data(), 12);
  if (o[0] < kMinGlossyOrder || o[0] > kMaxGlossyOrder || o[1] < kMinGlossyOrder || o[1] > kMaxGlossyOrder ||
      (o[2] != 1 && o[2] != 3))
    throw InputError(path, "'orders' out of range");
  *orderOut = o[0], *orderIn = o[1], *channels = o[2];
  const size_t rank = o[2] == 3 ? 4 : 3;
  const std::string mean = memberArray(m, "means", "<f4", rank, sm, path);
  const std::string basis = memberArray(m, "basis", "<f4", rank + 1, sb, path);
  const std::string ids = memberArray(m, "clusters", "<i4", 1, sc, path);
  // float32 weights, or int8 ones with float32 scales per cluster and vector.
  const bool int8 = m.count("weight_scales.npy") > 0;
  const std::string w = memberArray(m, "weights", int8 ? "|i1" : "<f4", 2, sw, path);
  std::vector<size_t> ss, st;
  const std::string scales = int8 ? memberArray(m, "weight_scales", "<f4", 2, ss, path) : std::string();
  const std::string vscales = int8 ? memberArray(m, "vertex_scales", "<f4", 1, st, path) : std::string();
  CpcaResult c;
  c.clusters = int(sm[0]), c.vectors = int(sb[1]), c.vertexCount = sc[0];
  c.dim = size_t(o[2]) * o[0] * o[0] * o[1] * o[1];
  if (sb[0] != sm[0] || sw[0] != sc[0] || sw[1] != sb[1] || mean.size() != size_t(c.clusters) * c.dim * 4 ||
      basis.size() != size_t(c.clusters) * size_t(c.vectors) * c.dim * 4 ||
      (int8 && (ss[0] != sm[0] || ss[1] != sb[1] || st[0] != sc[0])))
    throw InputError(path, "the CPCA arrays disagree in their shapes");
  auto copy = [](const std::string& b, auto& v) {
    v.resize(b.size() / 4);
    std::memcpy(v.data(), b.data(), b.size());
  };
  copy(mean, c.means);
  copy(basis, c.basis);
  copy(ids, c.clusterOf);
  for (int32_t k : c.clusterOf)
    if (k < 0 || k >= c.clusters) throw InputError(path, "cluster id out of range");
  if (int8) {
    copy(scales, c.weightScales);
    copy(vscales, c.vertexScales);
    c.weightBits = 8;
    const size_t P = size_t(c.vectors);
    c.weights.resize(w.size());
    for (size_t i = 0; i < w.size(); ++i) c.weights[i] = cpcaInt8Value(int8_t(w[i]), cpcaInt8Step(c, i / P, i % P));
  } else {
    copy(w, c.weights);
  }
  for (const std::vector<float>* v : {&c.means, &c.basis, &c.weights, &c.weightScales, &c.vertexScales})
    for (float x : *v)
      if (!std::isfinite(x)) throw InputError(path, "holds a non-finite value");
  return c;
}

}  // namespace prtbake
