// prtbake/glossy.h: glossy PRT, per-vertex transfer matrices (docs/conventions.md, "Glossy transfer").
//
// For vertex p with unit normal n, the transfer matrix M(p), n_out² × n_in², maps the
// environment's radiance coefficients l (order n_in) to the SH coefficients (order n_out)
// of the radiance that reaches p from above its tangent plane, in the world frame:
//   M_ij(p) = ∫ V(p, ω) H(n·ω) Y_i(ω) Y_j(ω) dω                            (shadowed)
// Unshadowed drops V. Interreflected adds the light that the scene's diffuse surfaces
// send to p: a ray from p that hits q brings q's diffuse exit radiance ρ(q) Σ_j l_j T_j(q),
// with T(q) the diffuse transport (transport.h) summed over bounces 0..B−1, so
//   M_ij(p) += ∫_{ray p→q hits} H(n·ω) Y_i(ω) ρ(q) T_j(q) dω.
// Shading with a lobe circularly symmetric about the reflected view direction R:
//   L_o = Σ_lm ĝ_l (M l)_lm Y_lm(R)      (ĝ_l: the lobe's Funk–Hecke factors, GlossyLobe)
// The clamped cosine about n over π (ĝ_l = Â_l/π) gives back the diffuse transport up to
// its truncation at order n_out: T_j ≈ Σ_i (Â_l(i)/π) Y_i(n) M_ij (see
// clampedCosineTruncationBound).
//
// Estimators (docs/glossy.md derives them):
//   shadowed:      N directions uniform over the hemisphere of n (pdf 1/2π), the shifted
//                  Hammersley set of transport.h warped from cosine to uniform
//                  (z_u = z_c², (x_u, y_u) = (x_c, y_c) √(1 + z_c²)):
//                  M_ij ≈ (2π/N) Σ_s V_s Y_i(ω_s) Y_j(ω_s)
//   unshadowed:    closed form by an exact product rule (Gauss–Legendre in n·ω with
//                  n_max points × 2 n_max azimuths: exact for the degree-2(n_max−1)
//                  polynomial Y_i Y_j), no rays
//   interreflected: the shadowed term plus, with the same directions,
//                  (2π/N) Σ_{s hits q_s} Y_i(ω_s) ρ(q_s) T_j(q_s)
// Every estimate M̂ = Yᵀ W Y (W ≥ 0 diagonal) is symmetric positive semidefinite for any
// sample set when n_in = n_out and there is no interreflection.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "prtbake/env.h"
#include "prtbake/mesh.h"
#include "prtbake/runtime.h"
#include "prtbake/transport.h"

namespace prtbake {

// Orders accepted for n_in and n_out.
constexpr int kMinGlossyOrder = 2;
constexpr int kMaxGlossyOrder = 6;

enum class MatrixDtype { Float32, Float16 };
const char* matrixDtypeName(MatrixDtype d);  // "float32" | "float16"
MatrixDtype parseMatrixDtype(const std::string& name);  // UsageError otherwise

struct GlossyOptions {
  TransportMode mode = TransportMode::Shadowed;
  int orderOut = 5, orderIn = 5;  // kMinGlossyOrder..kMaxGlossyOrder each
  int samples = 1024;             // directions per vertex (shadowed, interreflected)
  uint64_t seed = 0;
  // Interreflected: the diffuse transport T gathered at the hit points sums bounces
  // 0..bounces−1 (so M holds light of at most `bounces` bounces); the diffuse bounces
  // stop early as transport.h's do (bounceTolerance).
  int bounces = 3;
  double bounceTolerance = 1e-4;
  std::optional<std::array<float, 3>> albedoOverride;
  // The vertex range to compute, as TransportOptions: each vertex's rays depend only on
  // its global index and the seed, so a range is bit-identical to the same vertices of a
  // whole run (interreflected too: the diffuse transport is computed for the whole mesh).
  size_t firstVertex = 0;
  std::optional<size_t> vertexCount;
  // Vertices per device launch: device and host memory stay bounded by a block.
  size_t blockVertices = 4096;
  // Work-items per vertex: 1, the packet kernels (16 rays a work-item in vectors, a CPU's);
  // 2, 4, 8, 16 or 32, the lane form (each work-item traces one ray of a step and sums its
  // share of the matrix entries: a GPU's). −1: by the device (detail::rayLanesFor: 1 on a
  // CPU, 32 elsewhere). The results agree up to float summation order; the lane form's do not
  // depend on the work-group size.
  int rayLanes = -1;
};

// As transport's: the base colour textures too when interreflected without an albedo override.
inline MeshAlbedo meshAlbedo(const GlossyOptions& o) {
  return o.mode == TransportMode::Interreflected && !o.albedoOverride ? MeshAlbedo::Textures : MeshAlbedo::Factors;
}

struct GlossyStats {
  int orderOut = 0, orderIn = 0;
  int channels = 1;            // 3 when interreflected with a coloured albedo
  size_t vertexCount = 0, firstVertex = 0;
  int samples = 0;
  uint64_t rays = 0;
  // Independent-sample standard error of M̂ (Frobenius norm), per vertex:
  // √((v n_out² n_in²/4 − |M|²)/N), v = 2 M_00 the visible fraction (Σ_i Y_i² = n²/4π).
  double maxStdError = 0, meanStdError = 0;
  int bouncesUsed = 0;         // interreflected: the most bounces of light in M
  size_t verticesUnoccludable = 0, verticesWithoutNormal = 0, degenerateTriangles = 0, bvhNodes = 0;
  double diffuseSeconds = 0, kernelSeconds = 0, totalSeconds = 0;
  std::string device;
  size_t valuesPerVertex() const { return size_t(channels) * orderOut * orderOut * orderIn * orderIn; }
};

struct GlossyResult {
  GlossyStats stats;
  std::vector<float> matrices;  // vertexCount × channels × n_out² × n_in², row-major, row = output coefficient
  const float* vertex(size_t v) const { return matrices.data() + v * stats.valuesPerVertex(); }
};

// Checks the options (UsageError naming the option, orders out of range included).
void checkGlossyOptions(const GlossyOptions& options);
// The channels a bake of `mesh` has: 3 when interreflected with a coloured albedo, else 1.
int glossyChannels(const Mesh& mesh, const GlossyOptions& options);
// Bytes of float32 matrices of `vertices` vertices: vertices × channels × n_out² × n_in² × 4.
double glossyMatrixBytes(size_t vertices, int channels, int orderOut, int orderIn);

// Computes the matrices vertex block by vertex block and hands each block to `sink`
// (first vertex of the block, its vertex count, the block's values in the layout of
// GlossyResult::matrices). Memory: one block, whatever the mesh's size.
// Throws UsageError for bad options, InputError for an unusable mesh.
using GlossyBlockSink = std::function<void(size_t firstVertex, size_t count, const float* values)>;
GlossyStats bakeGlossyTransfer(Runtime& rt, const Mesh& mesh, const GlossyOptions& options,
                               const GlossyBlockSink& sink);
// The same for surface points (prtbake/transport.h, SurfacePoints): point i takes the rays a
// vertex of index i would, from its position offset along its face normal, over the hemisphere
// of its shading normal (as computeTransportAtPoints). The options' vertex range must be the
// default; `firstVertex` in the sink is the first point of the block.
GlossyStats bakeGlossyTransferAtPoints(Runtime& rt, const Mesh& mesh, const SurfacePoints& points,
                                       const GlossyOptions& options, const GlossyBlockSink& sink);
// The whole tensor in memory. UsageError stating the size when it exceeds the memory
// limit (inputMemoryLimit(), 4 GiB by default: PRTBAKE_INPUT_LIMIT_MB).
GlossyResult computeGlossyTransfer(Runtime& rt, const Mesh& mesh, const GlossyOptions& options);

// Double-precision CPU reference on exactly the kernel's rays (origins, frames, the
// uniform directions of the seed), brute force over every triangle (small meshes).
// Interreflected: the diffuse transport at the hit points comes from `diffuse`
// (vertexCount × channels × n_in², as TransportResult::coeffs of the matching
// transport run; channels = 1 is applied to every channel).
GlossyResult computeGlossyReference(const Mesh& mesh, const GlossyOptions& options,
                                    const std::vector<float>* diffuse = nullptr, int diffuseChannels = 1);

// The uniform hemisphere directions (x, y, z, 0) in the local frame (z = normal) of
// directions first … first + count − 1 of the seed's `samples`-point set.
std::vector<float> glossyDirectionChunk(int samples, int first, int count, uint64_t seed);

// --- closed forms (the oracles, and the unshadowed product) ---

// ∫_{n·ω ≥ cos α} Y_i(ω) Y_j(ω) dω for i, j < order², the visible cone of half-angle α
// about the unit vector n (α = π/2: the hemisphere, the unshadowed matrix). Computed in
// the frame of n (zonal: only equal m couple, a 1-D Legendre integral exact by
// Gauss–Legendre), then rotated with the exact SH rotation: M(n) = S M_z Sᵀ.
std::vector<double> coneGramMatrix(int order, const std::array<double, 3>& n, double halfAngleRad);
// Gaunt coefficients ∫ Y_i Y_j Y_k dω over the sphere, i, j < order², k < kOrder²
// (exact quadrature), as [i][j][k] flattened.
std::vector<double> gauntCoefficients(int order, int kOrder);
// ||c − c_n||₂ for c = max(0, n·ω)/π truncated after order n: √(Σ_{l≥n} (2l+1)/(4π) (Â_l/π)²).
// |T_j − Σ_i (Â_l/π) Y_i(n) M_ij| ≤ this × √(∫ V H Y_j²) ≤ this / √2 (Cauchy–Schwarz).
double clampedCosineTruncationBound(int orderOut);

// --- lobes: Funk–Hecke factors ĝ_l, l = 0..order−1 ---
struct GlossyLobe {
  std::string name;          // "phong s=32", "ggx r=0.5", "cosine"
  std::vector<double> g;     // ĝ_l
  double fitError = 0;       // GGX: the fit's stated error (see ggxLobe), 0 when exact
  double phongExponent = 0;  // the normalised Phong exponent (GGX: the fitted one)
};
// Normalised Phong G(t) = (s+1)/(2π) max(0, t)^s (∫ G dω = 1), exact Funk–Hecke factors:
//   ĝ_l = (s+1) ∫_0^1 t^s P_l(t) dt,  ĝ_0 = 1, ĝ_1 = (s+1)/(s+2), ĝ_l = ĝ_{l−2} (s−l+2)/(s+l+1).
// s = 1 is the clamped cosine over π (ĝ_l = Â_l/π). s ≥ 0.
GlossyLobe phongLobe(double exponent, int order);
// The GGX lobe about R as split-sum prefiltering takes it (N = V = R, docs/conventions.md
// "Prefiltered specular"): G(t) ∝ D_α(h) max(0, t) with h·R = cos(θ/2), t = cos θ, α = r²,
// normalised to ∫ G dω = 1; ĝ_l by adaptive Gauss–Legendre quadrature (exact to 1e-10).
// fitError: the relative L2 error of the lobe truncated after `order` bands,
// √(Σ_{l≥order} (2l+1) ĝ_l²/Σ_l (2l+1) ĝ_l²) over l < 64; phongExponent: the s whose
// Phong factors fit the GGX ones best in least squares over l < order.
GlossyLobe ggxLobe(double roughness, int order);

// "cosine" (phong s=1), "phong:S", "ggx:R" (roughness R). UsageError naming `option` otherwise.
GlossyLobe parseGlossyLobe(const std::string& text, int order, const std::string& option = "--lobe");

// The seed's arbitrary-BRDF form (Sloan et al. 2002): in the local frame (z = normal),
//   B_{k,k'} = ∫_{H} ∫_{H} Y_k(ω_o) f(ω_i, ω_o) cos θ_i Y_k'(ω_i) dω_i dω_o,
// order² × order², for an isotropic microfacet BRDF: GGX D, height-correlated Smith G₂,
// Schlick Fresnel with f0 (f90 = 1); `lambertian` = true gives f = albedo/π instead.
// The exit radiance of vertex p over ω_o: L_o(ω_o) = Σ_k (E l)_k Y_k(ω_o),
// E(p) = S(p) B Sᵀ(p) M(p), S(p) the SH rotation from the local frame to the world.
struct BrdfSpec {
  bool lambertian = false;
  double roughness = 0.5;  // perceptual, α = r² (≥ 0.05: the quadrature resolves the peak)
  double f0 = 0.04;
  double albedo = 1.0;      // lambertian only
};
// "ggx:R[:F0]" (F0 default 0.04) or "lambertian[:A]". UsageError otherwise.
BrdfSpec parseBrdfSpec(const std::string& text, const std::string& option = "--brdf");
std::vector<double> brdfMatrixLocal(const BrdfSpec& brdf, int order, int quadraturePoints = 32);
// Replaces the matrices of vertices first … first + count − 1 (layout of
// GlossyResult::matrices) by their exit-radiance matrices E = S B Sᵀ M, in place; B of
// order n_out. The frame: any rotation taking +z to the vertex normal (B is isotropic).
void exitRadianceBlock(const Mesh& mesh, size_t first, size_t count, int channels, int orderOut, int orderIn,
                       const std::vector<double>& brdfLocal, float* values);

// ĥ_l = 2π ∫_0^1 P_l(t) dt, the Funk–Hecke factors of the hemisphere's indicator H(n·ω):
// ∫ H(n·ω) Y_lm(ω) dω = ĥ_l Y_lm(n) (ĥ_0 = 2π, ĥ_1 = π, ĥ_l = 0 for even l > 0).
double hemisphereFactor(int l);

// --- shading (the host reference of the preview and of docs/glsl/prt_glossy.glsl) ---
// The "horizon-normalised" lobe: D(c) = Σ_l ĝ_l ĥ_l (2l+1)/(4π) P_l(c), c = n·R, is what the
// lobe returns from an unoccluded vertex under a white sky (ĥ_l = 2π ∫_0^1 P_l: the SH of
// the hemisphere); shading divides by it, so that a white furnace shows exactly the albedo.
double glossyHorizonNorm(const GlossyLobe& lobe, int orderOut, double cosNR);
// L = Σ_lm ĝ_l t_lm Y_lm(R) (t = M l, n_out² values), divided by glossyHorizonNorm when
// normalised (cosNR clamped to ≥ −0.95 there).
double shadeGlossy(const GlossyLobe& lobe, int orderOut, const double* t, const std::array<double, 3>& R,
                   bool normalised, double cosNR);

// --- CPCA (Sloan et al. 2003): clustered PCA of the vertices' matrices ---
struct CpcaOptions {
  int clusters = 0;          // K (0: chosen from targetError)
  int vectors = 0;           // P (0: chosen from targetError)
  double targetError = 0;    // > 0: the cheapest (K, P) of a fixed ladder with total relative RMS ≤ this
  int iterations = 10;       // the most Lloyd iterations (stops when < 0.1 % of vertices move)
  int threads = 0;           // 0: hardware concurrency
  int weightBits = 32;       // 32: float32 weights; 8: int8 weights, w = q · c_kp · t_v (CpcaResult)
};
constexpr int kMaxCpcaVectors = 128;
struct CpcaResult {
  int clusters = 0, vectors = 0;
  size_t vertexCount = 0, dim = 0;  // dim = values per vertex (channels × n_out² × n_in²)
  std::vector<float> means;         // K × dim
  std::vector<float> basis;         // K × P × dim (orthonormal rows per cluster)
  std::vector<int32_t> clusterOf;   // V
  std::vector<float> weights;       // V × P: w = Bᵀ(x − μ) (int8: q · (c_kp · t_v), cpcaInt8Value)
  int weightBits = 32;              // 32, or 8: int8 weights q_vp with float32 scales c_kp and t_v
  std::vector<float> weightScales;  // int8: K × P, c_kp = RMS of weight p over cluster k
  std::vector<float> vertexScales;  // int8: V, t_v = max_p |w_vp| / c_kp / 127
  std::vector<float> vertexError;   // V: |x − x̃| / |x| (0 for a zero matrix)
  double totalError = 0;            // √(Σ|x − x̃|² / Σ|x|²)
  double rmsVertexError = 0, maxVertexError = 0;
  int iterations = 0;
  std::vector<std::array<double, 3>> tried;  // targetError: (K, P, total error) evaluated
  double seconds = 0;
  // Bytes stored (means + basis + ids + weights + scales) and the ratio to V × dim float32.
  double storedBytes() const;
  double compressionRatio() const;
};
// x̃_v = μ_k + Σ_p w_vp b_kp, k = clusterOf[v]. `data`: V × dim floats.
CpcaResult cpcaCompress(const float* data, size_t vertices, size_t dim, const CpcaOptions& options);
void cpcaReconstruct(const CpcaResult& c, size_t v, float* out);
// The int8 step of weight p of vertex v, s = c_kp · t_v; the code of weight w under s, and its
// value q · s: compressor, writer and reader agree on them bit for bit.
inline float cpcaInt8Step(const CpcaResult& c, size_t v, size_t p) {
  return c.weightScales[size_t(c.clusterOf[v]) * size_t(c.vectors) + p] * c.vertexScales[v];
}
inline int8_t cpcaInt8Code(float w, float s) {
  return s > 0 ? int8_t(std::clamp(std::lround(w / s), -127L, 127L)) : int8_t(0);
}
inline float cpcaInt8Value(int8_t q, float s) { return float(q) * s; }

// --- files ---
// A .npy written block by block: the header with the final shape first, data appended
// (float32 or float16), renamed into place by commit() (atomic, like AtomicFile).
class NpyStreamWriter {
 public:
  NpyStreamWriter(const std::string& path, const std::vector<size_t>& shape, MatrixDtype dtype);
  ~NpyStreamWriter();
  void append(const float* values, size_t count);
  void commit();
  const std::string& path() const;

 private:
  struct Impl;
  Impl* impl_;
};
// The .npy (version 1.0) header of an array of `shape` in `dtype`, as NpyStreamWriter writes it.
std::string glossyNpyHeader(const std::vector<size_t>& shape, MatrixDtype dtype);
// The shape of a glossy .npy: [V, n_out², n_in²] or [V, 3, n_out², n_in²].
std::vector<size_t> glossyNpyShape(size_t vertices, int channels, int orderOut, int orderIn);
// Reads a glossy .npy (float32 or float16, 3-D or 4-D as above) as float32.
// Throws InputError for anything else; `expectedVertices` > 0 checks the count, and the
// decoded size is checked against the input memory limit.
struct GlossyMatrices {
  int orderOut = 0, orderIn = 0, channels = 1;
  size_t vertexCount = 0;
  MatrixDtype dtype = MatrixDtype::Float32;
  std::vector<float> values;
};
GlossyMatrices readGlossyNpy(const std::string& path, size_t expectedVertices = 0);
// A float32 glossy .npy mapped read-only instead of read (no copy, no fresh memory: the
// CPCA of a large bake reads it in place). The header is checked as readGlossyNpy does;
// info().values stays empty. A float16 file, or one whose data does not start at a
// multiple of 4 bytes, throws InputError (read it instead).
class GlossyNpyMap {
 public:
  explicit GlossyNpyMap(const std::string& path);
  ~GlossyNpyMap();
  GlossyNpyMap(const GlossyNpyMap&) = delete;
  GlossyNpyMap& operator=(const GlossyNpyMap&) = delete;
  const float* data() const { return data_; }
  const GlossyMatrices& info() const { return info_; }

 private:
  GlossyMatrices info_;
  void* base_ = nullptr;
  size_t length_ = 0;
  const float* data_ = nullptr;
};
// IEEE half conversion (round to nearest even), used for float16 output.
uint16_t floatToHalf(float f);
float halfToFloat(uint16_t h);

// The sidecar of a glossy bake (version, parameters, input SHA-256, conventions, layout,
// samples, error estimate, bounces, timings, device).
std::string glossySidecarBytes(const std::string& inputPath, const Mesh& mesh, const GlossyOptions& options,
                               const GlossyStats& stats, MatrixDtype dtype, const std::string& npyPath);
// CPCA output: one uncompressed NumPy .npz (numpy.load reads it) holding
//   means    float32 [K, (3,) n_out², n_in²]      μ_k
//   basis    float32 [K, P, (3,) n_out², n_in²]   b_kp, orthonormal per cluster
//   clusters int32   [V]                          k of each vertex
//   weights  float32 [V, P]                       w_vp = b_kp·(M_v − μ_k)
//   error    float32 [V]                          |M_v − M̃_v|_F / |M_v|_F
//   orders   int32   [3]                          n_out, n_in, channels
// and its description for a sidecar (K, P, errors, compression, the layout).
std::string cpcaNpzBytes(const CpcaResult& c, int orderOut, int orderIn, int channels);
std::string cpcaSidecarJson(const CpcaResult& c, const std::string& npzPath);  // a JSON object
// Reads a .npz written by cpcaNpzBytes (InputError otherwise).
CpcaResult readCpcaNpz(const std::string& path, int* orderOut, int* orderIn, int* channels);

// The glossy preview (renderGlossyPreview) is declared in preview.h.

}  // namespace prtbake
