#pragma once
/// Volume → closed surface tools: isosurfaces in world space, decimation and non-shrinking smoothing.
#include "msk/core/triangle_mesh.h"
#include "msk/imaging/volume.h"

namespace msk {

/// Which side of the level is the object.
enum class IsoInside {
  Above,  ///< object = {field > level} (probability maps, intensities)
  Below   ///< object = {field < level} (signed distances, negative inside)
};

/// Options of isosurface().
struct IsosurfaceOptions {
  IsoInside inside = IsoInside::Above;  ///< which side of the level is enclosed
  bool largestComponentOnly = false;    ///< keep only the connected component with the most faces
};

/// Closed, outward-oriented surface of the object {field > level} (or < level, see options) in world RAS mm.
/// Marching cubes (VTK flying edges) in voxel-index space, then mapped with field.grid.toWorld, so any oblique
/// or improper (det −1) grid works. The field is padded with one voxel of outside value, so objects touching the
/// grid border are closed there. Empty mesh if no voxel is inside. The result passes closedMeshProblem().
TriangleMesh isosurface(const ImageF& field, double level, const IsosurfaceOptions& opts = {});

/// Quadric-error edge-collapse decimation (Garland–Heckbert, CGAL's triangle-quadric policies) of a closed mesh to
/// `targetVertices` vertices (returned unchanged if it has no more). Collapses obey the link condition and turn no
/// face by more than about 78°, so the result stays a closed, outward-oriented manifold of the same genus (it may keep
/// more vertices than asked if no legal collapse is left). Deterministic. Per-vertex arrays are dropped. Throws Error
/// if the input is not closed or has a vertex whose faces do not form one fan, ParameterError if targetVertices < 4.
TriangleMesh decimateMesh(const TriangleMesh& mesh, int targetVertices);

/// Windowed-sinc (non-shrinking, Taubin-like) smoothing: `iterations` (e.g. 10–30) with pass band `passBand`
/// in (0, 2) (smaller smooths more, e.g. 0.05–0.1). Connectivity and per-vertex arrays are kept.
/// Throws ParameterError for iterations < 0 or passBand outside (0, 2).
TriangleMesh smoothMesh(const TriangleMesh& mesh, int iterations, double passBand);

}  // namespace msk
