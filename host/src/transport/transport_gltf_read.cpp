// Transport coefficients read back from the _PRT_* attributes of a glTF copy (the
// inverse of writeTransportGltf in transport_io.cpp).
#include <cmath>
#include <cstring>

#include "io/gltf.h"
#include "prtbake/error.h"
#include "prtbake/transport.h"

namespace prtbake {
namespace {

// A VEC4 float accessor (what writeTransportGltf writes) with `count` elements.
std::vector<float> readVec4Float(const tinygltf::Model& model, int index, size_t count, const std::string& path,
                                 const std::string& what) {
  if (index >= 0 && index < int(model.accessors.size())) {
    const auto& acc = model.accessors[size_t(index)];
    if (acc.type != TINYGLTF_TYPE_VEC4 || acc.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
      throw InputError(path, what + ": expected a VEC4 float accessor");
  }
  const std::vector<double> v = detail::readAccessor(model, index, 4, path, what, count);
  return std::vector<float>(v.begin(), v.end());
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
        const std::vector<float> v =
            readVec4Float(model, prim.attributes.at(name(c, g)), gp.vertexCount, path, where + " " + name(c, g));
        for (uint32_t i = 0; i < gp.vertexCount; ++i)
          for (int q = 0; q < 4 && 4 * g + q < nc; ++q)
            t.coeffs[(size_t(gp.firstVertex) + i) * size_t(channels * nc) + size_t(c * nc + 4 * g + q)] = v[4 * size_t(i) + size_t(q)];
      }
  }
  if (groups <= 0) throw InputError(path, "no transport attributes found");
  return t;
}

}  // namespace prtbake
