// Confinement of job files to roots (see confine.h).
#include "confine.h"

#include <dirent.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cstdlib>
#include <cstring>
#include <filesystem>

#include "prtbake/error.h"

namespace prtbake::jobs {
namespace fs = std::filesystem;

struct Confinement::Root {
  std::string given, real;  // absolute as named, and resolved
  int fd = -1;              // O_PATH descriptor of the directory
};

namespace {

std::vector<std::string> components(const std::string& rest) {
  std::vector<std::string> parts;
  size_t start = 0;
  while (start < rest.size()) {
    const size_t slash = rest.find('/', start);
    const size_t end = slash == std::string::npos ? rest.size() : slash;
    if (end > start) parts.push_back(rest.substr(start, end - start));
    start = end + 1;
  }
  return parts;
}

struct Walk {
  int fd = -1;          // the deepest directory reached (owned by the caller), or -1
  std::string why;      // set when a link or an error stopped the walk
  bool missing = false; // a directory on the way does not exist (and was not created)
};

// Opens `dirs` one below the other from `rootFd`, following no link; creates missing ones
// when `create`. `shown` is the root's name for messages.
Walk walkDirs(int rootFd, std::string shown, const std::vector<std::string>& dirs, bool create) {
  int fd = ::fcntl(rootFd, F_DUPFD_CLOEXEC, 0);
  if (fd < 0) {
    Walk w;
    w.why = shown + ": " + std::strerror(errno);
    return w;
  }
  for (const auto& c : dirs) {
    shown += "/" + c;
    int next = ::openat(fd, c.c_str(), O_PATH | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
    if (next < 0 && errno == ENOENT && create) {
      if (::mkdirat(fd, c.c_str(), 0777) != 0 && errno != EEXIST) {
        const std::string why = shown + ": cannot create the directory: " + std::strerror(errno);
        ::close(fd);
        return {-1, why};
      }
      next = ::openat(fd, c.c_str(), O_PATH | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
    }
    if (next < 0) {
      const int err = errno;
      struct stat st {};
      Walk w;
      if (::fstatat(fd, c.c_str(), &st, AT_SYMLINK_NOFOLLOW) == 0 && S_ISLNK(st.st_mode)) w.why = shown + " is a symbolic link";
      else if (err == ENOENT) w.missing = true;
      else w.why = shown + ": " + std::strerror(err);
      ::close(fd);
      return w;
    }
    ::close(fd);
    fd = next;
  }
  Walk w;
  w.fd = fd;
  return w;
}

// "" when every entry of the directory `name` in `parentFd` is a regular file or directory.
std::string checkEntries(int parentFd, const std::string& name, const std::string& shown) {
  const int fd = ::openat(parentFd, name.c_str(), O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
  if (fd < 0) return shown + ": " + std::strerror(errno);
  DIR* d = ::fdopendir(fd);
  if (!d) {
    ::close(fd);
    return shown + ": " + std::strerror(errno);
  }
  std::string why;
  while (const dirent* e = ::readdir(d)) {
    struct stat st {};
    if (!std::strcmp(e->d_name, ".") || !std::strcmp(e->d_name, "..")) continue;
    if (::fstatat(fd, e->d_name, &st, AT_SYMLINK_NOFOLLOW) == 0 && S_ISLNK(st.st_mode)) {
      why = shown + "/" + e->d_name + " is a symbolic link";
      break;
    }
  }
  ::closedir(d);
  return why;
}

}  // namespace

Confinement::Confinement(const std::vector<std::string>& inputRoots, const std::vector<std::string>& outputRoots) {
  auto open = [](const std::vector<std::string>& names, const char* what, std::vector<Root>& roots) {
    for (const auto& name : names) {
      char real[PATH_MAX];
      if (!::realpath(name.c_str(), real)) throw UsageError(what, name + ": " + std::strerror(errno));
      Root r;
      r.given = fs::absolute(name).lexically_normal().string();
      while (r.given.size() > 1 && r.given.back() == '/') r.given.pop_back();
      r.real = real;
      r.fd = ::open(real, O_PATH | O_DIRECTORY | O_CLOEXEC);
      if (r.fd < 0) throw UsageError(what, name + ": not a directory");
      roots.push_back(r);
    }
  };
  try {
    open(inputRoots, "--input-root", inputs_);
    open(outputRoots, "--output-root", outputs_);
  } catch (...) {
    for (const auto& r : inputs_) ::close(r.fd);
    for (const auto& r : outputs_) ::close(r.fd);
    throw;
  }
}

Confinement::~Confinement() {
  for (const auto& r : inputs_) ::close(r.fd);
  for (const auto& r : outputs_) ::close(r.fd);
}

std::string Confinement::rootList(const std::vector<Root>& roots) {
  std::string s;
  for (const auto& r : roots) s += (s.empty() ? "" : ", ") + r.real;
  return s;
}

const Confinement::Root* Confinement::rootOf(const std::vector<Root>& roots, const std::string& path,
                                              std::string* rest) const {
  const std::string p = fs::path(path).lexically_normal().string();
  const Root* best = nullptr;
  size_t bestLength = 0;
  for (const auto& r : roots)
    for (const std::string* prefix : {&r.given, &r.real}) {
      const std::string& pre = *prefix;
      const bool under = p == pre || (p.size() > pre.size() && p.compare(0, pre.size(), pre) == 0 &&
                                      (pre == "/" || p[pre.size()] == '/'));
      if (!under || pre.size() < bestLength) continue;
      best = &r;
      bestLength = pre.size();
      *rest = p.substr(std::min(p.size(), pre.size() + (pre == "/" ? 0 : 1)));
    }
  return best;
}

std::string Confinement::checkInput(const std::string& path) const {
  if (inputs_.empty()) return "";
  std::string rest;
  const Root* root = rootOf(inputs_, path, &rest);
  if (!root) return path + " is outside the input roots (" + rootList(inputs_) + ")";
  auto parts = components(rest);
  if (parts.empty()) return path + " is an input root itself, not a file in it";
  const std::string last = parts.back();
  parts.pop_back();
  const std::string links = " (no link is followed below the input root " + root->real + ")";
  const Walk w = walkDirs(root->fd, root->real, parts, false);
  if (w.missing) return path + ": file does not exist";
  if (w.fd < 0) return path + ": " + w.why + links;
  std::string why;
  struct stat st {};
  const std::string shown = fs::path(root->real) / rest;
  if (::fstatat(w.fd, last.c_str(), &st, AT_SYMLINK_NOFOLLOW) != 0) why = path + ": " + std::strerror(errno);
  else if (S_ISLNK(st.st_mode)) why = path + " is a symbolic link" + links;
  else if (S_ISDIR(st.st_mode)) {
    if (const std::string entry = checkEntries(w.fd, last, shown); !entry.empty()) why = path + ": " + entry + links;
  } else if (!S_ISREG(st.st_mode)) why = path + ": not a regular file";
  ::close(w.fd);
  return why;
}

std::string Confinement::checkOutput(const std::string& path) const {
  if (outputs_.empty()) return "";
  std::string rest;
  const Root* root = rootOf(outputs_, path, &rest);
  if (!root) return path + " is outside the output roots (" + rootList(outputs_) + ")";
  auto parts = components(rest);
  if (parts.empty()) return path + " is an output root itself";
  const std::string last = parts.back();
  parts.pop_back();
  const std::string links = " (no link is followed below the output root " + root->real + ")";
  const Walk w = walkDirs(root->fd, root->real, parts, false);
  if (w.missing) return "";  // created when the job runs
  if (w.fd < 0) return path + ": " + w.why + links;
  std::string why;
  struct stat st {};
  if (::fstatat(w.fd, last.c_str(), &st, AT_SYMLINK_NOFOLLOW) == 0 && S_ISLNK(st.st_mode))
    why = path + " is a symbolic link" + links;
  ::close(w.fd);
  return why;
}

Confinement::Dir::~Dir() { ::close(fd_); }

std::string Confinement::Dir::pinnedPath(const std::string& name) const {
  return "/proc/self/fd/" + std::to_string(fd_) + (name.empty() ? "" : "/" + name);
}

std::unique_ptr<Confinement::Dir> Confinement::Dir::makeSubdir(const std::string& name) const {
  int fd = -1;
  if (::mkdirat(fd_, name.c_str(), 0777) == 0)
    fd = ::openat(fd_, name.c_str(), O_PATH | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
  if (fd < 0) throw OutputError(pinnedPath(name), std::string("cannot create the directory: ") + std::strerror(errno));
  return std::make_unique<Dir>(fd);
}

std::unique_ptr<Confinement::Dir> Confinement::openOutputDir(const std::string& dir) const {
  std::string rest;
  const Root* root = rootOf(outputs_, dir, &rest);
  if (!root) throw OutputError(dir, "outside the output roots (" + rootList(outputs_) + ")");
  const Walk w = walkDirs(root->fd, root->real, components(rest), true);
  if (w.fd < 0)
    throw OutputError(dir, (w.why.empty() ? std::string("does not exist") : w.why) +
                               " (no link is followed below the output root " + root->real + ")");
  return std::make_unique<Dir>(w.fd);
}

std::vector<std::string> splitRootList(const std::string& list) {
  std::vector<std::string> roots;
  size_t start = 0;
  while (start <= list.size()) {
    const size_t colon = list.find(':', start);
    const size_t end = colon == std::string::npos ? list.size() : colon;
    if (end > start) roots.push_back(list.substr(start, end - start));
    start = end + 1;
  }
  return roots;
}

}  // namespace prtbake::jobs
