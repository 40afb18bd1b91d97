// loadEnvironment: from files on disk to an EnvMap in the conventions of docs/conventions.md.
//
// Layouts (the face orientations are docs/conventions.md "Cube faces" unless said otherwise):
//   directory   six faces posx/negx/posy/negy/posz/negz.{exr,hdr,png,jpg}
//   games202    the same directory, read the way the GAMES202 homework-2 framework
//               reads it (its face order, its direction table, (c/255)^2.2)
//   OpenEXR with the envmap attribute: lat-long as is; cube (N×6N) re-indexed
//               texel by texel through ImfEnvmap.h's CubeMap functions
//   2:1         lat-long (EnvMap's convention = OpenEXR LatLongMap axes)
//   4:3         horizontal cross:      [+Y]             3:4 vertical cross:   [+Y]
//                                 [−X] [+Z] [+X] [−Z]                    [−X] [+Z] [+X]
//                                      [−Y]                                   [−Y]
//                                                                             [−Z] (rotated 180°)
//   1:6, 6:1    strips of the six faces in the order +X, −X, +Y, −Y, +Z, −Z
#include <malloc.h>
#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <exception>
#include <filesystem>
#include <mutex>

#include "core/env_validate.h"
#include "core/parallel.h"
#include "io/exr_cube.h"
#include "io/image_read.h"
#include "prtbake/envmap.h"
#include "prtbake/error.h"

namespace prtbake {
namespace {

using detail::Image;
using detail::LdrDecode;

// The face order of docs/conventions.md "Cube faces" and the file names that hold them.
const std::array<const char*, 6> kFaceNames = {"posx", "negx", "posy", "negy", "posz", "negz"};
const std::array<const char*, 4> kFaceExtensions = {".exr", ".hdr", ".png", ".jpg"};

std::string sizeText(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

// An image's storage, as EnvMap's (envmap.h).
EnvStorage storageOf(const Image& img) {
  return img.codes ? EnvStorage::Code8 : !img.halfRgb.empty() ? EnvStorage::Half : EnvStorage::Float;
}

// Copies `count` texels from position src of img to position dst of env, both in the
// same storage.
void copyTexels(const Image& img, size_t src, EnvMap& env, size_t dst, size_t count) {
  switch (env.storage()) {
    case EnvStorage::Code8: std::copy_n(img.codes.get() + 3 * src, 3 * count, &env.codes[3 * dst]); break;
    case EnvStorage::Half: std::copy_n(&img.halfRgb[3 * src], 3 * count, &env.halfRgb[3 * dst]); break;
    case EnvStorage::Float: std::copy_n(&img.rgb[3 * src], 3 * count, &env.rgb[3 * dst]); break;
  }
}

// Copies the n×n block of `img` whose top-left pixel is (x0, y0) into cube face
// `face` of env (row 0 at the top). rotate180 turns the block upside down
// (row r, column c of the face comes from block row n−1−r, column n−1−c).
void copyFace(const Image& img, int x0, int y0, int n, bool rotate180, EnvMap& env, int face) {
  for (int r = 0; r < n; ++r) {
    const size_t dstRow = (size_t(face) * size_t(n) + size_t(r)) * size_t(n);
    if (!rotate180) {
      copyTexels(img, size_t(y0 + r) * size_t(img.width) + size_t(x0), env, dstRow, size_t(n));
      continue;
    }
    for (int c = 0; c < n; ++c)
      copyTexels(img, size_t(y0 + n - 1 - r) * size_t(img.width) + size_t(x0 + n - 1 - c), env, dstRow + size_t(c), 1);
  }
}

// An n×n cube in the storage of `like` (its 8-bit table too), texels unset.
EnvMap emptyCube(int n, const std::string& path, const std::string& layoutName, const Image& like) {
  EnvMap env;
  env.layout = EnvLayout::Cube;
  env.width = env.height = n;
  const size_t values = 6 * size_t(n) * size_t(n) * 3;
  switch (storageOf(like)) {
    case EnvStorage::Code8: env.codes.resize(values), env.codeToLinear = like.codeToLinear; break;
    case EnvStorage::Half: env.halfRgb.resize(values); break;
    case EnvStorage::Float: env.rgb.resize(values); break;
  }
  env.source = path;
  env.inputFiles = {path};
  env.layoutName = layoutName;
  return env;
}

EnvMap fromLatLong(Image&& img, const std::string& path) {
  if (img.width != 2 * img.height)
    throw InputError(path, "a lat-long map must be twice as wide as high (got " + sizeText(img.width, img.height) + ")");
  EnvMap env;
  env.layout = EnvLayout::LatLong;
  env.width = img.width, env.height = img.height;
  env.rgb = std::move(img.rgb);
  env.halfRgb = std::move(img.halfRgb);
  if (img.codes) env.codes.assign(img.codes.get(), img.codes.get() + 3 * env.texelCount());
  env.codeToLinear = img.codeToLinear;
  env.source = path;
  env.inputFiles = {path};
  env.layoutName = "latlong";
  return env;
}

// Cell (column, row) of each face, in face-size units, and whether it is rotated 180°.
struct CrossCell {
  int col, row;
  bool rotate180;
};

EnvMap fromCross(const Image& img, const std::string& path) {
  const bool horizontal = 3 * img.width == 4 * img.height;
  const bool vertical = 4 * img.width == 3 * img.height;
  if (!horizontal && !vertical)
    throw InputError(path, "a cross must be 4:3 (horizontal) or 3:4 (vertical), got " + sizeText(img.width, img.height));
  const int n = horizontal ? img.width / 4 : img.width / 3;
  // +X, −X, +Y, −Y, +Z, −Z. In both crosses +Z is the centre of the middle row with
  // −X to its left, +X to its right, +Y above and −Y below, all unrotated, so each
  // shared edge carries the same directions on both sides (tests/test_env_load.cpp
  // checks every seam). −Z sits right of +X (horizontal: +X's right edge u = 1 is
  // (1, −v, −1), −Z's left edge u = −1 is (1, −v, −1)), or below −Y turned 180°
  // (vertical: −Y's bottom edge v = 1 is (u, −1, −1); −Z's bottom row v = 1, seen
  // upside down, has u' = −u: (−u', −1, −1) = (u, −1, −1)).
  const std::array<CrossCell, 6> cells =
      horizontal ? std::array<CrossCell, 6>{{{2, 1, false}, {0, 1, false}, {1, 0, false},
                                             {1, 2, false}, {1, 1, false}, {3, 1, false}}}
                 : std::array<CrossCell, 6>{{{2, 1, false}, {0, 1, false}, {1, 0, false},
                                             {1, 2, false}, {1, 1, false}, {1, 3, true}}};
  EnvMap env = emptyCube(n, path, horizontal ? "cross" : "vertical-cross", img);
  for (int f = 0; f < 6; ++f) copyFace(img, cells[f].col * n, cells[f].row * n, n, cells[f].rotate180, env, f);
  return env;
}

EnvMap fromStrip(const Image& img, const std::string& path) {
  const bool vertical = img.height == 6 * img.width;
  const int n = vertical ? img.width : img.height;
  EnvMap env = emptyCube(n, path, "strip", img);
  for (int f = 0; f < 6; ++f) copyFace(img, vertical ? 0 : f * n, vertical ? f * n : 0, n, false, env, f);
  return env;
}

// OpenEXR cube (ENVMAP_CUBE): six N×N faces stacked vertically in a N×6N data window,
// each oriented as ImfEnvmap.h defines (exr_cube.h asks the library where each texel is).
EnvMap fromOpenExrCube(const Image& img, const std::string& path) {
  if (img.height != 6 * img.width)
    throw InputError(path, "an OpenEXR cube map must be N wide and 6N high (got " + sizeText(img.width, img.height) + ")");
  const int n = img.width;
  EnvMap env = emptyCube(n, path, "openexr-cube", img);
  const std::vector<size_t> pixel = detail::openExrCubePixels(n, env.faces, path);
  for (size_t t = 0; t < pixel.size(); ++t) copyTexels(img, pixel[t], env, t, 1);
  return env;
}

// One single image, layout from the envmap attribute, the forced layout, or the shape.
EnvMap fromImage(Image&& img, const std::string& path, const std::string& layout) {
  const int w = img.width, h = img.height;
  if (img.envmap == 1) {
    if (layout != "auto")
      throw InputError(path, "the OpenEXR envmap attribute says cube; layout '" + layout + "' does not apply");
    return fromOpenExrCube(img, path);
  }
  if (img.envmap == 0) {
    if (layout != "auto" && layout != "latlong")
      throw InputError(path, "the OpenEXR envmap attribute says lat-long; layout '" + layout + "' does not apply");
    return fromLatLong(std::move(img), path);
  }
  if (layout == "latlong") return fromLatLong(std::move(img), path);
  if (layout == "cross") return fromCross(img, path);
  // auto
  if (w == 2 * h) return fromLatLong(std::move(img), path);
  if (3 * w == 4 * h || 4 * w == 3 * h) return fromCross(img, path);
  if (h == 6 * w || w == 6 * h) return fromStrip(img, path);
  throw InputError(path, "cannot tell the layout of a " + sizeText(w, h) +
                             " image; expected 2:1 lat-long, 4:3 or 3:4 cross, 6:1 or 1:6 strip");
}

// The six face files of `dir`, in the order of `names`; names each missing face.
std::vector<std::string> findFaceFiles(const std::string& dir, const std::array<const char*, 6>& names,
                                       const std::vector<const char*>& extensions) {
  namespace fs = std::filesystem;
  std::vector<std::string> files, missing;
  for (const char* name : names) {
    std::vector<std::string> found;
    for (const char* ext : extensions) {
      const fs::path p = fs::path(dir) / (std::string(name) + ext);
      std::error_code ec;
      if (fs::is_regular_file(p, ec)) found.push_back(p.string());
    }
    if (found.size() > 1)
      throw InputError(dir, "face " + std::string(name) + " is ambiguous: " + found[0] + " and " + found[1]);
    if (found.empty()) missing.push_back(name);
    else files.push_back(found[0]);
  }
  if (!missing.empty()) {
    std::string list, exts;
    for (const auto& m : missing) list += (list.empty() ? "" : ", ") + m;
    for (const char* e : extensions) exts += std::string(exts.empty() ? "" : " ") + e;
    throw InputError(dir, "missing cube face" + std::string(missing.size() > 1 ? "s " : " ") + list +
                              " (expected posx, negx, posy, negy, posz, negz with one of " + exts + ")");
  }
  return files;
}

// Reads six face files into the cube faces 0..5 in the order given. The files are
// decoded in parallel (JPEG/PNG/EXR decoding dominates loading), and each face is
// copied into the cube as soon as it is decoded, so at most one decoded image per
// thread is alive beside the cube. Errors are reported in face order, whichever
// thread met them first.
EnvMap fromFaceFiles(const std::string& dir, const std::vector<std::string>& files, LdrDecode decode,
                     const std::string& layoutName, bool compact) {
  EnvMap env;
  env.layout = EnvLayout::Cube;
  struct Face {
    int width = 0, height = 0;
    EnvStorage storage = EnvStorage::Float;
    bool placed = false;
    std::exception_ptr error;
  };
  std::array<Face, 6> faces;
  std::mutex mutex;  // guards the cube's allocation
  bool allocated = false;
  // The six faces decode at once, one thread each.
  detail::parallelEach(6, 6, [&](size_t f) {
    Face& face = faces[f];
    try {
      const Image img = detail::readImage(files[f], decode, compact);
      face.width = img.width, face.height = img.height, face.storage = storageOf(img);
      if (img.width != img.height) return;  // reported below, in face order
      {
        std::lock_guard<std::mutex> lock(mutex);
        if (!allocated) env = emptyCube(img.width, dir, layoutName, img), allocated = true;
      }
      if (img.width == env.width && face.storage == env.storage()) {
        copyFace(img, 0, 0, img.width, false, env, int(f));
        face.placed = true;
      }
    } catch (...) {
      face.error = std::current_exception();
    }
  });
  for (const Face& face : faces)
    if (face.error) std::rethrow_exception(face.error);
  for (size_t f = 0; f < 6; ++f) {
    const Face& face = faces[f];
    if (face.width != face.height)
      throw InputError(files[f], "a cube face must be square (got " + sizeText(face.width, face.height) + ")");
    if (face.width != faces[0].width)
      throw InputError(files[f], "face is " + sizeText(face.width, face.height) + " but " + files[0] + " is " +
                                     sizeText(faces[0].width, faces[0].width) + "; all six faces must have the same size");
  }
  for (const Face& face : faces)
    if (!face.placed) {
      // Faces of different storages (a PNG beside an OpenEXR face): all as floats.
      PRTBAKE_CHECK(compact, "a face of the cube was not placed");
      return fromFaceFiles(dir, files, decode, layoutName, false);
    }
  env.inputFiles = files;
#ifdef __GLIBC__
  malloc_trim(0);  // the decoders' freed buffers: 20 MB of a 6 × 2048² JPEG cube stay resident otherwise
#endif
  return env;
}

// The GAMES202 homework-2 framework (github magicianA/GAMES202,
// homework2/prt/src/prt.cpp, namespace ProjEnv) loads the faces in the order
// negx, posx, posy, negy, posz, negz with stbi_loadf (8-bit → (c/255)^2.2, rows
// top first), and gives the pixel at column x, row y of face i the direction
// normalize(X·u + Y·v + Z), u = 2(x + 0.5)/width − 1, v = 2(y + 0.5)/height − 1,
// with (X, Y, Z) from its table cubemapFaceDirections[i] (below, the same rows).
// Its table's comments call rows 2 and 3 "negy" and "posy" while its load order
// puts posy.jpg at 2 and negy.jpg at 3; like the framework, we pair the file of
// load index i with row i, so posy.jpg's texels get −Y-facing directions. That is
// what its light.txt encodes, and what the preset must reproduce.
const std::array<const char*, 6> kGames202LoadOrder = {"negx", "posx", "posy", "negy", "posz", "negz"};
const std::array<CubeFaceBasis, 6> kGames202Bases = {{
    {{0, 0, 1}, {0, -1, 0}, {-1, 0, 0}},
    {{0, 0, 1}, {0, -1, 0}, {1, 0, 0}},
    {{1, 0, 0}, {0, 0, -1}, {0, -1, 0}},
    {{1, 0, 0}, {0, 0, 1}, {0, 1, 0}},
    {{-1, 0, 0}, {0, -1, 0}, {0, 0, -1}},
    {{1, 0, 0}, {0, -1, 0}, {0, 0, 1}},
}};

EnvMap loadDirectory(const std::string& dir, const std::string& layout, bool compact) {
  const std::vector<const char*> allExts(kFaceExtensions.begin(), kFaceExtensions.end());
  if (layout == "games202") {
    EnvMap env = fromFaceFiles(dir, findFaceFiles(dir, kGames202LoadOrder, allExts), LdrDecode::Gamma22, "games202", compact);
    env.faces = kGames202Bases;
    return env;
  }
  if (layout != "auto" && layout != "faces")
    throw InputError(dir, "is a directory; layout '" + layout + "' needs a single image");
  return fromFaceFiles(dir, findFaceFiles(dir, kFaceNames, allExts), LdrDecode::Srgb, "faces", compact);
}

}  // namespace

EnvMap loadEnvironment(const std::string& path, const EnvLoadOptions& options) {
  const std::string& layout = options.layout;
  if (layout != "auto" && layout != "faces" && layout != "cross" && layout != "latlong" && layout != "games202")
    throw UsageError("layout", "unknown layout '" + layout + "' (expected auto, faces, cross, latlong or games202)");
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  EnvMap env;
  if (S_ISDIR(st.st_mode)) {
    env = loadDirectory(path, layout, options.compact);
  } else {
    if (layout == "faces" || layout == "games202")
      throw InputError(path, "layout '" + layout + "' needs a directory of six face images");
    env = fromImage(detail::readImage(path, LdrDecode::Srgb, options.compact), path, layout);
  }
  validateEnvironment(env, options.clampInvalid);
  return env;
}

bool forEachLatLongBand(const std::string& path, const EnvLoadOptions& options, size_t bandBytes,
                        const std::function<void(EnvMap& band, int firstRow)>& band, EnvMap* header) {
  if (options.layout != "auto" && options.layout != "latlong") return false;
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode) || !detail::isOpenExr(path)) return false;
  // The library decodes up to 256 lines at a time (DWAB chunks); bands are checked as read.
  detail::ExrRowReader reader(path, options.compact, 256);
  const int w = reader.width(), h = reader.height();
  const bool latlong = reader.envmap() == 0 || (reader.envmap() == -1 && (options.layout == "latlong" || w == 2 * h));
  if (!reader.rowsReadable() || !latlong || w != 2 * h) return false;
  *header = EnvMap{};
  header->layout = EnvLayout::LatLong;
  header->width = w, header->height = h;
  header->source = path;
  header->inputFiles = {path};
  header->layoutName = "latlong";
  // Whole chunks of 32 lines (every compression's but DWAB's) where the band allows.
  int rows = int(std::clamp<size_t>(bandBytes / (12 * size_t(w)), 1, size_t(h)));
  if (rows > 32) rows -= rows % 32;
  detail::InvalidTexels bad;
  for (int y0 = 0; y0 < h; y0 += rows) {
    const int y1 = std::min(h, y0 + rows);
    Image img;
    reader.read(y0, y1, img);
    EnvMap texels;
    texels.layout = EnvLayout::LatLong;
    texels.width = w, texels.height = y1 - y0;
    texels.rgb = std::move(img.rgb);
    texels.halfRgb = std::move(img.halfRgb);
    texels.source = path;
    // Clamped whatever the option, so that bands after an invalid one stay projectable.
    const detail::InvalidTexels b = detail::countInvalidTexels(texels, true);
    bad.values += b.values, bad.nonFinite += b.nonFinite;
    if (bad.values == 0 || options.clampInvalid) band(texels, y0);
  }
  if (bad.values > 0 && !options.clampInvalid) throw detail::invalidTexelsError(path, bad);
  header->clampedTexels = bad.values;
  return true;
}

}  // namespace prtbake
