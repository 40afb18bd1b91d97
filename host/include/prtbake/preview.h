// prtbake/preview.h: images of what was baked, for people to check at a glance.
//
// Renderers return linear RGB float images (tests read them before tone mapping);
// writePreviewPng tone-maps (exposure in stops, then the sRGB curve, clamped) and
// writes an 8-bit PNG with the tone map and the image's meaning in tEXt chunks.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "prtbake/env.h"
#include "prtbake/envmap.h"
#include "prtbake/glossy.h"
#include "prtbake/lut.h"
#include "prtbake/mesh.h"
#include "prtbake/prefilter.h"
#include "prtbake/probes.h"
#include "prtbake/runtime.h"
#include "prtbake/transport.h"

namespace prtbake {

struct LinearImage {
  int width = 0, height = 0;
  std::vector<float> rgb;  // interleaved, row 0 on top
  std::array<float, 3> at(int x, int y) const {
    const size_t i = 3 * (size_t(y) * size_t(width) + size_t(x));
    return {rgb[i], rgb[i + 1], rgb[i + 2]};
  }
};

// The environment's radiance in direction `dirWorld` (nearest texel; yaw applied).
Rgb sampleEnvironment(const EnvMap& env, const double dirWorld[3]);

// Lat-long panels (OpenEXR LatLongMap axes, +Y up), each width × width/2, side by
// side: [the environment |] the SH reconstruction of its radiance | the
// reconstructed irradiance/π (the shading of a white diffuse surface). `radiance`
// holds radiance coefficients (windowed as wanted); env may be null.
LinearImage renderEnvPreview(const EnvMap* env, const ShCoeffs& radiance, int panelWidth);

// One panel per named channel of a table over (x = column, y = row), drawn with
// row 0 at the BOTTOM (so the second axis grows upward), grey-scale in [lo, hi],
// with a frame, axis labels and tick values.
struct LutChannel {
  std::string name;
  const float* data;  // size × size values, row-major, row 0 first
};
LinearImage renderLutPreview(int size, const std::vector<LutChannel>& channels, const std::string& xLabel,
                             const std::string& yLabel, float lo, float hi, int panelSize);

struct ToneMap {
  double exposureStops = 0.0;  // linear × 2^exposure before the sRGB curve
};

// Writes the PNG atomically; `text` adds tEXt chunks (key, value).
void writePreviewPng(const std::string& path, const LinearImage& image, const ToneMap& toneMap,
                     const std::vector<std::pair<std::string, std::string>>& text = {});
// The PNG's bytes (for a caller that writes several outputs together).
std::string previewPngBytes(const LinearImage& image, const ToneMap& toneMap,
                            const std::vector<std::pair<std::string, std::string>>& text = {});

// --- mesh preview: the mesh lit by the baked transport, as a real-time engine shades it ---
//
// The transport read back: TransportCoeffs, readTransportNpy, readTransportGltf (transport.h).

struct MeshPreviewOptions {
  int width = 800, height = 600;
  // Camera orbit around the centre of the mesh's bounds, in degrees. The camera sits
  // in direction (sin yaw cos pitch, sin pitch, cos yaw cos pitch) from the centre and
  // looks at it: yaw 0, pitch 0 is the front view (looking along −Z), yaw 90 the side
  // view (from +X), pitch 90 the top view (from +Y, screen-up = −Z). Screen-right is
  // (cos yaw, 0, −sin yaw). Vertical field of view 35° (landscape; for a portrait
  // image 35° is the horizontal one); the distance is the nearest at which the 8
  // corners of the mesh's bounds lie within the central 90% of the frame.
  double yawDeg = 0, pitchDeg = 0;
  // Rotates the lighting (the environment and its SH, with the exact SH rotation of
  // sh_rotate.h) by this angle about `lightAxis` (right-handed: counter-clockwise
  // looking down the axis toward the origin; any length but zero). Default axis +Y
  // (a turntable of light).
  double lightRotationDeg = 0;
  std::array<double, 3> lightAxis{0, 1, 0};
  // Background: sampled from this map when set (rotated like the lighting), else the
  // SH radiance reconstruction in each pixel's view direction.
  const EnvMap* background = nullptr;
};

struct MeshPreviewResult {
  LinearImage image;            // linear radiance, before tone mapping
  std::vector<int32_t> hitTriangle;  // per pixel: the mesh triangle seen, or −1 (background)
  double bvhSeconds = 0, kernelSeconds = 0, backgroundSeconds = 0;
  size_t triangles = 0;
  std::string camera;           // "eye (x, y, z), looking at (x, y, z), vfov D deg" (metadata)
};

// Renders one camera ray per pixel centre through the transport BVH (bvh.h). At the
// nearest hit (triangle vertices a, b, c, barycentrics (1−u−v, u, v)):
//   T = (1−u−v) T_a + u T_b + v T_c   (each channel; grey transport serves all three)
//   ρ = (1−u−v) ρ_a + u ρ_b + v ρ_c   (mesh albedo)
//   L_o[c] = ρ[c] Σ_i l_i[c] T_i[c]   (l: the radiance coefficients, rotated)
// The sum runs over the shorter of the two orders (the transport's order bounds what
// the lighting can contribute; a lower-order environment contributes zero above its
// bands); the background uses all of the environment's bands.
// Back faces are shaded with the same transport (it is baked per vertex, not per side).
// Throws InputError when the coefficients do not match the mesh or radiance is not
// radiance, UsageError for bad options.
MeshPreviewResult renderMeshPreview(Runtime& rt, const Mesh& mesh, const TransportCoeffs& transport,
                                    const ShCoeffs& radiance, const MeshPreviewOptions& options);

// --- probe grid preview ---
//
// Two panels side by side: the scene seen by `view`'s camera, each vertex shaded ρ E/π with E/π
// from the grid at the vertex moved half a cell along its normal (probeGridIrradianceOverPi, as
// three.js's shader samples the grid; interpolated over the triangles), and a sphere at every
// probe's position (moved probes where they were baked; every k-th probe along each axis when
// there are more than maxSpheres), white and shaded by that probe's own coefficients, red where
// the probe is invalid (filled from its neighbours); then the horizontal slice through the grid's
// middle height, x to the right and z downwards, shaded with E/π for an upward normal.
LinearImage renderProbeGridPreview(Runtime& rt, const Mesh& scene, const ProbeGridResult& grid,
                                   const MeshPreviewOptions& view, int maxSpheres = 4096);

// --- lightmap preview ---
//
// One row per product of the lightmap (ao, bent, bent_tangent, irradiance, sh, transport): on the
// left the mesh seen by `view`'s camera (size, orbit; the lighting options do not apply), each
// pixel showing the product read from the lightmap as an engine's linear sampler reads it
// (bilinear at the UV of the lightmap's set at the camera ray's hit, clamped to the edge: black
// shows a texel no repair reached); on the right the atlas, a square as tall as the view
// (nearest texel, empty texels dark blue). Shown: ao grey; bent as a normal map's colours
// (0.5 + b/2 after the sRGB curve); irradiance E/π; sh E/π = Σ_j D_j Y_j(n) along the
// interpolated shading normal (the atlas: the L0 term); transport under a white sky (√(4π) T_0).
// Throws InputError naming the mesh when it lacks the lightmap's UV set.
struct LightmapResult;
LinearImage renderLightmapPreview(Runtime& rt, const Mesh& mesh, const LightmapResult& lightmap,
                                  const MeshPreviewOptions& view);

// --- prefiltered chain preview ---
//
// Every level as a lat-long panel (OpenEXR LatLongMap axes, +Y up; panelWidth × panelWidth/2)
// side by side, labelled with its roughness and size, and below them six spheres from mirror
// to rough (r = 0, 0.2, …, 1) seen from +Z, shaded as an engine shades with the split sum:
// L = P(R, r) · (f0 A + B)(N·V, r) with f0 = 1 (a white metal), P read trilinearly from this
// chain (between the two levels whose roughness brackets r) and A, B from prtbake's own GGX LUT
// (32², 256 samples); Charlie lobes use the LUT's cloth table C instead of A + B, lambertian
// chains show P(N) (albedo 1). R = reflect(−V, N), V = +Z.
LinearImage renderPrefilterPreview(Runtime& rt, const PrefilterResult& chain, int panelWidth);
// One of those spheres: radius 1 seen from +Z by an orthographic camera (V = +Z; screen right
// +X, up +Y) filling size × size pixels, at perceptual roughness `roughness`, with A, B (or C for
// a cloth table) from `lut`. Pixels off the sphere are 0 and false in *mask.
LinearImage renderSplitSumSphere(const PrefilterResult& chain, const LutResult& lut, double roughness, int size,
                                 std::vector<bool>* mask = nullptr);
// Renders it and writes the PNG (tone map: exposure 0), stating what it shows.
void writePrefilterPreviewPng(const std::string& path, Runtime& rt, const PrefilterResult& chain, int panelWidth,
                              const std::string& source);

// Draws `text` with a small vector font into a linear image at (x, y), scaled.
void drawText(LinearImage& image, int x, int y, const std::string& text, float value, int scale = 1);

// --- preview: the mesh shaded view-dependently with glossy transfer ---
struct GlossyPreviewOptions {
  MeshPreviewOptions view;    // size, camera, light rotation, background
  bool normalised = true;     // divide by glossyHorizonNorm (the furnace shows the albedo)
};
// Per vertex t_v = M_v l (rotated lighting), interpolated with barycentrics per pixel with
// the normal; R = reflect(view, n); L = ρ(p) × shadeGlossy(lobe, t, R). `matrices` holds
// matrices (V × channels × n_out² × n_in²) or, with `cpca`, is empty and the CPCA
// reconstruction is used.
MeshPreviewResult renderGlossyPreview(Runtime& rt, const Mesh& mesh, const GlossyMatrices& matrices,
                                      const CpcaResult* cpca, const ShCoeffs& radiance, const GlossyLobe& lobe,
                                      const GlossyPreviewOptions& options);

}  // namespace prtbake
