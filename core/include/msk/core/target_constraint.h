#pragma once
/// Independent target constraints (image forces, DESIGN-NOTES §2): each vertex pulled toward a target of its own.
#include <Eigen/Core>
#include <string>

#include "msk/core/constraint_set.h"

namespace msk {

/// Independent target constraint of particle P toward `target` T as a one-particle row (index 0): C = P − T,
/// g = r = 1, γ, a target direction (anisotropic derivative): PBD moves a free particle by γ (T − P) (α = M dt⁻²).
/// Returns false if C is not finite.
bool targetRow(const Eigen::Vector3d& p, const Eigen::Vector3d& target, double gamma, ConstraintRow& row);

/// The position-based correction of targetRow() for a particle of inverse mass w: ΔP = γ (T − P); false if w = 0.
bool targetCorrection(const Eigen::Vector3d& p, const Eigen::Vector3d& target, double w, double gamma,
                      Eigen::Vector3d& dp);

/// Independent target constraints: each vertex pulled toward its target with γ·weight_i (weights in [0, 1]).
class TargetConstraints : public ConstraintSet {
 public:
  /// γ ∈ [0, 1] (throws ParameterError otherwise).
  explicit TargetConstraints(double gamma);
  std::string name() const override { return "image-targets"; }
  /// Sets the targets (#V×3) and per-vertex weights (#V, clamped to [0, 1]).
  void setTargets(const Points& targets, const Eigen::VectorXd& weights);
  /// One row per vertex (targetRow(), γ·weight); a vertex of weight 0 or a fixed one has nothing to do.
  int rowCount() const override { return static_cast<int>(targets_.rows()); }
  int rowParticles(int r, int index[kMaxRowParticles]) const override;
  void beginRows(const Points& p, const Eigen::VectorXd& w) override;
  bool row(int r, const Points& p, const Eigen::VectorXd& w, ConstraintRow& out) const override;

 private:
  double gamma_;
  Points targets_;
  Eigen::VectorXd weights_;
};

}  // namespace msk
