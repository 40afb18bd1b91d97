// Glossy transfer files: the streamed .npy writer (float32/float16), the reader, the
// sidecar, and the CPCA arrays.
#include <cmath>
#include <cstring>
#include <sstream>

#include <nlohmann/json.hpp>

#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/glossy.h"
#include "prtbake/hash.h"
#include "prtbake/limits.h"

namespace prtbake {
namespace {

void checkLittleEndian() {
  const uint32_t probe = 1;
  char little;
  std::memcpy(&little, &probe, 1);
  PRTBAKE_CHECK(little == 1, "the .npy writer assumes a little-endian host");
}

// Version 1.0 header padded to a 64-byte boundary (as npy.cpp writes it).
std::string npyHeader(const std::string& descr, const std::vector<size_t>& shape) {
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

template <class T>
std::string npyBytes(const std::string& descr, const std::vector<size_t>& shape, const std::vector<T>& data) {
  checkLittleEndian();
  std::string out = npyHeader(descr, shape);
  out.append(reinterpret_cast<const char*>(data.data()), data.size() * sizeof(T));
  return out;
}

// Header fields of a .npy (version 1–3) and the data offset.
struct NpyInfo {
  std::string descr;
  bool fortran = false;
  std::vector<size_t> shape;
  size_t dataOffset = 0;
};

NpyInfo parseNpy(const std::string& bytes, const std::string& path) {
  if (bytes.size() < 10 || bytes.compare(0, 6, "\x93NUMPY") != 0) throw InputError(path, "not a .npy file");
  const int major = uint8_t(bytes[6]);
  size_t len = 0, pre = 10;
  if (major == 1) {
    len = size_t(uint8_t(bytes[8])) | size_t(uint8_t(bytes[9])) << 8;
  } else if (major == 2 || major == 3) {
    if (bytes.size() < 12) throw InputError(path, "truncated .npy header");
    len = size_t(uint8_t(bytes[8])) | size_t(uint8_t(bytes[9])) << 8 | size_t(uint8_t(bytes[10])) << 16 |
          size_t(uint8_t(bytes[11])) << 24;
    pre = 12;
  } else {
    throw InputError(path, "unsupported .npy version " + std::to_string(major));
  }
  if (bytes.size() < pre + len) throw InputError(path, "truncated .npy header");
  const std::string dict = bytes.substr(pre, len);
  NpyInfo info;
  info.dataOffset = pre + len;
  auto value = [&](const std::string& key) {
    const size_t k = dict.find("'" + key + "'");
    if (k == std::string::npos) throw InputError(path, "not a .npy file: the header has no '" + key + "'");
    size_t p = dict.find(':', k);
    if (p == std::string::npos) throw InputError(path, "not a .npy file: malformed header");
    ++p;
    while (p < dict.size() && dict[p] == ' ') ++p;
    if (p >= dict.size()) throw InputError(path, "not a .npy file: malformed header");
    size_t e = p;
    if (dict[p] == '(') {
      e = dict.find(')', p);
      if (e == std::string::npos) throw InputError(path, "not a .npy file: malformed shape");
      return dict.substr(p + 1, e - p - 1);
    }
    if (dict[p] == '\'') {
      e = dict.find('\'', p + 1);
      if (e == std::string::npos) throw InputError(path, "not a .npy file: malformed header");
      return dict.substr(p + 1, e - p - 1);
    }
    while (e < dict.size() && dict[e] != ',' && dict[e] != '}') ++e;
    return dict.substr(p, e - p);
  };
  info.descr = value("descr");
  info.fortran = value("fortran_order").find("True") != std::string::npos;
  std::stringstream ss(value("shape"));
  std::string item;
  while (std::getline(ss, item, ',')) {
    const size_t a = item.find_first_not_of(' ');
    if (a == std::string::npos) continue;
    char* end = nullptr;
    const unsigned long long v = std::strtoull(item.c_str() + a, &end, 10);
    if (end == item.c_str() + a || (*end != '\0' && *end != ' ')) throw InputError(path, "malformed .npy shape");
    info.shape.push_back(size_t(v));
  }
  return info;
}

std::string shapeText(const std::vector<size_t>& shape) {
  std::string t = "[";
  for (size_t i = 0; i < shape.size(); ++i) t += (i ? ", " : "") + std::to_string(shape[i]);
  return t + "]";
}

int orderOfCount(size_t count) {
  const int n = int(std::lround(std::sqrt(double(count))));
  return size_t(n) * size_t(n) == count ? n : 0;
}

// A whole .npy file of `descr` with the expected rank; returns the data bytes.
std::string readArray(const std::string& path, const std::string& descr, size_t rank, std::vector<size_t>& shape) {
  const std::string bytes = readFile(path);
  const NpyInfo info = parseNpy(bytes, path);
  if (info.descr != descr || info.fortran || info.shape.size() != rank)
    throw InputError(path, "expected a C-order " + descr + " array of rank " + std::to_string(rank));
  double n = 1;
  for (size_t d : info.shape) n *= double(d);
  const size_t elem = descr == "<f2" ? 2 : 4;
  if (double(bytes.size() - info.dataOffset) != n * elem) throw InputError(path, "data size does not match the shape");
  shape = info.shape;
  return bytes.substr(info.dataOffset);
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
  checkLittleEndian();
  impl_->dtype = dtype;
  impl_->expected = 1;
  for (size_t d : shape) impl_->expected *= d;
  impl_->file.write(npyHeader(dtype == MatrixDtype::Float16 ? "<f2" : "<f4", shape));
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

std::vector<size_t> glossyNpyShape(size_t vertices, int channels, int orderOut, int orderIn) {
  std::vector<size_t> s{vertices};
  if (channels > 1) s.push_back(size_t(channels));
  s.push_back(size_t(orderOut) * orderOut);
  s.push_back(size_t(orderIn) * orderIn);
  return s;
}

GlossyMatrices readGlossyNpy(const std::string& path, size_t expectedVertices) {
  // The header first (a lying shape costs an error, not an allocation).
  std::string head = readFile(path);
  const NpyInfo info = parseNpy(head, path);
  GlossyMatrices g;
  if (info.descr == "<f4") g.dtype = MatrixDtype::Float32;
  else if (info.descr == "<f2") g.dtype = MatrixDtype::Float16;
  else throw InputError(path, "expected float32 or float16 transfer matrices, not '" + info.descr + "'");
  if (info.fortran) throw InputError(path, "expected C order");
  const auto& s = info.shape;
  if (s.size() != 3 && !(s.size() == 4 && s[1] == 3))
    throw InputError(path, "expected shape [V, n_out^2, n_in^2] or [V, 3, n_out^2, n_in^2], got " + shapeText(s));
  g.channels = s.size() == 4 ? 3 : 1;
  g.vertexCount = s[0];
  g.orderOut = orderOfCount(s[s.size() - 2]);
  g.orderIn = orderOfCount(s[s.size() - 1]);
  if (g.orderOut < 1 || g.orderIn < 1) throw InputError(path, "matrix dimensions are not squares: " + shapeText(s));
  if (expectedVertices && g.vertexCount != expectedVertices)
    throw InputError(path, "has " + std::to_string(g.vertexCount) + " vertices but the mesh has " +
                               std::to_string(expectedVertices));
  const double n = double(g.vertexCount) * g.channels * double(s[s.size() - 2]) * double(s[s.size() - 1]);
  checkInputMemory(path, "the transfer matrices", n * 4);
  const size_t elem = g.dtype == MatrixDtype::Float16 ? 2 : 4;
  if (double(head.size() - info.dataOffset) != n * elem) throw InputError(path, "data size does not match the shape");
  g.values.resize(size_t(n));
  const char* data = head.data() + info.dataOffset;
  if (elem == 4) {
    std::memcpy(g.values.data(), data, g.values.size() * 4);
  } else {
    for (size_t i = 0; i < g.values.size(); ++i) {
      uint16_t h;
      std::memcpy(&h, data + 2 * i, 2);
      g.values[i] = halfToFloat(h);
    }
  }
  for (float v : g.values)
    if (!std::isfinite(v)) throw InputError(path, "holds a non-finite value");
  return g;
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
  j["input"] = {{"path", inputPath}, {"sha256", sha256File(inputPath)}, {"vertices", mesh.vertexCount()},
                {"triangles", mesh.triangleCount()}};
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

std::vector<std::pair<std::string, std::string>> cpcaFiles(const std::string& prefix, const CpcaResult& c, int orderOut,
                                                           int orderIn, int channels, const std::string& source) {
  using nlohmann::json;
  const size_t K = size_t(c.clusters), P = size_t(c.vectors), V = c.vertexCount;
  std::vector<std::pair<std::string, std::string>> files;
  std::vector<size_t> dimShape = glossyNpyShape(0, channels, orderOut, orderIn);
  dimShape.erase(dimShape.begin());
  std::vector<size_t> means{K}, basis{K, P};
  means.insert(means.end(), dimShape.begin(), dimShape.end());
  basis.insert(basis.end(), dimShape.begin(), dimShape.end());
  files.emplace_back(prefix + ".means.npy", npyBytes("<f4", means, c.means));
  files.emplace_back(prefix + ".basis.npy", npyBytes("<f4", basis, c.basis));
  files.emplace_back(prefix + ".clusters.npy", npyBytes("<i4", {V}, c.clusterOf));
  files.emplace_back(prefix + ".weights.npy", npyBytes("<f4", {V, P}, c.weights));
  files.emplace_back(prefix + ".error.npy", npyBytes("<f4", {V}, c.vertexError));
  auto base = [](const std::string& p) {
    const size_t s = p.find_last_of('/');
    return s == std::string::npos ? p : p.substr(s + 1);
  };
  json tried = json::array();
  for (const auto& t : c.tried) tried.push_back({{"clusters", int(t[0])}, {"vectors", int(t[1])}, {"error", t[2]}});
  json j = {{"tool", {{"name", "prtbake"}, {"version", version()}}},
            {"product", "glossy_transfer_cpca"},
            {"source", source},
            {"clusters", K},
            {"vectors", P},
            {"vertices", V},
            {"order_out", orderOut},
            {"order_in", orderIn},
            {"channels", channels},
            {"files",
             {{"means", base(prefix + ".means.npy")},
              {"basis", base(prefix + ".basis.npy")},
              {"clusters", base(prefix + ".clusters.npy")},
              {"weights", base(prefix + ".weights.npy")},
              {"error", base(prefix + ".error.npy")}}},
            {"layout",
             "M(v) ~ means[k] + sum_p weights[v, p] * basis[k, p], k = clusters[v]; every array row-major; "
             "basis rows of a cluster are orthonormal; shading needs only means[k] l and basis[k, p] l "
             "(per cluster, per light) and then K-independent work per vertex (docs/glossy.md)"},
            {"error",
             {{"definition", "relative RMS: per vertex |M - M~|_F / |M|_F; total sqrt(sum |M - M~|^2 / sum |M|^2)"},
              {"total", c.totalError},
              {"rms_vertex", c.rmsVertexError},
              {"max_vertex", c.maxVertexError}}},
            {"compression",
             {{"stored_values", c.storedValues()},
              {"float32_matrices_values", double(V) * double(c.dim)},
              {"ratio", c.compressionRatio()}}},
            {"iterations", c.iterations},
            {"tried", tried},
            {"seconds", c.seconds}};
  files.emplace_back(prefix + ".json", j.dump(2) + "\n");
  return files;
}

CpcaResult readCpcaFiles(const std::string& prefix, int* orderOut, int* orderIn, int* channels) {
  using nlohmann::json;
  json j;
  try {
    j = json::parse(readFile(prefix + ".json"));
    *orderOut = j.at("order_out").get<int>();
    *orderIn = j.at("order_in").get<int>();
    *channels = j.at("channels").get<int>();
  } catch (const json::exception& e) {
    throw InputError(prefix + ".json", std::string("not a CPCA sidecar: ") + e.what());
  }
  CpcaResult c;
  std::vector<size_t> sm, sb, sc, sw;
  const size_t rank = *channels == 3 ? 4 : 3;
  const std::string m = readArray(prefix + ".means.npy", "<f4", rank, sm);
  const std::string b = readArray(prefix + ".basis.npy", "<f4", rank + 1, sb);
  const std::string ids = readArray(prefix + ".clusters.npy", "<i4", 1, sc);
  const std::string w = readArray(prefix + ".weights.npy", "<f4", 2, sw);
  c.clusters = int(sm[0]);
  c.vectors = int(sb[1]);
  c.vertexCount = sc[0];
  c.dim = size_t(*channels) * (*orderOut) * (*orderOut) * (*orderIn) * (*orderIn);
  if (sb[0] != sm[0] || sw[0] != sc[0] || sw[1] != sb[1])
    throw InputError(prefix + ".json", "the CPCA arrays disagree in their shapes");
  c.means.resize(m.size() / 4);
  std::memcpy(c.means.data(), m.data(), m.size());
  c.basis.resize(b.size() / 4);
  std::memcpy(c.basis.data(), b.data(), b.size());
  c.clusterOf.resize(ids.size() / 4);
  std::memcpy(c.clusterOf.data(), ids.data(), ids.size());
  c.weights.resize(w.size() / 4);
  std::memcpy(c.weights.data(), w.data(), w.size());
  if (c.means.size() != size_t(c.clusters) * c.dim) throw InputError(prefix + ".means.npy", "wrong size for the orders");
  for (int32_t k : c.clusterOf)
    if (k < 0 || k >= c.clusters) throw InputError(prefix + ".clusters.npy", "cluster id out of range");
  return c;
}

}  // namespace prtbake
