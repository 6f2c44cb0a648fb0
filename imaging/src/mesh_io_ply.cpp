// PLY (.ply, Stanford polygon format 1.0), read and written here: ascii, binary_little_endian and binary_big_endian
// in, binary little-endian out with double coordinates and one double property per point array.
// Own reader and writer: VTK 9.1's PLY reader crashes on truncated files and drops properties, its writer uses float32.
#include <cmath>
#include <sstream>

#include "mesh_io_detail.h"

namespace msk::detail {

namespace {

using Type = BinaryType;  // PLY names the 8- to 32-bit integers and both float sizes

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
    const size_t n = binarySize(t);
    if (pos_ + n > bytes_.size()) throw IoError(path_, "PLY data ends prematurely (truncated file)");
    const double v = decodeBinary(t, bytes_.data() + pos_, enc_ == Encoding::BigEndian);
    pos_ += n;
    return v;
  }
  /// Bytes (binary) or characters (ASCII) left: an upper bound on how many values can follow.
  size_t remaining() const { return bytes_.size() - pos_; }

 private:
  double nextText() {
    while (pos_ < bytes_.size() && std::isspace(static_cast<unsigned char>(bytes_[pos_]))) ++pos_;
    size_t end = pos_;
    while (end < bytes_.size() && !std::isspace(static_cast<unsigned char>(bytes_[end]))) ++end;
    if (end == pos_) throw IoError(path_, "PLY data ends prematurely (truncated file)");
    double v = 0;
    if (!parseNumber(bytes_.data() + pos_, bytes_.data() + end, v))
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

/// PLY property name for a point array (whitespace is not allowed in PLY names).
std::string propertyName(const std::string& name) {
  std::string s = name;
  for (char& c : s)
    if (std::isspace(static_cast<unsigned char>(c))) c = '_';
  return s;
}

/// Appends the `n` bytes at `value` (host order) to `out` in little-endian order.
void appendLittle(std::string& out, const void* value, size_t n) {
  unsigned char b[8];
  std::memcpy(b, value, n);
  if (!hostIsLittleEndian()) std::reverse(b, b + n);
  out.append(reinterpret_cast<const char*>(b), n);
}

}  // namespace

// Reads element "vertex" (x, y, z and any other scalar properties as point data) and element "face"
// (list "vertex_indices" or "vertex_index"; polygons are fan-triangulated). Other elements are skipped.
TriangleMesh readPly(const std::string& path, MeshSpace& space) {
  const std::string bytes = readBytes(path);
  const Header h = parseHeader(bytes, path);
  bool tagged = false;
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

// Binary little-endian: double x, y, z and one double property per point array; int32 index lists.
void writePly(const std::string& file, const std::string& path, const TriangleMesh& m, MeshSpace space) {
  std::vector<std::pair<std::string, const Eigen::VectorXd*>> arrays;
  for (const auto& [name, values] : m.pointData) {
    const std::string prop = propertyName(name);
    if (prop.empty() || isGeometryProperty(prop))
      throw IoError(path, "point array name '" + name + "' cannot be stored as a PLY vertex property");
    for (const auto& a : arrays)
      if (a.first == prop) throw IoError(path, "two point arrays map to the PLY property '" + prop + "'");
    arrays.emplace_back(prop, &values);
  }
  std::string out = "ply\nformat binary_little_endian 1.0\ncomment " + std::string(kMeshTitle) + "\ncomment " +
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

}  // namespace msk::detail
