// VTK legacy polydata (.vtk): read here (versions 2.0 to 5.1, ASCII and BINARY), written by VTK (4.2, binary).
// Own reader: VTK 9.1's vtkPolyDataReader crashes on truncated files and accepts truncated arrays uninitialised.
#include <vtkNew.h>
#include <vtkPolyDataWriter.h>

#include <cmath>
#include <cstdlib>
#include <map>

#include "mesh_io_detail.h"
#include "vtk_mesh.h"

namespace msk::detail {

namespace {

/// A VTK legacy data type: a number of a BinaryType, bits, strings, or a type this reader does not know.
struct ValueType {
  enum Kind { Number, Bit, String, Unsupported } kind = Unsupported;
  BinaryType number = BinaryType::U8;  ///< the number's type, with kind Number
};

ValueType numberType(BinaryType t) { return {ValueType::Number, t}; }

ValueType parseValueType(const std::string& text) {
  const std::string t = lowercase(text);
  if (t == "bit") return {ValueType::Bit};
  if (t == "char" || t == "signed_char") return numberType(BinaryType::I8);
  if (t == "unsigned_char") return numberType(BinaryType::U8);
  if (t == "short") return numberType(BinaryType::I16);
  if (t == "unsigned_short") return numberType(BinaryType::U16);
  if (t == "int") return numberType(BinaryType::I32);
  if (t == "unsigned_int") return numberType(BinaryType::U32);
  if (t == "long" || t == "vtktypeint64" || t == "vtkidtype") return numberType(BinaryType::I64);
  if (t == "unsigned_long" || t == "vtktypeuint64") return numberType(BinaryType::U64);
  if (t == "float") return numberType(BinaryType::F32);
  if (t == "double") return numberType(BinaryType::F64);
  if (t == "string" || t == "utf8_string") return {ValueType::String};
  return {ValueType::Unsupported};
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

/// One pass over the file bytes; every count is checked against the bytes present and every read is bounds-checked,
/// throwing IoError naming the file.
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
    const std::string format = lowercase(trim(line()));
    if (format == "binary")
      binary_ = true;
    else if (format != "ascii")
      fail("third line must be ASCII or BINARY, not '" + format + "'");
    if (lowercase(word()) != "dataset") fail("no DATASET line");
    const std::string kind = word();
    if (lowercase(kind) != "polydata") fail("dataset type is " + kind + ", not POLYDATA");

    TriangleMesh m;
    long long numPoints = -1;
    std::vector<int> tris;
    for (std::string key = lowercase(word()); !key.empty(); key = lowercase(word())) {
      if (key == "field") {
        readField(nullptr, 0);
      } else if (key == "points") {
        numPoints = count("number of points");
        const std::vector<double> xyz = numbers(parseValueType(word()), 3 * static_cast<size_t>(numPoints), "POINTS");
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
    if (t.kind == ValueType::Unsupported) fail("unsupported data type");
    std::vector<double> out;
    if (n == 0) return out;
    if (n > b_.size()) fail("array larger than the file");
    if (t.kind == ValueType::String) {
      skipStrings(n);
    } else if (!binary_) {
      out.resize(n);
      for (double& v : out) {
        const std::string w = word();
        if (w.empty()) fail("file ends inside a data array (truncated)");
        if (!parseNumber(w.data(), w.data() + w.size(), v)) fail("bad number '" + w.substr(0, 40) + "'");
      }
    } else {
      nextLine();
      out.resize(n);
      if (t.kind == ValueType::Bit) {
        need((n + 7) / 8);
        for (size_t i = 0; i < n; ++i) out[i] = (static_cast<unsigned char>(b_[pos_ + i / 8]) >> (7 - i % 8)) & 1;
        pos_ += (n + 7) / 8;
      } else {
        const size_t size = binarySize(t.number);
        need(n * size);
        for (size_t i = 0; i < n; ++i, pos_ += size) out[i] = decodeBinary(t.number, b_.data() + pos_, true);
      }
    }
    skipOptionalMetadata();
    return out;
  }
  /// `values` for an array that must hold numbers (coordinates, offsets, indices): a string array is refused.
  std::vector<double> numbers(ValueType t, size_t n, const char* what) {
    if (t.kind == ValueType::String) fail(std::string(what) + " of type string");
    return values(t, n);
  }
  void need(size_t bytes) const {
    if (bytes > b_.size() - pos_) fail("file ends inside a binary data block (truncated)");
  }
  void nextLine() {
    const size_t end = b_.find('\n', pos_);
    pos_ = end == std::string::npos ? b_.size() : end + 1;
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
    if (lowercase(word()) != "metadata") {
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
      if (lowercase(word()) != "offsets") fail("OFFSETS expected in " + key);
      const std::vector<double> offsets = numbers(parseValueType(word()), static_cast<size_t>(a), "OFFSETS");
      if (lowercase(word()) != "connectivity") fail("CONNECTIVITY expected in " + key);
      const std::vector<double> conn = numbers(parseValueType(word()), static_cast<size_t>(b), "CONNECTIVITY");
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
      const std::vector<double> raw = values(numberType(BinaryType::I32), static_cast<size_t>(b));
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
      if (keep && comps == 1 && rows == tuples && t.kind != ValueType::String)
        (*keep)[decodeName(name)] = Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
    }
  }
  /// POINT_DATA / CELL_DATA sections to the end of the file; 1-component numeric point arrays are kept.
  void readAttributes(std::string key, long long numPoints, TriangleMesh& m) {
    long long n = count("attribute count");
    bool onPoints = key == "point_data";
    if (onPoints && n != numPoints) fail("POINT_DATA count differs from the number of points");
    for (key = lowercase(word()); !key.empty(); key = lowercase(word())) {
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
        if (lowercase(next) != "lookup_table") {
          comps = std::atoll(next.c_str());
          if (comps < 1 || comps > 4) fail("bad SCALARS component count '" + next + "'");
          next = word();
        }
        if (lowercase(next) != "lookup_table") fail("SCALARS without LOOKUP_TABLE");
        word();  // table name
        const std::vector<double> v = values(t, static_cast<size_t>(n * comps));
        if (keep && comps == 1 && t.kind != ValueType::String)
          (*keep)[name] = Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
      } else if (key == "color_scalars") {
        word();
        const long long comps = count("component count");
        values(numberType(binary_ ? BinaryType::U8 : BinaryType::F32), static_cast<size_t>(n * comps));
      } else if (key == "lookup_table") {
        word();
        const long long size = count("lookup table size");
        values(numberType(binary_ ? BinaryType::U8 : BinaryType::F32), static_cast<size_t>(size * 4));
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

/// Space tag from the title line (2nd line) of the file's leading bytes `head`; also checks the magic line.
bool legacySpace(const std::string& head, const std::string& path, MeshSpace& out) {
  const std::vector<std::string> lines = splitLines(head);
  if (lines.empty() || !startsWith(lines[0], "# vtk DataFile Version"))
    throw IoError(path, "not a VTK legacy file (first line is not '# vtk DataFile Version x.y')");
  return lines.size() > 1 && findSpaceToken(lines[1], path, out);
}

}  // namespace

TriangleMesh readVtkLegacy(const std::string& path, MeshSpace& space) {
  std::string bytes = readBytes(path);
  legacySpace(bytes.substr(0, 1024), path, space);
  return Parser(std::move(bytes), path).parse();
}

void writeVtkLegacy(const std::string& file, const std::string& path, const TriangleMesh& m, MeshSpace space) {
  VtkQuiet quiet;
  const vtkSmartPointer<vtkPolyData> pd = toPolyData(m);
  addPointArrays(pd, m, path);
  const std::string header = headerText(space);
  vtkNew<vtkPolyDataWriter> w;
  w->SetInputData(pd);
  w->SetFileName(file.c_str());
  w->SetFileVersion(vtkPolyDataWriter::VTK_LEGACY_READER_VERSION_4_2);  // 5.1 is refused by older readers
  w->SetFileTypeToBinary();
  w->SetHeader(header.c_str());
  if (!(w->Write() && w->GetErrorCode() == 0)) throw IoError(path, "VTK could not write the file");
}

}  // namespace msk::detail
