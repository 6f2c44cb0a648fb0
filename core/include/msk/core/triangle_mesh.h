#pragma once
/// Closed triangle surface meshes as structs of arrays, in world millimetres (RAS inside mskseg).
#include <Eigen/Core>
#include <map>
#include <string>

namespace msk {

/// Vertex positions, #V×3, world mm.
using Points = Eigen::Matrix<double, Eigen::Dynamic, 3>;
/// Triangle vertex indices, #F×3, counter-clockwise seen from outside (outward normals).
using Triangles = Eigen::Matrix<int, Eigen::Dynamic, 3>;

/// A triangle surface mesh with named per-vertex scalar arrays.
struct TriangleMesh {
  Points vertices;                                   ///< #V×3 positions, mm
  Triangles faces;                                   ///< #F×3 indices into vertices
  std::map<std::string, Eigen::VectorXd> pointData;  ///< per-vertex scalars, each of length #V

  /// Number of vertices.
  int vertexCount() const { return static_cast<int>(vertices.rows()); }
  /// Number of triangles.
  int faceCount() const { return static_cast<int>(faces.rows()); }
};

/// Why a mesh is not a valid closed, consistently oriented 2-manifold; empty if it is.
/// Checks: non-empty, indices in range, no degenerate (repeated-index) faces, finite coordinates,
/// every edge shared by exactly two faces with opposite orientation, per-vertex arrays sized #V.
std::string closedMeshProblem(const TriangleMesh& mesh);

/// Signed enclosed volume, mm³ (positive for outward-oriented closed meshes).
double enclosedVolume(const TriangleMesh& mesh);
/// Total surface area, mm².
double surfaceArea(const TriangleMesh& mesh);
/// Unit face normals (#F×3); zero rows for zero-area faces.
Points faceNormals(const TriangleMesh& mesh);
/// Area-weighted unit vertex normals (#V×3).
Points vertexNormals(const TriangleMesh& mesh);
/// Mean edge length, mm.
double meanEdgeLength(const TriangleMesh& mesh);
/// Moves every vertex along its vertex normal by one distance δ = (volumeMm3 − V) / area, twice (the area changes with
/// δ), so that the closed mesh encloses about `volumeMm3`; the total offset is kept within ±limitMm. Returns it (mm).
double offsetToVolume(TriangleMesh& mesh, double volumeMm3, double limitMm);
/// Reverses every triangle's winding.
void flipFaces(TriangleMesh& mesh);
/// Applies x' = A x + t (A = affine.topLeftCorner(3,3)); flips windings when det(A) < 0 so normals stay outward.
void transformMesh(TriangleMesh& mesh, const Eigen::Matrix4d& affine);
/// The RAS↔LPS flip diag(−1, −1, 1, 1) (its own inverse).
Eigen::Matrix4d rasLpsFlip();

/// A geodesic sphere: icosahedron subdivided `subdivisions` times (20·4^s faces), outward oriented.
TriangleMesh makeIcosphere(double radiusMm, int subdivisions, const Eigen::Vector3d& center = Eigen::Vector3d::Zero());

}  // namespace msk
