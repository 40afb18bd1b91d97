// Private: what the mesh previews share (preview_mesh.cpp): the checks of their inputs, the
// rotated lighting, the automatic framing, the scene on the device and the launch, used by
// the diffuse and the glossy (preview_glossy.cpp) renderers.
#pragma once

#include "prtbake/preview.h"
#include "prtbake/runtime.h"
#include "prtbake/sh_rotate.h"

namespace prtbake::detail {

struct Camera {
  double eye[3], forward[3], right[3], up[3];  // right and up scaled by tan(fov/2)
  double vfovDeg;
  double centre[3];
  double radius;
};

// The camera of MeshPreviewOptions (orbit, field of view, distance that frames the bounds).
Camera frameCamera(const Mesh& mesh, const MeshPreviewOptions& options);

// The checks of both mesh previews: image size, finite angles, the mesh, radiance lighting.
void checkMeshPreview(const Mesh& mesh, const ShCoeffs& radiance, const MeshPreviewOptions& o);

// The lighting rotated by o.lightRotationDeg about o.lightAxis: L'(ω) = L(Rᵀω), c' = M c
// (sh_rotate.h); the rotation in *rot (identity when there is none).
ShCoeffs rotatedLighting(const ShCoeffs& radiance, const MeshPreviewOptions& o, Rotation* rot);

// The scene the preview kernels trace, on the device: the camera (eye, radius, forward, right,
// up: 16 floats), the BVH's nodes and triangles, each triangle's vertex indices and each
// vertex's albedo. r gets the triangle count, the BVH's seconds and the camera's description.
struct PreviewScene {
  Camera cam;
  cl::Buffer camera, nodes, tris, indices, albedo;
};
PreviewScene uploadPreviewScene(Runtime& rt, const Mesh& mesh, const MeshPreviewOptions& o, MeshPreviewResult& r);

// Runs k over the image's pixels, its arguments set but for the last two (from `arg` on: the
// RGB image and the hit triangles), which this sets; reads r.image and r.hitTriangle back and
// sets r.kernelSeconds.
void runPreviewKernel(Runtime& rt, cl::Kernel& k, int arg, const MeshPreviewOptions& o, MeshPreviewResult& r);

// Fills the pixels no triangle covers (r.hitTriangle < 0) from `background`, rotated like
// the lighting: L'(d) = L(Rᵀ d). Sets r.backgroundSeconds.
void fillBackground(MeshPreviewResult& r, const Camera& cam, const Rotation& rot, const EnvMap& background);

}  // namespace prtbake::detail
