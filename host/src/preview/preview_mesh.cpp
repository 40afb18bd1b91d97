// The mesh preview: camera set-up, light rotation, buffers, and the background from a
// map (see preview.h and kernels/preview.cl).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "core/constants.h"
#include "core/kernel_options.h"
#include "prtbake/bvh.h"
#include "prtbake/clock.h"
#include "prtbake/error.h"
#include "prtbake/preview.h"
#include "prtbake/sh_rotate.h"
#include "preview/preview_camera.h"

namespace prtbake {
namespace {
using Clock = std::chrono::steady_clock;

constexpr double kVerticalFovDeg = 35.0;  // of a landscape image (the narrower axis of a portrait one)
constexpr double kFill = 0.9;             // the bounds' corners stay inside 90% of the frame
constexpr size_t kLocalSize = 64;         // pixels per work-group (the traversal loops: PoCL runs it scalar)

}  // namespace

namespace detail {
Camera frameCamera(const Mesh& mesh, const MeshPreviewOptions& o) {
  double bmin[3], bmax[3];
  meshBounds(mesh, bmin, bmax);
  Camera c{};
  double radius = 0;
  for (int k = 0; k < 3; ++k) {
    c.centre[k] = 0.5 * (bmin[k] + bmax[k]);
    radius += 0.25 * (bmax[k] - bmin[k]) * (bmax[k] - bmin[k]);
  }
  radius = std::max(std::sqrt(radius), 1e-6);
  c.radius = radius;
  const double yaw = o.yawDeg * kPi / 180, pitch = o.pitchDeg * kPi / 180;
  const double toEye[3] = {std::sin(yaw) * std::cos(pitch), std::sin(pitch), std::cos(yaw) * std::cos(pitch)};
  const double right[3] = {std::cos(yaw), 0, -std::sin(yaw)};
  // up = right × forward, forward = −toEye
  const double f[3] = {-toEye[0], -toEye[1], -toEye[2]};
  const double up[3] = {right[1] * f[2] - right[2] * f[1], right[2] * f[0] - right[0] * f[2],
                        right[0] * f[1] - right[1] * f[0]};
  const double aspect = double(o.width) / double(o.height);
  double tanV = std::tan(0.5 * kVerticalFovDeg * kPi / 180), tanH = tanV * aspect;
  if (aspect < 1) tanH = std::tan(0.5 * kVerticalFovDeg * kPi / 180), tanV = tanH / aspect;
  // The nearest distance that keeps the 8 corners of the bounds inside kFill of the
  // frame (a corner q − centre at screen offsets (x, y) and depth offset z projects to
  // x / (D + z)), and keeps every corner in front of the eye.
  double distance = 0;
  for (int corner = 0; corner < 8; ++corner) {
    double q[3];
    for (int k = 0; k < 3; ++k) q[k] = ((corner >> k) & 1 ? bmax[k] : bmin[k]) - c.centre[k];
    const double x = q[0] * right[0] + q[1] * right[1] + q[2] * right[2];
    const double y = q[0] * up[0] + q[1] * up[1] + q[2] * up[2];
    const double z = q[0] * f[0] + q[1] * f[1] + q[2] * f[2];
    distance = std::max({distance, std::abs(x) / (kFill * tanH) - z, std::abs(y) / (kFill * tanV) - z,
                         0.05 * radius - z});
  }
  for (int k = 0; k < 3; ++k) {
    c.eye[k] = c.centre[k] + distance * toEye[k];
    c.forward[k] = f[k];
    c.right[k] = right[k] * tanH;
    c.up[k] = up[k] * tanV;
  }
  c.vfovDeg = 2 * std::atan(tanV) * 180 / kPi;
  return c;
}

}  // namespace detail

std::string detail::previewMeshOptions(int order, int channels, int lightOrder, bool shBackground) {
  return "-DSH_ORDER=" + std::to_string(order) + " -DCHANNELS=" + std::to_string(channels) +
         " -DBG_ORDER=" + std::to_string(lightOrder) + " -DSH_BACKGROUND=" + (shBackground ? "1" : "0");
}

void detail::checkMeshPreview(const Mesh& mesh, const ShCoeffs& radiance, const MeshPreviewOptions& o) {
  if (o.width < 8 || o.height < 8 || o.width > 16384 || o.height > 16384)
    throw UsageError("--size", "image size must be in [8, 16384] x [8, 16384]");
  if (!std::isfinite(o.yawDeg) || !std::isfinite(o.pitchDeg) || !std::isfinite(o.lightRotationDeg))
    throw UsageError("--view", "angles must be finite");
  validateMesh(mesh, mesh.sourcePath.empty() ? "mesh" : mesh.sourcePath);
  if (radiance.quantity != ShQuantity::Radiance)
    throw InputError("environment", std::string("the mesh preview needs radiance coefficients, not ") +
                                        toString(radiance.quantity));
}

ShCoeffs detail::rotatedLighting(const ShCoeffs& radiance, const MeshPreviewOptions& o, Rotation* rot) {
  *rot = Rotation();
  if (o.lightRotationDeg == 0) return radiance;
  const double len = std::sqrt(o.lightAxis[0] * o.lightAxis[0] + o.lightAxis[1] * o.lightAxis[1] +
                               o.lightAxis[2] * o.lightAxis[2]);
  if (!(len > 1e-12) || !std::isfinite(len)) throw UsageError("light axis", "must be a non-zero finite vector");
  const double a = o.lightRotationDeg * kPi / 180, s = std::sin(0.5 * a) / len;
  *rot = rotationFromQuaternion(std::cos(0.5 * a), o.lightAxis[0] * s, o.lightAxis[1] * s, o.lightAxis[2] * s);
  return applyShRotation(radiance, shRotationExact(*rot, radiance.order));
}

detail::PreviewScene detail::uploadPreviewScene(Runtime& rt, const Mesh& mesh, const MeshPreviewOptions& o,
                                                MeshPreviewResult& r) {
  r.triangles = mesh.triangleCount();
  const auto tBvh = Clock::now();
  const Bvh bvh = buildBvh(mesh);
  r.bvhSeconds = secondsSince(tBvh);
  std::vector<Bvh::Node> nodes = bvh.nodes;
  std::vector<float> packed = bvh.packed;
  if (nodes.empty()) {  // every triangle has zero area: one leaf with an empty box
    nodes = {Bvh::Node{{1, 1, 1}, 0, {-1, -1, -1}, 1}};
    packed.assign(12, 0.0f);
  }
  std::vector<int32_t> idx(mesh.triangleCount() * 4, 0);
  for (size_t k = 0; k < mesh.triangleCount(); ++k)
    for (int j = 0; j < 3; ++j) idx[4 * k + j] = int32_t(mesh.indices[3 * k + j]);
  std::vector<float> albedo(mesh.vertexCount() * 4, 0.0f);
  for (size_t v = 0; v < mesh.vertexCount(); ++v)
    for (int c = 0; c < 3; ++c) albedo[4 * v + c] = mesh.albedo[3 * v + c];

  PreviewScene scene;
  scene.cam = frameCamera(mesh, o);
  const Camera& cam = scene.cam;
  std::vector<float> camBuf(16, 0.0f);
  for (int k = 0; k < 3; ++k) {
    camBuf[k] = float(cam.eye[k]);
    camBuf[4 + k] = float(cam.forward[k]);
    camBuf[8 + k] = float(cam.right[k]);
    camBuf[12 + k] = float(cam.up[k]);
  }
  camBuf[3] = float(cam.radius);
  char desc[256];
  std::snprintf(desc, sizeof desc, "eye (%.4g, %.4g, %.4g), looking at (%.4g, %.4g, %.4g), vertical fov %.1f deg",
                cam.eye[0], cam.eye[1], cam.eye[2], cam.centre[0], cam.centre[1], cam.centre[2], cam.vfovDeg);
  r.camera = desc;
  scene.camera = rt.upload(camBuf);
  scene.nodes = rt.upload(nodes);
  scene.tris = rt.upload(packed);
  scene.indices = rt.upload(idx);
  scene.albedo = rt.upload(albedo);
  return scene;
}

void detail::runPreviewKernel(Runtime& rt, cl::Kernel& k, int arg, const MeshPreviewOptions& o, MeshPreviewResult& r) {
  const int pixels = o.width * o.height;
  cl::Buffer rgbDev(rt.context(), CL_MEM_WRITE_ONLY, size_t(pixels) * 12);
  cl::Buffer hitDev(rt.context(), CL_MEM_WRITE_ONLY, size_t(pixels) * 4);
  k.setArg(arg, rgbDev);
  k.setArg(arg + 1, hitDev);
  const auto tKernel = Clock::now();
  const size_t global = (size_t(pixels) + kLocalSize - 1) / kLocalSize * kLocalSize;
  rt.queue().enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(global), cl::NDRange(kLocalSize));
  r.image.width = o.width;
  r.image.height = o.height;
  r.image.rgb.resize(size_t(pixels) * 3);
  r.hitTriangle.resize(size_t(pixels));
  rt.queue().enqueueReadBuffer(rgbDev, CL_TRUE, 0, r.image.rgb.size() * 4, r.image.rgb.data());
  rt.queue().enqueueReadBuffer(hitDev, CL_TRUE, 0, r.hitTriangle.size() * 4, r.hitTriangle.data());
  r.kernelSeconds = secondsSince(tKernel);
}

MeshPreviewResult renderMeshPreview(Runtime& rt, const Mesh& mesh, const TransportCoeffs& t, const ShCoeffs& radiance,
                                    const MeshPreviewOptions& o) {
  detail::checkMeshPreview(mesh, radiance, o);
  if (radiance.order < 1 || radiance.rgb.size() != size_t(radiance.order) * size_t(radiance.order))
    throw InputError("environment", "malformed SH coefficients");
  if (t.channels != 1 && t.channels != 3) throw InputError("transport", "channels must be 1 or 3");
  if (t.order < 1 || t.coeffs.size() != t.vertexCount * size_t(t.channels) * size_t(t.order) * size_t(t.order))
    throw InputError("transport", "coefficient count does not match its shape");
  if (t.vertexCount != mesh.vertexCount())
    throw InputError("transport", "has " + std::to_string(t.vertexCount) + " vertices but the mesh has " +
                                      std::to_string(mesh.vertexCount()));
  Rotation rot;
  const ShCoeffs light = detail::rotatedLighting(radiance, o, &rot);
  const int nc = t.order * t.order, nb = light.order * light.order;
  std::vector<float> shade(size_t(3) * nc, 0.0f), bg(size_t(3) * nb);
  for (int c = 0; c < 3; ++c) {
    for (int i = 0; i < std::min(nc, nb); ++i) shade[size_t(c) * nc + i] = float(light.rgb[size_t(i)][size_t(c)]);
    for (int i = 0; i < nb; ++i) bg[size_t(c) * nb + i] = float(light.rgb[size_t(i)][size_t(c)]);
  }

  MeshPreviewResult r;
  detail::PreviewScene scene = detail::uploadPreviewScene(rt, mesh, o, r);
  const bool shBackground = o.background == nullptr;
  cl::Kernel k = rt.kernel("preview.cl", "preview_mesh",
                           detail::previewMeshOptions(t.order, t.channels, light.order, shBackground));
  cl::Buffer tDev = rt.upload(t.coeffs), lightDev = rt.upload(shade), bgDev = rt.upload(bg);
  int a = 0;
  k.setArg(a++, o.width);
  k.setArg(a++, o.height);
  for (cl::Buffer* b : {&scene.camera, &scene.nodes, &scene.tris, &scene.indices, &scene.albedo, &tDev, &lightDev, &bgDev})
    k.setArg(a++, *b);
  detail::runPreviewKernel(rt, k, a, o, r);
  if (!shBackground) detail::fillBackground(r, scene.cam, rot, *o.background);
  return r;
}

void detail::fillBackground(MeshPreviewResult& r, const Camera& cam, const Rotation& rot, const EnvMap& background) {
  const auto tBg = Clock::now();
  const int width = r.image.width, height = r.image.height;
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const size_t p = size_t(y) * size_t(width) + size_t(x);
      if (r.hitTriangle[p] >= 0) continue;
      const double px = 2 * (x + 0.5) / width - 1, py = 1 - 2 * (y + 0.5) / height;
      double d[3], n = 0;
      for (int j = 0; j < 3; ++j) d[j] = cam.forward[j] + px * cam.right[j] + py * cam.up[j], n += d[j] * d[j];
      n = std::sqrt(n);
      const auto& m = rot.m;
      const double dm[3] = {(m[0] * d[0] + m[3] * d[1] + m[6] * d[2]) / n, (m[1] * d[0] + m[4] * d[1] + m[7] * d[2]) / n,
                            (m[2] * d[0] + m[5] * d[1] + m[8] * d[2]) / n};
      const Rgb v = sampleEnvironment(background, dm);
      for (int c = 0; c < 3; ++c) r.image.rgb[3 * p + size_t(c)] = float(v[size_t(c)]);
    }
  r.backgroundSeconds = secondsSince(tBg);
}

}  // namespace prtbake
