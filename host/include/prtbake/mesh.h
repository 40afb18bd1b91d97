// prtbake/mesh.h: triangle meshes for the transport product.
//
// A Mesh is an indexed triangle list in the input's world frame (docs/conventions.md,
// "World frame"): glTF node transforms are applied (normals by the inverse transpose), OBJ
// is taken as is. Per vertex: position, shading normal (unit, or zero where none
// could be defined), and linear albedo ρ (RGB; grey when r = g = b).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace prtbake {

struct Mesh {
  std::vector<float> positions;  // 3 per vertex, world frame
  std::vector<float> normals;    // 3 per vertex, unit (zero: no normal; transport is zero there)
  std::vector<float> albedo;     // 3 per vertex, linear RGB in [0, 1]
  std::vector<uint32_t> indices; // 3 per triangle, counter-clockwise front faces
  // Texture coordinate sets: uvs[k] holds 2 floats per vertex (glTF TEXCOORD_k; OBJ's vt is
  // set 0), in glTF's convention: (0, 0) is the image's top-left corner, v grows downwards
  // (OBJ's v, which grows upwards, is stored as 1 − v). A set that some triangles lack is
  // empty, and uvMissing[k] names the first primitive (or OBJ face) without it.
  std::vector<std::vector<float>> uvs;
  std::vector<std::string> uvMissing;
  // glTF TANGENT: 4 floats per vertex, xyz a unit vector in the world frame and w = ±1 the
  // bitangent's sign (bitangent = w · normal × tangent, glTF's definition; a mirroring node
  // transform flips w). Empty unless every triangle primitive has it; tangentMissing then names
  // the first primitive without it.
  std::vector<float> tangents;
  std::string tangentMissing;

  // Where each glTF primitive instance's vertices live in this mesh (for the glTF
  // export): vertices [firstVertex, firstVertex + vertexCount) are the primitive's
  // accessor vertices 0..vertexCount-1 under node `node`.
  struct GltfPrimitive {
    int node = -1, mesh = -1, primitive = -1;
    uint32_t firstVertex = 0, vertexCount = 0;
  };
  std::vector<GltfPrimitive> gltfPrimitives;
  std::string sourcePath;  // the file it was loaded from ("" for procedural meshes)
  std::vector<std::string> inputFiles;  // every file read: the mesh and its external buffers/images
  std::string sourceSha256;  // SHA-256 (hex) of sourcePath's bytes as parsed, where the loader took it ("" if not)
  enum class Format { None, Gltf, Obj } format = Format::None;

  size_t vertexCount() const { return positions.size() / 3; }
  size_t triangleCount() const { return indices.size() / 3; }
  bool hasUvSet(int k) const { return k >= 0 && size_t(k) < uvs.size() && !uvs[size_t(k)].empty(); }
  // True when every vertex has r = g = b (the transport stays scalar).
  bool greyAlbedo() const;
  // SHA-256 (hex) of the file `path`: the loader's hash when `path` is the source it parsed
  // and hashed, else the file read now.
  std::string inputSha256(const std::string& path) const;
};

// Where a mesh's albedo comes from: a glTF's baseColorFactor × COLOR_0 (an OBJ's 1), or also its
// materials' colour textures (glTF's base colour texture; an OBJ's .mtl Kd and map_Kd) around each
// vertex, read only for the bakes that use the albedo (interreflection, bounces, previews).
enum class MeshAlbedo { Factors, Textures };

// Loads a .gltf/.glb (tinygltf) or .obj (tinyobjloader) by its extension, fills
// missing normals and validates. Throws InputError(path, what) for missing,
// malformed, empty or non-finite input.
Mesh loadMesh(const std::string& path, MeshAlbedo albedo = MeshAlbedo::Factors);

// glTF 2.0: every triangle primitive (triangles, strips, fans; indexed or not) of the
// default scene (or of every root node when there is no scene), node transforms
// applied; NORMAL, else area- and angle-weighted normals; albedo = baseColorFactor ×
// COLOR_0 (RGB), and with MeshAlbedo::Textures times the base colour texture's mean over the
// triangles around the vertex (weighted by their areas; each triangle's mean from bilinear
// samples, about one a texel of its footprint and at most 64², with the sampler's wrap modes and
// KHR_texture_transform; sRGB decoded). Such a texture must be PNG or JPEG. Points and lines are
// ignored.
Mesh loadGltf(const std::string& path, MeshAlbedo albedo = MeshAlbedo::Factors);
// The files that the .gltf or .glb (by its extension, any case) at `path` names by URI: its
// buffers' and images' URIs (data: URIs left out), decoded as the loader decodes them ('+' and
// %XX). Resolving one against the file's directory is the caller's. Empty for another
// extension, or when the file cannot be read or parsed (loadMesh reports that).
std::vector<std::string> gltfExternalUris(const std::string& path);
// OBJ: polygons triangulated; one mesh vertex per distinct (v, vt, vn) triple, as the
// GAMES202 framework's loader does; albedo 1, and with MeshAlbedo::Textures the area-weighted
// mean over the faces around the vertex of their material's Kd (1 where it gives none, clamped to
// [0, 1]; linear) times its map_Kd's mean over the face (as glTF's textures, with -s, -o and
// -clamp). The .mtl files are read only then; one that cannot be read is an InputError naming it.
Mesh loadObj(const std::string& path, MeshAlbedo albedo = MeshAlbedo::Factors);

// Replaces zero-length or absent normals with the area- and angle-weighted mean of
// the normals of the triangles that use the vertex. Vertices used only by
// zero-area triangles keep a zero normal.
void fillMissingNormals(Mesh& mesh);

// Throws InputError(subject, ...) for an empty mesh (no triangles), out-of-range
// indices, non-finite positions/normals/albedo, or size mismatches.
void validateMesh(const Mesh& mesh, const std::string& subject);

// Axis-aligned bounds of the positions used by triangles: min[3], max[3].
void meshBounds(const Mesh& mesh, double bmin[3], double bmax[3]);

// --- procedural meshes for tests and benchmarks (unit albedo, outward normals) ---

// A UV sphere of radius r: `rings` latitude bands × `segments` longitudes, poles
// included, radial normals, shared vertices (closed and convex).
Mesh makeUvSphere(double radius, int rings, int segments);
// An axis-aligned square [−h, h]² in the plane z = height, normal ±z (down = true: −z),
// split into n × n quads; UV set 0 maps it onto [0, 1]² (u along x, v along −y).
Mesh makeSquare(double halfSize, double height, int n, bool facingDown);
// A sphere of radius r whose cap around +z (polar angle < openingRad) is cut away;
// normals point inwards (the cavity's interior is its front side).
Mesh makeOpenSphereCavity(double radius, double openingRad, int rings, int segments);
// A bumpy, self-occluding closed shape with about `targetTriangles` triangles (a sphere
// displaced by a sum of sinusoids), for benchmarks.
Mesh makeBumpySphere(int targetTriangles);
// A (p, q) torus knot tube of `segments` rings of `sides` vertices each (2 · segments ·
// sides triangles, outward normals): a large, self-occluding mesh for benchmarks (800 × 128:
// 102,400 vertices, 204,800 triangles).
Mesh makeTorusKnot(int segments, int sides, int p = 2, int q = 3);
// Appends `b` to `a` (indices offset); a UV set survives where both have it.
void appendMesh(Mesh& a, const Mesh& b);
// Scales positions by s about the origin (normals unchanged).
void scaleMesh(Mesh& mesh, double s);

}  // namespace prtbake
