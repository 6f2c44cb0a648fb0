#pragma once
/// Mending a surface that is nearly closed: the two faults that exporters commonly leave in an otherwise sound surface
/// (vertices written once per face or per texture seam, small holes), fixed where that cannot change the shape.
#include <string>

#include "msk/core/triangle_mesh.h"

namespace msk {

/// What mendSurface() did.
struct MeshMending {
  int mergedVertices = 0;    ///< vertices merged into another at exactly the same position
  int droppedFaces = 0;      ///< faces dropped: degenerate after the merge (a repeated vertex) or duplicated
  int filledHoles = 0;       ///< holes closed by triangulation
  int largestHoleEdges = 0;  ///< edges around the largest hole closed
  /// One sentence for a warning: what was merged and filled ("" if nothing was).
  std::string summary() const;
};

/// A hole may be filled if its border has at most this many edges...
constexpr int kMaxFilledHoleEdges = 32;
/// ...and its perimeter is at most this share of the surface's bounding-box diagonal.
constexpr double kMaxFilledHolePerimeterShare = 0.25;

/// Mends `mesh` in place: merges vertices at exactly the same position (keeping the first), drops the faces this
/// leaves degenerate or duplicated, then fills every hole whose border has at most kMaxFilledHoleEdges edges and
/// a perimeter of at most kMaxFilledHolePerimeterShare of the bounding-box diagonal (CGAL's hole triangulation, which
/// adds no vertex). Larger holes stay (an open surface, e.g. a muscle cut by the scan's edge, is no template); faces
/// that cannot form a manifold surface stay as they are. Per-vertex arrays follow the merge (no vertex is added).
/// Returns what it did.
MeshMending mendSurface(TriangleMesh& mesh);

}  // namespace msk
