#include "msk/core/triangle_grid.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "msk/core/simplex_mesh.h"

namespace msk {

void TriangleGrid::build(const Layout& layout, const Points& p, const Triangles& tri) {
  layout_ = layout;
  triangles_ = static_cast<int>(tri.rows());
  const size_t cells =
      static_cast<size_t>(layout.dims[0]) * static_cast<size_t>(layout.dims[1]) * static_cast<size_t>(layout.dims[2]);
  // Cell ci's entries are [start_[ci], start_[ci + 1]); the counts go two places up so that the prefix sums leave
  // start_[ci + 1] at the cell's first item, the fill's cursor, which the fill then moves on to the next cell's first.
  start_.assign(cells + 2, 0);
  seen_.clear();  // closest() sizes it on first use
  query_ = 0;
  std::vector<CellItem>& boxes = boxes_;
  boxes.resize(static_cast<size_t>(triangles_));
  firstCells_.resize(static_cast<size_t>(triangles_));
  lastCells_.resize(static_cast<size_t>(triangles_));
  for (int t = 0; t < triangles_; ++t) {
    const Eigen::Vector3d x[3] = {p.row(tri(t, 0)), p.row(tri(t, 1)), p.row(tri(t, 2))};
    const Eigen::Vector3d lo = x[0].cwiseMin(x[1]).cwiseMin(x[2]), hi = x[0].cwiseMax(x[1]).cwiseMax(x[2]);
    CellItem& item = boxes[static_cast<size_t>(t)];
    // Grown by a millionth (more than a float's rounding, 2^-24 of the value) before rounding to float.
    for (int a = 0; a < 3; ++a) {
      item.lo[a] = static_cast<float>(lo[a] - (std::abs(lo[a]) + 1) * 1e-6);
      item.hi[a] = static_cast<float>(hi[a] + (std::abs(hi[a]) + 1) * 1e-6);
    }
    item.triangle = t;
    const Eigen::Vector3i first = cellOf(lo);
    firstCells_[static_cast<size_t>(t)] = {first[0], first[1], first[2]};
    lastCells_[static_cast<size_t>(t)] = cellOf(hi);
  }
  // visit(cell index, the axes along which the cell is past the box's first cell, as bits 0–2).
  auto forCells = [&](int t, auto&& visit) {
    const std::array<int, 3>& a = firstCells_[static_cast<size_t>(t)];
    const Eigen::Vector3i& b = lastCells_[static_cast<size_t>(t)];
    for (int z = a[2]; z <= b[2]; ++z)
      for (int y = a[1]; y <= b[1]; ++y)
        for (int x = a[0]; x <= b[0]; ++x)
          visit(cellIndex(x, y, z), static_cast<std::uint8_t>((x > a[0]) | (y > a[1]) << 1 | (z > a[2]) << 2));
  };
  for (int t = 0; t < triangles_; ++t) forCells(t, [&](size_t ci, std::uint8_t) { ++start_[ci + 2]; });
  for (size_t i = 2; i < cells + 2; ++i) start_[i] += start_[i - 1];
  // Resized, not cleared: every entry is written below (and the padding after the last is read by the 4-wide box
  // test, whose lanes past a cell's end are discarded).
  const size_t entries = static_cast<size_t>(start_[cells + 1]);
  for (int a = 0; a < 3; ++a) {
    entryLo_[a].resize(entries + kPad);
    entryHi_[a].resize(entries + kPad);
  }
  entryTriangle_.resize(entries);
  entryPast_.resize(entries);
  for (int t = 0; t < triangles_; ++t)
    forCells(t, [&](size_t ci, std::uint8_t past) {
      const size_t k = static_cast<size_t>(start_[ci + 1]++);
      const CellItem& box = boxes[static_cast<size_t>(t)];
      for (int a = 0; a < 3; ++a) {
        entryLo_[a][k] = box.lo[a];
        entryHi_[a][k] = box.hi[a];
      }
      entryTriangle_[k] = t;
      entryPast_[k] = past;
    });
}

SurfacePoint TriangleGrid::closestWithin(const Points& p, const Triangles& tri, const Eigen::Vector3d& q, double radius,
                                         int hint, double* clearance) const {
  SurfacePoint best;
  best.distance = radius;
  // Only the cells the ball of `radius` around q touches (at most 2 per axis, as cells are at least `radius` wide),
  // within the 3×3×3 block around q's cell; the result is that of scanning the whole block, each cell's triangles by
  // index, keeping the first of equally close ones: the least (distance, key), the key ordering the block's cells in
  // z, y, x order, then the triangles by index.
  // q's cell, and below the cells the ball of the search radius touches, from q's position in cell units (one
  // division per axis; the ball's cells are found with a slack far above the rounding of that position).
  double u[3];
  Eigen::Vector3i c;
  for (int a = 0; a < 3; ++a) {
    u[a] = (q[a] - layout_.lo[a]) / layout_.cell;
    c[a] = clampedCell(u[a], a);
  }
  auto keyOf = [&](const std::array<int, 3>& cell, int t) {
    const Eigen::Vector3i first = Eigen::Vector3i(cell[0], cell[1], cell[2]).cwiseMax(c - Eigen::Vector3i::Ones());
    return cellIndex(first[0], first[1], first[2]) * static_cast<size_t>(triangles_) + static_cast<size_t>(t);
  };
  size_t bestKey = 0;
  if (hint >= 0 && hint < triangles_ && firstCells_.size() == static_cast<size_t>(triangles_)) {
    Eigen::Vector3d bc;
    const Eigen::Vector3d cp = closestPointOnTriangle(
        q, p.row(tri(hint, 0)).transpose(), p.row(tri(hint, 1)).transpose(), p.row(tri(hint, 2)).transpose(), &bc);
    const double d = (cp - q).norm();
    if (d < radius) {
      best.distance = d;
      best.point = cp;
      best.triangle = hint;
      bestKey = keyOf(firstCells_[static_cast<size_t>(hint)], hint);
      for (int i = 0; i < 3; ++i) best.bary[i] = bc[i];
    }
  }
  const double padCells = (best.distance * (1 + 1e-9) + 1e-9) / layout_.cell;  // a superset of the touched cells
  Eigen::Vector3i from, to;
  for (int a = 0; a < 3; ++a) {
    from[a] = std::max(clampedCell(u[a] - padCells, a), c[a] - 1);
    to[a] = std::min(clampedCell(u[a] + padCells, a), c[a] + 1);
  }
  double nearestSq = std::numeric_limits<double>::infinity();  // of the triangles examined and passed over
  bool improved = true;  // the best distance changed since the 4-wide test's limit was set
  // The entry at k: passed over if its triangle was met in an earlier scanned cell; else its box is tested in double
  // (with a margin for rounding, so that a triangle exactly as close, sharing the best one's vertex, always reaches
  // the comparison of keys), then its closest point.
  auto examine = [&](int k, std::uint8_t firstScanned) {
    const size_t e = static_cast<size_t>(k);
    if (entryPast_[e] & ~firstScanned) return;
    double boxSq = 0;
    for (int a = 0; a < 3; ++a) {
      const double out = std::max(std::max(entryLo_[a][e] - q[a], q[a] - entryHi_[a][e]), 0.0);
      boxSq += out * out;
    }
    if (boxSq > best.distance * best.distance * (1 + 1e-12)) {
      nearestSq = std::min(nearestSq, boxSq);
      return;
    }
    const int t = entryTriangle_[e];
    Eigen::Vector3d bc;
    const Eigen::Vector3d cp = closestPointOnTriangle(q, p.row(tri(t, 0)).transpose(), p.row(tri(t, 1)).transpose(),
                                                      p.row(tri(t, 2)).transpose(), &bc);
    const double d = (cp - q).norm();
    if (!(d <= best.distance)) {
      nearestSq = std::min(nearestSq, d * d);
      return;
    }
    const size_t key = keyOf(firstCells_[static_cast<size_t>(t)], t);
    if (d == best.distance && (best.triangle < 0 || key >= bestKey)) return;
    improved = true;
    best.distance = d;
    best.point = cp;
    best.triangle = t;
    bestKey = key;
    for (int i = 0; i < 3; ++i) best.bary[i] = bc[i];
  };
  // A triangle listed in several of the scanned cells is examined once, in the first of them (the result does not
  // depend on the order: the closest wins, then the lowest key). Along each axis that first cell is the box's first
  // cell or the first scanned, so an entry is passed over where it is past its box's first cell along an axis along
  // which this cell is not the first scanned.
#if defined(__SSE2__)
  // Four entries' boxes at a time in float (SSE2, part of x86-64): an entry whose float box distance exceeds the best
  // distance plus `slack` (far above that distance's rounding error: q's rounding to float, 2^-24 of its coordinates,
  // and a few roundings of the distance) is passed over without the tests above; the least such distance, less the
  // slack, bounds those entries for the clearance.
  const double slack = 1e-6 * (1.0 + q.cwiseAbs().maxCoeff() + radius);
  const __m128 qx = _mm_set1_ps(static_cast<float>(q[0])), qy = _mm_set1_ps(static_cast<float>(q[1])),
               qz = _mm_set1_ps(static_cast<float>(q[2])), zero = _mm_setzero_ps();
  const __m128 inf = _mm_set1_ps(std::numeric_limits<float>::infinity());
  const __m128i laneIndex = _mm_set_epi32(3, 2, 1, 0);
  __m128 leastPassed = inf;  // per lane: the least float box distance² of the entries passed over
  __m128 limit = inf;        // the float box distance² beyond which an entry is passed over
#endif
  for (int z = from[2]; z <= to[2]; ++z)
    for (int y = from[1]; y <= to[1]; ++y)
      for (int x = from[0]; x <= to[0]; ++x) {
        const size_t ci = cellIndex(x, y, z);
        const auto firstScanned = static_cast<std::uint8_t>((x == from[0]) | (y == from[1]) << 1 | (z == from[2]) << 2);
        const int end = start_[ci + 1];
#if defined(__SSE2__)
        for (int k = start_[ci]; k < end; k += 4) {
          if (improved) {
            const double reach = best.distance + slack;
            limit =
                _mm_set1_ps(std::nextafter(static_cast<float>(reach * reach), std::numeric_limits<float>::infinity()));
            improved = false;
          }
          const size_t e = static_cast<size_t>(k);
          auto outsideSq = [&](int a, __m128 qa) {
            const __m128 lo = _mm_loadu_ps(&entryLo_[a][e]), hi = _mm_loadu_ps(&entryHi_[a][e]);
            const __m128 out = _mm_max_ps(_mm_max_ps(_mm_sub_ps(lo, qa), _mm_sub_ps(qa, hi)), zero);
            return _mm_mul_ps(out, out);
          };
          const __m128 sq = _mm_add_ps(_mm_add_ps(outsideSq(0, qx), outsideSq(1, qy)), outsideSq(2, qz));
          const __m128 near = _mm_cmple_ps(sq, limit);
          const int lanes = std::min(4, end - k);
          const int valid = (1 << lanes) - 1;
          const int hits = _mm_movemask_ps(near) & valid;
          if (hits != valid) {  // the valid lanes not near into the running least, the others as infinite
            const __m128 inCell = _mm_castsi128_ps(_mm_cmplt_epi32(laneIndex, _mm_set1_epi32(lanes)));
            const __m128 passed = _mm_andnot_ps(near, inCell);
            leastPassed = _mm_min_ps(leastPassed, _mm_or_ps(_mm_and_ps(passed, sq), _mm_andnot_ps(passed, inf)));
          }
          for (int lane = 0; lane < lanes; ++lane)
            if (hits >> lane & 1) examine(k + lane, firstScanned);
        }
#else
        for (int k = start_[ci]; k < end; ++k) examine(k, firstScanned);
#endif
      }
#if defined(__SSE2__)
  float least[4];
  _mm_storeu_ps(least, leastPassed);
  const double leastSq = std::min(std::min(least[0], least[1]), std::min(least[2], least[3]));
  if (leastSq < std::numeric_limits<float>::infinity()) {
    const double bound = std::max(0.0, std::sqrt(leastSq) - slack);
    nearestSq = std::min(nearestSq, bound * bound);
  }
#endif
  if (clearance && best.triangle < 0) {
    // A triangle listed in none of the scanned cells has its box outside the block of them (a border cell reaches to
    // infinity outward); every listed one was examined, its box or its closest point at nearestSq or farther.
    double bound = std::sqrt(nearestSq);
    for (int a = 0; a < 3; ++a) {
      if (from[a] > 0) bound = std::min(bound, q[a] - (layout_.lo[a] + from[a] * layout_.cell));
      if (to[a] < layout_.dims[a] - 1) bound = std::min(bound, layout_.lo[a] + (to[a] + 1) * layout_.cell - q[a]);
    }
    *clearance = std::max(bound, 0.0);
  }
  return best;
}

double TriangleGrid::cellDistance2(const Eigen::Vector3d& q, int x, int y, int z) const {
  const int cell[3] = {x, y, z};
  double s = 0;
  for (int i = 0; i < 3; ++i) {
    const double lo = cell[i] == 0 ? -std::numeric_limits<double>::infinity() : layout_.lo[i] + cell[i] * layout_.cell;
    const double hi = cell[i] == layout_.dims[i] - 1 ? std::numeric_limits<double>::infinity()
                                                     : layout_.lo[i] + (cell[i] + 1) * layout_.cell;
    const double d = q[i] < lo ? lo - q[i] : (q[i] > hi ? q[i] - hi : 0.0);
    s += d * d;
  }
  return s;
}

SurfacePoint TriangleGrid::closest(const Points& p, const Triangles& tri, const Eigen::Vector3d& q) const {
  const Eigen::Vector3i c = cellOf(q);
  const Eigen::Vector3i& dims = layout_.dims;
  if (seen_.size() != static_cast<size_t>(triangles_)) seen_.assign(static_cast<size_t>(triangles_), -1);
  const int id = query_++;
  SurfacePoint best;
  double best2 = std::numeric_limits<double>::infinity();
  const int maxRing = dims.maxCoeff();
  for (int r = 0; r <= maxRing; ++r) {
    for (int dz = -r; dz <= r; ++dz) {
      const int z = c[2] + dz;
      if (z < 0 || z >= dims[2]) continue;
      for (int dy = -r; dy <= r; ++dy) {
        const int y = c[1] + dy;
        if (y < 0 || y >= dims[1]) continue;
        const bool shell = std::abs(dz) == r || std::abs(dy) == r;
        for (int dx = -r; dx <= r; dx += shell ? 1 : std::max(1, 2 * r)) {
          const int x = c[0] + dx;
          if (x < 0 || x >= dims[0]) continue;
          if (cellDistance2(q, x, y, z) >= best2) continue;
          const size_t ci = cellIndex(x, y, z);
          for (int k = start_[ci]; k < start_[ci + 1]; ++k) {
            const int t = entryTriangle_[static_cast<size_t>(k)];
            if (seen_[static_cast<size_t>(t)] == id) continue;
            seen_[static_cast<size_t>(t)] = id;
            Eigen::Vector3d bary;
            const Eigen::Vector3d cp =
                closestPointOnTriangle(q, p.row(tri(t, 0)), p.row(tri(t, 1)), p.row(tri(t, 2)), &bary);
            const double d2 = (cp - q).squaredNorm();
            if (d2 < best2 || (d2 == best2 && t < best.triangle)) {
              best2 = d2;
              best.triangle = t;
              best.point = cp;
              for (int i = 0; i < 3; ++i) best.bary[i] = bary[i];
            }
          }
        }
      }
    }
    // Every triangle not yet seen lies in cells outside the cube of rings 0..r around c: bound its distance.
    double bound = std::numeric_limits<double>::infinity();
    for (int i = 0; i < 3; ++i) {
      if (c[i] - r > 0) bound = std::min(bound, std::max(0.0, q[i] - (layout_.lo[i] + (c[i] - r) * layout_.cell)));
      if (c[i] + r < dims[i] - 1)
        bound = std::min(bound, std::max(0.0, layout_.lo[i] + (c[i] + r + 1) * layout_.cell - q[i]));
    }
    if (best2 <= bound * bound) break;  // also ends once the cube covers the grid (bound = ∞)
  }
  best.distance = std::sqrt(best2);
  return best;
}

}  // namespace msk
