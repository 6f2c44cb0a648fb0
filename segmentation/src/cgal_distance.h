#pragma once
/// CGAL adapter (private to msk_segmentation): exact point-to-triangle-mesh distances with an AABB tree.
#include <vector>

#include "msk/core/triangle_mesh.h"

namespace msk::detail {

/// Euclidean distance (mm) from each row of `queries` (#Q×3, world mm) to the closest point on any triangle of
/// `mesh` (exact point-to-triangle distance, CGAL AABB tree). Throws Error if the mesh has no faces.
std::vector<double> pointToMeshDistances(const TriangleMesh& mesh, const Points& queries);

}  // namespace msk::detail
