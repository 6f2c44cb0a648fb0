#pragma once
/// File checksums (SHA-256, OpenSSL) for provenance and for checking that a folder's files are the ones it records;
/// base64 (OpenSSL) for embedding bytes in text.
#include <string>

namespace msk {

/// Lower-case hexadecimal SHA-256 of the file's bytes. Throws IoError naming the file if it cannot be read.
std::string sha256File(const std::string& path);

/// Lower-case hexadecimal SHA-256 of `bytes`.
std::string sha256Text(const std::string& bytes);

/// `bytes` in base64 (RFC 4648, with padding, no line breaks), e.g. for a data: URL.
std::string base64(const std::string& bytes);

}  // namespace msk
