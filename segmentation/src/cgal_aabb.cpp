#include "cgal_aabb.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

#include <cmath>
#include <vector>

#include "msk/core/error.h"

namespace msk::detail {

namespace {
using Kernel = CGAL::Simple_cartesian<double>;
using Point = Kernel::Point_3;
using Triangle = Kernel::Triangle_3;
using Primitive = CGAL::AABB_triangle_primitive<Kernel, std::vector<Triangle>::const_iterator>;
using AabbTree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;

Point toPoint(const Eigen::Vector3d& p) { return Point(p[0], p[1], p[2]); }
}  // namespace

struct TriangleDistance::Tree {
  std::vector<Triangle> triangles;  // the tree refers to them
  AabbTree tree;
};

TriangleDistance::TriangleDistance(const TriangleMesh& mesh, const std::string& what)
    : tree_(std::make_unique<Tree>()) {
  if (mesh.faceCount() == 0) throw Error(what + ": the mesh has no faces");
  tree_->triangles.reserve(static_cast<size_t>(mesh.faceCount()));
  for (int f = 0; f < mesh.faceCount(); ++f) {
    const Triangle t(toPoint(mesh.vertices.row(mesh.faces(f, 0)).transpose()),
                     toPoint(mesh.vertices.row(mesh.faces(f, 1)).transpose()),
                     toPoint(mesh.vertices.row(mesh.faces(f, 2)).transpose()));
    if (!t.is_degenerate()) tree_->triangles.push_back(t);
  }
  if (tree_->triangles.empty()) throw Error(what + ": every face of the mesh is degenerate");
  tree_->tree.insert(tree_->triangles.begin(), tree_->triangles.end());
  tree_->tree.build();
  tree_->tree.accelerate_distance_queries();
}

TriangleDistance::~TriangleDistance() = default;

double TriangleDistance::distance(const Eigen::Vector3d& p) const {
  return std::sqrt(tree_->tree.squared_distance(toPoint(p)));
}

}  // namespace msk::detail
