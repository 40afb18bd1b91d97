// Atomic output files: temp file in the same directory, fsync, rename.
#include "prtbake/atomic_file.h"

#include <dirent.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>

#include "prtbake/error.h"
#include "prtbake/limits.h"

namespace prtbake {
namespace {

const char* kTempMarker = ".prtbake-tmp.";

std::string dirOf(const std::string& path) {
  const auto slash = path.find_last_of('/');
  if (slash == std::string::npos) return ".";
  if (slash == 0) return "/";
  return path.substr(0, slash);
}

std::string baseOf(const std::string& path) {
  const auto slash = path.find_last_of('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

std::atomic<int> gTempCounter{0};

}  // namespace

const char* version() { return PRTBAKE_VERSION; }

AtomicFile::AtomicFile(std::string path) : path_(std::move(path)) {
  if (path_.empty()) throw OutputError("output", "empty output path");
  // The finished file is renamed into place, which would put a file where a device such as
  // /dev/null, a named pipe or the link /dev/stdout was (and fail on a directory only then).
  struct stat st {};
  if (::stat(path_.c_str(), &st) == 0 && !S_ISREG(st.st_mode))
    throw OutputError(path_, S_ISDIR(st.st_mode) ? "is a directory, expected a file"
                                                 : "not a regular file (a device, pipe or socket): an output is written "
                                                   "whole, then renamed into place");
  // O_EXCL | O_NOFOLLOW: a file or link that someone placed at the predictable temp name is
  // never written through; the next name is tried instead.
  for (int attempt = 0; fd_ < 0; ++attempt) {
    tempPath_ = dirOf(path_) + "/." + baseOf(path_) + kTempMarker + std::to_string(getpid()) + "." +
                std::to_string(gTempCounter++);
    fd_ = ::open(tempPath_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644);
    if (fd_ < 0 && (errno != EEXIST || attempt == 100))
      throw OutputError(path_, std::string("cannot create output: ") + std::strerror(errno));
  }
}

std::string AtomicFile::writerPath() const {
  static const bool procFd = ::access("/proc/self/fd", X_OK) == 0;
  return procFd && fd_ >= 0 ? "/proc/self/fd/" + std::to_string(fd_) : tempPath_;
}

AtomicFile::~AtomicFile() {
  if (fd_ >= 0) ::close(fd_);
  if (!committed_) ::unlink(tempPath_.c_str());
}

void AtomicFile::write(const void* data, size_t bytes) {
  const char* p = static_cast<const char*>(data);
  while (bytes > 0) {
    const ssize_t n = ::write(fd_, p, bytes);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw OutputError(path_, std::string("write failed: ") + std::strerror(errno));
    }
    p += n;
    bytes -= size_t(n);
  }
}

void AtomicFile::commit() {
  if (committed_) return;
  if (::fsync(fd_) != 0) throw OutputError(path_, std::string("fsync failed: ") + std::strerror(errno));
  if (::close(fd_) != 0) {
    fd_ = -1;
    throw OutputError(path_, std::string("close failed: ") + std::strerror(errno));
  }
  fd_ = -1;
  if (::rename(tempPath_.c_str(), path_.c_str()) != 0)
    throw OutputError(path_, std::string("rename failed: ") + std::strerror(errno));
  committed_ = true;
  const int dfd = ::open(dirOf(path_).c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
}

void writeFileAtomic(const std::string& path, const std::string& text) {
  AtomicFile f(path);
  f.write(text);
  f.commit();
}

int removeStaleTempFiles(const std::string& dir) {
  DIR* d = ::opendir(dir.c_str());
  if (!d) return 0;
  int removed = 0;
  while (dirent* e = ::readdir(d)) {
    const std::string name = e->d_name;
    const auto at = name.find(kTempMarker);
    if (name.empty() || name[0] != '.' || at == std::string::npos) continue;
    const long pid = std::strtol(name.c_str() + at + std::strlen(kTempMarker), nullptr, 10);
    const bool alive = pid > 0 && (::kill(pid_t(pid), 0) == 0 || errno == EPERM);
    if (pid == getpid() || alive) continue;
    std::error_code ec;  // a directory: the staging copy of a package (writeIblPackage)
    if (std::filesystem::remove_all(dir + "/" + name, ec) > 0 && !ec) ++removed;
  }
  ::closedir(d);
  return removed;
}

size_t inputFileSize(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  if (S_ISDIR(st.st_mode)) throw InputError(path, "is a directory, expected a file");
  if (!S_ISREG(st.st_mode)) throw InputError(path, "not a regular file (a device, pipe or socket), expected a file");
  return size_t(st.st_size);
}

std::string readFilePrefix(const std::string& path, size_t most, size_t* fileSize) {
  const size_t size = inputFileSize(path);
  if (fileSize) *fileSize = size;
  std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  std::string b(std::min(most, size), '\0');
  b.resize(std::fread(b.data(), 1, b.size(), f.get()));
  if (std::ferror(f.get())) throw InputError(path, std::string("cannot read: ") + std::strerror(errno));
  return b;
}

std::string readFile(const std::string& path) {
  const size_t size = inputFileSize(path);
  checkInputMemory(path, "reading the file (" + std::to_string(size) + " bytes)", double(size));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot open for reading");
  // Read into one buffer of the file's size (a string stream would hold two or three copies).
  std::string bytes(size, '\0');
  in.read(bytes.data(), std::streamsize(bytes.size()));
  bytes.resize(size_t(in.gcount()));
  if (in.bad()) throw InputError(path, "cannot read");
  return bytes;
}

}  // namespace prtbake
