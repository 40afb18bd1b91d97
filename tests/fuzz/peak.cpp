// fuzz_peak: the heap each fuzz target needs for each of its seeds and regression inputs,
// against the input's size (tests/fuzz/README.md, "Memory against file size").
//
//   fuzz_peak            the table: per target and format, the largest ratio of peak heap
//                        bytes to input bytes, and the bound that holds for it
//   fuzz_peak --check    the same, exit 1 when an input's peak exceeds its bound
//
// The process's malloc family is replaced by counting wrappers around glibc's own
// (__libc_malloc, ...), so every block counts: C++'s operator new, stb_image's, OpenEXR's,
// RawVector's aligned blocks. Peak heap bytes, not resident pages: a block that is
// allocated and never touched counts whole, as libFuzzer's -malloc_limit_mb sees it.
#include <malloc.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <vector>

#include "fuzz_target.h"

extern "C" {
void* __libc_malloc(size_t);
void* __libc_calloc(size_t, size_t);
void* __libc_realloc(void*, size_t);
void* __libc_memalign(size_t, size_t);
void __libc_free(void*);
}

namespace {
std::atomic<long long> live{0}, peak{0};

void* counted(void* p) {
  if (p) {
    const long long now = live += (long long)malloc_usable_size(p);
    long long seen = peak.load();
    while (now > seen && !peak.compare_exchange_weak(seen, now)) {
    }
  }
  return p;
}
void uncount(void* p) {
  if (p) live -= (long long)malloc_usable_size(p);
}
}  // namespace

extern "C" {
void* malloc(size_t n) { return counted(__libc_malloc(n)); }
void* calloc(size_t n, size_t s) { return counted(__libc_calloc(n, s)); }
void* realloc(void* p, size_t n) {
  uncount(p);
  return counted(__libc_realloc(p, n));
}
void free(void* p) {
  uncount(p);
  __libc_free(p);
}
void* memalign(size_t a, size_t n) { return counted(__libc_memalign(a, n)); }
void* aligned_alloc(size_t a, size_t n) { return counted(__libc_memalign(a, n)); }
int posix_memalign(void** out, size_t a, size_t n) {
  void* p = counted(__libc_memalign(a, n));
  if (!p) return ENOMEM;
  *out = p;
  return 0;
}
}

namespace fs = std::filesystem;

namespace {

// What an input is, for the table: the file's format where a target reads several.
std::string formatOf(const std::string& target, const std::string& bytes) {
  if (target != "env_image" && target != "lut_exr") return "";
  const std::string file = target == "env_image" ? bytes.substr(std::min<size_t>(1, bytes.size())) : bytes;
  if (file.compare(0, 4, "\x76\x2f\x31\x01") == 0) return "OpenEXR";
  if (file.compare(0, 2, "#?") == 0) return "Radiance";
  if (file.compare(0, 4, "\x89PNG") == 0) return "PNG";
  if (file.compare(0, 2, "\xff\xd8") == 0) return "JPEG";
  return "other";
}

// The bound that holds: peak heap bytes at most kFixed + ratio x input bytes. The ratios
// follow from what a file's bytes can decode to (image_check.h, exr_check.cpp) times the
// bytes a pixel takes at the decode's peak (image_read.cpp), and for the other parsers
// from what a byte of text or data becomes; tests/fuzz/README.md derives each.
constexpr double kFixed = 8.0 * (1 << 20);
double boundRatio(const std::string& target, const std::string& format) {
  static const std::map<std::string, double> kRatio = {
      {"env_image/Radiance", 381},  {"env_image/PNG", 173376}, {"env_image/JPEG", 10752},
      {"env_image/OpenEXR", 786432}, {"env_image/other", 0},   {"lut_exr/OpenEXR", 786432},
      {"lut_exr/other", 0},          {"env_faces", 786432},    {"gltf", 64},
      {"obj", 64},                   {"jobfile", 64},          {"sh_json", 64},
      {"npy", 64},                   {"glossy", 64},           {"lightmap", 64}};
  const auto it = kRatio.find(format.empty() ? target : target + "/" + format);
  return it == kRatio.end() ? -1 : it->second;
}

std::vector<std::string> filesIn(const std::string& dir) {
  std::vector<std::string> out;
  if (fs::is_directory(dir))
    for (const auto& e : fs::directory_iterator(dir))
      if (e.is_regular_file()) out.push_back(e.path().string());
  std::sort(out.begin(), out.end());
  return out;
}

// Small inputs' peaks are the parser's fixed costs (path strings, a file's buffer, tables):
// the ratio is taken over inputs of at least this size.
constexpr size_t kRatioFrom = 1024;

struct Row {
  int inputs = 0;
  double ratio = 0, ratioSize = 0, peakBytes = 0, peakSize = 0;
  std::string ratioInput, peakInput;
  bool over = false;
};

}  // namespace

int main(int argc, char** argv) {
  const bool check = argc > 1 && std::strcmp(argv[1], "--check") == 0;
  const std::string root = std::string(PRTBAKE_TEST_SOURCE_DIR) + "/fuzz";
  std::map<std::string, Row> rows;
  bool failed = false;
  for (const auto& t : prtbake::fuzz::targets())
    for (const char* kind : {"corpus", "regressions"})
      for (const std::string& f : filesIn(root + "/" + std::string(kind) + "/" + t.name)) {
        std::ifstream in(f, std::ios::binary);
        const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        const std::string format = formatOf(t.name, bytes);
        const long long before = live.load();
        peak = before;
        t.fn(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size());
        const double used = double(peak.load() - before), ratio = used / double(std::max<size_t>(bytes.size(), 1));
        Row& r = rows[format.empty() ? t.name : t.name + std::string("/") + format];
        ++r.inputs;
        const double bound = boundRatio(t.name, format);
        if (bound < 0 || used > kFixed + bound * double(bytes.size())) {
          std::fprintf(stderr, "fuzz_peak: %s: %.0f bytes of heap for %zu bytes of input, over the bound (%.0f + %.0f x size)\n",
                       f.c_str(), used, bytes.size(), kFixed, bound);
          r.over = failed = true;
        }
        const std::string name = fs::path(f).filename();
        if (used > r.peakBytes) r.peakBytes = used, r.peakSize = double(bytes.size()), r.peakInput = name;
        if (bytes.size() >= kRatioFrom && ratio > r.ratio) r.ratio = ratio, r.ratioSize = double(bytes.size()), r.ratioInput = name;
      }
  std::printf("| target / format | inputs | largest peak heap: input (bytes), KiB | largest peak / size, inputs of 1 KiB or more: input (bytes) | bound: 8 MiB + size x |\n");
  std::printf("|---|---|---|---|---|\n");
  for (const auto& [name, r] : rows) {
    const size_t slash = name.find('/');
    const double bound = boundRatio(name.substr(0, slash), slash == std::string::npos ? "" : name.substr(slash + 1));
    const std::string ratio = r.ratioInput.empty() ? std::string("(none)")
                                                   : std::to_string(int(r.ratio + 0.5)) + ": " + r.ratioInput + " (" +
                                                         std::to_string((long long)r.ratioSize) + ")";
    std::printf("| %s | %d | %s (%.0f), %.0f | %s | %.0f%s |\n", name.c_str(), r.inputs, r.peakInput.c_str(), r.peakSize,
                r.peakBytes / 1024, ratio.c_str(), bound, r.over ? " (EXCEEDED)" : "");
  }
  return check && failed ? 1 : 0;
}
