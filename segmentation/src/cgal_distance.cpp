#include "cgal_distance.h"

#include <cmath>

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

#include "msk/core/error.h"

namespace msk::detail {
namespace {

using Kernel = CGAL::Simple_cartesian<double>;
using Point = Kernel::Point_3;
using Triangle = Kernel::Triangle_3;
using TriangleIterator = std::vector<Triangle>::const_iterator;
using Primitive = CGAL::AABB_triangle_primitive<Kernel, TriangleIterator>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;

Point toPoint(const Eigen::Vector3d& p) { return Point(p[0], p[1], p[2]); }

}  // namespace

std::vector<double> pointToMeshDistances(const TriangleMesh& mesh, const Points& queries) {
  if (mesh.faceCount() == 0) throw Error("point-to-mesh distance: the mesh has no faces");
  std::vector<Triangle> triangles;
  triangles.reserve(static_cast<size_t>(mesh.faceCount()));
  for (int f = 0; f < mesh.faceCount(); ++f) {
    const Triangle t(toPoint(mesh.vertices.row(mesh.faces(f, 0)).transpose()),
                     toPoint(mesh.vertices.row(mesh.faces(f, 1)).transpose()),
                     toPoint(mesh.vertices.row(mesh.faces(f, 2)).transpose()));
    // Degenerate (collinear) faces add no surface; their edges belong to neighbouring faces.
    if (!t.is_degenerate()) triangles.push_back(t);
  }
  if (triangles.empty()) throw Error("point-to-mesh distance: every face of the mesh is degenerate");
  Tree tree(triangles.begin(), triangles.end());
  tree.accelerate_distance_queries();
  std::vector<double> d(static_cast<size_t>(queries.rows()));
  for (Eigen::Index q = 0; q < queries.rows(); ++q)
    d[static_cast<size_t>(q)] = std::sqrt(tree.squared_distance(toPoint(queries.row(q).transpose())));
  return d;
}

}  // namespace msk::detail
