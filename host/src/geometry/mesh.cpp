// Mesh utilities: loader dispatch, normals, validation, procedural meshes.
#include "prtbake/mesh.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/constants.h"
#include "io/gltf.h"
#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/hash.h"

namespace prtbake {
namespace {

std::string lowerExtension(const std::string& path) {
  const size_t dot = path.find_last_of('.');
  const size_t slash = path.find_last_of('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string ext = path.substr(dot + 1);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}
}  // namespace

bool Mesh::greyAlbedo() const {
  for (size_t i = 0; i + 2 < albedo.size(); i += 3)
    if (albedo[i] != albedo[i + 1] || albedo[i] != albedo[i + 2]) return false;
  return true;
}

std::string Mesh::inputSha256(const std::string& path) const {
  return path == sourcePath && !sourceSha256.empty() ? sourceSha256 : sha256File(path);
}

std::vector<std::string> gltfExternalUris(const std::string& path) {
  const std::string ext = lowerExtension(path);  // as loadMesh dispatches
  if (ext != "gltf" && ext != "glb") return {};
  std::vector<std::string> uris;
  try {
    // A GLB's URIs are in its JSON chunk, the first: only that much is read (its BIN chunk may be
    // gigabytes).
    std::string bytes = readFilePrefix(path, 20);
    if (bytes.size() == 20 && bytes.compare(0, 4, "glTF") == 0) {
      const uint32_t length = uint32_t(uint8_t(bytes[12])) | uint32_t(uint8_t(bytes[13])) << 8 |
                              uint32_t(uint8_t(bytes[14])) << 16 | uint32_t(uint8_t(bytes[15])) << 24;
      bytes = readFilePrefix(path, 20 + size_t(length));
    } else {
      bytes = readFile(path);
    }
    for (const auto& u : detail::gltfUris(bytes)) uris.push_back(u.uri);
  } catch (const std::exception&) {
  }
  return uris;
}

Mesh loadMesh(const std::string& path, MeshAlbedo albedo) {
  const std::string ext = lowerExtension(path);
  Mesh mesh;
  if (ext == "gltf" || ext == "glb")
    mesh = loadGltf(path, albedo);
  else if (ext == "obj")
    mesh = loadObj(path, albedo);
  else
    throw InputError(path, "unknown mesh format '." + ext + "' (expected .gltf, .glb or .obj)");
  validateMesh(mesh, path);
  fillMissingNormals(mesh);
  return mesh;
}

void fillMissingNormals(Mesh& mesh) {
  const size_t nv = mesh.vertexCount();
  mesh.normals.resize(3 * nv, 0.0f);
  std::vector<char> missing(nv, 0);
  bool any = false;
  for (size_t v = 0; v < nv; ++v) {
    const float* n = &mesh.normals[3 * v];
    const double len2 = double(n[0]) * n[0] + double(n[1]) * n[1] + double(n[2]) * n[2];
    if (!(len2 > 1e-20) || !std::isfinite(len2)) missing[v] = 1, any = true;
  }
  if (!any) return;
  std::vector<double> acc(3 * nv, 0.0);
  const auto& p = mesh.positions;
  for (size_t t = 0; t < mesh.triangleCount(); ++t) {
    const uint32_t id[3] = {mesh.indices[3 * t], mesh.indices[3 * t + 1], mesh.indices[3 * t + 2]};
    if (!missing[id[0]] && !missing[id[1]] && !missing[id[2]]) continue;
    double e[3][3];  // e[k] = p[k+1] - p[k]
    for (int k = 0; k < 3; ++k)
      for (int c = 0; c < 3; ++c) e[k][c] = double(p[3 * id[(k + 1) % 3] + c]) - p[3 * id[k] + c];
    // Area-weighted face normal: the cross product (length = 2 × area).
    const double fn[3] = {e[0][1] * e[2][2] - e[0][2] * e[2][1], e[0][2] * e[2][0] - e[0][0] * e[2][2],
                          e[0][0] * e[2][1] - e[0][1] * e[2][0]};
    // fn = e0 × e2 = (p1 − p0) × (p0 − p2) = −(p1 − p0) × (p2 − p0): flip.
    const double n[3] = {-fn[0], -fn[1], -fn[2]};
    if (!(n[0] * n[0] + n[1] * n[1] + n[2] * n[2] > 0)) continue;
    for (int k = 0; k < 3; ++k) {
      if (!missing[id[k]]) continue;
      // Corner angle between the two edges leaving corner k.
      const double* a = e[k];
      const double* b = e[(k + 2) % 3];  // p[k-1] - p[k-2]; the edge into k, reversed below
      const double la = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
      const double lb = std::sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
      if (la == 0 || lb == 0) continue;
      const double c = std::clamp(-(a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / (la * lb), -1.0, 1.0);
      const double angle = std::acos(c);
      for (int j = 0; j < 3; ++j) acc[3 * id[k] + j] += angle * n[j];
    }
  }
  for (size_t v = 0; v < nv; ++v) {
    if (!missing[v]) continue;
    const double* a = &acc[3 * v];
    const double len = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    for (int j = 0; j < 3; ++j) mesh.normals[3 * v + j] = len > 0 ? float(a[j] / len) : 0.0f;
  }
}

void validateMesh(const Mesh& mesh, const std::string& subject) {
  if (mesh.positions.size() % 3 || mesh.indices.size() % 3)
    throw InputError(subject, "malformed mesh (array sizes are not multiples of 3)");
  if (mesh.triangleCount() == 0) throw InputError(subject, "the mesh has no triangles");
  const size_t nv = mesh.vertexCount();
  if ((!mesh.normals.empty() && mesh.normals.size() != 3 * nv) || mesh.albedo.size() != 3 * nv)
    throw InputError(subject, "malformed mesh (normal or albedo count differs from the vertex count)");
  if (!mesh.tangents.empty() && mesh.tangents.size() != 4 * nv)
    throw InputError(subject, "malformed mesh (the tangent count differs from the vertex count)");
  for (size_t i = 0; i < mesh.indices.size(); ++i)
    if (mesh.indices[i] >= nv)
      throw InputError(subject, "triangle " + std::to_string(i / 3) + " uses vertex " +
                                    std::to_string(mesh.indices[i]) + " of " + std::to_string(nv));
  for (size_t i = 0; i < mesh.positions.size(); ++i)
    if (!std::isfinite(mesh.positions[i]))
      throw InputError(subject, "vertex " + std::to_string(i / 3) + " has a non-finite position (" +
                                    std::to_string(mesh.positions[i]) + ")");
  for (size_t i = 0; i < mesh.albedo.size(); ++i)
    if (!std::isfinite(mesh.albedo[i]))
      throw InputError(subject, "vertex " + std::to_string(i / 3) + " has a non-finite albedo");
}

void meshBounds(const Mesh& mesh, double bmin[3], double bmax[3]) {
  for (int c = 0; c < 3; ++c) bmin[c] = HUGE_VAL, bmax[c] = -HUGE_VAL;
  for (uint32_t i : mesh.indices)
    for (int c = 0; c < 3; ++c) {
      bmin[c] = std::min(bmin[c], double(mesh.positions[3 * i + c]));
      bmax[c] = std::max(bmax[c], double(mesh.positions[3 * i + c]));
    }
}

namespace {
void pushVertex(Mesh& m, double x, double y, double z, double nx, double ny, double nz) {
  m.positions.insert(m.positions.end(), {float(x), float(y), float(z)});
  m.normals.insert(m.normals.end(), {float(nx), float(ny), float(nz)});
  m.albedo.insert(m.albedo.end(), {1.0f, 1.0f, 1.0f});
}
// Sphere rings from polar angle theta0 to pi; normals outward (sign +1) or inward (−1).
Mesh sphereBand(double r, double theta0, int rings, int segments, double sign,
                double (*displace)(double, double) = nullptr) {
  Mesh m;
  const bool poleTop = theta0 == 0.0;
  // Vertex rows: i = 0..rings (theta0 → π); the pole rows collapse to one vertex.
  std::vector<uint32_t> rowStart(rings + 1);
  for (int i = 0; i <= rings; ++i) {
    const double th = theta0 + (kPi - theta0) * i / rings;
    rowStart[i] = uint32_t(m.vertexCount());
    const bool pole = (i == 0 && poleTop) || i == rings;
    const int count = pole ? 1 : segments;
    for (int j = 0; j < count; ++j) {
      const double ph = 2 * kPi * j / segments;
      const double dx = std::sin(th) * std::cos(ph), dy = std::sin(th) * std::sin(ph), dz = std::cos(th);
      const double rr = displace ? r * displace(th, ph) : r;
      pushVertex(m, rr * dx, rr * dy, rr * dz, sign * dx, sign * dy, sign * dz);
    }
  }
  auto vid = [&](int i, int j) -> uint32_t {
    const bool pole = (i == 0 && poleTop) || i == rings;
    return pole ? rowStart[i] : rowStart[i] + uint32_t(j % segments);
  };
  auto tri = [&](uint32_t a, uint32_t b, uint32_t c) {
    if (a == b || b == c || a == c) return;
    if (sign > 0)
      m.indices.insert(m.indices.end(), {a, b, c});
    else
      m.indices.insert(m.indices.end(), {a, c, b});
  };
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      // Counter-clockwise seen from outside: theta grows downward (−z), phi grows eastward.
      const uint32_t a = vid(i, j), b = vid(i + 1, j), c = vid(i + 1, j + 1), d = vid(i, j + 1);
      tri(a, b, c);
      tri(a, c, d);
    }
  return m;
}
double bumps(double th, double ph) {
  return 1.0 + 0.18 * std::sin(7 * th) * std::cos(5 * ph) + 0.08 * std::sin(19 * th + 3 * ph);
}
}  // namespace

Mesh makeUvSphere(double radius, int rings, int segments) {
  return sphereBand(radius, 0.0, rings, segments, 1.0);
}

Mesh makeOpenSphereCavity(double radius, double openingRad, int rings, int segments) {
  return sphereBand(radius, openingRad, rings, segments, -1.0);
}

Mesh makeBumpySphere(int targetTriangles) {
  // 2 × rings × segments triangles with segments = 2 × rings.
  const int rings = std::max(4, int(std::sqrt(targetTriangles / 4.0)) + 1);
  Mesh m = sphereBand(1.0, 0.0, rings, 2 * rings, 1.0, bumps);
  std::fill(m.normals.begin(), m.normals.end(), 0.0f);  // recomputed from the displaced surface
  fillMissingNormals(m);
  return m;
}

Mesh makeTorusKnot(int segments, int sides, int p, int q) {
  // The (p, q) torus knot r(t) = ((2 + cos qt) cos pt, (2 + cos qt) sin pt, sin qt), and a
  // tube of radius 0.4 around it: ring i is a circle in the plane ⟂ T (the tangent), in
  // the Frenet frame (N from the curve's second derivative, B = T × N).
  const double radius = 0.4;
  auto curve = [&](double t, double* c) {
    const double r = 2 + std::cos(q * t);
    c[0] = r * std::cos(p * t), c[1] = r * std::sin(p * t), c[2] = std::sin(q * t);
  };
  Mesh m;
  for (int i = 0; i < segments; ++i) {
    const double t = 2 * kPi * i / segments, h = 1e-4;
    double c0[3], cm[3], cp[3];
    curve(t, c0), curve(t - h, cm), curve(t + h, cp);
    double T[3], A[3], N[3], B[3];
    for (int k = 0; k < 3; ++k) T[k] = cp[k] - cm[k], A[k] = cp[k] - 2 * c0[k] + cm[k];
    auto normalize = [](double* v) {
      const double l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
      for (int k = 0; k < 3; ++k) v[k] /= l;
    };
    normalize(T);
    const double ta = T[0] * A[0] + T[1] * A[1] + T[2] * A[2];
    for (int k = 0; k < 3; ++k) N[k] = A[k] - ta * T[k];
    normalize(N);
    B[0] = T[1] * N[2] - T[2] * N[1], B[1] = T[2] * N[0] - T[0] * N[2], B[2] = T[0] * N[1] - T[1] * N[0];
    for (int j = 0; j < sides; ++j) {
      const double a = 2 * kPi * j / sides, ca = std::cos(a), sa = std::sin(a);
      const double n[3] = {ca * N[0] + sa * B[0], ca * N[1] + sa * B[1], ca * N[2] + sa * B[2]};
      pushVertex(m, c0[0] + radius * n[0], c0[1] + radius * n[1], c0[2] + radius * n[2], n[0], n[1], n[2]);
    }
  }
  for (int i = 0; i < segments; ++i)
    for (int j = 0; j < sides; ++j) {
      const uint32_t a = uint32_t(i * sides + j), b = uint32_t(i * sides + (j + 1) % sides);
      const uint32_t c = uint32_t(((i + 1) % segments) * sides + (j + 1) % sides),
                     d = uint32_t(((i + 1) % segments) * sides + j);
      m.indices.insert(m.indices.end(), {a, b, c, a, c, d});  // counter-clockwise seen from outside
    }
  return m;
}

Mesh makeSquare(double h, double height, int n, bool down) {
  Mesh m;
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j)
      pushVertex(m, -h + 2 * h * j / n, -h + 2 * h * i / n, height, 0, 0, down ? -1 : 1);
  m.uvs.resize(1);
  m.uvMissing.resize(1);
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j) m.uvs[0].insert(m.uvs[0].end(), {float(j) / n, 1.0f - float(i) / n});
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const uint32_t a = uint32_t(i * (n + 1) + j), b = a + 1, c = a + uint32_t(n + 1) + 1, d = a + uint32_t(n + 1);
      if (down)
        m.indices.insert(m.indices.end(), {a, c, b, a, d, c});
      else
        m.indices.insert(m.indices.end(), {a, b, c, a, c, d});
    }
  return m;
}

void appendMesh(Mesh& a, const Mesh& b) {
  const uint32_t off = uint32_t(a.vertexCount());
  const bool aEmpty = a.indices.empty();
  const size_t sets = aEmpty ? b.uvs.size() : std::min(a.uvs.size(), b.uvs.size());
  a.uvs.resize(sets);
  a.uvMissing.resize(sets);
  for (size_t k = 0; k < sets; ++k) {
    if (!aEmpty && (a.uvs[k].empty() || b.uvs[k].empty())) {
      a.uvs[k].clear();
      continue;
    }
    a.uvs[k].insert(a.uvs[k].end(), b.uvs[k].begin(), b.uvs[k].end());
  }
  if (!aEmpty && (a.tangents.empty() || b.tangents.empty()))
    a.tangents.clear();
  else
    a.tangents.insert(a.tangents.end(), b.tangents.begin(), b.tangents.end());
  a.positions.insert(a.positions.end(), b.positions.begin(), b.positions.end());
  a.normals.insert(a.normals.end(), b.normals.begin(), b.normals.end());
  a.albedo.insert(a.albedo.end(), b.albedo.begin(), b.albedo.end());
  for (uint32_t i : b.indices) a.indices.push_back(i + off);
}

void scaleMesh(Mesh& mesh, double s) {
  for (float& p : mesh.positions) p = float(p * s);
}

}  // namespace prtbake
