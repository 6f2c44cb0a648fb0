#pragma once
/// Surface quality of templates and results: isotropic remeshing and self-intersection counts (CGAL).
#include <cstddef>

#include "msk/core/triangle_mesh.h"

namespace msk {

/// A closed surface remeshed with near-equilateral triangles of one edge length, to about `targetVertices` vertices
/// (CGAL's isotropic remeshing: edge splits, collapses and flips, then tangential relaxation projected back onto the
/// input surface; the edge length comes from the area), then offset along its normals to enclose the input's volume. A
/// template of long thin triangles (decimated isosurfaces of elongated muscles: edges from 0.2 to 28 mm) has a badly
/// shaped 2-simplex dual whose vertices fold under image forces; remeshed, it does not (docs/method.md, Surface
/// quality). Deterministic; orientation and genus kept; per-vertex arrays dropped. A result that is not closed, or
/// crosses itself where the input does not, is tried again at edge lengths 3 % and 6 % shorter and longer; the input is
/// returned unchanged if none passes. Throws Error if the input is not closed, ParameterError if targetVertices < 4.
TriangleMesh remeshIsotropic(const TriangleMesh& mesh, int targetVertices);

/// Whether the triangles of a surface are already near-equilateral and of one size, as remeshIsotropic() leaves them:
/// the coefficient of variation of its edge lengths is below `maxVariation` (remeshed templates about 0.14, decimated
/// isosurfaces 0.7–0.9). Remeshing such a surface again moves its vertices without making its triangles better.
bool isotropicTriangulation(const TriangleMesh& mesh, double maxVariation = 0.3);

/// Number of pairs of faces of a closed mesh that intersect other than at a vertex or edge they share (CGAL box
/// intersection with exact predicates). 0 for a surface that is embedded. Throws Error if the mesh is not closed.
size_t selfIntersections(const TriangleMesh& mesh);

/// What makes a closed surface unusable as a template, or "": coordinates beyond ±1 km (not millimetres?), no enclosed
/// volume (zero area, or flat), or faces that cross each other in more than max(10, 0.5 % of the faces) pairs (the
/// inside of such a surface is not defined; fewer are local folds the evolution smooths out). A surface wound inward is
/// usable: scenes turn it outward.
std::string templateProblem(const TriangleMesh& mesh);

/// What unfoldSurface() did.
struct UnfoldReport {
  size_t before = 0, after = 0;  ///< self-intersecting face pairs before and after
  int rounds = 0;                ///< rounds run
  int verticesMoved = 0;         ///< distinct vertices moved
  double maxMoveMm = 0;          ///< largest distance a vertex moved, mm
};

/// Removes local folds of a closed surface: while faces cross each other (at most `maxRounds` rounds), the vertices of
/// the crossing faces and their neighbours within one ring (two from the fourth round on) are smoothed, three
/// half-steps toward the mean of their neighbours; nothing else moves. For the few folds an evolved surface can keep
/// where it is squeezed between partners. Throws Error if the mesh is not closed.
UnfoldReport unfoldSurface(TriangleMesh& mesh, int maxRounds = 8);

}  // namespace msk
