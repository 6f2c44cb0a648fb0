// Mending nearly closed surfaces: duplicate vertices merged (our own exact-position merge, which keeps the per-vertex
// arrays in step), small holes filled with CGAL's hole triangulation.
#include "msk/imaging/mesh_repair.h"

#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>

#include <algorithm>
#include <array>
#include <iterator>
#include <map>
#include <set>
#include <vector>

#include "msk/core/error.h"
#include "msk/imaging/detail/cgal_mesh.h"

namespace msk {

namespace {

/// Merges vertices at exactly the same position and drops the faces left degenerate or duplicated, then the vertices
/// no face uses; per-vertex arrays follow.
void mergeDuplicates(TriangleMesh& m, MeshMending& done) {
  const int nv = m.vertexCount();
  std::map<std::array<double, 3>, int> first;
  std::vector<int> target(static_cast<size_t>(nv));
  for (int v = 0; v < nv; ++v) {
    const std::array<double, 3> key = {m.vertices(v, 0), m.vertices(v, 1), m.vertices(v, 2)};
    const auto [it, fresh] = first.emplace(key, v);
    target[static_cast<size_t>(v)] = it->second;
    done.mergedVertices += fresh ? 0 : 1;
  }
  std::set<std::array<int, 3>> seen;
  std::vector<std::array<int, 3>> faces;
  for (int f = 0; f < m.faceCount(); ++f) {
    std::array<int, 3> t;
    for (int k = 0; k < 3; ++k) {
      const int v = m.faces(f, k);
      t[static_cast<size_t>(k)] = v >= 0 && v < nv ? target[static_cast<size_t>(v)] : v;
    }
    std::array<int, 3> sorted = t;
    std::sort(sorted.begin(), sorted.end());
    if (sorted[0] == sorted[1] || sorted[1] == sorted[2] || !seen.insert(sorted).second) {
      ++done.droppedFaces;
      continue;
    }
    faces.push_back(t);
  }
  if (done.mergedVertices == 0 && done.droppedFaces == 0) return;
  // Renumber the vertices still used, in their order.
  std::vector<int> index(static_cast<size_t>(nv), -1);
  for (const auto& t : faces)
    for (int v : t)
      if (v >= 0 && v < nv) index[static_cast<size_t>(v)] = 0;
  int next = 0;
  for (int& i : index) i = i == 0 ? next++ : -1;
  Points vertices(next, 3);
  for (int v = 0; v < nv; ++v)
    if (index[static_cast<size_t>(v)] >= 0) vertices.row(index[static_cast<size_t>(v)]) = m.vertices.row(v);
  for (auto& entry : m.pointData) {
    Eigen::VectorXd& values = entry.second;
    if (values.size() != nv) continue;
    Eigen::VectorXd kept(next);
    for (int v = 0; v < nv; ++v)
      if (index[static_cast<size_t>(v)] >= 0) kept[index[static_cast<size_t>(v)]] = values[v];
    values = kept;
  }
  m.vertices = vertices;
  m.faces.resize(static_cast<Eigen::Index>(faces.size()), 3);
  for (size_t f = 0; f < faces.size(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int v = faces[f][static_cast<size_t>(k)];
      m.faces(static_cast<Eigen::Index>(f), k) = v >= 0 && v < nv ? index[static_cast<size_t>(v)] : v;
    }
}

/// Fills the small holes of `m` (see mendSurface()); leaves `m` alone if its faces do not form a manifold surface.
void fillSmallHoles(TriangleMesh& m, MeshMending& done) {
  if (m.vertexCount() == 0 || m.faceCount() == 0) return;
  for (int f = 0; f < m.faceCount(); ++f)
    for (int k = 0; k < 3; ++k)
      if (m.faces(f, k) < 0 || m.faces(f, k) >= m.vertexCount()) return;
  detail::CgalMesh cm;
  try {
    cm = detail::toCgalMesh(m, "mesh");
  } catch (const Error&) {
    return;  // not a manifold surface: nothing sound to fill
  }
  const double diagonal = (m.vertices.colwise().maxCoeff() - m.vertices.colwise().minCoeff()).norm();
  using Halfedge = detail::CgalMesh::Halfedge_index;
  std::set<Halfedge> visited;
  std::vector<std::pair<Halfedge, int>> small;
  for (Halfedge h : cm.halfedges()) {
    if (!cm.is_border(h) || visited.count(h)) continue;
    int edges = 0;
    double perimeter = 0;
    Halfedge g = h;
    do {
      visited.insert(g);
      ++edges;
      perimeter += std::sqrt(CGAL::squared_distance(cm.point(cm.source(g)), cm.point(cm.target(g))));
      g = cm.next(g);
    } while (g != h && edges <= m.faceCount() * 3);
    if (edges <= kMaxFilledHoleEdges && perimeter <= kMaxFilledHolePerimeterShare * diagonal)
      small.emplace_back(h, edges);
  }
  if (small.empty()) return;
  const int vertices = m.vertexCount();
  for (const auto& [h, edges] : small) {
    std::vector<detail::CgalMesh::Face_index> patch;
    CGAL::Polygon_mesh_processing::triangulate_hole(cm, h, std::back_inserter(patch));
    if (patch.empty()) continue;
    ++done.filledHoles;
    done.largestHoleEdges = std::max(done.largestHoleEdges, edges);
  }
  if (done.filledHoles == 0) return;
  TriangleMesh filled = detail::fromCgalMesh(cm);
  if (filled.vertexCount() != vertices) return;  // the triangulation added vertices: keep the holes
  m.faces = filled.faces;
}

}  // namespace

std::string MeshMending::summary() const {
  std::string s;
  if (mergedVertices > 0) s += "merged " + std::to_string(mergedVertices) + " duplicate vertices";
  if (droppedFaces > 0)
    s += std::string(s.empty() ? "" : ", ") + "dropped " + std::to_string(droppedFaces) +
         " degenerate or repeated faces";
  if (filledHoles > 0)
    s += std::string(s.empty() ? "" : ", ") + "filled " + std::to_string(filledHoles) + " hole(s) of up to " +
         std::to_string(largestHoleEdges) + " edges";
  return s;
}

MeshMending mendSurface(TriangleMesh& mesh) {
  MeshMending done;
  mergeDuplicates(mesh, done);
  fillSmallHoles(mesh, done);
  return done;
}

}  // namespace msk
