#pragma once
/// How well a volume model's tet mesh sits on its surface: the distance from each surface vertex to the nearest
/// boundary node of the tets (the segmenter puts them on the surface's vertices, moving a few where the surface leaves
/// no room for its tets); and the residuals of its 3-simplex constraints.
#include "msk/core/triangle_mesh.h"
#include "msk/core/volume_simplex.h"

namespace msk::test {

/// The surface's vertices against the tet mesh's boundary nodes.
struct TetSurfaceOffsets {
  int boundaryNodes = 0;    ///< nodes of the tet boundary
  int surfaceVertices = 0;  ///< vertices of the surface
  int offSurface = 0;       ///< surface vertices with no boundary node within 1e-3 mm
  double largestMm = 0;     ///< the largest distance from a surface vertex to its nearest boundary node
  double meanEdgeMm = 0;    ///< the surface's mean edge length
};
TetSurfaceOffsets tetSurfaceOffsets(const TetMesh& tets, const TriangleMesh& surface);

/// The 3-simplex constraint's residual C = Σ ε̃i Pi − P of every vertex of `model` at `positions` (its rows with
/// VolumeBoundary::Constrained; zero for vertices without one), mm.
Points volumeResiduals(const VolumeSimplexMesh& model, const Points& positions);

}  // namespace msk::test
