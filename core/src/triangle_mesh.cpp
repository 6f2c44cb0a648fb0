#include "msk/core/triangle_mesh.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <vector>

namespace msk {

namespace {
inline long long edgeKey(int a, int b) { return (static_cast<long long>(a) << 32) | static_cast<unsigned>(b); }
}  // namespace

std::string closedMeshProblem(const TriangleMesh& m) {
  const int nv = m.vertexCount(), nf = m.faceCount();
  if (nv == 0 || nf == 0) return "empty mesh (" + std::to_string(nv) + " vertices, " + std::to_string(nf) + " faces)";
  if (nf < 4) return "too few faces for a closed surface (" + std::to_string(nf) + ")";
  if (!m.vertices.allFinite()) return "non-finite vertex coordinates";
  for (const auto& kv : m.pointData)
    if (kv.second.size() != nv)
      return "point array '" + kv.first + "' has " + std::to_string(kv.second.size()) + " values for " +
             std::to_string(nv) + " vertices";
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = m.faces(f, k), b = m.faces(f, (k + 1) % 3);
      if (a < 0 || a >= nv || b < 0 || b >= nv) return "face " + std::to_string(f) + " has a vertex index out of range";
      if (a == b) return "face " + std::to_string(f) + " is degenerate (repeated vertex)";
    }
  // A closed oriented manifold has each directed edge once and its reverse once. The directed edges are listed by
  // their first vertex, each list sorted by second vertex then edge (3 × face + corner), so that each check reads a few
  // neighbouring entries (a hash of all edges costs a cache miss per edge on large meshes) and a vertex shared by
  // very many faces costs a sort, not a scan per edge.
  const size_t ne = static_cast<size_t>(nf) * 3;
  std::vector<int> start(static_cast<size_t>(nv) + 1, 0);
  std::vector<std::pair<int, int>> out(ne);  // (second vertex, edge)
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) ++start[static_cast<size_t>(m.faces(f, k)) + 1];
  for (size_t v = 0; v < static_cast<size_t>(nv); ++v) start[v + 1] += start[v];
  {
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (int f = 0; f < nf; ++f)
      for (int k = 0; k < 3; ++k)
        out[static_cast<size_t>(fill[static_cast<size_t>(m.faces(f, k))]++)] = {m.faces(f, (k + 1) % 3), 3 * f + k};
  }
  for (size_t v = 0; v < static_cast<size_t>(nv); ++v) std::sort(out.begin() + start[v], out.begin() + start[v + 1]);
  auto edgeName = [&](int e) {
    return std::to_string(m.faces(e / 3, e % 3)) + "-" + std::to_string(m.faces(e / 3, (e % 3 + 1) % 3));
  };
  // The repeat reported is the first one made, in face order (a repeated edge's second use).
  int repeat = -1;
  for (size_t v = 0; v < static_cast<size_t>(nv); ++v)
    for (int j = start[v] + 1; j < start[v + 1]; ++j) {
      const auto& here = out[static_cast<size_t>(j)];
      if (here.first == out[static_cast<size_t>(j) - 1].first && (repeat < 0 || here.second < repeat))
        repeat = here.second;
    }
  if (repeat >= 0)
    return "edge " + edgeName(repeat) +
           " is used twice in the same direction (non-manifold or inconsistently oriented)";
  for (int e = 0; e < static_cast<int>(ne); ++e) {
    const int a = m.faces(e / 3, e % 3), b = m.faces(e / 3, (e % 3 + 1) % 3);
    const auto first = out.begin() + start[static_cast<size_t>(b)],
               last = out.begin() + start[static_cast<size_t>(b) + 1];
    const auto it = std::lower_bound(first, last, std::make_pair(a, -1));
    if (it == last || it->first != a) return "not closed: edge " + edgeName(e) + " belongs to only one face";
  }
  return "";
}

double enclosedVolume(const TriangleMesh& m) {
  double v = 0;
  for (int f = 0; f < m.faceCount(); ++f) {
    Eigen::Vector3d a = m.vertices.row(m.faces(f, 0)), b = m.vertices.row(m.faces(f, 1)),
                    c = m.vertices.row(m.faces(f, 2));
    v += a.dot(b.cross(c));
  }
  return v / 6.0;
}

double surfaceArea(const TriangleMesh& m) {
  double s = 0;
  for (int f = 0; f < m.faceCount(); ++f) {
    Eigen::Vector3d a = m.vertices.row(m.faces(f, 0)), b = m.vertices.row(m.faces(f, 1)),
                    c = m.vertices.row(m.faces(f, 2));
    s += 0.5 * (b - a).cross(c - a).norm();
  }
  return s;
}

Points faceNormals(const TriangleMesh& m) {
  Points n(m.faceCount(), 3);
  for (int f = 0; f < m.faceCount(); ++f) {
    Eigen::Vector3d a = m.vertices.row(m.faces(f, 0)), b = m.vertices.row(m.faces(f, 1)),
                    c = m.vertices.row(m.faces(f, 2));
    Eigen::Vector3d x = (b - a).cross(c - a);
    double len = x.norm();
    n.row(f) = len > 0 ? Eigen::Vector3d(x / len) : Eigen::Vector3d::Zero();
  }
  return n;
}

Points vertexNormals(const TriangleMesh& m) {
  Points n = Points::Zero(m.vertexCount(), 3);
  for (int f = 0; f < m.faceCount(); ++f) {
    Eigen::Vector3d a = m.vertices.row(m.faces(f, 0)), b = m.vertices.row(m.faces(f, 1)),
                    c = m.vertices.row(m.faces(f, 2));
    Eigen::Vector3d x = (b - a).cross(c - a);  // |x| = 2·area: area weighting
    for (int k = 0; k < 3; ++k) n.row(m.faces(f, k)) += x.transpose();
  }
  for (int i = 0; i < n.rows(); ++i) {
    double len = n.row(i).norm();
    if (len > 0) n.row(i) /= len;
  }
  return n;
}

double meanEdgeLength(const TriangleMesh& m) {
  if (m.faceCount() == 0) return 0;
  double s = 0;
  for (int f = 0; f < m.faceCount(); ++f)
    for (int k = 0; k < 3; ++k) s += (m.vertices.row(m.faces(f, k)) - m.vertices.row(m.faces(f, (k + 1) % 3))).norm();
  return s / (3.0 * m.faceCount());
}

double offsetToVolume(TriangleMesh& m, double volumeMm3, double limitMm) {
  double offset = 0;
  for (int pass = 0; pass < 2; ++pass) {
    const double area = surfaceArea(m);
    if (!(area > 0)) break;
    const double delta = std::clamp((volumeMm3 - enclosedVolume(m)) / area, -limitMm - offset, limitMm - offset);
    m.vertices += delta * vertexNormals(m);
    offset += delta;
  }
  return offset;
}

void flipFaces(TriangleMesh& m) { m.faces.col(1).swap(m.faces.col(2)); }

void transformMesh(TriangleMesh& m, const Eigen::Matrix4d& affine) {
  const Eigen::Matrix3d a = affine.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = affine.topRightCorner<3, 1>();
  for (int i = 0; i < m.vertexCount(); ++i) m.vertices.row(i) = (a * m.vertices.row(i).transpose() + t).transpose();
  if (a.determinant() < 0) flipFaces(m);
}

Eigen::Matrix4d rasLpsFlip() {
  Eigen::Matrix4d f = Eigen::Matrix4d::Identity();
  f(0, 0) = -1;
  f(1, 1) = -1;
  return f;
}

TriangleMesh makeIcosphere(double radius, int subdivisions, const Eigen::Vector3d& center) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Eigen::Vector3d> v = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                                    {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  std::vector<Eigen::Vector3i> f = {{0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                                    {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                                    {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (auto& p : v) p.normalize();
  for (int s = 0; s < subdivisions; ++s) {
    std::unordered_map<long long, int> mid;
    auto midpoint = [&](int a, int b) {
      long long key = a < b ? edgeKey(a, b) : edgeKey(b, a);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back((v[a] + v[b]).normalized());
      int id = static_cast<int>(v.size()) - 1;
      mid.emplace(key, id);
      return id;
    };
    std::vector<Eigen::Vector3i> nf;
    nf.reserve(f.size() * 4);
    for (const auto& tri : f) {
      int a = midpoint(tri[0], tri[1]), b = midpoint(tri[1], tri[2]), c = midpoint(tri[2], tri[0]);
      nf.push_back({tri[0], a, c});
      nf.push_back({tri[1], b, a});
      nf.push_back({tri[2], c, b});
      nf.push_back({a, b, c});
    }
    f.swap(nf);
  }
  TriangleMesh m;
  m.vertices.resize(static_cast<Eigen::Index>(v.size()), 3);
  for (size_t i = 0; i < v.size(); ++i)
    m.vertices.row(static_cast<Eigen::Index>(i)) = (center + radius * v[i]).transpose();
  m.faces.resize(static_cast<Eigen::Index>(f.size()), 3);
  for (size_t i = 0; i < f.size(); ++i) m.faces.row(static_cast<Eigen::Index>(i)) = f[i].transpose();
  if (enclosedVolume(m) < 0) flipFaces(m);
  return m;
}

}  // namespace msk
