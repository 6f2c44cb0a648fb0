// Closed mesh → label map by scanlines along the grid's i axis, in continuous voxel coordinates. A voxel is inside
// where the mesh's winding number is positive (signed crossings, not parity): for a surface without self-intersections
// the two agree; where an evolved surface folds over itself, a sheet turned inside out (winding number −1) is not taken
// for the object, and a region it covers twice (2) is not left as a hole.
#include "msk/imaging/rasterize.h"

#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <utility>
#include <vector>

#include "msk/core/error.h"

namespace msk {

namespace {

/// Which side of the directed edge a→b (projected to the (j, k) plane) the ray point (pj, pk) lies on: +1 left,
/// −1 right, 0 only for an edge of zero projected length. `f` receives the edge function (b−a)×(p−a).
/// The value is computed in a canonical vertex order (lower index first) so the two triangles sharing an edge
/// get exactly opposite values; exact zeros are broken by a symbolic perturbation of the point by (ε, ε²).
/// Together this makes the crossing count watertight: a ray through an edge or vertex is counted once.
inline int edgeSide(const Eigen::Vector3d& a, int ia, const Eigen::Vector3d& b, int ib, double pj, double pk,
                    double& f) {
  const bool swapped = ib < ia;
  const Eigen::Vector3d& p0 = swapped ? b : a;
  const Eigen::Vector3d& p1 = swapped ? a : b;
  const double du = p1[1] - p0[1], dv = p1[2] - p0[2];
  double value = du * (pk - p0[2]) - dv * (pj - p0[1]);
  int side = value > 0 ? 1 : value < 0 ? -1 : dv != 0 ? (dv < 0 ? 1 : -1) : du > 0 ? 1 : du < 0 ? -1 : 0;
  if (swapped) {
    value = -value;
    side = -side;
  }
  f = value;
  return side;
}

/// x clamped to the index range [0, n−1] and converted (safe for values far outside int).
inline int clampToIndex(double x, int n) { return static_cast<int>(std::clamp(x, 0.0, static_cast<double>(n - 1))); }

/// Calls `run(row, i0, i1)` for every run of voxels i0..i1 (inclusive) of the row (·, j, k) = row j + nj·k whose
/// centres lie inside the closed mesh, rows in ascending order and runs along a row in ascending i; consecutive runs
/// of a row may share their end voxel. Throws Error if the mesh is not closed or the grid invalid.
template <class Run>
void forEachInsideRun(const TriangleMesh& mesh, const Grid& g, const Run& run) {
  const std::string problem = closedMeshProblem(mesh);
  if (!problem.empty()) throw Error("rasterize: the mesh is not a closed surface: " + problem);
  const std::string gridProblem = g.problem();
  if (!gridProblem.empty()) throw Error("rasterize: invalid grid: " + gridProblem);

  // Vertices in continuous voxel coordinates: voxel centres sit at integer (i, j, k).
  const int nv = mesh.vertexCount(), nf = mesh.faceCount();
  std::vector<Eigen::Vector3d> v(static_cast<size_t>(nv));
  for (int i = 0; i < nv; ++i) v[static_cast<size_t>(i)] = g.toVoxel(mesh.vertices.row(i).transpose());

  // Bin triangles by the (j, k) voxel-centre rows their projected bounding box covers (CSR layout).
  const int ni = g.dims[0], nj = g.dims[1], nk = g.dims[2];
  const size_t rows = static_cast<size_t>(nj) * static_cast<size_t>(nk);
  std::vector<std::array<int, 4>> range(static_cast<size_t>(nf));  // j0, j1, k0, k1 (inclusive; empty if j0 > j1)
  std::vector<size_t> start(rows + 1, 0);
  for (int f = 0; f < nf; ++f) {
    double jmin = INFINITY, jmax = -INFINITY, kmin = INFINITY, kmax = -INFINITY;
    for (int c = 0; c < 3; ++c) {
      const Eigen::Vector3d& p = v[static_cast<size_t>(mesh.faces(f, c))];
      jmin = std::min(jmin, p[1]), jmax = std::max(jmax, p[1]);
      kmin = std::min(kmin, p[2]), kmax = std::max(kmax, p[2]);
    }
    // Rows on the box's boundary are included; the exact test below decides whether they cross.
    auto& r = range[static_cast<size_t>(f)];
    r[0] = clampToIndex(std::ceil(jmin), nj);
    r[1] = clampToIndex(std::floor(jmax), nj);
    r[2] = clampToIndex(std::ceil(kmin), nk);
    r[3] = clampToIndex(std::floor(kmax), nk);
    if (jmin > nj - 1 || jmax < 0 || kmin > nk - 1 || kmax < 0) r = {1, 0, 1, 0};
    if (r[0] > r[1] || r[2] > r[3]) continue;
    for (int k = r[2]; k <= r[3]; ++k)
      for (int j = r[0]; j <= r[1]; ++j) ++start[static_cast<size_t>(j) + static_cast<size_t>(nj) * k + 1];
  }
  for (size_t r = 0; r < rows; ++r) start[r + 1] += start[r];
  std::vector<int> binned(start[rows]);
  {
    std::vector<size_t> fill(start.begin(), start.end() - 1);
    for (int f = 0; f < nf; ++f) {
      const auto& r = range[static_cast<size_t>(f)];
      if (r[0] > r[1] || r[2] > r[3]) continue;
      for (int k = r[2]; k <= r[3]; ++k)
        for (int j = r[0]; j <= r[1]; ++j) binned[fill[static_cast<size_t>(j) + static_cast<size_t>(nj) * k]++] = f;
    }
  }

  // Each row: crossings of the line (·, j, k) with the triangles, sorted, each +1 where the ray enters (the face's
  // normal points toward −i) and −1 where it leaves; voxels between crossings where the running sum is positive are
  // filled.
  std::vector<std::pair<double, int>> hits;
  const bool rightHanded = g.direction.determinant() > 0;
  for (int k = 0; k < nk; ++k) {
    for (int j = 0; j < nj; ++j) {
      const size_t row = static_cast<size_t>(j) + static_cast<size_t>(nj) * k;
      if (start[row] == start[row + 1]) continue;
      hits.clear();
      const double pj = j, pk = k;
      for (size_t b = start[row]; b < start[row + 1]; ++b) {
        const int f = binned[b];
        const int ia = mesh.faces(f, 0), ib = mesh.faces(f, 1), ic = mesh.faces(f, 2);
        const Eigen::Vector3d &a = v[static_cast<size_t>(ia)], &bb = v[static_cast<size_t>(ib)],
                              &c = v[static_cast<size_t>(ic)];
        double wc, wa, wb;  // edge functions = unnormalised barycentric weights of the opposite vertex
        const int sc = edgeSide(a, ia, bb, ib, pj, pk, wc);
        const int sa = edgeSide(bb, ib, c, ic, pj, pk, wa);
        const int sb = edgeSide(c, ic, a, ia, pj, pk, wb);
        if (sa == 0 || sa != sb || sb != sc) continue;
        const double sum = wa + wb + wc;
        if (sum == 0) continue;  // zero projected area: a perturbed ray cannot cross it
        // The edge functions sum to the i component of (b − a) × (c − a): the face's normal points along +i when the
        // sum is positive, and the ray leaves the object there
        // (in voxel coordinates, whose handedness is that of the grid's direction matrix).
        hits.push_back({(wa * a[0] + wb * bb[0] + wc * c[0]) / sum, (sum > 0) == rightHanded ? -1 : 1});
      }
      if (hits.size() < 2) continue;
      std::sort(hits.begin(), hits.end());
      int winding = 0;
      for (size_t h = 0; h + 1 < hits.size(); ++h) {
        winding += hits[h].second;
        if (winding <= 0 || hits[h].first > ni - 1 || hits[h + 1].first < 0) continue;
        const int i0 = clampToIndex(std::ceil(hits[h].first), ni);
        const int i1 = clampToIndex(std::floor(hits[h + 1].first), ni);
        if (i0 <= i1) run(row, i0, i1);
      }
    }
  }
}

}  // namespace

void rasterizeInto(LabelMap& labels, const TriangleMesh& mesh, int32_t label) {
  MSK_ASSERT(labels.data.size() == labels.grid.voxelCount(), "label map data does not match its grid");
  const size_t ni = static_cast<size_t>(labels.grid.dims[0]);
  forEachInsideRun(mesh, labels.grid, [&](size_t row, int i0, int i1) {
    int32_t* out = labels.data.data() + row * ni;
    for (int i = i0; i <= i1; ++i) out[i] = label;
  });
}

std::vector<size_t> insideVoxelIndices(const TriangleMesh& mesh, const Grid& grid) {
  const size_t ni = static_cast<size_t>(grid.dims[0]);
  std::vector<size_t> out;
  forEachInsideRun(mesh, grid, [&](size_t row, int i0, int i1) {
    size_t from = row * ni + static_cast<size_t>(i0);
    if (!out.empty() && out.back() >= from) from = out.back() + 1;  // a run's first voxel may end the previous one
    for (size_t v = from; v <= row * ni + static_cast<size_t>(i1); ++v) out.push_back(v);
  });
  return out;
}

LabelMap rasterize(const TriangleMesh& mesh, const Grid& grid) {
  LabelMap labels(grid, 0);
  rasterizeInto(labels, mesh, 1);
  return labels;
}

}  // namespace msk
