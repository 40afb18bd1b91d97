// prtbake/atomic_file.h: outputs appear whole or not at all.
//
// Data goes to a temp file in the destination's directory (".<name>.prtbake-tmp.<pid>.<n>");
// commit() flushes, fsyncs and renames it over the destination, then fsyncs the
// directory. An AtomicFile destroyed without commit() removes its temp file, so a
// failed job leaves nothing behind. A killed process may leave a temp file; the
// names are recognisable so that the next run can remove them
// (removeStaleTempFiles). A destination that exists and is not a regular file (links
// followed: a directory, a device such as /dev/null, a named pipe, /dev/stdout) is refused
// when the AtomicFile is made: the rename would replace it with a file.
#pragma once

#include <cstddef>
#include <string>

namespace prtbake {

class AtomicFile {
 public:
  explicit AtomicFile(std::string path);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  void write(const void* data, size_t bytes);
  void write(const std::string& text) { write(text.data(), text.size()); }
  // Makes the file visible at its final path. Throws OutputError on failure.
  void commit();

  const std::string& path() const { return path_; }
  const std::string& tempPath() const { return tempPath_; }
  // For writers that open a file by name (OpenEXR): a name of this very temp file
  // (/proc/self/fd/N), which no rename or link in its directory can redirect.
  std::string writerPath() const;

 private:
  std::string path_, tempPath_;
  int fd_ = -1;
  bool committed_ = false;
};

// Writes `text` to `path` atomically.
void writeFileAtomic(const std::string& path, const std::string& text);

// Removes temp files left in `dir` by killed runs of this tool (owned by a
// process that no longer exists). Returns how many were removed.
int removeStaleTempFiles(const std::string& dir);

// Reads a whole file; throws InputError naming the file when it cannot be read.
std::string readFile(const std::string& path);
// The first `most` bytes of a file (all of a shorter one), and its size in *fileSize when given;
// throws as readFile.
std::string readFilePrefix(const std::string& path, size_t most, size_t* fileSize = nullptr);

// The size of the regular file `path` (links followed). Throws InputError naming it when it is
// missing, a directory, or a device, pipe or socket: reading /dev/zero never ends, opening a FIFO
// waits for a writer, and their size says nothing about what reading them allocates. Every
// reader of an input file calls this before it opens the file.
size_t inputFileSize(const std::string& path);

// The library version, e.g. "0.1.0".
const char* version();

}  // namespace prtbake
