#pragma once
/// The volumes tests and benchmarks share: ball and ellipsoid images with partial volume, ball label maps, a sphere's
/// signed distance, and the real-scan helpers (Dice, label centroids, boxes around meshes, crops). World mm throughout.
#include <Eigen/Core>
#include <functional>
#include <vector>

#include "msk/core/triangle_mesh.h"
#include "msk/imaging/volume.h"

namespace msk::test {

/// An image on `grid` with partial volume: each voxel is `inside` × f + `outside` × (1 − f), f the share of its 4³
/// sub-samples (world points) for which `isInside` holds.
ImageF partialVolumeImage(const Grid& grid, const std::function<bool(const Eigen::Vector3d&)>& isInside, float inside,
                          float outside);

/// An image on `grid` with partial volume: each voxel the mean of `intensity` over its 4³ sub-samples (world points).
ImageF sampledImage(const Grid& grid, const std::function<double(const Eigen::Vector3d&)>& intensity);

/// The ball |x − centre| ≤ radiusMm as a partialVolumeImage(): `inside` in, `outside` out.
ImageF ballImage(const Grid& grid, const Eigen::Vector3d& centre, double radiusMm, float inside, float outside);

/// The axis-aligned ellipsoid of semi-axes `axesMm` about `centre` as a partialVolumeImage().
ImageF ellipsoidImage(const Grid& grid, const Eigen::Vector3d& centre, const Eigen::Vector3d& axesMm, float inside,
                      float outside);

/// Sets `label` in every voxel of `labels` whose centre lies in the ball |x − centre| ≤ radiusMm (others kept).
void paintBall(LabelMap& labels, const Eigen::Vector3d& centre, double radiusMm, int label);

/// A label map on `grid`: `label` where the voxel centre lies in the ball |x − centre| ≤ radiusMm, 0 elsewhere.
LabelMap ballLabels(const Grid& grid, const Eigen::Vector3d& centre, double radiusMm, int label = 1);

/// Signed distance (mm) to the sphere of radius `radiusMm` about `centre` at every voxel centre, negative inside.
ImageF sphereSdf(const Grid& grid, const Eigen::Vector3d& centre, double radiusMm);

/// Dice 2|A∩B| / (|A|+|B|) between the voxels of `a` carrying `labelA` and those of `b` carrying `labelB` (same grid
/// size required; throws msk::Error otherwise); 1 when both are empty. Overlap only: labelMetrics() adds the
/// surface distances.
double labelDice(const LabelMap& a, int labelA, const LabelMap& b, int labelB);

/// Centroid (world mm) of the voxels carrying `label`; throws msk::Error if there are none.
Eigen::Vector3d labelCentroid(const LabelMap& labels, int label);

/// Voxel box [lo, hi] (inclusive, clipped to the grid) holding every vertex of `meshes` plus `marginMm`.
void voxelBox(const Grid& grid, const std::vector<TriangleMesh>& meshes, double marginMm, Eigen::Vector3i& lo,
              Eigen::Vector3i& hi);

/// The sub-volume of voxels [lo, hi] (inclusive), on a grid with the same spacing and direction (world positions kept).
ImageF cropVolume(const ImageF& image, const Eigen::Vector3i& lo, const Eigen::Vector3i& hi);

}  // namespace msk::test
