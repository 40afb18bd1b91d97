// prtbake/hash.h: SHA-256 of files and bytes (input hashes in sidecars and manifests).
#pragma once

#include <cstddef>
#include <string>

namespace prtbake {

// Lower-case hex SHA-256 of `bytes`.
std::string sha256Hex(const void* data, size_t bytes);
// Lower-case hex SHA-256 of a file's contents; throws InputError naming the file.
std::string sha256File(const std::string& path);

}  // namespace prtbake
