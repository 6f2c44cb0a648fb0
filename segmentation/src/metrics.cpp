#include "msk/segmentation/metrics.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "cgal_aabb.h"
#include "msk/core/error.h"
#include "msk/imaging/filters.h"
#include "msk/imaging/rasterize.h"

// Definitions (also in docs/measurements.md)
// --------------------------------
// Overlap, for object sets A and B:
//   dice = 2|A∩B| / (|A|+|B|), jaccard = |A∩B| / |A∪B|; both are 1 when A and B are both empty.
// Label maps (labelMetrics; both maps on the same grid: equal dims, affines equal within 1e-4 mm):
//   |·| counts voxels; volume = count × spacing_i·spacing_j·spacing_k (mm³).
//   Surface voxels: voxels of the object with at least one 6-neighbour outside the object or outside the grid.
//   d(a, B) for a surface voxel a of A: Euclidean distance in mm between the centre of a and the nearest centre of
//   a surface voxel of B (0 if a is itself a surface voxel of B). Computed exactly by a separable squared-distance
//   transform (Felzenszwalb & Huttenlocher 2012, "Distance transforms of sampled functions": 1-D lower envelope of
//   parabolas along each axis, with the axis spacing as weight). The spacing makes it anisotropic; the direction
//   matrix is a rotation/reflection and does not change distances.
// Meshes (meshMetrics): surfaces are the triangles; d(p, B) is the exact distance from point p to the closest point
//   of B's triangles. Each surface is sampled by all its vertices plus random points uniform by area (fixed seed,
//   about samplesPerMm2 per mm², at most 200 000 per mesh); every random sample stands for area/#samples mm².
//   Means, ASSD and HD95 use the random samples only (area-weighted); the Hausdorff distance is the maximum over
//   random samples and vertices. Dice/Jaccard come from rasterising both meshes (voxel centres inside) on a common
//   axis-aligned grid of spacing voxelMm that covers both bounding boxes plus 2 voxels; volumes are the exact
//   enclosed volumes of the meshes.
// Distances (both kinds), with dA the distances from A's surface to B and dB from B's surface to A:
//   meanAtoB = mean(dA), meanBtoA = mean(dB), assd = (ΣdA + ΣdB) / (nA + nB) (area-weighted sums for meshes),
//   hd95 = 95th percentile of the pooled distances dA ∪ dB (linear interpolation between order statistics for
//   label maps; weighted by area for meshes), hausdorff = max(dA ∪ dB).
//   If exactly one object is empty, every distance is +infinity; if both are empty, every distance is 0.

namespace msk {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// Distances from one surface to the other, each with its weight (voxel: 1; mesh sample: mm² it stands for).
struct DirectedDistances {
  std::vector<double> d, w;
  double max = 0;  ///< includes extra samples (mesh vertices) that take no part in the weighted statistics
};

/// Fills the distance fields of `m` from the two directed distance sets (see the definitions above).
void setDistances(SegmentationMetrics& m, const DirectedDistances& ab, const DirectedDistances& ba) {
  auto weightedSum = [](const DirectedDistances& x) {
    double s = 0, w = 0;
    for (size_t n = 0; n < x.d.size(); ++n) s += x.w[n] * x.d[n], w += x.w[n];
    return std::pair{s, w};
  };
  const auto [sAB, wAB] = weightedSum(ab);
  const auto [sBA, wBA] = weightedSum(ba);
  m.meanAtoB = sAB / wAB;
  m.meanBtoA = sBA / wBA;
  m.assd = (sAB + sBA) / (wAB + wBA);
  m.hausdorff = std::max(ab.max, ba.max);

  std::vector<double> pooled(ab.d);
  pooled.insert(pooled.end(), ba.d.begin(), ba.d.end());
  const bool uniform = std::all_of(ab.w.begin(), ab.w.end(), [](double w) { return w == 1.0; }) &&
                       std::all_of(ba.w.begin(), ba.w.end(), [](double w) { return w == 1.0; });
  if (uniform) {
    m.hd95 = percentile(std::move(pooled), 95.0);
    return;
  }
  // Weighted 95th percentile: the smallest distance whose cumulative weight reaches 95 % of the total.
  std::vector<double> weights(ab.w);
  weights.insert(weights.end(), ba.w.begin(), ba.w.end());
  std::vector<size_t> order(pooled.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::sort(order.begin(), order.end(), [&](size_t x, size_t y) { return pooled[x] < pooled[y]; });
  const double target = 0.95 * (wAB + wBA);
  double cumulative = 0;
  m.hd95 = pooled[order.back()];
  for (size_t n : order) {
    cumulative += weights[n];
    if (cumulative >= target) {
      m.hd95 = pooled[n];
      break;
    }
  }
}

/// Sets every distance to `value` (empty objects).
void setAllDistances(SegmentationMetrics& m, double value) {
  m.assd = m.meanAtoB = m.meanBtoA = m.hd95 = m.hausdorff = value;
}

/// Dice and Jaccard from the object sizes and their overlap (1 when both are empty).
void setOverlap(SegmentationMetrics& m, double nA, double nB, double nAB) {
  if (nA + nB == 0) {
    m.dice = m.jaccard = 1;
    return;
  }
  m.dice = 2 * nAB / (nA + nB);
  m.jaccard = nAB / (nA + nB - nAB);
}

// ---- label maps -------------------------------------------------------------------------------------------------

/// In-place exact 1-D squared distance transform of the samples f[0..n) at positions q·h (mm), Felzenszwalb &
/// Huttenlocher (2012), algorithm DT(f): d(p) = min_q (h(p−q))² + f(q). Infinite f(q) are not sites.
/// `v`, `z`, `out` are scratch buffers of at least n, n+1, n entries.
void squaredDistance1d(double* f, int n, double h, std::vector<int>& v, std::vector<double>& z,
                       std::vector<double>& out) {
  int k = -1;
  for (int q = 0; q < n; ++q) {
    if (f[q] == kInf) continue;
    const double xq = q * h, fq = f[q] + xq * xq;
    double s = -kInf;
    while (k >= 0) {
      const double xv = v[k] * h;
      s = (fq - (f[v[k]] + xv * xv)) / (2 * (xq - xv));  // intersection of the parabolas rooted at q and v[k]
      if (s > z[k]) break;
      --k;
    }
    ++k;
    v[k] = q;
    z[k] = k == 0 ? -kInf : s;
    z[k + 1] = kInf;
  }
  if (k < 0) return;  // no site on this line: everything stays infinite
  k = 0;
  for (int p = 0; p < n; ++p) {
    const double x = p * h;
    while (z[k + 1] < x) ++k;
    const double dx = x - v[k] * h;
    out[p] = dx * dx + f[v[k]];
  }
  std::copy(out.begin(), out.begin() + n, f);
}

/// Squared Euclidean distance (mm²) from every voxel centre to the nearest voxel with `site` set, on `grid`'s
/// spacing (separable: one 1-D transform per axis).
std::vector<double> squaredDistanceTransform(const std::vector<uint8_t>& site, const Grid& grid) {
  std::vector<double> dt(site.size());
  for (size_t n = 0; n < site.size(); ++n) dt[n] = site[n] ? 0.0 : kInf;
  const int maxDim = grid.dims.maxCoeff();
  std::vector<double> line(maxDim), z(maxDim + 1), out(maxDim);
  std::vector<int> v(maxDim);
  for (int axis = 0; axis < 3; ++axis) {
    const int n = grid.dims[axis];
    grid.forEachLine(axis, [&](size_t base, size_t stride) {
      for (int p = 0; p < n; ++p) line[p] = dt[base + p * stride];
      squaredDistance1d(line.data(), n, grid.spacing[axis], v, z, out);
      for (int p = 0; p < n; ++p) dt[base + p * stride] = line[p];
    });
  }
  return dt;
}

/// Marks the surface voxels of `mask`: object voxels with a 6-neighbour outside the object or outside the grid.
std::vector<uint8_t> surfaceOf(const std::vector<uint8_t>& mask, const Grid& g) {
  std::vector<uint8_t> surface(mask.size(), 0);
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        const size_t n = g.index(i, j, k);
        if (!mask[n]) continue;
        static const int kOffsets[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
        for (const auto& o : kOffsets) {
          const int ii = i + o[0], jj = j + o[1], kk = k + o[2];
          if (!g.contains(ii, jj, kk) || !mask[g.index(ii, jj, kk)]) {
            surface[n] = 1;
            break;
          }
        }
      }
  return surface;
}

/// Distances (mm) from each surface voxel of `from` to the nearest surface voxel marked in `to`.
DirectedDistances surfaceDistances(const std::vector<uint8_t>& from, const std::vector<uint8_t>& to, const Grid& g) {
  const std::vector<double> dt = squaredDistanceTransform(to, g);
  DirectedDistances r;
  for (size_t n = 0; n < from.size(); ++n)
    if (from[n]) {
      r.d.push_back(std::sqrt(dt[n]));
      r.max = std::max(r.max, r.d.back());
    }
  r.w.assign(r.d.size(), 1.0);
  return r;
}

// ---- meshes -----------------------------------------------------------------------------------------------------

/// At most this many random samples per mesh.
constexpr long kMaxSamples = 200000;

/// Random points uniform by area on a mesh, and the area (mm²) each stands for.
struct AreaSamples {
  Points points;
  double areaPerSample = 0;
};

/// Uniform double in [0, 1) from 53 random bits (the same on every standard library, unlike the distributions).
double unit(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

/// About `perMm2` random points per mm² on `mesh`, uniform by area (fixed seed, so results are reproducible).
AreaSamples sampleByArea(const TriangleMesh& mesh, double perMm2) {
  std::vector<double> cumulative(static_cast<size_t>(mesh.faceCount()));
  double total = 0;
  for (int f = 0; f < mesh.faceCount(); ++f) {
    const Eigen::Vector3d a = mesh.vertices.row(mesh.faces(f, 0)), b = mesh.vertices.row(mesh.faces(f, 1)),
                          c = mesh.vertices.row(mesh.faces(f, 2));
    total += 0.5 * (b - a).cross(c - a).norm();
    cumulative[static_cast<size_t>(f)] = total;
  }
  if (!(total > 0)) throw Error("meshMetrics: a mesh has zero surface area");
  const long count = std::clamp(std::lround(perMm2 * total), 1L, kMaxSamples);
  AreaSamples s;
  s.points.resize(count, 3);
  s.areaPerSample = total / static_cast<double>(count);
  std::mt19937_64 rng(20240601);
  for (long n = 0; n < count; ++n) {
    const double pick = unit(rng) * total;
    const auto it = std::upper_bound(cumulative.begin(), cumulative.end(), pick);
    const int f = static_cast<int>(std::min<std::ptrdiff_t>(it - cumulative.begin(), mesh.faceCount() - 1));
    // Uniform point in a triangle: P = (1−√r1)·A + √r1(1−r2)·B + √r1·r2·C (Osada et al. 2002, eq. 1).
    const double r1 = std::sqrt(unit(rng)), r2 = unit(rng);
    s.points.row(n) = (1 - r1) * mesh.vertices.row(mesh.faces(f, 0)) +
                      r1 * (1 - r2) * mesh.vertices.row(mesh.faces(f, 1)) +
                      r1 * r2 * mesh.vertices.row(mesh.faces(f, 2));
  }
  return s;
}

/// Area-weighted distances from the surface of `from` to the surface of `to`; max also over `from`'s vertices.
DirectedDistances meshDistances(const TriangleMesh& from, const TriangleMesh& to, double perMm2) {
  const AreaSamples s = sampleByArea(from, perMm2);
  const detail::TriangleDistance tree(to, "point-to-mesh distance");
  DirectedDistances r;
  for (Eigen::Index q = 0; q < s.points.rows(); ++q) r.d.push_back(tree.distance(s.points.row(q).transpose()));
  r.w.assign(r.d.size(), s.areaPerSample);
  r.max = *std::max_element(r.d.begin(), r.d.end());
  for (Eigen::Index v = 0; v < from.vertices.rows(); ++v)
    r.max = std::max(r.max, tree.distance(from.vertices.row(v).transpose()));
  return r;
}

}  // namespace

SegmentationMetrics labelMetrics(const LabelMap& a, int32_t labelA, const LabelMap& b, int32_t labelB) {
  if (!a.grid.sameGeometry(b.grid, 1e-4)) throw Error("label maps are on different grids");
  const Grid& g = a.grid;
  if (a.data.size() != g.voxelCount() || b.data.size() != g.voxelCount())
    throw Error("label map data size does not match its grid");
  std::vector<uint8_t> inA(a.data.size()), inB(b.data.size());
  size_t nA = 0, nB = 0, nAB = 0;
  for (size_t n = 0; n < a.data.size(); ++n) {
    inA[n] = a.data[n] == labelA;
    inB[n] = b.data[n] == labelB;
    nA += inA[n];
    nB += inB[n];
    nAB += inA[n] & inB[n];
  }
  SegmentationMetrics m;
  const double voxelVolume = g.spacing.prod();
  m.volumeA = static_cast<double>(nA) * voxelVolume;
  m.volumeB = static_cast<double>(nB) * voxelVolume;
  setOverlap(m, static_cast<double>(nA), static_cast<double>(nB), static_cast<double>(nAB));
  if (nA == 0 || nB == 0) {
    setAllDistances(m, nA == nB ? 0.0 : kInf);
    return m;
  }
  const std::vector<uint8_t> surfA = surfaceOf(inA, g), surfB = surfaceOf(inB, g);
  setDistances(m, surfaceDistances(surfA, surfB, g), surfaceDistances(surfB, surfA, g));
  return m;
}

SegmentationMetrics meshMetrics(const TriangleMesh& a, const TriangleMesh& b, double voxelMm, double samplesPerMm2) {
  if (!(voxelMm > 0) || !std::isfinite(voxelMm))
    throw ParameterError("voxelMm", std::to_string(voxelMm), "must be > 0");
  if (!(samplesPerMm2 > 0) || !std::isfinite(samplesPerMm2))
    throw ParameterError("samplesPerMm2", std::to_string(samplesPerMm2), "must be > 0");
  if (const std::string p = closedMeshProblem(a); !p.empty()) throw Error("meshMetrics: mesh A: " + p);
  if (const std::string p = closedMeshProblem(b); !p.empty()) throw Error("meshMetrics: mesh B: " + p);

  // Common axis-aligned grid over both bounding boxes plus 2 voxels on every side.
  const Eigen::Vector3d lo =
      a.vertices.colwise().minCoeff().transpose().cwiseMin(b.vertices.colwise().minCoeff().transpose());
  const Eigen::Vector3d hi =
      a.vertices.colwise().maxCoeff().transpose().cwiseMax(b.vertices.colwise().maxCoeff().transpose());
  Grid grid;
  grid.spacing.setConstant(voxelMm);
  grid.origin = lo.array() - 2 * voxelMm;
  double voxels = 1;
  for (int c = 0; c < 3; ++c) {
    const double n = std::ceil((hi[c] - lo[c]) / voxelMm) + 5;
    voxels *= n;
    grid.dims[c] = static_cast<int>(std::min(n, 1e9));
  }
  if (voxels > 512.0 * 512.0 * 512.0)
    throw ParameterError("voxelMm", std::to_string(voxelMm),
                         "too small for the meshes' extent (" + std::to_string(voxels) + " voxels)");
  const LabelMap ra = rasterize(a, grid), rb = rasterize(b, grid);
  size_t nA = 0, nB = 0, nAB = 0;
  for (size_t n = 0; n < ra.data.size(); ++n) {
    const bool ia = ra.data[n] != 0, ib = rb.data[n] != 0;
    nA += ia;
    nB += ib;
    nAB += ia && ib;
  }
  SegmentationMetrics m;
  setOverlap(m, static_cast<double>(nA), static_cast<double>(nB), static_cast<double>(nAB));
  m.volumeA = enclosedVolume(a);
  m.volumeB = enclosedVolume(b);
  setDistances(m, meshDistances(a, b, samplesPerMm2), meshDistances(b, a, samplesPerMm2));
  return m;
}

}  // namespace msk
