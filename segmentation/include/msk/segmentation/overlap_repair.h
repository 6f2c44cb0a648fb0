#pragma once
/// Last guard of a multi-object result: voxel centres that lie inside both output surfaces of a declared pair are
/// handed to one of the two, so that no voxel of the label map is claimed twice by collision partners.
#include <utility>
#include <vector>

#include "msk/core/triangle_mesh.h"
#include "msk/imaging/volume.h"

namespace msk {

/// What repairOverlapVoxels() did.
struct OverlapRepairReport {
  long handedOver = 0;   ///< voxel centres handed to one surface, over all rounds
  int rounds = 0;        ///< rounds that found shared centres
  size_t remaining = 0;  ///< centres still inside both surfaces of a pair after the last round
};

/// The voxels of `grid` whose centre lies inside `surface` (rasterize()'s rule), as sorted linear indices: the
/// compact form of a mask that repairOverlapVoxels() keeps per surface (a scene of many objects would otherwise hold
/// one full-grid label map per object).
std::vector<size_t> insideVoxels(const TriangleMesh& surface, const Grid& grid);

/// Hands every voxel centre c of `grid` inside both surfaces of a pair (i, j) of `surfaces` (closed, outward; `inside`
/// their insideVoxels() on `grid`) to the surface that holds it least deep: with d the distance from c to that
/// surface's closest triangle (CollisionSurface::closest, within 4 × the largest spacing), the triangle's corners move
/// by d + `marginMm` against its normal, so c ends `marginMm` outside. A corner asked to move by several centres takes
/// the longest move. Moves are inward only, so no new shared centre appears; the moved surfaces' `inside` lists are
/// computed again and the check repeats, at most `maxRounds` times.
///
/// Why it is needed after the output separation (core/surface_separation.h): that tests vertices and face centroids,
/// and two triangles whose edges cross between those samples can still share a thin lens of space. Throws
/// ParameterError for a negative or non-finite margin, maxRounds < 0, a pair index out of range or `inside` of another
/// size than the surfaces.
OverlapRepairReport repairOverlapVoxels(const std::vector<TriangleMesh*>& surfaces,
                                        const std::vector<std::pair<int, int>>& pairs, const Grid& grid,
                                        double marginMm, std::vector<std::vector<size_t>>& inside, int maxRounds = 4);

}  // namespace msk
