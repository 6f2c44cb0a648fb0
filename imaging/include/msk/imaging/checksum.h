#pragma once
/// File checksums (SHA-256, OpenSSL) for provenance and for checking that a folder's files are the ones it records.
#include <string>

namespace msk {

/// Lower-case hexadecimal SHA-256 of the file's bytes. Throws IoError naming the file if it cannot be read.
std::string sha256File(const std::string& path);

/// Lower-case hexadecimal SHA-256 of `bytes`.
std::string sha256Text(const std::string& bytes);

}  // namespace msk
