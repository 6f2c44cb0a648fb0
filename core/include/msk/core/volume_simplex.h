#pragma once
/// Volumetric models: tetrahedral meshes and their dual 3-simplex meshes (every vertex has 4 neighbours,
/// DESIGN-NOTES §1), the 3-simplex internal constraint (thesis seed Table 4.25, DESIGN-NOTES §2) and the coupling of
/// a volume model's boundary to a 2-simplex surface.
///
/// Boundary convention ("ghost" particles). A tet on the boundary has fewer than 4 face-adjacent tets. Each boundary
/// face of the tet mesh therefore contributes one extra simplex vertex, a ghost, placed at the face's centroid. A
/// ghost's 4 neighbours are the 3 ghosts of the edge-adjacent boundary faces and the tet that owns the face. So
/// every vertex has exactly 4 neighbours, adjacency is symmetric, and the ghosts form the 2-simplex mesh dual to the
/// boundary triangulation, the same mesh simplexFromTriangles() builds. The surface model *is* the ghost layer. In
/// a stacked particle system the volume model takes particles [first, first + T + B): the T tets first, then the B
/// ghosts. A 2-simplex surface model (SimplexInternalConstraints, image targets, collisions) working on
/// VolumeSimplexMesh::boundary with firstParticle = first + T shares its particles with the ghosts and drives the
/// volume model through the 3-simplex constraints of the boundary tets. A surface of another resolution can drive
/// the ghosts through SurfaceTransfer (bind the ghosts' rest positions to its triangles once, then carry its
/// displacements over as targets).
#include <Eigen/Core>
#include <string>
#include <vector>

#include "msk/core/constraint_set.h"
#include "msk/core/simplex_mesh.h"
#include "msk/core/triangle_mesh.h"

namespace msk {

/// Tetrahedron node indices, #T×4.
using Tets = Eigen::Matrix<int, Eigen::Dynamic, 4>;

/// A tetrahedral mesh. Every tet (a, b, c, d) is positively oriented: (b−a)·((c−a)×(d−a)) > 0.
struct TetMesh {
  Points nodes;  ///< #N×3 node positions, world mm
  Tets tets;     ///< #T×4 indices into nodes

  /// Number of nodes.
  int nodeCount() const { return static_cast<int>(nodes.rows()); }
  /// Number of tetrahedra.
  int tetCount() const { return static_cast<int>(tets.rows()); }
};

/// Signed volume of the tetrahedron (a, b, c, d), mm³: (b−a)·((c−a)×(d−a)) / 6.
double signedTetVolume(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                       const Eigen::Vector3d& d);

/// Signed volume of every tet, #T (mm³).
Eigen::VectorXd tetVolumes(const TetMesh& mesh);

/// Sum of the signed tet volumes, mm³.
double totalVolume(const TetMesh& mesh);

/// Smallest of the 6 dihedral angles of every tet, #T (degrees; 0 for a flat tet, slivers have a few degrees).
Eigen::VectorXd tetMinDihedralAngles(const TetMesh& mesh);

/// Why a mesh is not a valid tet mesh (empty if valid): non-empty, indices in range, no repeated node in a tet,
/// finite nodes, every tet positively oriented, every triangle face shared by at most two tets.
std::string tetMeshProblem(const TetMesh& mesh);

/// Boundary faces of a tet mesh (faces of exactly one tet), outward-oriented, as node indices (#B×3); `owner`
/// (optional) receives each face's tet. Faces come in the order of their tets and, within a tet, of the local face
/// opposite node 0, 1, 2, 3.
Triangles tetBoundaryFaces(const TetMesh& mesh, Eigen::VectorXi* owner = nullptr);

/// The boundary surface of a tet mesh as a compact, outward-oriented triangle mesh (unused nodes dropped);
/// `nodeOf` (optional) receives the tet-mesh node of each surface vertex.
TriangleMesh tetBoundary(const TetMesh& mesh, Eigen::VectorXi* nodeOf = nullptr);

/// An n×n×n block of cubes of edge `edgeMm` (corner at the origin), each cube split into the 6 Freudenthal tets
/// around its main diagonal, positively oriented (a test and benchmark volume, as makeIcosphere is for surfaces).
TetMesh makeCubeTets(int n, double edgeMm);

/// A 3-simplex volume model dual to a tet mesh, ghosts included (see the file comment).
struct VolumeSimplexMesh {
  /// k = 3 mesh: vertices [0, T) are the tets (at their centroids), [T, T + B) the ghosts (boundary face centroids).
  /// Tet t lists the vertex across its local face opposite node j in column j. Ghost T + g lists the 3 ghosts
  /// across its face's edges (in VolumeSimplexMesh::boundary's neighbour order, shifted by T) and its tet last.
  SimplexMesh simplex;
  /// #(T+B)×4 reference barycentric coordinates ε̃ (Σ = 1): P = Σ ε̃i Pi over the 4 neighbours at rest.
  Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor> epsilon;
  /// #(T+B) 1 where the 4 neighbours are (nearly) coplanar at rest: ε̃ is then the minimum-norm affine least-squares
  /// solution. Where P lies off that plane (no ε̃ reproduces it) the vertex is marked 2 and never constrained.
  Eigen::VectorXi degenerate;
  Tets tets;                ///< #T×4 primal tets (node indices), for node recovery and volumes
  Triangles boundaryFaces;  ///< #B×3 primal boundary faces (node indices, outward); ghost g ↔ row g
  int nodeCount = 0;        ///< number of primal nodes
  /// The ghost layer as a 2-simplex surface (dual of boundaryFaces, rest positions): its vertex g is ghost T + g.
  SimplexMesh boundary;

  /// Number of tet vertices T.
  int tetCount() const { return static_cast<int>(tets.rows()); }
  /// Number of ghost vertices B.
  int ghostCount() const { return static_cast<int>(boundaryFaces.rows()); }
  /// Number of simplex vertices T + B (= particles of the model).
  int vertexCount() const { return simplex.vertexCount(); }
};

/// Builds the dual 3-simplex model of a tet mesh (ghost convention, file comment) and its reference ε̃. Throws
/// Error if the tet mesh is invalid (tetMeshProblem) or its boundary is not a closed 2-manifold.
VolumeSimplexMesh volumeSimplexFromTets(const TetMesh& mesh);

/// Barycentric coordinates ε (Σ = 1) of p in the 4 points pi, lengths in mm. Returns 0 if the points span a
/// tetrahedron, 1 if they are (nearly) coplanar (relative volume < 1e-9) and p lies in their affine hull (ε the
/// minimum-norm solution), 2 if no affine combination reproduces p (ε the minimum-norm least-squares solution,
/// renormalised to Σ = 1). Non-finite input also gives 2.
int simplexBarycentric(const Eigen::Vector3d& p, const Eigen::Vector3d pi[4], double eps[4]);

/// Tet nodes recovered from simplex positions (#(T+B)×3): least squares making every tet's node mean equal its
/// simplex vertex and every boundary face's node mean equal its ghost, min |A N − P|² + μ|N − N₀|² with N₀ the mean
/// of the incident simplex vertices and μ small (1e-6), so the rest positions give back the rest nodes.
TetMesh tetsFromVolumeSimplex(const VolumeSimplexMesh& model, const Points& positions);

/// As tetsFromVolumeSimplex(), with the nodes `fixedNodes` held at the rows of `fixedPositions` (#F×3, mm) and only the
/// others solved for, e.g. the boundary nodes placed on the evolved surface's vertices. Throws ParameterError on sizes
/// that do not match or a node index out of range.
TetMesh tetsFromVolumeSimplex(const VolumeSimplexMesh& model, const Points& positions,
                              const Eigen::VectorXi& fixedNodes, const Points& fixedPositions);

/// The tets' equilibrium under their 3-simplex constraints with the ghosts held (SurfaceDriven), nearest to where
/// they are: returns `positions` (#(T+B)×3) with the tet rows x replaced by argmin Σ_t |Σ ε̃i Pi − P_t|² + μ|x − x₀|²
/// (x₀ the given tet rows, μ > 0 dimensionless), one sparse solve. The constraints alone leave some tet motions free
/// (the system is singular on regular meshes), which μ keeps at the start. Throws ParameterError if μ ≤ 0.
Points relaxVolumeSimplexTets(const VolumeSimplexMesh& model, const Points& positions, double mu = 1e-3);

/// Enclosed volume of the model at `positions` (#(T+B)×3), mm³: the sum of the signed volumes of the tets whose
/// nodes tetsFromVolumeSimplex() recovers (the primal volume, not the volume of the dual cells).
double volumeSimplexVolume(const VolumeSimplexMesh& model, const Points& positions);

/// 3-simplex internal constraint (thesis seed Table 4.25, DESIGN-NOTES §2) as a row over (P, P1..P4) (indices 0..4):
/// C = Σ ε̃i Pi − P, g = r = (−1, ε̃i), γ; forces F_P = αC, F_Pi = −α ε̃i C with α = γ m̄ dt⁻², reduced mass
/// m̄ = (w + Σ ε̃i² wi)⁻¹; as a position correction ΔP = γ w m̄ C, ΔPi = −γ wi ε̃i m̄ C, so a full step (γ = 1)
/// satisfies C = 0 exactly. Linear and angular momentum are conserved (Σ ε̃i = 1). Lengths in mm. Returns false if
/// Σ ε̃i ≠ 1 or C is not finite.
bool volumeSimplexRow(const Eigen::Vector3d& p, const Eigen::Vector3d pi[4], const double eps[4], double gamma,
                      ConstraintRow& row);

/// The position-based correction of volumeSimplexRow() for inverse masses w (P) and wi: ΔP into `dp`, ΔPi into
/// `dpi`. Returns false on degenerate input (every particle fixed, Σ ε̃i ≠ 1, non-finite values).
bool volumeSimplexCorrection(const Eigen::Vector3d& p, const Eigen::Vector3d pi[4], double w, const double wi[4],
                             const double eps[4], double gamma, Eigen::Vector3d& dp, Eigen::Vector3d dpi[4]);

/// Which vertices of a volume model carry a 3-simplex constraint.
enum class VolumeBoundary {
  SurfaceDriven,  ///< tets only: the ghosts are moved by the surface model that shares them (the default)
  Constrained     ///< tets and ghosts (a volume model without a surface model)
};

/// 3-simplex internal constraints of a volume model: one row per constrained vertex (volumeSimplexRow()), in vertex
/// order, reference ε̃ of the model. Particle first + v is simplex vertex v (tets, then ghosts).
class VolumeSimplexConstraints : public ConstraintSet {
 public:
  /// Records the neighbour table and ε̃ of `model`. γ ∈ [0, 1] (throws ParameterError otherwise).
  VolumeSimplexConstraints(const VolumeSimplexMesh& model, double gamma,
                           VolumeBoundary boundary = VolumeBoundary::SurfaceDriven);
  std::string name() const override { return "volume-simplex"; }
  /// One row per constrained vertex: the tets (and with VolumeBoundary::Constrained the ghosts) but for those marked
  /// degenerate = 2.
  int rowCount() const override { return static_cast<int>(rows_.size()); }
  int rowParticles(int r, int index[kMaxRowParticles]) const override;
  void beginRows(const Points& p, const Eigen::VectorXd& w) override;
  bool row(int r, const Points& p, const Eigen::VectorXd& w, ConstraintRow& out) const override;
  /// User stiffness γ.
  double gamma() const { return gamma_; }

 private:
  NeighborTable nb_;
  Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor> eps_;
  std::vector<int> rows_;  ///< the constrained vertices, in vertex order
  double gamma_;
};

}  // namespace msk
