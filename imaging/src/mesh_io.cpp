// Mesh files. VTK (legacy .vtk writing, XML .vtp, STL) is confined to this file. Legacy .vtk reading, OBJ and PLY
// are done here directly: VTK 9.1's legacy and PLY readers crash on truncated files (and the legacy one accepts
// truncated arrays), its OBJ reader renumbers vertices, its OBJ/PLY writers store float32, and its PLY reader
// drops extra vertex properties.
#include "msk/imaging/mesh_io.h"

#include <vtkCellArray.h>
#include <vtkCleanPolyData.h>
#include <vtkDataArray.h>
#include <vtkDoubleArray.h>
#include <vtkFieldData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataWriter.h>
#include <vtkSTLReader.h>
#include <vtkSTLWriter.h>
#include <vtkSmartPointer.h>
#include <vtkStringArray.h>
#include <vtkTriangleFilter.h>
#include <vtkXMLPolyDataReader.h>
#include <vtkXMLPolyDataWriter.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "msk/core/atomic_file.h"
#include "msk/core/error.h"

namespace fs = std::filesystem;

namespace msk {

namespace {

// ---------------------------------------------------------------------------------------------------------------
// Formats, tags and small helpers

enum class Format { Vtk, Vtp, Stl, Obj, Ply, Unknown };

Format formatOf(const std::string& path) {
  const std::string ext = fileExtension(path);
  if (ext == ".vtk") return Format::Vtk;
  if (ext == ".vtp") return Format::Vtp;
  if (ext == ".stl") return Format::Stl;
  if (ext == ".obj") return Format::Obj;
  if (ext == ".ply") return Format::Ply;
  return Format::Unknown;
}

IoError unsupported(const std::string& path) {
  const std::string ext = fileExtension(path);
  return IoError(path, "unsupported mesh format '" + (ext.empty() ? std::string("(no extension)") : ext) +
                           "' (use .vtk, .vtp, .stl, .obj or .ply)");
}

/// Switches VTK's global error/warning printing off for one read or write (libraries never print);
/// failures are detected from the output instead. Not safe against concurrent VTK use on other threads.
class VtkQuiet {
 public:
  VtkQuiet() : was_(vtkObject::GetGlobalWarningDisplay()) { vtkObject::GlobalWarningDisplayOff(); }
  ~VtkQuiet() { vtkObject::SetGlobalWarningDisplay(was_); }
  VtkQuiet(const VtkQuiet&) = delete;
  VtkQuiet& operator=(const VtkQuiet&) = delete;

 private:
  int was_;
};

/// The first `maxBytes` bytes of a file (all of it by default).
std::string readBytes(const std::string& path, size_t maxBytes = SIZE_MAX) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path, "cannot open the file for reading");
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  std::string s(ec ? 0 : std::min<size_t>(maxBytes, static_cast<size_t>(size)), '\0');
  in.read(s.data(), static_cast<std::streamsize>(s.size()));
  s.resize(static_cast<size_t>(in.gcount()));
  return s;
}

/// Writes `bytes` to `file`; IoError naming `path` (the user's target) on failure.
void writeBytes(const std::string& file, const std::string& path, const std::string& bytes) {
  std::ofstream o(file, std::ios::binary);
  o.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  o.close();
  if (!o) throw IoError(path, "cannot write the file");
}

/// Splits text into lines without their '\r'/'\n' terminators.
std::vector<std::string> splitLines(const std::string& text) {
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

bool startsWith(const std::string& s, const std::string& prefix) { return s.compare(0, prefix.size(), prefix) == 0; }

std::string tagText(MeshSpace space) { return std::string("SPACE=") + meshSpaceName(space); }

/// Looks for a "SPACE=<LPS|RAS>" token (case-insensitive) in `text`; true and `out` set if found.
/// An unknown value after "SPACE=" is an error rather than silently LPS.
bool findSpaceToken(const std::string& text, const std::string& path, MeshSpace& out) {
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

constexpr size_t kHeadBytes = 65536;

/// Space tag from the legacy VTK title line (2nd line); also checks the magic line.
bool legacySpace(const std::string& path, MeshSpace& out) {
  const std::vector<std::string> lines = splitLines(readBytes(path, 1024));
  if (lines.empty() || !startsWith(lines[0], "# vtk DataFile Version"))
    throw IoError(path, "not a VTK legacy file (first line is not '# vtk DataFile Version x.y')");
  return lines.size() > 1 && findSpaceToken(lines[1], path, out);
}

/// Space tag from the STL header: the 80-byte binary header or the ASCII "solid" line.
bool stlSpace(const std::string& path, MeshSpace& out) {
  std::string head = readBytes(path, 256);
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (!ec && head.size() >= 84) {
    uint32_t n = 0;
    for (int b = 3; b >= 0; --b) n = (n << 8) | static_cast<unsigned char>(head[80 + static_cast<size_t>(b)]);
    if (static_cast<uintmax_t>(n) * 50 + 84 == size) head.resize(80);  // binary: the header only
  }
  head = head.substr(0, head.find('\n'));
  head = head.substr(0, head.find('\0'));
  return findSpaceToken(head, path, out);
}

/// Space tag from OBJ comment lines.
bool objSpace(const std::string& path, MeshSpace& out) {
  for (const std::string& line : splitLines(readBytes(path, kHeadBytes))) {
    const size_t first = line.find_first_not_of(" \t");
    if (first != std::string::npos && line[first] == '#' && findSpaceToken(line.substr(first + 1), path, out))
      return true;
  }
  return false;
}

/// Space tag of a VTP file: field data "SPACE" (a string array), else an XML comment "<!-- SPACE=... -->".
bool vtpSpace(const std::string& path, vtkPolyData* pd, MeshSpace& out) {
  if (vtkFieldData* fd = pd->GetFieldData()) {
    if (auto* s = vtkStringArray::SafeDownCast(fd->GetAbstractArray("SPACE")); s && s->GetNumberOfValues() > 0) {
      const std::string value = s->GetValue(0);
      try {
        out = parseMeshSpace(value);
      } catch (const ParameterError&) {
        throw IoError(path, "unknown coordinate space '" + value + "' in field data SPACE (expected LPS or RAS)");
      }
      return true;
    }
  }
  std::string head = readBytes(path, kHeadBytes);
  head = head.substr(0, head.find("<AppendedData"));
  for (size_t open = head.find("<!--"); open != std::string::npos; open = head.find("<!--", open + 4)) {
    const size_t close = head.find("-->", open);
    if (findSpaceToken(head.substr(open + 4, close == std::string::npos ? std::string::npos : close - open - 4), path,
                       out))
      return true;
  }
  return false;
}

/// Removes vertices no face uses (free-standing points, line ends), keeping the order of the rest.
/// Leaves the mesh alone if a face index is out of range (closedMeshProblem reports that).
void dropUnusedVertices(TriangleMesh& m) {
  const int nv = m.vertexCount();
  std::vector<int> map(static_cast<size_t>(nv), -1);
  for (int f = 0; f < m.faceCount(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int v = m.faces(f, k);
      if (v < 0 || v >= nv) return;
      map[static_cast<size_t>(v)] = 1;
    }
  int next = 0;
  for (int& u : map) u = u > 0 ? next++ : -1;
  if (next == nv) return;
  Points kept(next, 3);
  for (int i = 0; i < nv; ++i)
    if (map[static_cast<size_t>(i)] >= 0) kept.row(map[static_cast<size_t>(i)]) = m.vertices.row(i);
  for (auto& [name, values] : m.pointData) {
    if (values.size() != nv) continue;
    Eigen::VectorXd k(next);
    for (int i = 0; i < nv; ++i)
      if (map[static_cast<size_t>(i)] >= 0) k[map[static_cast<size_t>(i)]] = values[i];
    values = k;
  }
  for (int f = 0; f < m.faceCount(); ++f)
    for (int k = 0; k < 3; ++k) m.faces(f, k) = map[static_cast<size_t>(m.faces(f, k))];
  m.vertices = kept;
}

// ---------------------------------------------------------------------------------------------------------------
// VTK legacy polydata reading (versions 2.0 to 5.1, ASCII and BINARY)
//
// Parsed here rather than with vtkPolyDataReader: VTK 9.1's reader crashes on a truncated or corrupt cell
// section of a version < 5 file (it keeps reading from the stream it has closed) and accepts truncated data
// arrays, leaving their tail uninitialised. This parser checks every count against the bytes present.

namespace legacy {

enum class ValueType { Bit, I8, U8, I16, U16, I32, U32, I64, U64, F32, F64, String, Unsupported };

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

ValueType parseValueType(const std::string& text) {
  const std::string t = lower(text);
  if (t == "bit") return ValueType::Bit;
  if (t == "char" || t == "signed_char") return ValueType::I8;
  if (t == "unsigned_char") return ValueType::U8;
  if (t == "short") return ValueType::I16;
  if (t == "unsigned_short") return ValueType::U16;
  if (t == "int") return ValueType::I32;
  if (t == "unsigned_int") return ValueType::U32;
  if (t == "long" || t == "vtktypeint64" || t == "vtkidtype") return ValueType::I64;
  if (t == "unsigned_long" || t == "vtktypeuint64") return ValueType::U64;
  if (t == "float") return ValueType::F32;
  if (t == "double") return ValueType::F64;
  if (t == "string" || t == "utf8_string") return ValueType::String;
  return ValueType::Unsupported;
}

size_t byteSize(ValueType t) {
  switch (t) {
    case ValueType::I8:
    case ValueType::U8:
      return 1;
    case ValueType::I16:
    case ValueType::U16:
      return 2;
    case ValueType::I32:
    case ValueType::U32:
    case ValueType::F32:
      return 4;
    case ValueType::I64:
    case ValueType::U64:
    case ValueType::F64:
      return 8;
    default:
      return 0;
  }
}

/// Undoes VTK's name encoding ("%20" for a space and so on).
std::string decodeName(const std::string& s) {
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%' && i + 2 < s.size() && std::isxdigit(static_cast<unsigned char>(s[i + 1])) &&
        std::isxdigit(static_cast<unsigned char>(s[i + 2]))) {
      out += static_cast<char>(std::stoi(s.substr(i + 1, 2), nullptr, 16));
      i += 2;
    } else {
      out += s[i];
    }
  }
  return out;
}

/// One pass over the file bytes; every read is bounds-checked and throws IoError naming the file.
class Parser {
 public:
  Parser(std::string bytes, const std::string& path) : b_(std::move(bytes)), path_(path) {}

  TriangleMesh parse() {
    // Header: magic line with the version, title line, ASCII|BINARY line.
    const std::string magic = line();
    const size_t v = magic.find("Version");
    if (!startsWith(magic, "# vtk DataFile Version") || v == std::string::npos)
      fail("first line is not '# vtk DataFile Version x.y'");
    major_ = std::atoi(magic.c_str() + v + 7);
    line();  // title (the SPACE tag is read separately)
    const std::string format = lower(trim(line()));
    if (format == "binary")
      binary_ = true;
    else if (format != "ascii")
      fail("third line must be ASCII or BINARY, not '" + format + "'");
    if (lower(word()) != "dataset") fail("no DATASET line");
    const std::string kind = word();
    if (lower(kind) != "polydata") fail("dataset type is " + kind + ", not POLYDATA");

    TriangleMesh m;
    long long numPoints = -1;
    std::vector<int> tris;
    for (std::string key = lower(word()); !key.empty(); key = lower(word())) {
      if (key == "field") {
        readField(nullptr, 0);
      } else if (key == "points") {
        numPoints = count("number of points");
        const std::vector<double> xyz = values(parseValueType(word()), 3 * static_cast<size_t>(numPoints));
        m.vertices = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(
            xyz.data(), static_cast<Eigen::Index>(numPoints), 3);
      } else if (key == "metadata") {
        skipMetadataBlock();
      } else if (key == "vertices" || key == "lines" || key == "polygons" || key == "triangle_strips") {
        const std::vector<std::vector<int>> cells = readCells(key);
        if (key == "polygons") {
          for (const auto& c : cells) {
            if (c.size() < 3) fail("polygon with fewer than 3 vertices");
            for (size_t k = 1; k + 1 < c.size(); ++k) tris.insert(tris.end(), {c[0], c[k], c[k + 1]});
          }
        } else if (key == "triangle_strips") {
          for (const auto& c : cells)
            for (size_t k = 0; k + 2 < c.size(); ++k) {
              if (k % 2 == 0)
                tris.insert(tris.end(), {c[k], c[k + 1], c[k + 2]});
              else
                tris.insert(tris.end(), {c[k + 1], c[k], c[k + 2]});
            }
        }  // vertices and lines are not part of a surface
      } else if (key == "point_data" || key == "cell_data") {
        readAttributes(key, numPoints, m);
        break;
      } else {
        fail("unknown keyword '" + key + "'");
      }
    }
    m.faces = Eigen::Map<const Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>>(
        tris.data(), static_cast<Eigen::Index>(tris.size() / 3), 3);
    return m;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw IoError(path_, "invalid VTK legacy file: " + what + " (near byte " + std::to_string(pos_) + ")");
  }
  static std::string trim(const std::string& s) {
    const size_t a = s.find_first_not_of(" \t\r"), e = s.find_last_not_of(" \t\r");
    return a == std::string::npos ? "" : s.substr(a, e - a + 1);
  }
  /// The rest of the current line (without '\n' and a trailing '\r'); moves past it.
  std::string line() {
    if (pos_ >= b_.size()) fail("file ends prematurely");
    size_t end = b_.find('\n', pos_);
    if (end == std::string::npos) end = b_.size();
    std::string s = b_.substr(pos_, end - pos_);
    pos_ = std::min(end + 1, b_.size());
    if (!s.empty() && s.back() == '\r') s.pop_back();
    return s;
  }
  /// Next whitespace-delimited token; empty at the end of the file.
  std::string word() {
    while (pos_ < b_.size() && std::isspace(static_cast<unsigned char>(b_[pos_]))) ++pos_;
    const size_t start = pos_;
    while (pos_ < b_.size() && !std::isspace(static_cast<unsigned char>(b_[pos_]))) ++pos_;
    return b_.substr(start, pos_ - start);
  }
  /// A non-negative integer token no larger than the file (a count of anything stored in it).
  long long count(const char* what) {
    const std::string w = word();
    long long n = -1;
    const auto res = std::from_chars(w.data(), w.data() + w.size(), n);
    if (res.ec != std::errc() || res.ptr != w.data() + w.size() || n < 0)
      fail(std::string("bad ") + what + " '" + w + "'");
    if (static_cast<unsigned long long>(n) > b_.size()) fail(std::string(what) + " exceeds the file size");
    return n;
  }
  /// `n` values of type `t` (binary big-endian data starts on the line after the header; ASCII is tokens).
  /// String arrays are consumed and returned empty. Skips a METADATA block that follows the data.
  std::vector<double> values(ValueType t, size_t n) {
    if (t == ValueType::Unsupported) fail("unsupported data type");
    std::vector<double> out;
    if (n == 0) return out;
    if (n > b_.size()) fail("array larger than the file");
    if (t == ValueType::String) {
      skipStrings(n);
    } else if (!binary_) {
      out.resize(n);
      for (double& v : out) {
        const std::string w = word();
        if (w.empty()) fail("file ends inside a data array (truncated)");
        const char* first = w.data() + (w[0] == '+' ? 1 : 0);
        const auto res = std::from_chars(first, w.data() + w.size(), v);
        if (res.ec != std::errc() || res.ptr != w.data() + w.size()) fail("bad number '" + w.substr(0, 40) + "'");
      }
    } else {
      nextLine();
      out.resize(n);
      if (t == ValueType::Bit) {
        need((n + 7) / 8);
        for (size_t i = 0; i < n; ++i) out[i] = (static_cast<unsigned char>(b_[pos_ + i / 8]) >> (7 - i % 8)) & 1;
        pos_ += (n + 7) / 8;
      } else {
        const size_t size = byteSize(t);
        need(n * size);
        for (size_t i = 0; i < n; ++i, pos_ += size) out[i] = bigEndianValue(t, size);
      }
    }
    skipOptionalMetadata();
    return out;
  }
  void need(size_t bytes) const {
    if (bytes > b_.size() - pos_) fail("file ends inside a binary data block (truncated)");
  }
  void nextLine() {
    const size_t end = b_.find('\n', pos_);
    pos_ = end == std::string::npos ? b_.size() : end + 1;
  }
  double bigEndianValue(ValueType t, size_t size) const {
    unsigned char c[8];
    for (size_t k = 0; k < size; ++k) c[k] = static_cast<unsigned char>(b_[pos_ + size - 1 - k]);  // → little
    const bool hostLittle = [] {
      const uint16_t one = 1;
      unsigned char first;
      std::memcpy(&first, &one, 1);
      return first == 1;
    }();
    if (!hostLittle) std::reverse(c, c + size);
    auto as = [&c](auto v) {
      std::memcpy(&v, c, sizeof v);
      return static_cast<double>(v);
    };
    switch (t) {
      case ValueType::I8:
        return as(int8_t{});
      case ValueType::U8:
        return as(uint8_t{});
      case ValueType::I16:
        return as(int16_t{});
      case ValueType::U16:
        return as(uint16_t{});
      case ValueType::I32:
        return as(int32_t{});
      case ValueType::U32:
        return as(uint32_t{});
      case ValueType::I64:
        return as(int64_t{});
      case ValueType::U64:
        return as(uint64_t{});
      case ValueType::F32:
        return as(float{});
      case ValueType::F64:
        return as(double{});
      default:
        return 0;
    }
  }
  /// String arrays: binary values carry a 1/2/4/8-byte big-endian length header, ASCII ones are one per line.
  void skipStrings(size_t n) {
    nextLine();
    for (size_t i = 0; i < n; ++i) {
      if (!binary_) {
        line();
        continue;
      }
      need(1);
      const unsigned char first = static_cast<unsigned char>(b_[pos_]);
      const size_t header = first >> 6 == 3 ? 1 : first >> 6 == 2 ? 2 : first >> 6 == 1 ? 4 : 8;
      need(header);
      uint64_t length = 0;
      for (size_t k = 0; k < header; ++k) length = (length << 8) | static_cast<unsigned char>(b_[pos_ + k]);
      if (header < 8) length &= (uint64_t{1} << (8 * header - 2)) - 1;
      pos_ += header;
      need(static_cast<size_t>(std::min<uint64_t>(length, b_.size())));
      if (length > b_.size()) fail("string longer than the file");
      pos_ += static_cast<size_t>(length);
    }
  }
  /// VTK writes an optional "METADATA" block (ended by a blank line) after an array.
  void skipOptionalMetadata() {
    const size_t save = pos_;
    if (lower(word()) != "metadata") {
      pos_ = save;
      return;
    }
    skipMetadataBlock();
  }
  void skipMetadataBlock() {
    nextLine();
    while (pos_ < b_.size() && !trim(line()).empty()) {
    }
  }
  /// Cells as index lists, from the version < 5 layout (n, id…)* or the 5.x OFFSETS/CONNECTIVITY arrays.
  std::vector<std::vector<int>> readCells(const std::string& key) {
    const long long a = count("cell count"), b = count("cell array size");
    std::vector<std::vector<int>> cells;
    auto index = [&](double v) {
      if (!(v >= 0 && v <= INT32_MAX && v == std::floor(v))) fail("bad vertex index in " + key);
      return static_cast<int>(v);
    };
    if (major_ >= 5) {
      if (lower(word()) != "offsets") fail("OFFSETS expected in " + key);
      const std::vector<double> offsets = values(parseValueType(word()), static_cast<size_t>(a));
      if (lower(word()) != "connectivity") fail("CONNECTIVITY expected in " + key);
      const std::vector<double> conn = values(parseValueType(word()), static_cast<size_t>(b));
      if (a == 0 ? b != 0 : (offsets.front() != 0 || offsets.back() != static_cast<double>(b)))
        fail("offsets do not match the connectivity in " + key);
      for (long long c = 0; c + 1 < a; ++c) {
        const double lo = offsets[static_cast<size_t>(c)], hi = offsets[static_cast<size_t>(c) + 1];
        if (!(hi >= lo && lo >= 0 && hi <= static_cast<double>(b))) fail("offsets not increasing in " + key);
        std::vector<int> cell;
        for (size_t k = static_cast<size_t>(lo); k < static_cast<size_t>(hi); ++k) cell.push_back(index(conn[k]));
        cells.push_back(std::move(cell));
      }
    } else {
      const std::vector<double> raw = values(ValueType::I32, static_cast<size_t>(b));
      size_t at = 0;
      while (at < raw.size()) {
        const int n = index(raw[at]);
        if (at + 1 + static_cast<size_t>(n) > raw.size()) fail("cell list overruns its size in " + key);
        std::vector<int> cell;
        for (int k = 0; k < n; ++k) cell.push_back(index(raw[at + 1 + static_cast<size_t>(k)]));
        cells.push_back(std::move(cell));
        at += 1 + static_cast<size_t>(n);
      }
      if (static_cast<long long>(cells.size()) != a) fail("cell count does not match the list in " + key);
    }
    return cells;
  }
  /// FIELD name n, then n arrays "name components tuples type" (or NULL_ARRAY); 1-component numeric arrays with
  /// `tuples` entries go into `keep` when it is given.
  void readField(std::map<std::string, Eigen::VectorXd>* keep, long long tuples) {
    word();  // field name
    const long long n = count("number of field arrays");
    for (long long i = 0; i < n; ++i) {
      const std::string name = word();
      if (name == "NULL_ARRAY") continue;
      const long long comps = count("component count"), rows = count("tuple count");
      const ValueType t = parseValueType(word());
      const std::vector<double> v = values(t, static_cast<size_t>(comps * rows));
      if (keep && comps == 1 && rows == tuples && t != ValueType::String)
        (*keep)[decodeName(name)] = Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
    }
  }
  /// POINT_DATA / CELL_DATA sections to the end of the file; 1-component numeric point arrays are kept.
  void readAttributes(std::string key, long long numPoints, TriangleMesh& m) {
    long long n = count("attribute count");
    bool onPoints = key == "point_data";
    if (onPoints && n != numPoints) fail("POINT_DATA count differs from the number of points");
    for (key = lower(word()); !key.empty(); key = lower(word())) {
      auto* keep = onPoints ? &m.pointData : nullptr;
      if (key == "point_data" || key == "cell_data") {
        n = count("attribute count");
        onPoints = key == "point_data";
        if (onPoints && n != numPoints) fail("POINT_DATA count differs from the number of points");
      } else if (key == "scalars") {
        const std::string name = decodeName(word());
        const ValueType t = parseValueType(word());
        std::string next = word();
        long long comps = 1;
        if (lower(next) != "lookup_table") {
          comps = std::atoll(next.c_str());
          if (comps < 1 || comps > 4) fail("bad SCALARS component count '" + next + "'");
          next = word();
        }
        if (lower(next) != "lookup_table") fail("SCALARS without LOOKUP_TABLE");
        word();  // table name
        const std::vector<double> v = values(t, static_cast<size_t>(n * comps));
        if (keep && comps == 1 && t != ValueType::String)
          (*keep)[name] = Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
      } else if (key == "color_scalars") {
        word();
        const long long comps = count("component count");
        values(binary_ ? ValueType::U8 : ValueType::F32, static_cast<size_t>(n * comps));
      } else if (key == "lookup_table") {
        word();
        const long long size = count("lookup table size");
        values(binary_ ? ValueType::U8 : ValueType::F32, static_cast<size_t>(size * 4));
      } else if (key == "vectors" || key == "normals" || key == "tensors" || key == "tensors6") {
        word();
        const long long comps = key == "tensors" ? 9 : key == "tensors6" ? 6 : 3;
        values(parseValueType(word()), static_cast<size_t>(n * comps));
      } else if (key == "texture_coordinates") {
        word();
        const long long dim = count("texture dimension");
        values(parseValueType(word()), static_cast<size_t>(n * dim));
      } else if (key == "global_ids" || key == "pedigree_ids" || key == "edge_flags") {
        word();
        values(parseValueType(word()), static_cast<size_t>(n));
      } else if (key == "field") {
        readField(keep, n);
      } else if (key == "metadata") {
        skipMetadataBlock();
      } else {
        fail("unknown attribute keyword '" + key + "'");
      }
    }
  }

  const std::string b_;
  const std::string& path_;
  size_t pos_ = 0;
  bool binary_ = false;
  int major_ = 0;
};

}  // namespace legacy

// ---------------------------------------------------------------------------------------------------------------
// VTK polydata ↔ TriangleMesh

/// Runs a reader and returns (a shallow copy of) its polydata output; IoError if it failed or is empty.
vtkSmartPointer<vtkPolyData> runReader(vtkAlgorithm* reader, const std::string& path, const std::string& what) {
  reader->Update();
  auto* out = vtkPolyData::SafeDownCast(reader->GetOutputDataObject(0));
  if (reader->GetErrorCode() != 0 || !out || out->GetNumberOfPoints() == 0)
    throw IoError(path, "cannot read the file as " + what + " (unreadable, corrupt or empty)");
  auto copy = vtkSmartPointer<vtkPolyData>::New();
  copy->ShallowCopy(out);
  return copy;
}

/// Triangle filter (polygons and strips → triangles; vertices and lines dropped), optionally merging
/// coincident points first (tolerance 0: exact duplicates only).
vtkSmartPointer<vtkPolyData> triangulate(vtkPolyData* in, bool mergePoints) {
  vtkSmartPointer<vtkPolyData> current = in;
  if (mergePoints) {
    vtkNew<vtkCleanPolyData> clean;
    clean->SetInputData(current);
    clean->PointMergingOn();
    clean->SetTolerance(0.0);
    clean->Update();
    current = clean->GetOutput();
  }
  vtkNew<vtkTriangleFilter> tri;
  tri->SetInputData(current);
  tri->PassVertsOff();
  tri->PassLinesOff();
  tri->Update();
  auto out = vtkSmartPointer<vtkPolyData>::New();
  out->ShallowCopy(tri->GetOutput());
  return out;
}

/// Copies triangles, points and named 1-component numeric point arrays.
TriangleMesh toMesh(vtkPolyData* pd, const std::string& path) {
  TriangleMesh m;
  vtkCellArray* polys = pd->GetPolys();
  const vtkIdType nv = pd->GetNumberOfPoints();
  if (!polys || polys->GetNumberOfCells() == 0 || nv == 0)
    throw IoError(path, "the file holds no triangles (empty mesh, or a truncated or corrupt file)");
  m.faces.resize(polys->GetNumberOfCells(), 3);
  vtkIdType npts = 0;
  const vtkIdType* ids = nullptr;
  int f = 0;
  polys->InitTraversal();
  while (polys->GetNextCell(npts, ids)) {
    if (npts != 3) throw IoError(path, "a polygon could not be triangulated");
    for (int k = 0; k < 3; ++k) {
      if (ids[k] < 0 || ids[k] >= nv) throw IoError(path, "a triangle refers to a missing vertex");
      m.faces(f, k) = static_cast<int>(ids[k]);
    }
    ++f;
  }
  m.vertices.resize(nv, 3);
  vtkPoints* pts = pd->GetPoints();
  for (vtkIdType i = 0; i < nv; ++i) {
    double p[3];
    pts->GetPoint(i, p);
    m.vertices.row(i) << p[0], p[1], p[2];
  }
  vtkPointData* pdata = pd->GetPointData();
  for (int a = 0; pdata && a < pdata->GetNumberOfArrays(); ++a) {
    vtkDataArray* arr = pdata->GetArray(a);  // null for non-numeric arrays
    if (!arr || arr->GetNumberOfComponents() != 1 || !arr->GetName() || !*arr->GetName()) continue;
    if (arr->GetNumberOfTuples() != nv)
      throw IoError(path, std::string("point array '") + arr->GetName() + "' has the wrong length");
    Eigen::VectorXd values(nv);
    for (vtkIdType i = 0; i < nv; ++i) values[i] = arr->GetTuple1(i);
    m.pointData[arr->GetName()] = values;
  }
  return m;
}

/// A vtkPolyData with the mesh's points (double), triangles and (optionally) point arrays (double).
vtkSmartPointer<vtkPolyData> toPolyData(const TriangleMesh& m, bool withPointData, const std::string& path) {
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  points->SetNumberOfPoints(m.vertexCount());
  for (int i = 0; i < m.vertexCount(); ++i) points->SetPoint(i, m.vertices(i, 0), m.vertices(i, 1), m.vertices(i, 2));
  vtkNew<vtkCellArray> polys;
  polys->AllocateExact(m.faceCount(), 3 * m.faceCount());
  for (int f = 0; f < m.faceCount(); ++f) {
    const vtkIdType ids[3] = {m.faces(f, 0), m.faces(f, 1), m.faces(f, 2)};
    polys->InsertNextCell(3, ids);
  }
  auto pd = vtkSmartPointer<vtkPolyData>::New();
  pd->SetPoints(points);
  pd->SetPolys(polys);
  if (withPointData) {
    for (const auto& [name, values] : m.pointData) {
      if (name.empty()) throw IoError(path, "a point array has an empty name and cannot be stored");
      vtkNew<vtkDoubleArray> arr;
      arr->SetName(name.c_str());
      arr->SetNumberOfComponents(1);
      arr->SetNumberOfTuples(values.size());
      for (Eigen::Index i = 0; i < values.size(); ++i) arr->SetValue(i, values[i]);
      pd->GetPointData()->AddArray(arr);
    }
  }
  return pd;
}

// ---------------------------------------------------------------------------------------------------------------
// OBJ

/// Shortest text that reads back as exactly `v` (locale-independent).
void appendNumber(std::string& out, double v) {
  char buf[32];
  const auto res = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, res.ptr);
}

/// OBJ is written directly: full double precision, the SPACE comment at the top, geometry only.
void writeObj(const std::string& file, const std::string& path, const TriangleMesh& m, MeshSpace space) {
  std::string out = "# mskseg triangle mesh (mm)\n# " + tagText(space) + "\n";
  out.reserve(out.size() + static_cast<size_t>(m.vertexCount()) * 60 + static_cast<size_t>(m.faceCount()) * 24);
  for (int i = 0; i < m.vertexCount(); ++i) {
    out += 'v';
    for (int c = 0; c < 3; ++c) {
      out += ' ';
      appendNumber(out, m.vertices(i, c));
    }
    out += '\n';
  }
  for (int f = 0; f < m.faceCount(); ++f)
    out += "f " + std::to_string(m.faces(f, 0) + 1) + ' ' + std::to_string(m.faces(f, 1) + 1) + ' ' +
           std::to_string(m.faces(f, 2) + 1) + '\n';
  writeBytes(file, path, out);
}

/// Reads "v x y z" and "f a b c …" records (1-based or negative indices; "a/t/n" forms use the position index
/// only, so texture seams do not split vertices; polygons are fan-triangulated). Vertex order is kept.
TriangleMesh readObj(const std::string& path) {
  const std::string text = readBytes(path);
  std::vector<double> xyz;
  std::vector<int> tri;
  size_t lineNo = 0;
  for (const std::string& raw : splitLines(text)) {
    ++lineNo;
    const std::string line = raw.substr(0, raw.find('#'));
    std::istringstream in(line);
    std::string key, token;
    in >> key;
    auto bad = [&](const std::string& what) {
      return IoError(path, "line " + std::to_string(lineNo) + ": " + what + " in '" + line.substr(0, 60) + "'");
    };
    if (key == "v") {
      for (int c = 0; c < 3; ++c) {
        double v = 0;
        if (!(in >> token)) throw bad("missing vertex coordinate");
        const char* first = token.data() + (token[0] == '+' ? 1 : 0);
        const auto res = std::from_chars(first, token.data() + token.size(), v);
        if (res.ec != std::errc() || res.ptr != token.data() + token.size()) throw bad("bad number");
        xyz.push_back(v);
      }
    } else if (key == "f") {
      std::vector<int> poly;
      while (in >> token) {
        long long idx = 0;
        const std::string head = token.substr(0, token.find('/'));
        const auto res = std::from_chars(head.data(), head.data() + head.size(), idx);
        if (res.ec != std::errc() || res.ptr != head.data() + head.size() || idx == 0) throw bad("bad vertex index");
        const long long nv = static_cast<long long>(xyz.size() / 3);
        idx = idx > 0 ? idx - 1 : nv + idx;  // negative: relative to the vertices read so far
        poly.push_back(idx >= 0 && idx <= INT32_MAX ? static_cast<int>(idx) : -1);
      }
      if (poly.size() < 3) throw bad("face with fewer than 3 vertices");
      for (size_t k = 1; k + 1 < poly.size(); ++k) tri.insert(tri.end(), {poly[0], poly[k], poly[k + 1]});
    }  // vt, vn, g, o, s, l, usemtl, mtllib …: not geometry of a closed surface
  }
  TriangleMesh m;
  m.vertices = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(
      xyz.data(), static_cast<Eigen::Index>(xyz.size() / 3), 3);
  m.faces = Eigen::Map<const Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>>(
      tri.data(), static_cast<Eigen::Index>(tri.size() / 3), 3);
  return m;
}

// ---------------------------------------------------------------------------------------------------------------
// PLY (Stanford polygon format 1.0): ascii, binary_little_endian and binary_big_endian

namespace ply {

enum class Type { I8, U8, I16, U16, I32, U32, F32, F64 };

bool parseType(const std::string& s, Type& t) {
  static const std::pair<const char*, Type> names[] = {
      {"char", Type::I8},   {"int8", Type::I8},     {"uchar", Type::U8},   {"uint8", Type::U8},
      {"short", Type::I16}, {"int16", Type::I16},   {"ushort", Type::U16}, {"uint16", Type::U16},
      {"int", Type::I32},   {"int32", Type::I32},   {"uint", Type::U32},   {"uint32", Type::U32},
      {"float", Type::F32}, {"float32", Type::F32}, {"double", Type::F64}, {"float64", Type::F64}};
  for (const auto& [name, type] : names)
    if (s == name) {
      t = type;
      return true;
    }
  return false;
}

size_t sizeOf(Type t) {
  switch (t) {
    case Type::I8:
    case Type::U8:
      return 1;
    case Type::I16:
    case Type::U16:
      return 2;
    case Type::I32:
    case Type::U32:
    case Type::F32:
      return 4;
    case Type::F64:
      return 8;
  }
  return 0;
}

struct Property {
  std::string name;
  Type type = Type::F32;  ///< value type (item type for lists)
  bool isList = false;
  Type countType = Type::U8;  ///< list length type
};

struct Element {
  std::string name;
  size_t count = 0;
  std::vector<Property> properties;
};

enum class Encoding { Ascii, LittleEndian, BigEndian };

struct Header {
  Encoding encoding = Encoding::Ascii;
  std::vector<Element> elements;
  std::vector<std::string> comments;  ///< "comment" and "obj_info" lines, without the keyword
  size_t bodyStart = 0;               ///< byte offset just after "end_header\n"
};

/// Parses the header; IoError on anything malformed.
Header parseHeader(const std::string& bytes, const std::string& path) {
  Header h;
  const size_t end = bytes.find("end_header");
  if (!startsWith(bytes, "ply") || (bytes.size() > 3 && bytes[3] != '\n' && bytes[3] != '\r'))
    throw IoError(path, "not a PLY file (first line is not 'ply')");
  if (end == std::string::npos) throw IoError(path, "not a PLY file (no 'end_header')");
  const size_t eol = bytes.find('\n', end);
  if (eol == std::string::npos) throw IoError(path, "truncated PLY header");
  h.bodyStart = eol + 1;
  const std::vector<std::string> lines = splitLines(bytes.substr(0, end));
  bool haveFormat = false;
  for (size_t i = 1; i < lines.size(); ++i) {
    std::istringstream in(lines[i]);
    std::string word;
    in >> word;
    if (word.empty()) continue;
    if (word == "comment" || word == "obj_info") {
      h.comments.push_back(lines[i].substr(std::min(lines[i].size(), word.size() + 1)));
    } else if (word == "format") {
      std::string enc, version;
      in >> enc >> version;
      if (enc == "ascii")
        h.encoding = Encoding::Ascii;
      else if (enc == "binary_little_endian")
        h.encoding = Encoding::LittleEndian;
      else if (enc == "binary_big_endian")
        h.encoding = Encoding::BigEndian;
      else
        throw IoError(path, "unknown PLY format '" + enc + "'");
      haveFormat = true;
    } else if (word == "element") {
      Element e;
      long long count = -1;
      in >> e.name >> count;
      if (!in || count < 0) throw IoError(path, "bad PLY element line '" + lines[i] + "'");
      e.count = static_cast<size_t>(count);
      h.elements.push_back(e);
    } else if (word == "property") {
      if (h.elements.empty()) throw IoError(path, "PLY property before any element");
      Property p;
      std::string t;
      in >> t;
      if (t == "list") {
        std::string ct, it;
        in >> ct >> it >> p.name;
        p.isList = true;
        if (!parseType(ct, p.countType) || !parseType(it, p.type) || p.countType == Type::F32 ||
            p.countType == Type::F64)
          throw IoError(path, "bad PLY list property '" + lines[i] + "'");
      } else {
        in >> p.name;
        if (!parseType(t, p.type)) throw IoError(path, "unknown PLY property type in '" + lines[i] + "'");
      }
      if (p.name.empty()) throw IoError(path, "PLY property without a name");
      h.elements.back().properties.push_back(p);
    } else {
      throw IoError(path, "unknown PLY header line '" + lines[i] + "'");
    }
  }
  if (!haveFormat) throw IoError(path, "PLY header has no format line");
  return h;
}

/// Reads values one by one from the body, with bounds checks; IoError at a premature end or bad number.
class Reader {
 public:
  Reader(const std::string& bytes, size_t pos, Encoding enc, const std::string& path)
      : bytes_(bytes), pos_(pos), enc_(enc), path_(path) {}

  double next(Type t) {
    if (enc_ == Encoding::Ascii) return nextText();
    const size_t n = sizeOf(t);
    if (pos_ + n > bytes_.size()) throw IoError(path_, "PLY data ends prematurely (truncated file)");
    unsigned char b[8];
    std::memcpy(b, bytes_.data() + pos_, n);
    pos_ += n;
    const bool fileLittle = enc_ == Encoding::LittleEndian;
    if (fileLittle != hostLittle()) std::reverse(b, b + n);
    switch (t) {
      case Type::I8:
        return static_cast<double>(static_cast<int8_t>(b[0]));
      case Type::U8:
        return static_cast<double>(b[0]);
      case Type::I16:
        return as<int16_t>(b);
      case Type::U16:
        return as<uint16_t>(b);
      case Type::I32:
        return as<int32_t>(b);
      case Type::U32:
        return as<uint32_t>(b);
      case Type::F32:
        return as<float>(b);
      case Type::F64:
        return as<double>(b);
    }
    return 0;
  }
  /// Bytes (binary) or characters (ASCII) left: an upper bound on how many values can follow.
  size_t remaining() const { return bytes_.size() - pos_; }

 private:
  static bool hostLittle() {
    const uint16_t one = 1;
    unsigned char c;
    std::memcpy(&c, &one, 1);
    return c == 1;
  }
  template <typename T>
  static double as(const unsigned char* b) {
    T v;
    std::memcpy(&v, b, sizeof v);
    return static_cast<double>(v);
  }
  double nextText() {
    while (pos_ < bytes_.size() && std::isspace(static_cast<unsigned char>(bytes_[pos_]))) ++pos_;
    size_t end = pos_;
    while (end < bytes_.size() && !std::isspace(static_cast<unsigned char>(bytes_[end]))) ++end;
    if (end == pos_) throw IoError(path_, "PLY data ends prematurely (truncated file)");
    double v = 0;
    const char* first = bytes_.data() + pos_;
    const auto res = std::from_chars(first + (*first == '+' ? 1 : 0), bytes_.data() + end, v);
    if (res.ec != std::errc() || res.ptr != bytes_.data() + end)
      throw IoError(path_, "bad number '" + bytes_.substr(pos_, std::min<size_t>(end - pos_, 40)) + "' in PLY data");
    pos_ = end;
    return v;
  }

  const std::string& bytes_;
  size_t pos_;
  Encoding enc_;
  const std::string& path_;
};

/// Vertex properties that are not scalar point data: coordinates and normals (which would need the frame change).
bool isGeometryProperty(const std::string& name) {
  return name == "x" || name == "y" || name == "z" || name == "nx" || name == "ny" || name == "nz";
}

/// Reads element "vertex" (x, y, z and any other scalar properties as point data) and element "face"
/// (list "vertex_indices" or "vertex_index"; polygons are fan-triangulated). Other elements are skipped.
TriangleMesh read(const std::string& path, MeshSpace& space, bool& tagged) {
  const std::string bytes = readBytes(path);
  const Header h = parseHeader(bytes, path);
  for (const std::string& c : h.comments)
    if (!tagged) tagged = findSpaceToken(c, path, space);
  Reader r(bytes, h.bodyStart, h.encoding, path);
  TriangleMesh m;
  std::vector<std::vector<int>> polygons;
  bool haveVertex = false, haveFace = false;
  for (const Element& e : h.elements) {
    if (!e.properties.empty() && e.count > r.remaining())
      throw IoError(path, "PLY element '" + e.name + "' count exceeds the file size");
    const bool isVertex = e.name == "vertex", isFace = e.name == "face";
    int xyz[3] = {-1, -1, -1}, indexProp = -1;
    if (isVertex) {
      haveVertex = true;
      for (size_t p = 0; p < e.properties.size(); ++p) {
        const Property& prop = e.properties[p];
        if (prop.isList) continue;
        if (prop.name == "x")
          xyz[0] = static_cast<int>(p);
        else if (prop.name == "y")
          xyz[1] = static_cast<int>(p);
        else if (prop.name == "z")
          xyz[2] = static_cast<int>(p);
        else if (!isGeometryProperty(prop.name))
          m.pointData[prop.name] = Eigen::VectorXd(static_cast<Eigen::Index>(e.count));
      }
      if (xyz[0] < 0 || xyz[1] < 0 || xyz[2] < 0) throw IoError(path, "PLY vertex element lacks x, y or z");
      if (e.count > static_cast<size_t>(INT32_MAX)) throw IoError(path, "too many PLY vertices");
      m.vertices.resize(static_cast<Eigen::Index>(e.count), 3);
    }
    if (isFace) {
      haveFace = true;
      for (size_t p = 0; p < e.properties.size(); ++p)
        if (e.properties[p].isList &&
            (e.properties[p].name == "vertex_indices" || e.properties[p].name == "vertex_index"))
          indexProp = static_cast<int>(p);
      if (indexProp < 0) throw IoError(path, "PLY face element has no vertex_indices list");
      polygons.reserve(e.count);
    }
    for (size_t row = 0; row < e.count; ++row) {
      for (size_t p = 0; p < e.properties.size(); ++p) {
        const Property& prop = e.properties[p];
        if (prop.isList) {
          const double n = r.next(prop.countType);
          if (!(n >= 0) || n != std::floor(n) || n > static_cast<double>(r.remaining()))
            throw IoError(path, "bad PLY list length");
          std::vector<int> items(static_cast<size_t>(n));
          for (int& it : items) {
            const double v = r.next(prop.type);
            it = (v >= 0 && v <= INT32_MAX && v == std::floor(v)) ? static_cast<int>(v) : -1;
          }
          if (isFace && static_cast<int>(p) == indexProp) polygons.push_back(std::move(items));
          continue;
        }
        const double v = r.next(prop.type);
        if (!isVertex) continue;
        const Eigen::Index i = static_cast<Eigen::Index>(row);
        if (static_cast<int>(p) == xyz[0])
          m.vertices(i, 0) = v;
        else if (static_cast<int>(p) == xyz[1])
          m.vertices(i, 1) = v;
        else if (static_cast<int>(p) == xyz[2])
          m.vertices(i, 2) = v;
        else if (auto it = m.pointData.find(prop.name); it != m.pointData.end())
          it->second[i] = v;
      }
    }
  }
  if (!haveVertex || !haveFace) throw IoError(path, "PLY file lacks a vertex or face element (empty mesh)");
  size_t triangles = 0;
  for (const auto& poly : polygons) {
    if (poly.size() < 3) throw IoError(path, "PLY face with fewer than 3 vertices");
    triangles += poly.size() - 2;
  }
  m.faces.resize(static_cast<Eigen::Index>(triangles), 3);
  Eigen::Index f = 0;
  for (const auto& poly : polygons)
    for (size_t k = 1; k + 1 < poly.size(); ++k) m.faces.row(f++) << poly[0], poly[k], poly[k + 1];
  return m;
}

/// PLY property name for a point array (whitespace is not allowed in PLY names).
std::string propertyName(const std::string& name) {
  std::string s = name;
  for (char& c : s)
    if (std::isspace(static_cast<unsigned char>(c))) c = '_';
  return s;
}

void appendLittle(std::string& out, const void* value, size_t n) {
  unsigned char b[8];
  std::memcpy(b, value, n);
  const uint16_t one = 1;
  unsigned char first;
  std::memcpy(&first, &one, 1);
  if (first != 1) std::reverse(b, b + n);
  out.append(reinterpret_cast<const char*>(b), n);
}

/// Binary little-endian PLY: double x, y, z and one double property per point array; int32 index lists.
void write(const std::string& file, const std::string& path, const TriangleMesh& m, MeshSpace space) {
  std::vector<std::pair<std::string, const Eigen::VectorXd*>> arrays;
  for (const auto& [name, values] : m.pointData) {
    const std::string prop = propertyName(name);
    if (prop.empty() || isGeometryProperty(prop))
      throw IoError(path, "point array name '" + name + "' cannot be stored as a PLY vertex property");
    for (const auto& a : arrays)
      if (a.first == prop) throw IoError(path, "two point arrays map to the PLY property '" + prop + "'");
    arrays.emplace_back(prop, &values);
  }
  std::string out = "ply\nformat binary_little_endian 1.0\ncomment mskseg triangle mesh (mm)\ncomment " +
                    tagText(space) + "\nelement vertex " + std::to_string(m.vertexCount()) +
                    "\nproperty double x\nproperty double y\nproperty double z\n";
  for (const auto& a : arrays) out += "property double " + a.first + "\n";
  out += "element face " + std::to_string(m.faceCount()) + "\nproperty list uchar int vertex_indices\nend_header\n";
  out.reserve(out.size() + static_cast<size_t>(m.vertexCount()) * 8 * (3 + arrays.size()) +
              static_cast<size_t>(m.faceCount()) * 13);
  for (int i = 0; i < m.vertexCount(); ++i) {
    for (int c = 0; c < 3; ++c) {
      const double v = m.vertices(i, c);
      appendLittle(out, &v, 8);
    }
    for (const auto& a : arrays) {
      const double v = (*a.second)[i];
      appendLittle(out, &v, 8);
    }
  }
  for (int f = 0; f < m.faceCount(); ++f) {
    out += static_cast<char>(3);
    for (int c = 0; c < 3; ++c) {
      const int32_t v = m.faces(f, c);
      appendLittle(out, &v, 4);
    }
  }
  writeBytes(file, path, out);
}

}  // namespace ply

}  // namespace

const char* meshSpaceName(MeshSpace s) { return s == MeshSpace::LPS ? "LPS" : "RAS"; }

MeshSpace parseMeshSpace(const std::string& text) {
  std::string t(text);
  std::transform(t.begin(), t.end(), t.begin(), [](unsigned char c) { return std::tolower(c); });
  if (t == "lps") return MeshSpace::LPS;
  if (t == "ras") return MeshSpace::RAS;
  throw ParameterError("mesh space", text, "expected LPS or RAS");
}

bool isMeshFile(const std::string& path) { return formatOf(path) != Format::Unknown; }

TriangleMesh readMesh(const std::string& path, MeshSpace* fileSpace) {
  const Format format = formatOf(path);
  if (format == Format::Unknown) throw unsupported(path);
  std::error_code ec;
  if (!fs::exists(path, ec)) throw IoError(path, "file does not exist");
  if (!fs::is_regular_file(path, ec)) throw IoError(path, "not a regular file");

  VtkQuiet quiet;
  MeshSpace space = MeshSpace::LPS;  // untagged files are LPS
  bool tagged = false;
  TriangleMesh mesh;
  try {
    vtkSmartPointer<vtkPolyData> pd;
    switch (format) {
      case Format::Vtk:
        tagged = legacySpace(path, space);
        mesh = legacy::Parser(readBytes(path), path).parse();
        break;
      case Format::Vtp: {
        vtkNew<vtkXMLPolyDataReader> r;
        r->SetFileName(path.c_str());
        pd = runReader(r, path, "VTK XML polydata");
        tagged = vtpSpace(path, pd, space);
        pd = triangulate(pd, false);
        break;
      }
      case Format::Stl: {
        tagged = stlSpace(path, space);
        vtkNew<vtkSTLReader> r;
        r->SetFileName(path.c_str());
        r->MergingOn();
        // STL stores each face's corners: merge them so the surface is closed.
        pd = triangulate(runReader(r, path, "STL"), true);
        break;
      }
      case Format::Obj:
        tagged = objSpace(path, space);
        mesh = readObj(path);
        break;
      case Format::Ply:
        mesh = ply::read(path, space, tagged);
        break;
      case Format::Unknown:
        break;
    }
    if (pd) mesh = toMesh(pd, path);
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {  // e.g. std::bad_alloc from a garbage count inside VTK
    throw IoError(path, std::string("cannot read the file: ") + e.what());
  }

  dropUnusedVertices(mesh);
  if (mesh.vertexCount() > 0 && !mesh.vertices.allFinite())
    throw IoError(path, "vertex coordinates are not finite (NaN or infinity)");
  const std::string problem = closedMeshProblem(mesh);
  if (!problem.empty()) throw IoError(path, "not a closed triangle surface: " + problem);
  if (space == MeshSpace::LPS) transformMesh(mesh, rasLpsFlip());
  if (fileSpace) *fileSpace = space;
  return mesh;
}

void writeMesh(const std::string& path, const TriangleMesh& rasMesh, MeshSpace space) {
  const Format format = formatOf(path);
  if (format == Format::Unknown) throw unsupported(path);
  const std::string problem = closedMeshProblem(rasMesh);
  if (!problem.empty()) throw IoError(path, "refusing to write an invalid mesh: " + problem);
  TriangleMesh m = rasMesh;
  if (space == MeshSpace::LPS) transformMesh(m, rasLpsFlip());
  const std::string header = "mskseg triangle mesh (mm) " + tagText(space);

  writeAtomically(path, [&](const std::string& tmp) {
    VtkQuiet quiet;
    int ok = 1;
    switch (format) {
      case Format::Vtk: {
        vtkNew<vtkPolyDataWriter> w;
        w->SetInputData(toPolyData(m, true, path));
        w->SetFileName(tmp.c_str());
        w->SetFileVersion(vtkPolyDataWriter::VTK_LEGACY_READER_VERSION_4_2);  // 5.1 is refused by older readers
        w->SetFileTypeToBinary();
        w->SetHeader(header.c_str());
        ok = w->Write() && w->GetErrorCode() == 0;
        break;
      }
      case Format::Vtp: {
        vtkSmartPointer<vtkPolyData> pd = toPolyData(m, true, path);
        vtkNew<vtkStringArray> s;
        s->SetName("SPACE");
        s->InsertNextValue(meshSpaceName(space));
        pd->GetFieldData()->AddArray(s);
        vtkNew<vtkXMLPolyDataWriter> w;
        w->SetInputData(pd);
        w->SetFileName(tmp.c_str());
        ok = w->Write() && w->GetErrorCode() == 0;
        break;
      }
      case Format::Stl: {
        vtkNew<vtkSTLWriter> w;
        w->SetInputData(toPolyData(m, false, path));
        w->SetFileName(tmp.c_str());
        w->SetFileTypeToBinary();
        w->SetHeader(header.c_str());
        ok = w->Write() && w->GetErrorCode() == 0;
        break;
      }
      case Format::Obj:
        writeObj(tmp, path, m, space);
        break;
      case Format::Ply:
        ply::write(tmp, path, m, space);
        break;
      case Format::Unknown:
        break;
    }
    if (!ok) throw IoError(path, "VTK could not write the file");
  });
}

}  // namespace msk
