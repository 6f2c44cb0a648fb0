#pragma once
/// Global shape prior (shape matching, DESIGN-NOTES §1): every vertex pulled toward the best-fitting transform of its
/// reference shape.
#include <Eigen/Core>
#include <string>

#include "msk/core/constraint_set.h"
#include "msk/core/transform_fit.h"

namespace msk {

/// Pulls every vertex toward the best-fitting transform of the reference shape, mass-weighted (fitTransform()). The
/// weight λ can be changed between steps (ramped over a run).
class ShapeMatchingConstraint : public ConstraintSet {
 public:
  /// `reference` #V×3; λ ∈ [0, 1] (throws ParameterError otherwise).
  ShapeMatchingConstraint(const Points& reference, PriorTransform transform, double lambda);
  std::string name() const override { return "global-prior"; }
  /// One row per vertex: C = P − goal, g = r = 1, γ = λ, the goals of the transform fitted by beginRows().
  int rowCount() const override { return static_cast<int>(ref_.rows()); }
  int rowParticles(int r, int index[kMaxRowParticles]) const override;
  void beginRows(const Points& p, const Eigen::VectorXd& w) override;
  bool row(int r, const Points& p, const Eigen::VectorXd& w, ConstraintRow& out) const override;
  /// Sets λ ∈ [0, 1].
  void setLambda(double lambda);
  /// Current λ.
  double lambda() const { return lambda_; }
  /// The last fitted 4×4 transform (reference → current).
  const Eigen::Matrix4d& lastTransform() const { return last_; }

 private:
  /// Fits last_ to the set's particles of `pAll`, mass-weighted.
  void fit(const Points& pAll, const Eigen::VectorXd& wAll);
  Points ref_;
  PriorTransform transform_;
  double lambda_;
  Eigen::Matrix4d last_ = Eigen::Matrix4d::Identity();
};

}  // namespace msk
