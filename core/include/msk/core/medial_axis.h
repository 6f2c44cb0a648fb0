#pragma once
/// Medial axes of tubular objects and the radial constraints that bind a surface to its axis (DESIGN-NOTES §4):
/// a 1-simplex curve built by slicing the surface along its principal axis, every surface vertex attached to its
/// projection on the curve with a reference radius, and a two-way interaction constraint that restores that radius.
#include <Eigen/Core>
#include <string>

#include "msk/core/constraint_set.h"
#include "msk/core/simplex_mesh.h"
#include "msk/core/triangle_mesh.h"

namespace msk {

// ------------------------------------------------------------------------------------------------ building

/// Settings of buildMedialAxis() (user input).
struct MedialAxisOptions {
  double spacingMm = 5.0;  ///< wanted distance between axis vertices along the principal axis, mm (> 0)
  int slices = 0;          ///< number of slabs = axis vertices (≥ 3); 0 = max(3, round(length / spacingMm)),
                           ///< at most the surface's vertex count
};

/// A medial curve and the frame it was sliced in.
struct MedialAxis {
  /// k = 1 open curve, vertices ordered along `direction`; the ends are wrapped in the neighbour table
  /// (see openCurveMesh()), so the segments of the axis are (j, j+1) for j < #V−1 only.
  SimplexMesh curve;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();      ///< area-weighted centroid of the surface, mm
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();  ///< unit principal axis (largest spread), sign fixed so that
                                                         ///< its largest-magnitude component is positive
  double lengthMm = 0;                                   ///< extent of the surface along `direction`, mm
};

/// A k = 1 simplex mesh for the open polyline `vertices` (#V ≥ 3, in order). simplexMeshProblem() accepts only
/// 2-regular, symmetric neighbour tables for k = 1 (an end vertex may neither list itself nor a neighbour's neighbour),
/// so row j is (j−1, j+1) with the ends wrapped: row 0 = (#V−1, 1), row #V−1 = (#V−2, 0). The wrap link is not a
/// segment of the axis. Throws Error if #V < 3.
SimplexMesh openCurveMesh(const Points& vertices);

/// Medial axis of a closed tubular surface (RAS mm) by slicing: principal axis = largest-eigenvalue eigenvector of the
/// area-weighted covariance of the vertices (each vertex weighs a third of its triangles' area); the extent along it
/// is cut into N equal slabs and axis vertex j is the area-weighted centroid of the vertices about slab j's centre
/// (each vertex shared between the two nearest slab centres in proportion to its nearness, so that no rounding decides
/// where a vertex on a slab boundary counts; an interior slab without weight is interpolated between its weighted
/// neighbours). Throws Error if the surface is not closed or has no area, ParameterError for spacingMm ≤ 0 or
/// non-finite, or slices in {1, 2} or < 0.
MedialAxis buildMedialAxis(const TriangleMesh& surface, const MedialAxisOptions& opts = {});

// ------------------------------------------------------------------------------------------------ attachment

/// Binding of surface vertices to an open axis polyline: vertex v projects to Q̄ = Σ_j weights(v, j)·Q_axisIndex(v, j).
struct RadialAttachment {
  Eigen::Matrix<int, Eigen::Dynamic, 2, Eigen::RowMajor> axisIndex;   ///< #V×2 axis vertices (j, j+1) of the segment,
                                                                      ///< indices into the axis (0-based)
  Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor> weights;  ///< #V×2 (1 − t, t), t ∈ [0, 1]
  Eigen::VectorXd radius;                                             ///< #V reference radius r̃ = |Q̄ − P|, mm

  /// Number of attached surface vertices.
  int vertexCount() const { return static_cast<int>(radius.size()); }
};

/// Attaches every surface point P (#V×3, mm) to its closest point Q̄ on the open polyline `axis` (#A×3, mm, #A ≥ 2;
/// segments (j, j+1), exact point–segment distance, ties to the lower segment) and records r̃ = |Q̄ − P|. Call again to
/// rebind after large motions. Throws Error if #A < 2 or a coordinate is non-finite.
RadialAttachment attachToAxis(const Points& surface, const Points& axis);

/// Inverse masses for the axis vertices (#A) that give axis vertex j the mass of the surface it carries,
/// M_j = Σ_v cj(v) M_v over the attached surface vertices (cj their attachment weight, M_v = 1/surfaceInverseMass[v]):
/// an axis much lighter than its ring is thrown about by sequential projection of the radial constraints and settles
/// off-centre. 0 (fixed) if a fixed surface vertex is attached; axis vertices with nothing attached get the surface's
/// mean inverse mass. Throws Error on a size mismatch or a negative inverse mass.
Eigen::VectorXd axisInverseMass(const RadialAttachment& attachment, int axisVertexCount,
                                const Eigen::VectorXd& surfaceInverseMass);

// ------------------------------------------------------------------------------------------------ kernel

/// Radial constraint, "radius method" (thesis seed §4 radial constraint; DESIGN-NOTES §2 interaction and §4), as a row
/// over (P, Q0, Q1) (indices 0..2): with Q̄ = Σ cj Qj and goal G = r̃·(Q̄ − P)/|Q̄ − P|, C = G − (Q̄ − P) (the goal
/// direction held constant), g = r = (1, −c0, −c1), γ. The PBD step ΔP = −γ m̄ w C, ΔQj = γ m̄ cj wj C with the reduced
/// mass m̄ = (w + Σ cj² wj)⁻¹ changes Q̄ − P by exactly γC and conserves linear momentum when Σ cj = 1. Positions and
/// r̃ in mm, cj the attachment weights. Returns false on degenerate input (|Q̄ − P| ≤ 1e-9 mm, r̃ < 0, anything
/// non-finite).
bool radialRow(const Eigen::Vector3d& p, const Eigen::Vector3d q[2], const double weights[2], double radiusMm,
               double gamma, ConstraintRow& row);

/// The position-based correction of radialRow() for inverse masses w (P) and wq (Q0, Q1): ΔP into `dp`, ΔQj into
/// `dq`. Returns false if the row is degenerate, every particle is fixed, or γ is outside [0, 1].
bool radialCorrection(const Eigen::Vector3d& p, const Eigen::Vector3d q[2], const double weights[2], double radiusMm,
                      double w, const double wq[2], double gamma, Eigen::Vector3d& dp, Eigen::Vector3d dq[2]);

// ------------------------------------------------------------------------------------------------ sets

/// Radial constraints of one tubular object, two-way coupled: the surface's #V particles start at firstParticle()
/// (setFirstParticle, default 0), the axis particles at `firstAxisParticle`, both in the same stacked arrays; the axis
/// vertices take the reactions. Projected in surface-vertex order (Gauss–Seidel). Give the axis particles the mass of
/// the surface they carry (axisInverseMass()); a unit-mass axis under a unit-mass surface is thrown off-centre (by
/// ~8 mm in the squeezed 10 mm tube of the tests, where the radius then did not recover).
class RadialConstraints : public ConstraintSet {
 public:
  /// Keeps `attachment` (axis indices local to the axis); γ ∈ [0, 1] (throws ParameterError otherwise, and for a
  /// negative firstAxisParticle).
  RadialConstraints(const RadialAttachment& attachment, int firstAxisParticle, double gamma);
  std::string name() const override { return "radial"; }
  /// One row per surface vertex (radialRow()), over its particle and its two axis particles.
  int rowCount() const override { return att_.vertexCount(); }
  int rowParticles(int r, int index[kMaxRowParticles]) const override;
  bool row(int r, const Points& p, const Eigen::VectorXd& w, ConstraintRow& out) const override;
  /// Sets γ ∈ [0, 1] (throws ParameterError otherwise).
  void setGamma(double gamma);
  /// User stiffness γ.
  double gamma() const { return gamma_; }
  /// Index of the first axis particle in the solver's arrays.
  int firstAxisParticle() const { return firstAxis_; }
  /// See firstAxisParticle(); throws ParameterError if negative.
  void setFirstAxisParticle(int first);
  /// The attachment in use.
  const RadialAttachment& attachment() const { return att_; }
  void beginRows(const Points& p, const Eigen::VectorXd& w) override;

 private:
  RadialAttachment att_;
  int firstAxis_;
  double gamma_;
  int axisCount_ = 0;
};

/// Re-centres an axis on its surface ("otherwise the average of their attached surface vertices", DESIGN-NOTES §4):
/// c_j = Σ_v cj(v) P_v / Σ_v cj(v) over the surface vertices attached to axis vertex j (cj their attachment weight),
/// and Q_j += γ (I − t tᵀ)(c_j − Q_j) with t the local unit tangent (central difference, one-sided at the ends). Only
/// the part across the axis is applied, so vertices keep their spacing and the end caps do not drag the ends outward.
/// Vertices with no attached surface vertex, or with `axisInverseMasses` (optional, #A) = 0, do not move. Positions in
/// mm, γ ∈ [0, 1] (ParameterError otherwise). Not momentum-conserving: it is a kinematic update of the axis only.
void recenterAxis(const Points& surface, Points& axis, const RadialAttachment& attachment, double gamma,
                  const Eigen::VectorXd* axisInverseMasses = nullptr);

/// recenterAxis() as a constraint set on stacked arrays: surface at firstParticle(), axis at `firstAxisParticle`.
class AxisCentering : public ConstraintSet {
 public:
  /// `axisVertexCount` axis particles start at `firstAxisParticle`; γ ∈ [0, 1] (ParameterError otherwise).
  AxisCentering(const RadialAttachment& attachment, int firstAxisParticle, int axisVertexCount, double gamma);
  std::string name() const override { return "axis-centering"; }
  void project(Points& p, const Eigen::VectorXd& w) override;

 private:
  RadialAttachment att_;
  int firstAxis_, axisCount_;
  double gamma_;
};

// ------------------------------------------------------------------------------------------------ axis-first stage

/// Settings of one axis-first step (GeneralisedCylinder::step(); user input).
struct AxisFirstOptions {
  double imageGain = 1.0;    ///< share of the axis image drive D_j applied per step, [0, 1]
  double shapeMemory = 0.5;  ///< γ of the axis shape memory (axisShapeTargets()) per step, [0, 1]
};

/// Shape-memory targets of an open axis polyline (#A ≥ 3, mm) against its reference (same size, mm): the 1-simplex
/// analogue of the simplex meshes' shape memory (DESIGN-NOTES §4 "axis smoothness"). Interior vertex j goes to
/// ½(Q_{j−1} + Q_{j+1}) + R_j (Q̃_j − ½(Q̃_{j−1} + Q̃_{j+1})), R_j the smallest rotation taking the reference chord
/// Q̃_{j+1} − Q̃_{j−1} onto the current one; an end vertex goes to the extrapolation 2Q_1 − Q_2 + R (Q̃_0 − 2Q̃_1 + Q̃_2)
/// (likewise at the other end), R taking Q̃_2 − Q̃_1 onto Q_2 − Q_1. Translations of the reference, and rotations
/// about an axis across all its chords (a planar reference turned in its plane), are fixed points; a twist about the
/// chords is not restored. A straight reference makes it Laplacian smoothing. Throws Error if the sizes differ or
/// #A < 3.
Points axisShapeTargets(const Points& axis, const Points& reference);

/// A tubular surface moved as a generalised cylinder by its medial axis: the axis-first coarse stage (DESIGN-NOTES §4,
/// "evolve the axis first"). Every surface vertex keeps its reference offset from its attachment point Q̄ (so its
/// reference radius r̃ exactly: the radial constraints taken as infinitely stiff), turned by the smallest rotation
/// that takes the reference axis tangent at Q̄ onto the current one; the axis is driven by the image displacements of
/// the surface vertices it carries, averaged with the attachment weights, and kept in shape by axisShapeTargets().
class GeneralisedCylinder {
 public:
  /// Reference surface (#V×3, mm), reference axis (#A×3, #A ≥ 3, mm) and the attachment of the one to the other
  /// (attachToAxis(referenceSurface, referenceAxis)). Throws Error on a size mismatch or an index beyond the axis.
  GeneralisedCylinder(const Points& referenceSurface, const Points& referenceAxis, const RadialAttachment& attachment);
  /// The surface (#V×3, mm) swept by `axis` (#A×3, mm): P_v = Q̄_v + R_v (P̃_v − Q̃̄_v), R_v the smallest rotation from
  /// the reference to the current unit tangent at the attachment point (vertex tangents by central differences,
  /// one-sided at the ends, interpolated with the attachment weights). The reference axis gives the reference surface.
  Points surface(const Points& axis) const;
  /// Image drive of the axis (#A×3, mm): D_j = Σ_v cj(v) d_v / Σ_v cj(v) over the surface vertices attached to axis
  /// vertex j (cj their attachment weight, d_v = surfaceDisplacements row v, mm, e.g. the weighted image-target
  /// offsets); 0 for an axis vertex that carries nothing.
  Points axisDrive(const Points& surfaceDisplacements) const;
  /// One step: Q += imageGain · axisDrive(d), then Q += shapeMemory · (axisShapeTargets(Q, Q̃) − Q) (Jacobi). Returns
  /// the largest axis vertex move, mm. Throws ParameterError for gains outside [0, 1].
  double step(Points& axis, const Points& surfaceDisplacements, const AxisFirstOptions& opts) const;
  /// Number of axis vertices.
  int axisVertexCount() const { return static_cast<int>(refAxis_.rows()); }

 private:
  /// Unit tangents at the axis vertices (central differences, one-sided at the ends).
  static Points tangents(const Points& axis);
  Points refSurface_, refAxis_, refOffset_;  ///< P̃, Q̃, P̃ − Q̃̄
  RadialAttachment att_;
  Eigen::VectorXd carried_;  ///< Σ_v cj(v) per axis vertex
};

}  // namespace msk
