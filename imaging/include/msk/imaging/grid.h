#pragma once
/// The sampling grid of a volume in world space: the only place voxel↔world conversion happens.
#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <string>

namespace msk {

/// Voxel grid geometry. World = NIfTI RAS millimetres:
/// world = origin + direction · diag(spacing) · (i, j, k), voxel (0,0,0) at `origin`.
struct Grid {
  Eigen::Vector3i dims = Eigen::Vector3i::Ones();           ///< voxels along i, j, k
  Eigen::Vector3d spacing = Eigen::Vector3d::Ones();        ///< mm per voxel along i, j, k (all > 0)
  Eigen::Matrix3d direction = Eigen::Matrix3d::Identity();  ///< columns: unit RAS directions of i, j, k (det ±1)
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();         ///< RAS mm of voxel (0,0,0)

  /// Number of voxels.
  size_t voxelCount() const {
    return static_cast<size_t>(dims[0]) * static_cast<size_t>(dims[1]) * static_cast<size_t>(dims[2]);
  }
  /// Linear index of voxel (i, j, k), i fastest (NIfTI order).
  size_t index(int i, int j, int k) const {
    return static_cast<size_t>(i) +
           static_cast<size_t>(dims[0]) *
               (static_cast<size_t>(j) + static_cast<size_t>(dims[1]) * static_cast<size_t>(k));
  }
  /// True if integer voxel (i, j, k) lies in the grid.
  bool contains(int i, int j, int k) const {
    return i >= 0 && j >= 0 && k >= 0 && i < dims[0] && j < dims[1] && k < dims[2];
  }
  /// Calls f(base, stride) once for every line of voxels along `axis` (0, 1, 2): the line's voxels have linear
  /// indices base + p·stride for p in [0, dims[axis]). Separable filters and distance transforms run on these.
  template <typename F>
  void forEachLine(int axis, F&& f) const {
    const size_t stride = axis == 0   ? 1
                          : axis == 1 ? static_cast<size_t>(dims[0])
                                      : static_cast<size_t>(dims[0]) * static_cast<size_t>(dims[1]);
    const int u = axis == 0 ? 1 : 0, w = axis == 2 ? 1 : 2;  // the other two axes enumerate the lines
    for (int b = 0; b < dims[w]; ++b)
      for (int a = 0; a < dims[u]; ++a) {
        int ijk[3] = {0, 0, 0};
        ijk[u] = a;
        ijk[w] = b;
        f(index(ijk[0], ijk[1], ijk[2]), stride);
      }
  }
  /// 4×4 voxel→world affine (RAS mm).
  Eigen::Matrix4d voxelToWorld() const;
  /// 4×4 world→voxel affine.
  Eigen::Matrix4d worldToVoxel() const;
  /// World position (RAS mm) of continuous voxel coordinates.
  Eigen::Vector3d toWorld(const Eigen::Vector3d& ijk) const { return origin + direction * spacing.cwiseProduct(ijk); }
  /// Continuous voxel coordinates of a world position (RAS mm).
  Eigen::Vector3d toVoxel(const Eigen::Vector3d& xyz) const {
    return (direction.transpose() * (xyz - origin)).cwiseQuotient(spacing);
  }
  /// World-space axis-aligned bounding box of the voxel centres: {min, max}.
  std::array<Eigen::Vector3d, 2> worldBounds() const;
  /// Same dims, and affines equal within `tolMm` (per entry, mm).
  bool sameGeometry(const Grid& other, double tolMm = 1e-4) const;
  /// Empty if valid, otherwise what is wrong (dims ≤ 0, spacing ≤ 0 or non-finite, direction not orthonormal).
  std::string problem() const;

  /// Builds a grid from a 4×4 voxel→world affine whose 3×3 part is orthogonal up to per-column scale.
  /// Returns false (grid untouched) if a column is zero or columns are not orthogonal within `tolDegrees`.
  static bool fromAffine(const Eigen::Vector3i& dims, const Eigen::Matrix4d& affine, Grid& out,
                         double tolDegrees = 0.1);
  /// Direction matrix from rotations (degrees) about the x, then y, then z axes.
  static Eigen::Matrix3d rotationXYZ(const Eigen::Vector3d& degrees);
};

}  // namespace msk
