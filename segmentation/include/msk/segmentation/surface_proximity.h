#pragma once
/// Proximity of closed surfaces: how far apart two templates are, and which of many come within a distance
/// (the "auto" collision pairs of a scene).
#include <utility>
#include <vector>

#include "msk/core/triangle_mesh.h"

namespace msk {

/// Separation of two closed surfaces, mm: 0 if they overlap (cross, or one lies inside the other), else the
/// smallest distance from a vertex of either surface to the other's triangles (exact point-to-triangle distance,
/// CGAL AABB tree). This bounds the true surface-to-surface distance from above and equals it when a closest pair
/// of points includes a vertex; edge-to-edge closest pairs are over-estimated by at most an edge's sagitta.
/// Throws Error if either mesh has no faces.
double surfaceSeparationMm(const TriangleMesh& a, const TriangleMesh& b);

/// Every pair (i, j), i < j, of closed surfaces whose separation is ≤ `withinMm` (≥ 0; throws ParameterError
/// otherwise), in lexicographic order. Pairs whose bounding boxes, grown by `withinMm`, do not meet are skipped
/// without a distance query, and only the vertices inside the partner's grown box are queried.
std::vector<std::pair<int, int>> surfacesWithin(const std::vector<const TriangleMesh*>& surfaces, double withinMm);

}  // namespace msk
