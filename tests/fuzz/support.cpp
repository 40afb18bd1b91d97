// Scratch files and input splitting for the fuzz targets (fuzz_target.h).
#include <sys/stat.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>

#include "fuzz_target.h"
#include "prtbake/limits.h"

namespace prtbake::fuzz {
namespace {

// Decoded inputs are capped at a quarter of libFuzzer's -malloc_limit_mb (512, scripts/fuzz.sh),
// so that a block the cap did not account for is a finding, not an out-of-memory report
// about a legitimately large input. Below the cap, what a file may decode to is bounded by
// its size (image_check.h, exr_check.cpp): a mutated header that claims a large image over
// a few bytes is refused from its size. (The cap was 32 MiB while that was the only bound:
// headers claiming up to the cap cost a zero-filled block of that size on every such run.)
constexpr size_t kFuzzInputLimitBytes = size_t(128) << 20;

struct Scratch {
  std::string dir;
  Scratch() {
    setInputMemoryLimit(kFuzzInputLimitBytes);
    struct stat st {};
    const char* tmp = std::getenv("TMPDIR");
    const std::string base = ::stat("/dev/shm", &st) == 0 && S_ISDIR(st.st_mode) ? "/dev/shm" : (tmp && *tmp ? tmp : "/tmp");
    dir = base + "/prtbake-fuzz-" + std::to_string(::getpid());
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
  }
  ~Scratch() {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
};

Scratch& scratch() {
  static Scratch s;
  return s;
}

}  // namespace

const std::string& scratchDir() { return scratch().dir; }

void clearScratch() {
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(scratchDir(), ec)) std::filesystem::remove_all(e.path(), ec);
}

std::string writeScratch(const std::string& name, const std::string& bytes) {
  const std::string path = scratchDir() + "/" + name;
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
  return path;
}

std::vector<std::string> splitParts(const uint8_t* data, size_t size, size_t count) {
  std::vector<std::string> parts;
  size_t pos = 0;
  for (size_t i = 0; i + 1 < count; ++i) {
    uint32_t len = 0;
    for (int k = 0; k < 4; ++k) len |= pos + k < size ? uint32_t(data[pos + k]) << (8 * k) : 0;
    pos = std::min(size, pos + 4);
    const size_t n = std::min<size_t>(len, size - pos);
    parts.emplace_back(reinterpret_cast<const char*>(data) + pos, n);
    pos += n;
  }
  parts.emplace_back(reinterpret_cast<const char*>(data) + pos, size - pos);
  return parts;
}

#ifdef PRTBAKE_FUZZ_REPLAY
std::vector<Target>& targets() {
  static std::vector<Target> t;
  return t;
}
Registrar::Registrar(const char* name, TargetFn fn) { targets().push_back({name, fn}); }
#endif

}  // namespace prtbake::fuzz
