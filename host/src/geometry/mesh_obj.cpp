// OBJ loader (tinyobjloader): polygons triangulated, one vertex per (v, vt, vn) triple.
#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <future>
#include <map>
#include <sstream>
#include <vector>

#include <tiny_obj_loader.h>

#include "geometry/mesh_texture.h"
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

// The material libraries an OBJ names (`mtllib` lines, names split at blanks as tinyobjloader
// splits them), read whole: their text joined, each material's file (for its map_Kd) and
// whether it gives Kd. A library that cannot be read is an InputError naming it.
struct MaterialLibraries {
  std::string text;
  std::vector<std::string> files;
  struct Material {
    std::string library;
    bool kd = false, mapKd = false;  // whether it has a Kd line, a map_Kd line
  };
  std::map<std::string, Material> materials;
};

std::string directoryOf(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? "." : path.substr(0, slash);
}

MaterialLibraries readMaterialLibraries(const std::string& path, const std::string& objText) {
  MaterialLibraries libs;
  std::istringstream lines(objText);
  for (std::string line; std::getline(lines, line);) {
    std::istringstream words(line);
    std::string key;
    if (!(words >> key) || key != "mtllib") continue;
    for (std::string name; words >> name;) {
      std::replace(name.begin(), name.end(), '\\', '/');
      const std::string file = directoryOf(path) + "/" + name;
      if (std::find(libs.files.begin(), libs.files.end(), file) != libs.files.end()) continue;
      std::string text;
      try {
        text = readFile(file);
      } catch (const InputError& e) {
        throw InputError(file, e.detail() + " (the mtllib of " + path +
                                   ", whose materials give the albedo of this bake: give --albedo instead)");
      }
      libs.files.push_back(file);
      libs.text += text + "\n";
      std::istringstream mtl(text);
      std::string current;
      for (std::string l; std::getline(mtl, l);) {
        std::istringstream w(l);
        std::string k;
        if (!(w >> k)) continue;
        if (k == "newmtl") {
          std::getline(w >> std::ws, current);
          while (!current.empty() && (current.back() == '\r' || current.back() == ' ')) current.pop_back();
          libs.materials.emplace(current, MaterialLibraries::Material{file});
        } else if ((k == "Kd" || k == "map_Kd") && libs.materials.count(current)) {
          (k == "Kd" ? libs.materials[current].kd : libs.materials[current].mapKd) = true;
        }
      }
    }
  }
  return libs;
}

// Each triangle's albedo from its face's material (Kd, 1 where the material gives none, clamped
// to [0, 1], times the mean of its map_Kd around the triangle; 1 for a face without a material),
// then each vertex's as their area-weighted mean (detail::multiplyAlbedo).
void applyObjMaterials(const std::string& path, const MaterialLibraries& libs,
                       const std::vector<tinyobj::material_t>& materials, const std::vector<int>& triangleMaterial,
                       Mesh& mesh) {
  std::vector<std::array<double, 3>> albedo(mesh.triangleCount(), {1.0, 1.0, 1.0});
  std::map<std::string, std::vector<int>> byTexture;  // texture file -> materials
  auto libraryOf = [&](const std::string& material) {  // the .mtl that defines it (else the OBJ)
    const auto lib = libs.materials.find(material);
    return lib == libs.materials.end() ? path : lib->second.library;
  };
  for (size_t m = 0; m < materials.size(); ++m) {
    const auto lib = libs.materials.find(materials[m].name);
    // tinyobjloader reads -o and -s as three numbers: with fewer, it takes the file name for one.
    if (materials[m].diffuse_texname.empty() && lib != libs.materials.end() && lib->second.mapKd)
      throw InputError(lib->second.library, "material '" + materials[m].name +
                                                "': its map_Kd names no file as read (give -o and -s three numbers each)");
    if (materials[m].diffuse_texname.empty()) continue;
    std::string name = materials[m].diffuse_texname;
    std::replace(name.begin(), name.end(), '\\', '/');
    byTexture[directoryOf(libraryOf(materials[m].name)) + "/" + name].push_back(int(m));
  }
  for (size_t t = 0; t < mesh.triangleCount(); ++t) {
    const int m = triangleMaterial[t];
    if (m < 0 || size_t(m) >= materials.size()) continue;
    const auto lib = libs.materials.find(materials[size_t(m)].name);
    if (lib != libs.materials.end() && lib->second.kd)
      for (size_t c = 0; c < 3; ++c) albedo[t][c] = std::clamp(double(materials[size_t(m)].diffuse[c]), 0.0, 1.0);
  }
  std::vector<std::vector<uint32_t>> trianglesOf(materials.size());  // one pass, whatever the count
  for (size_t t = 0; t < mesh.triangleCount(); ++t)
    if (triangleMaterial[t] >= 0 && size_t(triangleMaterial[t]) < materials.size())
      trianglesOf[size_t(triangleMaterial[t])].push_back(uint32_t(t));
  for (const auto& [file, users] : byTexture) {
    std::vector<detail::TextureUse> uses;
    for (int m : users) {
      const tinyobj::texture_option_t& opt = materials[size_t(m)].diffuse_texopt;
      detail::TextureUse use;
      use.wrapS = use.wrapT = opt.clamp ? detail::Wrap::Clamp : detail::Wrap::Repeat;
      if (!trianglesOf[size_t(m)].empty() && mesh.uvs[0].empty())
        throw InputError(path, mesh.uvMissing[0] + ", and material '" + materials[size_t(m)].name +
                                   "' has a map_Kd (its texture is read at every face's vt)");
      for (uint32_t t : trianglesOf[size_t(m)]) {
        use.triangles.push_back(t);
        for (int corner = 0; corner < 3; ++corner) {
          const size_t v = mesh.indices[3 * size_t(t) + size_t(corner)];
          // -s and -o act on OBJ's (u, v), v up; the mesh keeps 1 - v.
          const double u = mesh.uvs[0][2 * v], vUp = 1.0 - double(mesh.uvs[0][2 * v + 1]);
          const double su = u * opt.scale[0] + opt.origin_offset[0], sv = 1.0 - (vUp * opt.scale[1] + opt.origin_offset[1]);
          if (!std::isfinite(su) || !std::isfinite(sv))
            throw InputError(libraryOf(materials[size_t(m)].name), "material '" + materials[size_t(m)].name +
                                                                       "': its map_Kd's -s and -o give a face corner "
                                                                       "a texture coordinate that is not finite");
          use.uv.push_back(su);
          use.uv.push_back(sv);
        }
      }
      uses.push_back(std::move(use));
    }
    mesh.inputFiles.push_back(file);
    const std::vector<std::array<double, 3>> means =
        detail::textureMeans(detail::readImage(file, detail::LdrDecode::Srgb, /*compact=*/true), uses);
    size_t k = 0;
    for (const auto& use : uses)
      for (uint32_t t : use.triangles) {
        for (size_t c = 0; c < 3; ++c) albedo[t][c] *= means[k][c];
        ++k;
      }
  }
  detail::multiplyAlbedo(mesh, albedo, std::vector<char>(mesh.triangleCount(), 1));
}

}  // namespace

Mesh loadObj(const std::string& path, MeshAlbedo albedo) {
  const std::string text = readFile(path);  // a missing or unreadable file is an InputError naming it
  // The bytes' SHA-256 (for the outputs' provenance) on another thread while they are parsed.
  auto hash = std::async(std::launch::async, [&text] { return sha256Hex(text.data(), text.size()); });
  checkObjText(path, text);
  tinyobj::ObjReaderConfig config;
  config.triangulate = true;
  config.vertex_color = false;
  tinyobj::ObjReader reader;
  // From memory: the material libraries only where the albedo is read from them.
  const MaterialLibraries libs = albedo == MeshAlbedo::Textures ? readMaterialLibraries(path, text) : MaterialLibraries{};
  if (!reader.ParseFromString(text, libs.text, config)) {
    std::string err = reader.Error();
    while (!err.empty() && (err.back() == '\n' || err.back() == ' ')) err.pop_back();
    throw InputError(path, "cannot parse OBJ: " + (err.empty() ? std::string("unknown error") : err));
  }
  const auto& attrib = reader.GetAttrib();
  Mesh mesh;
  mesh.sourcePath = path;
  mesh.inputFiles = {path};
  mesh.inputFiles.insert(mesh.inputFiles.end(), libs.files.begin(), libs.files.end());
  mesh.format = Mesh::Format::Obj;
  std::vector<int> triangleMaterial;  // per triangle: its face's material (-1: none), where materials are read
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
      if (albedo == MeshAlbedo::Textures)
        triangleMaterial.push_back(f < shape.mesh.material_ids.size() ? shape.mesh.material_ids[f] : -1);
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
  if (albedo == MeshAlbedo::Textures && !reader.GetMaterials().empty())
    applyObjMaterials(path, libs, reader.GetMaterials(), triangleMaterial, mesh);
  return mesh;
}

}  // namespace prtbake
