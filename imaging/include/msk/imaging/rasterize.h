#pragma once
/// Closed surface mesh → label map on any grid (oblique and anisotropic included).
#include <vector>

#include "msk/core/triangle_mesh.h"
#include "msk/imaging/volume.h"

namespace msk {

/// Sets `label` in every voxel of `labels` whose centre lies inside the closed mesh (world mm).
/// Voxels already non-zero are overwritten. Throws Error if the mesh is not closed.
void rasterizeInto(LabelMap& labels, const TriangleMesh& mesh, int32_t label);

/// A new label map on `grid`: 1 inside the mesh, 0 outside.
LabelMap rasterize(const TriangleMesh& mesh, const Grid& grid);

/// The indices (Grid::index) of the voxels rasterize() sets to 1, ascending, without a label map.
std::vector<size_t> insideVoxelIndices(const TriangleMesh& mesh, const Grid& grid);

}  // namespace msk
