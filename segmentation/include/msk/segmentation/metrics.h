#pragma once
/// Segmentation metrics between label maps and between meshes, in mm (definitions in docs/measurements.md).
#include <cstdint>

#include "msk/core/triangle_mesh.h"
#include "msk/imaging/volume.h"

namespace msk {

/// Overlap and boundary distances between two segmentations A (result) and B (reference).
struct SegmentationMetrics {
  double dice = 0;                  ///< 2|A∩B| / (|A|+|B|)
  double jaccard = 0;               ///< |A∩B| / |A∪B|
  double assd = 0;                  ///< average symmetric surface distance, mm
  double meanAtoB = 0;              ///< mean distance from A's surface to B's, mm
  double meanBtoA = 0;              ///< mean distance from B's surface to A's, mm
  double hd95 = 0;                  ///< 95th percentile of the pooled symmetric surface distances, mm
  double hausdorff = 0;             ///< maximum symmetric surface distance, mm
  double volumeA = 0, volumeB = 0;  ///< mm³
};

/// Metrics between the voxels equal to `labelA` in `a` and `labelB` in `b` (same grid required; throws Error
/// otherwise). Surface = foreground voxels with a 6-neighbour outside the object; distances are Euclidean between voxel
/// centres in world mm (exact distance transform with the grid's spacing; direction does not change distances).
SegmentationMetrics labelMetrics(const LabelMap& a, int32_t labelA, const LabelMap& b, int32_t labelB);

/// Metrics between two closed meshes: overlap from signed volumes of the intersection is not needed here,
/// so dice/jaccard are computed by rasterising both on a common grid of `voxelMm`; surface distances are
/// point-to-surface (exact, CGAL AABB tree), area-weighted over `samplesPerMm2` random surface samples plus vertices.
SegmentationMetrics meshMetrics(const TriangleMesh& a, const TriangleMesh& b, double voxelMm = 0.5,
                                double samplesPerMm2 = 4.0);

}  // namespace msk
