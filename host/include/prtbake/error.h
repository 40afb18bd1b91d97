// prtbake/error.h: the exceptions the library throws at its boundary.
//
// Every user-facing failure carries the thing it is about (a file, a job, a
// parameter) and what is wrong with it, so a front end can print one line:
//   prtbake: error: <subject>: <what is wrong>
#pragma once

#include <stdexcept>
#include <string>

namespace prtbake {

// The message is one line, whatever a library's reason or a file name holds: control
// characters (a newline in a decoder's message, a tab in a path) are written as \xNN.
// subject() and detail() keep the raw text.
class Error : public std::runtime_error {
 public:
  Error(std::string subject, std::string what)
      : std::runtime_error(oneLine(subject.empty() ? what : subject + ": " + what)),
        subject_(std::move(subject)), detail_(std::move(what)) {}
  const std::string& subject() const { return subject_; }
  const std::string& detail() const { return detail_; }

  static std::string oneLine(const std::string& text) {
    std::string out;
    out.reserve(text.size());
    for (const char ch : text) {
      const auto c = static_cast<unsigned char>(ch);
      if (c >= 0x20 && c != 0x7f) {
        out += ch;
      } else {
        static const char* hex = "0123456789abcdef";
        out += "\\x";
        out += hex[c >> 4];
        out += hex[c & 15];
      }
    }
    return out;
  }

 private:
  std::string subject_, detail_;
};

// Nonsense parameters (order 0, size -1, unknown NDF). Exit code 2 in the CLI.
class UsageError : public Error {
 public:
  using Error::Error;
};

// Missing, truncated, malformed or non-finite input files. Exit code 1.
class InputError : public Error {
 public:
  using Error::Error;
};

// OpenCL failures: no device, build errors (with the log), out of memory.
class DeviceError : public Error {
 public:
  using Error::Error;
};

// Writing outputs failed (disk full, permissions).
class OutputError : public Error {
 public:
  using Error::Error;
};

// Cheap invariant check that stays on in release builds.
#define PRTBAKE_CHECK(cond, msg)                                                   \
  do {                                                                             \
    if (!(cond))                                                                   \
      throw ::prtbake::Error(std::string(__FILE__) + ":" + std::to_string(__LINE__), \
                             std::string("internal check failed: ") + #cond + ": " + (msg)); \
  } while (0)

}  // namespace prtbake
