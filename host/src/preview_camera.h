// Private: the automatic framing of the mesh previews (preview_mesh.cpp), shared by the
// diffuse and the glossy (glossy_preview.cpp) renderers.
#pragma once

#include "prtbake/preview.h"

namespace prtbake::detail {

struct Camera {
  double eye[3], forward[3], right[3], up[3];  // right and up scaled by tan(fov/2)
  double vfovDeg;
  double centre[3];
  double radius;
};

// The camera of MeshPreviewOptions (orbit, field of view, distance that frames the bounds).
Camera frameCamera(const Mesh& mesh, const MeshPreviewOptions& options);

}  // namespace prtbake::detail
