// Transport outputs: GAMES202 transport.txt, the glTF copy with _PRT_T* attributes,
// and the JSON sidecar.
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <sstream>

#include <nlohmann/json.hpp>

#include "core/constants.h"
#include "io/gltf.h"
#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/transport.h"
#include "core/tolerance_pilot.h"

namespace prtbake {

std::string games202TransportBytes(const Mesh& mesh, const TransportResult& r) {
  if (r.channels != 1)
    throw UsageError("--games202", "the GAMES202 transport.txt holds grey transport only (the albedo is coloured)");
  const int nc = r.order * r.order;
  std::string out;
  out.reserve(mesh.indices.size() * nc * 12 + 32);
  out += std::to_string(mesh.vertexCount()) + "\n";
  char buf[32];
  for (uint32_t v : mesh.indices) {
    const float* t = r.vertex(v);
    for (int k = 0; k < nc; ++k) {
      // The framework's transport has no 1/π: ×π. The shortest text that reads back as
      // the same float (std::to_chars; ~10× faster than printf's %.9g on mary.obj).
      const auto res = std::to_chars(buf, buf + sizeof buf, float(t[k] * kPi));
      if (k) out += ' ';
      out.append(buf, res.ptr);
    }
    out += '\n';
  }
  return out;
}

void writeGames202Transport(const std::string& path, const Mesh& mesh, const TransportResult& r) {
  writeFileAtomic(path, games202TransportBytes(mesh, r));
}

std::string transportGltfBytes(const std::string& path, const Mesh& mesh, const TransportResult& r) {
  if (mesh.format != Mesh::Format::Gltf || mesh.sourcePath.empty())
    throw UsageError("--gltf", "a glTF copy needs a glTF input (this mesh is not one)");
  tinygltf::Model model;
  detail::loadGltfModel(mesh.sourcePath, model);
  const int nc = r.order * r.order, groups = (nc + 3) / 4;
  const char* channelNames[3] = {"_PRT_R", "_PRT_G", "_PRT_B"};
  if (model.buffers.empty()) model.buffers.emplace_back();
  auto& buffer = model.buffers[0].data;
  std::vector<std::pair<int, int>> done;  // (mesh, primitive) already written
  for (const auto& gp : mesh.gltfPrimitives) {
    bool seen = false;
    for (const auto& d : done) seen = seen || (d.first == gp.mesh && d.second == gp.primitive);
    if (seen) continue;
    done.emplace_back(gp.mesh, gp.primitive);
    auto& prim = model.meshes[gp.mesh].primitives[gp.primitive];
    for (int c = 0; c < r.channels; ++c)
      for (int g = 0; g < groups; ++g) {
        while (buffer.size() % 4) buffer.push_back(0);
        tinygltf::BufferView view;
        view.buffer = 0;
        view.byteOffset = buffer.size();
        view.byteLength = size_t(gp.vertexCount) * 16;
        view.target = TINYGLTF_TARGET_ARRAY_BUFFER;
        float mn[4] = {INFINITY, INFINITY, INFINITY, INFINITY}, mx[4] = {-INFINITY, -INFINITY, -INFINITY, -INFINITY};
        for (uint32_t v = 0; v < gp.vertexCount; ++v) {
          const float* t = r.vertex(gp.firstVertex + v) + size_t(c) * nc;
          float q[4];
          for (int k = 0; k < 4; ++k) {
            const int i = 4 * g + k;
            q[k] = i < nc ? t[i] : 0.0f;
            mn[k] = std::min(mn[k], q[k]), mx[k] = std::max(mx[k], q[k]);
          }
          const size_t at = buffer.size();
          buffer.resize(at + 16);
          std::memcpy(buffer.data() + at, q, 16);
        }
        model.bufferViews.push_back(view);
        tinygltf::Accessor acc;
        acc.bufferView = int(model.bufferViews.size() - 1);
        acc.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
        acc.count = gp.vertexCount;
        acc.type = TINYGLTF_TYPE_VEC4;
        if (gp.vertexCount) {
          acc.minValues.assign(mn, mn + 4);
          acc.maxValues.assign(mx, mx + 4);
        }
        model.accessors.push_back(acc);
        const std::string name = (r.channels == 1 ? std::string("_PRT_T") : std::string(channelNames[c])) + std::to_string(g);
        prim.attributes[name] = int(model.accessors.size() - 1);
      }
  }
  return detail::gltfCopyBytes(model, path, mesh.sourcePath);
}

void writeTransportGltf(const std::string& path, const Mesh& mesh, const TransportResult& r) {
  writeFileAtomic(path, transportGltfBytes(path, mesh, r));
}

std::string transportSidecarBytes(const std::string& inputPath, const Mesh& mesh, const TransportOptions& o,
                                  const TransportResult& r) {
  using nlohmann::json;
  json j;
  j["tool"] = {{"name", "prtbake"}, {"version", version()}};
  j["product"] = "transport";
  json params = {{"mode", transportModeName(o.mode)}, {"order", o.order}, {"samples", o.samples},
                 {"seed", o.seed}};
  if (o.mode == TransportMode::Interreflected) {
    params["bounces"] = o.bounces;
    params["bounce_tolerance"] = o.bounceTolerance;
  }
  if (o.sampler != TransportSampler::Hammersley) params["sampler"] = transportSamplerName(o.sampler);
  if (o.tolerance > 0) {
    params["tolerance"] = o.tolerance;
    params["max_samples"] = o.toleranceMaxSamples;
  }
  if (o.albedoOverride) params["albedo"] = {(*o.albedoOverride)[0], (*o.albedoOverride)[1], (*o.albedoOverride)[2]};
  j["parameters"] = params;
  j["input"] = {{"path", inputPath}, {"sha256", mesh.inputSha256(inputPath)}, {"vertices", mesh.vertexCount()},
                {"triangles", mesh.triangleCount()}};
  j["conventions"] = {
      {"basis", "real orthonormal SH with the Condon-Shortley phase"},
      {"index", "i = l(l+1)+m"},
      {"frame", mesh.format == Mesh::Format::Gltf ? "glTF world (node transforms applied), right-handed, +Y up"
                                                  : "input frame as is"},
      {"quantity", o.mode == TransportMode::Interreflected ? "transport with interreflection T = sum_k T^(k)"
                                                           : std::string(transportModeName(o.mode)) + " transport"},
      {"units", "T_i = (1/pi) * integral of V(p,w) max(0, n.w) Y_i(w) dw; shade L_o = albedo * sum_i l_i T_i"},
      {"games202_units", "pi * T_i"},
      {"layout", r.channels == 1 ? "[vertices, n^2] float32" : "[vertices, 3 (RGB), n^2] float32"},
      {"sampling", "cosine-weighted shifted Hammersley, per-vertex rotation about the normal"}};
  j["samples"] = {{"per_vertex", r.samples}, {"rays", r.rays}, {"total", r.totalSamples},
                  {"vertices_unoccludable", r.verticesUnoccludable}};
  if (o.tolerance > 0) {
    json terms = json::array();
    for (const ToleranceReport& t : r.tolerance) terms.push_back(detail::toleranceJson(t));
    j["tolerance"] = {{"terms", terms},
                      {"meaning", "term 0 is the direct term, term k the k-th bounce; each got the count its pilot "
                                  "predicted for its share of the tolerance (docs/transport.md)"}};
  }
  j["error"] = {{"estimate", "standard error of the direct term's coefficient vector (L2), independent-sample bound "
                             "(0 for vertices that take the closed form)"},
                {"max", r.maxStdError}, {"mean", r.meanStdError}};
  if (o.mode == TransportMode::Interreflected)
    j["bounces"] = {{"used", r.bouncesUsed}, {"max_norm_per_bounce", r.bounceMaxNorm}};
  j["mesh"] = {{"degenerate_triangles", r.degenerateTriangles}, {"vertices_without_normal", r.verticesWithoutNormal},
               {"bvh_nodes", r.bvhNodes}};
  j["timings_s"] = {{"bvh", r.bvhSeconds}, {"kernels", r.kernelSeconds}, {"total", r.totalSeconds}};
  j["device"] = r.device;
  return j.dump(2) + "\n";
}

void writeTransportSidecar(const std::string& path, const std::string& inputPath, const Mesh& mesh,
                           const TransportOptions& o, const TransportResult& r) {
  writeFileAtomic(path, transportSidecarBytes(inputPath, mesh, o, r));
}

}  // namespace prtbake
