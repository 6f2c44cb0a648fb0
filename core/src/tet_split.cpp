#include "msk/core/tet_split.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "msk/core/error.h"

namespace msk {

namespace {

using Vec3 = Eigen::Vector3d;
using Tet = std::array<int, 4>;

/// Local face j of a tet: the nodes other than j.
constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
/// Local edges of a tet.
constexpr int kEdge[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};

std::pair<int, int> edgeKey(int a, int b) { return a < b ? std::make_pair(a, b) : std::make_pair(b, a); }

std::array<int, 3> faceKey(int a, int b, int c) {
  std::array<int, 3> k = {a, b, c};
  std::sort(k.begin(), k.end());
  return k;
}

bool contains(const Tet& t, int v) { return t[0] == v || t[1] == v || t[2] == v || t[3] == v; }

/// t with node `from` replaced by `to` (same local slot, so the orientation is kept when `to` lies on the segment or
/// face that `from` is cut along).
Tet replaced(Tet t, int from, int to) {
  for (int& v : t)
    if (v == from) v = to;
  return t;
}

}  // namespace

std::vector<char> boundaryNodeMask(const TetMesh& mesh) {
  std::vector<char> on(static_cast<size_t>(mesh.nodeCount()), 0);
  const Triangles faces = tetBoundaryFaces(mesh);
  for (Eigen::Index f = 0; f < faces.rows(); ++f)
    for (int k = 0; k < 3; ++k) on[static_cast<size_t>(faces(f, k))] = 1;
  return on;
}

int boundaryOnlyTetCount(const TetMesh& mesh) {
  const std::vector<char> on = boundaryNodeMask(mesh);
  int n = 0;
  for (int t = 0; t < mesh.tetCount(); ++t) {
    bool all = true;
    for (int k = 0; k < 4; ++k) all = all && on[static_cast<size_t>(mesh.tets(t, k))];
    n += all ? 1 : 0;
  }
  return n;
}

TetMesh splitBoundaryTets(const TetMesh& mesh, int* added, BoundarySplit rule) {
  const std::string problem = tetMeshProblem(mesh);
  if (!problem.empty()) throw Error("splitBoundaryTets: invalid tet mesh: " + problem);
  const Triangles bfaces = tetBoundaryFaces(mesh);
  std::vector<char> onBoundary(static_cast<size_t>(mesh.nodeCount()), 0);
  std::set<std::pair<int, int>> boundaryEdges;
  std::set<std::array<int, 3>> boundaryFaces;
  for (Eigen::Index f = 0; f < bfaces.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      onBoundary[static_cast<size_t>(bfaces(f, k))] = 1;
      boundaryEdges.insert(edgeKey(bfaces(f, k), bfaces(f, (k + 1) % 3)));
    }
    boundaryFaces.insert(faceKey(bfaces(f, 0), bfaces(f, 1), bfaces(f, 2)));
  }

  std::vector<Vec3> nodes;
  nodes.reserve(static_cast<size_t>(mesh.nodeCount()));
  for (int i = 0; i < mesh.nodeCount(); ++i) nodes.push_back(mesh.nodes.row(i).transpose());
  std::vector<Tet> tets;
  tets.reserve(static_cast<size_t>(mesh.tetCount()));
  std::vector<std::vector<int>> incident(nodes.size());  // node → tets that use it
  for (int t = 0; t < mesh.tetCount(); ++t) {
    tets.push_back({mesh.tets(t, 0), mesh.tets(t, 1), mesh.tets(t, 2), mesh.tets(t, 3)});
    for (int k = 0; k < 4; ++k) incident[static_cast<size_t>(mesh.tets(t, k))].push_back(t);
  }
  auto boundaryOnly = [&](const Tet& t) {
    for (int v : t)
      if (v >= static_cast<int>(onBoundary.size()) || !onBoundary[static_cast<size_t>(v)]) return false;
    return true;
  };
  auto addTet = [&](const Tet& t) {
    tets.push_back(t);
    for (int v : t) incident[static_cast<size_t>(v)].push_back(static_cast<int>(tets.size()) - 1);
  };
  auto dropIncidence = [&](int node, int tet) {
    auto& list = incident[static_cast<size_t>(node)];
    list.erase(std::remove(list.begin(), list.end(), tet), list.end());
  };
  auto newNode = [&](const Vec3& x) {
    nodes.push_back(x);
    incident.emplace_back();
    return static_cast<int>(nodes.size()) - 1;
  };

  int steiner = 0;
  // Bisects edge (a, b) at its midpoint: every tet around it is cut in two.
  auto splitEdge = [&](int a, int b) {
    std::vector<int> around;
    for (int u : incident[static_cast<size_t>(a)])
      if (contains(tets[static_cast<size_t>(u)], b)) around.push_back(u);
    if (around.empty()) return;
    const int m = newNode(0.5 * (nodes[static_cast<size_t>(a)] + nodes[static_cast<size_t>(b)]));
    for (int u : around) {
      const Tet old = tets[static_cast<size_t>(u)];
      tets[static_cast<size_t>(u)] = replaced(old, b, m);  // the half at a
      dropIncidence(b, u);
      incident[static_cast<size_t>(m)].push_back(u);
      addTet(replaced(old, a, m));  // the half at b
    }
    ++steiner;
  };
  // Splits face (a, b, c) at its centroid: both tets on it are cut in three.
  auto splitFace = [&](int a, int b, int c) {
    std::vector<int> around;
    for (int u : incident[static_cast<size_t>(a)])
      if (contains(tets[static_cast<size_t>(u)], b) && contains(tets[static_cast<size_t>(u)], c)) around.push_back(u);
    if (around.empty()) return;
    const int m =
        newNode((nodes[static_cast<size_t>(a)] + nodes[static_cast<size_t>(b)] + nodes[static_cast<size_t>(c)]) / 3.0);
    for (int u : around) {
      const Tet old = tets[static_cast<size_t>(u)];
      tets[static_cast<size_t>(u)] = replaced(old, a, m);
      dropIncidence(a, u);
      incident[static_cast<size_t>(m)].push_back(u);
      addTet(replaced(old, b, m));
      addTet(replaced(old, c, m));
    }
    ++steiner;
  };
  auto isBoundary = [&](int v) {
    return v < static_cast<int>(onBoundary.size()) && onBoundary[static_cast<size_t>(v)];
  };

  if (rule == BoundarySplit::Bridges) {
    std::set<std::pair<int, int>> bridges;
    for (const Tet& t : tets)
      for (const auto& e : kEdge) {
        const std::pair<int, int> k = edgeKey(t[e[0]], t[e[1]]);
        if (isBoundary(k.first) && isBoundary(k.second) && !boundaryEdges.count(k)) bridges.insert(k);
      }
    for (const auto& e : bridges) splitEdge(e.first, e.second);
    std::set<std::array<int, 3>> faces;
    for (const Tet& t : tets)
      for (const auto& f : kFace) {
        const std::array<int, 3> k = faceKey(t[f[0]], t[f[1]], t[f[2]]);
        if (isBoundary(k[0]) && isBoundary(k[1]) && isBoundary(k[2]) && !boundaryFaces.count(k)) faces.insert(k);
      }
    for (const auto& f : faces) splitFace(f[0], f[1], f[2]);
  }

  const int original = static_cast<int>(tets.size());
  for (int i = 0; i < original; ++i) {
    const Tet t = tets[static_cast<size_t>(i)];
    if (!boundaryOnly(t)) continue;  // earlier splits may have given it an interior node already
    // Longest interior edge: its midpoint lies inside the domain.
    int bestEdge = -1;
    double bestLength = -1;
    for (int e = 0; e < 6; ++e) {
      const int a = t[kEdge[e][0]], b = t[kEdge[e][1]];
      if (boundaryEdges.count(edgeKey(a, b))) continue;
      const double len = (nodes[static_cast<size_t>(a)] - nodes[static_cast<size_t>(b)]).squaredNorm();
      if (len > bestLength) bestLength = len, bestEdge = e;
    }
    if (bestEdge >= 0) {
      splitEdge(t[kEdge[bestEdge][0]], t[kEdge[bestEdge][1]]);
      continue;
    }
    // Every edge on the boundary: split the largest face that is not a boundary face at its centroid.
    int bestFace = -1;
    double bestArea = -1;
    for (int j = 0; j < 4; ++j) {
      const int a = t[kFace[j][0]], b = t[kFace[j][1]], c = t[kFace[j][2]];
      if (boundaryFaces.count(faceKey(a, b, c))) continue;
      const Vec3 &pa = nodes[static_cast<size_t>(a)], &pb = nodes[static_cast<size_t>(b)],
                 &pc = nodes[static_cast<size_t>(c)];
      const double area = (pb - pa).cross(pc - pa).squaredNorm();
      if (area > bestArea) bestArea = area, bestFace = j;
    }
    if (bestFace < 0) throw Error("splitBoundaryTets: a tet with four boundary faces (a mesh of one tet)");
    splitFace(t[kFace[bestFace][0]], t[kFace[bestFace][1]], t[kFace[bestFace][2]]);
  }
  if (added) *added = steiner;

  TetMesh out;
  out.nodes.resize(static_cast<Eigen::Index>(nodes.size()), 3);
  for (size_t i = 0; i < nodes.size(); ++i) out.nodes.row(static_cast<Eigen::Index>(i)) = nodes[i].transpose();
  out.tets.resize(static_cast<Eigen::Index>(tets.size()), 4);
  for (size_t i = 0; i < tets.size(); ++i)
    out.tets.row(static_cast<Eigen::Index>(i)) << tets[i][0], tets[i][1], tets[i][2], tets[i][3];
  const std::string tp = tetMeshProblem(out);
  MSK_ASSERT(tp.empty(), "splitBoundaryTets: invalid result: " + tp);
  return out;
}

}  // namespace msk
