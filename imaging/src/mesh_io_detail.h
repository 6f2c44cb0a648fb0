#pragma once
/// Private to msk_imaging: the per-format mesh adapters (mesh_io_<format>.cpp) and the byte and text helpers they
/// share. No third-party headers here; VTK stays in vtk_mesh.h.
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "msk/core/error.h"
#include "msk/core/triangle_mesh.h"
#include "msk/imaging/mesh_io.h"

namespace msk::detail {

// ---------------------------------------------------------------------------------------------------------------
// Format adapters. A reader returns the mesh as the file stores it (file space, unused vertices kept) and sets
// `space` only if the file carries a SPACE tag. A writer writes `m` (already in `space`) to `file`, naming `path`
// (the user's target) in its errors. Both throw IoError.

/// Reads a VTK legacy polydata file (mesh_io_vtk_legacy.cpp).
TriangleMesh readVtkLegacy(const std::string& path, MeshSpace& space);
/// Writes a VTK legacy 4.2 binary polydata file with double points and point arrays (mesh_io_vtk_legacy.cpp).
void writeVtkLegacy(const std::string& file, const std::string& path, const TriangleMesh& m, MeshSpace space);
/// Reads a VTK XML polydata file (mesh_io_vtp.cpp).
TriangleMesh readVtp(const std::string& path, MeshSpace& space);
/// Writes a VTK XML polydata file with the field data string array SPACE (mesh_io_vtp.cpp).
void writeVtp(const std::string& file, const std::string& path, const TriangleMesh& m, MeshSpace space);
/// Reads an ASCII or binary STL file, merging the corners it repeats per face (mesh_io_stl.cpp).
TriangleMesh readStl(const std::string& path, MeshSpace& space);
/// Writes a binary STL file, the SPACE tag in its 80-byte header (mesh_io_stl.cpp).
void writeStl(const std::string& file, const std::string& path, const TriangleMesh& m, MeshSpace space);
/// Reads a Wavefront OBJ file (mesh_io_obj.cpp).
TriangleMesh readObj(const std::string& path, MeshSpace& space);
/// Writes a Wavefront OBJ file, the SPACE tag in a comment (mesh_io_obj.cpp).
void writeObj(const std::string& file, const std::string& path, const TriangleMesh& m, MeshSpace space);
/// Reads a PLY file, ASCII or binary (mesh_io_ply.cpp).
TriangleMesh readPly(const std::string& path, MeshSpace& space);
/// Writes a binary little-endian PLY file, the SPACE tag in a comment (mesh_io_ply.cpp).
void writePly(const std::string& file, const std::string& path, const TriangleMesh& m, MeshSpace space);

/// IoError unless `path` exists and is a regular file (also used by tet_mesh_io.cpp).
inline void requireRegularFile(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw IoError(path, "file does not exist");
  if (!std::filesystem::is_regular_file(path, ec)) throw IoError(path, "not a regular file");
}

// ---------------------------------------------------------------------------------------------------------------
// Bytes and text

/// How many leading bytes the SPACE tag is looked for in, where a format allows it anywhere in a header.
constexpr size_t kHeadBytes = 65536;

/// The first `maxBytes` bytes of a file (all of it by default).
inline std::string readBytes(const std::string& path, size_t maxBytes = SIZE_MAX) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path, "cannot open the file for reading");
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  std::string s(ec ? 0 : std::min<size_t>(maxBytes, static_cast<size_t>(size)), '\0');
  in.read(s.data(), static_cast<std::streamsize>(s.size()));
  s.resize(static_cast<size_t>(in.gcount()));
  return s;
}

/// Writes `bytes` to `file`; IoError naming `path` (the user's target) on failure.
inline void writeBytes(const std::string& file, const std::string& path, const std::string& bytes) {
  std::ofstream o(file, std::ios::binary);
  o.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  o.close();
  if (!o) throw IoError(path, "cannot write the file");
}

/// Splits text into lines without their '\r'/'\n' terminators.
inline std::vector<std::string> splitLines(const std::string& text) {
  std::vector<std::string> lines;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t end = text.find('\n', start);
    std::string line = text.substr(start, end == std::string::npos ? std::string::npos : end - start);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    lines.push_back(line);
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return lines;
}

/// True if `s` begins with `prefix`.
inline bool startsWith(const std::string& s, const std::string& prefix) {
  return s.compare(0, prefix.size(), prefix) == 0;
}

/// `s` in lower case (ASCII).
inline std::string lowercase(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

/// A whole token [first, last) as a double: an optional leading '+', then what std::from_chars reads (no locale,
/// no whitespace); false if anything is left over or it is not a number.
inline bool parseNumber(const char* first, const char* last, double& value) {
  if (first != last && *first == '+') ++first;
  const auto res = std::from_chars(first, last, value);
  return res.ec == std::errc() && res.ptr == last;
}

/// True on a little-endian host.
inline bool hostIsLittleEndian() {
  const uint16_t one = 1;
  unsigned char first;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

/// The sizeof(T) bytes at `b`, in host byte order, read as a T and converted to double.
template <typename T>
double bytesAs(const unsigned char* b) {
  T v;
  std::memcpy(&v, b, sizeof v);
  return static_cast<double>(v);
}

/// Numeric value types of the binary mesh formats (VTK legacy, PLY).
enum class BinaryType { I8, U8, I16, U16, I32, U32, I64, U64, F32, F64 };

/// Bytes of one value of type `t`.
inline size_t binarySize(BinaryType t) {
  switch (t) {
    case BinaryType::I8:
    case BinaryType::U8:
      return 1;
    case BinaryType::I16:
    case BinaryType::U16:
      return 2;
    case BinaryType::I32:
    case BinaryType::U32:
    case BinaryType::F32:
      return 4;
    case BinaryType::I64:
    case BinaryType::U64:
    case BinaryType::F64:
      return 8;
  }
  return 0;
}

/// The value of type `t` stored at `p` (binarySize(t) bytes, big-endian if `bigEndian`, else little-endian) as a
/// double.
inline double decodeBinary(BinaryType t, const char* p, bool bigEndian) {
  unsigned char b[8];
  const size_t n = binarySize(t);
  std::memcpy(b, p, n);
  if (bigEndian == hostIsLittleEndian()) std::reverse(b, b + n);
  switch (t) {
    case BinaryType::I8:
      return bytesAs<int8_t>(b);
    case BinaryType::U8:
      return bytesAs<uint8_t>(b);
    case BinaryType::I16:
      return bytesAs<int16_t>(b);
    case BinaryType::U16:
      return bytesAs<uint16_t>(b);
    case BinaryType::I32:
      return bytesAs<int32_t>(b);
    case BinaryType::U32:
      return bytesAs<uint32_t>(b);
    case BinaryType::I64:
      return bytesAs<int64_t>(b);
    case BinaryType::U64:
      return bytesAs<uint64_t>(b);
    case BinaryType::F32:
      return bytesAs<float>(b);
    case BinaryType::F64:
      return bytesAs<double>(b);
  }
  return 0;
}

// ---------------------------------------------------------------------------------------------------------------
// SPACE tags

/// What the written files say they hold (header, title or comment line).
constexpr const char* kMeshTitle = "mskseg triangle mesh (mm)";

/// "SPACE=LPS" or "SPACE=RAS", the tag written into headers and comments.
inline std::string tagText(MeshSpace space) { return std::string("SPACE=") + meshSpaceName(space); }

/// Header line of the formats that have one (VTK legacy title, STL header).
inline std::string headerText(MeshSpace space) { return std::string(kMeshTitle) + " " + tagText(space); }

/// Looks for a "SPACE=<LPS|RAS>" token (case-insensitive) in `text`; true and `out` set if found.
/// An unknown value after "SPACE=" is an error rather than silently LPS.
inline bool findSpaceToken(const std::string& text, const std::string& path, MeshSpace& out) {
  std::string upper(text);
  std::transform(upper.begin(), upper.end(), upper.begin(), [](unsigned char c) { return std::toupper(c); });
  for (size_t pos = upper.find("SPACE="); pos != std::string::npos; pos = upper.find("SPACE=", pos + 1)) {
    if (pos > 0 && (std::isalnum(static_cast<unsigned char>(upper[pos - 1])) || upper[pos - 1] == '_')) continue;
    size_t end = pos + 6;
    while (end < upper.size() && std::isalpha(static_cast<unsigned char>(upper[end]))) ++end;
    const std::string word = text.substr(pos + 6, end - pos - 6);
    try {
      out = parseMeshSpace(word);
    } catch (const ParameterError&) {
      throw IoError(path, "unknown coordinate-space tag 'SPACE=" + word + "' (expected LPS or RAS)");
    }
    return true;
  }
  return false;
}

}  // namespace msk::detail
