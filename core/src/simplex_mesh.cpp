#include "msk/core/simplex_mesh.h"

#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "msk/core/error.h"
#include "msk/core/triangle_grid.h"

namespace msk {

namespace {

using Vec3 = Eigen::Vector3d;

std::string str(long long v) { return std::to_string(v); }

/// Face table of a 2-simplex mesh: the mesh's own if present, else rebuilt from its neighbours.
struct FaceTable {
  std::vector<int> offsets, vertices;
};

/// Traces the faces of a valid k = 2 neighbour table (arriving at v from neighbour j, continue to (j + 2) mod 3).
/// Returns an empty string on success, else the problem.
std::string traceFaces(const NeighborTable& nb, std::vector<int>& offsets, std::vector<int>& vertices) {
  const int n = static_cast<int>(nb.rows());
  offsets.assign(1, 0);
  vertices.clear();
  vertices.reserve(static_cast<size_t>(n) * 3);
  std::vector<char> used(static_cast<size_t>(n) * 3, 0);  // directed edge (nb(v, j) → v) already in a face
  for (int v0 = 0; v0 < n; ++v0) {
    for (int j0 = 0; j0 < 3; ++j0) {
      if (used[static_cast<size_t>(v0) * 3 + j0]) continue;
      // Walk u → v → next ... until the directed edge (nb(v0, j0) → v0) comes round again.
      int v = v0, j = j0;
      for (int steps = 0;; ++steps) {
        if (steps > 3 * n) return "face tracing did not close (inconsistent neighbour order)";
        used[static_cast<size_t>(v) * 3 + j] = 1;
        vertices.push_back(v);
        const int next = nb(v, (j + 2) % 3);
        int jn = -1;
        for (int q = 0; q < 3; ++q)
          if (nb(next, q) == v) jn = q;
        if (jn < 0) return "adjacency not symmetric at " + str(v) + "-" + str(next);
        v = next;
        j = jn;
        if (v == v0 && j == j0) break;
        if (used[static_cast<size_t>(v) * 3 + j]) return "face tracing hit a used edge (inconsistent neighbour order)";
      }
      offsets.push_back(static_cast<int>(vertices.size()));
    }
  }
  return "";
}

/// The neighbour-table part of simplexMeshProblem (shape, range, self, repeats, symmetry).
std::string tableProblem(const SimplexMesh& m) {
  const int n = m.vertexCount();
  const int cols = m.k + 1;
  if (m.neighbors.rows() != n || m.neighbors.cols() != cols)
    return "neighbour table is " + str(m.neighbors.rows()) + "x" + str(m.neighbors.cols()) + ", expected " + str(n) +
           "x" + str(cols) + " for k = " + str(m.k);
  for (int v = 0; v < n; ++v) {
    for (int a = 0; a < cols; ++a) {
      const int u = m.neighbors(v, a);
      if (u < 0 || u >= n) return "vertex " + str(v) + " has a neighbour index out of range (" + str(u) + ")";
      if (u == v) return "vertex " + str(v) + " is its own neighbour";
      for (int b = 0; b < a; ++b)
        if (m.neighbors(v, b) == u) return "vertex " + str(v) + " lists neighbour " + str(u) + " twice";
    }
  }
  for (int v = 0; v < n; ++v) {
    for (int a = 0; a < cols; ++a) {
      const int u = m.neighbors(v, a);
      bool back = false;
      for (int b = 0; b < cols; ++b) back = back || m.neighbors(u, b) == v;
      if (!back) return "adjacency not symmetric: " + str(u) + " is a neighbour of " + str(v) + " but not the reverse";
    }
  }
  return "";
}

/// The face-table part of simplexMeshProblem (k = 2, faces present).
std::string faceProblem(const SimplexMesh& m) {
  const int n = m.vertexCount();
  const auto& off = m.faceOffsets;
  const auto& fv = m.faceVertices;
  if (off.front() != 0) return "faceOffsets must start at 0";
  if (off.back() != static_cast<int>(fv.size()))
    return "faceOffsets ends at " + str(off.back()) + " but there are " + str(static_cast<long long>(fv.size())) +
           " face vertices";
  if (static_cast<long long>(fv.size()) != 3LL * n)
    return "faces list " + str(static_cast<long long>(fv.size())) + " vertex slots, expected 3 per vertex (" +
           str(3LL * n) + ")";
  std::vector<char> used(static_cast<size_t>(n) * 3, 0);
  for (size_t f = 0; f + 1 < off.size(); ++f) {
    const int b = off[f], e = off[f + 1];
    if (e - b < 3) return "face " + str(static_cast<long long>(f)) + " has fewer than 3 vertices";
    for (int i = b; i < e; ++i)
      if (fv[i] < 0 || fv[i] >= n) return "face " + str(static_cast<long long>(f)) + " has a vertex out of range";
    for (int i = b; i < e; ++i) {
      const int u = fv[i == b ? e - 1 : i - 1], v = fv[i], w = fv[i + 1 == e ? b : i + 1];
      int j = -1;
      for (int q = 0; q < 3; ++q)
        if (m.neighbors(v, q) == u) j = q;
      if (j < 0 || m.neighbors(v, (j + 2) % 3) != w)
        return "face " + str(static_cast<long long>(f)) + " does not follow the neighbour order at vertex " + str(v);
      char& flag = used[static_cast<size_t>(v) * 3 + j];
      if (flag) return "edge " + str(u) + "->" + str(v) + " is in two faces";
      flag = 1;
    }
  }
  return "";
}

/// Faces of a 2-simplex mesh (its own or traced); throws Error if the mesh is invalid.
FaceTable facesOf(const SimplexMesh& m, const char* caller) {
  if (m.k != 2) throw Error(std::string(caller) + ": a 2-simplex mesh is required (k = " + str(m.k) + ")");
  const std::string problem = simplexMeshProblem(m);
  if (!problem.empty()) throw Error(std::string(caller) + ": invalid simplex mesh: " + problem);
  FaceTable t;
  if (m.faceCount() > 0) {
    t.offsets = m.faceOffsets;
    t.vertices = m.faceVertices;
  } else {
    const std::string p = traceFaces(m.neighbors, t.offsets, t.vertices);
    if (!p.empty()) throw Error(std::string(caller) + ": " + p);
  }
  return t;
}

/// Triangle table of the dual: tri(t, j) = the face holding the directed edge (nb(t, j) → t). With that choice the
/// triangle's edge (j, j+1) is shared with simplex neighbour j and the winding is counter-clockwise from outside.
Triangles dualTriangles(const NeighborTable& nb, const FaceTable& t) {
  Triangles tri(nb.rows(), 3);
  tri.setConstant(-1);
  for (size_t f = 0; f + 1 < t.offsets.size(); ++f) {
    const int b = t.offsets[f], e = t.offsets[f + 1];
    for (int i = b; i < e; ++i) {
      const int u = t.vertices[i == b ? e - 1 : i - 1], v = t.vertices[i];
      for (int q = 0; q < 3; ++q)
        if (nb(v, q) == u) tri(v, q) = static_cast<int>(f);
    }
  }
  MSK_ASSERT((tri.array() >= 0).all(), "dual triangle table incomplete");
  return tri;
}

}  // namespace

// ------------------------------------------------------------------------------------------------ validity

std::string simplexMeshProblem(const SimplexMesh& m) {
  if (m.k < 1 || m.k > 3) return "simplex order k = " + str(m.k) + " (expected 1, 2 or 3)";
  const int n = m.vertexCount();
  if (n == 0) return "empty mesh";
  if (n < m.k + 2) return "too few vertices (" + str(n) + ") for k = " + str(m.k);
  if (!m.positions.allFinite()) return "non-finite vertex coordinates";
  for (const auto& kv : m.pointData)
    if (kv.second.size() != n)
      return "point array '" + kv.first + "' has " + str(kv.second.size()) + " values for " + str(n) + " vertices";
  std::string p = tableProblem(m);
  if (!p.empty()) return p;
  if (m.k != 2) {
    if (!m.faceOffsets.empty() || !m.faceVertices.empty()) return "face table given for k = " + str(m.k);
    return "";
  }
  if (m.faceOffsets.empty()) return m.faceVertices.empty() ? "" : "faceVertices given without faceOffsets";
  return faceProblem(m);
}

void buildSimplexFaces(SimplexMesh& m) {
  if (m.k != 2) throw Error("buildSimplexFaces: a 2-simplex mesh is required (k = " + str(m.k) + ")");
  SimplexMesh bare;
  bare.k = 2;
  bare.positions = m.positions;
  bare.neighbors = m.neighbors;
  const std::string problem = simplexMeshProblem(bare);
  if (!problem.empty()) throw Error("buildSimplexFaces: invalid simplex mesh: " + problem);
  const std::string p = traceFaces(m.neighbors, m.faceOffsets, m.faceVertices);
  if (!p.empty()) throw Error("buildSimplexFaces: " + p);
}

// ------------------------------------------------------------------------------------------------ duality

SimplexMesh simplexFromTriangles(const TriangleMesh& tm) {
  const std::string problem = closedMeshProblem(tm);
  if (!problem.empty()) throw Error("simplexFromTriangles: " + problem);
  const int nv = tm.vertexCount(), nt = tm.faceCount();
  const Triangles& F = tm.faces;

  // Vertex → incident triangles (CSR).
  std::vector<int> vStart(static_cast<size_t>(nv) + 1, 0), vTri(static_cast<size_t>(nt) * 3);
  for (int t = 0; t < nt; ++t)
    for (int k = 0; k < 3; ++k) ++vStart[static_cast<size_t>(F(t, k)) + 1];
  for (int v = 0; v < nv; ++v) vStart[v + 1] += vStart[v];
  {
    std::vector<int> fill(vStart.begin(), vStart.end() - 1);
    for (int t = 0; t < nt; ++t)
      for (int k = 0; k < 3; ++k) vTri[fill[F(t, k)]++] = t;
  }
  auto slot = [&](int t, int v) {  // position of v in triangle t, −1 if absent
    for (int k = 0; k < 3; ++k)
      if (F(t, k) == v) return k;
    return -1;
  };

  SimplexMesh s;
  s.k = 2;
  s.positions.resize(nt, 3);
  s.neighbors.resize(nt, 3);
  for (int t = 0; t < nt; ++t) {
    s.positions.row(t) = (tm.vertices.row(F(t, 0)) + tm.vertices.row(F(t, 1)) + tm.vertices.row(F(t, 2))) / 3.0;
    for (int k = 0; k < 3; ++k) {
      // Neighbour across edge (a, b) = the triangle holding the directed edge (b, a).
      const int a = F(t, k), b = F(t, (k + 1) % 3);
      int found = -1;
      for (int i = vStart[b]; i < vStart[b + 1] && found < 0; ++i) {
        const int u = vTri[i];
        const int q = slot(u, b);
        if (u != t && F(u, (q + 1) % 3) == a) found = u;
      }
      MSK_ASSERT(found >= 0, "closed mesh without an opposite edge");
      s.neighbors(t, k) = found;
    }
  }

  // Faces: the ring of triangles around each vertex, counter-clockwise from outside. Triangle t holds vertex v at
  // slot i; the next triangle counter-clockwise around v is across edge (slot i−1, slot i), i.e. neighbour (i+2)%3.
  s.faceOffsets.assign(1, 0);
  s.faceVertices.reserve(static_cast<size_t>(nt) * 3);
  for (int v = 0; v < nv; ++v) {
    const int valence = vStart[v + 1] - vStart[v];
    if (valence == 0) throw Error("simplexFromTriangles: vertex " + str(v) + " is not used by any triangle");
    const int t0 = vTri[vStart[v]];
    int t = t0, count = 0;
    do {
      s.faceVertices.push_back(t);
      t = s.neighbors(t, (slot(t, v) + 2) % 3);
      ++count;
    } while (t != t0 && count <= valence);
    if (count != valence)
      throw Error("simplexFromTriangles: vertex " + str(v) + " is non-manifold (its " + str(valence) +
                  " triangles form more than one fan)");
    s.faceOffsets.push_back(static_cast<int>(s.faceVertices.size()));
  }

  for (const auto& kv : tm.pointData) {
    Eigen::VectorXd d(nt);
    for (int t = 0; t < nt; ++t) d[t] = (kv.second[F(t, 0)] + kv.second[F(t, 1)] + kv.second[F(t, 2)]) / 3.0;
    s.pointData.emplace(kv.first, std::move(d));
  }
  const std::string sp = simplexMeshProblem(s);
  if (!sp.empty()) throw Error("simplexFromTriangles: the dual is not a valid simplex mesh: " + sp);
  return s;
}

TriangleMesh trianglesFromSimplex(const SimplexMesh& s) {
  const FaceTable ft = facesOf(s, "trianglesFromSimplex");
  const int ns = s.vertexCount();
  const int nf = static_cast<int>(ft.offsets.size()) - 1;

  TriangleMesh tm;
  tm.faces = dualTriangles(s.neighbors, ft);

  // V₀: polygon centroids.
  Points v0(nf, 3);
  for (int f = 0; f < nf; ++f) {
    Eigen::RowVector3d c = Eigen::RowVector3d::Zero();
    for (int i = ft.offsets[f]; i < ft.offsets[f + 1]; ++i) c += s.positions.row(ft.vertices[i]);
    v0.row(f) = c / static_cast<double>(ft.offsets[f + 1] - ft.offsets[f]);
  }

  // min |C V − P|² + μ |V − V₀|²  ⇔  (CᵀC + μI) V = CᵀP + μV₀; C is #S×#F with 1/3 at each triangle's vertices.
  // μ is relative to the mean diagonal of CᵀC (Σ = #S/3), so it holds at any resolution.
  // CᵀC is assembled directly: each triangle adds 1/9 to the 3×3 block of its vertices.
  const double mu = 1e-3 * (static_cast<double>(ns) / 3.0) / static_cast<double>(nf);
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(static_cast<size_t>(ns) * 9 + static_cast<size_t>(nf));
  Eigen::MatrixXd rhs = mu * Eigen::MatrixXd(v0);
  for (int t = 0; t < ns; ++t) {
    for (int i = 0; i < 3; ++i) {
      rhs.row(tm.faces(t, i)) += s.positions.row(t) / 3.0;  // CᵀP
      for (int j = 0; j < 3; ++j) trip.emplace_back(tm.faces(t, i), tm.faces(t, j), 1.0 / 9.0);
    }
  }
  for (int f = 0; f < nf; ++f) trip.emplace_back(f, f, mu);
  Eigen::SparseMatrix<double> a(nf, nf);
  a.setFromTriplets(trip.begin(), trip.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(a);
  MSK_ASSERT(ldlt.info() == Eigen::Success, "trianglesFromSimplex: factorisation failed");
  const Eigen::MatrixXd v = ldlt.solve(rhs);  // the factorisation serves all 3 coordinates
  MSK_ASSERT(ldlt.info() == Eigen::Success && v.allFinite(), "trianglesFromSimplex: solve failed");
  tm.vertices = v;

  for (const auto& kv : s.pointData) {
    Eigen::VectorXd d(nf);
    for (int f = 0; f < nf; ++f) {
      double sum = 0;
      for (int i = ft.offsets[f]; i < ft.offsets[f + 1]; ++i) sum += kv.second[ft.vertices[i]];
      d[f] = sum / static_cast<double>(ft.offsets[f + 1] - ft.offsets[f]);
    }
    tm.pointData.emplace(kv.first, std::move(d));
  }
  return tm;
}

// ------------------------------------------------------------------------------------------------ geometry

namespace {
/// Area-weighted vertex normals from a valid face table `offsets`/`vertices` over the rows of `s.positions`.
Points vertexNormals(const SimplexMesh& s, const std::vector<int>& offsets, const std::vector<int>& vertices) {
  const int n = s.vertexCount();
  Points nrm = Points::Zero(n, 3);
  for (size_t f = 0; f + 1 < offsets.size(); ++f) {
    Vec3 area = Vec3::Zero();  // ½ Σ vi × vi+1, outward for counter-clockwise faces
    const int b = offsets[f], e = offsets[f + 1];
    for (int i = b; i < e; ++i) {
      const Vec3 a = s.positions.row(vertices[i]), c = s.positions.row(vertices[i + 1 == e ? b : i + 1]);
      area += a.cross(c);
    }
    area *= 0.5;
    for (int i = b; i < e; ++i) nrm.row(vertices[i]) += area.transpose();
  }
  for (int v = 0; v < n; ++v) {
    double len = nrm.row(v).norm();
    if (!(len > 0)) {  // flat or folded neighbourhood: the neighbours' plane
      const Vec3 p1 = s.positions.row(s.neighbors(v, 0)), p2 = s.positions.row(s.neighbors(v, 1)),
                 p3 = s.positions.row(s.neighbors(v, 2));
      nrm.row(v) = (p2 - p1).cross(p3 - p1).transpose();
      len = nrm.row(v).norm();
    }
    if (len > 0) nrm.row(v) /= len;
  }
  return nrm;
}
}  // namespace

Points simplexVertexNormals(const SimplexMesh& s) {
  const FaceTable ft = facesOf(s, "simplexVertexNormals");
  return vertexNormals(s, ft.offsets, ft.vertices);
}

Points validSimplexVertexNormals(const SimplexMesh& s) {
  if (s.k != 2 || s.faceCount() == 0 || s.neighbors.rows() != s.vertexCount()) return simplexVertexNormals(s);
  if (!s.positions.allFinite())
    throw Error("simplexVertexNormals: invalid simplex mesh: non-finite vertex coordinates");
  return vertexNormals(s, s.faceOffsets, s.faceVertices);
}

Triangles simplexFanTriangles(const SimplexMesh& s) {
  const FaceTable ft = facesOf(s, "simplexFanTriangles");
  int count = 0;
  for (size_t f = 0; f + 1 < ft.offsets.size(); ++f) count += ft.offsets[f + 1] - ft.offsets[f] - 2;
  Triangles tri(count, 3);
  int r = 0;
  for (size_t f = 0; f + 1 < ft.offsets.size(); ++f) {
    const int b = ft.offsets[f], e = ft.offsets[f + 1];
    for (int i = b + 1; i + 1 < e; ++i) tri.row(r++) << ft.vertices[b], ft.vertices[i], ft.vertices[i + 1];
  }
  return tri;
}

// ------------------------------------------------------------------------------------------------ closest points

namespace {
/// Closest point on segment (a, b) to p; writes the parameter t (point = a + t (b − a)).
Vec3 closestOnSegment(const Vec3& p, const Vec3& a, const Vec3& b, double& t) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  t = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return a + t * ab;
}
}  // namespace

Eigen::Vector3d closestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                       const Eigen::Vector3d& c, Eigen::Vector3d* bary) {
  const Vec3 ab = b - a, ac = c - a, bc = c - b;
  const double scale2 = std::max({ab.squaredNorm(), ac.squaredNorm(), bc.squaredNorm()});
  const double cross2 = ab.cross(ac).squaredNorm();
  if (!(cross2 > 1e-24 * scale2 * scale2)) {
    // Degenerate (collinear or coincident) triangle: the best of its three edges.
    double t[3];
    const Vec3 q[3] = {closestOnSegment(p, a, b, t[0]), closestOnSegment(p, b, c, t[1]),
                       closestOnSegment(p, c, a, t[2])};
    int best = 0;
    for (int i = 1; i < 3; ++i)
      if ((q[i] - p).squaredNorm() < (q[best] - p).squaredNorm()) best = i;
    if (bary) {
      if (best == 0)
        *bary = Vec3(1 - t[0], t[0], 0);
      else if (best == 1)
        *bary = Vec3(0, 1 - t[1], t[1]);
      else
        *bary = Vec3(t[2], 0, 1 - t[2]);
    }
    return q[best];
  }
  // Ericson, Real-Time Collision Detection (2005) §5.1.5: vertex, edge and face Voronoi regions in turn.
  const Vec3 ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) {
    if (bary) *bary = Vec3(1, 0, 0);
    return a;
  }
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) {
    if (bary) *bary = Vec3(0, 1, 0);
    return b;
  }
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    if (bary) *bary = Vec3(1 - v, v, 0);
    return a + v * ab;
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) {
    if (bary) *bary = Vec3(0, 0, 1);
    return c;
  }
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    if (bary) *bary = Vec3(1 - w, 0, w);
    return a + w * ac;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    if (bary) *bary = Vec3(0, 1 - w, w);
    return b + w * bc;
  }
  const double denom = 1.0 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  if (bary) *bary = Vec3(1 - v - w, v, w);
  return a + v * ab + w * ac;
}

// ------------------------------------------------------------------------------------------------ transfer

namespace {
/// The transfer's grid layout over `f` at `v`: cells about one mean edge long (coarser while there would be more than a
/// few cells per triangle, so huge, thin or far-flung meshes stay cheap), over the triangles' bounding box.
TriangleGrid::Layout transferLayout(const Points& v, const Triangles& f) {
  const int nt = static_cast<int>(f.rows());
  Eigen::RowVector3d lo = Eigen::RowVector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  double edgeSum = 0;
  for (int t = 0; t < nt; ++t) {
    for (int k = 0; k < 3; ++k) {
      lo = lo.cwiseMin(v.row(f(t, k)));
      hi = hi.cwiseMax(v.row(f(t, k)));
      edgeSum += (v.row(f(t, k)) - v.row(f(t, (k + 1) % 3))).norm();
    }
  }
  const Vec3 ext = (hi - lo).transpose();
  double h = edgeSum / (3.0 * nt);
  if (!(h > 0)) h = std::max(ext.maxCoeff(), 1.0);
  const double maxCells = 8.0 * nt + 64.0;
  for (;;) {
    const double cells = std::ceil(ext.x() / h + 1e-9) * std::ceil(ext.y() / h + 1e-9) * std::ceil(ext.z() / h + 1e-9);
    if (cells <= maxCells) break;
    h *= 1.25;
  }
  TriangleGrid::Layout layout;
  layout.lo = lo.transpose();
  layout.cell = h;
  for (int i = 0; i < 3; ++i) layout.dims[i] = std::max(1, static_cast<int>(std::ceil(ext[i] / h + 1e-9)));
  return layout;
}
}  // namespace

SurfaceTransfer::SurfaceTransfer(const TriangleMesh& source, const Points& targetPoints) {
  if (source.faceCount() == 0) throw Error("SurfaceTransfer: the source mesh has no triangles");
  const int nv = source.vertexCount();
  if ((source.faces.array() < 0).any() || (source.faces.array() >= nv).any())
    throw Error("SurfaceTransfer: a source triangle has a vertex index out of range");
  if (!source.vertices.allFinite()) throw Error("SurfaceTransfer: non-finite source vertex coordinates");
  if (!targetPoints.allFinite()) throw Error("SurfaceTransfer: non-finite target point coordinates");
  sourceVertexCount_ = nv;
  const int n = static_cast<int>(targetPoints.rows());
  tri_.resize(n, 3);
  bary_.resize(n, 3);
  distances_.resize(n);
  TriangleGrid grid;
  grid.build(transferLayout(source.vertices, source.faces), source.vertices, source.faces);
  for (int i = 0; i < n; ++i) {
    const SurfacePoint s = grid.closest(source.vertices, source.faces, targetPoints.row(i).transpose());
    MSK_ASSERT(s.triangle >= 0, "SurfaceTransfer: no closest triangle found");
    tri_.row(i) = source.faces.row(s.triangle);
    bary_.row(i) << s.bary[0], s.bary[1], s.bary[2];
    distances_[i] = s.distance;
  }
}

Eigen::MatrixXd SurfaceTransfer::apply(const Eigen::MatrixXd& sourceValues) const {
  if (sourceValues.rows() != sourceVertexCount_)
    throw Error("SurfaceTransfer::apply: " + str(sourceValues.rows()) + " rows given for " + str(sourceVertexCount_) +
                " source vertices");
  Eigen::MatrixXd out(tri_.rows(), sourceValues.cols());
  for (Eigen::Index i = 0; i < tri_.rows(); ++i)
    out.row(i) = bary_(i, 0) * sourceValues.row(tri_(i, 0)) + bary_(i, 1) * sourceValues.row(tri_(i, 1)) +
                 bary_(i, 2) * sourceValues.row(tri_(i, 2));
  return out;
}

}  // namespace msk
