// OBJ loader (tinyobjloader): polygons triangulated, one vertex per (v, vt, vn) triple.
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <future>
#include <vector>

#include <tiny_obj_loader.h>

#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/hash.h"
#include "prtbake/mesh.h"

namespace prtbake {

namespace {

// tinyobjloader reads "nan"/"inf" coordinates as 0 and lets out-of-range face
// indices overflow silently, so the text is checked first: every number on a
// v/vn/vt line must be finite (as strtod reads it), and every face index must fit an int.
// Plain decimals are judged from their digits (at most 200 before the exponent and two
// in it: finite); anything else goes to strtod/strtoll.
bool isBlank(char c) { return c == ' ' || (c >= '\t' && c <= '\r'); }  // as isspace in the C locale
bool isSeparator(char c) { return isBlank(c) || c == '/' || c == '\0'; }
bool isDigit(char c) { return c >= '0' && c <= '9'; }

// A plain decimal token at p that is surely finite (or, for faces, fits an int); its end
// in *end. False: let strtod/strtoll judge it.
bool plainNumber(const char* p, bool integer, const char** end) {
  if (*p == '+' || *p == '-') ++p;
  int digits = 0;
  for (; isDigit(*p); ++p) ++digits;
  if (integer) {
    *end = p;
    return digits > 0 && digits <= 9 && isSeparator(*p);
  }
  if (*p == '.')
    for (++p; isDigit(*p); ++p) ++digits;
  if (digits == 0 || digits > 200) return false;
  if (*p == 'e' || *p == 'E') {
    ++p;
    if (*p == '+' || *p == '-') ++p;
    int expDigits = 0;
    for (; isDigit(*p); ++p) ++expDigits;
    if (expDigits == 0 || expDigits > 2) return false;
  }
  *end = p;
  return isSeparator(*p);
}

void checkObjText(const std::string& path, const std::string& text) {
  size_t lineNo = 0, pos = 0;
  while (pos < text.size()) {
    size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    const char* line = text.c_str() + pos;
    const char* const lineEnd = text.c_str() + end;
    pos = end + 1;
    ++lineNo;
    while (line < lineEnd && (*line == ' ' || *line == '\t')) ++line;
    const size_t len = size_t(lineEnd - line);
    if (len < 2) continue;
    const bool coords = (line[0] == 'v' && (line[1] == ' ' || line[1] == '\t')) ||
                        (len >= 3 && line[0] == 'v' && (line[1] == 'n' || line[1] == 't') && line[2] == ' ');
    const bool face = line[0] == 'f' && (line[1] == ' ' || line[1] == '\t');
    if (!coords && !face) continue;
    const char* p = line + (line[1] == ' ' || line[1] == '\t' ? 1 : 2);
    while (p < lineEnd && *p) {
      while (p < lineEnd && (isBlank(*p) || *p == '/')) ++p;  // as strtod skips
      if (p >= lineEnd || !*p) break;
      const char* stop = nullptr;
      if (plainNumber(p, face, &stop)) {
        p = stop;
        continue;
      }
      char* s = nullptr;
      if (coords) {
        const double v = std::strtod(p, &s);
        if (s != p && !std::isfinite(v))
          throw InputError(path, "line " + std::to_string(lineNo) + ": non-finite coordinate");
      } else {
        errno = 0;
        const long long v = std::strtoll(p, &s, 10);
        if (s != p && (errno == ERANGE || v > 2147483647LL || v < -2147483647LL))
          throw InputError(path, "line " + std::to_string(lineNo) + ": face index out of range");
      }
      if (s == p) ++p;  // not a number: let the parser judge it
      else p = s;
    }
  }
}

}  // namespace

Mesh loadObj(const std::string& path) {
  const std::string text = readFile(path);  // a missing or unreadable file is an InputError naming it
  // The bytes' SHA-256 (for the outputs' provenance) on another thread while they are parsed.
  auto hash = std::async(std::launch::async, [&text] { return sha256Hex(text.data(), text.size()); });
  checkObjText(path, text);
  tinyobj::ObjReaderConfig config;
  config.triangulate = true;
  config.vertex_color = false;
  tinyobj::ObjReader reader;
  // From memory, with no material text: materials are not used, no .mtl file is read.
  if (!reader.ParseFromString(text, std::string(), config)) {
    std::string err = reader.Error();
    while (!err.empty() && (err.back() == '\n' || err.back() == ' ')) err.pop_back();
    throw InputError(path, "cannot parse OBJ: " + (err.empty() ? std::string("unknown error") : err));
  }
  const auto& attrib = reader.GetAttrib();
  Mesh mesh;
  mesh.sourcePath = path;
  mesh.inputFiles = {path};
  mesh.format = Mesh::Format::Obj;
  const size_t np = attrib.vertices.size() / 3, nn = attrib.normals.size() / 3, nt = attrib.texcoords.size() / 2;
  // One mesh vertex per distinct (position, texcoord, normal) triple, numbered in order of
  // first use: the triples met so far per position, as linked lists.
  struct Corner {
    int vt, vn;
    uint32_t id, next;
  };
  constexpr uint32_t kNone = ~0u;
  std::vector<uint32_t> firstCorner(np, kNone);
  std::vector<Corner> corners;
  // UV set 0 from vt (v flipped to glTF's convention), kept when every corner has one.
  std::vector<float> uv;
  std::string uvMissing = nt == 0 ? "the file has no vt lines" : "";
  for (const auto& shape : reader.GetShapes()) {
    const auto& ix = shape.mesh.indices;
    size_t offset = 0;
    for (size_t f = 0; f < shape.mesh.num_face_vertices.size(); ++f) {
      const size_t fv = shape.mesh.num_face_vertices[f];
      if (fv != 3) {  // points and lines (triangulation leaves polygons as triangles)
        offset += fv;
        continue;
      }
      for (size_t k = 0; k < 3; ++k) {
        const auto& idx = ix[offset + k];
        if (idx.vertex_index < 0 || size_t(idx.vertex_index) >= np)
          throw InputError(path, "face " + std::to_string(f + 1) + " in '" + shape.name + "' uses a missing vertex");
        const int vn = idx.normal_index >= 0 && size_t(idx.normal_index) < nn ? idx.normal_index : -1;
        const int vt = idx.texcoord_index >= 0 && size_t(idx.texcoord_index) < nt ? idx.texcoord_index : -1;
        uint32_t* link = &firstCorner[size_t(idx.vertex_index)];
        while (*link != kNone && !(corners[*link].vt == vt && corners[*link].vn == vn)) link = &corners[*link].next;
        uint32_t at = *link;
        if (at == kNone) {
          at = *link = uint32_t(corners.size());  // before push_back, which may move `corners`
          corners.push_back({vt, vn, uint32_t(mesh.vertexCount()), kNone});
          for (int c = 0; c < 3; ++c) mesh.positions.push_back(attrib.vertices[3 * size_t(idx.vertex_index) + c]);
          for (int c = 0; c < 3; ++c) mesh.normals.push_back(vn >= 0 ? attrib.normals[3 * size_t(vn) + c] : 0.0f);
          mesh.albedo.insert(mesh.albedo.end(), {1.0f, 1.0f, 1.0f});
          uv.push_back(vt >= 0 ? attrib.texcoords[2 * size_t(vt)] : 0.0f);
          uv.push_back(vt >= 0 ? 1.0f - attrib.texcoords[2 * size_t(vt) + 1] : 0.0f);
          if (vt < 0 && uvMissing.empty())
            uvMissing = "face " + std::to_string(f + 1) + " in '" + shape.name + "' has no vt";
        }
        mesh.indices.push_back(corners[at].id);
      }
      offset += 3;
    }
  }
  mesh.sourceSha256 = hash.get();
  mesh.uvs.push_back(uvMissing.empty() ? std::move(uv) : std::vector<float>());
  mesh.uvMissing.push_back(uvMissing);
  // Normalise the given normals (a zero one is recomputed by fillMissingNormals).
  for (size_t v = 0; v < mesh.vertexCount(); ++v) {
    float* n = &mesh.normals[3 * v];
    const double len = std::sqrt(double(n[0]) * n[0] + double(n[1]) * n[1] + double(n[2]) * n[2]);
    for (int c = 0; c < 3; ++c) n[c] = len > 1e-12 && std::isfinite(len) ? float(n[c] / len) : 0.0f;
  }
  return mesh;
}

}  // namespace prtbake
