// Transport coefficients read back from the _PRT_* attributes of a glTF copy (the
// inverse of writeTransportGltf in transport_io.cpp).
#include <cmath>
#include <cstring>

#include "gltf_common.h"
#include "prtbake/error.h"
#include "prtbake/preview.h"

namespace prtbake {
namespace {

// A VEC4 float accessor (what writeTransportGltf writes), bounds-checked.
std::vector<float> readVec4Float(const tinygltf::Model& model, int index, const std::string& path, const std::string& what) {
  if (index < 0 || index >= int(model.accessors.size())) throw InputError(path, what + ": no such accessor");
  const auto& acc = model.accessors[size_t(index)];
  if (acc.type != TINYGLTF_TYPE_VEC4 || acc.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
    throw InputError(path, what + ": expected a VEC4 float accessor");
  std::vector<float> out(acc.count * 4, 0.0f);
  if (acc.bufferView < 0 || acc.count == 0) return out;
  if (acc.bufferView >= int(model.bufferViews.size())) throw InputError(path, what + ": no such buffer view");
  const auto& view = model.bufferViews[size_t(acc.bufferView)];
  if (view.buffer < 0 || view.buffer >= int(model.buffers.size())) throw InputError(path, what + ": no such buffer");
  const auto& buf = model.buffers[size_t(view.buffer)].data;
  const size_t stride = view.byteStride ? view.byteStride : 16, start = view.byteOffset + acc.byteOffset;
  if (start + (acc.count - 1) * stride + 16 > buf.size() || acc.byteOffset + (acc.count - 1) * stride + 16 > view.byteLength)
    throw InputError(path, what + ": runs past the end of its buffer (truncated file?)");
  for (size_t i = 0; i < acc.count; ++i) std::memcpy(&out[4 * i], buf.data() + start + i * stride, 16);
  return out;
}

}  // namespace

TransportCoeffs readTransportGltf(const Mesh& mesh) {
  const std::string& path = mesh.sourcePath;
  if (mesh.format != Mesh::Format::Gltf || path.empty())
    throw InputError(path.empty() ? "mesh" : path, "transport attributes can only be read from a glTF file");
  tinygltf::Model model;
  detail::loadGltfModel(path, model);
  TransportCoeffs t;
  t.vertexCount = mesh.vertexCount();
  int groups = -1, nc = 0;
  const char* rgbNames[3] = {"_PRT_R", "_PRT_G", "_PRT_B"};
  for (const auto& gp : mesh.gltfPrimitives) {
    const auto& prim = model.meshes[size_t(gp.mesh)].primitives[size_t(gp.primitive)];
    const std::string where = "mesh " + std::to_string(gp.mesh) + " primitive " + std::to_string(gp.primitive);
    const int channels = prim.attributes.count("_PRT_T0") ? 1 : prim.attributes.count("_PRT_R0") ? 3 : 0;
    if (channels == 0)
      throw InputError(path, where + " has no _PRT_T0 or _PRT_R0 attribute (not a glTF copy written by prtbake transport --gltf)");
    auto name = [&](int c, int g) { return (channels == 1 ? std::string("_PRT_T") : std::string(rgbNames[c])) + std::to_string(g); };
    int k = 0;
    while (prim.attributes.count(name(0, k))) ++k;
    if (groups < 0) {
      groups = k;
      t.channels = channels;
      t.order = int(std::floor(std::sqrt(4.0 * k) + 1e-9));
      nc = t.order * t.order;
      t.coeffs.assign(t.vertexCount * size_t(channels) * size_t(nc), 0.0f);
    } else if (k != groups || channels != t.channels) {
      throw InputError(path, where + " has " + std::to_string(k) + " transport attributes per channel (" +
                                 std::to_string(channels) + " channels), another primitive " + std::to_string(groups) +
                                 " (" + std::to_string(t.channels) + ")");
    }
    for (int c = 0; c < channels; ++c)
      for (int g = 0; g < groups; ++g) {
        if (!prim.attributes.count(name(c, g))) throw InputError(path, where + ": " + name(c, g) + " is missing");
        const std::vector<float> v = readVec4Float(model, prim.attributes.at(name(c, g)), path, where + " " + name(c, g));
        if (v.size() != size_t(gp.vertexCount) * 4)
          throw InputError(path, where + ": " + name(c, g) + " has " + std::to_string(v.size() / 4) + " elements, the primitive " +
                                     std::to_string(gp.vertexCount) + " vertices");
        for (uint32_t i = 0; i < gp.vertexCount; ++i)
          for (int q = 0; q < 4 && 4 * g + q < nc; ++q)
            t.coeffs[(size_t(gp.firstVertex) + i) * size_t(channels * nc) + size_t(c * nc + 4 * g + q)] = v[4 * size_t(i) + size_t(q)];
      }
  }
  if (groups <= 0) throw InputError(path, "no transport attributes found");
  return t;
}

}  // namespace prtbake
