#pragma once
// CGAL adapter (private to msk_segmentation): exact point-to-triangle distances to a triangle mesh through CGAL's AABB
// tree, for the metrics and the surface proximity of scenes. CGAL stays in cgal_aabb.cpp.
#include <Eigen/Core>
#include <memory>
#include <string>

#include "msk/core/triangle_mesh.h"

namespace msk::detail {

/// Distances from points to the triangles of a mesh (any mesh: a triangle soup, degenerate faces left out, as their
/// edges belong to neighbouring faces).
class TriangleDistance {
 public:
  /// Builds the tree over `mesh`'s faces; throws Error naming `what` if the mesh has no face or every face is
  /// degenerate.
  TriangleDistance(const TriangleMesh& mesh, const std::string& what);
  ~TriangleDistance();
  TriangleDistance(const TriangleDistance&) = delete;
  TriangleDistance& operator=(const TriangleDistance&) = delete;
  /// Euclidean distance (mm) from `p` to the closest point of any triangle.
  double distance(const Eigen::Vector3d& p) const;

 private:
  struct Tree;
  std::unique_ptr<Tree> tree_;
};

}  // namespace msk::detail
