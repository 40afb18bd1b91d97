// Confinement of job files to roots (docs/jobs.md, "A shared queue"): where a job may read
// and where it may write, for job files that someone else wrote.
//
// A path is allowed when, after lexical normalisation (so `..` cannot climb out), it lies
// under one of the roots and no component below the root is a symbolic link: the walk opens
// each directory from the root's descriptor with O_NOFOLLOW instead of trusting the name.
// Outputs go further: the runner opens each output directory that way once (creating missing
// ones with mkdirat) and writes, renames and removes only through that descriptor
// (pinnedPath: /proc/self/fd/N/name), so a link swapped into the path after the check
// changes nothing, and a link at the last component is replaced by the rename, never
// followed.
#pragma once

#include <memory>
#include <string>
#include <vector>

namespace prtbake::jobs {

class Confinement {
 public:
  // Each root must be an existing directory (UsageError otherwise, naming `what`); it is
  // resolved and opened here, so links above a root are the owner's and are allowed.
  Confinement(const std::vector<std::string>& inputRoots, const std::vector<std::string>& outputRoots);
  ~Confinement();
  Confinement(const Confinement&) = delete;
  Confinement& operator=(const Confinement&) = delete;

  bool confinesInputs() const { return !inputs_.empty(); }
  bool confinesOutputs() const { return !outputs_.empty(); }

  // "" when the absolute normalised `path` may be read (a regular file, or a directory of
  // regular files), else the reason, naming the path and the roots.
  std::string checkInput(const std::string& path) const;
  // "" when `path` may be written: under an output root, no link on the way, not a link itself;
  // missing directories on the way are fine (openOutputDir creates them).
  std::string checkOutput(const std::string& path) const;

  // The directory `dir` under an output root, opened (and created) component by component
  // without following links. Throws OutputError naming the directory.
  class Dir {
   public:
    explicit Dir(int fd) : fd_(fd) {}
    ~Dir();
    Dir(const Dir&) = delete;
    Dir& operator=(const Dir&) = delete;
    // A path that names `name` in this very directory, whatever happens to its path later.
    std::string pinnedPath(const std::string& name) const;
    // Creates the directory `name` in this one and opens it, following no link.
    std::unique_ptr<Dir> makeSubdir(const std::string& name) const;

   private:
    int fd_;
  };
  std::unique_ptr<Dir> openOutputDir(const std::string& dir) const;

 private:
  struct Root;
  const Root* rootOf(const std::vector<Root>& roots, const std::string& path, std::string* rest) const;
  static std::string rootList(const std::vector<Root>& roots);
  std::vector<Root> inputs_, outputs_;
};

// "a:b:c" → {"a", "b", "c"} (the --input-root and --output-root lists; empty parts dropped).
std::vector<std::string> splitRootList(const std::string& list);

}  // namespace prtbake::jobs
