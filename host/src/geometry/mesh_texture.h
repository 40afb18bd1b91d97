// mesh_texture.h (internal): a mesh's albedo from colour textures, shared by the glTF loader
// (base colour textures) and the OBJ loader (map_Kd).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "io/image_read.h"
#include "prtbake/mesh.h"

namespace prtbake::detail {

// How a texture coordinate outside [0, 1] reads the image (glTF sampler wrapS / wrapT).
enum class Wrap { Repeat, Clamp, Mirror };

// Triangles of a mesh that read one image: each triangle's three corners' texture coordinates in
// glTF's convention ((0, 0) the image's top-left corner, v down), any transform applied.
struct TextureUse {
  std::vector<uint32_t> triangles;  // triangle numbers in the mesh
  std::vector<double> uv;           // 6 per triangle: corner 0's (u, v), corner 1's, corner 2's
  Wrap wrapS = Wrap::Repeat, wrapT = Wrap::Repeat;
};

// The image's mean (linear RGB) over each triangle of `uses`, in their order: bilinear samples of
// level 0 at the centroids of its k × k equal sub-triangles, k² about the texels its footprint
// covers (1 to 64²), fewer in proportion (at least one) when the uses would take more than 2^24
// samples together. Every coordinate must be finite.
std::vector<std::array<double, 3>> textureMeans(const Image& image, const std::vector<TextureUse>& uses);

// Multiplies each vertex's albedo by the mean of `triangleAlbedo` over the triangles around it
// that have one (`has`), weighted by their areas in space (a plain mean where those all have zero
// area); a vertex of no such triangle keeps its albedo.
void multiplyAlbedo(Mesh& mesh, const std::vector<std::array<double, 3>>& triangleAlbedo, const std::vector<char>& has);

}  // namespace prtbake::detail
