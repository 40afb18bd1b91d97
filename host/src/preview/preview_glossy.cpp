// The glossy mesh preview: per-vertex transferred radiance for the rotated lighting, then
// the view-dependent lobe per pixel on the device (kernels/glossy_preview.cl).
#include <algorithm>
#include <cmath>

#include "core/kernel_options.h"
#include "preview/preview_camera.h"
#include "prtbake/error.h"
#include "prtbake/glossy.h"
#include "prtbake/sh.h"
#include "prtbake/sh_rotate.h"

namespace prtbake {

std::string detail::glossyPreviewOptions(int orderOut, int lightOrder, bool shBackground) {
  return "-DOUT_ORDER=" + std::to_string(orderOut) + " -DBG_ORDER=" + std::to_string(lightOrder) +
         " -DSH_BACKGROUND=" + (shBackground ? "1" : "0");
}

MeshPreviewResult renderGlossyPreview(Runtime& rt, const Mesh& mesh, const GlossyMatrices& g, const CpcaResult* cpca,
                                      const ShCoeffs& radiance, const GlossyLobe& lobe, const GlossyPreviewOptions& go) {
  const MeshPreviewOptions& o = go.view;
  detail::checkMeshPreview(mesh, radiance, o);
  const int no = g.orderOut, ni = g.orderIn, ch = g.channels, no2 = no * no, ni2 = ni * ni;
  const size_t nv = mesh.vertexCount(), dim = size_t(ch) * no2 * ni2;
  if (cpca) {
    if (cpca->vertexCount != nv || cpca->dim != dim)
      throw InputError("cpca", "has " + std::to_string(cpca->vertexCount) + " vertices of " +
                                   std::to_string(cpca->dim) + " values; the mesh has " + std::to_string(nv));
  } else if (g.vertexCount != nv || g.values.size() != nv * dim) {
    throw InputError("matrices", "have " + std::to_string(g.vertexCount) + " vertices but the mesh has " +
                                     std::to_string(nv));
  }
  // The lighting, rotated as the diffuse preview does, cut or zero-padded to n_in.
  Rotation rot;
  const ShCoeffs light = detail::rotatedLighting(radiance, o, &rot);
  const int nb = light.order * light.order;
  std::vector<double> l(size_t(3) * ni2, 0.0);
  for (int c = 0; c < 3; ++c)
    for (int j = 0; j < std::min(ni2, nb); ++j) l[size_t(c) * ni2 + j] = light.rgb[size_t(j)][size_t(c)];
  std::vector<float> bg(size_t(3) * nb);
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < nb; ++i) bg[size_t(c) * nb + i] = float(light.rgb[size_t(i)][size_t(c)]);

  // t_v = M_v l per channel (grey matrices serve all three), or from the CPCA clusters:
  // t_v = (μ_k l) + Σ_p w_vp (b_kp l), the products precomputed per cluster.
  std::vector<float> t(nv * 3 * no2, 0.0f), hemi(nv * no2, 0.0f), normals(nv * 4, 0.0f);
  auto apply = [&](const float* m, int c, double* out) {  // out[i] += Σ_j m_ij l_cj (one channel of m)
    for (int i = 0; i < no2; ++i) {
      double s = 0;
      for (int j = 0; j < ni2; ++j) s += double(m[size_t(i) * ni2 + j]) * l[size_t(c) * ni2 + j];
      out[i] += s;
    }
  };
  std::vector<double> acc(size_t(3) * no2);
  if (!cpca) {
    for (size_t v = 0; v < nv; ++v) {
      std::fill(acc.begin(), acc.end(), 0.0);
      for (int c = 0; c < 3; ++c) apply(&g.values[v * dim + size_t(ch == 3 ? c : 0) * no2 * ni2], c, &acc[size_t(c) * no2]);
      for (size_t k = 0; k < acc.size(); ++k) t[v * 3 * no2 + k] = float(acc[k]);
    }
  } else {
    const size_t K = size_t(cpca->clusters), P = size_t(cpca->vectors);
    std::vector<double> u(K * (P + 1) * 3 * no2, 0.0);  // per cluster: μ l, then b_p l
    for (size_t k = 0; k < K; ++k)
      for (size_t p = 0; p <= P; ++p) {
        const float* m = p == 0 ? &cpca->means[k * dim] : &cpca->basis[(k * P + p - 1) * dim];
        for (int c = 0; c < 3; ++c) apply(m + size_t(ch == 3 ? c : 0) * no2 * ni2, c, &u[((k * (P + 1) + p) * 3 + c) * no2]);
      }
    for (size_t v = 0; v < nv; ++v) {
      const size_t k = size_t(cpca->clusterOf[v]);
      for (size_t i = 0; i < size_t(3) * no2; ++i) {
        double s = u[(k * (P + 1)) * 3 * no2 + i];
        for (size_t p = 0; p < P; ++p) s += double(cpca->weights[v * P + p]) * u[(k * (P + 1) + 1 + p) * 3 * no2 + i];
        t[v * 3 * no2 + i] = float(s);
      }
    }
  }
  std::vector<double> y(static_cast<size_t>(no2)), hl(static_cast<size_t>(no));
  for (int ll = 0; ll < no; ++ll) hl[size_t(ll)] = hemisphereFactor(ll);
  for (size_t v = 0; v < nv; ++v) {
    double n[3] = {mesh.normals[3 * v], mesh.normals[3 * v + 1], mesh.normals[3 * v + 2]};
    const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(len > 0)) continue;
    for (int c = 0; c < 3; ++c) normals[4 * v + c] = float(n[c] / len);
    shEval(no, n[0] / len, n[1] / len, n[2] / len, y.data());
    for (int ll = 0; ll < no; ++ll)
      for (int m = -ll; m <= ll; ++m) hemi[v * no2 + shIndex(ll, m)] = float(hl[size_t(ll)] * y[size_t(shIndex(ll, m))]);
  }
  std::vector<float> lobeG(size_t(no), 0.0f);
  for (int ll = 0; ll < std::min(no, int(lobe.g.size())); ++ll) lobeG[size_t(ll)] = float(lobe.g[size_t(ll)]);

  MeshPreviewResult r;
  detail::PreviewScene scene = detail::uploadPreviewScene(rt, mesh, o, r);
  const bool shBackground = o.background == nullptr;
  cl::Kernel k = rt.kernel("glossy_preview.cl", "preview_glossy",
                           detail::glossyPreviewOptions(no, light.order, shBackground));
  cl::Buffer normalsDev = rt.upload(normals), tDev = rt.upload(t), hemiDev = rt.upload(hemi),
             lobeDev = rt.upload(lobeG), bgDev = rt.upload(bg);
  int a = 0;
  k.setArg(a++, o.width);
  k.setArg(a++, o.height);
  for (cl::Buffer* b : {&scene.camera, &scene.nodes, &scene.tris, &scene.indices, &scene.albedo, &normalsDev, &tDev,
                        &hemiDev, &lobeDev})
    k.setArg(a++, *b);
  k.setArg(a++, go.normalised ? 1 : 0);
  k.setArg(a++, bgDev);
  detail::runPreviewKernel(rt, k, a, o, r);
  if (!shBackground) detail::fillBackground(r, scene.cam, rot, *o.background);
  return r;
}

}  // namespace prtbake
