// CGAL adapter behind decimateMesh() (declared in msk/imaging/surface_extraction.h): quadric-error edge collapse with
// CGAL's Surface_mesh_simplification on a CGAL::Surface_mesh.
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/GarlandHeckbert_triangle_policies.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cstddef>
#include <string>

#include "msk/core/error.h"
#include "msk/imaging/detail/cgal_mesh.h"
#include "msk/imaging/surface_extraction.h"

namespace msk {

namespace {

namespace SMS = CGAL::Surface_mesh_simplification;
using detail::CgalKernel;
using detail::CgalMesh;

/// Stop predicate: true once the mesh has at most `targetVertices` vertices. A collapse on a closed triangle mesh
/// removes 1 vertex, 3 edges and 2 faces and so keeps the Euler characteristic χ = V − E + F; with F = 2E/3 that
/// gives V = E/3 + χ, so the edge count CGAL passes in tells the vertex count.
class VertexCountStop {
 public:
  /// `euler` is χ of the input.
  VertexCountStop(long long targetVertices, long long euler)
      : maxEdges_(static_cast<std::size_t>(std::max(0LL, 3 * (targetVertices - euler)))) {}
  /// True if the collapse should stop.
  template <typename Cost, typename Profile>
  bool operator()(const Cost&, const Profile&, std::size_t /*initialEdges*/, std::size_t currentEdges) const {
    return currentEdges <= maxEdges_;
  }

 private:
  std::size_t maxEdges_;
};

/// Collapse filter: refuses a placement that turns any face of the edge's star (other than the two that vanish) by
/// more than acos(kMinCos) ≈ 78° or shrinks it to (nearly) zero area, so no face flips or nearly flips.
/// CGAL's Bounded_normal_change_filter refuses only turns beyond 90°.
class FaceTurnFilter {
 public:
  /// The placement, or none if it turns a face too far.
  template <typename Profile>
  boost::optional<typename Profile::Point> operator()(const Profile& profile,
                                                      boost::optional<typename Profile::Point> placement) const {
    if (!placement) return placement;
    auto point = [&profile](typename Profile::vertex_descriptor v) {
      const auto& p = get(profile.vertex_point_map(), v);
      return Eigen::Vector3d(p.x(), p.y(), p.z());
    };
    const Eigen::Vector3d x(placement->x(), placement->y(), placement->z());
    // triangles(): the faces left and right of the edge first (if they exist), then the star's other faces, each
    // with the vertex that moves to the placement as v1.
    const auto& triangles = profile.triangles();
    auto t = triangles.begin();
    if (profile.left_face_exists()) ++t;
    if (profile.right_face_exists()) ++t;
    for (; t != triangles.end(); ++t) {
      const Eigen::Vector3d a = point(t->v0), moved = point(t->v1), c = point(t->v2);
      const Eigen::Vector3d n0 = (a - moved).cross(c - moved), n1 = (a - x).cross(c - x);
      const double l0 = n0.norm(), l1 = n1.norm();
      if (l1 <= 1e-12 * (l0 + 1e-300) || !(n0.dot(n1) > kMinCos * l0 * l1)) return boost::none;
    }
    return placement;
  }

 private:
  static constexpr double kMinCos = 0.2;
};

}  // namespace

TriangleMesh decimateMesh(const TriangleMesh& mesh, int targetVertices) {
  if (targetVertices < 4) throw ParameterError("targetVertices", std::to_string(targetVertices), "must be at least 4");
  const std::string inProblem = closedMeshProblem(mesh);
  if (!inProblem.empty()) throw Error("decimateMesh: input mesh is not closed: " + inProblem);
  if (mesh.vertexCount() <= targetVertices) return mesh;

  CgalMesh cgal = detail::toCgalMesh(mesh, "decimateMesh");
  {
    // Garland–Heckbert ("Surface simplification using quadric error metrics", 1997) cost and optimal placement, with
    // quadrics of the distance to the faces' triangles rather than to their planes: better-shaped triangles at the
    // same accuracy. CGAL checks the link condition. The policies keep their quadrics as a property of `cgal`,
    // removed when they go out of scope.
    // CGAL fills each vertex's quadric with a copy of a default-constructed (uninitialised) Eigen matrix and zeroes
    // them all before use; GCC warns about the copy.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
    SMS::GarlandHeckbert_triangle_policies<CgalMesh, CgalKernel> policies(cgal);
#pragma GCC diagnostic pop
    const long long euler = mesh.vertexCount() - mesh.faceCount() / 2;  // V − E + F with E = 3F/2
    SMS::edge_collapse(cgal, VertexCountStop(targetVertices, euler),
                       CGAL::parameters::get_cost(policies.get_cost())
                           .get_placement(policies.get_placement())
                           .filter(FaceTurnFilter()));
  }
  TriangleMesh m = detail::fromCgalMesh(std::move(cgal));
  const std::string problem = closedMeshProblem(m);
  MSK_ASSERT(problem.empty(), "decimation broke the manifold: " + problem);
  return m;
}

}  // namespace msk
