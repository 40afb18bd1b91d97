// OBJ loader (tinyobjloader): polygons triangulated, one vertex per (v, vt, vn) triple.
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <map>
#include <tuple>

#include <tiny_obj_loader.h>

#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/mesh.h"

namespace prtbake {

namespace {

// tinyobjloader reads "nan"/"inf" coordinates as 0 and lets out-of-range face
// indices overflow silently, so the text is checked first: every number on a
// v/vn/vt line must be finite, and every face index must fit an int.
void checkObjText(const std::string& path, const std::string& text) {
  size_t lineNo = 0, pos = 0;
  while (pos < text.size()) {
    size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    const std::string line = text.substr(pos, end - pos);
    pos = end + 1;
    ++lineNo;
    const size_t first = line.find_first_not_of(" \t");
    if (first == std::string::npos) continue;
    const bool coords = line.compare(first, 2, "v ") == 0 || line.compare(first, 3, "vn ") == 0 ||
                        line.compare(first, 3, "vt ") == 0 || line.compare(first, 2, "v\t") == 0;
    const bool face = line.compare(first, 2, "f ") == 0 || line.compare(first, 2, "f\t") == 0;
    if (!coords && !face) continue;
    const char* p = line.c_str() + first + (line[first + 1] == ' ' || line[first + 1] == '\t' ? 1 : 2);
    while (*p) {
      while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '/') ++p;
      if (!*p) break;
      char* stop = nullptr;
      if (coords) {
        const double v = std::strtod(p, &stop);
        if (stop != p && !std::isfinite(v))
          throw InputError(path, "line " + std::to_string(lineNo) + ": non-finite coordinate");
      } else {
        errno = 0;
        const long long v = std::strtoll(p, &stop, 10);
        if (stop != p && (errno == ERANGE || v > 2147483647LL || v < -2147483647LL))
          throw InputError(path, "line " + std::to_string(lineNo) + ": face index out of range");
      }
      if (stop == p) ++p;  // not a number: let the parser judge it
      else p = stop;
    }
  }
}

}  // namespace

Mesh loadObj(const std::string& path) {
  checkObjText(path, readFile(path));  // also: a missing or unreadable file is an InputError naming it
  tinyobj::ObjReaderConfig config;
  config.triangulate = true;
  config.vertex_color = false;
  config.mtl_search_path = "";  // materials are not used: do not read .mtl files
  tinyobj::ObjReader reader;
  if (!reader.ParseFromFile(path, config)) {
    std::string err = reader.Error();
    while (!err.empty() && (err.back() == '\n' || err.back() == ' ')) err.pop_back();
    throw InputError(path, "cannot parse OBJ: " + (err.empty() ? std::string("unknown error") : err));
  }
  const auto& attrib = reader.GetAttrib();
  Mesh mesh;
  mesh.sourcePath = path;
  mesh.inputFiles = {path};
  mesh.format = Mesh::Format::Obj;
  std::map<std::tuple<int, int, int>, uint32_t> seen;
  const size_t np = attrib.vertices.size() / 3, nn = attrib.normals.size() / 3, nt = attrib.texcoords.size() / 2;
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
        const auto key = std::make_tuple(idx.vertex_index, vt, vn);
        auto it = seen.find(key);
        if (it == seen.end()) {
          const uint32_t id = uint32_t(mesh.vertexCount());
          it = seen.emplace(key, id).first;
          for (int c = 0; c < 3; ++c) mesh.positions.push_back(attrib.vertices[3 * size_t(idx.vertex_index) + c]);
          for (int c = 0; c < 3; ++c) mesh.normals.push_back(vn >= 0 ? attrib.normals[3 * size_t(vn) + c] : 0.0f);
          mesh.albedo.insert(mesh.albedo.end(), {1.0f, 1.0f, 1.0f});
        }
        mesh.indices.push_back(it->second);
      }
      offset += 3;
    }
  }
  // Normalise the given normals (a zero one is recomputed by fillMissingNormals).
  for (size_t v = 0; v < mesh.vertexCount(); ++v) {
    float* n = &mesh.normals[3 * v];
    const double len = std::sqrt(double(n[0]) * n[0] + double(n[1]) * n[1] + double(n[2]) * n[2]);
    for (int c = 0; c < 3; ++c) n[c] = len > 1e-12 && std::isfinite(len) ? float(n[c] / len) : 0.0f;
  }
  return mesh;
}

}  // namespace prtbake
