#pragma once
/// Closest points on a triangle mesh through a uniform grid over its faces' bounding boxes: the search structure of
/// collision partners (a bounded query, rebuilt every step) and of surface transfers (an unbounded query).
#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "msk/core/triangle_mesh.h"

namespace msk {

/// Closest point of a surface to a query point.
struct SurfacePoint {
  int triangle = -1;                                ///< −1 if nothing was found
  double bary[3] = {0, 0, 0};                       ///< barycentric weights on the triangle's corners (sum 1)
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  ///< the closest point, mm
  double distance = 0;                              ///< |point − query|, mm
};

/// A uniform grid listing each triangle in the cells its bounding box touches (cell lists in CSR form, each entry with
/// a copy of its triangle's box so that a query streams through a cell's list). The triangles are rows of a table over
/// the rows of a position array; both are passed to the queries, at the positions the grid was built for.
class TriangleGrid {
 public:
  /// The cells: the corner of cell (0, 0, 0), the cell size (mm) and the number of cells per axis. Points outside map
  /// to the nearest border cell.
  struct Layout {
    Eigen::Vector3d lo = Eigen::Vector3d::Zero();
    double cell = 1;
    Eigen::Vector3i dims = Eigen::Vector3i::Ones();
  };

  /// Lists every triangle of `tri` (rows of `p`) in the cells of `layout` its bounding box at `p` touches.
  void build(const Layout& layout, const Points& p, const Triangles& tri);
  /// Whether build() listed no triangle.
  bool empty() const { return entryTriangle_.empty(); }
  /// The layout of the last build().
  const Layout& layout() const { return layout_; }

  /// The closest point of the triangles to `q` no farther than `radius` (at most the cell size): the cells the ball
  /// touches within the 3×3×3 block around q's cell. Of equally close triangles (a shared vertex or edge) the one a
  /// scan of the block in z, y, x order meets first wins, then the lower index. `hint` (optional): a triangle likely
  /// to be the closest (the last answer for a point that has moved little); when it lies within `radius` the scan
  /// starts from it and skips the cells and triangles farther than it, with the same answer. `clearance` (optional):
  /// when nothing lies within `radius`, a distance (≥ radius) that no triangle is nearer than, from what the scan saw.
  /// Thread-safe.
  SurfacePoint closestWithin(const Points& p, const Triangles& tri, const Eigen::Vector3d& q, double radius,
                             int hint = -1, double* clearance = nullptr) const;

  /// The closest point of the triangles to `q` at any distance: rings of cells around q's cell until no triangle not
  /// yet seen can be closer (border cells reach to infinity outward); of equally close triangles the lower index
  /// wins. Not thread-safe (it marks the triangles a query has seen).
  SurfacePoint closest(const Points& p, const Triangles& tri, const Eigen::Vector3d& q) const;

 private:
  /// The cell holding `x` (clamped to the grid).
  Eigen::Vector3i cellOf(const Eigen::Vector3d& x) const {
    Eigen::Vector3i c;
    for (int a = 0; a < 3; ++a) c[a] = clampedCell((x[a] - layout_.lo[a]) / layout_.cell, a);
    return c;
  }
  /// The cell along axis `a` at `u` cell sizes from the grid's corner, clamped to the grid.
  int clampedCell(double u, int a) const {
    const double f = std::floor(u);
    return !(f >= 0) ? 0 : f >= layout_.dims[a] - 1 ? layout_.dims[a] - 1 : static_cast<int>(f);
  }
  size_t cellIndex(int x, int y, int z) const {
    const Eigen::Vector3i& d = layout_.dims;
    return (static_cast<size_t>(z) * static_cast<size_t>(d[1]) + static_cast<size_t>(y)) * static_cast<size_t>(d[0]) +
           static_cast<size_t>(x);
  }
  /// Squared distance from `q` to cell (x, y, z), border cells reaching to infinity outward.
  double cellDistance2(const Eigen::Vector3d& q, int x, int y, int z) const;
  /// A triangle's bounding box in floats rounded outward (a box the exact one lies in, so that a rejection by it is
  /// exact), and its index.
  struct CellItem {
    float lo[3], hi[3];
    int triangle;
  };
  static constexpr size_t kPad = 4;  ///< floats after the last entry's box, read (and discarded) by 4-wide tests
  Layout layout_;
  int triangles_ = 0;
  std::vector<int> start_;  ///< cell ci → its entries [start_[ci], start_[ci + 1]) (CSR; one spare entry)
  /// The cells' entries, each cell's by triangle index, in columns: the triangle's box, the triangle, and the axes
  /// along which the entry's cell is past the box's first cell (bits 0–2: x, y, z), from which a query tells whether
  /// an earlier cell of its scan listed the triangle too.
  std::vector<float> entryLo_[3], entryHi_[3];
  std::vector<int> entryTriangle_;
  std::vector<std::uint8_t> entryPast_;
  std::vector<CellItem> boxes_;                 ///< build(): each triangle's box (kept to reuse its memory)
  std::vector<std::array<int, 3>> firstCells_;  ///< each triangle's box's lowest cell
  std::vector<Eigen::Vector3i> lastCells_;      ///< build(): the cell of each box's highest corner
  mutable std::vector<int> seen_;               ///< closest(): the query that last examined each triangle
  mutable int query_ = 0;
};

}  // namespace msk
