// Wavefront OBJ (.obj), read and written here: geometry only, the SPACE tag in a comment, full double precision.
// Own reader and writer: VTK 9.1's vtkOBJReader renumbers vertices and both it and vtkOBJWriter use float32.
#include <sstream>

#include "mesh_io_detail.h"

namespace msk::detail {

namespace {

/// Space tag from the OBJ comment lines in the file's leading bytes `head`.
bool objSpace(const std::string& head, const std::string& path, MeshSpace& out) {
  for (const std::string& line : splitLines(head)) {
    const size_t first = line.find_first_not_of(" \t");
    if (first != std::string::npos && line[first] == '#' && findSpaceToken(line.substr(first + 1), path, out))
      return true;
  }
  return false;
}

/// Shortest text that reads back as exactly `v` (locale-independent).
void appendNumber(std::string& out, double v) {
  char buf[32];
  const auto res = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, res.ptr);
}

}  // namespace

// Reads "v x y z" and "f a b c …" records (1-based or negative indices; "a/t/n" forms use the position index
// only, so texture seams do not split vertices; polygons are fan-triangulated). Vertex order is kept.
TriangleMesh readObj(const std::string& path, MeshSpace& space) {
  const std::string text = readBytes(path);
  objSpace(text.substr(0, kHeadBytes), path, space);
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
        if (!parseNumber(token.data(), token.data() + token.size(), v)) throw bad("bad number");
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

void writeObj(const std::string& file, const std::string& path, const TriangleMesh& m, MeshSpace space) {
  std::string out = "# " + std::string(kMeshTitle) + "\n# " + tagText(space) + "\n";
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

}  // namespace msk::detail
