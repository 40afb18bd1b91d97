// Private helpers shared by the glTF loader and the glTF export.
#pragma once

#include <tiny_gltf.h>

#include <string>

namespace prtbake::detail {

// Loads .gltf (with external or data-URI buffers) or .glb (by magic, not by
// extension) without decoding images. Throws InputError(path, ...) on failure.
void loadGltfModel(const std::string& path, tinygltf::Model& model);

// The nodes to walk: the default scene's roots, scene 0's, or every root node.
std::vector<int> gltfRootNodes(const tinygltf::Model& model);

}  // namespace prtbake::detail
