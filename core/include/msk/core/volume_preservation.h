#pragma once
/// Volume preservation of a closed 2-simplex surface (the ghost layer of a 3-simplex volume model): one global
/// constraint C = V(P) − V* on the volume V enclosed by the surface's triangle mesh, the one trianglesFromSimplex()
/// recovers (triangle vertices T = A⁻¹(Cᵀ + μF)P, A = CᵀC + μI, a fixed linear map of the simplex vertices P), so the
/// volume held is the volume of the surface and of the tet mesh the segmenter reports. Projected as a position-based
/// constraint (Müller et al. 2007, §3.3; DESIGN-NOTES §2 weighting): ΔPi = −γ wi C ∇iV / Σj wj |∇jV|², with
/// ∇_P V = (C + μFᵀ) A⁻¹ ∇_T V. Lengths in mm, volumes in mm³.
///
/// "Unless the image demands otherwise": the set first watches the surface evolve under the image forces without
/// acting, for at least `minObserveProjections` projections and then until its volume settles (changes by less than
/// `settleRate` of V* between two projections), at most `maxObserveProjections` projections. If the settled volume is
/// within `tolerance` of the reference V* (the template's), the change is taken for the image force's own bias (blur,
/// partial volume) and the volume is held at V* from then on; if it has moved further, the image demands another volume
/// and the set never acts.
#include <Eigen/Core>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <string>

#include "msk/core/constraint_set.h"
#include "msk/core/simplex_mesh.h"

namespace msk {

/// Options of VolumePreservation.
struct VolumePreservationOptions {
  double stiffness = 1.0;          ///< γ ∈ [0, 1] of the volume constraint once it holds
  double tolerance = 0.10;         ///< |V/V* − 1| up to which the image is not taken to demand a volume change
  double settleRate = 0.002;       ///< |ΔV| / V* between projections under which the volume has settled
  int minObserveProjections = 1;   ///< projections watched at least
  int maxObserveProjections = 30;  ///< projections watched at most before deciding (0 = hold from the start)
};

/// What a VolumePreservation set has decided.
enum class VolumeDecision {
  Observing,  ///< still watching the image forces
  Holding,    ///< the volume is held at the reference
  Following   ///< the image demanded another volume: the set does nothing
};

/// Global volume constraint of a closed 2-simplex surface with the decision rule of the file comment. Particle
/// first + v is vertex v of the surface. Project-only (no rows), so every solver scheme runs it through project().
class VolumePreservation : public ConstraintSet {
 public:
  /// Connectivity and recovery map from `surface` (k = 2, with faces); reference volume V* = the volume of its triangle
  /// mesh at its positions (the template). Throws ParameterError on a stiffness or tolerance outside [0, 1] or negative
  /// maxObserveProjections or settleRate, Error if the surface encloses no volume.
  explicit VolumePreservation(const SimplexMesh& surface, const VolumePreservationOptions& options = {});
  std::string name() const override { return "volume-preservation"; }
  void project(Points& p, const Eigen::VectorXd& w) override;
  /// The decision so far.
  VolumeDecision decision() const { return decision_; }
  /// Volume of the surface's triangle mesh at `positions` of its simplex vertices (#V×3), mm³.
  double volume(const Points& positions) const;
  /// Gradient of volume() with respect to the simplex vertices, #V×3 (mm²).
  Points volumeGradient(const Points& positions) const;
  /// Volume at the last projection (before it), mm³.
  double lastVolume() const { return lastVolume_; }
  /// Reference volume V*, mm³.
  double reference() const { return reference_; }

 private:
  /// Triangle vertices T (#F×3) of simplex positions P: A⁻¹ (Cᵀ + μF) P.
  Points recover(const Points& p) const;
  Triangles triangles_;                                      ///< #V×3: triangle t (simplex vertex t) → its vertices
  Eigen::SparseMatrix<double> c_, f_;                        ///< C (#V×#F, 1/3) and F (#F×#V, face means)
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt_;  ///< A = CᵀC + μI
  double mu_ = 0;
  double reference_ = 0;
  VolumePreservationOptions opt_;
  int seen_ = 0;
  double previous_ = 0;  ///< volume at the previous projection while observing
  double lastVolume_ = 0;
  VolumeDecision decision_ = VolumeDecision::Observing;
};

}  // namespace msk
