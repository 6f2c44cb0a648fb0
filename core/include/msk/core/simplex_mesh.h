#pragma once
/// k-simplex meshes (every vertex has exactly k+1 neighbours) as structs of arrays, and the 2-simplex ↔
/// triangle-mesh duality (DESIGN-NOTES §1).
#include <Eigen/Core>
#include <map>
#include <string>
#include <vector>

#include "msk/core/triangle_mesh.h"

namespace msk {

/// Neighbour table, #V×(k+1), row-major.
using NeighborTable = Eigen::Matrix<int, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// A k-simplex mesh: k = 1 curve (medial axis), k = 2 closed surface, k = 3 volume.
/// For k = 2 the neighbours (P1, P2, P3) of a vertex are ordered so that (P2−P1)×(P3−P1) points outward.
struct SimplexMesh {
  int k = 2;                ///< simplex order
  Points positions;         ///< #V×3, world mm
  NeighborTable neighbors;  ///< #V×(k+1) vertex indices
  /// k = 2 only: the mesh's faces (polygons, one per vertex of the primal triangle mesh) in CSR form:
  /// face f has vertices faceVertices[faceOffsets[f] .. faceOffsets[f+1]), ordered counter-clockwise from outside.
  std::vector<int> faceOffsets, faceVertices;
  std::map<std::string, Eigen::VectorXd> pointData;  ///< per-vertex scalars, each of length #V

  /// Number of vertices.
  int vertexCount() const { return static_cast<int>(positions.rows()); }
  /// Number of polygonal faces (k = 2).
  int faceCount() const { return faceOffsets.empty() ? 0 : static_cast<int>(faceOffsets.size()) - 1; }
};

/// Why a mesh is not a valid k-simplex mesh (empty if valid): table shape, indices in range, no self or repeated
/// neighbours, symmetric adjacency, finite positions, face table consistent (k = 2).
std::string simplexMeshProblem(const SimplexMesh& mesh);

/// Rebuilds faceOffsets/faceVertices of a 2-simplex mesh from its oriented neighbour table: arriving at a vertex from
/// its neighbour j, a face continues to neighbour (j + 2) mod 3. Throws Error if the table is not a valid k = 2 table.
void buildSimplexFaces(SimplexMesh& mesh);

/// Dual of a closed triangle mesh: one simplex vertex per triangle, at the triangle's centroid; one face per
/// triangle-mesh vertex. Point data of the triangle mesh is averaged onto the simplex vertices. Throws Error if the
/// mesh is not closed.
SimplexMesh simplexFromTriangles(const TriangleMesh& mesh);

/// Triangle mesh back from a 2-simplex mesh, with the geometric correction: the triangle vertices V are solved
/// (sparse least squares) so that each triangle's centroid equals its simplex vertex, min |C V − P|² + μ|V − V₀|²
/// with V₀ the face centroids and μ small, so the round trip triangles → simplex → triangles does not shrink.
TriangleMesh trianglesFromSimplex(const SimplexMesh& mesh);

/// Area-weighted outward vertex normals of a 2-simplex mesh's surface (smoother than the neighbour-plane normal).
Points simplexVertexNormals(const SimplexMesh& mesh);
/// simplexVertexNormals() of a mesh whose tables are known to be valid (simplexMeshProblem() empty, as
/// simplexFromTriangles() makes it, with its face table) while its positions change, as in every step of a run: only
/// the positions are checked (finite; Error otherwise), the tables are neither checked again nor copied. A mesh without
/// its own face table gets the full check.
Points validSimplexVertexNormals(const SimplexMesh& mesh);

/// The faces of a 2-simplex mesh split into triangles fanned from each face's first vertex (outward, indices are
/// simplex vertices): a triangulated surface whose corners are the particles themselves (used for collisions).
Triangles simplexFanTriangles(const SimplexMesh& mesh);

/// Interpolation from one surface to another, set up once between two reference shapes (e.g. two resolution levels
/// of a template): each target point is bound to its closest point on the source's triangles with barycentric
/// weights; apply() then carries per-vertex vectors (e.g. displacements) or scalars across.
class SurfaceTransfer {
 public:
  /// Binds every point of `targetPoints` to its closest point on the triangles of `source` (a grid-accelerated
  /// exact search). Throws Error if `source` has no triangles.
  SurfaceTransfer(const TriangleMesh& source, const Points& targetPoints);
  /// Interpolates per-source-vertex rows (#Vsource×c) to the target points (#Vtarget×c).
  Eigen::MatrixXd apply(const Eigen::MatrixXd& sourceValues) const;
  /// Distance from each target point to its bound source point (mm).
  const Eigen::VectorXd& distances() const { return distances_; }
  /// Per target point: the source triangle's three vertex indices and their barycentric weights (rows sum to 1).
  const Eigen::Matrix<int, Eigen::Dynamic, 3>& corners() const { return tri_; }
  const Eigen::MatrixX3d& weights() const { return bary_; }

 private:
  int sourceVertexCount_ = 0;
  Eigen::Matrix<int, Eigen::Dynamic, 3> tri_;
  Eigen::MatrixX3d bary_;
  Eigen::VectorXd distances_;
};

/// Closest point on a triangle (a, b, c) to p; writes barycentric weights (sum 1). Exact (Ericson's regions).
Eigen::Vector3d closestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                       const Eigen::Vector3d& c, Eigen::Vector3d* barycentric = nullptr);

}  // namespace msk
