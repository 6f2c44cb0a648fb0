#pragma once
/// The 2-simplex internal constraint (DESIGN-NOTES §2, method 2; thesis seed §4.8.1): each vertex of a 2-simplex
/// mesh pulled toward its shape-memory target, its three neighbours taking the reaction. simplexInternalRow() is the
/// definition; the set (SimplexInternalConstraints) owns indices, reference parameters and stiffness, and its batch
/// kernel (simplex_batch.h) computes the same rows several at a time with the constants below.
#include <Eigen/Core>
#include <memory>
#include <string>

#include "msk/core/constraint_set.h"
#include "msk/core/simplex_mesh.h"

namespace msk {

class SimplexInternalBatch;

/// Constants of the reaction split λ of simplexInternalRow(), shared with the batch kernel.
namespace simplex_internal {
/// Neighbours whose (P2 − P1) × (P3 − P1) is shorter than this × their longest edge² are degenerate (no frame).
constexpr double kMinFrameRatio = 1e-12;
/// The torque-free split λ = μ / Σμ exists only where |Σμ| exceeds this share of Σ|μi|.
constexpr double kMinSplitShare = 0.05;
/// A split farther than this from ε̃ (max |λi − ε̃i|) is pulled back to this distance.
constexpr double kMaxSplitDeviation = 0.75;
/// A split with some |λi| above this is replaced by λ = ε̃.
constexpr double kMaxReaction = 3.0;
/// A split whose W = w + Σ ε̃i λi wi falls below w + this × Σ ε̃i² wi is replaced by λ = ε̃.
constexpr double kMinInverseMassShare = 0.5;
/// Smoothing mode: share of the step along the neighbours' normal taken per projection (1 / (1 + 3 neighbours)).
constexpr double kSmoothingNormalStep = 0.25;
}  // namespace simplex_internal

/// How the 2-simplex internal constraint chooses its target.
enum class InternalMode {
  ShapeMemory,  ///< ε̃, h̃ of the template (scale-free), the default
  /// ε̃ = 1/3, h̃ = mean of the neighbours' current scale-free heights; the step along the normal is a quarter of the
  /// way (the consistent step: P's own move changes its neighbours' heights) and the reactions are ε̃
  Smoothing
};

/// Target of the 2-simplex shape memory at the current neighbours: P̃ = Σ ε̃i Pi + h̃·r⊥·n, with the reference height
/// stored scale-free (h̃ = h_ref / r⊥_ref) and rescaled by the current circumradius r⊥ of P1P2P3, so the memory holds
/// under a change of size. Returns false if the neighbours are degenerate (collinear).
bool simplexShapeTarget(const Eigen::Vector3d pi[3], const double epsRef[3], double heightOverRadius,
                        Eigen::Vector3d& target);

/// The 2-simplex internal constraint of vertex P (inverse mass w) toward `target` P̃ as a row over (P, P1, P2, P3)
/// (indices 0..3): C = P − P̃, g = (1, −ε̃i), r = (1, −λi) with λ' = [PP1 PP2 PP3]⁻¹ PP̃, λi = λ'i / Σλ'j, so linear and
/// angular momentum are conserved and the reduced mass m̄ = 1/W, W = w + Σ ε̃i λi wi, makes the full step (γ = 1) land
/// on the target to first order. Where no torque-free split exists (PP̃ nearly parallel to the neighbours' plane, or λ
/// extreme; see simplex_internal) the neighbours share the reaction with λ = ε̃ instead (linear momentum still
/// conserved); `torqueFree` (optional) tells which. Lengths in mm, inverse masses wi (0 = fixed), γ ∈ [0, 1]. Returns
/// false on degenerate input (every particle fixed, non-finite target).
bool simplexInternalRow(const Eigen::Vector3d& p, const Eigen::Vector3d pi[3], const Eigen::Vector3d& target, double w,
                        const double wi[3], const double epsTarget[3], double gamma, ConstraintRow& row,
                        bool* torqueFree = nullptr);

/// The position-based correction of simplexInternalRow() (pbdCorrections()): ΔP into `dp`, ΔPi into `dpi`.
bool simplexInternalCorrection(const Eigen::Vector3d& p, const Eigen::Vector3d pi[3], const Eigen::Vector3d& target,
                               double w, const double wi[3], const double epsTarget[3], double gamma,
                               Eigen::Vector3d& dp, Eigen::Vector3d dpi[3], bool* torqueFree = nullptr);

/// Reference metric parameters of every vertex of a 2-simplex mesh (DESIGN-NOTES §2, method 2): ε̃ (#V×3, barycentric
/// coordinates of the vertex's projection on its neighbours' plane) and the scale-free height h̃ = h / r⊥ (#V); a
/// vertex whose neighbours are degenerate gets ε̃ = ⅓ and h̃ = 0.
void simplexReferenceParameters(const SimplexMesh& reference, Eigen::MatrixX3d& eps, Eigen::VectorXd& hOverR);

/// Internal constraints of a 2-simplex mesh: one row per vertex (simplexInternalRow()), targets from the reference
/// (template) geometry.
class SimplexInternalConstraints : public ConstraintSet {
 public:
  /// Records the neighbour table and the reference metric parameters of `reference` (same connectivity as the
  /// meshes it will be applied to). γ ∈ [0, 1] (throws ParameterError otherwise).
  SimplexInternalConstraints(const SimplexMesh& reference, double gamma, InternalMode mode = InternalMode::ShapeMemory);
  ~SimplexInternalConstraints() override;
  std::string name() const override { return "simplex-internal"; }
  int rowCount() const override { return static_cast<int>(nb_.rows()); }
  int rowParticles(int r, int index[kMaxRowParticles]) const override;
  void beginRows(const Points& p, const Eigen::VectorXd& w) override;
  bool row(int r, const Points& p, const Eigen::VectorXd& w, ConstraintRow& out) const override;
  /// The same rows as a batch kernel (simplex_batch.h: no virtual calls, several rows at a time), which the Solver's
  /// coloured Gauss–Seidel and Jacobi schemes run instead of row(); built on first use, at the set's first particle.
  /// Shape-memory mode only: nullptr in smoothing mode (its targets need a pass over the current heights).
  SimplexInternalBatch* batch();
  /// User stiffness γ.
  double gamma() const { return gamma_; }

 private:
  /// Smoothing mode: the neighbourhood means of the current scale-free heights of the set's vertices `p` (#n×3).
  Eigen::VectorXd smoothingHeights(const Eigen::Ref<const Points>& p) const;
  std::unique_ptr<SimplexInternalBatch> batch_;  ///< built by batch() on first use
  NeighborTable nb_;
  Eigen::MatrixX3d eps_;
  Eigen::VectorXd hOverR_;
  Eigen::VectorXd rowHeights_;  ///< smoothing heights of the current row pass (beginRows())
  double gamma_;
  InternalMode mode_;
};

}  // namespace msk
