// glTF 2.0 reading shared by the mesh loader and the transport glTF copy's reader (io/gltf.h).
#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstring>
#include <string_view>
#include <sstream>
#include <nlohmann/json.hpp>
#include <sys/stat.h>

#include "io/gltf.h"
#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/limits.h"

namespace prtbake {
namespace detail {
namespace {
// Images are not decoded here: the encoded bytes of a file or data URI are kept where the caller
// asks for them (`user` is then the vector of images), and passed through untouched. (A buffer
// view's bytes are read after the load, with its bounds checked: tinygltf does not check them.)
bool keepImageBytes(tinygltf::Image* image, const int index, std::string*, std::string*, int, int,
                    const unsigned char* bytes, int size, void* user) {
  if (user && index >= 0 && size > 0 && image->bufferView < 0) {
    auto& images = *static_cast<std::vector<std::vector<unsigned char>>*>(user);
    if (images.size() <= size_t(index)) images.resize(size_t(index) + 1);
    images[size_t(index)].assign(bytes, bytes + size);
  }
  return true;
}
}  // namespace

void loadGltfModel(const std::string& path, tinygltf::Model& model, std::vector<std::string>* files,
                   std::vector<std::vector<unsigned char>>* images) {
  const std::string bytes = readFile(path);
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(keepImageBytes, images);
  std::string err, warn;
  const size_t slash = path.find_last_of('/');
  const std::string baseDir = slash == std::string::npos ? "." : path.substr(0, slash);
  // tinygltf lets some malformed files end in a standard exception (vector::at on an empty
  // list of a GLB: found by fuzzing); those are bad input like the errors it reports.
  auto guarded = [&](const std::function<bool()>& load) {
    try {
      return load();
    } catch (const Error&) {
      throw;
    } catch (const std::exception& e) {
      throw InputError(path, std::string("not a valid glTF 2.0 file: ") + e.what());
    }
  };
  // External buffer and image files must be regular files: tinygltf would try to read a
  // directory as a file of size 2^63 (std::bad_alloc). It joins a URI to the directory as text.
  std::vector<std::string> external;
  for (const auto& [key, uri] : gltfUris(bytes)) {
    struct stat st {};
    external.push_back(baseDir + "/" + uri);
    if (::stat(external.back().c_str(), &st) == 0 && !S_ISREG(st.st_mode))
      throw InputError(path, key + " uri '" + uri + "' is not a regular file");
  }
  bool ok;
  if (bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0) {
    // The GLB header's version field (bytes 4..7, little-endian) is 2 for glTF 2.0;
    // glTF 1.0 binaries (version 1) have another layout that this loader does not read.
    if (bytes.size() < 12) throw InputError(path, "truncated GLB header (" + std::to_string(bytes.size()) + " bytes)");
    const uint32_t glbVersion = uint32_t(uint8_t(bytes[4])) | uint32_t(uint8_t(bytes[5])) << 8 |
                                uint32_t(uint8_t(bytes[6])) << 16 | uint32_t(uint8_t(bytes[7])) << 24;
    if (glbVersion != 2)
      throw InputError(path, "GLB container version " + std::to_string(glbVersion) + " (glTF 2.0 needs version 2)");
    ok = guarded([&] {
      return loader.LoadBinaryFromMemory(&model, &err, &warn, reinterpret_cast<const unsigned char*>(bytes.data()),
                                         unsigned(bytes.size()), baseDir);
    });
  } else {
    ok = guarded([&] { return loader.LoadASCIIFromString(&model, &err, &warn, bytes.data(), unsigned(bytes.size()), baseDir); });
  }
  if (!ok) {
    while (!err.empty() && (err.back() == '\n' || err.back() == ' ')) err.pop_back();
    throw InputError(path, "not a valid glTF 2.0 file: " + (err.empty() ? std::string("parse error") : err));
  }
  // Required extensions: those that leave the accessors, nodes and base colour as core glTF
  // reads them are fine; another (compressed or instanced geometry, or one not known here)
  // would be read wrong, so the file is refused.
  for (const auto& e : model.extensionsRequired) {
    static const char* const kReadable[] = {"KHR_mesh_quantization", "KHR_texture_transform", "KHR_texture_basisu",
                                            "EXT_texture_webp", "EXT_texture_avif", "KHR_lights_punctual",
                                            "KHR_materials_variants", "KHR_xmp_json_ld"};
    const bool readable = e.rfind("KHR_materials_", 0) == 0 ||
                          std::any_of(std::begin(kReadable), std::end(kReadable), [&](const char* k) { return e == k; });
    if (!readable)
      throw InputError(path, "requires the glTF extension " + e +
                                 ", which this loader does not read (store the geometry without it)");
  }
  if (files) *files = std::move(external);
  if (images) {
    images->resize(model.images.size());
    for (size_t i = 0; i < model.images.size(); ++i) {
      const int v = model.images[i].bufferView;
      if (v < 0) continue;
      const auto& view = model.bufferViews[size_t(v)];  // tinygltf checked the indices
      const auto& data = model.buffers[size_t(view.buffer)].data;
      if (view.byteOffset > data.size() || view.byteLength > data.size() - view.byteOffset)
        throw InputError(path, "image " + std::to_string(i) + "'s buffer view " + std::to_string(v) +
                                   " lies outside its buffer");
      (*images)[i].assign(data.begin() + ptrdiff_t(view.byteOffset),
                          data.begin() + ptrdiff_t(view.byteOffset + view.byteLength));
    }
  }
}

std::string imageMediaType(std::string_view bytes) {
  auto starts = [&](size_t at, std::string_view magic) {
    return bytes.size() >= at + magic.size() && bytes.compare(at, magic.size(), magic) == 0;
  };
  return starts(0, "\x89PNG\r\n\x1a\n")          ? "image/png"
         : starts(0, "\xff\xd8\xff")                ? "image/jpeg"
         : starts(0, "\xabKTX 20\xbb")               ? "image/ktx2"
         : starts(0, "RIFF") && starts(8, "WEBP") ? "image/webp"
                                                  : "";
}

std::string decodeGltfUri(const std::string& uri) {
  // As tinygltf decodes it (its urldecode): '+' a space, '%' and the next two characters a byte,
  // a character that is no hex digit counting as 0.
  auto nibble = [](char c) {
    return std::isdigit(uint8_t(c)) ? c - '0' : std::isxdigit(uint8_t(c)) ? std::tolower(uint8_t(c)) - 'a' + 10 : 0;
  };
  std::string decoded;
  for (size_t i = 0; i < uri.size(); ++i)
    if (uri[i] == '+') {
      decoded += ' ';
    } else if (uri[i] == '%' && i + 2 < uri.size()) {
      decoded += char(nibble(uri[i + 1]) << 4 | nibble(uri[i + 2]));
      i += 2;
    } else {
      decoded += uri[i];
    }
  return decoded;
}

std::vector<GltfUri> gltfUris(const std::string& bytes) {
  std::string_view text = bytes;
  if (text.size() >= 20 && text.compare(0, 4, "glTF") == 0) {  // GLB: the JSON chunk (the first)
    const uint32_t length = uint32_t(uint8_t(text[12])) | uint32_t(uint8_t(text[13])) << 8 |
                            uint32_t(uint8_t(text[14])) << 16 | uint32_t(uint8_t(text[15])) << 24;
    text = text.substr(20, std::min<size_t>(length, text.size() - 20));
  }
  std::vector<GltfUri> uris;
  try {
    const auto doc = nlohmann::json::parse(text);
    for (const char* key : {"buffers", "images"})
      if (doc.contains(key) && doc[key].is_array())
        for (const auto& item : doc[key])
          if (item.is_object() && item.contains("uri") && item["uri"].is_string()) {
            const std::string uri = item["uri"].get<std::string>();
            if (uri.empty() || uri.rfind("data:", 0) == 0) continue;  // no file (a GLB's own buffer)
            uris.push_back({key, decodeGltfUri(uri)});
          }
  } catch (const nlohmann::json::exception&) {
    // not JSON: the loader reports the syntax error
  }
  return uris;
}

std::vector<int> gltfRootNodes(const tinygltf::Model& model) {
  if (!model.scenes.empty()) {
    const int s = model.defaultScene >= 0 && model.defaultScene < int(model.scenes.size()) ? model.defaultScene : 0;
    return model.scenes[s].nodes;
  }
  std::vector<char> isChild(model.nodes.size(), 0);
  for (const auto& n : model.nodes)
    for (int c : n.children)
      if (c >= 0 && c < int(isChild.size())) isChild[c] = 1;
  std::vector<int> roots;
  for (size_t i = 0; i < model.nodes.size(); ++i)
    if (!isChild[i]) roots.push_back(int(i));
  return roots;
}

namespace {

// The first byte of `count` elements of `elementBytes` bytes, `stride` apart (0: the view's
// stride, or packed), at `byteOffset` in buffer view `viewIndex`: each number checked against
// the views and buffers first (`name` in the messages).
const unsigned char* viewElements(const tinygltf::Model& model, int viewIndex, size_t byteOffset, size_t count,
                                  size_t elementBytes, size_t* stride, const std::string& path, const std::string& what,
                                  const std::string& name) {
  if (viewIndex < 0 || viewIndex >= int(model.bufferViews.size()))
    throw InputError(path, what + ": buffer view " + std::to_string(viewIndex) + " does not exist");
  const auto& view = model.bufferViews[size_t(viewIndex)];
  if (view.buffer < 0 || view.buffer >= int(model.buffers.size()))
    throw InputError(path, what + ": buffer " + std::to_string(view.buffer) + " does not exist");
  const auto& buf = model.buffers[size_t(view.buffer)].data;
  const std::string past = name + " runs past the end of its buffer (truncated file?)";
  // Each comparison keeps the next subtraction or product from wrapping around.
  if (view.byteOffset > buf.size() || view.byteLength > buf.size() - view.byteOffset)
    throw InputError(path, what + ": buffer view " + std::to_string(viewIndex) +
                               " runs past the end of its buffer (truncated file?)");
  if (view.byteStride != 0 && (view.byteStride < elementBytes || view.byteStride > 252))
    throw InputError(path, what + ": buffer view " + std::to_string(viewIndex) + " has byte stride " +
                               std::to_string(view.byteStride) + " (an element of " + name + " takes " +
                               std::to_string(elementBytes) + " bytes; the most is 252)");
  *stride = view.byteStride ? view.byteStride : elementBytes;
  if (byteOffset > view.byteLength || count > view.byteLength) throw InputError(path, past);
  if (count > 0 && (count - 1) * *stride + elementBytes > view.byteLength - byteOffset) throw InputError(path, past);
  return buf.data() + view.byteOffset + byteOffset;
}

// Component c of the element at p, as readAccessor gives it.
double component(const unsigned char* p, int componentType, bool normalized, const std::string& path,
                 const std::string& name) {
  switch (componentType) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: { float f; std::memcpy(&f, p, 4); return f; }
    case TINYGLTF_COMPONENT_TYPE_DOUBLE: { double d; std::memcpy(&d, p, 8); return d; }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return normalized ? *p / 255.0 : *p;
    case TINYGLTF_COMPONENT_TYPE_BYTE: { const double v = *reinterpret_cast<const signed char*>(p); return normalized ? std::max(v / 127.0, -1.0) : v; }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: { uint16_t u; std::memcpy(&u, p, 2); return normalized ? u / 65535.0 : u; }
    case TINYGLTF_COMPONENT_TYPE_SHORT: { int16_t v; std::memcpy(&v, p, 2); return normalized ? std::max(v / 32767.0, -1.0) : v; }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: { uint32_t u; std::memcpy(&u, p, 4); return u; }
    case TINYGLTF_COMPONENT_TYPE_INT: { int32_t v; std::memcpy(&v, p, 4); return v; }
    default: throw InputError(path, name + " has an unsupported component type");
  }
}

}  // namespace

// See gltf_common.h: every number the file gives is checked before it is used.
std::vector<double> readAccessor(const tinygltf::Model& model, int index, int comps, const std::string& path,
                                 const std::string& what, size_t expectedCount) {
  const std::string name = what + ": accessor " + std::to_string(index);
  if (index < 0 || index >= int(model.accessors.size())) throw InputError(path, name + " does not exist");
  const auto& acc = model.accessors[size_t(index)];
  if (expectedCount != SIZE_MAX && acc.count != expectedCount)
    throw InputError(path, name + " has " + std::to_string(acc.count) + " elements, but the primitive has " +
                               std::to_string(expectedCount) + " vertices (POSITION)");
  const int ncomp = tinygltf::GetNumComponentsInType(uint32_t(acc.type));
  if (ncomp < comps) throw InputError(path, name + " has too few components");
  const int csize = tinygltf::GetComponentSizeInBytes(uint32_t(acc.componentType));
  if (csize <= 0) throw InputError(path, name + " has an unsupported component type");
  const size_t elementBytes = size_t(ncomp) * size_t(csize);
  checkInputMemory(path, name + " (" + std::to_string(acc.count) + " elements)", 8.0 * double(acc.count) * comps);
  // Without a buffer view every element is zero (and a sparse accessor replaces some).
  std::vector<double> out;
  if (acc.bufferView < 0) {
    out.assign(acc.count * size_t(comps), 0.0);
  } else {
    size_t stride = 0;
    const unsigned char* e = viewElements(model, acc.bufferView, acc.byteOffset, acc.count, elementBytes, &stride, path,
                                          what, name);
    out.assign(acc.count * size_t(comps), 0.0);  // allocated once the count is known to fit the buffer
    for (size_t i = 0; i < acc.count; ++i, e += stride)
      for (int c = 0; c < comps; ++c) out[i * comps + c] = component(e + size_t(c) * csize, acc.componentType, acc.normalized, path, name);
  }
  if (acc.sparse.isSparse) {  // `count` elements replaced: their indices, then their values, each packed
    const std::string sparse = name + " (sparse)";
    const auto& ix = acc.sparse.indices;
    const int isize = tinygltf::GetComponentSizeInBytes(uint32_t(ix.componentType));
    if (acc.sparse.count < 1 || size_t(acc.sparse.count) > acc.count)
      throw InputError(path, sparse + " replaces " + std::to_string(acc.sparse.count) + " of its " +
                                 std::to_string(acc.count) + " elements");
    if (ix.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && ix.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
        ix.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
      throw InputError(path, sparse + " has indices that are not unsigned integers");
    const size_t n = size_t(acc.sparse.count);
    size_t istride = 0, vstride = 0;
    const unsigned char* idx = viewElements(model, ix.bufferView, size_t(std::max(ix.byteOffset, 0)), n, size_t(isize),
                                            &istride, path, what, sparse + " indices");
    const unsigned char* val = viewElements(model, acc.sparse.values.bufferView,
                                            size_t(std::max(acc.sparse.values.byteOffset, 0)), n, elementBytes, &vstride,
                                            path, what, sparse + " values");
    for (size_t k = 0; k < n; ++k) {
      const double i = component(idx + k * size_t(isize), ix.componentType, false, path, sparse);
      if (!(i < double(acc.count)))
        throw InputError(path, sparse + " replaces element " + std::to_string(int64_t(i)) + " of " + std::to_string(acc.count));
      for (int c = 0; c < comps; ++c)
        out[size_t(i) * comps + c] = component(val + k * elementBytes + size_t(c) * csize, acc.componentType, acc.normalized, path, sparse);
    }
  }
  return out;
}

std::string gltfCopyBytes(tinygltf::Model& model, const std::string& path, const std::string& sourcePath) {
  const size_t dot = path.find_last_of('.');
  std::string ext = dot == std::string::npos ? "" : path.substr(dot + 1);
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  const bool binary = ext == "glb";
  // One buffer: a GLB holds one (its BIN chunk), and a URI there draws glTF-Validator's warning.
  if (model.buffers.size() > 1) {
    std::vector<size_t> start(model.buffers.size(), 0);
    auto& first = model.buffers[0].data;
    for (size_t b = 1; b < model.buffers.size(); ++b) {
      first.resize((first.size() + 3) / 4 * 4);
      start[b] = first.size();
      first.insert(first.end(), model.buffers[b].data.begin(), model.buffers[b].data.end());
    }
    for (auto& view : model.bufferViews)
      if (view.buffer > 0 && size_t(view.buffer) < start.size()) view.byteOffset += start[size_t(view.buffer)], view.buffer = 0;
    model.buffers.resize(1);
  }
  for (auto& b : model.buffers) b.uri.clear();
  // An image file the source names by URI goes into buffer 0 with its bytes as they are: the copy
  // is written elsewhere than the source, where the URI would name nothing.
  const size_t slash = sourcePath.find_last_of('/');
  const std::string sourceDir = slash == std::string::npos ? "." : sourcePath.substr(0, slash);
  for (auto& image : model.images) {
    if (image.uri.empty() || image.uri.rfind("data:", 0) == 0) continue;
    const std::string file = sourceDir + "/" + decodeGltfUri(image.uri);
    const std::string bytes = readFile(file);
    std::string mime = imageMediaType(bytes);
    if (mime.empty()) mime = image.mimeType;  // as the source declares it
    if (mime.empty())
      throw InputError(file, "not a PNG, JPEG, KTX2 or WebP image, and the glTF gives no mimeType: cannot embed it in "
                             "the glTF copy " + path);
    if (model.buffers.empty()) model.buffers.emplace_back();
    auto& data = model.buffers[0].data;
    data.resize((data.size() + 3) / 4 * 4);
    tinygltf::BufferView view;
    view.buffer = 0, view.byteOffset = data.size(), view.byteLength = bytes.size();
    data.insert(data.end(), bytes.begin(), bytes.end());
    model.bufferViews.push_back(view);
    image.bufferView = int(model.bufferViews.size() - 1);
    image.mimeType = mime;
    image.uri.clear();
  }
  tinygltf::TinyGLTF writer;
  std::ostringstream os;
  if (!writer.WriteGltfSceneToStream(&model, os, !binary, binary))
    throw OutputError(path, "cannot serialise the glTF copy");
  return os.str();
}

}  // namespace detail

}  // namespace prtbake
