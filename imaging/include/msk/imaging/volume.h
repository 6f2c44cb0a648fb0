#pragma once
/// A scalar volume in world space: a Grid plus voxel values (i fastest).
#include <cstdint>
#include <vector>

#include "msk/core/large_buffer.h"
#include "msk/imaging/grid.h"

namespace msk {

/// Voxel values of type T on a world-space grid.
template <typename T>
struct Volume {
  Grid grid;            ///< geometry
  LargeVector<T> data;  ///< grid.voxelCount() values, i fastest (huge pages where the kernel offers them)

  Volume() = default;
  /// Allocates a volume on `g` filled with `fill`.
  explicit Volume(const Grid& g, T fill = T()) : grid(g), data(g.voxelCount(), fill) {}
  /// Value at voxel (i, j, k); no bounds check.
  T& at(int i, int j, int k) { return data[grid.index(i, j, k)]; }
  /// Value at voxel (i, j, k); no bounds check.
  const T& at(int i, int j, int k) const { return data[grid.index(i, j, k)]; }
};

/// Intensity image (processing precision).
using ImageF = Volume<float>;
/// Label map (0 = background).
using LabelMap = Volume<int32_t>;

}  // namespace msk
