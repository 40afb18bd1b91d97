// Private helpers shared by the glTF loader and the glTF export.
#pragma once

#include <tiny_gltf.h>

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace prtbake::detail {

// Loads .gltf (with external or data-URI buffers) or .glb (by magic, not by
// extension) without decoding images. Throws InputError(path, ...) on failure. `files`, when
// given, receives the external files it read (buffers, then images), as the loader named them;
// `images`, when given, image i's encoded bytes at index i (whether from a file, a data URI or a
// buffer view; empty where it has none).
void loadGltfModel(const std::string& path, tinygltf::Model& model, std::vector<std::string>* files = nullptr,
                   std::vector<std::vector<unsigned char>>* images = nullptr);

// Reads `comps` components per element of accessor `index` as doubles (normalised
// integers mapped to [0, 1] or [−1, 1]). Every number the file gives is checked
// before it is used, in this one place, for every attribute and the indices: the
// accessor, its buffer view and buffer exist; the view lies inside the buffer and the
// accessor inside the view; a view's stride is at least one element and at most 252
// bytes (glTF 2.0); the count equals expectedCount when one is given (a vertex
// attribute against POSITION). So the allocation is bounded by the buffer's size and
// nothing is read outside it. Throws InputError(path, what + ...) otherwise.
std::vector<double> readAccessor(const tinygltf::Model& model, int index, int comps, const std::string& path,
                                 const std::string& what, size_t expectedCount = SIZE_MAX);

// The bytes of a glTF copy at `path` of the model loaded from `sourcePath`: binary (.glb, buffer
// 0 as its BIN chunk) when the extension is .glb (any case), else .gltf text with buffer 0
// embedded as a data URI; the model's buffers are first joined into buffer 0 (its views moved
// with them) and their URIs cleared. The image files the source names
// by URI are embedded in buffer 0 as they are, with their media type (PNG, JPEG, KTX2 or WebP by
// their bytes, another kind by the image's mimeType; InputError without one). Throws
// OutputError(path, ...) when tinygltf cannot write it.
std::string gltfCopyBytes(tinygltf::Model& model, const std::string& path, const std::string& sourcePath);

// The media type of an image's bytes by their magic number: "image/png", "image/jpeg",
// "image/ktx2", "image/webp", or "" for another.
std::string imageMediaType(std::string_view bytes);

// A URI as tinygltf decodes it before opening the file: '+' a space, %XX a byte.
std::string decodeGltfUri(const std::string& uri);

// The URIs that a glTF text or GLB container (`bytes`, by the GLB magic) names: its buffers'
// and images' (data: URIs left out), decoded as tinygltf decodes them, each with the key that
// holds it ("buffers" or "images"). Empty when the JSON does not parse (the loader reports that).
struct GltfUri {
  std::string key, uri;
};
std::vector<GltfUri> gltfUris(const std::string& bytes);

// The nodes to walk: the default scene's roots, scene 0's, or every root node.
std::vector<int> gltfRootNodes(const tinygltf::Model& model);

}  // namespace prtbake::detail
