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

// Decoded inputs are capped far below libFuzzer's -rss_limit_mb (2048), so that an
// input which makes prtbake allocate past its own cap is a finding, not an
// out-of-memory report about a legitimately large input; and low, because a mutated
// header that claims the most the cap allows costs a zero-filled allocation of that
// size on every such run (at 256 MiB those runs took 0.4 s each).
constexpr size_t kFuzzInputLimitBytes = size_t(32) << 20;

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
