// Private: the automatic framing of the mesh previews (preview_mesh.cpp), shared by the
// diffuse and the glossy (glossy_preview.cpp) renderers.
#pragma once

#include "prtbake/preview.h"
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

// Fills the pixels no triangle covers (r.hitTriangle < 0) from `background`, rotated like
// the lighting: L'(d) = L(Rᵀ d). Sets r.backgroundSeconds.
void fillBackground(MeshPreviewResult& r, const Camera& cam, const Rotation& rot, const EnvMap& background);

}  // namespace prtbake::detail
